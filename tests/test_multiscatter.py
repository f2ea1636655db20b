"""Blender 5.0's default microfacet and rough diffuse as Cycles has them: Multiscatter GGX
(engine/bsdf/multiscatter.py) on the GGX and glass lobes, and the energy-preserving Oren-Nayar
lobe (engine/bsdf/oren_nayar.py).

Without Blender: the albedo tables against a fresh integration of Ember's GGX at some of their
nodes; white furnaces (directional albedo, f cos / pdf over the lobe's own samples): Multiscatter
GGX with F = 1 and Oren-Nayar of a white colour reflect all light, glass of white tint seen
from outside reflects and refracts all of it (without radiance scaling), every other model at
most all of it and at least the single-scattering lobe; the compensation tinted as Kulla and
Conty's sum of bounces; the compensation's closed forms (Fss = 1: 1 / E); Oren-Nayar's
reciprocity and its sigma = 0 limit (Lambert). The samplers' chi-square and the interface are
in test_lobes.py (its multi_* and oren_nayar cases).
With Blender (marked blender): the node setting reaches the lobes in both export paths, and a
grid of spheres (gold metal, Principled plastic and glass at roughness 0.3 / 0.7 / 1.0, the
default Multiscatter GGX, an Oren-Nayar diffuse, a Beckmann metal and an Ashikhmin-Shirley
Glossy) in a white furnace renders as Cycles does.
"""
import numpy as np
import pytest

from ember.engine.bsdf import beckmann, lobes, multiscatter as ms, oren_nayar
from ember.engine.bsdf.lobes import inputs
from ember.engine.scene import (DIST_ASHIKHMIN_SHIRLEY, DIST_BECKMANN, DIST_GGX, DIST_MULTI_GGX, FRESNEL_DIELECTRIC,
                                FRESNEL_F82, FRESNEL_NONE,
                                LOBE_DIELECTRIC, LOBE_MICROFACET, LOBE_OREN_NAYAR, MAT_NODES, Materials)
from feature_spheres import bpy_module, node_material

N = 200_000
ROUGHNESS = (0.3, 0.7, 1.0)
ANGLES = (0.0, 45.0, 75.0)  # wo's polar angle, degrees


def directional_albedo(spec, theta, n=N, inside=False, seed=1):
    """(mean (3,), its standard error (3,)) of f |cos| / pdf over the lobe's own samples at
    wo of polar angle theta; refraction counted without the radiance scaling 1 / eta^2 (the
    albedo Cycles' tables hold)."""
    m = Materials.make([dict(kind=MAT_NODES, lobes=[spec])])
    lobe = lobes.LOBES[spec["kind"]]
    p = lobe.parameters(m, np.zeros(n, np.int64), np.arange(n), inputs.Sources(None), np.full(n, inside))
    t = np.radians(theta)
    wo = np.tile([np.sin(t), 0.0, np.cos(t)], (n, 1))
    rng = np.random.default_rng(seed)
    s = lobe.sample(p, wo, rng.random((n, 2)), rng.random(n))
    ok = s.pdf > 0
    f, _ = lobe.eval(p, wo, s.wi)
    w = np.where(ok[:, None], f * np.abs(s.wi[:, 2:3]) / np.where(ok, s.pdf, 1.0)[:, None], 0.0)
    if s.eta2 is not None:
        w = w * np.where(s.wi[:, 2:3] * wo[:, 2:3] < 0, s.eta2[:, None], 1.0)
    return w.mean(axis=0), w.std(axis=0) / np.sqrt(n)


def _glossy(r, dist=DIST_MULTI_GGX, **kw):
    return dict(dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_NONE, color=(1.0, 1.0, 1.0), roughness=r, distribution=dist),
                **kw)


# ---------------------------------------------------------------- the tables

@pytest.mark.parametrize("i, j", [(6, 31), (12, 31), (20, 16), (31, 8), (31, 31), (25, 3)])
def test_albedo_table_is_the_integral_of_embers_ggx(i, j):
    """E at node (roughness i, mu j) against 512^2 stratified samples (about 2e-4 accurate)."""
    r, mu = ms.nodes(ms.E_SIZE)[i], ms.nodes(ms.E_SIZE)[j]
    direct = ms._reflection_albedo(np.array([r]), np.array([mu]), ms._strata(512, np.random.default_rng(i + 7 * j)))[0]
    assert ms.E([r], [mu])[0] == pytest.approx(direct, abs=1e-3)


