"""Small bpy scenes for comparisons with Cycles: an empty scene at a size, a node material,
a camera, and the add-on registered for the time of a comparison."""
from __future__ import annotations

import contextlib

import bpy

import ember


def new_scene(size: int, world=(0.0, 0.0, 0.0)):
    """An empty scene of size x size pixels, a constant world of colour `world` (its Background
    node's), box filter, CPU, no denoising."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    w = bpy.data.worlds.new("World")
    sc.world = w  # Blender 5's worlds render their node tree: World.color alone is not seen
    w.node_tree.nodes["Background"].inputs["Color"].default_value = (*world, 1.0)
    sc.render.resolution_x = sc.render.resolution_y = size
    sc.render.resolution_percentage = 100
    sc.cycles.pixel_filter_type = "BOX"
    sc.cycles.device = "CPU"
    sc.cycles.use_denoising = False
    return sc


def node_material(name):
    """(material, its node tree, its Material Output) with nothing else in the tree."""
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    for n in list(nt.nodes):
        if n.bl_idname != "ShaderNodeOutputMaterial":
            nt.nodes.remove(n)
    return mat, nt, nt.nodes["Material Output"]


def camera(sc, location, rotation):
    bpy.ops.object.camera_add(location=location, rotation=rotation)
    sc.camera = bpy.context.active_object
    return sc.camera


@contextlib.contextmanager
def addon():
    ember.register()
    try:
        yield
    finally:
        ember.unregister()


def diffuse_floor(size=8.0, color=(0.8, 0.8, 0.8)):
    """A plane at z = 0 with a Diffuse BSDF of `color` (an object without a material would be a
    default Principled BSDF)."""
    bpy.ops.mesh.primitive_plane_add(size=size)
    mat, nt, out = node_material("Floor")
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (*color, 1.0)
    nt.links.new(d.outputs[0], out.inputs["Surface"])
    bpy.context.active_object.data.materials.append(mat)
    return bpy.context.active_object
