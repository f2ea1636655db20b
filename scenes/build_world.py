"""Build the environment-lighting scenes from bpy and NumPy, and save them as .blend.

    python scenes/build_world.py [--out DIR] [--only hdri|env_marker] [--glossy]

hdri.blend: a grey ground plane out to the horizon, a white diffuse sphere and a blue object (diffuse; `--glossy`
makes it a Glossy BSDF once Ember has glossy materials) under a procedural HDRI: blue sky
brighter towards the horizon with faint cloud bands, brown ground, and a sun of 4 pixels with
~6000x the sky's radiance, 35 deg up and coming from the camera's front right. The map
(256 x 128 float EXR, packed into the .blend) goes through Texture Coordinate (Generated) ->
Mapping (POINT, rotation z = 21 texels = 29.5 deg) -> Environment Texture (Closest) ->
Background (strength 1.5), so the export of the rotation and strength is part of what the
reference checks.

env_marker.blend: proves the direction -> pixel orientation against Cycles. The camera at
the origin looks along +X (Z up, 100 deg field of view); the map is dark grey with a red
marker at +X, a green one 40 deg towards +Y (so on the image's left) and a blue one 35 deg up,
plus a small grey cube low in the view (Ember needs geometry). No mapping node.

Maps are written with engine.imageio (float32 EXR), loaded by Blender and packed, so the .blend
files are self-contained. Needs the bpy module or `blender -b -P scenes/build_world.py --`.
"""
from __future__ import annotations

import math
import os
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))
import bpy  # noqa: E402

sys.path.insert(0, HERE)
sys.path.insert(0, ROOT)
import build  # noqa: E402  (scenes/build.py: shared helpers)
from _bootstrap import load_ember  # noqa: E402

load_ember()
from ember.engine import imageio  # noqa: E402

HDRI_SIZE = (256, 128)  # W, H
# 21 texels of the 256-wide map (29.53 deg): a whole number of texels, so Cycles' importance
# map, which it bakes in world space at cell centres, lines up with the texture. With a
# fractional offset (30 deg measured) Cycles gives a sliver of the 2-texel sun only sky
# importance and its 16 x 1024-spp reference comes out ~1 % dark where the sun lights (a heavy
# tail it does not resolve); Ember's table lives in texture space and is not affected.
HDRI_ROTATION_Z = 21 * 2.0 * math.pi / 256
HDRI_STRENGTH = 1.5
SUN_RADIANCE = (3200.0, 3000.0, 2700.0)
SUN_AZIMUTH, SUN_ELEVATION = math.radians(-50.0), math.radians(35.0)  # world: front right


def equirect_directions(width, height):
    """(H, W, 3) unit directions of pixel centres in Cycles' equirectangular mapping
    (u = 0.5 - atan2(y, x) / 2 pi, v = 1 - theta / pi, rows top-down)."""
    u = (np.arange(width) + 0.5) / width
    theta = (np.arange(height) + 0.5) / height * np.pi
    phi = np.pi * (1.0 - 2.0 * u)
    st = np.sin(theta)[:, None]
    return np.stack([st * np.cos(phi)[None, :], st * np.sin(phi)[None, :],
                     np.broadcast_to(np.cos(theta)[:, None], (height, width))], axis=-1)


def equirect_pixel(d, width, height):
    """(row, col) of the pixel holding unit direction d (rows top-down)."""
    u = 0.5 - math.atan2(d[1], d[0]) / (2.0 * math.pi)
    theta = math.acos(max(-1.0, min(1.0, d[2])))
    return min(int(theta / math.pi * height), height - 1), min(int(u * width), width - 1)


def sky_map(width, height, rotation_z):
    """The HDRI (H, W, 3) float32: sky + ground + a 2x2-pixel sun placed so that, after the
    Mapping node's rotation about z, the sun is at (SUN_AZIMUTH, SUN_ELEVATION) in the world."""
    d = equirect_directions(width, height)
    z = d[..., 2]
    az = np.arctan2(d[..., 1], d[..., 0])
    up = np.clip(z, 0.0, 1.0)
    sky = (0.25 + 0.55 * (1.0 - up) ** 3)[..., None] * np.array([0.45, 0.6, 1.0])
    clouds = 1.0 + 0.25 * np.sin(3.0 * az + 9.0 * up) ** 2 * (up > 0.05)
    ground = (0.12 + 0.03 * np.cos(5.0 * az))[..., None] * np.array([1.0, 0.8, 0.55])
    img = np.where((z > 0)[..., None], sky * clouds[..., None], ground)
    # Sun: world direction -> env direction e = Rz(rotation) d (Mapping POINT), -> pixel.
    ce, se = math.cos(SUN_ELEVATION), math.sin(SUN_ELEVATION)
    dw = np.array([ce * math.cos(SUN_AZIMUTH), ce * math.sin(SUN_AZIMUTH), se])
    c, s = math.cos(rotation_z), math.sin(rotation_z)
    e = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ dw
    r, col = equirect_pixel(e, width, height)
    img[r:r + 2, col:col + 2] = SUN_RADIANCE
    return img.astype(np.float32)


def marker_map(width, height):
    """Dark grey map with red (+X), green (40 deg towards +Y) and blue (35 deg up) markers of
    about 8 x 8 degrees."""
    img = np.full((height, width, 3), 0.05, np.float32)
    d = equirect_directions(width, height)
    for direction, colour in (((1.0, 0.0, 0.0), (4.0, 0.0, 0.0)),
                              ((math.cos(math.radians(40)), math.sin(math.radians(40)), 0.0), (0.0, 3.0, 0.0)),
                              ((math.cos(math.radians(35)), 0.0, math.sin(math.radians(35))), (0.0, 0.0, 5.0))):
        near = d @ np.asarray(direction) > math.cos(math.radians(4.0))
        img[near] = colour
    return img


