"""Materials without Blender: texture lookups, Cycles' layering estimate, the closure's lobe
mixture (sampling distribution, weights, delta lobes), normal maps, transparency, glass and
mirror furnaces, and per-kind dispatch (a diffuse scene never runs glossy code)."""
import numpy as np
import pytest
from scipy import stats as st

from ember.engine import textures
from ember.engine.bsdf import closure as closure_mod
from ember.engine.bsdf import dielectric, fresnel, layering, microfacet, phong
from ember.engine.scene import (EXT_CLIP, EXT_EXTEND, EXT_MIRROR, EXT_REPEAT, FRESNEL_DIELECTRIC,
                                INTERP_CLOSEST, INTERP_LINEAR, LOBE_DIELECTRIC, LOBE_DIFFUSE,
                                LOBE_MICROFACET, LOBE_PHONG, LOBE_TRANSPARENT, MAT_NODES, TEX_ALPHA,
                                Lights, Materials, Mesh, Scene, World)
from ember.engine.session import RenderSession

from core_scenes import furnace_box, perspective, quads_mesh, settings, uv_sphere
from stats import ChiSquareTest, Sphere, sidak_alpha

ALPHA = 0.01
RNG = np.random.default_rng(20261122)


def render(scene):
    session = RenderSession(scene)
    stats = session.run()
    return session.film.mean(), session.film.variance_of_mean(), stats


# --- textures ----------------------------------------------------------------------------
def _texture_table(texels, **slot):
    return Materials.make([dict(kind=MAT_NODES, lobes=[])], slots=[dict(image=0, **slot)],
                          images=[dict(texels=texels, srgb=slot.pop("srgb", False))])


def _tent_reference(texels, u, v, extension):
    """Bilinear filtering written as a sum of tent weights over every texel centre (and its
    periodic / mirrored copies): an independent formulation of Cycles' linear lookup."""
    h, w = texels.shape[:2]
    x, y = u * w - 0.5, v * h - 0.5
    out = np.zeros((len(u), 4))
    for i in range(-2 * w, 3 * w):
        for j in range(-2 * h, 3 * h):
            weight = np.maximum(0, 1 - np.abs(x - i)) * np.maximum(0, 1 - np.abs(y - j))
            if extension == EXT_REPEAT:
                ii, jj, inside = i % w, j % h, True
            elif extension == EXT_EXTEND:
                ii, jj, inside = min(max(i, 0), w - 1), min(max(j, 0), h - 1), True
            elif extension == EXT_MIRROR:
                ii = i % (2 * w) if i % (2 * w) < w else 2 * w - 1 - i % (2 * w)
                jj = j % (2 * h) if j % (2 * h) < h else 2 * h - 1 - j % (2 * h)
                inside = True
            else:
                ii, jj, inside = i, j, 0 <= i < w and 0 <= j < h
            if inside:
                out += weight[:, None] * texels[jj, ii]
    return out


@pytest.mark.parametrize("extension", [EXT_REPEAT, EXT_EXTEND, EXT_CLIP, EXT_MIRROR])
def test_linear_lookup_matches_tent_filter(extension):
    texels = RNG.random((3, 5, 4)).astype(np.float32)
    m = _texture_table(texels, extension=extension)
    uv = RNG.uniform(-1.3, 2.2, (400, 2))
    got = textures.lookup(m, np.zeros(400, int), uv)
    want = _tent_reference(texels.astype(np.float64), uv[:, 0], uv[:, 1], extension)
    assert np.max(np.abs(got - want)) < 1e-6


