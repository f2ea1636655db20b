"""Tests of the BSDF models: Phong (engine/bsdf/phong.py), GGX (microfacet.py), dielectric
(dielectric.py) and Fresnel (fresnel.py).

Chi-square goodness of fit of every sampler against its pdf over a grid of incident angles up
to 89.9 degrees and exponents / roughnesses down to the extremes, each in coordinates that
resolve the lobe (Phong: the lobe frame with 1 - cos(alpha) rescaled by n; GGX and rough
dielectric: the half vector with tan^2(theta_h) rescaled by alpha^2). The chi-square cases
share one family-wise level of 0.01 (Sidak over CHI2_CASES); Monte Carlo albedos use 3 sigma.
All randomness is seeded.
"""
import numpy as np
import pytest

from ember.engine import sampling
from ember.engine.bsdf import dielectric, fresnel, microfacet, phong
from stats import ChiSquareTest, Discrete, Hemisphere, Mapped

N_CHI2 = 100_000
N_MC = 100_000
ANGLES = (0.0, 30.0, 60.0, 85.0, 89.9)
PHONG_N = (1.0, 10.0, 100.0, 1e4, 1e6)
GGX_ALPHA = (0.001, 0.01, 0.1, 0.5, 1.0)
DIELECTRIC_ALPHA = (0.05, 0.3, 1.0)
ETAS = (1.5, 1.0 / 1.5)
TWO_PI = 2.0 * np.pi
PHI_O = 1.0  # azimuth of wo: keeps the frames honest (nothing lines up with x)
GRID = (30, 48)  # cells of every directional fit: (polar coordinate, azimuth)


def _seed(*key):
    return [int(k * 1000) for k in key]


def _rng(*key):
    return np.random.default_rng(_seed(*key))


def _wo(theta_deg, n, phi=PHI_O):
    """n copies of the unit direction at polar angle theta_deg (degrees), azimuth phi."""
    t = np.radians(theta_deg)
    return np.tile([np.sin(t) * np.cos(phi), np.sin(t) * np.sin(phi), np.cos(t)], (n, 1))


def _unit_from_polar(cos_t, sin_t, phi):
    return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)


def _azimuth(v):
    return np.mod(np.arctan2(v[:, 1], v[:, 0]), TWO_PI)


def _rows(v, m):
    """v (3,) as m read-only rows."""
    return np.broadcast_to(v, (m, 3))


def _fit(domain, sampler, pdf, seed, resolution=GRID):
    """The chi-square test of a BSDF sampler: u (N, 3) (two for the direction, one for the
    lobe), samples of pdf 0 rejected, cells cut by the lobe's support edge (the horizon, total
    internal reflection) integrated finely."""
    return ChiSquareTest(domain, sampler, pdf, resolution, N_CHI2, seed=seed, sample_dim=3, refine=True)


# ----------------------------------------------------------------------------------------------
# Phong: glossy lobe in its own frame; mixtures over the hemisphere

def _phong_args(kd, ks, n, rows):
    return (np.broadcast_to(np.asarray(kd, float), (rows, 3)),
            np.broadcast_to(np.asarray(ks, float), (rows, 3)), np.full(rows, float(n)))


def _phong_sampler(kd, ks, n, wo):
    def sampler(u):
        wi, _, pdf = phong.sample(*_phong_args(kd, ks, n, len(u)), _rows(wo, len(u)), u[:, :2], u[:, 2])
        return wi, pdf > 0.0
    return sampler


def _phong_pdf(kd, ks, n, wo):
    return lambda wi: phong.pdf(*_phong_args(kd, ks, n, len(wi)), _rows(wo, len(wi)), wi)


def case_phong_lobe(theta, n):
    """Pure glossy lobe. Coordinates around R: s = 1 - exp(-n (1 - cos alpha)) in [0, 1 -
    exp(-2n)] and the azimuth; ds = n (1 - s) d(cos alpha), so even n = 1e6 fills the grid."""
    wo = _wo(theta, 1)[0]
    R = wo * [-1.0, -1.0, 1.0]
    t, b = (v[0] for v in sampling.frame_from_z(R[None]))

    def coordinates(wi):
        d = wi - R
        return -np.expm1(-n * 0.5 * np.sum(d * d, axis=1)), _azimuth(sampling.to_local(wi, t, b, R))

    def points(s, phi):
        one_minus_cos = -np.log1p(-s) / n
        sin_a = np.sqrt(one_minus_cos * (2.0 - one_minus_cos))
        return sampling.to_world(_unit_from_polar(1.0 - one_minus_cos, sin_a, phi), t, b, R), 1.0 / (n * (1.0 - s))

    domain = Mapped(((0.0, -np.expm1(-2.0 * n)), (0.0, TWO_PI)), coordinates, points, periodic=(False, True))
    return _fit(domain, _phong_sampler(0.0, 0.8, n, wo), _phong_pdf(0.0, 0.8, n, wo), _seed(1, theta, np.log10(n)))


def case_phong_mixture(theta, n, kd, ks):
    """Diffuse + glossy over the hemisphere in (cos theta, phi); the horizon is a cell edge."""
    wo = _wo(theta, 1)[0]
    return _fit(Hemisphere(), _phong_sampler(kd, ks, n, wo), _phong_pdf(kd, ks, n, wo),
                _seed(2, theta, n, kd[0], ks[0]))


