"""Anisotropic microfacet reflection (engine/bsdf/anisotropic.py through the microfacet lobe):
GGX, Multiscatter GGX and Beckmann with alpha_x = alpha / s along a tangent and alpha_y = alpha
s across it, as Cycles' Glossy, Metallic and Principled BSDFs make them.

Without Blender: the lobe's samples against its pdf (chi-square, Sidak over the cases) and the
pdf's integral against the share of samples it keeps; the distributions normalised (int D cos
= 1, and the visible normals' density integrates to 1); reciprocity of the single-scattering
lobes; the white furnace (F = 1: single scattering at most 1, Multiscatter the single one
divided by Cycles' E at the roughness (alpha_x alpha_y)^(1/4)); the anisotropic formulas at
alpha_x = alpha_y equal to the isotropic ones, and a tangent turned by 90 degrees equal to the
inverse aspect. With Blender (marked blender): an anisotropic metal sphere (a linked tangent
and the default one, rotated), Glossy and Principled, against Cycles within noise.
"""
import numpy as np
import pytest

from ember.engine.bsdf import anisotropic, beckmann, lobes, microfacet, multiscatter
from ember.engine.bsdf.lobes import inputs
from ember.engine.scene import (DIST_BECKMANN, DIST_GGX, DIST_MULTI_GGX, FRESNEL_F82, FRESNEL_NONE, LOBE_MICROFACET,
                                MAT_NODES, Materials)

from stats import ChiSquareTest, Hemisphere, Sphere, integrate

N_CHI2 = 100_000


def _spec(r, dist=DIST_GGX, **kw):
    return dict(dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_NONE, color=(1.0, 1.0, 1.0), roughness=r,
                     distribution=dist), **kw)


# name: (lobe, aspect s, tangent azimuth (degrees), wo polar angle, wo azimuth (degrees))
CASES = {
    "ggx_s2_r0.4": (_spec(0.4), 2.0, 30.0, 40.0, 60.0),
    "ggx_s0.3_r0.6_grazing": (_spec(0.6), 0.3, -20.0, 75.0, 10.0),
    "ggx_f82_s1.6_r0.3": (_spec(0.3, fresnel=FRESNEL_F82, color=(0.9, 0.6, 0.3), tint=(0.8, 0.9, 1.0)), 1.6, 110.0,
                          55.0, 200.0),
    "multi_ggx_s2.5_r0.7": (_spec(0.7, DIST_MULTI_GGX), 2.5, 45.0, 30.0, 0.0),
    "beckmann_s2_r0.4": (_spec(0.4, DIST_BECKMANN), 2.0, 70.0, 45.0, 100.0),
    "beckmann_s0.5_r0.6": (_spec(0.6, DIST_BECKMANN), 0.5, 0.0, 65.0, 30.0),
}


def _direction(theta, phi):
    t, f = np.radians(theta), np.radians(phi)
    return np.array([np.sin(t) * np.cos(f), np.sin(t) * np.sin(f), np.cos(t)])


def make(spec, k, aspect, azimuth):
    """(lobe, parameters of k rows with the aspect and the tangent at `azimuth` degrees in the
    local frame, as the closure gives them)."""
    m = Materials.make([dict(kind=MAT_NODES, lobes=[spec])])
    lobe = lobes.LOBES[spec["kind"]]
    a = np.radians(azimuth)
    tangent = np.tile([np.cos(a), np.sin(a), 0.3], (k, 1))  # off the plane: only its projection counts
    frame = (np.tile([1.0, 0.0, 0.0], (k, 1)), np.tile([0.0, 1.0, 0.0], (k, 1)))
    has = np.ones(k, bool)
    src = inputs.Sources(None, {"aspect": (np.full(k, float(aspect)), has), "tangent": (tangent, has)}, frame)
    return lobe, lobe.parameters(m, np.zeros(k, np.int64), np.arange(k), src, np.zeros(k, bool))


def _case(name, k):
    spec, aspect, azimuth, theta, phi = CASES[name]
    lobe, p = make(spec, k, aspect, azimuth)
    return lobe, p, np.tile(_direction(theta, phi), (k, 1))


def test_aspect_makes_the_rows_anisotropic():
    _, p, _ = _case("ggx_s2_r0.4", 4)
    np.testing.assert_allclose(p.alpha, 0.16 / 2.0)
    np.testing.assert_allclose(p.alpha_y, 0.16 * 2.0)
    np.testing.assert_allclose(p.roughness, 0.4)  # (ax ay)^(1/4)
    np.testing.assert_allclose(p.azimuth, np.tile([np.cos(np.radians(30)), np.sin(np.radians(30))], (4, 1)))
    _, q = make(_spec(0.9), 2, 3.0, 0.0)  # alpha_y clamped to 1 (Cycles' setup)
    assert q.alpha_y[0] == 1.0 and q.roughness[0] == pytest.approx((0.81 / 3.0) ** 0.25)


