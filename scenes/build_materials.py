"""Build the material test scenes with bpy and save them as .blend.

    python scenes/build_materials.py [--out DIR] [--only NAME]

Scenes (DIR/NAME.blend, DIR defaults to this folder):
  cornell_glossy   the Cornell box (scenes/build.py) with a GGX Glossy short block, a
                   Principled (dielectric specular over diffuse) tall block, a Principled
                   metallic mirror sphere, and a light of 4x the area at the same power
  cornell_rough    the Cornell box with moderately rough glossy surfaces, for radiance caching
                   (bench/radiance_cache.py): a GGX Glossy back wall (grey, roughness 0.7) and
                   short block (gold, 0.75), a Principled floor (white, specular over diffuse,
                   roughness 0.7) and tall block (0.8); the standard light
  glass_sphere     a sharp Glass BSDF sphere on a grey diffuse floor under a large area light
                   (large so the caustic under the sphere converges in Cycles too)
  textured_plane   a floor with a byte sRGB checker image (Mapping x3, Repeat, Linear) and a
                   tilted Principled panel with a float image (Extend, Closest) and a tangent
                   normal map of ridges, under an area light and a sun
  veach_mis        Veach's multiple-importance test (scenes/veach_layout.py): four plates of
                   Glossy BSDF with Beckmann alpha 0.01/0.05/0.1/0.25 as roughness sqrt(alpha),
                   four sphere lights of very different radii and equal power, direct light
                   only; scene.ember.glossy_as_phong is set, so Ember
                   renders the plates as Phong with n = 2 / alpha^2 - 2 (19998/798/198/30)

Comparison scenes use Cycles' box pixel filter (one pixel wide: per-pixel estimates are plain
means, well behaved at a few hundred samples) and GGX (not Multiscatter GGX), which Ember
models. Images are generated here and packed into the .blend.
"""
from __future__ import annotations

import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import build as base  # noqa: E402  (sets BLENDER_USER_RESOURCES, imports bpy)
import veach_layout as veach  # noqa: E402

bpy = base.bpy


def _nodes(name):
    mat = bpy.data.materials.new(name)
    nt, out = base._clear_nodes(mat)
    return mat, nt, out


def principled_material(name, base_color, roughness, metallic=0.0, ior=1.5, **inputs):
    mat, nt, out = _nodes(name)
    p = nt.nodes.new("ShaderNodeBsdfPrincipled")
    p.distribution = "GGX"
    p.inputs["Base Color"].default_value = (*base_color, 1.0)
    p.inputs["Roughness"].default_value = roughness
    p.inputs["Metallic"].default_value = metallic
    p.inputs["IOR"].default_value = ior
    for key, value in inputs.items():
        p.inputs[key].default_value = value
    nt.links.new(p.outputs["BSDF"], out.inputs["Surface"])
    return mat, nt, p


def glass_material(name, color=(1.0, 1.0, 1.0), ior=1.45, roughness=0.0):
    mat, nt, out = _nodes(name)
    g = nt.nodes.new("ShaderNodeBsdfGlass")
    g.distribution = "GGX"
    g.inputs["Color"].default_value = (*color, 1.0)
    g.inputs["IOR"].default_value = ior
    g.inputs["Roughness"].default_value = roughness
    nt.links.new(g.outputs["BSDF"], out.inputs["Surface"])
    return mat


def sphere_object(scene, name, center, radius, material, segments=64, rings=32):
    bpy.ops.mesh.primitive_uv_sphere_add(segments=segments, ring_count=rings, radius=radius,
                                         location=center)
    ob = bpy.context.active_object
    ob.name = name
    ob.data.shade_smooth()
    ob.data.materials.append(material)
    return ob


def packed_image(name, rgba, float_buffer=False, colorspace=None):
    """A Blender image from (H,W,4) values (rows bottom-up), packed into the .blend."""
    h, w = rgba.shape[:2]
    img = bpy.data.images.new(name, w, h, alpha=True, float_buffer=float_buffer)
    if colorspace:  # before the pixels: changing it reloads (clears) a generated buffer
        img.colorspace_settings.name = colorspace
    img.pixels.foreach_set(np.ascontiguousarray(rgba, np.float32).ravel())
    img.pack()
    return img


def ember_settings(scene, **values):
    """Set scene.ember values; registers Ember (its properties) in this process first."""
    sys.path.insert(0, os.path.dirname(HERE))
    from _bootstrap import load_ember
    load_ember()
    import ember
    if not hasattr(scene, "ember"):
        ember.register()
    for key, value in values.items():
        setattr(scene.ember, key, value)


def box_filter(scene):
    scene.cycles.pixel_filter_type = "BOX"


