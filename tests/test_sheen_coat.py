"""Sheen and coat as Cycles 5.0 renders them: the sheen lobe (microfiber LTC and Ashikhmin
velvet, engine/bsdf/sheen.py), the Principled BSDF's sheen and coat layers.

Lobe tests (no bpy): each sampler against its own pdf (chi-square, Sidak over the cases), the
white furnace (the microfiber's albedo is its table's R, at most 1, and R is the reference
model's: a short random walk in the fibre slab at a few nodes; the velvet's at most 1),
reciprocity (the velvet; the microfiber's adjoint is f with wo and wi swapped), and the
layering (a coat's weight, tint and stack). Renders (bpy): spheres under an HDRI, one per
quadrant, Ember against Cycles within noise (cycles_renders.agree, TOL)."""
import math
import pathlib
import sys

import numpy as np
import pytest

from ember.engine.bsdf import lobes, sheen
from ember.engine.bsdf.lobes import inputs
from ember.engine.scene import (DIST_MULTI_GGX, DIST_VELVET, FRESNEL_COAT, LOBE_DIFFUSE, LOBE_MICROFACET, LOBE_SHEEN,
                                MAT_NODES, Materials)

from stats import ChiSquareTest, Sphere, integrate

ROOT = pathlib.Path(__file__).resolve().parents[1]
N_CHI2 = 100_000

# name: (lobe as Materials.make takes it, wo's polar angle in degrees)
CASES = {
    "microfiber_r0.2": (dict(kind=LOBE_SHEEN, color=(0.9, 0.8, 0.7), roughness=0.2), 70),
    "microfiber_r0.6": (dict(kind=LOBE_SHEEN, color=(0.9, 0.8, 0.7), roughness=0.6), 30),
    "microfiber_r1": (dict(kind=LOBE_SHEEN, color=(0.9, 0.8, 0.7), roughness=1.0), 5),
    "velvet_r0.5": (dict(kind=LOBE_SHEEN, color=(0.9, 0.8, 0.7), roughness=0.5, distribution=DIST_VELVET), 60),
    "coat_r0.3": (dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_COAT, color=(0.8, 0.8, 0.8), tint=(0.9, 0.5, 0.3),
                       ior=1.5, roughness=0.3, distribution=DIST_MULTI_GGX), 50),
}


def lobe_and_params(name, k, theta=None):
    """(lobe, its parameters at k rows, wo (k,3) at azimuth 1 rad)."""
    spec, deg = CASES[name]
    m = Materials.make([dict(kind=MAT_NODES, lobes=[spec])])
    lobe = lobes.LOBES[spec["kind"]]
    p = lobe.parameters(m, np.zeros(k, np.int64), np.arange(k), inputs.Sources(None), np.zeros(k, bool))
    t = np.radians(deg if theta is None else theta)
    wo = np.tile([np.sin(t) * np.cos(1.0), np.sin(t) * np.sin(1.0), np.cos(t)], (k, 1))
    return lobe, p, wo


@pytest.mark.parametrize("name", list(CASES))
def test_samples_follow_the_pdf_chi2(name):
    lobe, p, wo = lobe_and_params(name, N_CHI2)

    def sampler(u):
        s = lobe.sample(p, wo, u[:, :2], u[:, 2])
        return s.wi, s.pdf > 0

    def pdf(d):
        lobe_d, q, wo_d = lobe_and_params(name, len(d))
        return lobe_d.pdf(q, wo_d, d)

    ChiSquareTest(Sphere(), sampler, pdf, resolution=(40, 30), n_samples=N_CHI2, seed=list(CASES).index(name),
                  sample_dim=3, order=6, name=name).check(n_tests=len(CASES))


@pytest.mark.parametrize("name", list(CASES))
def test_the_sample_pdf_is_evals(name):
    k = 20_000
    lobe, p, wo = lobe_and_params(name, k)
    rng = np.random.default_rng(5)
    s = lobe.sample(p, wo, rng.random((k, 2)), rng.random(k))
    kept = s.pdf > 0
    assert kept.mean() > 0.9 and not np.any(s.delta)
    f, pdf = lobe.eval(p.take(np.flatnonzero(kept)), wo[kept], s.wi[kept])
    np.testing.assert_allclose(pdf, s.pdf[kept], rtol=1e-9)
    assert np.all(np.isfinite(f)) and np.all(f >= 0)