@pytest.mark.parametrize("i", [8, 20, 31])
def test_mean_albedo_table_is_the_cosine_weighted_mean(i):
    r = ms.nodes(ms.E_SIZE)[i]
    mu = (np.arange(64) + 0.5) / 64  # midpoint rule over the table's own E
    assert ms.E_avg([r])[0] == pytest.approx((2.0 * mu * ms.E(np.full(64, r), mu)).mean(), abs=3e-3)


@pytest.mark.parametrize("side, k, j, i", [(0, 7, 15, 15), (0, 3, 8, 10), (1, 7, 15, 15), (1, 10, 6, 12), (1, 4, 12, 8)])
def test_glass_table_is_the_integral_of_embers_glass(side, k, j, i):
    eta = ms.eta_nodes()[k] if side == 0 else 1.0 / ms.eta_nodes()[k]
    r, mu = ms.nodes(ms.GLASS_SIZE)[i], ms.nodes(ms.GLASS_SIZE)[j]
    direct = ms._glass_albedo(np.array([r]), np.array([mu]), np.array([eta]),
                              ms._strata(384, np.random.default_rng(k + 16 * j)))[0]
    assert ms.tables()["glass_E"][side, k, j, i] == pytest.approx(direct, abs=2e-3)


def test_compensation_closed_forms():
    """Fss = 1: the factor is 1 / E and the albedo estimate keeps 1; Fss = 0: nothing added;
    a coloured Fss: between, and the darkening at most 1."""
    E, A = np.array([0.5, 0.8]), np.array([0.6, 0.9])
    scale, dark = ms.factor(E, A, np.ones((2, 3)))
    np.testing.assert_allclose(scale, np.tile(1 / E[:, None], 3))
    np.testing.assert_allclose(dark, 1.0)
    scale, dark = ms.factor(E, A, np.zeros((2, 3)))
    np.testing.assert_allclose(scale, 1.0)
    scale, dark = ms.factor(E, A, np.full((2, 3), 0.5))
    assert np.all((scale > 1) & (scale < 1 / E[:, None])) and np.all(dark <= 1)
    # Kulla & Conty's fits of the mean dielectric Fresnel (Cycles') against 2 int F mu dmu: a rough fit.
    mu = (np.arange(20_000) + 0.5) / 20_000
    from ember.engine.bsdf import fresnel
    for eta in (1.33, 1.5, 2.0, 1 / 1.5):
        assert ms.fss_dielectric(eta) == pytest.approx((2 * mu * fresnel.dielectric(mu, eta)).mean(), abs=0.01)


# ---------------------------------------------------------------- white furnaces

@pytest.mark.parametrize("r", ROUGHNESS)
def test_multiscatter_conductor_with_unit_fresnel_reflects_all_light(r):
    """Directional albedo 1 within 4 standard errors plus the tables' interpolation (3e-3);
    single-scattering GGX loses light, the more the rougher."""
    for theta in ANGLES:
        a, se = directional_albedo(_glossy(r), theta)
        assert abs(a[0] - 1.0) < 4 * se[0] + 3e-3, (theta, a[0], se[0])
        single, _ = directional_albedo(_glossy(r, DIST_GGX), theta)
        assert single[0] < 1.0 - (0.005 if r < 0.5 else 0.1)
        assert single[0] == pytest.approx(ms.E([r], [np.cos(np.radians(theta))])[0], abs=4 * se[0] + 3e-3)


@pytest.mark.parametrize("r", ROUGHNESS)
def test_coloured_multiscatter_reflects_what_kulla_and_conty_give(r):
    """A constant Fresnel c (the Glossy colour): albedo c (E + Fms (1 - E)), Fms = c E_avg /
    (1 - c (1 - E_avg)): what light reflected on and on between microfacets of reflectance c
    adds up to (each extra bounce tinted by c)."""
    c = np.array([0.9, 0.5, 0.2])
    for theta in ANGLES:
        a, se = directional_albedo(_glossy(r, color=tuple(c)), theta)
        E, A = ms.E([r], [np.cos(np.radians(theta))])[0], ms.E_avg([r])[0]
        Fms = c * A / (1 - c * (1 - A))
        np.testing.assert_allclose(a, c * (E + Fms * (1 - E)), atol=1e-3 + 4 * se.max())


