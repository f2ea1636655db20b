"""World -> World (constant background radiance).

As Cycles' sync_world (intern/cycles/blender/shader.cpp, 5.x): the view layer's world
override, else the scene world; with a node tree, the World Output Surface link; without
one, world.color at strength 1; no world -> black. The view layer's Environment toggle
(use_sky) off disables the background shader entirely. Camera visibility comes from
world.cycles_visibility.camera and film_transparent.
"""
from __future__ import annotations

import numpy as np

from ..scene import World
from .export_material import find_output, follow_link, rgb


def _world_color(world, warn) -> np.ndarray:
    tree = world.node_tree
    if tree is None:
        return np.array(world.color[:3], np.float64)
    out = find_output(tree, "ShaderNodeOutputWorld")
    if out is None:
        warn(f"World '{world.name}': no World Output node; the background is black.")
        return np.zeros(3)
    node = follow_link(out.inputs["Surface"])
    if node is None:
        return np.zeros(3)
    if node.bl_idname not in ("ShaderNodeBackground", "ShaderNodeEmission") or node.mute:
        warn(f"World '{world.name}': node '{node.name}' ({node.bl_label}) is not supported yet; "
             "the background is black.")
        return np.zeros(3)
    col, stre = node.inputs["Color"], node.inputs["Strength"]
    linked = [s.name for s in (col, stre) if s.is_linked]
    if linked:
        warn(f"World '{world.name}': the {', '.join(linked)} input of '{node.name}' is linked "
             "(textures are not supported yet); using its unlinked value.")
    return np.array(rgb(col), np.float64) * float(stre.default_value)


def export_world(depsgraph, scene, warn) -> World:
    view_layer = depsgraph.view_layer_eval
    world = getattr(view_layer, "world_override", None) or scene.world
    if world is None or not getattr(view_layer, "use_sky", True):
        return World(color=np.zeros(3), visible=True)
    color = _world_color(world, warn)
    vis = getattr(world, "cycles_visibility", None)
    visible = bool(getattr(vis, "camera", True)) and not scene.render.film_transparent
    if vis is not None and not (vis.diffuse and vis.glossy and vis.transmission):
        warn(f"World '{world.name}': per-ray-type visibility is not supported; it lights everything.")
    return World(color=color, visible=visible)
