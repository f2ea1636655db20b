"""Photon map: density estimates against known irradiance, wrong-side rejection, BSDF weighting,
fixed-radius gathering, memory, radiance photons (engine/integrators/photon/photon_map.py).

The statistical tests use the exact unbiasedness of the (k-1)/(pi r^2) form on a uniform density
(module docstring): estimates at query points whose neighbourhoods do not overlap are
independent, so their mean is z-tested with the sample variance, Sidak-corrected.
"""
import sys
import tracemalloc

import numpy as np
import pytest
from scipy import stats as scipy_stats

from ember.engine.integrators.photon import photon_map as pm
from ember.engine.integrators.photon.photon_map import (KERNELS, PhotonMap, RadiancePhotons,
                                                        decode_octahedral, encode_octahedral)
from stats import sidak_alpha

UP = np.array([0.0, 0.0, 1.0])
ALPHA = 1e-3


def _plane(xy, z=0.0):
    return np.column_stack([xy, np.full(len(xy), z)])


def _hemisphere(rng, m, sign=1.0):
    """m cosine-distributed unit directions around sign * z."""
    u = rng.random((m, 2))
    r, phi = np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), sign * np.sqrt(1 - u[:, 0])])


def _map(rng, xy, flux, n_emitted, z=0.0, sign=1.0):
    m = len(xy)
    return PhotonMap(_plane(xy, z), _hemisphere(rng, m, sign), np.broadcast_to(flux, (m, 3)),
                     np.tile(sign * UP, (m, 1)), n_emitted)


def _grid(lo, hi, step, z=0.0):
    g = np.arange(lo, hi + 1e-9, step)
    x, y = np.meshgrid(g, g)
    return _plane(np.column_stack([x.ravel(), y.ravel()]), z)


def _z_test_mean(samples, expected, n_tests):
    """Two-sided p-value that mean(samples) == expected, honest sample variance."""
    samples = np.asarray(samples, dtype=np.float64)
    se = samples.std(ddof=1) / np.sqrt(len(samples))
    z = (samples.mean() - expected) / se
    p = 2 * scipy_stats.norm.sf(abs(z))
    assert p > sidak_alpha(ALPHA, n_tests), (
        f"mean {samples.mean():.5g} vs expected {expected:.5g} (rel {samples.mean() / expected - 1:+.4f}, "
        f"z = {z:.2f})")


# ----------------------------------------------------------------------------------------------
# Encoding