# (theta, n, kd, ks); max(kd) + max(ks) != 1 in most, so lobe probabilities that are not
# normalised by their sum (the seed listing's pd /= pd + ps; ps /= pd + ps) would show.
PHONG_MIXTURES = (
    (0.0, 1.0, (0.5, 0.5, 0.5), (0.5, 0.5, 0.5)),
    (60.0, 10.0, (0.3, 0.15, 0.05), (0.1, 0.2, 0.15)),
    (30.0, 100.0, (0.2, 0.2, 0.2), (0.3, 0.3, 0.3)),
    (89.9, 10.0, (0.2, 0.2, 0.2), (0.7, 0.7, 0.7)),
    (85.0, 1.0, (0.6, 0.3, 0.1), (0.2, 0.4, 0.3)),
    (0.0, 100.0, (0.9, 0.0, 0.0), (0.0, 0.0, 0.05)),
)


# ----------------------------------------------------------------------------------------------
# GGX and rough dielectric: half-vector coordinates

def _half_vector_coordinates(h, alpha):
    """(v, phi_h) with v = 1 - (1 + tan^2(theta_h) / alpha^2)^(-1/4) in [0, 1).

    GGX's D cos(theta_h) is uniform in t = 1 - (1 - v)^4. The power 1/4 spreads the half
    vectors near the horizon over whole cells: a grazing wo sees facets up to 89.9 degrees,
    and refraction out of a TIR-dominated interface happens only through those. The density
    stays finite at v -> 1 (the visible-normal factor (wo.h) / cos(theta_h) ~ (1 - t)^(-1/2)
    is outweighed by dt / dv ~ (1 - v)^3), so Gauss nodes integrate it.
    """
    a = (h[:, 0] ** 2 + h[:, 1] ** 2) / (h[:, 2] ** 2 * alpha * alpha)
    return 1.0 - (1.0 + a) ** -0.25, _azimuth(h)


def _half_vector_from_coordinates(v, phi, alpha):
    """(h (M,3), d omega_h / (dv dphi) (M,)) for the coordinates above."""
    a = (1.0 - v) ** -4 - 1.0
    tan_t = alpha * np.sqrt(a)
    cos_t = 1.0 / np.sqrt(1.0 + tan_t * tan_t)
    # d omega_h = sin dtheta dphi and dv / dtheta = tan sec^2 / (2 alpha^2 (1 + a)^1.25).
    return (_unit_from_polar(cos_t, tan_t * cos_t, phi),
            2.0 * alpha ** 2 * (1.0 + a) ** 1.25 * cos_t ** 3)


def _unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def case_ggx(theta, alpha):
    wo = _wo(theta, 1)[0]

    def sampler(u):
        wi, _, pdf = microfacet.sample_reflection(np.full(len(u), alpha), _rows(wo, len(u)), u[:, :2])
        return wi, pdf > 0.0

    def points(v, phi):
        h, jac = _half_vector_from_coordinates(v, phi, alpha)
        c = h @ wo
        # d omega_i = 4 |wo . h| d omega_h for a reflection.
        return 2.0 * c[:, None] * h - wo, 4.0 * np.abs(c) * jac

    domain = Mapped(((0.0, 1.0), (0.0, TWO_PI)), lambda wi: _half_vector_coordinates(_unit(wo + wi), alpha), points,
                    periodic=(False, True))
    return _fit(domain, sampler, lambda wi: microfacet.pdf_reflection(alpha, _rows(wo, len(wi)), wi),
                _seed(3, theta, alpha))


def case_rough_dielectric(theta, alpha, eta):
    """Both lobes in one grid: x = v of the half vector for reflection, 1 + v for refraction.
    eta is the relative index seen from wo; eta < 1 puts wo inside an object of IOR 1 / eta
    (wo.z < 0, the caller's convention), so both sides of the interface are exercised."""
    inside = eta < 1.0
    eta_obj = 1.0 / eta if inside else eta
    flip = -1.0 if inside else 1.0
    wo = _wo(theta, 1)[0] * flip
    wo_up = wo * flip  # on +z, relative index eta

    def sampler(u):
        wi, _, pdf = dielectric.sample_rough(np.full(len(u), alpha), eta_obj, _rows(wo, len(u)), u[:, :2], u[:, 2])
        return wi, pdf > 0.0

    def coordinates(wi):
        wi_up = wi * flip
        reflected = wi_up[:, 2] > 0.0
        h = np.where(reflected[:, None], wo_up + wi_up, -(wo_up + eta * wi_up))
        v, phi = _half_vector_coordinates(h * np.sign(h[:, 2:3]) / np.linalg.norm(h, axis=1, keepdims=True), alpha)
        return v + np.where(reflected, 0.0, 1.0), phi

    def points(x, phi):
        refracted = x >= 1.0
        h, jac = _half_vector_from_coordinates(x - refracted, phi, alpha)
        c = h @ wo_up
        w_r = 2.0 * c[:, None] * h - wo_up
        # Snell through h; no transmission under total internal reflection.
        cos2_t = 1.0 - (1.0 - c * c) / (eta * eta)
        w_t = -wo_up / eta + (c / eta - np.sqrt(np.maximum(cos2_t, 0.0)))[:, None] * h
        # Walter et al. 2007 eq. 17: d omega_h / d omega_i = eta^2 |wi.h| / |wo + eta wi|^2.
        d = wo_up + eta * w_t
        jac_t = np.sum(d * d, axis=1) / (eta * eta * np.maximum(np.abs(np.sum(w_t * h, 1)), 1e-300))
        # A direction on the other side belongs to the other lobe (through another h).
        on_lobe_side = np.where(refracted, (w_t[:, 2] < 0.0) & (cos2_t > 0.0) & (c > 0.0), w_r[:, 2] > 0.0)
        w_i = np.where(refracted[:, None], w_t, w_r)
        return w_i * flip, np.where(on_lobe_side, np.where(refracted, jac_t, 4.0 * np.abs(c)) * jac, 0.0)

    domain = Mapped(((0.0, 2.0), (0.0, TWO_PI)), coordinates, points, periodic=(False, True))
    return _fit(domain, sampler, lambda wi: dielectric.pdf_rough(alpha, eta_obj, _rows(wo, len(wi)), wi),
                _seed(4, theta, alpha, eta), resolution=(2 * GRID[0], GRID[1]))


