"""Thin-film iridescence (engine/bsdf/thin_film.py) against an independent computation: the
exact reflectance of one film (Born and Wolf's single-layer formula with complex amplitude
ratios, all orders of interference, complex indices for a conductor) at every wavelength from
380 to 780 nm, integrated against the CIE 1931 colour matching functions in Rec.709 with each
channel's function normalised to area 1 (what Cycles' table stands for); the Principled
specular's F0 scaling; the conductor Fresnel against the same formula without a film; the
lobes' samplers with a film (chi-square); glass with a film reflecting F_c and refracting
1 - F_c (a white furnace that keeps all light). With Blender (marked blender): a thin-film
Principled sphere, a physical-conductor Metallic sphere and a Refraction BSDF sphere against
Cycles within noise."""
import numpy as np
import pytest

from ember.engine.bsdf import fresnel, lobes, thin_film
from ember.engine.bsdf.lobes import inputs
from ember.engine.nodes.color import XYZ_TO_REC709, wavelength_xyz
from ember.engine.scene import (DIST_BECKMANN, DIST_GGX, FRESNEL_CONDUCTOR, FRESNEL_DIELECTRIC, FRESNEL_F82, LOBE_DIELECTRIC,
                                LOBE_MICROFACET, MAT_NODES, Materials)

from stats import ChiSquareTest, Sphere

LAMBDA = np.arange(380.0, 781.0, 1.0)


def _cos_t(n1, n2, cos1):
    """Complex cosine in medium n2 of a wave from n1 at cosine cos1 (Snell)."""
    sin2 = (n1 / n2) ** 2 * (1.0 - cos1 ** 2)
    c = np.sqrt(1.0 - sin2 + 0j)
    return np.where(c.imag < 0, -c, c)


def _amplitudes(n1, c1, n2, c2):
    r_s = (n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2)
    r_p = (n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2)
    return r_s, r_p


def spectral_reflectance(cos1, d, n_f, n_sub):
    """(L,) unpolarised reflectance of air | film (d nm, index n_f) | substrate (complex index
    n_sub (L,) or scalar) at cosine cos1, all orders: r = (r12 + r23 e^{2i beta}) / (1 + r12
    r23 e^{2i beta}), beta = 2 pi n_f d cos_2 / lambda."""
    n_sub = np.broadcast_to(np.asarray(n_sub, complex), LAMBDA.shape)
    c2 = _cos_t(1.0, n_f, cos1)
    c3 = _cos_t(n_f, n_sub, c2)
    r12 = _amplitudes(1.0, cos1, n_f, c2)
    r23 = _amplitudes(n_f, c2, n_sub, c3)
    e = np.exp(2j * (2 * np.pi * n_f * d * c2 / LAMBDA))
    R = [np.abs((a + b * e) / (1 + a * b * e)) ** 2 for a, b in zip(r12, r23)]
    return 0.5 * (R[0] + R[1])


def to_rgb(R):
    """(3,) of a spectral reflectance (L,): each Rec.709 channel's matching function normalised."""
    cmf = wavelength_xyz(LAMBDA) @ XYZ_TO_REC709.T
    return (R[:, None] * cmf).sum(0) / cmf.sum(0)


CASES = [  # (cos, thickness nm, film index, substrate)
    (1.0, 250.0, 1.33, 1.5), (0.6, 500.0, 1.33, 1.5), (0.25, 400.0, 1.8, 1.45), (0.8, 120.0, 2.2, 1.5),
    (0.9, 800.0, 1.45, 1.33), (0.5, 300.0, 1.4, 1.0), (0.7, 350.0, 1.33, 0.8)]


@pytest.mark.parametrize("cos, d, n_f, eta", CASES)
def test_film_over_a_dielectric_is_the_integrated_spectral_reflectance(cos, d, n_f, eta):
    """Within 3e-3: Cycles' sum stops after three orders and reads a 512-node table."""
    expected = np.clip(to_rgb(spectral_reflectance(cos, d, n_f, eta)), 0.0, 1.0)  # Cycles saturates
    got = thin_film.over_dielectric(np.array([cos]), np.array([d]), np.array([n_f]), np.array([eta]))[0]
    np.testing.assert_allclose(got, expected, atol=3e-3)
    # Not the plain Fresnel: the film colours it.
    assert np.ptp(expected) > 0.01 or abs(expected[0] - fresnel.dielectric(np.array([cos]), eta)[0]) > 0.01


GOLD = (np.array([0.18, 0.42, 1.37]), np.array([3.42, 2.35, 1.77]))  # n, k at about 650, 550, 450 nm


