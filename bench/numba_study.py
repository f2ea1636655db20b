"""Would a JIT pay for the node programs? Numba kernels of the two node kinds that dominate
procedural materials (3D fBm Noise, 3D Voronoi F1) against Ember's NumPy evaluators.

    pip install --target /tmp/numba_eval numba==0.61.2 llvmlite==0.44.0   # not a dependency
    PYTHONPATH=/tmp/numba_eval ./dev python bench/numba_study.py [--points 65536] [--json out.json]

Each kernel is one loop over the points, in the order of Cycles' kernel (svm/noise.h
perlin_3d with lookup3's final, svm/fractal_noise.h noise_fbm; svm/voronoi.h voronoi_f1 with
hash_pcg3d_i), with the float32 cell decisions Ember's NumPy code makes and float64 after them.
Reports the largest difference from Ember's values (the kernels must agree with them within
the node tests' tolerance), CPU time per point of both, single-threaded, and the first call's
compile time (what each worker process would pay, without Numba's on-disk cache).
"""
from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numba  # noqa: E402
from numba import njit  # noqa: E402

M32 = 0xFFFFFFFF


@njit(inline="always")
def _rot(x, k):
    return ((x << k) | (x >> (32 - k))) & M32


@njit(inline="always")
def _final(a, b, c):
    c ^= b; c = (c - _rot(b, 14)) & M32  # noqa: E702
    a ^= c; a = (a - _rot(c, 11)) & M32  # noqa: E702
    b ^= a; b = (b - _rot(a, 25)) & M32  # noqa: E702
    c ^= b; c = (c - _rot(b, 16)) & M32  # noqa: E702
    a ^= c; a = (a - _rot(c, 4)) & M32  # noqa: E702
    b ^= a; b = (b - _rot(a, 14)) & M32  # noqa: E702
    c ^= b; c = (c - _rot(b, 24)) & M32  # noqa: E702
    return c


@njit(inline="always")
def _grad3(h, x, y, z):
    h &= 15
    u = x if h < 8 else y
    v = y if h < 4 else (x if (h == 12 or h == 14) else z)
    return (-u if h & 1 else u) + (-v if h & 2 else v)


@njit(inline="always")
def _fade(t):
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


@njit(inline="always")
def _perlin3(x, y, z):
    fx, fy, fz = np.floor(x), np.floor(y), np.floor(z)
    X, Y, Z = np.int64(np.int32(fx)) & M32, np.int64(np.int32(fy)) & M32, np.int64(np.int32(fz)) & M32
    x, y, z = np.float64(x - fx), np.float64(y - fy), np.float64(z - fz)
    seed = (0xDEADBEEF + (3 << 2) + 13) & M32
    g = np.empty(8)  # Numba keeps this small array off the heap in the optimised loop
    for k in range(8):
        dx, dy, dz = k & 1, (k >> 1) & 1, (k >> 2) & 1
        h = _final((X + dx + seed) & M32, (Y + dy + seed) & M32, (Z + dz + seed) & M32)
        g[k] = _grad3(h, x - dx, y - dy, z - dz)
    u, v, w = _fade(x), _fade(y), _fade(z)
    x00 = g[0] + u * (g[1] - g[0])
    x10 = g[2] + u * (g[3] - g[2])
    x01 = g[4] + u * (g[5] - g[4])
    x11 = g[6] + u * (g[7] - g[6])
    y0 = x00 + v * (x10 - x00)
    y1 = x01 + v * (x11 - x01)
    return y0 + w * (y1 - y0)


@njit(cache=False)
def fbm3(px, py, pz, octaves, roughness, lacunarity, out):
    """Normalised fBm of whole octaves (0..octaves) at float32 points."""
    scale = np.float32(0.9820)
    lac = np.float32(lacunarity)
    for i in range(px.shape[0]):
        fscale = np.float32(1.0)
        amp, maxamp, total = 1.0, 0.0, 0.0
        for o in range(octaves + 1):
            x, y, z = np.float32(px[i] * fscale), np.float32(py[i] * fscale), np.float32(pz[i] * fscale)
            t = scale * _perlin3(x, y, z)
            total += t * amp
            maxamp += amp
            amp *= roughness
            fscale = np.float32(fscale * lac)
        out[i] = 0.5 * total / maxamp + 0.5


@njit(inline="always")
def _pcg3(x, y, z):
    x = np.int32(x * np.int32(1664525) + np.int32(1013904223))
    y = np.int32(y * np.int32(1664525) + np.int32(1013904223))
    z = np.int32(z * np.int32(1664525) + np.int32(1013904223))
    x = np.int32(x + y * z)
    y = np.int32(y + z * x)
    z = np.int32(z + x * y)
    x ^= x >> 16
    y ^= y >> 16
    z ^= z >> 16
    x = np.int32(x + y * z)
    y = np.int32(y + z * x)
    z = np.int32(z + x * y)
    return x & 0x7FFFFFFF, y & 0x7FFFFFFF, z & 0x7FFFFFFF


