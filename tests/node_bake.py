"""Node conformance against Cycles: a node's output routed to Emission, baked by Cycles at the
texel centres of a plane, and the same graph evaluated by Ember's node programs at the same
points (exact values, no sampling noise on either side).

Each case is a function that builds a material's nodes and returns the output socket to
test; cases run in one bake (one plane per case, side by side), so hundreds cost about a
second. Cycles bakes EMIT at each texel (u, v) = ((i + 0.5) / S, (j + 0.5) / S) of the plane's
UV map (nudged by BAKE_OFFSET), which spans the plane corner to corner: object position (2u - 1, 2v - 1, 0), normal
+z, the ray arriving along -z. A case given as Placed(build, location, rotation, scale) bakes on
a plane moved from its slot, turned (Euler XYZ) and scaled, for nodes that read the object's
transform. The scene has a camera (CAMERA_*), for nodes that read camera space; with
view_from="ACTIVE_CAMERA" the baker's rays come from it instead of straight down the normal.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

import bpy

from ember.engine.blender.export_nodes import export_graph
from ember.engine.nodes.closures import closures
from ember.engine.nodes.program import compile
from ember.engine.nodes.state import ShadingState

SIZE = 32
SPACING = 3.0
# Objects per bake call: Blender's bake time grows faster than its number of objects.
BAKE_CHUNK = 24
# Where in a texel Blender's baker puts its point: the centre, nudged by these fractions of a
# texel in u and v (measured from a baked UV coordinate: the same at 16 to 128 texels).
BAKE_OFFSET = (0.001, 0.002)
# The bake scene's camera: off every axis, so that no camera-space component is trivially 0,
# and scaled, which Cycles' camera space ignores.
CAMERA_LOCATION = (2.0, -7.0, 5.0)
CAMERA_ROTATION = (0.9, 0.15, 0.35)
CAMERA_SCALE = (2.0, 0.5, 3.0)


@dataclass(frozen=True)
class Placed:
    """A case baked on a plane moved by `location` from its slot, turned by `rotation` (Euler
    XYZ, radians) and scaled by `scale`."""

    build: Callable
    location: tuple = (0.0, 0.0, 0.0)
    rotation: tuple = (0.0, 0.0, 0.0)
    scale: tuple = (1.0, 1.0, 1.0)


def _plane_mesh():
    """Blender's default plane: 2 m square, UV map corner to corner (what primitive_plane_add
    makes), built without operators (each costs a scene update)."""
    mesh = bpy.data.meshes.new("plane")
    mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    for loop, corner in zip(uv.data, ((0, 0), (1, 0), (1, 1), (0, 1))):
        loop.uv = corner
    return mesh


def _plane(k: int, case, mesh):
    place = case if isinstance(case, Placed) else Placed(case)
    ob = bpy.data.objects.new(f"plane_{k}", mesh.copy())
    bpy.context.scene.collection.objects.link(ob)
    ob.location = tuple(a + b for a, b in zip((SPACING * k, 0.0, 0.0), place.location))
    ob.rotation_euler, ob.scale = place.rotation, place.scale
    return ob, place.build


def _camera():
    bpy.ops.object.camera_add(location=CAMERA_LOCATION, rotation=CAMERA_ROTATION)
    camera = bpy.context.active_object
    camera.scale = CAMERA_SCALE
    bpy.context.scene.camera = camera
    return camera


def _world_from_camera(camera) -> np.ndarray:
    """Cycles' camera frame in world space: Blender's camera looks down its -z, Cycles' camera
    space has z forward (into the view), and the camera's scale is dropped."""
    m = np.array(camera.matrix_world, np.float64) @ np.diag([1.0, 1.0, -1.0, 1.0])
    m[:3, :3] /= np.linalg.norm(m[:3, :3], axis=0)
    return m


def _material(name: str, build):
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    emission = nt.nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = 1.0
    nt.links.new(emission.outputs[0], out.inputs["Surface"])
    socket = build(nt)
    if socket is not None:
        nt.links.new(socket, emission.inputs["Color"])
    return mat, out


def _window(camera, P, camera_from_world) -> np.ndarray:
    """P in normalised window coordinates ([0, 1] across the camera's frame, z 0) of the
    perspective camera, as bpy_extras.object_utils.world_to_camera_view computes them."""
    c = P @ camera_from_world[:3, :3].T + camera_from_world[:3, 3]  # z forward
    frame = camera.data.view_frame(scene=bpy.context.scene)[:3]  # corners at depth -frame.z
    depth = -frame[0].z
    x = (c[:, 0] * depth / c[:, 2] - frame[2].x) / (frame[1].x - frame[2].x)
    y = (c[:, 1] * depth / c[:, 2] - frame[1].y) / (frame[0].y - frame[1].y)
    return np.stack([x, y, np.zeros_like(x)], axis=1)