MODELS = {
    "glossy_colour": _glossy(0.7, color=(0.9, 0.5, 0.2)),
    "f82_gold": _glossy(0.7, fresnel=FRESNEL_F82, color=(1.0, 0.78, 0.34), tint=(0.9, 0.9, 0.8)),
    "f82_black_tint": _glossy(1.0, fresnel=FRESNEL_F82, color=(0.5, 0.5, 0.5), tint=(0.0, 0.0, 0.0)),
    "specular": _glossy(0.7, fresnel=FRESNEL_DIELECTRIC, ior=1.5, tint=(1.0, 1.0, 1.0)),
    "specular_ior_below_1": _glossy(1.0, fresnel=FRESNEL_DIELECTRIC, ior=0.8, tint=(1.0, 1.0, 1.0)),
    "glass": dict(kind=LOBE_DIELECTRIC, color=(0.9, 0.7, 0.5), tint=(0.9, 0.7, 0.5), roughness=1.0, ior=1.5,
                  distribution=DIST_MULTI_GGX),
    "oren_nayar": dict(kind=LOBE_OREN_NAYAR, color=(0.9, 0.7, 0.5), roughness=1.0),
    "beckmann": _glossy(0.6, DIST_BECKMANN),
    "ashikhmin_shirley": _glossy(0.5, DIST_ASHIKHMIN_SHIRLEY),
}


@pytest.mark.parametrize("name", list(MODELS))
def test_albedo_is_at_most_one_and_at_least_single_scattering(name):
    spec = MODELS[name]
    for theta in ANGLES:
        for inside in ((False, True) if spec["kind"] == LOBE_DIELECTRIC else (False,)):
            a, se = directional_albedo(spec, theta, inside=inside)
            assert np.all(a <= 1.0 + 4 * se + 1e-3), (theta, inside, a)
            if spec["kind"] != LOBE_OREN_NAYAR and spec["distribution"] in (DIST_GGX, DIST_MULTI_GGX):
                single, _ = directional_albedo(dict(spec, distribution=DIST_GGX), theta, inside=inside)
                assert np.all(a >= single - 1e-12)


@pytest.mark.parametrize("r", ROUGHNESS)
def test_multiscatter_glass_of_white_tint_keeps_all_light(r):
    """Outside (eta 1.5): within 4 standard errors plus 5e-3. Inside (eta 1 / 1.5) at normal
    incidence within 2 % (the tables' IOR axis is coarse there, as Cycles'); toward grazing
    Cycles' inverse table counts refractions the lobe drops, so glass seen from inside keeps
    less (at most all, at least its single scattering: the albedo test above)."""
    spec = dict(kind=LOBE_DIELECTRIC, color=(1.0, 1.0, 1.0), tint=(1.0, 1.0, 1.0), roughness=r, ior=1.5,
                distribution=DIST_MULTI_GGX)
    for theta in ANGLES:
        a, se = directional_albedo(spec, theta)
        assert abs(a[0] - 1.0) < 4 * se[0] + 5e-3, (theta, a[0])
    a, se = directional_albedo(spec, 0.0, inside=True)
    assert abs(a[0] - 1.0) < 4 * se[0] + 0.02, a[0]


@pytest.mark.parametrize("r", ROUGHNESS)
def test_oren_nayar_of_white_reflects_all_light(r):
    for theta in ANGLES + (88.0,):
        a, se = directional_albedo(dict(kind=LOBE_OREN_NAYAR, color=(1.0, 1.0, 1.0), roughness=r), theta)
        assert abs(a[0] - 1.0) < 4 * se[0] + 1e-3, (theta, a[0])


def test_oren_nayar_is_reciprocal_and_lambert_when_smooth():
    rng = np.random.default_rng(3)
    k = 5000
    wo, wi = (v / np.linalg.norm(v, axis=1, keepdims=True) for v in rng.normal(size=(2, k, 3)))
    wo[:, 2], wi[:, 2] = np.abs(wo[:, 2]), np.abs(wi[:, 2])
    color = rng.random((k, 3))
    sigma = rng.random(k)
    np.testing.assert_allclose(oren_nayar.eval(color, sigma, wo, wi), oren_nayar.eval(color, sigma, wi, wo), rtol=1e-12)
    np.testing.assert_allclose(oren_nayar.eval(color, np.zeros(k), wo, wi), color / np.pi, rtol=1e-12)
    # Rougher: flatter - back-scattering toward the light grows against forward scattering.
    back = oren_nayar.eval(np.ones((1, 3)), np.array([1.0]), np.array([[0.8, 0, 0.6]]), np.array([[0.8, 0, 0.6]]))
    fwd = oren_nayar.eval(np.ones((1, 3)), np.array([1.0]), np.array([[0.8, 0, 0.6]]), np.array([[-0.8, 0, 0.6]]))
    assert back[0, 0] > fwd[0, 0]


