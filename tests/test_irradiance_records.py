"""Irradiance-cache records (engine/integrators/irradiance/hemisphere.py): gather directions, E,
the harmonic-mean radius, the rotational and translational gradients, and extrapolation.

Every reference here is analytic and written in this file, independently of the module:
- a uniformly emitting spherical cap (what an on-axis disk or a bright patch of sky looks like)
  tilted by beta: E = pi L sin^2(alpha) cos(beta), grad_r E = pi L sin^2(alpha) (n x c);
- an emitting half-space of directions (an infinite emitting plane seen at a tilt):
  E = pi L (1 + cos beta) / 2, grad_r E = (pi L / 2) (n x c);
- a parallel emitting disk of radius a at height d, its axis at lateral distance c: the view
  factor F = (1 - (d^2 + c^2 - a^2) / sqrt((d^2 + c^2 + a^2)^2 - 4 a^2 c^2)) / 2, dF/dc =
  -4 a^2 d^2 c / (...)^(3/2) (derived here; the test checks it against finite differences);
- a ceiling at height d that emits beyond a straight edge at lateral distance s:
  F = (1 - s / sqrt(s^2 + d^2)) / 2;
- a dark disk in front of an emitting plane (the gradient must use the nearer distance).
Gradient estimators are biased for a finite M x N grid, so the tests measure the relative error
(per record, RMS over records with random azimuths of the scene) at two grids and assert that it
falls by at least half from M x N = 8 x 16 to 32 x 64 and stays below a stated bound there (the
bounds leave a margin of about 1.5-2x over these seeds' errors, which are in
bench/results/icache/code_choices.md).

Deliberate bugs these tests catch (checked by patching the module one at a time): dropping the
j = 1 row of the translational gradient (as Mitsuba 0.6's loop does), a sign flip of the
rotational gradient, the cell-start azimuth instead of the cell centre (rotational or
translational), the translational gradient's v vectors at the centre, max instead of min
distance, the column neighbour on the wrong side, cos instead of cos^2, tan(theta) at the row
start, directions linear in sin(theta), directions at cell centres only, 2 pi instead of pi in E,
a radius that counts only the rays that hit, a reversed tilt in extrapolation, a transposed frame.
Seeded; statistical tests share a family-wise level of 0.01 per test (Sidak).
"""
import numpy as np
import pytest
from scipy import stats as st
from scipy.integrate import trapezoid

from ember.engine import sampling
from ember.engine.integrators.irradiance import hemisphere as H

from stats import ChiSquareTest, Hemisphere, sidak_alpha

LE = np.array([1.0, 0.5, 2.0])  # emitted radiance per channel (three channels, three scales)
Z = np.array([0.0, 0.0, 1.0])


def _directions(R, M, N, seed):
    rng = np.random.default_rng(seed)
    return H.cell_directions(M, N, rng.random((R, M, N, 2))), rng.random(R) * 2.0 * np.pi


def _axis(beta, psi):
    """(R, 3) unit vectors at polar angle beta, azimuths psi (R,)."""
    return np.stack([np.sin(beta) * np.cos(psi), np.sin(beta) * np.sin(psi),
                     np.cos(beta) * np.ones_like(psi)], axis=-1)


def _rel_error(est, ref):
    """RMS over records and channels of |est - ref| / |ref| (vectors on the last axis)."""
    per = np.linalg.norm(est - ref, axis=-1) / np.linalg.norm(ref, axis=-1)
    return float(np.sqrt(np.mean(per ** 2)))


# ----------------------------------------------------------------------------------------------
# Analytic scenes (record at the origin, normal +z, in its local frame)

def cap_scene(w, psi, beta, alpha):
    """Cap of half-angle alpha around c at tilt beta: L (R,M,N,3), grad_r (R,3,3), E (3,)."""
    c = _axis(beta, psi)
    L = (np.einsum("rmnx,rx->rmn", w, c) > np.cos(alpha))[..., None] * LE
    grad = np.pi * np.sin(alpha) ** 2 * np.cross(Z, c)[:, None, :] * LE[None, :, None]
    return L, grad, np.pi * np.sin(alpha) ** 2 * np.cos(beta) * LE


def halfspace_scene(w, psi, beta):
    """Everything with w . c > 0 emits (c at tilt beta): L, grad_r."""
    c = _axis(beta, psi)
    L = (np.einsum("rmnx,rx->rmn", w, c) > 0.0)[..., None] * LE
    return L, 0.5 * np.pi * np.cross(Z, c)[:, None, :] * LE[None, :, None]


