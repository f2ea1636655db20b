"""Photon map study: kd-tree libraries, memory per photon, query throughput, radiance photons, kernels.

    ./dev python bench/photon_map_study.py             # everything at 1M photons (~1-2 min)
    ./dev python bench/photon_map_study.py --photons 200000 --quick

Photons lie on the six faces of a unit box (a 2D set in 3D, as in a scene), density (1 + a)^2
along one face axis, so irradiance is known everywhere: E = (M/6) (3/7) (1 + a)^2 Phi / N_e.
Every query runs on one thread (OMP_NUM_THREADS does not matter: the map sets it per call), as
in a worker process. Memory is malloc's own count (glibc mallinfo2) around the build, which
sees C allocations that NumPy's nbytes does not. Times are the least CPU time of a few repeats
(the machine is shared); queries are in Morton order unless said otherwise, as a batch of
neighbouring pixels asks.
"""
import argparse
import ctypes
import pathlib
import sys
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
from _bootstrap import load_ember  # noqa: E402

load_ember()
import numpy as np  # noqa: E402

from ember.engine.integrators.photon import photon_map as pm  # noqa: E402
from ember.engine.integrators.photon.photon_map import KERNELS, PhotonMap, RadiancePhotons  # noqa: E402


class _MallInfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in
                "arena ordblks smblks hblks hblkhd usmblks fsmblks uordblks fordblks keepcost".split()]


def heap_bytes():
    """Bytes in use by malloc (small blocks + mmapped blocks), or None off glibc."""
    try:
        libc = ctypes.CDLL("libc.so.6")
        libc.mallinfo2.restype = _MallInfo2
    except (OSError, AttributeError):
        return None
    info = libc.mallinfo2()
    return info.uordblks + info.hblkhd


def best_time(fn, repeats=3):
    """Least CPU time of the process over repeats (one-threaded work: CPU time is what a worker
    on its own core would take; wall time on a shared machine varies 2x), and fn's result."""
    best, out = np.inf, None
    for _ in range(repeats):
        t = time.process_time()
        out = fn()
        best = min(best, time.process_time() - t)
    return best, out


# ----------------------------------------------------------------------------------------------
# The test distribution: six faces of the unit box, inward normals, density ~ (1 + a)^2

_FACES = [  # (fixed axis, value, inward normal sign, axis of a, axis of b)
    (0, 0.0, 1.0, 1, 2), (0, 1.0, -1.0, 2, 1), (1, 0.0, 1.0, 2, 0),
    (1, 1.0, -1.0, 0, 2), (2, 0.0, 1.0, 0, 1), (2, 1.0, -1.0, 1, 0)]


def box_points(rng, m, graded=True):
    """m points on the box faces: position (m,3), normal (m,3), a-coordinate (m,)."""
    face = rng.integers(0, 6, m)
    u = rng.random((m, 2))
    a = np.cbrt(1 + 7 * u[:, 0]) - 1 if graded else u[:, 0]  # inverse CDF of (1+a)^2 / (7/3)
    p, n = np.empty((m, 3)), np.zeros((m, 3))
    for f, (axis, value, sign, ax_a, ax_b) in enumerate(_FACES):
        s = face == f
        p[s, axis], p[s, ax_a], p[s, ax_b] = value, a[s], u[s, 1]
        n[s, axis] = sign
    return p, n, a


def hemisphere(rng, n):
    """Cosine-distributed directions around the unit normals n (m,3)."""
    from ember.engine.sampling import frame_from_z, to_world

    u = rng.random((len(n), 2))
    r, phi = np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
    local = np.column_stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u[:, 0])])
    t, b = frame_from_z(n)
    return to_world(local, t, b, n)


def box_map(rng, m, n_emitted):
    p, n, _ = box_points(rng, m)
    return PhotonMap(p, hemisphere(rng, n), np.ones((m, 3)), n, n_emitted)


def irradiance_true(a, m, n_emitted):
    return (m / 6) * (3 / 7) * (1 + a) ** 2 / n_emitted


# ----------------------------------------------------------------------------------------------

