"""bpy scenes of Cycles' shadow behaviours, shared by tests/test_shadows.py and
bench/closures_shadows.py:

  leaf_card    an alpha-masked image on a tilted card over a floor, lit by a small area light:
               its shadow is Cycles' transparent shadow (holes and half-transparent texels)
  terminator   a smooth-shaded low-poly icosphere under a sun at a grazing angle (Cycles'
               shadow terminator offsets, per object)
  linking      two lights each linked to one object, and a blocker that only one light's shadow
               sees (Light Linking and Shadow Linking)
"""
from __future__ import annotations

import math

import numpy as np

import bpy


def _base(size: int):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    world = bpy.data.worlds.new("World")
    world.color = (0.0, 0.0, 0.0)
    sc.world = world
    sc.render.resolution_x = sc.render.resolution_y = size
    sc.render.resolution_percentage = 100
    sc.cycles.device = "CPU"
    sc.cycles.use_denoising = False
    sc.cycles.use_adaptive_sampling = False
    sc.cycles.light_sampling_threshold = 0.0
    return sc


def _camera(sc, location, target, angle=40.0):
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.angle = math.radians(angle)
    cam.location = location
    direction = np.subtract(target, location)
    cam.rotation_euler = _look(direction)
    sc.collection.objects.link(cam)
    sc.camera = cam
    return cam


def _look(direction):
    from mathutils import Vector
    return Vector(tuple(direction)).to_track_quat("-Z", "Y").to_euler()


def _diffuse(name, color):
    mat = bpy.data.materials.new(name)
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    bsdf.inputs["Roughness"].default_value = 1.0
    return mat


def _plane(sc, name, half, mat, location=(0, 0, 0), rotation=(0, 0, 0), uv=False):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(-half, -half, 0), (half, -half, 0), (half, half, 0), (-half, half, 0)], [], [(0, 1, 2, 3)])
    if uv:
        layer = mesh.uv_layers.new(name="UVMap")
        for loop, corner in zip(layer.data, ((0, 0), (1, 0), (1, 1), (0, 1))):
            loop.uv = corner
    mesh.materials.append(mat)
    ob = bpy.data.objects.new(name, mesh)
    ob.location, ob.rotation_euler = location, tuple(math.radians(a) for a in rotation)
    sc.collection.objects.link(ob)
    return ob


def leaf_alpha(n: int = 16) -> np.ndarray:
    """(n, n) the card's alpha: a leaf (an ellipse) with holes, opaque (1) inside, half
    transparent (0.5) along its rim and where its veins are missing, clear (0) outside."""
    y, x = (np.mgrid[0:n, 0:n] + 0.5) / n * 2.0 - 1.0
    inside = x * x / 0.8 + y * y / 0.5 < 1.0
    alpha = np.where(inside, 1.0, 0.0)
    alpha[inside & ((np.abs(x * 4.0 - np.round(x * 4.0)) < 0.2) | (x * x / 0.8 + y * y / 0.5 > 0.7))] = 0.5
    alpha[inside & (np.hypot(x - 0.3, y + 0.1) < 0.18)] = 0.0
    return alpha


def leaf_card(size: int = 24, light_size: float = 0.6):
    """The leaf card: a green 1 m card 0.6 m over a grey floor, its Principled Alpha from an
    Image Texture of leaf_alpha (Closest), under a square area light."""
    sc = _base(size)
    _plane(sc, "floor", 1.5, _diffuse("floor", (0.8, 0.8, 0.8)))
    alpha = leaf_alpha()
    img = bpy.data.images.new("leaf", alpha.shape[1], alpha.shape[0], alpha=True, float_buffer=True)
    rgba = np.empty(alpha.shape + (4,), np.float32)
    rgba[..., :3] = (0.2, 0.6, 0.1)
    rgba[..., 3] = alpha
    img.pixels.foreach_set(rgba.ravel())
    img.pack()
    mat = bpy.data.materials.new("leaf")
    nt = mat.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    bsdf.inputs["Roughness"].default_value = 1.0
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image, tex.interpolation = img, "Closest"
    bsdf.inputs["Base Color"].default_value = (0.2, 0.6, 0.1, 1.0)
    nt.links.new(tex.outputs["Alpha"], bsdf.inputs["Alpha"])
    _plane(sc, "card", 0.5, mat, location=(0.0, 0.0, 0.6), rotation=(15.0, 0.0, 0.0), uv=True)
    light = bpy.data.objects.new("Area", bpy.data.lights.new("Area", "AREA"))
    light.data.energy, light.data.size = 120.0, light_size
    light.location = (0.2, -0.3, 2.2)
    sc.collection.objects.link(light)
    _camera(sc, (0.0, -2.2, 2.6), (0.0, 0.0, 0.2))
    return sc