@pytest.mark.parametrize("cos, d, n_f", [(1.0, 300.0, 1.33), (0.5, 450.0, 1.5), (0.35, 200.0, 1.3)])
def test_film_over_a_conductor_is_the_integrated_spectral_reflectance(cos, d, n_f):
    """A grey conductor (one n + ik for all wavelengths) so that the spectral reference is exact.
    Where the film reflects strongly at both interfaces (grazing, a high film index), Cycles'
    three orders fall short of the exact sum by a few per cent: such cases are left out."""
    n, k = 0.6, 2.8
    expected = to_rgb(spectral_reflectance(cos, d, n_f, n + 1j * k))
    got = thin_film.over_conductor(np.array([cos]), np.array([d]), np.array([n_f]), np.full((1, 3), n),
                                   np.full((1, 3), k))[0]
    np.testing.assert_allclose(got, expected, atol=3e-3)


def test_conductor_fresnel_is_the_single_interface_formula():
    cos = np.array([1.0, 0.7, 0.3, 0.05])
    n, k = np.tile(GOLD[0], (4, 1)), np.tile(GOLD[1], (4, 1))
    for c in range(3):
        exact = [0.5 * sum(np.abs(r) ** 2 for r in _amplitudes(1.0, x, n[0, c] + 1j * k[0, c],
                                                             _cos_t(1.0, n[0, c] + 1j * k[0, c], x))) for x in cos]
        np.testing.assert_allclose(fresnel.conductor(cos, n, k)[:, c], exact, rtol=1e-9)
    # Without a film (thickness 0: the film's index falls back to the ambient one), the same.
    np.testing.assert_allclose(thin_film.over_conductor(cos, np.zeros(4), np.full(4, 1.5), n, k),
                               fresnel.conductor(cos, n, k), atol=1e-9)


def test_principled_scaling_keeps_f0_and_one():
    F = np.array([[0.04, 0.2, 1.0]])
    out = thin_film.scale_to_f0(F, np.array([[0.08, 0.08, 0.08]]), np.array([1.5]))
    np.testing.assert_allclose(out, [[0.08, 0.2 * (1 + 1 * (0.8 / 0.96)), 1.0]])


def _lobe(spec, k, inside=False):
    m = Materials.make([dict(kind=MAT_NODES, lobes=[spec])])
    lobe = lobes.LOBES[spec["kind"]]
    return lobe, lobe.parameters(m, np.zeros(k, np.int64), np.arange(k), inputs.Sources(None), np.full(k, inside))


FILM = dict(film_thickness=380.0, film_ior=1.4)
LOBE_CASES = {
    "specular": (dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_DIELECTRIC, ior=1.5, roughness=0.3, **FILM), False),
    "metal_f82": (dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_F82, color=(0.9, 0.6, 0.3), roughness=0.4, **FILM), False),
    "conductor": (dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_CONDUCTOR, color=tuple(GOLD[0]), tint=tuple(GOLD[1]),
                       roughness=0.35, **FILM), False),
    "glass_outside": (dict(kind=LOBE_DIELECTRIC, color=(1.0, 1.0, 1.0), tint=(1.0, 1.0, 1.0), roughness=0.4, ior=1.5,
                           **FILM), False),
    "glass_inside": (dict(kind=LOBE_DIELECTRIC, color=(0.9, 0.8, 1.0), tint=(1.0, 1.0, 1.0), roughness=0.4, ior=1.5,
                          **FILM), True),
    "principled_glass_tint": (dict(kind=LOBE_DIELECTRIC, fresnel=FRESNEL_DIELECTRIC, color=(1.0, 1.0, 1.0),
                                   tint=(0.2, 1.0, 1.8), roughness=0.3, ior=1.5), False),
    "refraction_only": (dict(kind=LOBE_DIELECTRIC, color=(1.0, 1.0, 1.0), tint=(0.0, 0.0, 0.0), roughness=0.3,
                             ior=1.5, refract_only=True), True),
    "glass_beckmann_inside": (dict(kind=LOBE_DIELECTRIC, color=(0.9, 0.8, 1.0), tint=(0.9, 0.8, 1.0), roughness=0.4,
                                   ior=1.5, distribution=DIST_BECKMANN), True),
    "refraction_beckmann": (dict(kind=LOBE_DIELECTRIC, color=(1.0, 1.0, 1.0), tint=(0.0, 0.0, 0.0), roughness=0.35,
                                 ior=1.45, refract_only=True, distribution=DIST_BECKMANN), False),
}
WO = np.array([np.sin(0.8) * np.cos(1.0), np.sin(0.8) * np.sin(1.0), np.cos(0.8)])