def study_libraries(m, n_query, k):
    print(f"\n## kd-tree libraries: {m} float32 points on box faces (Morton order), {n_query} queries, "
          f"k = {k}, one thread, CPU seconds")
    rng = np.random.default_rng(1)
    p, n, _ = box_points(rng, m)
    p32 = p[pm.morton_order(p)].astype(np.float32)  # as PhotonMap.pack stores them
    q32 = p32[np.sort(rng.integers(0, m, n_query))] + rng.normal(0, 1e-3, (n_query, 3)).astype(np.float32)
    r_max = 4 * np.sqrt(k / (np.pi * m / 6))
    print("| library | build s | query k-NN pts/s | memory B/point (malloc) |")
    print("|---|---|---|---|")
    from pykdtree.kdtree import KDTree
    from scipy.spatial import cKDTree

    threads = pm._omp_set_num_threads()
    variants = [
        ("pykdtree leafsize 16", lambda: KDTree(p32, leafsize=16),
         lambda t: (threads(1), t.query(q32, k=k, distance_upper_bound=r_max, sqr_dists=True))),
        ("pykdtree leafsize 32", lambda: KDTree(p32, leafsize=32),
         lambda t: (threads(1), t.query(q32, k=k, distance_upper_bound=r_max, sqr_dists=True))),
        ("cKDTree (defaults)", lambda: cKDTree(p32),
         lambda t: t.query(q32, k=k, distance_upper_bound=r_max, workers=1)),
        ("cKDTree unbalanced, non-compact", lambda: cKDTree(p32, balanced_tree=False, compact_nodes=False),
         lambda t: t.query(q32, k=k, distance_upper_bound=r_max, workers=1)),
    ]
    trees, rows = [], []
    for name, build, query in variants:
        h0 = heap_bytes()
        t_build, tree = best_time(build, 3)
        h1 = heap_bytes()
        trees.append(tree)
        rows.append([name, t_build, np.inf, (h1 - h0) / m if h0 is not None else float("nan")])
    for _ in range(4):  # interleaved rounds: a busy spell on the machine hits every variant
        for row, tree, (_, _, query) in zip(rows, trees, variants):
            row[2] = min(row[2], best_time(lambda: query(tree), 1)[0])
    for name, t_build, t_query, mem in rows:
        print(f"| {name} | {t_build:.3f} | {n_query / t_query:,.0f} | {mem:.1f} |")


def study_photon_map(m, n_query, k):
    print(f"\n## PhotonMap: {m} photons, k = {k}")
    rng = np.random.default_rng(2)
    p, n, _ = box_points(rng, m)
    wi = hemisphere(rng, n)
    flux = np.ones((m, 3))
    t_pack, arrays = best_time(lambda: PhotonMap.pack(p, wi, flux, n), 1)
    h0 = heap_bytes()
    t_build, photon_map = best_time(lambda: PhotonMap.from_packed(arrays, m), 1)
    h1 = heap_bytes()
    packed = sum(a.nbytes for a in arrays.values())
    print(f"- pack (octahedral encoding, float32): {t_pack:.3f} s; index build (from_packed): {t_build:.3f} s")
    print(f"- memory: packed {packed / m:.1f} B/photon + tree {(h1 - h0) / m:.1f} B/photon measured "
          f"(malloc); nbytes says {photon_map.nbytes / m:.1f} B/photon in all (limit 64)")
    qi = rng.integers(0, m, n_query)
    qi = qi[pm.morton_order(p[qi])]
    q, nq = p[qi] + 1e-4 * n[qi], n[qi]
    r_max = 4 * np.sqrt(k / (np.pi * m / 6))
    albedo = np.array([0.5, 0.6, 0.7]) / np.pi
    for kk in (k, 2 * k):
        t_e, _ = best_time(lambda: photon_map.irradiance(q, nq, kk, r_max))
        t_l, _ = best_time(lambda: photon_map.radiance(q, nq, lambda rows, w: np.broadcast_to(albedo, (len(rows), 3)),
                                                       kk, r_max, kernel="epanechnikov"))
        print(f"- k = {kk}: irradiance {n_query / t_e:,.0f} points/s, radiance (Lambert f, Epanechnikov) "
              f"{n_query / t_l:,.0f} points/s")
    shuffle_q = rng.permutation(n_query)
    t_e, _ = best_time(lambda: photon_map.irradiance(q[shuffle_q], nq[shuffle_q], k, r_max))
    print(f"- k = {k}, queries in random order: irradiance {n_query / t_e:,.0f} points/s")
    r = np.full(n_query, np.sqrt(k / (np.pi * m / 6)))
    t_g, (_, count) = best_time(lambda: photon_map.gather_radius(q, nq, r))
    print(f"- gather_radius with r holding ~{count.mean():.0f} photons: {n_query / t_g:,.0f} points/s")
    # pack() sorts photons in Morton order; the same map in random order, for comparison
    t_sort, _ = best_time(lambda: pm.morton_order(p), 1)
    shuffle = rng.permutation(m)
    shuffled = PhotonMap.from_packed({key: a[shuffle] for key, a in arrays.items()}, m)
    t_b, _ = best_time(lambda: PhotonMap.from_packed({key: a[shuffle] for key, a in arrays.items()}, m), 1)
    t_s, _ = best_time(lambda: shuffled.irradiance(q, nq, k, r_max))
    t_u, _ = best_time(lambda: photon_map.irradiance(q, nq, k, r_max))
    print(f"- Morton order (sort {t_sort:.2f} s in pack): irradiance {n_query / t_u:,.0f} points/s vs "
          f"{n_query / t_s:,.0f} in random order; index build {t_build:.3f} s vs {t_b:.3f} s")
    # chunk size
    saved = pm._CHUNK_PAIRS
    for pairs in (1 << 14, 1 << 17, 1 << 19, 1 << 21):
        pm._CHUNK_PAIRS = pairs
        t_c, _ = best_time(lambda: photon_map.irradiance(q, nq, k, r_max), 2)
        print(f"- chunk of {pairs} pairs ({pairs // k} points): {n_query / t_c:,.0f} points/s")
    pm._CHUNK_PAIRS = saved