def disk_view_factor(c, a, d):
    return 0.5 * (1.0 - (d * d + c * c - a * a) / np.sqrt((d * d + c * c + a * a) ** 2 - 4 * a * a * c * c))


def disk_view_factor_dc(c, a, d):
    return -4.0 * a * a * d * d * c / ((d * d + c * c + a * a) ** 2 - 4 * a * a * c * c) ** 1.5


def disk_scene(w, psi, c, a, d, plane_behind=None):
    """Emitting disk (radius a, height d, axis at distance c toward azimuth psi), background
    escaping (r = inf, L = 0): L, r, grad_t. With plane_behind = d2 the disk is dark instead and
    an emitting plane at height d2 > d fills the rest of the hemisphere."""
    t = d / w[..., 2]
    centre = np.stack([c * np.cos(psi), c * np.sin(psi)], axis=-1)[:, None, None, :]
    on = np.sum((t[..., None] * w[..., :2] - centre) ** 2, axis=-1) < a * a
    e = np.stack([np.cos(psi), np.sin(psi), np.zeros_like(psi)], axis=-1)
    grad = (-np.pi * disk_view_factor_dc(c, a, d) * e)[:, None, :] * LE[None, :, None]
    if plane_behind is None:
        return on[..., None] * LE, np.where(on, t, np.inf), grad
    return (~on)[..., None] * LE, np.where(on, t, plane_behind / w[..., 2]), -grad


def halfplane_scene(w, psi, s, d):
    """Ceiling at height d emitting where x . e > s (e toward azimuth psi), dark elsewhere."""
    t = d / w[..., 2]
    e = np.stack([np.cos(psi), np.sin(psi), np.zeros_like(psi)], axis=-1)
    on = t * np.einsum("rmnx,rx->rmn", w, e) > s
    grad = (0.5 * np.pi * d * d / (s * s + d * d) ** 1.5 * e)[:, None, :] * LE[None, :, None]
    return on[..., None] * LE, t, grad


# ----------------------------------------------------------------------------------------------
# Directions

def _cells_of(w, M, N):
    sin2 = 1.0 - w[..., 2] ** 2
    phi = np.mod(np.arctan2(w[..., 1], w[..., 0]), 2.0 * np.pi)
    return np.floor(sin2 * M).astype(int), np.floor(phi * N / (2.0 * np.pi)).astype(int)


@pytest.mark.parametrize("M,N", [(1, 1), (3, 5), (7, 13), (14, 28)])
def test_exactly_one_direction_per_cell(M, N):
    R = 64
    w, _ = _directions(R, M, N, seed=11)
    assert w.shape == (R, M, N, 3)
    np.testing.assert_allclose(np.linalg.norm(w, axis=-1), 1.0, atol=1e-12)
    assert np.all(w[..., 2] > 0.0)
    j, k = _cells_of(w, M, N)
    np.testing.assert_array_equal(j, np.broadcast_to(np.arange(M)[:, None], (R, M, N)))
    np.testing.assert_array_equal(k, np.broadcast_to(np.arange(N)[None, :], (R, M, N)))
    # The extreme uniforms stay in (or on the edge of) their cell and above the horizon.
    for edge in (0.0, 1.0):
        we = H.cell_directions(M, N, np.full((1, M, N, 2), edge))
        assert np.all(we[..., 2] > 0.0) and np.all(np.isfinite(we))


def test_directions_are_cosine_distributed():
    """Chi-square of (cos theta, phi) against cos(theta)/pi on a grid not aligned with the cells.
    One direction per record, from a randomly chosen cell, so the samples are independent."""
    R = 20_000
    grids = [(4, 6), (9, 12)]
    for i, (M, N) in enumerate(grids):
        def sampler(u, M=M, N=N):
            # u[:, :2] choose the cell, u[:, 2:] the direction in it (the other cells' are unused).
            j, k = np.minimum((u[:, 0] * M).astype(int), M - 1), np.minimum((u[:, 1] * N).astype(int), N - 1)
            u_cells = np.zeros((R, M, N, 2))
            u_cells[np.arange(R), j, k] = u[:, 2:]
            return H.cell_directions(M, N, u_cells)[np.arange(R), j, k]

        ChiSquareTest(Hemisphere(), sampler, lambda d: d[:, 2] / np.pi, (10, 7), R, seed=20 + i, sample_dim=4,
                      name=f"{M} x {N} cells").check(n_tests=len(grids))