def _normalize(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _incoming(P, n, camera_position):
    """The direction toward the ray's origin as Cycles' baker sets it up looking from the camera
    (integrator/init_from_bake.h): toward the camera, kept at least 0.2 above the normal and
    pulled toward the normal on faces turned away (the plane is flat: N = Ng)."""
    d = _normalize(camera_position - P)
    dn = np.sum(d * n, axis=1, keepdims=True)
    d = np.where(dn <= 0.2, _normalize(d - n * (dn - 0.2)), d)
    d = np.where(dn <= 0.0, _normalize(d + (n - d) * -dn), d)
    dg = np.sum(d * n, axis=1, keepdims=True)
    return np.where(dg <= 1e-5, _normalize(d - n * (dg - 1e-5)), d)


def _state(ob, size: int, camera, world_from_camera, view_from: str) -> ShadingState:
    i = np.arange(size) + 0.5
    u, v = (a.ravel() for a in np.meshgrid((i + BAKE_OFFSET[0]) / size, (i + BAKE_OFFSET[1]) / size))
    obj = np.stack([2.0 * u - 1.0, 2.0 * v - 1.0, np.zeros_like(u)], axis=1)
    world_from_object = np.array(ob.matrix_world, np.float64)
    object_from_world = np.linalg.inv(world_from_object)
    world = obj @ world_from_object[:3, :3].T + world_from_object[:3, 3]
    loc = np.asarray(ob.data.texspace_location, np.float64)
    half = np.asarray(ob.data.texspace_size, np.float64)
    # The normal transforms by the inverse transpose (n_world ~ M^-T n_object).
    n = np.tile(_normalize(np.array([0.0, 0.0, 1.0]) @ object_from_world[:3, :3]), (len(u), 1))
    camera_from_world = np.linalg.inv(world_from_camera)
    incoming = n if view_from == "ABOVE_SURFACE" else _incoming(world, n, world_from_camera[:3, 3])
    per_point = (len(u), 4, 4)
    return ShadingState(len(u), P=world, N=n, Ng=n, I=incoming, backfacing=np.zeros(len(u), bool),
                        uv=np.stack([u, v, np.zeros_like(u)], axis=1), generated=(obj - loc + half) / (2.0 * half),
                        object=obj, camera=world @ camera_from_world[:3, :3].T + camera_from_world[:3, 3],
                        window=_window(camera, world, camera_from_world),
                        ray_length=np.ones(len(u)), instancer_generated=np.zeros((len(u), 3)),
                        instancer_uv=np.zeros((len(u), 3)),
                        world_from_object=np.broadcast_to(world_from_object, per_point),
                        object_from_world=np.broadcast_to(object_from_world, per_point),
                        world_from_camera=world_from_camera, camera_from_world=camera_from_world)


def bake(cases: dict, size: int = SIZE, view_from: str = "ABOVE_SURFACE") -> dict:
    """{name: (cycles (S*S,3), ember (S*S,3))} for cases {name: build(node_tree) -> socket, or
    Placed(build, ...)}; view_from: the baker's ABOVE_SURFACE (rays down the normal) or
    ACTIVE_CAMERA (rays from the scene's camera)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 1
    scene.render.bake.view_from = view_from
    camera = _camera()
    mesh = _plane_mesh()
    made = {}
    for k, (name, case) in enumerate(cases.items()):
        ob, build = _plane(k, case, mesh)
        mat, out = _material(name, build)
        image = bpy.data.images.new(f"bake_{k}", size, size, float_buffer=True)
        tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
        tex.image = image
        mat.node_tree.nodes.active = tex
        ob.data.materials.append(mat)
        made[name] = (ob, out, image)
    objects = [ob for ob, _, _ in made.values()]
    for first in range(0, len(objects), BAKE_CHUNK):
        bpy.ops.object.select_all(action="DESELECT")
        for ob in objects[first:first + BAKE_CHUNK]:
            ob.select_set(True)
        bpy.context.view_layer.objects.active = objects[first]
        bpy.ops.object.bake(type="EMIT")
    bpy.context.view_layer.update()
    world_from_camera = _world_from_camera(camera)
    results = {}
    for name, (ob, out, image) in made.items():
        cycles = np.array(image.pixels[:], np.float64).reshape(size * size, 4)[:, :3]
        results[name] = (cycles, evaluate(out, _state(ob, size, camera, world_from_camera, view_from)))
    return results


def evaluate(output_node, state: ShadingState) -> np.ndarray:
    """Ember's emitted radiance (N,3) of a material output node's Surface at the state's points."""
    warnings = []
    graph = export_graph({"surface": output_node.inputs["Surface"]}, warnings.append)
    program = compile(graph, {"surface": "shader"})
    # A node without its image renders magenta as in Cycles, and says so; anything else warned
    # about is something Ember renders differently.
    warnings = [w for w in warnings if "magenta, as in Cycles" not in w]
    assert not warnings and not program.warnings, warnings + list(program.warnings)
    total = np.zeros((state.n, 3))
    for c in closures(program.run(state)["surface"]):
        if c.kind == "emission":
            total = total + c.weight
    return total


def agreement(cycles: np.ndarray, ember: np.ndarray, tol: float = 1e-4) -> float:
    """Share of texels whose three channels all agree within tol: absolute up to 1, relative
    above (Cycles computes in float32, whose steps at 1000 are 6e-5)."""
    return float(np.mean(np.all(np.abs(cycles - ember) <= tol * np.maximum(1.0, np.abs(cycles)), axis=1)))