# ------------------------------------------------------------------------------------------
def build_cornell_glossy():
    scene = base.build_cornell_box()
    scene.name = "CornellGlossy"
    box_filter(scene)
    gold = base.glossy_material("GoldGGX", (0.9, 0.65, 0.3), 0.3)
    coated, _, _ = principled_material("Coated", (0.7, 0.7, 0.7), 0.2, ior=1.5)
    chrome, _, _ = principled_material("Chrome", (0.95, 0.95, 0.95), 0.0, metallic=1.0)
    for name, mat in (("ShortBlock", gold), ("TallBlock", coated)):
        ob = bpy.data.objects[name]
        ob.data.materials.clear()
        ob.data.materials.append(mat)
    centre = base.cornell_to_blender((410.0, 80.0, 140.0))
    sphere_object(scene, "MirrorSphere", tuple(centre), 0.8, chrome)
    # A light of 4x the area and 1/4 the radiance (same power): glossy caustics converge.
    light = bpy.data.objects["Light"]
    quad = np.array(base.CORNELL_LIGHT)
    quad = quad.mean(axis=0) + 2.0 * (quad - quad.mean(axis=0))
    v, t = base.triangles_from_quads(base.cornell_to_blender(quad[None]), lambda c, n: n[2] < 0)
    bpy.data.objects.remove(light)
    lamp = base.emission_material("LargeLight", tuple(np.array(base.CORNELL_LIGHT_RADIANCE) / 4.0))
    base.mesh_object(scene, "Light", v, t, lamp)
    return scene


def build_cornell_rough():
    scene = base.build_cornell_box()
    scene.name = "CornellRough"
    box_filter(scene)
    mats = {"BackWall": base.glossy_material("RoughGrey", (0.7, 0.7, 0.7), 0.7),
            "ShortBlock": base.glossy_material("RoughGold", (0.9, 0.65, 0.3), 0.75),
            "Floor": principled_material("RoughFloor", (0.7, 0.7, 0.7), 0.7)[0],
            "TallBlock": principled_material("RoughCoated", (0.6, 0.6, 0.65), 0.8)[0]}
    for name, mat in mats.items():
        ob = bpy.data.objects[name]
        ob.data.materials.clear()
        ob.data.materials.append(mat)
    return scene


def build_glass_sphere():
    scene = base.new_empty_file()
    scene.name = "GlassSphere"
    base.set_output(scene, 256)
    base.black_world(scene)
    box_filter(scene)
    grey = base.diffuse_material("Floor", (0.8, 0.8, 0.8))
    floor = [[(-4, -3, 0), (4, -3, 0), (4, 5, 0), (-4, 5, 0)]]
    v, t = base.triangles_from_quads(np.array(floor, float), lambda c, n: n[2] > 0)
    base.mesh_object(scene, "Floor", v, t, grey)
    sphere_object(scene, "GlassSphere", (0.0, 0.0, 0.5), 0.5, glass_material("Glass"))
    base.light_object(scene, "Area", "AREA", (0.6, 0.4, 3.0), target=(0.0, 0.0, 0.0),
                      energy=120.0, shape="SQUARE", size=2.0)
    loc = (0.0, -3.2, 2.0)
    base.camera_object(scene, "Camera", loc, base.look_at_euler(loc, (0.0, 0.2, 0.35)), 50.0, 36.0)
    return scene


def checker(size=16, squares=4):
    """(size, size, 4) RGBA checker of a warm and a cool colour, sRGB-encoded byte values."""
    y, x = np.mgrid[0:size, 0:size] * squares // size
    odd = ((x + y) % 2 == 1)[..., None]
    rgba = np.where(odd, [0.9, 0.55, 0.2, 1.0], [0.15, 0.35, 0.8, 1.0])
    return np.round(rgba * 255) / 255


def gradient(size=8):
    """(size, size, 4) float RGBA: red grows along u, green along v (linear values)."""
    v, u = (np.mgrid[0:size, 0:size] + 0.5) / size
    return np.stack([0.1 + 0.8 * u, 0.1 + 0.8 * v, np.full_like(u, 0.3), np.ones_like(u)], axis=-1)