def _albedo(name, theta):
    """(integral of f cos over the sphere (3,), the lobe's albedo estimate (3,)) at wo's theta."""
    lobe, _, _ = lobe_and_params(name, 1)

    def f_cos(d):
        _, q, wo = lobe_and_params(name, len(d), theta)
        return lobe.eval(q, wo, d)[0][:, 0] * np.maximum(d[:, 2], 0.0)

    _, q, wo = lobe_and_params(name, 1, theta)
    return integrate(Sphere(), f_cos, (200, 160), order=6).sum(), lobe.albedo(q, wo)[0, 0]


@pytest.mark.parametrize("name", ["microfiber_r0.2", "microfiber_r0.6", "microfiber_r1"])
@pytest.mark.parametrize("theta", [0.0, 45.0, 80.0])
def test_microfiber_white_furnace_is_its_table_albedo(name, theta):
    """f cos integrates to colour x R (the LTC density is normalised), R <= 1."""
    total, estimate = _albedo(name, theta)
    assert estimate <= CASES[name][0]["color"][0] + 1e-12
    assert total == pytest.approx(estimate, rel=2e-3, abs=1e-6)


def test_velvet_white_furnace_at_most_one():
    for theta in (0.0, 30.0, 60.0, 85.0):
        total, _ = _albedo("velvet_r0.5", theta)
        assert 0.0 < total <= 0.9 + 1e-9  # the colour's red channel: 0.9


def test_the_table_is_within_bounds_and_smooth():
    t = sheen.table()
    assert np.all((t["R"] >= 0) & (t["R"] <= 1)) and np.all(t["a"] >= 0)
    assert t["R"][-1].min() > 0.3  # roughness 1 scatters a good share back at every angle


@pytest.mark.parametrize("mu, roughness", [(0.1, 0.6), (0.55, 0.3), (0.9, 1.0)])
def test_the_table_albedo_is_the_reference_models(mu, roughness):
    """R at table nodes against a fresh random walk in the fibre slab (tools/sheen_table.py),
    within 4 binomial standard errors plus the table's own (its walks' count)."""
    sys.path.insert(0, str(ROOT / "tools"))
    import sheen_table
    nodes = np.maximum(0.01, np.linspace(0.0, 1.0, sheen.GRID))
    i, j = np.argmin(np.abs(nodes - mu)), np.argmin(np.abs(nodes - roughness))
    n = 40_000
    R_walk = len(sheen_table.walk(nodes[i], nodes[j], n, np.random.default_rng(17))) / n
    R = sheen.table()["R"][j, i]
    se = np.sqrt(R * (1 - R) * (1 / n + 1 / 200_000))
    assert abs(R_walk - R) <= 4 * se, (R_walk, R)


def test_velvet_is_reciprocal_and_microfiber_adjoint_swaps():
    k = 4000
    rng = np.random.default_rng(3)
    for name in ("velvet_r0.5", "microfiber_r0.6"):
        lobe, p, wo = lobe_and_params(name, k)
        wo = lobe.sample(p, wo, rng.random((k, 2)), rng.random(k)).wi  # random pairs
        wi = lobe.sample(p, wo, rng.random((k, 2)), rng.random(k)).wi
        keep = (wo[:, 2] > 0.05) & (wi[:, 2] > 0.05)
        wo, wi = wo[keep], wi[keep]
        q = p.take(np.flatnonzero(keep))
        forward, backward = lobe.eval(q, wo, wi)[0], lobe.eval(q, wi, wo)[0]
        if name.startswith("velvet"):
            np.testing.assert_allclose(forward, backward, rtol=1e-9)
        else:
            _, adj, _ = lobe_and_params(name, int(keep.sum()))
            adj.adjoint = True
            np.testing.assert_allclose(lobe.eval(adj, wo, wi)[0], backward, rtol=1e-9)
            assert np.max(np.abs(forward - backward)) > 1e-3  # not reciprocal: the adjoint matters


@pytest.mark.parametrize("theta", [0.0, 60.0])
def test_coat_albedo_and_layer_weight_are_cycles(theta):
    """A smooth coat of weight w: albedo w F(cos_o) (the table's s is the remapped Fresnel
    there; no energy compensation at roughness 0), and the weight under it
    (1 - w F(cos_o)) mix(1, tint^(1 / cos_t), w), cos_t of wo refracted into the coat."""
    from ember.engine.bsdf import fresnel
    lobe, p, wo = lobe_and_params("coat_r0.3", 1, theta=theta)
    p.roughness[:] = 0.0
    p.alpha[:] = 0.0
    w, eta, tint = 0.8, 1.5, np.array([0.9, 0.5, 0.3])
    mu = np.cos(np.radians(theta))
    F = fresnel.dielectric(np.array([mu]), eta)[0]
    cos_t = np.sqrt(1.0 - (1.0 - mu * mu) / eta ** 2)
    np.testing.assert_allclose(lobe.albedo(p, wo)[0], w * F, rtol=1e-9)
    expected = (1 - w * F) * (1 + w * (tint ** (1 / cos_t) - 1))
    np.testing.assert_allclose(lobe.layer_weight(p, wo)[0], expected, rtol=3e-3)