@pytest.mark.parametrize("alpha", [0.05, 0.3, 1.0])
def test_beckmann_normals_are_normalised_and_its_lambda_near_the_exact_one(alpha):
    """int D(h) cos_h dh = 1 (quadrature in theta); Cycles' rational Lambda within 0.6 % of
    G1's exact value 1 / (1 + (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)))."""
    import math
    n = 200_000
    theta = (np.arange(n) + 0.5) / n * (np.pi / 2)
    h = np.stack([np.sin(theta), np.zeros(n), np.cos(theta)], -1)
    integral = (beckmann.D(alpha, h) * np.cos(theta) * np.sin(theta)).sum() * (np.pi / 2 / n) * 2 * np.pi
    assert integral == pytest.approx(1.0, abs=1e-4)
    w = np.stack([np.sin(theta), np.zeros(n), np.cos(theta)], -1)[::1000]
    a = 1.0 / (alpha * np.tan(theta[::1000]))
    exact = np.array([1.0 / (1.0 + (math.erf(x) - 1) / 2 + math.exp(-x * x) / (2 * x * math.sqrt(math.pi))) for x in a])
    np.testing.assert_allclose(1.0 / (1.0 + beckmann.Lambda(alpha, w)), exact, rtol=6e-3)


def test_multiscatter_is_a_factor_of_wo_alone():
    """Cycles scales the whole lobe by a factor of wo: eval at fixed wo is the single-scattering
    eval times one colour for every wi (not reciprocal); the pdf is unchanged."""
    k = 1000
    rng = np.random.default_rng(5)
    wi = rng.normal(size=(k, 3))
    wi[:, 2] = np.abs(wi[:, 2])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo = np.tile([0.6, 0.0, 0.8], (k, 1))
    spec = _glossy(0.8, fresnel=FRESNEL_F82, color=(0.9, 0.6, 0.3), tint=(1.0, 1.0, 1.0))
    out = []
    for dist in (DIST_MULTI_GGX, DIST_GGX):
        m = Materials.make([dict(kind=MAT_NODES, lobes=[dict(spec, distribution=dist)])])
        lobe = lobes.LOBES[LOBE_MICROFACET]
        p = lobe.parameters(m, np.zeros(k, np.int64), np.arange(k), inputs.Sources(None), np.zeros(k, bool))
        out.append(lobe.eval(p, wo, wi))
    (f1, pdf1), (f0, pdf0) = out
    np.testing.assert_array_equal(pdf1, pdf0)
    ratio = f1[f0[:, 0] > 0] / f0[f0[:, 0] > 0]
    np.testing.assert_allclose(ratio, np.broadcast_to(ratio[0], ratio.shape), rtol=1e-9)
    assert np.all(ratio[0] > 1.0)