def test_closest_lookup_transform_alpha_and_srgb_order():
    texels = RNG.random((4, 4, 4)).astype(np.float32)
    # Mapping x2 then +0.25 in u: image u = 2 u + 0.25.
    m = _texture_table(texels, interpolation=INTERP_CLOSEST, output=TEX_ALPHA,
                       transform=((2.0, 0.0, 0.25), (0.0, 1.0, 0.0)))
    uv = RNG.random((300, 2))
    ix = np.floor((2 * uv[:, 0] + 0.25) * 4).astype(int) % 4
    iy = np.floor(uv[:, 1] * 4).astype(int) % 4
    np.testing.assert_array_equal(textures.scalar(m, np.zeros(300, int), uv), texels[iy, ix, 3])
    np.testing.assert_array_equal(textures.color(m, np.zeros(300, int), uv), np.repeat(texels[iy, ix, 3:4], 3, 1))
    # Byte sRGB: interpolate the stored values, then decode (not the other way round).
    pair = np.array([[[0.0, 0.0, 0.0, 1.0], [1.0, 1.0, 1.0, 1.0]]], np.float32)
    m = _texture_table(pair, srgb=True, extension=EXT_EXTEND, interpolation=INTERP_LINEAR)
    mid = textures.color(m, np.zeros(1, int), np.array([[0.5, 0.5]]))
    np.testing.assert_allclose(mid, textures.srgb_to_linear(np.full((1, 3), 0.5)), rtol=1e-12)
    assert abs(mid[0, 0] - 0.5) > 0.2  # decoding first would give 0.5
    # A colour fed to a float input becomes its Rec.709 luminance.
    m = _texture_table(np.array([[[0.2, 0.4, 0.8, 1.0]]], np.float32), interpolation=INTERP_CLOSEST)
    assert textures.scalar(m, np.zeros(1, int), np.array([[0.3, 0.6]]))[0] == pytest.approx(
        0.2 * 0.2126729 + 0.4 * 0.7151522 + 0.8 * 0.0721750, rel=1e-6)


# --- Cycles' layering estimate --------------------------------------------------------------
def test_layering_table_matches_monte_carlo_at_its_nodes():
    """The stored table s(roughness, cos_o, eta) against an independent Monte Carlo estimate
    (uniform random u, not the table's jittered strata) at grid nodes; at roughness 0 it is
    exactly the remapped Fresnel at wo (Cycles samples a smooth lobe as its normal)."""
    nodes = layering.nodes()
    n = 200_000
    for k, j, i in ((5, 8, 0), (5, 8, 6), (5, 3, 12), (9, 1, 9), (12, 15, 15), (2, 6, 3)):
        eta = float(layering.eta_of_z(k / 15))
        got = layering.schlick_factor(nodes[i], nodes[j], eta)
        if i == 0:
            F0 = fresnel.f0_from_ior(eta)
            exact = (fresnel.dielectric(np.array([nodes[j]]), eta)[0] - F0) / (1 - F0)
            assert got == pytest.approx(exact, abs=1e-6)
            continue
        alpha = np.full(n, nodes[i] ** 2)
        wo = np.tile([np.sqrt(1 - nodes[j] ** 2), 0.0, nodes[j]], (n, 1))
        h = microfacet.sample_vndf(alpha, wo, RNG.random((n, 2)))
        F0 = fresnel.f0_from_ior(eta)
        s = np.clip((fresnel.dielectric(np.einsum("ij,ij->i", wo, h), eta) - F0) / (1 - F0), 0, 1)
        s = np.where(microfacet.reflect(wo, h)[:, 2] > 0, s, 0.0)
        assert abs(got - s.mean()) < 4 * s.std() / np.sqrt(n) + 3e-4, (k, j, i, got, s.mean())


# --- the closure ------------------------------------------------------------------------------
def _closure(lobes, wo, n=1, slots=(), images=(), normal_tex=-1, uvs=None, inside=False):
    """A Closure at n identical points of a unit quad in the z = 0 plane (normal +z), seen
    from wo (3,) (from below when inside)."""
    mats = Materials.make([dict(kind=MAT_NODES, lobes=lobes, normal_tex=normal_tex)], slots=list(slots),
                          images=list(images))
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    t = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    normals = np.tile(np.array([0, 0, 1], np.float32), (2, 3, 1))
    if uvs is None:
        uvs = v[t][:, :, :2]
    mesh = Mesh(v, t, normals, np.zeros(2, np.int32), uvs=uvs)
    scene = Scene(mesh, mats, Lights.make([]), World(), perspective((0, 0, 1), (0, 0, 0)), settings())
    wo = np.tile(np.asarray(wo, np.float64) / np.linalg.norm(wo), (n, 1))
    side = np.sign(wo[:, 2:3])
    ng = np.tile([0.0, 0.0, 1.0], (n, 1)) * side
    bary = np.tile([0.2, 0.3, 0.5], (n, 1))
    return closure_mod.Closure(scene, np.zeros(n, np.int32), ng.copy(), ng, wo, np.zeros(n, np.int64), bary)