@pytest.mark.parametrize("name", list(LOBE_CASES))
def test_samples_follow_the_pdf_chi2(name):
    spec, inside = LOBE_CASES[name]
    n = 100_000

    def sampler(u):
        lobe, p = _lobe(spec, n, inside)
        s = lobe.sample(p, np.tile(WO, (n, 1)), u[:, :2], u[:, 2])
        return s.wi, s.pdf > 0

    def pdf(d):
        lobe, p = _lobe(spec, len(d), inside)
        return lobe.pdf(p, np.tile(WO, (len(d), 1)), d)

    # refine: total internal reflection cuts the refraction-only pdf off sharply, and Beckmann
    # normals (sampled from D cos, not the visible ones) where they turn away from wo
    # and a finer grid for the narrow Beckmann lobe (the pdf's integral over coarse cells falls short)
    resolution = (80, 60) if "beckmann" in name else (40, 30)
    ChiSquareTest(Sphere(), sampler, pdf, resolution=resolution, n_samples=n, seed=31 + list(LOBE_CASES).index(name),
                  sample_dim=3, order=6, refine=name.startswith("refraction") or "beckmann" in name, name=name).check(n_tests=len(LOBE_CASES))


def _albedo(spec, inside, cos, n=200_000):
    lobe, p = _lobe(spec, n, inside)
    wo = np.tile([np.sqrt(1 - cos * cos), 0.0, cos], (n, 1))
    rng = np.random.default_rng(4)
    s = lobe.sample(p, wo, rng.random((n, 2)), rng.random(n))
    ok = s.pdf > 0
    if np.all(s.delta):
        w = s.weight
    else:
        f, _ = lobe.eval(p, wo, s.wi)
        w = np.where(ok[:, None], f * np.abs(s.wi[:, 2:3]) / np.where(ok, s.pdf, 1.0)[:, None], 0.0)
    w = w * np.where(s.wi[:, 2:3] < 0, s.eta2[:, None], 1.0)  # flux, not radiance
    return w.mean(0), w.std(0) / np.sqrt(n)


@pytest.mark.parametrize("inside", [False, True])
def test_smooth_glass_with_a_film_keeps_all_light(inside):
    """A smooth white glass with a film reflects F_c and refracts 1 - F_c: all of the light
    (in flux) at any angle, and reflects F_c itself."""
    spec = dict(kind=LOBE_DIELECTRIC, color=(1.0, 1.0, 1.0), tint=(1.0, 1.0, 1.0), roughness=0.0, ior=1.5, **FILM)
    for cos in (0.95, 0.5, 0.2):
        a, se = _albedo(spec, inside, cos)
        np.testing.assert_allclose(a, 1.0, atol=1e-9 + 5 * se.max())
    lobe, p = _lobe(spec, 200_000, inside)
    wo = np.tile([0.6, 0.0, 0.8], (200_000, 1))
    s = lobe.sample(p, wo, np.full((200_000, 2), 0.5), (np.arange(200_000) + 0.5) / 200_000)
    reflected = np.where((s.wi[:, 2:3] > 0), s.weight, 0.0).mean(0)  # F_c / F with probability F
    eta = 1 / 1.5 if inside else 1.5
    film = 1.4 / 1.5 if inside else 1.4
    F_c = thin_film.over_dielectric(np.array([0.8]), np.array([380.0]), np.array([film]), np.array([eta]))[0]
    np.testing.assert_allclose(reflected, F_c, rtol=1e-3)