# ----------------------------------------------------------------------------------------------
# Irradiance and radius

def test_constant_radiance_gives_pi_L_exactly():
    rng = np.random.default_rng(3)
    L = np.broadcast_to(np.array([0.7, 1.3, 0.0]), (5, 6, 11, 3))
    E = H.irradiance(L)
    np.testing.assert_allclose(E, np.broadcast_to(np.pi * np.array([0.7, 1.3, 0.0]), (5, 3)), rtol=1e-14)
    assert H.irradiance(rng.random((2, 4, 4, 3))).shape == (2, 3)


def test_irradiance_of_cos_power_and_of_a_bright_cap():
    """Unbiased: means over records match the analytic values (z-tests, Sidak over 5 cases)."""
    R, M, N = 400, 8, 16
    w, psi = _directions(R, M, N, seed=5)
    cases = []
    for m in (0.5, 1.0, 2.0, 5.0):  # L = cos^m theta: E = 2 pi / (m + 2)
        cases.append((H.irradiance((w[..., 2] ** m)[..., None])[:, 0], 2.0 * np.pi / (m + 2.0)))
    # A sky bright only above the elevation 90 deg - alpha, sin^2 alpha = 0.3 (inside row 2).
    alpha = np.arcsin(np.sqrt(0.3))
    L, _, E = cap_scene(w, psi, 0.0, alpha)
    cases.append((H.irradiance(L)[:, 2], E[2]))
    level = sidak_alpha(0.01, len(cases))
    for est, exact in cases:
        z = (est.mean() - exact) / (est.std(ddof=1) / np.sqrt(R))
        assert 2.0 * st.norm.sf(abs(z)) > level, (est.mean(), exact)
        assert abs(est.mean() - exact) < 0.01 * exact  # and the scale is right, not only the noise
    # A cap whose edge lies on a row boundary (sin^2 alpha = 3/8 with M = 8) is integrated exactly.
    L, _, E = cap_scene(w, psi, 0.0, np.arcsin(np.sqrt(3.0 / 8.0)))
    np.testing.assert_allclose(H.irradiance(L), np.broadcast_to(E, (R, 3)), rtol=1e-12)


def test_harmonic_radius_exact_and_inf_handling():
    R, M, N = 4, 5, 7
    j, k = np.meshgrid(np.arange(M), np.arange(N), indexing="ij")
    scale = np.array([0.5, 1.0, 2.0, 10.0])
    r = scale[:, None, None] / (1.0 + j + 2.0 * k)[None]
    np.testing.assert_allclose(H.harmonic_radius(r), scale * M * N / np.sum(1.0 + j + 2.0 * k), rtol=1e-14)
    rng = np.random.default_rng(9)
    rr = rng.uniform(0.1, 5.0, (6, M, N))
    np.testing.assert_allclose(H.harmonic_radius(rr), st.hmean(rr.reshape(6, -1), axis=1), rtol=1e-12)
    # Escaped rays count in M N and add 0 to the sum; all escaped gives inf; a zero distance 0.
    r_inf = rr.copy()
    r_inf[0, :, ::2] = np.inf
    r_inf[1] = np.inf
    r_inf[2, 0, 0] = 0.0
    got = H.harmonic_radius(r_inf)
    finite = np.isfinite(r_inf[0])
    assert got[0] == pytest.approx(M * N / np.sum(1.0 / r_inf[0][finite]), rel=1e-14)
    assert got[1] == np.inf and got[2] == 0.0
    np.testing.assert_allclose(got[3:], st.hmean(rr[3:].reshape(3, -1), axis=1), rtol=1e-12)


def test_radius_in_front_of_a_plane_is_three_halves_of_its_distance():
    """r = d / cos theta: d / R = mean of cos theta over the cosine density = 2/3 (unbiased)."""
    R, M, N, d = 200, 10, 20, 0.8
    w, _ = _directions(R, M, N, seed=13)
    ratio = d / H.harmonic_radius(d / w[..., 2])
    assert abs(ratio.mean() - 2.0 / 3.0) < 4.0 * ratio.std(ddof=1) / np.sqrt(R) + 1e-12


# ----------------------------------------------------------------------------------------------
# Rotational gradient