MIXED = [  # Principled-like: dielectric specular over diffuse, plus rough glass and a Phong lobe
    dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_DIELECTRIC, roughness=0.4, ior=1.5, weight=(0.5,) * 3),
    dict(kind=LOBE_DIFFUSE, color=(0.6, 0.5, 0.4), layer=0, weight=(0.5,) * 3),
    dict(kind=LOBE_DIELECTRIC, color=(0.9, 0.9, 0.9), tint=(1, 1, 1), roughness=0.6, ior=1.4, weight=(0.3,) * 3),
    dict(kind=LOBE_PHONG, color=(0.1, 0.1, 0.1), tint=(0.5, 0.5, 0.5), exponent=40.0, weight=(0.2,) * 3),
]


@pytest.mark.parametrize("theta_deg,inside", [(20, False), (70, False), (40, True)])
def test_mixture_sampling_matches_mixture_pdf(theta_deg, inside):
    """Chi-square of the closure's sampled directions over the whole sphere against the
    mixture pdf its eval() reports (Sidak over the three configurations). Samples a lobe drops
    (its pdf is 0 there) are rejected: the pdf integrates to the share kept."""
    th = np.radians(theta_deg)
    wo = [np.sin(th), 0.0, -np.cos(th) if inside else np.cos(th)]

    def sampler(u):
        s = _closure(MIXED, wo, len(u)).sample(u[:, :2], u[:, 2])
        assert not s.delta.any() and np.all(np.isfinite(s.weight))
        return s.wi, s.valid

    def pdf(d):
        return _closure(MIXED, wo, len(d)).eval(d, np.arange(len(d)))[1]

    ChiSquareTest(Sphere(), sampler, pdf, 40, 200_000, seed=[theta_deg, inside], sample_dim=3,
                  refine=True).check(ALPHA, n_tests=3)


def test_sample_weight_and_pdf_are_those_of_eval():
    """Consistency only: sample() and eval() share Closure._mixture, so this cannot see a wrong
    mixture weight; test_sampler_directions checks the values against formulas written there
    (test_mixture_pdf_and_weight_against_independent_formulas) and the pdf's integral against
    the fraction of kept samples."""
    c = _closure(MIXED, [0.5, 0.2, 0.8], 5000)
    s = c.sample(RNG.random((5000, 2)), RNG.random(5000))
    rows = np.flatnonzero(s.valid)
    f, pdf = c.eval(s.wi[rows], rows)
    np.testing.assert_allclose(s.pdf[rows], pdf, rtol=1e-9)
    cos = np.abs(s.wi[rows, 2])
    np.testing.assert_allclose(s.weight[rows], f * cos[:, None] / pdf[:, None], rtol=1e-9)


def _albedo_by_uniform_sampling(c, n):
    """Integral of f |cos| over the sphere by uniform sampling (non-delta part), and its s.e."""
    d = RNG.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    f, _ = c.eval(d, np.arange(n))
    x = f * np.abs(d[:, 2:3]) * 4 * np.pi
    return x.mean(0), x.std(0) / np.sqrt(n)