def _chi2(name, seed):
    lobe, p, wo = _case(name, N_CHI2)

    def sampler(u):
        s = lobe.sample(p, wo, u[:, :2], u[:, 2])
        return s.wi, s.pdf > 0

    def pdf(d):
        lobe_d, q, wo_d = _case(name, len(d))
        return lobe_d.pdf(q, wo_d, d)

    return ChiSquareTest(Sphere(), sampler, pdf, resolution=(40, 30), n_samples=N_CHI2, seed=seed, sample_dim=3,
                         order=6, name=name)


@pytest.mark.parametrize("name", list(CASES))
def test_anisotropic_samples_follow_the_pdf_chi2(name):
    _chi2(name, 7 + list(CASES).index(name)).check(n_tests=len(CASES))


@pytest.mark.parametrize("name", list(CASES))
def test_anisotropic_pdf_integrates_to_the_share_kept_and_evals(name):
    test = _chi2(name, 200 + list(CASES).index(name))
    _, kept = test.draw()
    share = kept.mean()
    integral = integrate(Sphere(), test.pdf, (160, 120), order=6).sum()
    assert abs(integral - share) < 4 * np.sqrt(share * (1 - share) / N_CHI2) + 1e-4, (integral, share)
    lobe, p, wo = _case(name, 4096)
    rng = np.random.default_rng(3)
    s = lobe.sample(p, wo, rng.random((4096, 2)), rng.random(4096))
    ok = s.pdf > 0
    f, pdf = lobe.eval(p.take(np.flatnonzero(ok)), wo[ok], s.wi[ok])
    np.testing.assert_allclose(pdf, s.pdf[ok], rtol=1e-9)
    assert np.all(f > 0)


@pytest.mark.parametrize("dist", [anisotropic.GGX_ANISO, anisotropic.BECKMANN_ANISO])
@pytest.mark.parametrize("ax, ay", [(0.1, 0.4), (0.5, 0.2), (0.3, 0.3)])
def test_distributions_are_normalised(dist, ax, ay):
    """int D(h) cos_h dh = 1, and (GGX) the visible normals' density G1(wo) (wo.h)+ D / wo.z
    integrates to 1 (the Lambda that makes it so is the one the pdf uses)."""
    def a(n):
        return np.tile([ax, ay, 1.0, 0.0], (n, 1))
    total = integrate(Hemisphere(), lambda h: dist.D(a(len(h)), h) * h[:, 2], (200, 200), order=6).sum()
    assert total == pytest.approx(1.0, abs=2e-3)
    wo = _direction(60.0, 35.0)

    def visible(h):
        w = np.tile(wo, (len(h), 1))
        g1 = 1.0 / (1.0 + dist.Lambda(a(len(h)), w))
        return g1 * np.maximum(h @ wo, 0.0) * dist.D(a(len(h)), h) / wo[2]
    if dist is anisotropic.GGX_ANISO:  # exact for GGX; Cycles' Beckmann Lambda is a fit
        assert integrate(Hemisphere(), visible, (200, 200), order=6).sum() == pytest.approx(1.0, abs=2e-3)


@pytest.mark.parametrize("name", ["ggx_s2_r0.4", "ggx_s0.3_r0.6_grazing", "beckmann_s2_r0.4"])
def test_single_scattering_is_reciprocal(name):
    lobe, p, _ = _case(name, 2000)
    rng = np.random.default_rng(5)
    wo = np.stack([rng.normal(size=2000), rng.normal(size=2000), np.abs(rng.normal(size=2000))], 1)
    wi = np.stack([rng.normal(size=2000), rng.normal(size=2000), np.abs(rng.normal(size=2000))], 1)
    wo, wi = wo / np.linalg.norm(wo, axis=1, keepdims=True), wi / np.linalg.norm(wi, axis=1, keepdims=True)
    f1, _ = lobe.eval(p, wo, wi)
    f2, _ = lobe.eval(p, wi, wo)
    np.testing.assert_allclose(f1, f2, rtol=1e-10)
    assert np.mean(f1[:, 0] > 1e-3) > 0.1  # not vacuous (Beckmann falls off fast)


def _albedo(lobe, p, wo, n):
    rng = np.random.default_rng(17)
    s = lobe.sample(p, wo, rng.random((n, 2)), rng.random(n))
    ok = s.pdf > 0
    f, _ = lobe.eval(p, wo, s.wi)
    w = np.where(ok[:, None], f * np.abs(s.wi[:, 2:3]) / np.where(ok, s.pdf, 1.0)[:, None], 0.0)
    return w[:, 0].mean(), w[:, 0].std() / np.sqrt(n)