def terminator(size: int = 24, geometry=None, shading=None, elevation: float = 12.0):
    """An icosphere (subdivision 1, shaded smooth) on nothing, under a sun `elevation` degrees
    above its horizon, seen from the side the sun sets on; geometry, shading: the object's
    shadow terminator offsets (None: Blender's defaults)."""
    sc = _base(size)
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=1, radius=1.0)
    ob = bpy.context.active_object
    ob.data.shade_smooth()
    ob.data.materials.append(_diffuse("sphere", (0.8, 0.8, 0.8)))
    _set_offsets(ob, geometry, shading)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy, sun.data.angle = 3.0, 0.0
    sun.rotation_euler = (math.radians(90.0 - elevation), 0.0, math.radians(90.0))
    sc.collection.objects.link(sun)
    _camera(sc, (0.0, -4.0, 0.0), (0.0, 0.0, 0.0), angle=35.0)
    return sc


def _set_offsets(ob, geometry, shading):
    if geometry is not None:
        ob.shadow_terminator_geometry_offset = geometry
    if shading is not None:
        ob.shadow_terminator_shading_offset = shading


def _sphere(sc, name, location, radius, mat):
    bpy.ops.mesh.primitive_uv_sphere_add(segments=24, ring_count=12, radius=radius, location=location)
    ob = bpy.context.active_object
    ob.name = name
    ob.data.shade_smooth()
    ob.data.materials.append(mat)
    ob.shadow_terminator_geometry_offset = 0.0
    return ob


def _linking_collection(name, entries):
    """A collection holding objects with link states: entries [(object, 'INCLUDE' | 'EXCLUDE')]."""
    coll = bpy.data.collections.new(name)
    for ob, state in entries:
        coll.objects.link(ob)
    states = dict((o.name, s) for o, s in entries)
    for ob, entry in zip(coll.objects, coll.collection_objects):  # parallel lists
        entry.light_linking.link_state = states[ob.name]
    return coll


def linking(size: int = 24):
    """Two spheres A (left) and B (right) on a floor under a grey shade. Key: a soft point
    light that lights A alone (receivers: A included). Fill: an area light that lights all but
    A (receivers: A excluded) and that only B shadows (blockers: B included: the shade casts
    no shadow from it). Glow: an emissive card that lights B alone."""
    sc = _base(size)
    sc.cycles.max_bounces = 4
    _plane(sc, "floor", 2.0, _diffuse("floor", (0.7, 0.7, 0.7)))
    a = _sphere(sc, "A", (-0.7, 0.0, 0.45), 0.45, _diffuse("A", (0.8, 0.3, 0.2)))
    b = _sphere(sc, "B", (0.7, 0.0, 0.45), 0.45, _diffuse("B", (0.2, 0.4, 0.8)))
    _plane(sc, "shade", 0.4, _diffuse("shade", (0.5, 0.5, 0.5)), location=(0.6, 0.2, 1.6))
    key = bpy.data.objects.new("Key", bpy.data.lights.new("Key", "POINT"))
    key.data.energy, key.data.shadow_soft_size = 300.0, 0.2
    key.location = (-1.2, -1.0, 2.2)
    sc.collection.objects.link(key)
    key.light_linking.receiver_collection = _linking_collection("key receivers", [(a, "INCLUDE")])
    fill = bpy.data.objects.new("Fill", bpy.data.lights.new("Fill", "AREA"))
    fill.data.energy, fill.data.size = 200.0, 0.8
    fill.location = (0.8, 0.3, 2.6)
    sc.collection.objects.link(fill)
    fill.light_linking.receiver_collection = _linking_collection("fill receivers", [(a, "EXCLUDE")])
    fill.light_linking.blocker_collection = _linking_collection("fill blockers", [(b, "INCLUDE")])
    glow_mat = bpy.data.materials.new("glow")
    nt = glow_mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = 6.0
    nt.links.new(em.outputs["Emission"], nt.nodes["Material Output"].inputs["Surface"])
    glow = _plane(sc, "glow", 0.25, glow_mat, location=(1.6, -0.2, 0.6), rotation=(0.0, -70.0, 0.0))
    glow.light_linking.receiver_collection = _linking_collection("glow receivers", [(b, "INCLUDE")])
    _camera(sc, (0.0, -4.2, 2.6), (0.0, 0.0, 0.5))
    return sc