@pytest.mark.parametrize("case", ["smooth_glass_and_mirror", "phong_mixture"])
def test_closure_estimator_is_unbiased_with_delta_lobes(case):
    """E[weight] of sample() equals the known albedo: delta lobes analytically, the rest by an
    independent uniform-sampling integral of eval(); a two-sided z-test per channel."""
    mu = 0.6
    wo = [np.sqrt(1 - mu * mu), 0.0, mu]
    n = 200_000
    if case == "smooth_glass_and_mirror":
        lobes = [dict(kind=LOBE_DIELECTRIC, color=(0.8, 0.9, 1.0), tint=(1, 1, 1), roughness=0.0, ior=1.5, weight=(0.4,) * 3),
                 dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_DIELECTRIC, roughness=0.0, ior=1.5, weight=(0.6,) * 3),
                 dict(kind=LOBE_DIFFUSE, color=(0.5, 0.5, 0.5), layer=1, weight=(0.6,) * 3),
                 dict(kind=LOBE_TRANSPARENT, color=(1.0, 0.5, 0.0), weight=(0.2,) * 3)]
        F = fresnel.dielectric(np.array([mu]), 1.5)[0]
        delta = 0.4 * (F + (1 - F) / 1.5**2 * np.array([0.8, 0.9, 1.0])) + 0.6 * F + 0.2 * np.array([1.0, 0.5, 0.0])
    else:
        lobes = [dict(kind=LOBE_PHONG, color=(0.3, 0.2, 0.1), tint=(0.6, 0.7, 0.8), exponent=200.0)]
        delta = np.zeros(3)
    c = _closure(lobes, wo, n)
    s = c.sample(RNG.random((n, 2)), RNG.random(n))
    assert np.all(s.weight[~s.valid] == 0)
    smooth, smooth_se = _albedo_by_uniform_sampling(_closure(lobes, wo, n), n)
    mean, se = s.weight.mean(0), s.weight.std(0) / np.sqrt(n)
    z = (mean - delta - smooth) / np.sqrt(se**2 + smooth_se**2)
    assert np.all(np.abs(z) < st.norm.ppf(1 - sidak_alpha(ALPHA, 6) / 2)), z


def test_total_internal_reflection_inside_glass():
    """wo inside the glass (behind the winding normal), 60 deg from the normal, beyond the
    critical angle asin(1 / 1.5) = 41.8 deg: the smooth interface reflects every sample with
    weight 1 (F = 1); the rough one returns finite weights only."""
    wo = [np.sin(np.radians(60)), 0.0, -np.cos(np.radians(60))]
    glass = dict(kind=LOBE_DIELECTRIC, color=(1, 1, 1), tint=(1, 1, 1), ior=1.5)
    c = _closure([dict(glass, roughness=0.0)], wo, 1000)
    assert c.inside.all()
    s = c.sample(RNG.random((1000, 2)), RNG.random(1000))
    assert s.delta.all() and s.valid.all()
    np.testing.assert_allclose(s.weight, 1.0, rtol=1e-12)
    np.testing.assert_allclose(s.wi, np.tile([-wo[0], 0.0, wo[2]], (1000, 1)), atol=1e-12)  # the mirror image, inside
    c = _closure([dict(glass, roughness=0.2)], wo, 20000)
    s = c.sample(RNG.random((20000, 2)), RNG.random(20000))
    assert np.all(np.isfinite(s.weight)) and np.all(np.isfinite(s.pdf)) and s.valid.mean() > 0.9
    # Tilted microfacets let a few samples out; most reflect back inside.
    assert np.mean(s.wi[s.valid, 2] < 0) > 0.95


def test_phong_samples_under_the_surface_get_zero():
    """Grazing wo and n = 30: many glossy samples fall under the surface; they keep weight 0
    (no redraw), and the delta-free closure reports them invalid."""
    wo = [np.sin(np.radians(85)), 0.0, np.cos(np.radians(85))]
    c = _closure([dict(kind=LOBE_PHONG, color=(0, 0, 0), tint=(0.9, 0.9, 0.9), exponent=30.0)], wo, 20000)
    s = c.sample(RNG.random((20000, 2)), RNG.random(20000))
    below = s.wi[:, 2] <= 0
    assert below.mean() > 0.1
    assert np.all(s.weight[below] == 0) and not s.valid[below].any()


def test_layered_diffuse_keeps_one_minus_specular_albedo():
    wo = np.array([0.6, 0.0, 0.8])
    spec = dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_DIELECTRIC, roughness=0.5, ior=1.45, tint=(1.0, 0.8, 0.6))
    both = _closure([spec, dict(kind=LOBE_DIFFUSE, color=(0.5, 0.6, 0.7), layer=0)], wo, 50)
    alone = _closure([spec], wo, 50)
    d = RNG.normal(size=(50, 3))
    d[:, 2] = np.abs(d[:, 2])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    f_both = both.eval(d, np.arange(50))[0]
    f_spec = alone.eval(d, np.arange(50))[0]
    f0 = fresnel.f0_from_ior(1.45) * np.array([[1.0, 0.8, 0.6]])
    keep = layering.base_weight(f0, np.array([0.5]), np.array([0.8]), np.array([1.45]))
    np.testing.assert_allclose(f_both - f_spec, np.array([[0.5, 0.6, 0.7]]) / np.pi * keep[:, None] * np.ones((50, 1)), rtol=1e-9)


