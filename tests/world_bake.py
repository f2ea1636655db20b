"""World shaders against Cycles: an Environment bake (tests/node_bake.py bakes surfaces).

Cycles' ENVIRONMENT bake evaluates the world's background in the direction from the origin to
each texel's point, normalize(P) (integrator/init_from_bake.h), so planes placed around the
origin choose the directions: the six faces of a cube about it see every direction, a small
plane far away a narrow cone (a sun disc and its rim). One bake per world, since a scene has
one; its planes are joined into one object and baked together. Ember evaluates the world's Surface with the shading state
of a background: P and the Generated coordinate are the direction (Cycles' background
shader_setup_from_background).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import bpy

from ember.engine.blender.export_nodes import export_graph
from ember.engine.nodes.closures import closures
from ember.engine.nodes.program import compile
from ember.engine.nodes.state import ShadingState

import node_bake


@dataclass(frozen=True)
class View:
    """A plane of size 2 (side), its centre at `location`, turned by Euler XYZ `rotation`."""

    location: tuple
    rotation: tuple = (0.0, 0.0, 0.0)


# The six faces of the cube [-1, 1]^3: together they see the whole sphere of directions.
CUBE = (View((0, 0, 1)), View((0, 0, -1), (np.pi, 0, 0)), View((1, 0, 0), (0, np.pi / 2, 0)),
        View((-1, 0, 0), (0, -np.pi / 2, 0)), View((0, 1, 0), (-np.pi / 2, 0, 0)), View((0, -1, 0), (np.pi / 2, 0, 0)))


def toward(direction, distance: float) -> View:
    """A plane facing the origin at `distance` along `direction`: it sees the directions within
    about atan(1 / distance) of it."""
    d = np.asarray(direction, np.float64)
    d = d / np.linalg.norm(d)
    # Turn +z onto d: about x by the polar angle, then about z by the azimuth.
    theta, phi = np.arccos(np.clip(d[2], -1.0, 1.0)), np.arctan2(d[1], d[0])
    return View(tuple(d * distance), (theta, 0.0, phi + np.pi / 2.0))


def bake_world(build, views=CUBE, size: int = 32) -> tuple:
    """(cycles (N,3), ember (N,3), directions (N,3)) of the world whose Background colour is the
    socket build(node_tree) returns (strength 1), over size x size texels of each view.

    Cycles bakes one object at a time, its world and sky set up anew each time, so the views
    are joined into one object, each plane's UVs a tile of one image (no margin)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 1
    scene.render.bake.margin = 0
    camera = node_bake._camera()
    world = bpy.data.worlds.new("world")
    world.cycles.sampling_method = "NONE"  # no importance map: the bake reads the background only
    scene.world = world
    nt = world.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new("ShaderNodeOutputWorld")
    socket = build(nt)
    background = nt.nodes.new("ShaderNodeBackground")
    background.inputs["Strength"].default_value = 1.0
    nt.links.new(background.outputs[0], out.inputs["Surface"])
    if socket is not None:
        nt.links.new(socket, background.inputs["Color"])
    columns = int(np.ceil(np.sqrt(len(views))))
    rows = int(np.ceil(len(views) / columns))
    world_from_camera = node_bake._world_from_camera(camera)
    planes, positions = [], []
    for k, view in enumerate(views):
        bpy.ops.mesh.primitive_plane_add(size=2.0, location=view.location, rotation=view.rotation)
        ob = bpy.context.active_object
        bpy.context.view_layer.update()
        positions.append(node_bake._state(ob, size, camera, world_from_camera, "ABOVE_SURFACE").P)
        for loop in ob.data.uv_layers.active.data:  # into tile k of the atlas
            u, v = loop.uv
            loop.uv = ((k % columns + u) / columns, (k // columns + v) / rows)
        planes.append(ob)
    bpy.ops.object.select_all(action="DESELECT")
    for ob in planes:
        ob.select_set(True)
    bpy.context.view_layer.objects.active = planes[0]
    bpy.ops.object.join()
    joined = bpy.context.active_object
    mat = bpy.data.materials.new("views")
    image = bpy.data.images.new("bake", columns * size, rows * size, float_buffer=True)
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    mat.node_tree.nodes.active = tex
    joined.data.materials.clear()
    joined.data.materials.append(mat)
    bpy.ops.object.bake(type="ENVIRONMENT")
    atlas = np.array(image.pixels[:], np.float64).reshape(rows * size, columns * size, 4)[..., :3]
    cycles = [atlas[(k // columns) * size:(k // columns + 1) * size, (k % columns) * size:(k % columns + 1) * size]
              .reshape(-1, 3) for k in range(len(views))]
    P = np.concatenate(positions)
    directions = P / np.linalg.norm(P, axis=1, keepdims=True)
    cycles, ember = np.concatenate(cycles), evaluate(out, directions)
    node_bake.log_conformance({"world": (cycles, ember)})
    return cycles, ember, directions


def evaluate(output_node, directions: np.ndarray) -> np.ndarray:
    """Ember's background radiance (N,3) of a World Output's Surface in `directions`."""
    warnings = []
    graph = export_graph({"surface": output_node.inputs["Surface"]}, warnings.append)
    program = compile(graph, {"surface": "shader"})
    assert not warnings and not program.warnings, warnings + list(program.warnings)
    state = ShadingState(len(directions), P=directions, generated=directions, N=-directions, Ng=-directions,
                         I=-directions)
    total = np.zeros((len(directions), 3))
    for c in closures(program.run(state)["surface"]):
        if c.kind in ("background", "emission"):
            total = total + c.weight
    return total