def test_references_match_finite_differences():
    """The closed forms used as references below, against central differences of E."""
    h = 1e-5
    alpha, beta = 0.5, 0.6
    E = lambda b: np.pi * np.sin(alpha) ** 2 * np.cos(b)  # noqa: E731  cap, fully above the horizon
    exact = np.pi * np.sin(alpha) ** 2 * np.sin(beta)
    assert (E(beta - h) - E(beta + h)) / (2 * h) == pytest.approx(exact, rel=1e-8)
    E = lambda b: np.pi * (1.0 + np.cos(b)) / 2.0  # noqa: E731  half-space
    assert (E(beta - h) - E(beta + h)) / (2 * h) == pytest.approx(0.5 * np.pi * np.sin(beta), rel=1e-8)
    for c, a, d in [(0.5, 0.6, 1.0), (0.2, 0.3, 1.0), (1.5, 0.4, 0.7)]:
        fd = (disk_view_factor(c + h, a, d) - disk_view_factor(c - h, a, d)) / (2 * h)
        assert fd == pytest.approx(disk_view_factor_dc(c, a, d), rel=1e-7)
    assert disk_view_factor(0.0, 0.6, 1.0) == pytest.approx(0.36 / 1.36, rel=1e-14)
    F = lambda s, d: 0.5 * (1.0 - s / np.sqrt(s * s + d * d))  # noqa: E731  half-plane
    s, d = 0.3, 1.0
    exact = 0.5 * d * d / (s * s + d * d) ** 1.5
    assert (F(s - h, d) - F(s + h, d)) / (2 * h) == pytest.approx(exact, rel=1e-8)
    # And the half-plane's view factor by quadrature of cos(theta) / pi over the emitting part.
    x, y = np.meshgrid(np.linspace(s, 400, 4001), np.linspace(-400, 400, 4001), indexing="ij")
    g = d * d / (np.pi * (x * x + y * y + d * d) ** 2)
    quad = trapezoid(trapezoid(g, y[0], axis=1), x[:, 0])
    assert quad == pytest.approx(F(s, d), abs=2e-3)


def test_gradients_vanish_for_uniform_radiance():
    """A closed enclosure of uniform radiance: every gradient is 0, whatever the distances."""
    rng = np.random.default_rng(2)
    R, M, N = 8, 7, 12
    L = np.broadcast_to(LE, (R, M, N, 3))
    r = rng.uniform(0.1, 3.0, (R, M, N))
    np.testing.assert_allclose(H.rotational_gradient(L, M, N), 0.0, atol=1e-13)
    assert np.all(H.translational_gradient(L, r, M, N) == 0.0)
    # A distant environment (every ray escaped) has no translational gradient either.
    assert np.all(H.translational_gradient(rng.random((R, M, N, 3)), np.full((R, M, N), np.inf), M, N) == 0.0)


ROT_BOUNDS = {"cap": 0.03, "halfspace": 0.16}  # at 32 x 64


@pytest.mark.parametrize("beta", [0.3, 0.6, 0.9])
def test_rotational_gradient_of_a_tilted_cap(beta):
    alpha, R = 0.5, 200
    errors = {}
    for M, N in [(8, 16), (32, 64)]:
        w, psi = _directions(R, M, N, seed=100 + M)
        L, grad, _ = cap_scene(w, psi, beta, alpha)
        est = H.rotational_gradient(L, M, N)
        assert np.all(est[..., 2] == 0.0)
        errors[M] = _rel_error(est, grad)
    assert errors[32] < 0.5 * errors[8], errors
    assert errors[32] < ROT_BOUNDS["cap"], errors


def test_rotational_gradient_of_an_emitting_half_space():
    """The lit region reaches the horizon, where tan(theta) at the row centres underestimates
    the last row (the error falls only like 1 / sqrt(M)); still halves from 8 x 16 to 32 x 64."""
    R = 200
    errors = {}
    for M, N in [(8, 16), (32, 64)]:
        w, psi = _directions(R, M, N, seed=200 + M)
        L, grad = halfspace_scene(w, psi, 0.8)
        errors[M] = _rel_error(H.rotational_gradient(L, M, N), grad)
    assert errors[32] < 0.5 * errors[8], errors
    assert errors[32] < ROT_BOUNDS["halfspace"], errors


# ----------------------------------------------------------------------------------------------
# Translational gradient

TRANS_CASES = {
    # name: (scene builder, bound on the RMS relative error at 32 x 64)
    "disk": (lambda w, psi: disk_scene(w, psi, c=0.5, a=0.6, d=1.0), 0.15),
    "disk_near_zenith": (lambda w, psi: disk_scene(w, psi, c=0.25, a=0.35, d=1.0), 0.5),
    "halfplane": (lambda w, psi: halfplane_scene(w, psi, s=0.3, d=1.0), 0.018),
    "occluder": (lambda w, psi: disk_scene(w, psi, c=0.5, a=0.6, d=0.5, plane_behind=2.0), 0.015),
}