def test_normal_map_tilts_the_shading_normal_along_the_uv_tangent():
    """A constant tangent-space normal (sin t, 0, cos t) tilts ns toward dp/du (here +x; with
    the UVs mirrored in u, toward -x); strength 0.5 goes halfway in the vector sense."""
    t = np.radians(30)
    texel = np.array([[[0.5 + 0.5 * np.sin(t), 0.5, 0.5 + 0.5 * np.cos(t), 1.0]]], np.float32)
    lobes = [dict(kind=LOBE_DIFFUSE)]
    c = _closure(lobes, [0, 0, 1], 3, slots=[dict(image=0)], images=[dict(texels=texel)], normal_tex=0)
    np.testing.assert_allclose(c.ns, np.tile([np.sin(t), 0, np.cos(t)], (3, 1)), atol=1e-7)
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    mirrored = (1 - v[np.array([[0, 1, 2], [0, 2, 3]])][:, :, :2]) * [1, -1] + [0, 1]
    c = _closure(lobes, [0, 0, 1], 3, slots=[dict(image=0)], images=[dict(texels=texel)], normal_tex=0, uvs=mirrored)
    np.testing.assert_allclose(c.ns, np.tile([-np.sin(t), 0, np.cos(t)], (3, 1)), atol=1e-7)


def test_normal_map_keeps_the_mirror_direction_above_the_surface():
    """Tilted 85 deg toward a 75 deg view, the mapped normal would mirror wo under the surface;
    Cycles' bend leaves the mirror direction min(0.9 wo.ng, 0.01) above it."""
    t = np.radians(85)
    texel = np.array([[[0.5 + 0.5 * np.sin(t), 0.5, 0.5 + 0.5 * np.cos(t), 1.0]]], np.float32)
    wo = np.array([np.sin(np.radians(75)), 0.0, np.cos(np.radians(75))])
    c = _closure([dict(kind=LOBE_MICROFACET, roughness=0.0)], wo, 1, slots=[dict(image=0)],
                 images=[dict(texels=texel)], normal_tex=0)
    n = c.ns[0]
    r = 2 * np.dot(n, wo) * n - wo
    assert r[2] == pytest.approx(min(0.9 * wo[2], 0.01), abs=1e-6)


# --- whole renders -----------------------------------------------------------------------------
def _sphere_in_white_world(lobes, samples=16, size=16):
    v, t, n = uv_sphere((0, 0, 0), 1.0, 32, 64)
    mesh = Mesh(v, t, n, np.zeros(len(t), np.int32))
    mats = Materials.make([dict(kind=MAT_NODES, lobes=lobes)])
    return Scene(mesh, mats, Lights.make([]), World(color=np.ones(3)), perspective((0, -4, 0), (0, 0, 0), 20),
                 settings(samples=samples, width=size, height=size, threads=1))


@pytest.mark.parametrize("lobe", [
    dict(kind=LOBE_DIELECTRIC, color=(1, 1, 1), tint=(1, 1, 1), roughness=0.0, ior=1.5),
    dict(kind=LOBE_MICROFACET, color=(1, 1, 1), roughness=0.0),
], ids=["smooth_glass", "mirror"])
def test_lossless_sphere_in_white_furnace_is_invisible(lobe):
    """A smooth glass (or F = 1 mirror) sphere filling the view of a white world: every path
    leaves with weight exactly 1 (refraction scales radiance by 1/eta^2 going in and eta^2
    coming out; no NaN at total internal reflection)."""
    mean, var, stats = render(_sphere_in_white_world([lobe]))
    assert stats.nonfinite == 0
    np.testing.assert_allclose(mean[4:12, 4:12], 1.0, atol=1e-9)