def ridges(size=64, periods=6, slope=0.5):
    """(size, size, 4) tangent-space normal map of ridges along v (x = tilt along u)."""
    u = (np.arange(size) + 0.5) / size
    tilt = slope * np.sin(2 * np.pi * periods * u)
    n = np.stack([tilt, np.zeros_like(u), np.ones_like(u)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    row = np.concatenate([0.5 * n + 0.5, np.ones((size, 1))], axis=-1)
    return np.round(np.broadcast_to(row, (size, size, 4)) * 255) / 255


def build_textured_plane():
    scene = base.new_empty_file()
    scene.name = "TexturedPlane"
    base.set_output(scene, 256)
    base.black_world(scene)
    box_filter(scene)
    # Floor: Diffuse BSDF <- Image Texture (byte sRGB, Linear, Repeat) <- Mapping (x3) <- UV.
    floor_mat, nt, out = _nodes("CheckerFloor")
    diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = packed_image("Checker", checker())
    tex.interpolation, tex.extension = "Linear", "REPEAT"
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (3.0, 3.0, 1.0)
    coords = nt.nodes.new("ShaderNodeTexCoord")
    nt.links.new(coords.outputs["UV"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], diffuse.inputs["Color"])
    nt.links.new(diffuse.outputs["BSDF"], out.inputs["Surface"])
    bpy.ops.mesh.primitive_plane_add(size=6.0, location=(0.0, 1.0, 0.0))
    floor = bpy.context.active_object
    floor.name = "Floor"
    floor.data.materials.append(floor_mat)
    # Panel: Principled <- float image (Closest, Extend) on Base Color, Normal Map of ridges.
    panel_mat, nt, p = principled_material("RidgedPanel", (0.8, 0.8, 0.8), 0.35)
    img = nt.nodes.new("ShaderNodeTexImage")
    img.image = packed_image("Gradient", gradient(), float_buffer=True)
    img.interpolation, img.extension = "Closest", "EXTEND"
    nt.links.new(img.outputs["Color"], p.inputs["Base Color"])
    bump = nt.nodes.new("ShaderNodeTexImage")
    bump.image = packed_image("Ridges", ridges(), colorspace="Non-Color")
    normal_map = nt.nodes.new("ShaderNodeNormalMap")
    normal_map.inputs["Strength"].default_value = 1.0
    nt.links.new(bump.outputs["Color"], normal_map.inputs["Color"])
    nt.links.new(normal_map.outputs["Normal"], p.inputs["Normal"])
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(0.4, 1.6, 1.1), rotation=(math.radians(70), 0.0, math.radians(-15)))
    panel = bpy.context.active_object
    panel.name = "Panel"
    panel.data.materials.append(panel_mat)
    base.light_object(scene, "Area", "AREA", (-1.5, -0.5, 2.5), target=(0.3, 1.0, 0.3),
                      energy=150.0, shape="SQUARE", size=1.2)
    sun = base.light_object(scene, "Sun", "SUN", (0.0, 0.0, 5.0), energy=1.5, angle=math.radians(3.0))
    sun.rotation_euler = base.look_at_euler((2.0, -2.0, 4.0), (0.0, 0.0, 0.0))
    loc = (0.0, -3.6, 2.2)
    base.camera_object(scene, "Camera", loc, base.look_at_euler(loc, (0.2, 1.0, 0.5)), 40.0, 36.0)
    return scene


def build_veach_mis():
    scene = base.new_empty_file()
    scene.name = "VeachMIS"
    base.set_output(scene, 256)
    base.black_world(scene)
    ember_settings(scene, glossy_as_phong=True, max_depth=1)
    scene.cycles.max_bounces = 0  # direct light only
    for i, (q, a) in enumerate(zip(veach.plates(), veach.ALPHAS)):
        v, t = base.triangles_from_quads(q[None], lambda c, n: True)
        mat = base.glossy_material(f"Plate{i}", (veach.PLATE_REFLECTANCE,) * 3, math.sqrt(a))
        base.mesh_object(scene, f"Plate{i}", v, t, mat)
    v, t = base.triangles_from_quads(np.array([veach.BACKDROP]), lambda c, n: n[1] < 0)
    backdrop = base.diffuse_material("Backdrop", (veach.BACKDROP_ALBEDO,) * 3)
    base.mesh_object(scene, "Backdrop", v, t, backdrop)
    for i, (p, r) in enumerate(zip(veach.lights(), veach.RADII)):
        base.light_object(scene, f"Light{i}", "POINT", tuple(p), energy=veach.POWER, shadow_soft_size=r)
    cam = veach.CAMERA
    base.camera_object(scene, "Camera", cam["position"], base.look_at_euler(cam["position"], cam["target"]),
                       cam["lens_mm"], cam["sensor_mm"])
    return scene


SCENES = {"cornell_glossy": build_cornell_glossy, "cornell_rough": build_cornell_rough, "glass_sphere": build_glass_sphere,
          "textured_plane": build_textured_plane, "veach_mis": build_veach_mis}


def main(argv=None):
    base.save_scenes(SCENES, base.scene_arguments(__doc__, SCENES).parse_args(base.script_argv(argv)))


if __name__ == "__main__":
    main()
