"""World export: the fast path (an Environment Texture read with Closest interpolation: its
pixels, colour spaces, projection, Mapping node chain -> env_from_world, strength), what goes
through the node graph instead, visibility and the warnings."""
import math
import os
import tempfile

import numpy as np
import pytest

os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))
bpy = pytest.importorskip("bpy")
from mathutils import Euler, Matrix  # noqa: E402

from ember.engine.blender.export import export_scene  # noqa: E402
from ember.engine.blender.export_world import MISSING_IMAGE  # noqa: E402
from ember.engine.lights.world import world_emitters  # noqa: E402
from ember.engine.textures import srgb_to_linear  # noqa: E402

pytestmark = pytest.mark.blender


def scene_with_environment(make_image, strength=1.0, interpolation="Closest"):
    """Empty file + a cube + World: Environment Texture (image from make_image(), made after
    the file is reset; Closest interpolation: the fast path) -> Background."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    bpy.ops.mesh.primitive_cube_add()
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = (0.0, -10.0, 0.0)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    world = bpy.data.worlds.new("Sky")
    nt = world.node_tree
    bg = nt.nodes["Background"]
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = make_image()
    env.interpolation = interpolation
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = strength
    sc.world = world
    return sc, nt, env


def random_pixels(h=4, w=8, seed=0):
    return np.random.default_rng(seed).random((h, w, 4)).astype(np.float32) * 10


def float_image(pixels):
    h, w = pixels.shape[:2]
    img = bpy.data.images.new("hdr", w, h, float_buffer=True)
    img.pixels.foreach_set(pixels.ravel())  # Blender rows bottom-up
    return img


def export():
    return export_scene(bpy.context.evaluated_depsgraph_get())


def test_environment_pixels_projection_and_strength():
    pixels = random_pixels()
    sc, nt, env = scene_with_environment(lambda: float_image(pixels), strength=2.5)
    scene, warnings = export()
    w = scene.world
    assert warnings == []
    assert w.image.dtype == np.float32 and w.image.shape == (4, 8, 3) and w.image.flags.c_contiguous
    np.testing.assert_array_equal(w.image, pixels[::-1, :, :3])  # top-down rows, alpha dropped
    np.testing.assert_allclose(w.color, [2.5, 2.5, 2.5])
    np.testing.assert_array_equal(w.env_from_world, np.eye(3))
    assert w.projection == "EQUIRECTANGULAR" and w.visible
    env.projection = "MIRROR_BALL"
    assert export()[0].world.projection == "MIRROR_BALL"
    sc.render.film_transparent = True  # background hidden from the camera (black, alpha 1)
    assert not export()[0].world.visible


def test_byte_images_are_decoded_by_their_colour_space():
    codes = np.arange(8 * 4 * 4, dtype=np.float32).reshape(4, 8, 4) * 2 % 256

    def byte_image(space="sRGB"):
        img = bpy.data.images.new("ldr", 8, 4)  # byte
        img.colorspace_settings.name = space  # before the pixels: a generated image is rebuilt
        img.pixels.foreach_set((codes / 255.0).ravel())
        return img

    sc, nt, env = scene_with_environment(byte_image)
    w, warnings = export()
    assert warnings == []
    np.testing.assert_allclose(w.world.image, srgb_to_linear(codes[::-1, :, :3] / 255.0), rtol=1e-6, atol=1e-7)
    env.image = byte_image("Non-Color")
    np.testing.assert_allclose(export()[0].world.image, codes[::-1, :, :3] / 255.0, rtol=1e-6)
    env.image = byte_image("Filmic Log")  # Cycles converts with OpenColorIO: the graph warns
    w, warnings = export()
    assert w.world.image is None and w.world.graph and any("Filmic Log" in t for t in warnings)


@pytest.mark.parametrize("vector_type", ["POINT", "VECTOR", "TEXTURE", "NORMAL"])
def test_mapping_chain_becomes_env_from_world(vector_type):
    """TexCoord Generated -> Mapping -> Mapping -> Environment: the lookup vector is
    M2 M1 d with Cycles' per-type matrices (checked against mathutils)."""
    sc, nt, env = scene_with_environment(lambda: float_image(random_pixels()))
    tc = nt.nodes.new("ShaderNodeTexCoord")
    m1, m2 = nt.nodes.new("ShaderNodeMapping"), nt.nodes.new("ShaderNodeMapping")
    m1.vector_type = vector_type
    rot, scale = (0.3, -0.7, 1.9), (1.0, 2.0, 0.5)
    m1.inputs["Rotation"].default_value = rot
    m1.inputs["Scale"].default_value = scale
    m2.inputs["Rotation"].default_value = (0.0, 0.0, 0.4)
    nt.links.new(tc.outputs["Generated"], m1.inputs["Vector"])
    nt.links.new(m1.outputs["Vector"], m2.inputs["Vector"])
    nt.links.new(m2.outputs["Vector"], env.inputs["Vector"])
    w, warnings = export()
    assert warnings == []
    R = np.array(Euler(rot, "XYZ").to_matrix())
    S = np.diag(scale)
    M1 = {"POINT": R @ S, "VECTOR": R @ S, "TEXTURE": np.linalg.inv(S) @ R.T,
          "NORMAL": R @ np.linalg.inv(S)}[vector_type]
    M2 = np.array(Euler((0.0, 0.0, 0.4), "XYZ").to_matrix())
    np.testing.assert_allclose(w.world.env_from_world, M2 @ M1, atol=1e-6)