def study_radiance_photons(m, n_query, k, stride):
    print(f"\n## Radiance photons: {m} photons, every {stride}-th, k = {k}")
    rng = np.random.default_rng(3)
    photon_map = box_map(rng, m, m)
    r_max = 4 * np.sqrt(k / (np.pi * m / 6))
    t_build, rp = best_time(lambda: RadiancePhotons.build(photon_map, k, r_max, stride=stride), 1)
    q, nq, a = box_points(rng, n_query)
    order = pm.morton_order(q)
    q, nq, a = q[order], nq[order], a[order]
    q = q + 1e-4 * nq
    t_full, (E_full, _) = best_time(lambda: photon_map.irradiance(q, nq, k, r_max))
    t_rp, E_rp = best_time(lambda: rp.lookup(q, nq, r_max))
    E_true = irradiance_true(a, m, m)

    def rel_rms(E, where=slice(None)):
        return np.sqrt(np.mean((E[where, 0] / E_true[where] - 1) ** 2))

    inner = np.all((q > 0.05) & (q < 0.95) | (np.abs(nq) > 0.5), axis=1)  # away from box edges
    print(f"- build {t_build:.2f} s ({len(rp)} estimates, one thread); memory {rp.nbytes / m:.1f} B per photon of the map")
    print(f"- lookup {n_query / t_rp:,.0f} points/s vs full estimate {n_query / t_full:,.0f} points/s: "
          f"speed-up {t_full / t_rp:.1f}x")
    print(f"- relative RMS error vs truth, all points: full {rel_rms(E_full):.4f}, radiance photons {rel_rms(E_rp):.4f}")
    print(f"- away from edges (5 cm): full {rel_rms(E_full, inner):.4f}, radiance photons {rel_rms(E_rp, inner):.4f}")
    both = E_full[:, 0] > 0
    print(f"- radiance photons vs full estimate (where it is > 0): relative RMS difference "
          f"{np.sqrt(np.mean((E_rp[both, 0] / E_full[both, 0] - 1) ** 2)):.4f}, "
          f"mean ratio {np.mean(E_rp[:, 0]) / np.mean(E_full[:, 0]):.4f}; "
          f"{np.mean(E_rp[:, 0] == 0):.4f} of lookups found none, {np.mean(~both):.4f} of full estimates are 0")
    gathered = 32 * n_query // 8  # a final-gather step: 32 gather rays per shading point
    print(f"- break-even: building costs {t_build / (t_full / n_query - t_rp / n_query):,.0f} lookups "
          f"(e.g. {gathered:,} gather rays of {n_query // 8:,} shading points x 32)")


def study_kernels(m, k):
    print(f"\n## Kernels: relative RMS error and mean bias, {m} photons, k = {k}")
    rng = np.random.default_rng(4)
    # a caustic-like spot (Gaussian, sigma 5 cm) on a uniform floor of 1/4 the photons
    m_spot = 3 * m // 4
    xy = np.vstack([rng.random((m - m_spot, 2)), 0.5 + 0.05 * rng.normal(size=(m_spot, 2))])
    n = np.tile([0.0, 0.0, 1.0], (m, 1))
    photon_map = PhotonMap(np.column_stack([xy, np.zeros(m)]), hemisphere(rng, n), np.ones((m, 3)), n, m)
    q = np.column_stack([0.2 + 0.6 * rng.random((20000, 2)), np.zeros(20000)])
    d2 = np.sum((q[:, :2] - 0.5) ** 2, axis=1)
    E_true = (m - m_spot) / m + m_spot / m * np.exp(-d2 / (2 * 0.05 ** 2)) / (2 * np.pi * 0.05 ** 2)
    print("| kernel | rel. RMS | rel. bias (mean) | rel. RMS in the spot (d < 5 cm) |")
    print("|---|---|---|---|")
    spot = d2 < 0.05 ** 2
    for kernel in KERNELS:
        E, _ = photon_map.irradiance(q, np.tile([0.0, 0.0, 1.0], (len(q), 1)), k, 0.2, kernel=kernel)
        rel = E[:, 0] / E_true - 1
        print(f"| {kernel} | {np.sqrt(np.mean(rel ** 2)):.4f} | {np.mean(rel):+.4f} | "
              f"{np.sqrt(np.mean(rel[spot] ** 2)):.4f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--photons", type=int, default=1_000_000)
    ap.add_argument("--queries", type=int, default=100_000)
    ap.add_argument("--k", type=int, default=50)
    ap.add_argument("--stride", type=int, default=4)
    ap.add_argument("--quick", action="store_true", help="skip the library comparison")
    args = ap.parse_args()
    if not args.quick:
        study_libraries(args.photons, args.queries, args.k)
    study_photon_map(args.photons, args.queries, args.k)
    study_radiance_photons(args.photons, args.queries, args.k, args.stride)
    study_kernels(args.photons // 4, args.k)


if __name__ == "__main__":
    main()