def test_lookup_reads_the_table_at_its_nodes():
    t = sheen.table()
    j, i = np.meshgrid(np.arange(1, 32, 5), np.arange(0, 32, 7), indexing="ij")
    a, b, R = sheen.lookup(i.ravel() / 31.0, np.maximum(j.ravel() / 31.0, sheen.MIN_ROUGHNESS))
    np.testing.assert_allclose(R, t["R"][j, i].ravel(), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(a, t["a"][j, i].ravel(), rtol=1e-9, atol=1e-9)


def test_layers_stack_down_the_principled_bsdf():
    """Diffuse under a specular layer under a coat under a sheen keeps the product of what each
    leaves (Cycles' running weight); the coat and sheen keep their own weights' colour."""
    from core_scenes import furnace_box
    from ember.engine.bsdf.closure import Closure
    from ember.engine.scene import FRESNEL_DIELECTRIC
    lobe_rows = [dict(kind=LOBE_SHEEN, color=(0.5, 0.5, 0.5), roughness=0.5),
                 dict(CASES["coat_r0.3"][0], layer=0),
                 dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_DIELECTRIC, ior=1.5, roughness=0.5, layer=1),
                 dict(kind=LOBE_DIFFUSE, color=(0.8, 0.2, 0.2), layer=2)]
    scene = furnace_box().replace(materials=Materials.make([dict(kind=MAT_NODES, lobes=lobe_rows)]))
    t = np.radians(40)
    wo = np.array([[np.sin(t), 0.0, np.cos(t)]])
    n = np.array([[0.0, 0.0, 1.0]])
    c = Closure(scene, np.zeros(1, np.int64), n, n, wo, np.zeros(1, np.int64), np.full((1, 3), 1 / 3))
    left = []
    for k, spec in enumerate(lobe_rows[:3]):
        lobe = lobes.LOBES[spec["kind"]]
        m = Materials.make([dict(kind=MAT_NODES, lobes=[dict(spec, layer=-1)])])
        p = lobe.parameters(m, np.zeros(1, np.int64), np.zeros(1, np.int64), inputs.Sources(None), np.zeros(1, bool))
        w = lobe.layer_weight(p, wo)
        left.append(w[0] if w.ndim == 2 else np.full(3, w[0]))
    np.testing.assert_allclose(c.weight[0], 1.0)
    np.testing.assert_allclose(c.weight[1], left[0], rtol=1e-12)
    np.testing.assert_allclose(c.weight[2], left[0] * left[1], rtol=1e-12)
    np.testing.assert_allclose(c.weight[3], left[0] * left[1] * left[2], rtol=1e-12)


# ----------------------------------------------------------------------------------------------
# Against Cycles

SIZE = 32
SEEDS = 6
EMBER_SAMPLES = 64
CYCLES_SAMPLES = 256
TOL = 0.01
HDRI = "courtyard.exr"


def sheen_principled(pb):
    pb.inputs["Base Color"].default_value = (0.25, 0.04, 0.04, 1.0)
    pb.inputs["Sheen Weight"].default_value = 1.0
    pb.inputs["Sheen Roughness"].default_value = 0.4
    pb.inputs["Sheen Tint"].default_value = (1.0, 0.9, 0.7, 1.0)


def coat_diffuse(pb):
    pb.inputs["Base Color"].default_value = (0.8, 0.1, 0.1, 1.0)
    pb.inputs["Coat Weight"].default_value = 1.0
    pb.inputs["Coat Roughness"].default_value = 0.15
    pb.inputs["Coat IOR"].default_value = 1.6
    pb.inputs["Coat Tint"].default_value = (0.9, 0.8, 0.5, 1.0)


def coat_metal(pb):
    pb.inputs["Base Color"].default_value = (0.9, 0.6, 0.3, 1.0)
    pb.inputs["Metallic"].default_value = 1.0
    pb.inputs["Roughness"].default_value = 0.4
    pb.inputs["Coat Weight"].default_value = 0.8
    pb.inputs["Coat Roughness"].default_value = 0.3
    pb.inputs["Coat Tint"].default_value = (0.7, 0.8, 1.0, 1.0)


