"""Normal-mapped diffuse light as Cycles shades it: its bump shadowing term (closure/bsdf.h
bump_shadowing_term, after Conty Estevez et al. 2019) and a Normal Map of constant colour.

A plane whose Principled BSDF (no specular) has its normal tilted by a Normal Map node of
constant colour, lit by a sun at a grazing angle from either side of the tilt (a delta light:
the image is nearly noise-free). Without the term Ember is 16-30 % brighter than Cycles; without
the constant Normal Map the plane is flat (off by a factor 2 or 14); the image means agree
within TOL.
"""
import math

import pytest

bpy = pytest.importorskip("bpy")

import ember  # noqa: E402
from cycles_renders import cycles_image, ember_image  # noqa: E402

pytestmark = pytest.mark.blender
SIZE = 16
SAMPLES = 16
TOL = 0.05

CASES = {  # name: (Normal Map colour, sun rotation in degrees)
    "towards the tilt": ((0.85, 0.5, 0.85), (75.0, 0.0, 90.0)),
    "against the tilt": ((0.85, 0.5, 0.85), (60.0, 0.0, -90.0)),
    "grazing": ((0.7, 0.5, 0.95), (80.0, 0.0, 90.0)),
}


@pytest.fixture(scope="module", autouse=True)
def addon():
    ember.register()
    yield
    ember.unregister()


def _scene(color, rotation):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    world = bpy.data.worlds.new("World")
    world.color = (0.0, 0.0, 0.0)
    sc.world = world
    mesh = bpy.data.meshes.new("plane")
    mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    for loop, corner in zip(uv.data, ((0, 0), (1, 0), (1, 1), (0, 1))):
        loop.uv = corner
    sc.collection.objects.link(bpy.data.objects.new("plane", mesh))
    mat = bpy.data.materials.new("tilted")
    nt = mat.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    nmap = nt.nodes.new("ShaderNodeNormalMap")
    nmap.inputs["Color"].default_value = (*color, 1.0)
    nt.links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    mesh.materials.append(mat)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy, sun.data.angle = 3.0, 0.0
    sun.rotation_euler = tuple(math.radians(a) for a in rotation)
    sc.collection.objects.link(sun)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.angle = math.radians(30.0)
    cam.location = (0.0, 0.0, 3.0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    sc.render.resolution_x = sc.render.resolution_y = SIZE
    sc.render.resolution_percentage = 100
    sc.cycles.device = "CPU"
    sc.cycles.use_denoising = False
    sc.cycles.use_adaptive_sampling = False
    return sc


@pytest.mark.parametrize("case", list(CASES))
def test_normal_mapped_diffuse_light_matches_cycles(case, tmp_path):
    sc = _scene(*CASES[case])
    cycles = cycles_image(sc, SAMPLES, 0, tmp_path / "cycles.exr").mean()
    ember_mean = ember_image(sc, "PATH", SAMPLES, 0).mean()
    assert cycles > 0.01
    assert ember_mean == pytest.approx(cycles, rel=TOL), (ember_mean / cycles)
