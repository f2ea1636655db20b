"""Phase functions behind the lobe interface (engine/bsdf/lobes/): Henyey-Greenstein against
its definition and Cycles' convention (cos between the propagation directions -wo and wi,
g > 0 forward), normalisation, chi-square of its samples over (cos theta, phi) around the
forward direction for g from -0.99 to 0.99, eval = pdf (exact importance sampling), and the
mean cosine g. Seeded; the chi-square cases share a family-wise level of 0.01 (Sidak)."""
import numpy as np
import pytest

from ember.engine import sampling
from ember.engine.bsdf.lobes import PHASE_FUNCTIONS
from ember.engine.bsdf.lobes.henyey_greenstein import MAX_G, HenyeyGreenstein

from stats import ChiSquareTest, Sphere

HG = HenyeyGreenstein()
G_VALUES = (-0.99, -0.7, -0.2, 0.0, 0.3, 0.8, 0.99)
N = 200_000
WO = np.array([0.3, -0.5, 0.81]) / np.linalg.norm([0.3, -0.5, 0.81])  # toward the previous vertex


def _cycles_phase(cos, g):
    """Cycles' phase_henyey_greenstein as printed (kernel/closure/volume_util.h)."""
    return (1 - g * g) / (4 * np.pi * (1 + g * (g - 2 * cos)) ** 1.5)


def _cos_edges():
    """Cells over cos in [-1, 1], geometric toward both poles (where |g| ~ 1 puts its peak)."""
    m = np.geomspace(1e-6, 1.0, 20)
    return np.concatenate([[-1.0], -1.0 + m, 1.0 - m[::-1][1:], [1.0]])


def _forward_frame():
    forward = -WO[None]
    t, b = sampling.frame_from_z(forward)
    return t[0], b[0], forward[0]


def _directions(cos, phi):
    t, b, z = _forward_frame()
    sin = np.sqrt(np.maximum(0.0, 1.0 - cos * cos))
    return (sin * np.cos(phi))[:, None] * t + (sin * np.sin(phi))[:, None] * b + cos[:, None] * z


def test_is_a_phase_function_of_the_table():
    assert any(isinstance(p, HenyeyGreenstein) for p in PHASE_FUNCTIONS)


@pytest.mark.parametrize("g", G_VALUES)
def test_pdf_integrates_to_one(g):
    """2 pi times the integral over cos of p, composite Gauss-Legendre on cells that resolve
    the peak."""
    edges = _cos_edges()
    x, w = np.polynomial.legendre.leggauss(24)
    lo, hi = edges[:-1, None], edges[1:, None]
    cos = (lo + (hi - lo) * 0.5 * (x + 1)).ravel()
    weights = ((hi - lo) * 0.5 * w).ravel()
    p = HG.parameters(np.full(len(cos), g))
    pdf = HG.pdf(p, np.tile(WO, (len(cos), 1)), _directions(cos, np.zeros(len(cos))))
    np.testing.assert_allclose(2 * np.pi * np.sum(pdf * weights), 1.0, rtol=1e-9)


@pytest.mark.parametrize("g", G_VALUES)
def test_eval_is_the_pdf_and_cycles_formula(g):
    rng = np.random.default_rng(3)
    k = 1000
    d = rng.normal(size=(k, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    p = HG.parameters(np.full(k, g))
    wo = np.tile(WO, (k, 1))
    f, pdf = HG.eval(p, wo, d)
    np.testing.assert_array_equal(f, np.repeat(pdf[:, None], 3, axis=1))
    np.testing.assert_array_equal(HG.pdf(p, wo, d), pdf)
    np.testing.assert_allclose(pdf, _cycles_phase(d @ -WO, g), rtol=1e-10)
    np.testing.assert_array_equal(HG.albedo(p, wo), 1.0)
    s = HG.sample(p, wo, rng.random((k, 2)), rng.random(k))
    np.testing.assert_allclose(s.pdf, HG.pdf(p, wo, s.wi), rtol=1e-9)
    assert not np.any(s.delta) and s.weight is None and np.all(s.pdf > 0)


@pytest.mark.parametrize("g", G_VALUES)
def test_samples_follow_the_pdf_chi2(g):
    """The sampled directions over (cos theta, phi) about the forward direction -wo, against
    the pdf integrated over the same cells (geometric toward the poles, where |g| ~ 1 peaks)."""
    t, b, z = _forward_frame()

    def sampler(u):
        s = HG.sample(HG.parameters(np.full(len(u), g)), np.tile(WO, (len(u), 1)), u[:, :2], u[:, 2])
        np.testing.assert_allclose(np.linalg.norm(s.wi, axis=1), 1.0, rtol=1e-12)
        return s.wi

    def pdf(d):
        return HG.pdf(HG.parameters(np.full(len(d), g)), np.tile(WO, (len(d), 1)), d)

    test = ChiSquareTest(Sphere(frame=np.stack([t, b, z])), sampler, pdf, resolution=(_cos_edges(), 8),
                         n_samples=N, seed=int(1000 * (g + 1)), sample_dim=3, order=8, name=f"g = {g}")
    test.check(n_tests=len(G_VALUES))


@pytest.mark.parametrize("g", G_VALUES)
def test_mean_cosine_is_g(g):
    """E[cos(-wo, wi)] = g: g > 0 scatters forward (Cycles' sign)."""
    rng = np.random.default_rng(5)
    p = HG.parameters(np.full(N, g))
    s = HG.sample(p, np.tile(WO, (N, 1)), rng.random((N, 2)), rng.random(N))
    cos = s.wi @ -WO
    assert abs(cos.mean() - g) < 4 * cos.std() / np.sqrt(N) + 1e-12


def test_g_is_clamped_as_cycles():
    p = HG.parameters(np.array([-1.0, -0.5, 0.0, 0.9995, 1.0]))
    np.testing.assert_array_equal(p.g, [-MAX_G, -0.5, 0.0, MAX_G, MAX_G])
    # The extreme samples stay finite and unit (u at 0 and just below 1).
    u = np.array([[0.0, 0.0], [sampling.ONE_MINUS_EPSILON, 0.5], [0.5, sampling.ONE_MINUS_EPSILON]])
    for g in (-MAX_G, 0.0, MAX_G):
        q = HG.parameters(np.full(3, g))
        s = HG.sample(q, np.tile(WO, (3, 1)), u, np.zeros(3))
        assert np.all(np.isfinite(s.wi)) and np.all(np.isfinite(s.pdf)) and np.all(s.pdf > 0)
        np.testing.assert_allclose(np.linalg.norm(s.wi, axis=1), 1.0, rtol=1e-12)