def test_beckmann_glass_is_walters_model_with_beckmanns_distribution():
    """The Beckmann glass lobe's f against Walter et al.'s eqs. 20-21 written here with
    beckmann.D and G2 (reflection F D G2 / (4 cos_o cos_i); refraction |wo.h wi.h| (1 - F) D G2
    / (cos_o cos_i (wo.h + eta wi.h)^2), Ember's radiance scaling 1 / eta^2): not GGX's."""
    from ember.engine.bsdf import beckmann, microfacet
    spec, inside = LOBE_CASES["glass_beckmann_inside"]
    spec = dict(spec, color=(1.0, 1.0, 1.0), tint=(1.0, 1.0, 1.0))
    n = 2000
    lobe, p = _lobe(spec, n, inside=False)
    rng = np.random.default_rng(8)
    wo = np.tile([np.sin(0.6), 0.0, np.cos(0.6)], (n, 1))
    wi = rng.normal(size=(n, 3))
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    f, _ = lobe.eval(p, wo, wi)
    alpha, eta = 0.16, 1.5
    up = wi[:, 2] > 0
    h = np.where(up[:, None], wo + wi, -(wo + eta * wi))
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    h *= np.sign(h[:, 2:3])
    c_o, c_i = (wo * h).sum(1), (wi * h).sum(1)
    F = fresnel.dielectric(c_o, eta)
    dg = beckmann.D(alpha, h) * beckmann.G2(alpha, wo, wi)
    refl = F * dg / (4 * wo[:, 2] * wi[:, 2])
    refr = np.abs(c_o * c_i) * (1 - F) * dg / (np.abs(wo[:, 2] * wi[:, 2]) * (c_o + eta * c_i) ** 2)
    valid = c_o > 0
    expected = np.where(valid, np.where(up, refl, np.where(c_i < 0, refr, 0.0)), 0.0)
    np.testing.assert_allclose(f[:, 0], expected, rtol=1e-6, atol=1e-12)
    assert np.abs(f[:, 0] - np.where(up, F * microfacet.D(alpha, h) * microfacet.G2(alpha, wo, wi)
                                     / (4 * wo[:, 2] * wi[:, 2]), f[:, 0])).max() > 0.01


def test_refraction_only_never_reflects_and_keeps_the_refraction():
    """The Refraction BSDF from outside at 60 degrees: no reflection, and (smooth) all light
    refracted (Cycles' refraction closure has no Fresnel factor)."""
    spec = dict(kind=LOBE_DIELECTRIC, color=(1.0, 1.0, 1.0), tint=(0.0, 0.0, 0.0), roughness=0.0, ior=1.5,
                refract_only=True)
    a, _ = _albedo(spec, False, 0.5)
    np.testing.assert_allclose(a, 1.0, rtol=1e-9)
    rough = dict(spec, roughness=0.3)
    lobe, p = _lobe(rough, 50_000)
    rng = np.random.default_rng(1)
    s = lobe.sample(p, np.tile([0.8, 0.0, 0.6], (50_000, 1)), rng.random((50_000, 2)), rng.random(50_000))
    assert np.all(s.wi[s.pdf > 0, 2] < 0)
    assert DIST_GGX == 0  # GGX: the refraction-only lobe's distribution here


# ---------------------------------------------------------------- with Blender

PRINCIPLED = "ShaderNodeBsdfPrincipled"
SPHERES = [
    dict(name="film_specular", kind=PRINCIPLED, Roughness=0.2,
         **{"Base Color": (0.05, 0.05, 0.05, 1.0), "Thin Film Thickness": 500.0, "Thin Film IOR": 1.33}),
    dict(name="film_metal", kind=PRINCIPLED, Roughness=0.25, Metallic=1.0,
         **{"Base Color": (0.9, 0.9, 0.9, 1.0), "Thin Film Thickness": 320.0, "Thin Film IOR": 1.5}),
    dict(name="film_glass", kind="ShaderNodeBsdfGlass", Roughness=0.15,
         **{"Thin Film Thickness": 400.0, "Thin Film IOR": 1.6}),
    dict(name="physical_conductor", kind="ShaderNodeBsdfMetallic", Roughness=0.3, fresnel_type="PHYSICAL_CONDUCTOR",
         IOR=tuple(GOLD[0]), Extinction=tuple(GOLD[1])),
    dict(name="refraction", kind="ShaderNodeBsdfRefraction", Roughness=0.1, IOR=1.45),
    dict(name="transmission_specular_tint", kind=PRINCIPLED, Roughness=0.2,
         **{"Transmission Weight": 1.0, "Specular Tint": (1.0, 0.3, 0.1, 1.0), "Base Color": (0.9, 0.9, 0.9, 1.0)}),
    dict(name="glass_beckmann", kind="ShaderNodeBsdfGlass", Roughness=0.3, distribution="BECKMANN"),
]
RUNS, SAMPLES, TOL = 6, 96, 0.01


@pytest.mark.blender
def test_film_conductor_and_refraction_spheres_render_as_cycles():
    """Thin film on a Principled dielectric, a Principled metal and a Glass BSDF; a physical
    conductor Metallic BSDF (gold's n, k); a Refraction BSDF; Principled transmission with a
    Specular Tint; a Beckmann Glass BSDF: each quadrant of each sphere, per channel, within 1 % plus the noise band."""
    import feature_spheres as fs
    fs.spheres_agree_with_cycles(SPHERES, SAMPLES, RUNS, TOL)