def test_what_the_fast_path_does_not_read_goes_through_the_graph():
    """A Location in the Mapping, another vector source, filtered lookups, a missing image, a
    Sky Texture: exported as the node graph (World.graph), no image, no warning where the
    evaluator computes it as Cycles does."""
    sc, nt, env = scene_with_environment(lambda: float_image(random_pixels()))
    tc = nt.nodes.new("ShaderNodeTexCoord")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Location"].default_value = (1.0, 0.0, 0.0)
    nt.links.new(tc.outputs["Generated"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    w, warnings = export()
    assert warnings == [] and w.world.image is None and len(w.world.graph) == 1
    kinds = {n.kind for n in w.world.graph[0].nodes}
    assert {"ShaderNodeMapping", "ShaderNodeTexEnvironment", "ShaderNodeBackground"} <= kinds
    np.testing.assert_array_equal(w.world.color, np.ones(3))
    assert w.world.map_resolution == 0
    nt.links.new(tc.outputs["Generated"], env.inputs["Vector"])
    env.interpolation = "Linear"
    w, warnings = export()
    assert warnings == [] and w.world.image is None and w.world.graph
    # No image: Cycles' magenta everywhere, a constant table: a constant light, no table.
    env.image = None
    w, warnings = export()
    assert w.world.image is None and any("magenta" in t for t in warnings)
    constant, background, table = world_emitters(w.world)
    np.testing.assert_array_equal(constant, MISSING_IMAGE)
    assert table is None and background is not None
    # A file that cannot be loaded: magenta.
    missing = bpy.data.images.new("gone", 4, 4)
    missing.source = "FILE"
    missing.filepath = "/nonexistent/ember_sky.exr"
    env.image = missing
    w, warnings = export()
    np.testing.assert_array_equal(world_emitters(w.world)[0], MISSING_IMAGE)
    # Sky Texture: evaluated by the node program.
    sky = nt.nodes.new("ShaderNodeTexSky")
    bg = nt.nodes["Background"]
    nt.links.new(sky.outputs["Color"], bg.inputs["Color"])
    w, warnings = export()
    assert warnings == [] and w.world.graph and w.world.graph[0].nodes[0].kind == "ShaderNodeTexSky"
    # Sampling settings: Manual resolution, None.
    world = sc.world
    world.cycles.sampling_method = "MANUAL"
    world.cycles.sample_map_resolution = 256
    assert export()[0].world.map_resolution == 256
    world.cycles.sampling_method = "NONE"
    assert export()[0].world.map_resolution < 0


def test_constant_graphs_fold_to_a_colour():
    """A Background of a Blackbody colour times a Math strength is a constant: World.color,
    no graph (as the background's colour x strength)."""
    sc, nt, env = scene_with_environment(lambda: float_image(random_pixels()))
    bg = nt.nodes["Background"]
    black = nt.nodes.new("ShaderNodeBlackbody")
    black.inputs["Temperature"].default_value = 4000.0
    math_node = nt.nodes.new("ShaderNodeMath")
    math_node.operation = "MULTIPLY"
    math_node.inputs[0].default_value, math_node.inputs[1].default_value = 1.5, 2.0
    nt.links.new(black.outputs["Color"], bg.inputs["Color"])
    nt.links.new(math_node.outputs["Value"], bg.inputs["Strength"])
    w, warnings = export()
    assert warnings == [] and not w.world.graph and w.world.image is None
    from ember.engine.nodes.color import blackbody_rec709  # noqa: PLC0415
    np.testing.assert_allclose(w.world.color, 3.0 * np.maximum(blackbody_rec709(4000.0), 0.0), rtol=1e-6)


def test_rotated_environment_matches_blender_lookup():
    """A Mapping rotation about z turns the image: the direction d sees the texel at the
    rotated direction Rz d (as Cycles' POINT mapping), checked by EnvironmentMap.eval."""
    from ember.engine.lights.environment import EnvironmentMap
    pixels = random_pixels(16, 32, seed=3)
    sc, nt, env = scene_with_environment(lambda: float_image(pixels))
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(90.0))
    nt.links.new(nt.nodes.new("ShaderNodeTexCoord").outputs["Generated"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    w = export()[0].world
    e = EnvironmentMap(w.image, w.color, w.projection, w.env_from_world)
    # World -Y, rotated by +90 deg about z, looks up +X: the image centre (u = 0.5, v = 0.5).
    d = np.array([[1e-3, -1.0, 1e-3]])
    top_down = pixels[::-1, :, :3]
    np.testing.assert_array_equal(e.eval(d / np.linalg.norm(d))[0], top_down[7, 15])
    assert Matrix(w.env_from_world.tolist()).is_orthogonal