@njit(cache=False)
def voronoi_f1_3(px, py, pz, randomness, out):
    inv = 2.0 ** -31
    for i in range(px.shape[0]):
        cx, cy, cz = np.floor(px[i]), np.floor(py[i]), np.floor(pz[i])
        lx, ly, lz = np.float64(px[i]) - cx, np.float64(py[i]) - cy, np.float64(pz[i]) - cz
        kx, ky, kz = np.int32(cx), np.int32(cy), np.int32(cz)
        best = 3.4028234663852886e38
        for k in range(-1, 2):
            for j in range(-1, 2):
                for m in range(-1, 2):
                    hx, hy, hz = _pcg3(np.int32(kx + m), np.int32(ky + j), np.int32(kz + k))
                    qx = m + np.float64(np.float32(hx)) * inv * randomness - lx
                    qy = j + np.float64(np.float32(hy)) * inv * randomness - ly
                    qz = k + np.float64(np.float32(hz)) * inv * randomness - lz
                    b = qx * qx + qy * qy + qz * qz
                    if b < best:
                        best = b
        out[i] = np.sqrt(best)


def _cpu(fn, repeat=3):
    best = np.inf
    for _ in range(repeat):
        t0 = time.process_time()
        value = fn()
        best = min(best, time.process_time() - t0)
    return best, value


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=65536)
    ap.add_argument("--octaves", type=int, default=4)
    ap.add_argument("--json")
    args = ap.parse_args(argv)
    from _bootstrap import load_ember
    load_ember()
    from ember.engine.allocator import keep_freed_memory
    from ember.engine.nodes import noise, voronoi
    keep_freed_memory()  # as a tracing process has it
    rng = np.random.default_rng(1)
    n = args.points
    p = [(rng.random(n) * 8.0 - 4.0).astype(np.float32) for _ in range(3)]
    rows = {}
    # fBm
    t0 = time.perf_counter()
    out = np.empty(n)
    fbm3(p[0][:4], p[1][:4], p[2][:4], args.octaves, 0.5, 2.0, out[:4])
    compile_fbm = time.perf_counter() - t0
    t_np, ref = _cpu(lambda: noise.fbm(tuple(p), float(args.octaves), 0.5, 2.0, True))
    t_nb, _ = _cpu(lambda: fbm3(p[0], p[1], p[2], args.octaves, 0.5, 2.0, out))
    rows["Noise fBm 3D"] = dict(numpy_us=1e6 * t_np / n, numba_us=1e6 * t_nb / n, speedup=t_np / t_nb,
                                max_diff=float(np.max(np.abs(out - ref))), compile_s=compile_fbm,
                                octaves=args.octaves + 1)
    # Voronoi F1
    t0 = time.perf_counter()
    vout = np.empty(n)
    voronoi_f1_3(p[0][:4], p[1][:4], p[2][:4], 1.0, vout[:4])
    compile_vor = time.perf_counter() - t0

    class P:
        randomness, metric, exponent = 1.0, "EUCLIDEAN", 1.0

    def numpy_voronoi():
        out = np.empty(n)
        for s in range(0, n, voronoi.CHUNK):
            part = tuple(c[s:s + voronoi.CHUNK] for c in p)
            out[s:s + voronoi.CHUNK] = voronoi.voronoi_f1(voronoi.Lattice(part), P)[0]
        return out
    t_np, vref = _cpu(numpy_voronoi)
    t_nb, _ = _cpu(lambda: voronoi_f1_3(p[0], p[1], p[2], 1.0, vout))
    rows["Voronoi F1 3D"] = dict(numpy_us=1e6 * t_np / n, numba_us=1e6 * t_nb / n, speedup=t_np / t_nb,
                                 max_diff=float(np.max(np.abs(vout - vref))), compile_s=compile_vor)
    print(f"numba {numba.__version__}, {n} points, one thread")
    print("| kernel | NumPy us/point | Numba us/point | speed-up | max |diff| | first-call compile s |")
    print("|---|---|---|---|---|---|")
    for k, r in rows.items():
        print(f"| {k} | {r['numpy_us']:.3f} | {r['numba_us']:.3f} | {r['speedup']:.1f}x | {r['max_diff']:.2e} | "
              f"{r['compile_s']:.2f} |")
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(dict(numba=numba.__version__, points=n, rows=rows), indent=1))


if __name__ == "__main__":
    main()