@pytest.mark.parametrize("r, aspect", [(0.4, 2.0), (0.8, 0.4), (1.0, 1.8)])
def test_white_furnace(r, aspect):
    """F = 1: single-scattering anisotropic GGX reflects at most all light; Multiscatter GGX is
    it times Cycles' 1 / E(roughness (ax ay)^(1/4), cos_o), the same samples (so exactly)."""
    n = 100_000
    for theta in (0.0, 50.0, 80.0):
        wo = np.tile(_direction(theta, 25.0), (n, 1))
        lobe, p = make(_spec(r), n, aspect, 15.0)
        single, se = _albedo(lobe, p, wo, n)
        assert single < 1.0 + 3 * se
        lobe, q = make(_spec(r, DIST_MULTI_GGX), n, aspect, 15.0)
        multi, _ = _albedo(lobe, q, wo, n)
        E = multiscatter.E(q.roughness[:1], [np.cos(np.radians(theta))])[0]
        assert multi == pytest.approx(single / E, rel=1e-9)


def test_equal_alphas_are_the_isotropic_formulas():
    rng = np.random.default_rng(9)
    n = 1000
    wo = np.stack([rng.normal(size=n), rng.normal(size=n), np.abs(rng.normal(size=n))], 1)
    wi = np.stack([rng.normal(size=n), rng.normal(size=n), np.abs(rng.normal(size=n))], 1)
    wo, wi = wo / np.linalg.norm(wo, axis=1, keepdims=True), wi / np.linalg.norm(wi, axis=1, keepdims=True)
    alpha = rng.uniform(0.05, 1.0, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    a = np.stack([alpha, alpha, np.cos(phi), np.sin(phi)], 1)
    F = np.ones((n, 3))
    for aniso, iso in ((anisotropic.GGX_ANISO, microfacet), (anisotropic.BECKMANN_ANISO, beckmann)):
        np.testing.assert_allclose(aniso.eval_reflection(a, wo, wi, F), iso.eval_reflection(alpha, wo, wi, F), rtol=1e-9)
        np.testing.assert_allclose(aniso.pdf_reflection(a, wo, wi), iso.pdf_reflection(alpha, wo, wi), rtol=1e-9)


def test_a_quarter_turn_is_the_inverse_aspect():
    rng = np.random.default_rng(2)
    n = 500
    wo = np.stack([rng.normal(size=n), rng.normal(size=n), np.abs(rng.normal(size=n))], 1)
    wi = np.stack([rng.normal(size=n), rng.normal(size=n), np.abs(rng.normal(size=n))], 1)
    wo, wi = wo / np.linalg.norm(wo, axis=1, keepdims=True), wi / np.linalg.norm(wi, axis=1, keepdims=True)
    lobe, p = make(_spec(0.5), n, 2.5, 20.0)
    _, q = make(_spec(0.5), n, 1 / 2.5, 110.0)
    np.testing.assert_allclose(lobe.eval(p, wo, wi)[0], lobe.eval(q, wo, wi)[0], rtol=1e-9)
    assert not np.allclose(lobe.eval(p, wo, wi)[0], lobe.eval(make(_spec(0.5), n, 2.5, 110.0)[1], wo, wi)[0])


# ---------------------------------------------------------------- with Blender

GOLD = (1.0, 0.78, 0.34, 1.0)
METALLIC = "ShaderNodeBsdfMetallic"
SPHERES = [
    dict(name="metal_default_tangent", kind=METALLIC, Roughness=0.35, Anisotropy=0.8, **{"Base Color": GOLD}),
    dict(name="metal_rotated", kind=METALLIC, Roughness=0.35, Anisotropy=0.8, Rotation=0.2, **{"Base Color": GOLD}),
    dict(name="metal_linked_tangent", kind=METALLIC, Roughness=0.35, Anisotropy=0.8, **{"Base Color": GOLD},
         links=[("ShaderNodeTangent", "Tangent", "Tangent", dict(direction_type="RADIAL", axis="X"))]),
    dict(name="glossy_negative", kind="ShaderNodeBsdfAnisotropic", Roughness=0.4, Anisotropy=-0.7,
         Color=(0.8, 0.8, 0.8, 1.0)),
    dict(name="principled_specular", kind="ShaderNodeBsdfPrincipled", Roughness=0.3, Anisotropic=0.9,
         **{"Base Color": (0.1, 0.2, 0.5, 1.0)}),
    dict(name="beckmann_metal", kind=METALLIC, Roughness=0.4, Anisotropy=0.7, distribution="BECKMANN",
         **{"Base Color": (0.95, 0.64, 0.54, 1.0)}),
]
RUNS, SAMPLES, TOL = 6, 128, 0.01


@pytest.mark.blender
def test_anisotropic_spheres_render_as_cycles():
    """Anisotropic Metallic (the default tangent, rotated, a linked Tangent node; Beckmann),
    Glossy (negative anisotropy) and Principled spheres under an area light: each quadrant of
    each sphere, per channel, within 1 % plus the noise band of Cycles' (Multiscatter GGX,
    Blender's default, where not said)."""
    import feature_spheres as fs
    fs.spheres_agree_with_cycles(SPHERES, SAMPLES, RUNS, TOL)