@pytest.mark.parametrize("name", list(TRANS_CASES))
def test_translational_gradient_against_analytic_derivative(name):
    scene, bound = TRANS_CASES[name]
    R = 200
    errors = {}
    for M, N in [(8, 16), (32, 64)]:
        w, psi = _directions(R, M, N, seed=300 + M)
        L, r, grad = scene(w, psi)
        est = H.translational_gradient(L, r, M, N)
        assert np.all(est[..., 2] == 0.0)
        errors[M] = _rel_error(est, grad)
    assert errors[32] < 0.5 * errors[8], errors
    assert errors[32] < bound, errors


def _signed_angle(est, ref):
    """Angle (R, C) from ref to est around +z, in (-pi, pi]."""
    cross = ref[..., 0] * est[..., 1] - ref[..., 1] * est[..., 0]
    return np.arctan2(cross, np.sum(ref * est, axis=-1))


def test_gradients_have_no_systematic_rotation():
    """The grid is mirror-symmetric about every cell centre and boundary azimuth and the scenes'
    azimuths are uniform, so a correct estimator points, on average over records, along the true
    gradient. Tangent vectors at the wrong azimuth (cell start instead of centre) rotate it by up
    to pi / N. z-test of the mean signed angle at 8 x 16 (Sidak over the cases)."""
    R, M, N = 400, 8, 16
    w, psi = _directions(R, M, N, seed=500)
    cases = []
    L, grad, _ = cap_scene(w, psi, 0.6, 0.5)
    cases.append(("rotational cap", H.rotational_gradient(L, M, N), grad))
    L, grad = halfspace_scene(w, psi, 0.8)
    cases.append(("rotational half-space", H.rotational_gradient(L, M, N), grad))
    for name in ("disk", "halfplane", "occluder"):
        L, r, grad = TRANS_CASES[name][0](w, psi)
        cases.append((name, H.translational_gradient(L, r, M, N), grad))
    level = sidak_alpha(0.01, len(cases))
    for name, est, ref in cases:
        angle = _signed_angle(est, ref)[:, 0]
        z = angle.mean() / (angle.std(ddof=1) / np.sqrt(R))
        assert 2.0 * st.norm.sf(abs(z)) > level, (name, angle.mean())
        assert abs(angle.mean()) < 0.1 * np.pi / N, (name, angle.mean())


# ----------------------------------------------------------------------------------------------
# World space and extrapolation

def _world_frames(R, seed):
    n = np.random.default_rng(seed).normal(size=(R, 3))
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    t, b = sampling.frame_from_z(n)
    return t, b, n


