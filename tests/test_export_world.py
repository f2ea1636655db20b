"""World export: Environment Texture pixels, colour spaces, projection, Mapping node
chain -> env_from_world, strength, visibility and the warnings for what is not supported."""
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
from ember.engine.textures import srgb_to_linear  # noqa: E402

pytestmark = pytest.mark.blender


def scene_with_environment(make_image, strength=1.0):
    """Empty file + a cube + World: Environment Texture (image from make_image(), made after
    the file is reset) -> Background."""
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
    env.image = byte_image("Filmic Log")
    w, warnings = export()
    assert len(warnings) == 1 and "Filmic Log" in warnings[0]


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


def test_unsupported_parts_warn_and_fall_back():
    sc, nt, env = scene_with_environment(lambda: float_image(random_pixels()))
    tc = nt.nodes.new("ShaderNodeTexCoord")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Location"].default_value = (1.0, 0.0, 0.0)
    nt.links.new(tc.outputs["Generated"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    w, warnings = export()
    assert len(warnings) == 1 and "Location" in warnings[0] and "'Sky'" in warnings[0]
    np.testing.assert_allclose(w.world.env_from_world, np.eye(3))
    geometry = nt.nodes.new("ShaderNodeNewGeometry")
    nt.links.new(geometry.outputs["Normal"], env.inputs["Vector"])
    w, warnings = export()
    assert len(warnings) == 1 and "Geometry" in warnings[0] and w.world.image is not None
    # No image: Cycles' magenta, constant.
    env.image = None
    w, warnings = export()
    assert w.world.image is None and len(warnings) == 1 and "magenta" in warnings[0]
    np.testing.assert_allclose(w.world.color, MISSING_IMAGE)
    # A file that cannot be loaded: the same.
    missing = bpy.data.images.new("gone", 4, 4)
    missing.source = "FILE"
    missing.filepath = "/nonexistent/ember_sky.exr"
    env.image = missing
    w, warnings = export()
    assert w.world.image is None and "could not be loaded" in warnings[0]
    # Sky Texture: no bake through the Python API; the Background's own colour is used.
    sky = nt.nodes.new("ShaderNodeTexSky")
    bg = nt.nodes["Background"]
    bg.inputs["Color"].default_value = (0.2, 0.3, 0.4, 1.0)
    nt.links.new(sky.outputs["Color"], bg.inputs["Color"])
    w, warnings = export()
    assert len(warnings) == 1 and "Sky Texture" in warnings[0]
    np.testing.assert_allclose(w.world.color, [0.2, 0.3, 0.4], rtol=1e-6)
    assert w.world.image is None


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
