"""Materials through the node evaluator, rendered: Ember against Cycles on scenes an artist
would make, built here with bpy - a floor whose colour is a Noise Texture through a Color Ramp,
a sphere mixing diffuse and glossy by a Voronoi Texture, and a floor lit by an emitter whose
colour is a Checker Texture (textured emission: light sampling, emission found by rays and
photon emission all read the texture). Both renderers run SEEDS independent renders here; the
image's mean and its four quadrants' means agree within TOL (modelling: tessellation, float32)
plus the Sidak-corrected noise band of the between-seed spread (a t-test with SEEDS - 1
degrees of freedom per renderer). A 3 % error in a textured emitter's radiance fails it.
Nodes that trace rays render here too: Ambient Occlusion as emission on a floor and boxes
(every pixel is an AO estimate), outside and inside, local and not.

GGX is set on both sides where the scene is glossy: Cycles 5.0's default, Multiscatter GGX, is
compared in test_multiscatter.py."""
import pytest

bpy = pytest.importorskip("bpy")

import ember  # noqa: E402
from cycles_renders import agree, cycles_image, ember_image  # noqa: E402
from cycles_scenes import camera, new_scene, node_material  # noqa: E402

pytestmark = pytest.mark.blender
SIZE = 32
SEEDS = 4
EMBER_SAMPLES = 64  # per seed
CYCLES_SAMPLES = 256  # per seed
TOL = 0.01


@pytest.fixture(scope="module", autouse=True)
def addon():
    ember.register()
    yield
    ember.unregister()


def procedural_scene():
    sc = new_scene(SIZE, world=(0.05, 0.05, 0.06))
    bpy.ops.mesh.primitive_plane_add(size=6)
    floor = bpy.context.active_object
    mat = bpy.data.materials.new("Floor")
    nt = mat.node_tree
    pb = nt.nodes["Principled BSDF"]
    pb.distribution = "GGX"
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 3.0
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.8, 0.1, 0.05, 1)
    ramp.color_ramp.elements[1].color = (0.1, 0.3, 0.9, 1)
    nt.links.new(noise.outputs["Fac"], ramp.inputs["Fac"])
    nt.links.new(ramp.outputs["Color"], pb.inputs["Base Color"])
    pb.inputs["Roughness"].default_value = 0.6
    floor.data.materials.append(mat)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, location=(0, 0, 1), segments=48, ring_count=24)
    bpy.ops.object.shade_smooth()
    ball = bpy.context.active_object
    mat, nt, out = node_material("Ball")
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (0.9, 0.8, 0.2, 1)
    g = nt.nodes.new("ShaderNodeBsdfAnisotropic")
    g.distribution = "GGX"
    g.inputs["Roughness"].default_value = 0.25
    mix = nt.nodes.new("ShaderNodeMixShader")
    vor = nt.nodes.new("ShaderNodeTexVoronoi")
    vor.inputs["Scale"].default_value = 4.0
    nt.links.new(vor.outputs["Distance"], mix.inputs["Fac"])
    nt.links.new(d.outputs[0], mix.inputs[1])
    nt.links.new(g.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    ball.data.materials.append(mat)
    bpy.ops.object.light_add(type="AREA", location=(2, -2, 4), rotation=(0.5, 0.4, 0.6))
    light = bpy.context.active_object
    light.data.energy, light.data.size = 800, 1.5
    camera(sc, (5, -5, 3.5), (1.15, 0, 0.785))
    return sc


def textured_emitter_scene(scale=1.0):
    sc = new_scene(SIZE)
    bpy.ops.mesh.primitive_plane_add(size=6)
    floor = bpy.context.active_object
    mat, nt, out = node_material("Floor")
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (0.7, 0.7, 0.7, 1)
    nt.links.new(d.outputs[0], out.inputs["Surface"])
    floor.data.materials.append(mat)
    bpy.ops.mesh.primitive_plane_add(size=3, location=(0, 0, 2.5), rotation=(0.35, 0, 0))
    lamp = bpy.context.active_object
    mat, nt, out = node_material("Lamp")
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = 6.0 * scale
    chk = nt.nodes.new("ShaderNodeTexChecker")
    chk.inputs["Scale"].default_value = 3.0
    chk.inputs["Color1"].default_value = (1, 0.9, 0.2, 1)
    chk.inputs["Color2"].default_value = (0.02, 0.05, 0.6, 1)
    nt.links.new(chk.outputs["Color"], em.inputs["Color"])
    nt.links.new(em.outputs[0], out.inputs["Surface"])
    lamp.data.materials.append(mat)
    # Looking down at the floor only: its light is all from the textured emitter (no direct view).
    camera(sc, (0, -1.5, 6.0), (0.25, 0, 0))
    return sc


def _ao_material(name, distance, samples, color, inside=False, only_local=False):
    mat, nt, out = node_material(name)
    ao = nt.nodes.new("ShaderNodeAmbientOcclusion")
    ao.samples, ao.inside, ao.only_local = samples, inside, only_local
    ao.inputs["Distance"].default_value = distance
    ao.inputs["Color"].default_value = color + (1.0,)
    em = nt.nodes.new("ShaderNodeEmission")
    nt.links.new(ao.outputs["Color"], em.inputs["Color"])
    nt.links.new(em.outputs[0], out.inputs["Surface"])
    return mat


def ambient_occlusion_scene():
    """Boxes on a floor, all emitting their AO: the floor's darkens toward the boxes, a box's
    own (Only Local, Inside) toward its faces' edges from the inside, and the second box's
    (Only Local, outside) not at all, though the floor and the first box are in reach."""
    sc = new_scene(SIZE)
    bpy.ops.mesh.primitive_plane_add(size=6)
    bpy.context.active_object.data.materials.append(_ao_material("Floor", 0.8, 4, (0.9, 0.7, 0.4)))
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(-0.2, 0.0, 0.5), rotation=(0, 0, 0.3))
    bpy.context.active_object.data.materials.append(
        _ao_material("Inside", 0.6, 4, (0.3, 0.8, 0.9), inside=True, only_local=True))
    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(0.9, 0.4, 0.4))
    bpy.context.active_object.data.materials.append(_ao_material("Outside", 1.5, 2, (1.0, 1.0, 1.0), only_local=True))
    camera(sc, (3.2, -3.2, 3.0), (0.95, 0, 0.785))
    return sc


def _compare(build, integrator, tmp_path, n_tests):
    sc = build()
    cycles = [cycles_image(sc, CYCLES_SAMPLES, 100 + k, tmp_path / f"cycles{k}.exr") for k in range(SEEDS)]
    ember_images = [ember_image(sc, integrator, EMBER_SAMPLES, k) for k in range(SEEDS)]
    return agree(ember_images, cycles, n_tests, TOL)


def test_procedural_materials_render_as_cycles(tmp_path):
    _compare(procedural_scene, "PATH", tmp_path, 1)


@pytest.mark.parametrize("integrator", ["PATH", "PHOTON"])
def test_a_textured_emitter_lights_as_cycles(integrator, tmp_path):
    _compare(textured_emitter_scene, integrator, tmp_path, 2)


def test_ambient_occlusion_renders_as_cycles(tmp_path):
    _compare(ambient_occlusion_scene, "PATH", tmp_path, 1)