@pytest.mark.parametrize("kind", [LOBE_MICROFACET, LOBE_DIELECTRIC])
def test_photons_see_the_adjoint_of_multiscatter(kind):
    """A closure of light particles (Params.adjoint: wo toward the light) scales by the factor
    of wi, the viewing side of the adjoint: f_adjoint(wo, wi) / f_single(wo, wi) equals
    f(wi, wo) / f_single(wi, wo), on both sides of glass."""
    k = 4000
    rng = np.random.default_rng(9)
    wo, wi = rng.normal(size=(2, k, 3))
    wo[:, 2] = np.abs(wo[:, 2])
    if kind == LOBE_MICROFACET:
        wi[:, 2] = np.abs(wi[:, 2])
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    spec = dict(kind=kind, color=(0.9, 0.6, 0.3), tint=(0.9, 0.6, 0.3), roughness=0.8, ior=1.5)
    if kind == LOBE_MICROFACET:
        spec["fresnel"] = FRESNEL_F82

    def ratio(a, b, adjoint, inside):
        out = []
        for dist in (DIST_MULTI_GGX, DIST_GGX):
            m = Materials.make([dict(kind=MAT_NODES, lobes=[dict(spec, distribution=dist)])])
            lobe = lobes.LOBES[kind]
            p = lobe.parameters(m, np.zeros(k, np.int64), np.arange(k), inputs.Sources(None), inside)
            p.adjoint = adjoint
            out.append(lobe.eval(p, a, b)[0])
        ok = out[1][:, 0] > 1e-8
        return np.where(ok[:, None], out[0] / np.where(ok[:, None], out[1], 1.0), np.nan)

    inside = rng.random(k) < 0.5
    # Seen from wi's side the surface is inside where wi crossed it.
    other = inside ^ (wi[:, 2] < 0)
    wi_up = wi * np.where(wi[:, 2:3] < 0, -1.0, 1.0)  # the frame flips with the side it is seen from
    wo_seen = wo * np.where(wi[:, 2:3] < 0, -1.0, 1.0)
    adj = ratio(wo, wi, True, inside)
    fwd = ratio(wi_up, wo_seen, False, other)
    both = ~np.isnan(adj[:, 0]) & ~np.isnan(fwd[:, 0])
    assert both.mean() > 0.3
    np.testing.assert_allclose(adj[both], fwd[both], rtol=1e-9)
    assert np.abs(adj[both] - ratio(wo, wi, False, inside)[both]).max() > 0.01  # not the forward factor


# ---------------------------------------------------------------- with Blender