def case_smooth_dielectric_lobe_choice(theta, eta):
    """Fraction reflected = F: two values, 0 reflected, 1 refracted."""
    wo = _wo(theta, 1)[0]
    F = _fresnel_reference(np.cos(np.radians(theta)), eta)
    return ChiSquareTest(Discrete(2), lambda u: (~dielectric.sample_smooth(eta, _rows(wo, len(u)), u[:, 0])[3]).astype(int),
                         lambda k: np.array([F, 1.0 - F])[k], n_samples=N_CHI2, seed=_seed(5, theta, eta), sample_dim=1)


def _fresnel_reference(cos_i, eta):
    """Unpolarised Fresnel reflectance from outside, via Snell's angles (independent form)."""
    theta_i = np.arccos(cos_i)
    theta_t = np.arcsin(np.sin(theta_i) / eta)
    if theta_i == 0.0:
        return ((eta - 1.0) / (eta + 1.0)) ** 2
    r_s = np.sin(theta_i - theta_t) / np.sin(theta_i + theta_t)
    r_p = np.tan(theta_i - theta_t) / np.tan(theta_i + theta_t)
    return 0.5 * (r_s ** 2 + r_p ** 2)


CHI2_CASES = {
    **{f"phong_lobe_{th:g}deg_n{n:g}": (lambda th=th, n=n: case_phong_lobe(th, n))
       for th in ANGLES for n in PHONG_N},
    **{f"phong_mixture_{th:g}deg_n{n:g}_kd{kd[0]:g}_ks{ks[0]:g}":
       (lambda th=th, n=n, kd=kd, ks=ks: case_phong_mixture(th, n, kd, ks))
       for th, n, kd, ks in PHONG_MIXTURES},
    **{f"ggx_{th:g}deg_alpha{a:g}": (lambda th=th, a=a: case_ggx(th, a))
       for th in ANGLES for a in GGX_ALPHA},
    **{f"rough_dielectric_{th:g}deg_alpha{a:g}_eta{eta:.3g}":
       (lambda th=th, a=a, eta=eta: case_rough_dielectric(th, a, eta))
       for th in ANGLES for a in DIELECTRIC_ALPHA for eta in ETAS},
    # 1 / 1.5 beyond 41.8 degrees is total internal reflection: tested exactly below.
    **{f"smooth_dielectric_{th:g}deg_eta{eta:.3g}":
       (lambda th=th, eta=eta: case_smooth_dielectric_lobe_choice(th, eta))
       for th in ANGLES for eta in ETAS if eta > 1.0 or th < 40.0},
}


@pytest.mark.parametrize("name", list(CHI2_CASES))
def test_chi2_goodness_of_fit(name):
    CHI2_CASES[name]().check(n_tests=len(CHI2_CASES))


# ----------------------------------------------------------------------------------------------
# Sample / pdf / weight consistency, on rows that mix every parameter in one call

def _mixed_rows(seed, n_rows, params):
    """Random wo (over ANGLES, random azimuths) and one parameter per row drawn from params."""
    rng = np.random.default_rng(seed)
    theta = np.radians(rng.choice(ANGLES, n_rows))
    wo = _unit_from_polar(np.cos(theta), np.sin(theta), rng.random(n_rows) * TWO_PI)
    return rng, wo, rng.choice(np.asarray(params, float), n_rows)


def test_phong_sample_pdf_weight_agree():
    rng, wo, n = _mixed_rows(60, 40_000, PHONG_N)
    kd = rng.random((len(n), 3)) * 0.5
    ks = rng.random((len(n), 3)) * 0.5
    kd[::7] = 0.0  # pure glossy rows
    wi, weight, pdf = phong.sample(kd, ks, n, wo, rng.random((len(n), 2)), rng.random(len(n)))
    valid = pdf > 0.0
    assert valid.mean() > 0.8
    assert np.max(np.abs(np.linalg.norm(wi, axis=1) - 1.0)) < 1e-12
    np.testing.assert_allclose(phong.pdf(kd, ks, n, wo, wi)[valid], pdf[valid], rtol=1e-9)
    f = phong.eval(kd, ks, n, wo, wi)
    np.testing.assert_allclose(weight[valid], f[valid] * wi[valid, 2:3] / pdf[valid, None],
                               rtol=1e-9)
    # Under the surface: no redraw, zero contribution, zero pdf.
    assert np.all(wi[~valid, 2] <= 0.0)
    assert np.all(weight[~valid] == 0.0)


