"""Multiscatter GGX (engine/bsdf/multiscatter.py) as Cycles renders it.

- The albedo table: E(roughness, mu) read from it against a direct quadrature of the
  single-scattering lobe's reflected energy (uniform directions, many samples).
- Rendered: three spheres in a uniform grey world (no lights), a Glossy BSDF (white, roughness
  1), a metallic Principled BSDF (gold, roughness 0.8) and a dielectric one (base colour 0.6,
  roughness 0.7), every node at Blender's default Multiscatter GGX. Cycles renders them
  brighter than single-scattering GGX would (a rough white Glossy nearly as bright as the
  world); Ember's mean over each sphere's third of the image agrees with Cycles' within TOL
  plus the Sidak-corrected noise band of the between-seed spread (a t-test).
"""
import math

import numpy as np
import pytest
from scipy import stats as st

from ember.engine.bsdf import microfacet, multiscatter

from stats import sidak_alpha


@pytest.mark.parametrize("roughness,mu", [(0.3, 0.8), (0.6, 0.2), (0.9, 0.5), (1.0, 1.0), (0.75, 0.05)])
def test_albedo_table_matches_a_quadrature(roughness, mu):
    rng = np.random.default_rng(3)
    n = 400_000
    u = rng.random((n, 2))
    z, phi = u[:, 0], 2.0 * math.pi * u[:, 1]
    r = np.sqrt(1.0 - z * z)
    wi = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    wo = np.tile([math.sqrt(1.0 - mu * mu), 0.0, mu], (n, 1))
    f = microfacet.eval_reflection(np.full(n, roughness ** 2), wo, wi, np.ones((n, 3)))[:, 0]
    values = f * z * 2.0 * math.pi  # uniform hemisphere pdf 1 / (2 pi)
    E, _ = multiscatter.energy(np.array([roughness]), np.array([mu]))
    # The table interpolates between 32 nodes: a few thousandths off between them.
    assert abs(E[0] - values.mean()) <= 0.006 + 4.0 * values.std() / math.sqrt(n)


def test_compensation_is_energy_conserving_for_a_white_lobe():
    """Fss = 1: c = 1 / E, so the lobe reflects all the energy at every angle."""
    rough, mu = np.array([0.2, 0.7, 1.0]), np.array([0.9, 0.4, 0.1])
    c, E = multiscatter.compensation(np.ones((3, 3)), rough, mu)
    assert np.allclose(c * E[:, None], 1.0)


bpy = pytest.importorskip("bpy")

import ember  # noqa: E402
from ember.engine.blender import final  # noqa: E402

SIZE = (48, 16)
SEEDS = 3
EMBER_SAMPLES = 32
CYCLES_SAMPLES = 64
TOL = 0.01


@pytest.fixture(scope="module")
def addon():
    ember.register()
    yield
    ember.unregister()


def _sphere(x, build):
    bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=0.9, location=(x, 0.0, 0.0))
    bpy.ops.object.shade_smooth()
    ob = bpy.context.active_object
    mat = bpy.data.materials.new(f"m{x}")
    nt = mat.node_tree
    for n in list(nt.nodes):
        if n.bl_idname != "ShaderNodeOutputMaterial":
            nt.nodes.remove(n)
    node = build(nt)
    node.distribution = "MULTI_GGX"
    nt.links.new(node.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    ob.data.materials.append(mat)


def _glossy(nt):
    node = nt.nodes.new("ShaderNodeBsdfAnisotropic")
    node.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    node.inputs["Roughness"].default_value = 1.0
    return node


def _metal(nt):
    node = nt.nodes.new("ShaderNodeBsdfPrincipled")
    node.inputs["Base Color"].default_value = (0.95, 0.7, 0.3, 1.0)
    node.inputs["Metallic"].default_value = 1.0
    node.inputs["Roughness"].default_value = 0.8
    return node


def _dielectric(nt):
    node = nt.nodes.new("ShaderNodeBsdfPrincipled")
    node.inputs["Base Color"].default_value = (0.6, 0.6, 0.6, 1.0)
    node.inputs["Roughness"].default_value = 0.7
    return node


def _scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    world = bpy.data.worlds.new("World")
    world.color = (0.5, 0.5, 0.5)
    sc.world = world
    for x, build in zip((-2.0, 0.0, 2.0), (_glossy, _metal, _dielectric)):
        _sphere(x, build)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 6.0
    cam.location, cam.rotation_euler = (0.0, -8.0, 0.0), (math.pi / 2, 0.0, 0.0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    sc.render.resolution_x, sc.render.resolution_y = SIZE
    sc.render.resolution_percentage = 100
    sc.cycles.pixel_filter_type = "BOX"
    sc.cycles.device = "CPU"
    sc.cycles.use_denoising = False
    sc.cycles.use_adaptive_sampling = False
    return sc


class _Film:
    film = None

    def on_progress(self, layer, progress):
        self.film = progress.film


def _ember(sc, seed):
    sc.render.engine = "EMBER"
    sc.ember.integrator, sc.ember.samples, sc.ember.seed = "PATH", EMBER_SAMPLES, seed
    grab = _Film()
    final.listeners.append(grab)
    try:
        bpy.ops.render.render()
    finally:
        final.listeners.remove(grab)
    return grab.film.mean().reshape(SIZE[1], SIZE[0], 3)


def _cycles(sc, seed, path):
    sc.render.engine = "CYCLES"
    sc.cycles.samples, sc.cycles.seed = CYCLES_SAMPLES, seed
    sc.render.filepath = str(path)
    sc.render.image_settings.file_format = "OPEN_EXR"
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(path))
    pixels = np.array(img.pixels[:]).reshape(SIZE[1], SIZE[0], 4)[::-1, :, :3]
    bpy.data.images.remove(img)
    return pixels


def _thirds(images):
    """(SEEDS, 3) means over each sphere's third of the image (all channels)."""
    w = SIZE[0] // 3
    return np.array([[img[:, k * w:(k + 1) * w].mean() for k in range(3)] for img in images])


@pytest.mark.blender
def test_multiscatter_ggx_renders_as_cycles(addon, tmp_path):
    sc = _scene()
    cycles = [_cycles(sc, 100 + k, tmp_path / f"c{k}.exr") for k in range(SEEDS)]
    ember_images = [_ember(sc, k) for k in range(SEEDS)]
    e, c = _thirds(ember_images), _thirds(cycles)
    diff = e.mean(axis=0) - c.mean(axis=0)
    se = np.sqrt(e.var(axis=0, ddof=1) / SEEDS + c.var(axis=0, ddof=1) / SEEDS)
    t = st.t.ppf(1 - sidak_alpha(0.01, e.shape[1]) / 2, SEEDS - 1)
    ok = np.abs(diff) <= TOL * np.abs(c.mean(axis=0)) + t * se
    assert ok.all(), f"Ember / Cycles per sphere {e.mean(0) / c.mean(0)}, noise band {t * se / c.mean(0)}"