def _export(bpy, *materials):
    """A plane per material (and a camera); (Materials, {name: its lobe rows})."""
    from ember.engine.blender.export import export_scene
    sc = bpy.context.scene
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location, cam.rotation_euler = (0.0, -10.0, 0.0), (np.pi / 2, 0.0, 0.0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    for i, mat in enumerate(materials):
        bpy.ops.mesh.primitive_plane_add(location=(3.0 * i, 0.0, 0.0))
        bpy.context.active_object.data.materials.append(mat)
    sc, _ = export_scene(bpy.context.evaluated_depsgraph_get())
    m = sc.materials
    return m, {name: np.flatnonzero(m.lobe_material == i) for i, name in enumerate(m.names)}


def _noise_on(bpy, mat, socket):
    """Link a Noise Texture into the material's BSDF `socket`: the converter cannot take it,
    so the material goes through the node evaluator."""
    nt = mat.node_tree
    bsdf = next(n for n in nt.nodes if n.bl_idname != "ShaderNodeOutputMaterial")
    noise = nt.nodes.new("ShaderNodeTexNoise")
    nt.links.new(noise.outputs["Fac"], bsdf.inputs[socket])


@pytest.mark.blender
@pytest.mark.parametrize("path", ["converter", "nodes"])
def test_the_distribution_and_diffuse_roughness_reach_the_lobes(path):
    """Blender's defaults (Multiscatter GGX) and GGX set by hand, on Glossy, Metallic, Glass and
    the Principled's metallic, transmission and specular lobes; Beckmann on Glossy and Metallic,
    Ashikhmin-Shirley on Glossy, Beckmann on Glass; Diffuse and Principled diffuse roughness: Oren-Nayar,
    Lambert at 0."""
    bpy = bpy_module()
    import ember
    from ember.engine import scene as S
    ember.register()
    try:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        mats = [
            node_material(bpy, "glossy", "ShaderNodeBsdfAnisotropic"),
            node_material(bpy, "glossy_ggx", "ShaderNodeBsdfAnisotropic", distribution="GGX"),
            node_material(bpy, "metal", "ShaderNodeBsdfMetallic"),
            node_material(bpy, "glass", "ShaderNodeBsdfGlass", Roughness=0.4),
            node_material(bpy, "principled", "ShaderNodeBsdfPrincipled", Metallic=0.3, **{"Transmission Weight": 0.3,
                                                                                     "Diffuse Roughness": 0.6}),
            node_material(bpy, "principled_ggx", "ShaderNodeBsdfPrincipled", distribution="GGX"),
            node_material(bpy, "rough_diffuse", "ShaderNodeBsdfDiffuse", Roughness=0.5),
            node_material(bpy, "diffuse", "ShaderNodeBsdfDiffuse"),
            node_material(bpy, "glossy_beckmann", "ShaderNodeBsdfAnisotropic", distribution="BECKMANN"),
            node_material(bpy, "metal_beckmann", "ShaderNodeBsdfMetallic", distribution="BECKMANN"),
            node_material(bpy, "glass_beckmann", "ShaderNodeBsdfGlass", Roughness=0.4, distribution="BECKMANN"),
            node_material(bpy, "glossy_as", "ShaderNodeBsdfAnisotropic", distribution="ASHIKHMIN_SHIRLEY"),
        ]
        if path == "nodes":
            for mat, socket in zip(mats, ["Roughness", "Roughness", "Roughness", "Roughness", "Roughness",
                                          "Roughness", "Roughness", "Color"] + ["Roughness"] * 4):
                _noise_on(bpy, mat, socket)
        m, rows = _export(bpy, *mats)
        multi, ggx = S.DIST_MULTI_GGX, S.DIST_GGX
        kinds = lambda name: m.lobe_kind[rows[name]].tolist()
        dists = lambda name: m.lobe_distribution[rows[name]].tolist()
        if path == "nodes":  # the node evaluator keeps the graph for the varying inputs
            assert m.graphs and all(m.graphs[m.names.index(mat.name)] is not None for mat in mats)
        assert kinds("glossy") == [S.LOBE_MICROFACET] and dists("glossy") == [multi]
        assert dists("glossy_ggx") == [ggx] and dists("metal") == [multi]
        assert kinds("glass") == [S.LOBE_DIELECTRIC] and dists("glass") == [multi]
        assert kinds("principled") == [S.LOBE_MICROFACET, S.LOBE_DIELECTRIC, S.LOBE_MICROFACET, S.LOBE_OREN_NAYAR]
        assert dists("principled")[:3] == [multi] * 3 and dists("principled_ggx")[0] == ggx
        assert m.lobe_roughness[rows["principled"][3]] == pytest.approx(0.6)
        assert m.lobe_layer[rows["principled"][3]] == rows["principled"][2]
        assert kinds("principled_ggx")[-1] == S.LOBE_DIFFUSE
        assert kinds("rough_diffuse") == [S.LOBE_OREN_NAYAR] and kinds("diffuse") == [S.LOBE_DIFFUSE]
        if path == "converter":
            assert m.lobe_roughness[rows["rough_diffuse"][0]] == pytest.approx(0.5)
        # Beckmann on Glossy, Metallic and Glass; Ashikhmin-Shirley on Glossy.
        assert dists("glossy_beckmann") == dists("metal_beckmann") == dists("glass_beckmann") == [S.DIST_BECKMANN]
        assert dists("glossy_as") == [S.DIST_ASHIKHMIN_SHIRLEY]
    finally:
        ember.unregister()


COLUMNS = ROUGHNESS
ROWS = ("gold", "plastic", "glass", "oren_nayar", "beckmann", "ashikhmin_shirley")
SIZE_W, SIZE_H = 36, 12 * len(ROWS)  # 12 pixels per unit
RUNS = 8
CYCLES_SAMPLES, EMBER_SAMPLES = 256, 128  # per run


def _furnace_scene(bpy, distribution="MULTI_GGX"):
    """Spheres of radius 0.4 on a 1-unit grid in the x-z plane (columns: roughness, rows: ROWS
    from the top; the Beckmann row a copper Metallic BSDF, the Ashikhmin-Shirley row a grey
    Glossy BSDF) under a white world of strength 1,
    seen by an orthographic camera from -y."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.resolution_x, sc.render.resolution_y = SIZE_W, SIZE_H
    sc.render.resolution_percentage = 100
    cam_data = bpy.data.cameras.new("Camera")
    cam_data.type, cam_data.ortho_scale = "ORTHO", float(len(ROWS))
    cam = bpy.data.objects.new("Camera", cam_data)
    cam.location, cam.rotation_euler = (0.0, -10.0, 0.0), (np.pi / 2, 0.0, 0.0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    world = bpy.data.worlds.new("World")
    sc.world = world
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    for row, what in enumerate(ROWS):
        for col, r in enumerate(COLUMNS):
            if what == "gold":
                mat = node_material(bpy, f"{what}{r}", "ShaderNodeBsdfPrincipled", Metallic=1.0, Roughness=r,
                                distribution=distribution, **{"Base Color": (1.0, 0.78, 0.34, 1.0)})
            elif what == "plastic":
                mat = node_material(bpy, f"{what}{r}", "ShaderNodeBsdfPrincipled", Roughness=r, distribution=distribution,
                                **{"Base Color": (0.05, 0.1, 0.3, 1.0)})
            elif what == "glass":
                mat = node_material(bpy, f"{what}{r}", "ShaderNodeBsdfGlass", Roughness=r, distribution=distribution)
            elif what == "oren_nayar":
                mat = node_material(bpy, f"{what}{r}", "ShaderNodeBsdfDiffuse", Roughness=r,
                                Color=(0.5, 0.3, 0.2, 1.0))
            elif what == "beckmann":
                mat = node_material(bpy, f"{what}{r}", "ShaderNodeBsdfMetallic", Roughness=r, distribution="BECKMANN",
                                **{"Base Color": (0.95, 0.64, 0.54, 1.0)})
            else:
                mat = node_material(bpy, f"{what}{r}", "ShaderNodeBsdfAnisotropic", Roughness=r,
                                distribution="ASHIKHMIN_SHIRLEY", Color=(0.8, 0.8, 0.8, 1.0))
            bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=0.4,
                                                 location=(col - 1.0, 0.0, _row_z(row)))
            bpy.ops.object.shade_smooth()
            bpy.context.active_object.data.materials.append(mat)
    return sc


def _row_z(row):
    return (len(ROWS) - 1) / 2 - row


def _masks():
    """{(row, column): (H, W) bool} pixels well inside each sphere's disc."""
    px = len(ROWS) / SIZE_H  # world units per pixel (ortho scale spans the larger side)
    x = (np.arange(SIZE_W) + 0.5 - SIZE_W / 2) * px
    z = (SIZE_H / 2 - np.arange(SIZE_H) - 0.5) * px
    X, Z = np.meshgrid(x, z)
    return {(i, j): (X - (j - 1.0)) ** 2 + (Z - _row_z(i)) ** 2 < 0.32 ** 2
            for i in range(len(ROWS)) for j in range(len(COLUMNS))}


def _cycles_furnace(bpy, sc, samples):
    from feature_spheres import cycles_images
    return cycles_images(bpy, sc, samples, RUNS, bounces=63)


def _ember_furnace(bpy, samples):
    from ember.engine.blender.export import export_scene
    from ember.engine.session import RenderSession
    images = []
    for k in range(RUNS):
        scene, _ = export_scene(bpy.context.evaluated_depsgraph_get(),
                                overrides=dict(samples=samples, seed=1 + k, integrator="path", threads=2))
        session = RenderSession(scene)
        session.run()
        images.append(session.film.mean().reshape(SIZE_H, SIZE_W, 3))
    return np.stack(images)


def furnace_ratios(ember_images, cycles_images):
    """{(row, column): (Ember / Cycles - 1 of the sphere's mean, its standard error)}."""
    out = {}
    for key, mask in _masks().items():
        e = ember_images[:, mask].mean(axis=(1, 2))
        c = cycles_images[:, mask].mean(axis=(1, 2))
        se = np.sqrt(e.var(ddof=1) / len(e) + c.var(ddof=1) / len(c)) / c.mean()
        out[key] = (e.mean() / c.mean() - 1.0, se)
    return out


TOL = 0.005


@pytest.mark.blender
def test_spheres_in_a_white_furnace_render_as_cycles():
    """Each sphere's mean within TOL plus the Sidak-corrected noise band (a t-test with RUNS - 1
    degrees of freedom) of Cycles'."""
    from scipy import stats as st
    from stats import sidak_alpha
    bpy = bpy_module()
    import ember
    ember.register()
    try:
        sc = _furnace_scene(bpy)
        cycles = _cycles_furnace(bpy, sc, CYCLES_SAMPLES)
        emb = _ember_furnace(bpy, EMBER_SAMPLES)
    finally:
        ember.unregister()
    ratios = furnace_ratios(emb, cycles)
    t = st.t.ppf(1 - sidak_alpha(0.01, len(ratios)) / 2, RUNS - 1)
    bad = {f"{ROWS[i]} r={COLUMNS[j]}": f"{d:+.2%} (se {se:.2%})" for (i, j), (d, se) in ratios.items()
           if abs(d) > TOL + t * se}
    assert not bad, bad