def test_phong_eval_matches_its_definition():
    rng, wo, n = _mixed_rows(61, 5_000, (1.0, 3.0, 10.0, 100.0))
    kd, ks = rng.random((len(n), 3)) * 0.5, rng.random((len(n), 3)) * 0.5
    wi = sampling.sample_uniform_hemisphere(rng.random((len(n), 2)))
    R = 2.0 * wo[:, 2:3] * np.array([0.0, 0.0, 1.0]) - wo  # 2 (n.wo) n - wo
    cos_a = np.maximum(np.sum(wi * R, axis=1), 0.0)
    expected = kd / np.pi + ks * ((n + 2.0) / TWO_PI * cos_a ** n)[:, None]
    np.testing.assert_allclose(phong.eval(kd, ks, n, wo, wi), expected, rtol=1e-12, atol=1e-15)


def test_phong_stable_lobe_at_n_1e6():
    """The sampled 1 - cos(alpha), re-measured from wi by the chord, is the exact law's.

    The chord of float64 directions carries ~1e-16 absolute error, i.e. 1e-16 / alpha relative:
    the smallest u0 here puts alpha at 1.4e-6 rad, a thousandth of the lobe width.
    """
    n = 1e6
    u0 = np.array([1e-6, 1e-3, 0.3, 0.5, 0.9, 1.0 - 1e-12])
    u = np.stack([u0, np.full(6, 0.25)], axis=1)
    wo = _wo(60.0, 6)
    wi, weight, pdf = phong.sample(np.zeros((6, 3)), np.full((6, 3), 0.5), np.full(6, n), wo, u,
                                   np.full(6, 0.5))
    d = wi - wo * [-1.0, -1.0, 1.0]
    one_minus_cos = 0.5 * np.sum(d * d, axis=1)
    np.testing.assert_allclose(one_minus_cos, -np.expm1(np.log1p(-u0) / (n + 1.0)), rtol=1e-9)
    # Glossy-only weight is ks (n + 2) / (n + 1) cos(theta_i), finite and positive.
    np.testing.assert_allclose(weight[:, 0], 0.5 * (n + 2.0) / (n + 1.0) * wi[:, 2], rtol=1e-9)


def test_ggx_sample_pdf_weight_agree():
    rng, wo, alpha = _mixed_rows(62, 40_000, GGX_ALPHA)
    wi, h, pdf = microfacet.sample_reflection(alpha, wo, rng.random((len(alpha), 2)))
    valid = pdf > 0.0
    assert valid.mean() > 0.8
    np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(h, (wo + wi) / np.linalg.norm(wo + wi, axis=1, keepdims=True),
                               atol=1e-9)
    np.testing.assert_allclose(microfacet.pdf_reflection(alpha, wo, wi)[valid], pdf[valid],
                               rtol=1e-9)
    F = rng.random((len(alpha), 3))
    f = microfacet.eval_reflection(alpha, wo, wi, F)
    weight = f[valid] * wi[valid, 2:3] / pdf[valid, None]
    # Independent Smith terms (Heitz 2014 eq. 72): f cos / pdf = F G2 / G1(wo).
    lam = lambda w: 0.5 * (np.sqrt(1.0 + alpha[valid] ** 2 * (1.0 / w[valid, 2] ** 2 - 1.0)) - 1.0)
    expected = F[valid] * ((1.0 + lam(wo)) / (1.0 + lam(wo) + lam(wi)))[:, None]
    np.testing.assert_allclose(weight, expected, rtol=1e-6)
    assert np.all(wi[~valid, 2] <= 0.0)


def test_rough_dielectric_sample_pdf_weight_agree():
    rng, wo, alpha = _mixed_rows(63, 40_000, DIELECTRIC_ALPHA + (0.001, 0.01))
    wo[::2] *= -1.0  # half the rows arrive from inside
    eta = rng.choice([1.5, 1.33, 2.4], len(alpha))
    wi, weight, pdf = dielectric.sample_rough(alpha, eta, wo, rng.random((len(alpha), 2)),
                                              rng.random(len(alpha)))
    valid = pdf > 0.0
    assert valid.mean() > 0.8
    np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(dielectric.pdf_rough(alpha, eta, wo, wi)[valid], pdf[valid],
                               rtol=1e-9)
    f = dielectric.eval_rough(alpha, eta, wo, wi)
    np.testing.assert_allclose(weight[valid], f[valid] * np.abs(wi[valid, 2:3]) / pdf[valid, None],
                               rtol=1e-9)
    assert np.all(weight[~valid] == 0.0)
    # Both lobes and both sides occur.
    crossed = np.sign(wi[valid, 2]) != np.sign(wo[valid, 2])
    assert 0.2 < crossed.mean() < 0.98


def test_smooth_dielectric_directions_and_weights():
    rng = np.random.default_rng(64)
    n = 20_000
    wo = sampling.sample_uniform_sphere(rng.random((n, 2)))  # both sides
    eta = 1.5
    wi, weight, pdf, reflected = dielectric.sample_smooth(eta, wo, rng.random(n))
    np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1.0, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(wi[reflected], wo[reflected] * [-1.0, -1.0, 1.0])
    t = ~reflected
    eta_rel = np.where(wo[t, 2] > 0.0, eta, 1.0 / eta)
    # Snell: tangential components scale by -1 / eta_rel; the normal component changes side.
    np.testing.assert_allclose(wi[t, :2], -wo[t, :2] / eta_rel[:, None], atol=1e-15)
    assert np.all(np.sign(wi[t, 2]) == -np.sign(wo[t, 2]))
    # R + T = 1: each sample carries exactly 1 once the radiance factor 1 / eta_rel^2 is removed.
    np.testing.assert_allclose(weight[reflected], 1.0, rtol=0, atol=0)
    np.testing.assert_allclose(weight[t] * (eta_rel ** 2)[:, None], 1.0, rtol=1e-15)
    F = fresnel.dielectric(wo[:, 2], eta)
    np.testing.assert_array_equal(pdf, np.where(reflected, F, 1.0 - F))