def packed_exr_image(name, pixels, tmp):
    """Write pixels (H, W, 3) as a float EXR, load it in Blender as linear data and pack it."""
    path = os.path.join(tmp, name + ".exr")
    imageio.write_rgba_exr(path, pixels)
    img = bpy.data.images.load(path, check_existing=False)
    img.name = name
    img.colorspace_settings.name = "Linear Rec.709"
    img.pack()
    img.filepath = f"//{name}.exr"  # nominal: the packed copy is what renders use
    return img


def environment_world(scene, image, rotation_z=0.0, strength=1.0):
    """World: TexCoord Generated -> Mapping (POINT, rot z) -> Environment (Closest) -> Background."""
    world = bpy.data.worlds.new("World")
    nt = world.node_tree
    nt.nodes.clear()
    tc = nt.nodes.new("ShaderNodeTexCoord")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.vector_type = "POINT"
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, rotation_z)
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    env.projection = "EQUIRECTANGULAR"
    env.interpolation = "Closest"  # Ember looks pixels up nearest; Closest makes Cycles do the same
    bg = nt.nodes.new("ShaderNodeBackground")
    bg.inputs["Strength"].default_value = strength
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(tc.outputs["Generated"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])
    scene.world = world
    return world


def uv_sphere(scene, name, location, radius, material):
    bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=radius, location=location)
    ob = bpy.context.active_object
    ob.name = name
    ob.data.materials.append(material)
    ob.data.shade_smooth()
    return ob


def cube(scene, name, lo, hi, material):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    c = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
         (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    idx = [(0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    quads = np.array([[c[i] for i in q] for q in idx], float)
    centre = quads.reshape(-1, 3).mean(axis=0)
    v, t = build.triangles_from_quads(quads, lambda cc, n: np.dot(cc - centre, n) > 0)
    return build.mesh_object(scene, name, v, t, material)


def build_hdri(glossy=False):
    scene = build.new_empty_file()
    scene.name = "HDRI"
    build.set_output(scene, 256)
    with tempfile.TemporaryDirectory(prefix="ember_hdri_") as tmp:
        image = packed_exr_image("hdri_sky", sky_map(*HDRI_SIZE, HDRI_ROTATION_Z), tmp)
    environment_world(scene, image, HDRI_ROTATION_Z, HDRI_STRENGTH)
    ground = build.diffuse_material("Ground", (0.5, 0.5, 0.5))
    white = build.diffuse_material("White", (0.8, 0.8, 0.8))
    blue = build.glossy_material("BlueGlossy", (0.3, 0.5, 0.9), 0.2) if glossy else build.diffuse_material("Blue", (0.2, 0.4, 0.8))
    # The ground reaches the horizon (its far edge 0.1 deg below it), so no sharp edge between
    # the lit ground and the map's dark lower half is in view: there both renderers' values are
    # nearly noise-free and Cycles' tabulated pixel filter differs from Ember's exact one by a
    # few 1e-4 (measured with a 60 m plane: 2 rows of pixels failed the z-test).
    half = 1000.0
    v, t = build.triangles_from_quads(np.array([[(-half, -half, 0), (half, -half, 0), (half, half, 0),
                                                 (-half, half, 0)]], float), lambda c, n: n[2] > 0)
    build.mesh_object(scene, "Ground", v, t, ground)
    uv_sphere(scene, "WhiteSphere", (-0.75, 0.2, 0.6), 0.6, white)
    uv_sphere(scene, "BlueSphere", (0.8, -0.1, 0.5), 0.5, blue)
    loc = (0.0, -5.5, 1.8)
    cam = build.camera_object(scene, "Camera", loc, build.look_at_euler(loc, (0.0, 0.0, 0.6)), 35.0, 36.0)
    cam.data.clip_end = 10000.0  # beyond the ground's far edge
    return scene


def build_env_marker():
    scene = build.new_empty_file()
    scene.name = "EnvMarker"
    build.set_output(scene, 64)
    with tempfile.TemporaryDirectory(prefix="ember_marker_") as tmp:
        image = packed_exr_image("env_marker", marker_map(256, 128), tmp)
    world = environment_world(scene, image)
    world.node_tree.nodes.remove(world.node_tree.nodes["Mapping"])  # direction straight in
    tc, env = world.node_tree.nodes["Texture Coordinate"], world.node_tree.nodes["Environment Texture"]
    world.node_tree.links.new(tc.outputs["Generated"], env.inputs["Vector"])
    cube(scene, "Cube", (3.0, 1.2, -1.6), (3.6, 1.8, -1.0), build.diffuse_material("Grey", (0.5, 0.5, 0.5)))
    cam = build.camera_object(scene, "Camera", (0.0, 0.0, 0.0), (math.pi / 2, 0.0, -math.pi / 2), 15.1, 36.0)
    cam.data.sensor_fit = "HORIZONTAL"  # 36 mm / 15.1 mm: ~100 deg horizontal field of view
    return scene


SCENES = {"hdri": build_hdri, "env_marker": build_env_marker}


def main(argv=None):
    ap = build.scene_arguments(__doc__, SCENES)
    ap.add_argument("--glossy", action="store_true", help="hdri: the blue sphere is glossy (GGX 0.2)")
    args = ap.parse_args(build.script_argv(argv))
    build.save_scenes({**SCENES, "hdri": lambda: build_hdri(glossy=args.glossy)}, args)


if __name__ == "__main__":
    main()