def coat_and_sheen(pb):
    coat_diffuse(pb)
    pb.inputs["Base Color"].default_value = (0.1, 0.3, 0.7, 1.0)
    pb.inputs["Sheen Weight"].default_value = 0.7
    pb.inputs["Sheen Roughness"].default_value = 0.8


def sheen_node(distribution, color, roughness):
    def build(nt, out):
        node = nt.nodes.new("ShaderNodeBsdfSheen")
        node.distribution = distribution
        node.inputs["Color"].default_value = (*color, 1.0)
        node.inputs["Roughness"].default_value = roughness
        nt.links.new(node.outputs["BSDF"], out.inputs["Surface"])
    return build


def principled(setup):
    def build(nt, out):
        pb = nt.nodes["Principled BSDF"]
        setup(pb)
    return build


# Two rows of four spheres: each half of the image holds four, one per quadrant of it
# (region_means' regions), top-left first.
SPHERES = (principled(sheen_principled), sheen_node("MICROFIBER", (0.8, 0.8, 0.8), 0.3),
           principled(coat_diffuse), principled(coat_metal),
           sheen_node("MICROFIBER", (0.7, 0.8, 0.9), 0.9), sheen_node("ASHIKHMIN", (1.0, 1.0, 1.0), 0.5),
           principled(coat_and_sheen), sheen_node("MICROFIBER", (0.9, 0.5, 0.2), 0.05))
ONE_FEATURE = {  # the bench's single-sphere scenes
    "principled sheen": principled(sheen_principled),
    "sheen microfiber r0.3": sheen_node("MICROFIBER", (0.8, 0.8, 0.8), 0.3),
    "sheen velvet r0.5": sheen_node("ASHIKHMIN", (1.0, 1.0, 1.0), 0.5),
    "coat over red diffuse": principled(coat_diffuse),
    "coat over metal": principled(coat_metal),
}


def spheres_scene(builders, size=SIZE):
    """One sphere (one builder) or two rows of four (eight) with the materials `builders` under
    the HDRI, seen from the front; size: the image's height in pixels."""
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    world = bpy.data.worlds.new("World")
    sc.world = world
    nt = world.node_tree
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(str(pathlib.Path(bpy.utils.resource_path("LOCAL")) / "datafiles" /
                                         "studiolights" / "world" / HDRI))
    nt.links.new(env.outputs["Color"], nt.nodes["Background"].inputs["Color"])
    # A smaller importance map than Cycles' automatic one: the same image, set up in a fraction
    # of the time (the map only changes the noise).
    world.cycles.sampling_method, world.cycles.sample_map_resolution = "MANUAL", 256
    places = [(0.0, 0.0)] if len(builders) == 1 else [(x, z) for z in (1.1, -1.1) for x in (-3.3, -1.1, 1.1, 3.3)]
    for k, (build, (x, z)) in enumerate(zip(builders, places)):
        bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, location=(x, 0.0, z), segments=48, ring_count=24)
        ob = bpy.context.active_object
        bpy.ops.object.shade_smooth()
        mat = bpy.data.materials.new(f"m{k}")
        build(mat.node_tree, mat.node_tree.nodes["Material Output"])
        ob.data.materials.append(mat)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 2.2 if len(builders) == 1 else 8.8
    cam.location, cam.rotation_euler = (0.0, -6.0, 0.0), (math.radians(90.0), 0.0, 0.0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    sc.render.resolution_x, sc.render.resolution_y = (size if len(builders) == 1 else 2 * size), size
    sc.render.resolution_percentage = 100
    sc.cycles.pixel_filter_type = "BOX"
    sc.cycles.device = "CPU"
    sc.cycles.use_denoising = False
    sc.cycles.use_adaptive_sampling = False
    return sc


@pytest.fixture(scope="module")
def addon():
    bpy = pytest.importorskip("bpy")
    import ember
    ember.register()
    yield bpy
    ember.unregister()


@pytest.mark.blender
def test_spheres_render_as_cycles(addon, tmp_path):
    """Each half of the image (four spheres) by its quadrants, as cycles_renders.agree compares."""
    from cycles_renders import agree, cycles_image, ember_image
    sc = spheres_scene(SPHERES)
    cycles = [cycles_image(sc, CYCLES_SAMPLES, 100 + k, tmp_path / f"cycles{k}.exr") for k in range(SEEDS)]
    ember_images = [ember_image(sc, "PATH", EMBER_SAMPLES, k) for k in range(SEEDS)]
    for half in (slice(0, SIZE), slice(SIZE, 2 * SIZE)):
        agree([e[:, half] for e in ember_images], [c[:, half] for c in cycles], 2, TOL)