# ----------------------------------------------------------------------------------------------
# Reciprocity

def _random_pairs(seed, n):
    rng = np.random.default_rng(seed)
    a = sampling.sample_uniform_hemisphere(rng.random((n, 2)))
    b = sampling.sample_uniform_hemisphere(rng.random((n, 2)))
    return rng, a, b


def test_phong_is_reciprocal():
    rng, a, _ = _random_pairs(70, 20_000)
    n = rng.choice(np.asarray(PHONG_N), len(a))
    # Directions near the mirror of a, so that cos^n is not 0 even at n = 1e6.
    jitter = rng.normal(size=a.shape) * np.sqrt(1.0 / n)[:, None]
    b = a * [-1.0, -1.0, 1.0] + jitter
    b = b / np.linalg.norm(b, axis=1, keepdims=True)
    kd, ks = rng.random((len(a), 3)) * 0.5, rng.random((len(a), 3)) * 0.5
    f_ab, f_ba = phong.eval(kd, ks, n, a, b), phong.eval(kd, ks, n, b, a)
    assert np.mean(f_ab[:, 0] > kd[:, 0] / np.pi * (1.0 + 1e-9)) > 0.5  # the lobe is exercised
    np.testing.assert_allclose(f_ab, f_ba, rtol=1e-12)


def test_ggx_is_reciprocal():
    rng, a, b = _random_pairs(71, 20_000)
    alpha = rng.choice(np.asarray(GGX_ALPHA[1:]), len(a))
    F = np.ones((len(a), 3))
    np.testing.assert_allclose(microfacet.eval_reflection(alpha, a, b, F),
                               microfacet.eval_reflection(alpha, b, a, F), rtol=1e-12)


def test_rough_dielectric_reciprocity():
    """Reflection: f(a, b) = f(b, a). Refraction (radiance BTDF): f(b, a) = f(a, b) (n_b / n_a)^2
    with n the index on each direction's side (Veach 1997, generalised reciprocity)."""
    rng, a, b = _random_pairs(72, 20_000)
    alpha = rng.choice(np.asarray(DIELECTRIC_ALPHA), len(a))
    eta = 1.5
    for side_a in (1.0, -1.0):
        wa = a * [1.0, 1.0, side_a]
        np.testing.assert_allclose(dielectric.eval_rough(alpha, eta, wa, b * [1, 1, side_a]),
                                   dielectric.eval_rough(alpha, eta, b * [1, 1, side_a], wa),
                                   rtol=1e-9)
        wb = b * [1.0, 1.0, -side_a]
        f_ab = dielectric.eval_rough(alpha, eta, wa, wb)
        f_ba = dielectric.eval_rough(alpha, eta, wb, wa)
        assert np.mean(f_ab[:, 0] > 0.0) > 0.1
        n_a, n_b = (1.0, eta) if side_a > 0 else (eta, 1.0)
        # 1e-7: at the critical angle 1 - F -> 0 with infinite slope and amplifies rounding.
        np.testing.assert_allclose(f_ba, f_ab * (n_b / n_a) ** 2, rtol=1e-7)


# ----------------------------------------------------------------------------------------------
# White furnace: directional albedo <= 1, and the analytic value where one exists

def _mean_and_sigma(x):
    return x.mean(), x.std() / np.sqrt(len(x))