def test_textured_alpha_is_stochastic_transparency():
    """A quad covering the view in a white world, diffuse albedo 0.5 with a Principled-style
    alpha from a texture: opaque in the left half (L = 0.5), cut out in the right (L = 1).
    With constant alpha 0.3 as lobe weights, L = 0.3 x 0.5 + 0.7. In a constant world every
    sample of this closure returns exactly its albedo (the lobe choice by albedo makes the
    weights equal), so the pixels are exact, not just unbiased."""
    texels = np.array([[[1, 1, 1, 1.0], [1, 1, 1, 0.0]]], np.float32)
    quads = np.array([[[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]]], float)
    mesh = quads_mesh(quads, [0])
    uvs = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], np.float32)
    mesh = Mesh(mesh.vertices, mesh.triangles, mesh.normals, mesh.material, uvs=uvs)
    lobes = [dict(kind=LOBE_TRANSPARENT, color=(1, 1, 1), opacity_tex=0, opacity_invert=True),
             dict(kind=LOBE_DIFFUSE, color=(0.5, 0.5, 0.5), opacity_tex=0)]
    mats = Materials.make([dict(kind=MAT_NODES, lobes=lobes)], slots=[dict(image=0, output=TEX_ALPHA,
                          interpolation=INTERP_CLOSEST)], images=[dict(texels=texels)])
    cam = perspective((0, -3, 0), (0, 0, 0), 20)
    scene = Scene(mesh, mats, Lights.make([]), World(color=np.ones(3)), cam, settings(samples=16, width=8, height=8, threads=1))
    mean, _, stats = render(scene)
    assert stats.nonfinite == 0
    np.testing.assert_allclose(mean[:, :4], 0.5, atol=1e-12)
    np.testing.assert_allclose(mean[:, 4:], 1.0, atol=1e-12)
    lobes = [dict(kind=LOBE_TRANSPARENT, color=(1, 1, 1), weight=(0.7,) * 3),
             dict(kind=LOBE_DIFFUSE, color=(0.5, 0.5, 0.5), weight=(0.3,) * 3)]
    mean, _, _ = render(scene.replace(materials=Materials.make([dict(kind=MAT_NODES, lobes=lobes)])))
    np.testing.assert_allclose(mean, 0.85, atol=1e-12)


def test_diffuse_scene_never_runs_glossy_code(monkeypatch):
    def forbidden(*args, **kwargs):
        raise AssertionError("glossy / texture code ran in a diffuse-only scene")

    for module, names in ((microfacet, ("D", "G1", "G2", "sample_vndf", "sample_reflection", "eval_reflection",
                                        "is_delta", "alpha_from_roughness")),
                          (dielectric, ("sample_smooth", "sample_rough", "eval_rough", "pdf_rough", "is_delta")),
                          (phong, ("eval", "pdf", "sample", "albedo")),
                          (layering, ("schlick_factor", "base_weight")),
                          (textures, ("lookup", "mesh_uv")),
                          (fresnel, ("dielectric", "f82_tint", "dielectric_remapped"))):
        for name in names:
            monkeypatch.setattr(module, name, forbidden)
    mean, var, stats = render(furnace_box(albedo=0.5, Le=1.0, samples=4, threads=1))
    assert stats.nonfinite == 0 and abs(mean.mean() - 2.0) < 0.5


def test_scene_save_load_round_trips_lobes_textures_and_uvs(tmp_path):
    texels = RNG.random((3, 2, 4)).astype(np.float32)
    mats = Materials.make([dict(kind=MAT_NODES, lobes=MIXED, normal_tex=0, normal_strength=0.5, name="mixed")],
                          slots=[dict(image=0, extension=EXT_MIRROR, transform=((2, 0, 0.5), (0, 1, 0)))],
                          images=[dict(texels=texels, srgb=True, name="img")])
    mesh = Mesh(np.eye(3, dtype=np.float32), np.array([[0, 1, 2]], np.int32), np.zeros((1, 3, 3), np.float32),
                np.zeros(1, np.int32), uvs=RNG.random((1, 3, 2)).astype(np.float32))
    scene = Scene(mesh, mats, Lights.make([]), World(), perspective((0, 0, 1), (0, 0, 0)), settings())
    path = tmp_path / "scene.npz"
    scene.save(path)
    loaded = Scene.load(path)
    for part in ("mesh", "materials"):
        a, b = getattr(scene, part), getattr(loaded, part)
        for name in a.__dataclass_fields__:
            x, y = getattr(a, name), getattr(b, name)
            if isinstance(x, tuple):
                assert x == y, name
            else:
                np.testing.assert_array_equal(x, y, err_msg=name)
                assert np.asarray(x).dtype == np.asarray(y).dtype, name