def test_extrapolation_with_analytic_gradients_is_second_order():
    """Local-frame gradients of closed-form scenes, turned into world space and applied by
    `extrapolate` to tilted normals and shifted points of records in random world frames: the
    error against the closed form is O(h^2), while E_i alone is off by O(h)."""
    R, h = 50, 0.02
    rng = np.random.default_rng(17)
    frame = _world_frames(R, 18)
    t, b, n_i = frame
    p_i = rng.normal(size=(R, 3))
    psi = rng.random(R) * 2.0 * np.pi
    # Rotation: a cap (alpha = 0.5 at tilt 0.6): E(n) = K n . c, K = pi L sin^2 alpha.
    alpha, beta = 0.5, 0.6
    c_local = _axis(beta, psi)
    c = sampling.to_world(c_local, t, b, n_i)
    K = np.pi * np.sin(alpha) ** 2 * LE
    E_i = K * np.cos(beta)
    grad_r = K[None, :, None] * np.cross(Z, c_local)[:, None, :]
    m = np.cross(n_i, rng.normal(size=(R, 3)))
    m /= np.linalg.norm(m, axis=-1, keepdims=True)      # a random tangent direction
    n = np.cos(h) * n_i + np.sin(h) * m
    exact = K * np.sum(n * c, axis=-1, keepdims=True)
    got = H.extrapolate(E_i, grad_r, np.zeros_like(grad_r), p_i, n_i, p_i, n, frame=frame)
    assert np.max(np.abs(got - exact) / K) <= 0.5 * h * h * (1 + 1e-9)
    assert np.max(np.abs(E_i - exact) / K) > 10 * 0.5 * h * h  # the test can tell
    world = H.gradient_to_world(grad_r, frame)
    np.testing.assert_allclose(H.extrapolate(E_i, world, 0 * world, p_i, n_i, p_i, n), got, rtol=1e-12)
    np.testing.assert_allclose(np.einsum("rcx,rx->rc", world, n_i), 0.0, atol=1e-12)
    # Translation: a ceiling at height d emitting beyond an edge at distance s along e.
    s, d = 0.3, 1.0
    e_local = np.stack([np.cos(psi), np.sin(psi), np.zeros(R)], axis=-1)
    e = sampling.to_world(e_local, t, b, n_i)
    F = lambda x: 0.5 * (1.0 - x / np.sqrt(x * x + d * d))  # noqa: E731
    grad_t = (np.pi * 0.5 * d * d / (s * s + d * d) ** 1.5 * LE)[None, :, None] * e_local[:, None, :]
    shift = h * (np.cos(1.0) * e + np.sin(1.0) * np.cross(n_i, e))   # partly along the edge
    exact = np.pi * LE * F(s - np.sum(shift * e, axis=-1, keepdims=True))
    got = H.extrapolate(np.pi * LE * F(s) * np.ones((R, 1)), 0 * grad_t, grad_t, p_i, n_i, p_i + shift, n_i,
                        frame=frame)
    assert np.max(np.abs(got - exact) / (np.pi * LE)) <= 0.5 * h * h  # |F''| <= 1 / d^3
    assert np.max(np.abs(np.pi * LE * F(s) - exact) / (np.pi * LE)) > 10 * 0.5 * h * h


def test_extrapolate_clamps_and_broadcasts():
    E = np.array([1.0, 0.2, 0.5])
    grad_t = np.zeros((3, 3))
    grad_t[:, 0] = [1.0, 1.0, -1.0]
    p = np.array([[0.0, 0, 0], [0.5, 0, 0], [-1.0, 0, 0], [2.0, 3.0, 0]])
    got = H.extrapolate(E, np.zeros((3, 3)), grad_t, np.zeros(3), Z, p, Z)
    assert got.shape == (4, 3)
    np.testing.assert_allclose(got, [[1.0, 0.2, 0.5], [1.5, 0.7, 0.0], [0.0, 0.0, 1.5], [3.0, 2.2, 0.0]])
    assert np.all(got >= 0.0)


def test_estimated_gradients_improve_extrapolation_in_world_space():
    """The whole chain: directions turned into world space, radiance and distances of a scene
    built in world space, gradients estimated (32 x 64), turned back into world space and
    applied. Extrapolated changes of E match the closed form within 5 % of the change."""
    R, M, N, h = 100, 32, 64, 0.05
    rng = np.random.default_rng(23)
    frame = _world_frames(R, 24)
    t, b, n_i = frame
    p_i = rng.normal(size=(R, 3))
    w_local = H.cell_directions(M, N, rng.random((R, M, N, 2)))
    w = sampling.to_world(w_local, t[:, None, None], b[:, None, None], n_i[:, None, None])
    # A ceiling parallel to each record's tangent plane at height d, emitting where
    # (x - p_i) . e > s for a world direction e in that plane (the half-plane scene in world space).
    d, s = 1.0, 0.3
    e = np.cross(n_i, rng.normal(size=(R, 3)))
    e /= np.linalg.norm(e, axis=-1, keepdims=True)
    dist = d / np.einsum("rmnx,rx->rmn", w, n_i)
    on = dist * np.einsum("rmnx,rx->rmn", w, e) > s
    L = on[..., None] * LE
    E_i, _, grad_r, grad_t = H.record_terms(L, dist)
    F = lambda x: 0.5 * (1.0 - x / np.sqrt(x * x + d * d))  # noqa: E731
    for direction in (e, np.cross(n_i, e), (e + np.cross(n_i, e)) / np.sqrt(2.0)):
        shift = h * direction
        change = np.pi * LE * (F(s - np.sum(shift * e, axis=-1, keepdims=True)) - F(s))
        got = H.extrapolate(E_i, grad_r, grad_t, p_i, n_i, p_i + shift, n_i, frame=frame) - E_i
        scale = h * np.pi * LE * 0.5 * d * d / (s * s + d * d) ** 1.5   # |change| along e
        assert np.sqrt(np.mean(((got - change) / scale) ** 2)) < 0.05