@pytest.mark.parametrize("kd, ks", [(0.0, 1.0), (0.5, 0.5), (0.2, 0.8)])
def test_phong_albedo_at_most_one(kd, ks):
    for theta in ANGLES:
        for n in PHONG_N:
            args = _phong_args(kd, ks, n, N_MC // 4)
            rng = _rng(80, kd, theta, np.log10(n))
            wo = _wo(theta, N_MC // 4)
            _, weight, _ = phong.sample(*args, wo, rng.random((N_MC // 4, 2)),
                                        rng.random(N_MC // 4))
            mean, sigma = _mean_and_sigma(weight[:, 0])
            assert mean <= 1.0 + 3.0 * sigma, (theta, n, mean)
            assert mean <= phong.albedo(*args, wo)[0, 0] + 3.0 * sigma  # albedo() bounds it


@pytest.mark.parametrize("n", PHONG_N)
def test_phong_glossy_albedo_at_normal_incidence_is_ks(n):
    """int (n + 2) / (2 pi) cos^n cos d omega = 1: the normalised lobe reflects exactly ks."""
    ks = 0.7
    args = _phong_args(0.0, ks, n, N_MC)
    rng = _rng(81, np.log10(n))
    _, weight, pdf = phong.sample(*args, _wo(0.0, N_MC), rng.random((N_MC, 2)), rng.random(N_MC))
    assert np.all(pdf > 0.0)
    mean, sigma = _mean_and_sigma(weight[:, 0])
    assert abs(mean - ks) <= 3.0 * sigma + 1e-12, (mean, sigma)
    np.testing.assert_allclose(phong.albedo(*args, _wo(0.0, N_MC))[:, 0], ks)


def _quadrature_albedo(f_cos, n_theta=600):
    """int f cos d omega over the upper hemisphere by a midpoint rule in (cos theta, phi);
    f_cos(wi (M,3)) -> (M,)."""
    c = (np.arange(n_theta) + 0.5) / n_theta
    phi = (np.arange(2 * n_theta) + 0.5) / (2 * n_theta) * TWO_PI
    C, P = (a.ravel() for a in np.meshgrid(c, phi, indexing="ij"))
    wi = _unit_from_polar(C, np.sqrt(1.0 - C * C), P)
    return f_cos(wi).sum() / n_theta * TWO_PI / (2 * n_theta)


@pytest.mark.parametrize("theta, n, kd, ks", [(60.0, 10.0, 0.0, 1.0), (89.9, 1.0, 0.0, 1.0),
                                              (85.0, 30.0, 0.2, 0.3)])
def test_phong_sampled_albedo_matches_quadrature(theta, n, kd, ks):
    """Clipped lobes (no redraw) must still estimate the true albedo."""
    rows = 200_000
    args = _phong_args(kd, ks, n, rows)
    rng = _rng(82, theta, n)
    _, weight, _ = phong.sample(*args, _wo(theta, rows), rng.random((rows, 2)), rng.random(rows))
    mean, sigma = _mean_and_sigma(weight[:, 0])
    reference = _quadrature_albedo(
        lambda wi: phong.eval(*_phong_args(kd, ks, n, len(wi)), _wo(theta, len(wi)), wi)[:, 0]
        * wi[:, 2])
    assert abs(mean - reference) <= 3.0 * sigma + 1e-3, (mean, reference, sigma)


def test_ggx_albedo_at_most_one_and_one_for_a_mirror_like_lobe():
    for theta in ANGLES:
        for alpha in GGX_ALPHA:
            rows = N_MC // 4
            wo = _wo(theta, rows)
            u = _rng(83, theta, alpha).random((rows, 2))
            wi, _, pdf = microfacet.sample_reflection(np.full(rows, alpha), wo, u)
            f = microfacet.eval_reflection(alpha, wo, wi, np.ones((rows, 3)))[:, 0]
            weight = np.divide(f * wi[:, 2], pdf, out=np.zeros(rows), where=pdf > 0.0)
            mean, sigma = _mean_and_sigma(weight)
            assert mean <= 1.0 + 3.0 * sigma, (theta, alpha, mean)
            if alpha == 0.001 and theta <= 60.0:  # alpha -> 0: a perfect mirror, albedo 1
                assert abs(mean - 1.0) <= 3.0 * sigma + 1e-5, (theta, mean, sigma)


@pytest.mark.parametrize("theta, alpha", [(0.0, 0.5), (60.0, 1.0), (85.0, 0.3)])
def test_ggx_sampled_albedo_matches_quadrature(theta, alpha):
    rows = 200_000
    wo = _wo(theta, rows)
    wi, _, pdf = microfacet.sample_reflection(np.full(rows, alpha), wo,
                                              _rng(84, theta, alpha).random((rows, 2)))
    f = microfacet.eval_reflection(alpha, wo, wi, np.ones((rows, 3)))[:, 0]
    mean, sigma = _mean_and_sigma(np.divide(f * wi[:, 2], pdf, out=np.zeros(rows), where=pdf > 0))
    reference = _quadrature_albedo(lambda wi: microfacet.eval_reflection(
        alpha, _wo(theta, len(wi)), wi, np.ones((len(wi), 3)))[:, 0] * wi[:, 2])
    assert abs(mean - reference) <= 3.0 * sigma + 1e-3, (mean, reference, sigma)


@pytest.mark.parametrize("eta", [1.5, 1.0 / 1.5])
def test_rough_dielectric_albedo_at_most_one(eta):
    """R + T (with the radiance factor removed) <= 1, and -> 1 as alpha -> 0."""
    for theta in ANGLES:
        for alpha in (0.001,) + DIELECTRIC_ALPHA:
            rows = N_MC // 4
            wo = _wo(theta, rows)
            rng = _rng(85, theta, alpha, eta)
            wi, weight, _ = dielectric.sample_rough(np.full(rows, alpha), eta, wo,
                                                    rng.random((rows, 2)), rng.random(rows))
            energy = weight[:, 0] * np.where(wi[:, 2] < 0.0, eta * eta, 1.0)
            mean, sigma = _mean_and_sigma(energy)
            assert mean <= 1.0 + 3.0 * sigma, (theta, alpha, mean)
            if alpha == 0.001 and theta <= 60.0:  # a smooth interface: R + T = 1
                assert abs(mean - 1.0) <= 3.0 * sigma + 1e-5, (theta, mean, sigma)


# ----------------------------------------------------------------------------------------------
# Microfacet distribution identities

@pytest.mark.parametrize("alpha", [1.5e-5, 0.001, 0.1, 1.0])
def test_ggx_D_is_normalised(alpha):
    """D(h) cos(theta_h) d omega_h = dt dphi / (2 pi) for t = a / (1 + a), a = tan^2 / alpha^2:
    checked pointwise, so the normalisation holds to rounding even for alpha = 1.5e-5."""
    t = np.linspace(0.0, 0.999, 1000)
    a = t / (1.0 - t)
    tan_t = alpha * np.sqrt(a)
    cos_t = 1.0 / np.sqrt(1.0 + tan_t ** 2)
    h = _unit_from_polar(cos_t, tan_t * cos_t, np.full(t.shape, 0.3))
    jacobian = 0.5 * alpha ** 2 * (1.0 + a) ** 2 * cos_t ** 3  # d omega_h / (dt dphi)
    np.testing.assert_allclose(microfacet.D(alpha, h) * cos_t * jacobian, 1.0 / TWO_PI, rtol=1e-12)


@pytest.mark.parametrize("theta, alpha", [(0.0, 0.3), (60.0, 0.1), (85.0, 1.0), (89.9, 0.5)])
def test_ggx_visible_normals_are_normalised(theta, alpha):
    """int G1(wo) max(0, wo.h) D(h) / cos_o d omega_h = 1: Smith's G1 matches D."""
    m = 400
    x, wx = np.polynomial.legendre.leggauss(m)
    v, wv = 0.5 * (x + 1.0), 0.5 * wx
    phi, wp = np.pi * (x + 1.0), np.pi * wx
    V, P = (g.ravel() for g in np.meshgrid(v, phi, indexing="ij"))
    h, jac = _half_vector_from_coordinates(V, P, alpha)
    wo = _wo(theta, len(V))
    integrand = (microfacet.G1(alpha, wo) * np.maximum(np.sum(wo * h, axis=1), 0.0)
                 * microfacet.D(alpha, h) / wo[:, 2] * jac)
    assert np.sum(integrand * np.outer(wv, wp).ravel()) == pytest.approx(1.0, abs=2e-3)


def test_roughness_mapping_and_delta_threshold():
    np.testing.assert_allclose(microfacet.alpha_from_roughness([0.0, 0.5, 1.0, 2.0]),
                               [0.0, 0.25, 1.0, 1.0])
    # Cycles: alpha^2 <= 2e-10, i.e. roughness <= 2e-10^(1/4) = 0.00376.
    delta = microfacet.is_delta(microfacet.alpha_from_roughness([0.0, 0.0037, 0.0038, 0.1]))
    np.testing.assert_array_equal(delta, [True, True, False, False])
    np.testing.assert_array_equal(dielectric.is_delta(np.array([0.1, 0.1, 0.0]),
                                                      np.array([1.5, 1.00005, 1.5])),
                                  [False, True, True])


# ----------------------------------------------------------------------------------------------
# Fresnel

def test_dielectric_fresnel_against_snell_form():
    cos_i = np.cos(np.radians(np.linspace(0.0, 89.9, 200)))
    for eta in (1.5, 1.33, 2.4, 1.0 / 1.5):
        expected = [_fresnel_reference(c, eta) if np.sin(np.arccos(c)) < eta else 1.0
                    for c in cos_i]
        np.testing.assert_allclose(fresnel.dielectric(cos_i, eta), expected, rtol=1e-10)
    assert fresnel.dielectric(np.array([1.0]), 1.5)[0] == pytest.approx(0.04, rel=1e-15)
    # Brewster's angle: the parallel polarisation vanishes.
    cos_b = np.cos(np.arctan(1.5))
    r_s = _fresnel_reference(cos_b, 1.5) * 2.0
    assert fresnel.dielectric(np.array([cos_b]), 1.5)[0] == pytest.approx(r_s / 2.0, rel=1e-12)


def test_dielectric_fresnel_sides_tir_and_grazing():
    eta = 1.5
    cos_i = np.cos(np.radians(np.linspace(0.0, 89.0, 50)))
    F, cos_t = fresnel.dielectric_with_cos_t(cos_i, eta)
    assert np.all(cos_t < 0.0)
    # The same interface seen from inside along the refracted ray reflects the same fraction.
    F_back, cos_back = fresnel.dielectric_with_cos_t(cos_t, eta)
    np.testing.assert_allclose(F_back, F, rtol=1e-12)
    np.testing.assert_allclose(cos_back, cos_i, rtol=1e-12)
    # Beyond the critical angle (41.8 degrees) from inside: total internal reflection.
    inside = -np.cos(np.radians([42.0, 60.0, 89.9, 90.0]))
    F, cos_t = fresnel.dielectric_with_cos_t(inside, eta)
    np.testing.assert_array_equal(F, 1.0)
    np.testing.assert_array_equal(cos_t, 0.0)
    assert fresnel.dielectric(np.array([0.0, -0.0]), eta).tolist() == [1.0, 1.0]


def test_schlick_f82_and_remapped_fresnel():
    rng = np.random.default_rng(90)
    f0 = rng.random((200, 3))
    cos = rng.random(200)
    np.testing.assert_allclose(fresnel.schlick(f0, np.ones(200)), f0)
    np.testing.assert_allclose(fresnel.schlick(f0, np.zeros(200)), 1.0)
    np.testing.assert_allclose(fresnel.schlick(f0, cos), f0 + (1 - f0) * ((1 - cos) ** 5)[:, None])
    # F82-tint: white tint is plain Schlick; at cos = 1/7 it is Schlick x tint; f0 at normal.
    np.testing.assert_allclose(fresnel.f82_tint(f0, np.ones((200, 3)), cos),
                               fresnel.schlick(f0, cos), rtol=1e-12)
    tint = 0.5 + 0.5 * rng.random((200, 3))
    np.testing.assert_allclose(fresnel.f82_tint(f0, tint, np.full(200, 1.0 / 7.0)),
                               fresnel.schlick(f0, np.full(200, 1.0 / 7.0)) * tint, rtol=1e-12)
    np.testing.assert_allclose(fresnel.f82_tint(f0, tint, np.ones(200)), f0, rtol=1e-12)
    F = fresnel.f82_tint(f0, rng.random((200, 3)), cos)
    assert np.all((F >= 0.0) & (F <= 1.0))
    # Remapped dielectric: identity for f0 = F0(eta), f0 at normal incidence, f90 under TIR.
    eta = np.full(200, 1.45)
    F0 = np.repeat(fresnel.f0_from_ior(eta)[:, None], 3, axis=1)
    np.testing.assert_allclose(fresnel.dielectric_remapped(F0, cos, eta),
                               np.repeat(fresnel.dielectric(cos, eta)[:, None], 3, axis=1),
                               rtol=1e-12)
    np.testing.assert_allclose(fresnel.dielectric_remapped(f0, np.ones(200), eta), f0, atol=1e-15)
    np.testing.assert_allclose(fresnel.dielectric_remapped(f0, np.full(200, -0.1), eta, 0.8), 0.8)


# ----------------------------------------------------------------------------------------------
# Extremes: no NaN / Inf, no floating-point errors, zero where the model is zero

def test_extremes_are_finite_and_guarded():
    u = np.array([[0.0, 0.0], [0.0, 1.0 - 2 ** -53], [1.0 - 2 ** -53, 0.5], [0.5, 0.5],
                  [1e-300, 1e-300], [1.0, 1.0]])
    m = len(u)
    horizon = np.tile([np.cos(PHI_O), np.sin(PHI_O), 0.0], (m, 1))
    below = _wo(120.0, m)
    with np.errstate(divide="raise", invalid="raise", over="raise"):
        for wo in (_wo(89.9, m), _wo(0.0, m), horizon, below):
            for n in (0.0, 1.0, 1e6):
                for kd, ks in ((0.0, 1.0), (0.5, 0.5), (0.0, 0.0)):
                    args = _phong_args(kd, ks, n, m)
                    for u_lobe in (0.0, 1.0 - 2 ** -53):
                        wi, w, p = phong.sample(*args, wo, u, np.full(m, u_lobe))
                        assert np.all(np.isfinite(wi)) and np.all(np.isfinite(w))
                        assert np.all(np.isfinite(p)) and np.all((w == 0.0) | (p > 0.0)[:, None])
                        if wo[0, 2] <= 0.0 or kd + ks == 0.0:
                            assert np.all(w == 0.0) and np.all(p == 0.0)
            for alpha in (1.5e-5, 0.001, 1.0):
                a = np.full(m, alpha)
                wi, h, p = microfacet.sample_reflection(a, wo, u)
                f = microfacet.eval_reflection(a, wo, wi, np.ones((m, 3)))
                assert np.all(np.isfinite(wi)) and np.all(np.isfinite(p)) and np.all(np.isfinite(f))
                if wo[0, 2] <= 0.0:
                    assert np.all(p == 0.0) and np.all(f == 0.0)
                for eta in (1.5, 1.0 / 1.5, 1.001):
                    for side in (1.0, -1.0):
                        wo_s = wo * [1.0, 1.0, side]
                        wi, w, p = dielectric.sample_rough(a, eta, wo_s, u, np.full(m, 0.999))
                        assert np.all(np.isfinite(wi)) and np.all(np.isfinite(w))
                        assert np.all(np.isfinite(p))
                        assert np.all(np.isfinite(dielectric.eval_rough(a, eta, wo_s, wi)))
                        wi, w, p, _ = dielectric.sample_smooth(eta, wo_s, np.full(m, 0.999))
                        assert np.all(np.isfinite(wi)) and np.all(np.isfinite(w))
        # Exact zeros: alpha = 0 and directions on the horizon.
        assert np.all(microfacet.G1(0.0, horizon) == 0.0)
        assert np.all(microfacet.D(0.0, np.tile([0.0, 0.0, 1.0], (m, 1))) == 0.0)


def test_total_internal_reflection():
    """From inside glass beyond the critical angle, every sample reflects: weight 1, no NaN."""
    m = 1000
    rng = np.random.default_rng(91)
    for theta in (45.0, 60.0, 85.0, 89.9):
        wo = _wo(theta, m) * [1.0, 1.0, -1.0]
        wi, w, p, reflected = dielectric.sample_smooth(1.5, wo, rng.random(m))
        assert np.all(reflected) and np.all(p == 1.0) and np.all(w == 1.0)
        np.testing.assert_array_equal(wi, wo * [-1.0, -1.0, 1.0])
    # Rough: a half vector at normal incidence on the microfacet cannot refract beyond TIR;
    # whatever refracts through tilted facets is valid and finite.
    wo = _wo(89.9, m) * [1.0, 1.0, -1.0]
    wi, w, p = dielectric.sample_rough(np.full(m, 0.001), 1.5, wo, rng.random((m, 2)),
                                       rng.random(m))
    assert np.all(wi[p > 0.0, 2] < 0.0)  # stays inside: reflected
    assert np.all(np.isfinite(w)) and np.all(w[p > 0.0] > 0.0)