def test_octahedral_round_trip():
    rng = np.random.default_rng(1)
    v = rng.normal(size=(200_000, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    axes = np.vstack([np.eye(3), -np.eye(3), [[1, 1, -1], [-1, -1, -1]] / np.sqrt(3)])
    v = np.vstack([v, axes])
    d = decode_octahedral(encode_octahedral(v)).astype(np.float64)
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-6)
    angle = np.arcsin(np.clip(np.linalg.norm(np.cross(d, v), axis=1), 0, 1))  # exact near 0
    assert angle.max() < 1e-4
    assert np.all(np.sum(d * v, axis=1) > 0.99)


def test_pack_keeps_each_photon_together_in_morton_order():
    rng = np.random.default_rng(2)
    m = 10_000
    p, wi, flux = rng.random((m, 3)) * [4, 1, 1] - 2, _hemisphere(rng, m), rng.random((m, 3))
    n = -_hemisphere(rng, m)
    order = pm.morton_order(p)
    assert np.array_equal(np.sort(order), np.arange(m))
    # neighbours in memory are neighbours in space: the mean step is a small fraction of a
    # random pair's (sorting on a 64^2 grid in x, y only would not pass)
    step = np.linalg.norm(np.diff(p[order], axis=0), axis=1).mean()
    assert step < 0.1 * np.linalg.norm(p[1:] - p[:-1], axis=1).mean()
    arrays = PhotonMap.pack(p, wi, flux, n)
    assert np.array_equal(arrays["position"], p[order].astype(np.float32))
    assert np.array_equal(arrays["flux"], flux[order].astype(np.float32))
    assert np.allclose(decode_octahedral(arrays["wi"]), wi[order], atol=1e-4)
    assert np.allclose(decode_octahedral(arrays["normal"]), n[order], atol=1e-4)


# ----------------------------------------------------------------------------------------------
# Uniform density with known irradiance

M_UNIFORM = 100_000
FLUX = np.array([0.7, 1.3, 2.0])
N_EMITTED = 3 * M_UNIFORM  # most paths stored nothing here: the estimate must use N_e
E_UNIFORM = M_UNIFORM * FLUX / N_EMITTED  # W/m^2 on the unit square
K = 50
R_KNN = np.sqrt(K / (np.pi * M_UNIFORM))


@pytest.fixture(scope="module")
def uniform_maps():
    return [_map(np.random.default_rng(100 + s), np.random.default_rng(200 + s).random((M_UNIFORM, 2)),
                 FLUX, N_EMITTED) for s in range(4)]


@pytest.mark.parametrize("kernel", KERNELS)
@pytest.mark.parametrize("regime", ["k_nearest", "r_max"])
def test_uniform_density_irradiance(uniform_maps, kernel, regime):
    """E on a uniform density: the k-NN form (k-th photon sets r) and the fixed r_max form
    (fewer than k inside) are unbiased for every kernel; each channel z-tested."""
    # Query spacing > 2 r: disjoint neighbourhoods, independent estimates
    if regime == "k_nearest":
        k, r_max, step = K, 10 * R_KNN, 2.2 * R_KNN
    else:
        k, r_max, step = 10 * K, 1.5 * R_KNN, 3.3 * R_KNN  # ~112 photons expected inside
    q = _grid(0.05, 0.95, step)
    n = np.tile(UP, (len(q), 1))
    estimates, radii = [], []
    for photon_map in uniform_maps:
        E, r = photon_map.irradiance(q, n, k, r_max, kernel=kernel)
        estimates.append(E)
        radii.append(r)
    E, r = np.vstack(estimates), np.concatenate(radii)
    assert len(E) > 1500
    if regime == "r_max":
        assert np.all(r == r_max)
    else:
        assert np.all(r < r_max) and np.all(r > 0.3 * R_KNN)
    for ch in range(3):
        _z_test_mean(E[:, ch], E_UNIFORM[ch], n_tests=3 * 2 * len(KERNELS))


@pytest.fixture(scope="module")
def uniform_maps_with_radii(uniform_maps):
    for photon_map in uniform_maps:
        photon_map.set_photon_radii(K, 10 * R_KNN)
    return uniform_maps


@pytest.mark.parametrize("kernel", KERNELS)
def test_uniform_density_irradiance_of_photon_radii(uniform_maps_with_radii, kernel):
    """The sample-point form (each photon's own k-nearest radius, the caustic map's) is
    unbiased on a uniform density too, for every kernel; each channel z-tested."""
    q = _grid(0.05, 0.95, 2.2 * R_KNN)
    n = np.tile(UP, (len(q), 1))
    estimates = [m.radiance_scattered(q, n, None, kernel=kernel) for m in uniform_maps_with_radii]
    E = np.vstack(estimates)
    for ch in range(3):
        _z_test_mean(E[:, ch], E_UNIFORM[ch], n_tests=3 * len(KERNELS))


def test_uniform_density_radius_and_min_count(uniform_maps):
    photon_map = uniform_maps[0]
    q = _grid(0.1, 0.9, 0.1)
    n = np.tile(UP, (len(q), 1))
    E, r = photon_map.irradiance(q, n, K, np.inf)
    # r = distance to the k-th photon, checked by brute force
    d = np.linalg.norm(photon_map.position[None, :, :2] - q[:, None, :2], axis=2)
    assert np.allclose(r, np.sort(d, axis=1)[:, K - 1], rtol=1e-5)
    # fewer photons than min_count inside r_max (~8 expected): zero, else the Poisson form
    r_max = 0.4 * R_KNN
    E, r = photon_map.irradiance(q, n, K, r_max, min_count=8)
    count = np.sum(d < r_max, axis=1)
    assert np.sum(count < 8) > 10 and np.sum(count >= 8) > 10
    assert np.all(E[count < 8] == 0.0)
    assert np.allclose(E[count >= 8], count[count >= 8, None] * FLUX / N_EMITTED / (np.pi * r_max ** 2))


def test_convergence_on_gradient():
    """Density ~ (1 + x)^2: relative RMS error falls as photons grow (k ~ sqrt(M), so both the
    variance ~1/k and the curvature bias ~ k/M fall), at the noise floor of each level."""
    rng = np.random.default_rng(7)
    q = np.column_stack([0.15 + 0.7 * rng.random((3000, 2)), np.zeros(3000)])
    n = np.tile(UP, (len(q), 1))
    flux, n_e = np.ones(3), 1_000_000
    errors = []
    levels = [(8_000, 16), (32_000, 32), (128_000, 64), (512_000, 128)]
    for m, k in levels:
        u = rng.random((m, 2))
        xy = np.column_stack([np.cbrt(1 + 7 * u[:, 0]) - 1, u[:, 1]])  # inverse CDF of (1+x)^2 / (7/3)
        photon_map = _map(rng, xy, flux, n_e)
        E, _ = photon_map.irradiance(q, n, k, 0.2)
        E_true = m / n_e * (1 + q[:, 0]) ** 2 * 3 / 7
        errors.append(np.sqrt(np.mean((E[:, 1] / E_true - 1) ** 2)))
    errors = np.array(errors)
    slope = np.polyfit(np.log([m for m, _ in levels]), np.log(errors), 1)[0]
    assert np.all(np.diff(errors) < 0), errors
    assert slope < -0.2, (slope, errors)   # -0.25 expected
    # the noise floor of an unbiased estimate: Var[(k-1)/Gamma(k)] = 1/(k-2) relative
    noise = 1 / np.sqrt(np.array([k for _, k in levels]) - 2.0)
    assert np.all(errors < 1.15 * noise), errors / noise


# ----------------------------------------------------------------------------------------------
# Wrong side

def test_thin_wall_back_photons_contribute_nothing():
    rng = np.random.default_rng(3)
    m = 60_000
    lit = _map(rng, rng.random((m, 2)), np.ones(3), m)
    # A thin wall: lit front at z = 0 (normal +z); back face 1 mm below (normal -z) holding a
    # third of the photons. Queries on both faces, with their own normals.
    xy_back = rng.random((m // 3, 2))
    both = PhotonMap(np.vstack([lit.position, _plane(xy_back, -1e-3)]),
                     np.vstack([lit.wi(np.arange(m)), _hemisphere(rng, m // 3, -1.0)]),
                     np.ones((m + m // 3, 3)),
                     np.vstack([np.tile(UP, (m, 1)), np.tile(-UP, (m // 3, 1))]), m)
    q = _grid(0.05, 0.95, 0.025)
    up, down = np.tile(UP, (len(q), 1)), np.tile(-UP, (len(q), 1))
    # the dark side of the lit-only wall stays exactly dark
    E_back, _ = lit.irradiance(q - [0, 0, 1e-3], down, K, 0.1)
    assert np.all(E_back == 0.0)
    # with both faces holding photons each face sees only its own density (z-tests)
    r_knn = np.sqrt(K / (np.pi * (m + m // 3)))
    q = _grid(0.05, 0.95, 2.2 * r_knn)
    up, down = np.tile(UP, (len(q), 1)), np.tile(-UP, (len(q), 1))
    E_front, _ = both.irradiance(q, up, K, 0.1)
    E_back, _ = both.irradiance(q - [0, 0, 1e-3], down, K, 0.1)
    _z_test_mean(E_front[:, 0], 1.0, n_tests=2)
    _z_test_mean(E_back[:, 0], (m // 3) / m, n_tests=2)


def test_rejects_incident_direction_below_and_perpendicular_normals():
    rng = np.random.default_rng(4)
    m = 5_000
    xy = rng.random((m, 2))
    q = _grid(0.2, 0.8, 0.2)
    n = np.tile(UP, (len(q), 1))
    below = PhotonMap(_plane(xy), _hemisphere(rng, m, -1.0), np.ones((m, 3)), np.tile(UP, (m, 1)), m)
    assert np.all(below.irradiance(q, n, K, 0.2)[0] == 0.0)  # wi . n <= 0
    side = np.tile([1.0, 0.0, 0.0], (m, 1))  # a perpendicular wall's photons near a corner
    perpendicular = PhotonMap(_plane(xy), _hemisphere(rng, m), np.ones((m, 3)), side, m)
    assert np.all(perpendicular.irradiance(q, n, K, 0.2)[0] == 0.0)  # n_p . n = 0 < 0.1


# ----------------------------------------------------------------------------------------------
# BSDF weighting

def _brute_force_radiance(position, wi, flux, normal, n_e, q, nq, f, k, r_max, c, weight):
    """The estimator written out point by point (a reference for the vectorised one)."""
    L = np.zeros((len(q), 3))
    for i in range(len(q)):
        d2 = np.sum((position - q[i]) ** 2, axis=1)
        order = np.argsort(d2)
        inside = order[d2[order] < r_max ** 2][:k]
        if len(inside) == k:
            r2, inside = d2[inside[-1]], inside[:-1]
        else:
            r2 = r_max ** 2
        keep = inside[(normal[inside] @ nq[i] > 0.1) & (wi[inside] @ nq[i] > 0)]
        if len(keep) < 8:
            continue
        w = weight(d2[keep] / r2)[:, None] / (c * np.pi * r2)
        L[i] = np.sum(f(np.full(len(keep), i), wi[keep]) * flux[keep] * w, axis=0) / n_e
    return L


@pytest.mark.parametrize("kernel", KERNELS)
def test_direction_dependent_bsdf_matches_brute_force(kernel, monkeypatch):
    """f uses each photon's own wi and the query row it is called with; small chunks so rows
    cross chunk boundaries."""
    monkeypatch.setattr(pm, "_CHUNK_PAIRS", 7 * 20)
    rng = np.random.default_rng(5)
    m = 3_000
    position = np.column_stack([rng.random((m, 2)), 0.01 * rng.random(m)])
    wi = _hemisphere(rng, m)
    flux = rng.random((m, 3))
    normal = np.tile(UP, (m, 1))
    normal[::7] = -UP  # some wrong-side photons
    photon_map = PhotonMap(position, wi, flux, normal, 5 * m)
    q = _plane(0.1 + 0.8 * rng.random((40, 2)), 0.005)
    nq = np.tile(UP, (len(q), 1))
    gain = 1.0 + np.arange(len(q)) % 3

    def f(rows, w):  # a direction- and point-dependent BSDF value (K,3)
        return np.column_stack([gain[rows] * (1 + w[:, 0]), w[:, 2] ** 2, np.abs(w[:, 1])]) / np.pi

    L, _ = photon_map.radiance(q, nq, f, 20, 0.2, kernel=kernel)
    weight, c = pm._kernel(kernel)
    ref = _brute_force_radiance(position, wi, flux, normal, 5 * m, q, nq, f, 20, 0.2, c,
                                weight or (lambda t: np.ones_like(t)))
    assert np.all(ref[:, 0] > 0)
    assert np.allclose(L, ref, rtol=2e-4, atol=0)


def test_lambertian_radiance_is_albedo_over_pi_times_irradiance(uniform_maps):
    photon_map = uniform_maps[1]
    q = _grid(0.1, 0.9, 0.05)
    n = np.tile(UP, (len(q), 1))
    albedo = np.array([0.2, 0.5, 0.8])
    E, r_e = photon_map.irradiance(q, n, K, 0.1)
    L, r_l = photon_map.radiance(q, n, lambda rows, wi: np.broadcast_to(albedo / np.pi, (len(rows), 3)), K, 0.1)
    assert np.all(E > 0)
    assert np.array_equal(r_e, r_l)
    assert np.allclose(L, albedo / np.pi * E, rtol=1e-12)


# ----------------------------------------------------------------------------------------------
# Fixed-radius gathering (progressive photon mapping)

def test_gather_radius_counts_only_accepted_photons():
    rng = np.random.default_rng(6)
    m = 20_000
    position = _plane(rng.random((m, 2)))
    wi = _hemisphere(rng, m)
    normal = np.tile(UP, (m, 1))
    normal[::5] = -UP                         # wrong side
    wi[1::5, 2] *= -1                         # incident from below
    flux = rng.random((m, 3))
    photon_map = PhotonMap(position, wi, flux, normal, m)
    q = _plane(0.2 + 0.6 * rng.random((300, 2)))
    nq = np.tile(UP, (len(q), 1))
    r = np.exp(rng.uniform(np.log(0.003), np.log(0.08), len(q)))  # 0.5 to ~400 photons: k grows

    def f(rows, w):  # zero for photons arriving from x < 0
        return np.where(w[:, :1] > 0, 1.0 + rows[:, None] % 2, 0.0) * np.ones((1, 3))

    for bsdf in (None, f):
        total, count = photon_map.gather_radius(q, nq, r, bsdf)
        d2 = np.sum((position[None] - q[:, None]) ** 2, axis=2)
        ok = (d2 < r[:, None] ** 2) & (normal @ UP > 0.1)[None] & (wi @ UP > 0)[None]
        ref = np.einsum("qm,mc->qc", ok, flux)
        if bsdf is not None:
            ok &= (wi[:, 0] > 0)[None]
            ref = np.einsum("qm,mc->qc", ok, flux) * (1.0 + np.arange(len(q)) % 2)[:, None]
        assert np.array_equal(count, ok.sum(axis=1))
        assert count.min() == 0 and np.sum(d2 < r[:, None] ** 2, axis=1).max() > 130  # k = 512 used
        assert np.allclose(total, ref, rtol=1e-5)


# ----------------------------------------------------------------------------------------------
# Memory and sharing

def test_memory_per_photon_and_no_copies():
    rng = np.random.default_rng(8)
    m = 1_000_000
    wi = _hemisphere(rng, m)
    arrays = PhotonMap.pack(rng.random((m, 3)), wi, rng.random((m, 3)), wi)
    for a in arrays.values():
        a.setflags(write=False)  # as views of shared memory
    photon_map = PhotonMap.from_packed(arrays, n_emitted=m)
    assert photon_map.nbytes / m <= 64.0
    assert photon_map.nbytes >= sum(a.nbytes for a in arrays.values()) + 4 * m
    for key, a in arrays.items():
        assert photon_map.arrays[key] is a
    # queries run in chunks: 20k points x k = 200 would be ~800 MB of temporaries at once
    q = rng.random((20_000, 3))
    tracemalloc.start()
    E, _ = photon_map.radiance(q, wi[:20_000], lambda rows, w: np.abs(w), 200, 0.2, kernel="cone")
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert np.all(np.isfinite(E)) and np.any(E > 0)
    assert peak < 100e6, peak


def test_ckdtree_fallback_gives_the_same_estimates(monkeypatch):
    rng = np.random.default_rng(13)
    photon_map = _gradient_map(rng, 20_000, 20_000)
    q = _plane(0.1 + 0.8 * rng.random((200, 2)))
    n = np.tile(UP, (len(q), 1))
    r = np.full(len(q), 0.03)
    expected = photon_map.irradiance(q, n, 20, 0.05, "cone"), photon_map.gather_radius(q, n, r)
    monkeypatch.setitem(sys.modules, "pykdtree.kdtree", None)  # import fails: scipy's cKDTree
    fallback = PhotonMap.from_packed(photon_map.arrays, photon_map.n_emitted)
    assert fallback._index.kind == "cKDTree"
    got = fallback.irradiance(q, n, 20, 0.05, "cone"), fallback.gather_radius(q, n, r)
    for a, b in zip(expected, got):
        assert np.allclose(a[0], b[0], rtol=1e-5) and np.allclose(a[1], b[1], rtol=1e-5)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the wheel's OpenMP runtime is checked on Linux")
def test_queries_can_be_held_to_one_thread():
    """Workers use every core already: the map must find pykdtree's OpenMP runtime to set one
    thread per query (else each query would start one thread per core)."""
    photon_map = PhotonMap(np.random.default_rng(0).random((100, 3)), np.tile(UP, (100, 1)),
                           np.ones((100, 3)), np.tile(UP, (100, 1)), 100)
    assert photon_map._index.kind == "pykdtree"
    assert photon_map._index._threads is not None


def test_empty_and_small_maps():
    empty = PhotonMap(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), 10)
    q, n = np.zeros((3, 3)), np.tile(UP, (3, 1))
    E, r = empty.irradiance(q, n, K, 0.5)
    assert np.all(E == 0) and np.all(r == 0.5)
    total, count = empty.gather_radius(q, n, np.full(3, 0.5))
    assert np.all(total == 0) and np.all(count == 0)
    # fewer photons than k: all of them count, r = r_max
    rng = np.random.default_rng(9)
    small = _map(rng, 0.5 + 0.01 * rng.random((20, 2)), np.ones(3), 100)
    E, r = small.irradiance(q + [0.5, 0.5, 0], n, K, 0.5)
    assert np.all(r == 0.5)
    assert np.allclose(E, 20 / 100 / (np.pi * 0.25))


# ----------------------------------------------------------------------------------------------
# Radiance photons

def _gradient_map(rng, m, n_e):
    u = rng.random((m, 2))
    xy = np.column_stack([np.cbrt(1 + 7 * u[:, 0]) - 1, u[:, 1]])
    return _map(rng, xy, np.ones(3), n_e)


def test_radiance_photons_at_own_positions_equal_full_estimate():
    rng = np.random.default_rng(10)
    photon_map = _gradient_map(rng, 100_000, 100_000)
    rp = RadiancePhotons.build(photon_map, K, 0.1, stride=4)
    assert len(rp) == 25_000
    rows = RadiancePhotons.rows(len(photon_map), 4)
    p, n = photon_map.position[rows], photon_map.normal(rows)
    E_full, _ = photon_map.irradiance(p, n, K, 0.1)
    E_rp = rp.lookup(p, n)
    assert np.allclose(E_rp, E_full, rtol=1e-6)
    packed = RadiancePhotons.from_packed(rp.arrays)
    assert np.array_equal(packed.lookup(p[:100], n[:100]), E_rp[:100])


def test_radiance_photons_error_bounded_on_smooth_density():
    """Away from radiance photons the lookup error stays within 1.3x the full estimate's (the
    nearest radiance photon's estimate is as noisy, displaced by ~half a photon spacing)."""
    rng = np.random.default_rng(11)
    m = 200_000
    photon_map = _gradient_map(rng, m, m)
    rp = RadiancePhotons.build(photon_map, K, 0.1, stride=4)
    q = _plane(0.15 + 0.7 * rng.random((5000, 2)))
    n = np.tile(UP, (len(q), 1))
    E_true = (1 + q[:, 0]) ** 2 * 3 / 7
    E_full, _ = photon_map.irradiance(q, n, K, 0.1)
    E_rp = rp.lookup(q, n)
    err_full = np.sqrt(np.mean((E_full[:, 0] / E_true - 1) ** 2))
    err_rp = np.sqrt(np.mean((E_rp[:, 0] / E_true - 1) ** 2))
    assert err_full < 0.2
    assert err_rp < 1.3 * err_full, (err_rp, err_full)
    assert abs(np.mean(E_rp[:, 0] / E_true) - 1) < 0.02


def test_radiance_photons_pick_agreeing_normals_at_a_corner():
    """Floor (z = 0, normal +z, E = 1) meets a wall (x = 0, normal +x, E = 10) at a corner: near
    the corner the nearest radiance photon is often on the wall; the lookup skips it."""
    rng = np.random.default_rng(12)
    m = 80_000
    floor = _plane(rng.random((m, 2)))
    wall = np.column_stack([np.zeros(m), rng.random((m, 2))])
    x_axis = np.array([1.0, 0.0, 0.0])
    photon_map = PhotonMap(np.vstack([floor, wall]),
                           np.vstack([_hemisphere(rng, m), _hemisphere(rng, m)[:, ::-1]]),
                           np.vstack([np.ones((m, 3)), np.full((m, 3), 10.0)]),
                           np.vstack([np.tile(UP, (m, 1)), np.tile(x_axis, (m, 1))]), m)
    rp = RadiancePhotons.build(photon_map, K, 0.05, stride=4)
    q = _plane(np.column_stack([0.002 * rng.random(2000), 0.2 + 0.6 * rng.random(2000)]))
    E, found = rp.lookup(q, np.tile(UP, (len(q), 1)), r_max=0.05, return_found=True)
    assert found.all()
    # floor values only: ~0.5 at the edge (half the disc is off the floor), never the wall's ~5
    assert np.all(E[:, 0] < 2.0) and np.all(E[:, 0] > 0.2)
    # a query with a normal nothing agrees with finds nothing
    E, found = rp.lookup(q[:10], np.tile(-UP, (10, 1)), r_max=0.05, return_found=True)
    assert not found.any() and np.all(E == 0)
