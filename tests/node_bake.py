"""Node conformance against Cycles: a node's output routed to Emission, baked by Cycles at the
texel centres of a plane, and the same graph evaluated by Ember's node programs at the same
points (exact values, no sampling noise on either side).

Each case is a function that builds a material's nodes and returns the output socket to
test; cases run in one bake (one plane per case, side by side), so hundreds cost about a
second. Cycles bakes EMIT at each texel (u, v) = ((i + 0.5) / S, (j + 0.5) / S) of the plane's
UV map (nudged by BAKE_OFFSET), which spans the plane corner to corner: object position (2u - 1,
2v - 1, 0), normal +z, the ray arriving along -z. A case given as Placed(build, location,
rotation, scale) bakes on a plane moved from its slot, turned (Euler XYZ) and scaled, for nodes
that read the object's transform; Placed(..., mesh=make) on another mesh, and setup= sets the
object's colour, pass index or custom properties. The scene has a camera (CAMERA_*), for nodes
that read camera space; with view_from="ACTIVE_CAMERA" the baker's rays come from it instead of
straight down the normal.

The shading state is rebuilt from the object's mesh as Cycles' baker sets it up (_Surface):
each texel's triangle and barycentric weights from the bake UV map (the texels no triangle
covers stay black, as the bake's margin is 0), the smooth or flat normals, the incoming
direction, the texel's ray differential (Blender's bake_differentials, half a texel's footprint),
named attributes, MikkTSpace tangents, pointiness and islands as Cycles derives them
(engine/blender/export_attributes.py), the object's and material's values, and a camera ray's
path state.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass
from typing import Callable

import numpy as np

import bpy

from ember.engine.blender.export_attributes import MeshAttributes, object_attribute
from ember.engine.blender.export_nodes import export_graph
from ember.engine.nodes import light_path
from ember.engine.nodes.bump import bump_from_displacement
from ember.engine.nodes.closures import closures
from ember.engine.nodes.mesh_attributes import at_hits, object_random
from ember.engine.nodes.program import compile
from ember.engine.nodes.state import Attribute, ShadingState

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
    XYZ, radians) and scaled by `scale`; on the mesh `mesh()` makes instead of the plane (its
    active UV map is the bake's, and should cover the unit square for every texel to count);
    `setup(object)` sets what else the case needs of the object (colour, pass index, custom
    properties)."""

    build: Callable
    location: tuple = (0.0, 0.0, 0.0)
    rotation: tuple = (0.0, 0.0, 0.0)
    scale: tuple = (1.0, 1.0, 1.0)
    mesh: Callable | None = None
    setup: Callable | None = None


def _plane_mesh():
    """Blender's default plane: 2 m square, UV map corner to corner (what primitive_plane_add
    makes), built without operators (each costs a scene update)."""
    mesh = bpy.data.meshes.new("plane")
    mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    for loop, corner in zip(uv.data, ((0, 0), (1, 0), (1, 1), (0, 1))):
        loop.uv = corner
    return mesh


def _slot(k: int, count: int, columns: int | None) -> tuple:
    """Where case k of `count` stands: along x, or in a grid of `columns` centred on the origin."""
    if columns is None:
        return (SPACING * k, 0.0, 0.0)
    rows = -(-count // columns)
    return (SPACING * (k % columns - (columns - 1) / 2.0), SPACING * (k // columns - (rows - 1) / 2.0), 0.0)


def _plane(k: int, case, mesh, slot: tuple):
    place = case if isinstance(case, Placed) else Placed(case)
    ob = bpy.data.objects.new(f"plane_{k}", place.mesh() if place.mesh is not None else mesh.copy())
    bpy.context.scene.collection.objects.link(ob)
    ob.location = tuple(a + b for a, b in zip(slot, place.location))
    ob.rotation_euler, ob.scale = place.rotation, place.scale
    if place.setup is not None:
        place.setup(ob)
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


def _ndc_from_world(camera, camera_from_world) -> np.ndarray:
    """Cycles' worldtondc for the perspective camera: normalised window coordinates ([0, 1]
    across the camera's frame, as bpy_extras.object_utils.world_to_camera_view computes them)
    of a world point, after the divide by w (the camera-space depth)."""
    frame = camera.data.view_frame(scene=bpy.context.scene)[:3]  # corners at depth -frame.z
    depth = -frame[0].z
    sx, sy = frame[1].x - frame[2].x, frame[0].y - frame[1].y
    ndc_from_camera = np.array([[depth / sx, 0.0, -frame[2].x / sx, 0.0], [0.0, depth / sy, -frame[1].y / sy, 0.0],
                                [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
    return ndc_from_camera @ camera_from_world


def _normalize(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _incoming(P, n, ng, camera_position):
    """The direction toward the ray's origin as Cycles' baker sets it up looking from the camera
    (integrator/init_from_bake.h): toward the camera, kept at least 0.2 above the normal N,
    pulled toward N on faces turned away, and kept above the true normal Ng."""
    d = _normalize(camera_position - P)
    dn = np.sum(d * n, axis=1, keepdims=True)
    d = np.where(dn <= 0.2, _normalize(d - n * (dn - 0.2)), d)
    d = np.where(dn <= 0.0, _normalize(d + (n - d) * -dn), d)
    dg = np.sum(d * ng, axis=1, keepdims=True)
    return np.where(dg <= 1e-5, _normalize(d - ng * (dg - 1e-5)), d)


def _texels(size: int) -> np.ndarray:
    """The bake's sample points in UV space, (S*S, 2), row by row from the bottom."""
    i = np.arange(size) + 0.5
    u, v = np.meshgrid((i + BAKE_OFFSET[0]) / size, (i + BAKE_OFFSET[1]) / size)
    return np.stack([u.ravel(), v.ravel()], axis=1)


def _rasterize(tri_uv, points):
    """(triangle index or -1, Blender's weights of the triangle's corners (N,3)) of each point
    in the UV layout: the last triangle containing it wins, as Blender's baker overwrites."""
    tri = np.full(len(points), -1)
    weights = np.zeros((len(points), 3))
    for first in range(0, len(tri_uv), 256):
        a, b, c = (tri_uv[first:first + 256, k][:, None, :] for k in range(3))
        v0, v1, p = b - a, c - a, points[None, :, :] - a
        det = v0[..., 0] * v1[..., 1] - v1[..., 0] * v0[..., 1]
        with np.errstate(all="ignore"):
            w1 = (p[..., 0] * v1[..., 1] - v1[..., 0] * p[..., 1]) / det
            w2 = (v0[..., 0] * p[..., 1] - p[..., 0] * v0[..., 1]) / det
        w0 = 1.0 - w1 - w2
        inside = (w0 >= 0.0) & (w1 >= 0.0) & (w2 >= 0.0) & (det != 0.0)
        for k in range(inside.shape[0]):
            hit = inside[k]
            tri[hit] = first + k
            weights[hit] = np.stack([w0[k, hit], w1[k, hit], w2[k, hit]], axis=1)
    return tri, weights


class _Surface:
    """The shading state at the texels an object's bake covers, as Cycles sets it up for a bake
    (integrator/init_from_bake.h, geom/shader_data.h shader_setup_from_ray): a method per
    ShadingState field, evaluated when a program reads it. `covered` marks the texels of the
    S*S image some triangle of the bake UV map (the active one) covers."""

    def __init__(self, ob, size: int, camera, world_from_camera, view_from: str):
        self.ob, self.mesh, self.size = ob, ob.data, size
        self.camera_ob, self.view_from = camera, view_from
        self.camera_frame = world_from_camera
        self.attributes = MeshAttributes(self.mesh)
        mesh, tris = self.mesh, self.attributes
        bake_uv = np.empty(2 * len(mesh.loops))
        mesh.uv_layers.active.data.foreach_get("uv", bake_uv)
        bake_uv = bake_uv.reshape(-1, 2)[tris.triangle_loops]  # (T,3,2)
        tri, weights = _rasterize(bake_uv, _texels(size))
        self.covered = tri >= 0
        self.tri = tri[self.covered]
        self.weights = weights[self.covered]  # Blender's (u_b, v_b, 1 - u_b - v_b) = Cycles' (1 - u - v, u, v)
        self.n = len(self.tri)
        self.loops = tris.triangle_loops[self.tri]
        self.verts = tris.triangle_verts[self.tri]
        self.faces = tris.triangle_faces[self.tri]
        self.world_from_object_m = np.array(ob.matrix_world, np.float64)
        self.object_from_world_m = np.linalg.inv(self.world_from_object_m)
        co = np.empty(3 * len(mesh.vertices))
        mesh.vertices.foreach_get("co", co)
        self.co = co.reshape(-1, 3)
        self.corners_world = self.co[self.verts] @ self.world_from_object_m[:3, :3].T + self.world_from_object_m[:3, 3]
        smooth = np.empty(len(mesh.loop_triangles), bool)
        mesh.loop_triangles.foreach_get("use_smooth", smooth)
        self.smooth_m = smooth[self.tri]
        self._bake_differentials(bake_uv[self.tri])

    def _bake_differentials(self, uv):
        """Blender's bake_differentials per triangle (half the barycentric change per texel, in
        pixel units offset as the rasterizer offsets them), turned to Cycles' barycentrics, and
        the ray's compact dP = 0.5 (|dP/dx| + |dP/dy|) from them (init_from_bake.h)."""
        px = uv * self.size - np.array([0.501, 0.502])
        a, b, c = px[:, 0], px[:, 1], px[:, 2]
        area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
        ok = np.abs(area) > np.finfo(np.float32).eps
        k = np.where(ok, 0.5 / np.where(ok, area, 1.0), 0.0)
        du_dx, dv_dx = (b[:, 1] - c[:, 1]) * k, (c[:, 1] - a[:, 1]) * k
        du_dy, dv_dy = (c[:, 0] - b[:, 0]) * k, (a[:, 0] - c[:, 0]) * k
        dpdu, dpdv = self._edges()
        dpdx = dpdu * dv_dx[:, None] + dpdv * (-du_dx - dv_dx)[:, None]
        dpdy = dpdu * dv_dy[:, None] + dpdv * (-du_dy - dv_dy)[:, None]
        self._dP = 0.5 * (np.linalg.norm(dpdx, axis=1) + np.linalg.norm(dpdy, axis=1))

    def _edges(self):
        c = self.corners_world
        return c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]

    def _point_attribute(self, kind, domain, values):
        cycles = self.weights  # Blender's (u_b, v_b, w_b) weigh corners 0, 1, 2 as Cycles' (1-u-v, u, v)
        value, du, dv = at_hits(values, domain, self.loops, self.verts, self.faces, self.tri, cycles)
        return Attribute(kind, value, du, dv)

    # --- the hit ---------------------------------------------------------------------------
    def P(self):
        return np.einsum("nk,nkc->nc", self.weights, self.corners_world)

    def _true_normal(self):
        dpdu, dpdv = self._edges()
        ng = _normalize(np.cross(dpdu, dpdv))
        return -ng if np.linalg.det(self.world_from_object_m[:3, :3]) < 0.0 else ng

    def _vertex_normals_world(self):
        n = np.empty(3 * len(self.mesh.vertices))
        self.mesh.vertex_normals.foreach_get("vector", n)
        world = n.reshape(-1, 3) @ self.object_from_world_m[:3, :3]  # M^-T n
        return _normalize(world)[self.verts]  # (N,3,3)

    def _smooth_raw(self):
        return np.einsum("nk,nkc->nc", self.weights, self._vertex_normals_world())

    def _unflipped_normal(self):
        raw = self._smooth_raw()
        length = np.linalg.norm(raw, axis=1, keepdims=True)
        smooth = np.where(length > 0.0, raw / np.where(length > 0.0, length, 1.0), self._true_normal())
        return np.where(self.smooth_m[:, None], smooth, self._true_normal())

    def _incoming_unflipped(self):
        n = self._unflipped_normal()
        if self.view_from == "ABOVE_SURFACE":
            return n
        return _incoming(self.P(), n, self._true_normal(), self.camera_frame[:3, 3])

    def backfacing(self):
        return np.sum(self._true_normal() * self._incoming_unflipped(), axis=1) < 0.0

    def _flip(self):
        return np.where(self.backfacing(), -1.0, 1.0)[:, None]

    def N(self):
        return self._unflipped_normal() * self._flip()

    def Ng(self):
        return self._true_normal() * self._flip()

    def I(self):  # noqa: E743 (Cycles' name)
        return self._incoming_unflipped()

    def ray_length(self):
        return np.ones(self.n)

    def barycentric(self):
        return self.weights[:, 1:].copy()

    def triangle(self):
        return self.corners_world

    def dPdu(self):
        return self._edges()[0] * self._flip()

    def dPdv(self):
        return self._edges()[1] * self._flip()

    def dP(self):
        return self._dP

    def smooth(self):
        return self.smooth_m

    def vertex_normal(self):
        n = np.empty(3 * len(self.mesh.vertex_normals))
        self.mesh.vertex_normals.foreach_get("vector", n)
        return np.einsum("nk,nkc->nc", self.weights, n.reshape(-1, 3)[self.verts])

    def _normal_derivatives(self):
        corners = self._vertex_normals_world()
        length = np.linalg.norm(self._smooth_raw(), axis=1, keepdims=True)
        scale = np.where(self.smooth_m[:, None], self._flip() / length, 0.0)
        return (corners[:, 1] - corners[:, 0]) * scale, (corners[:, 2] - corners[:, 0]) * scale

    def N_du(self):
        return self._normal_derivatives()[0]

    def N_dv(self):
        return self._normal_derivatives()[1]

    # --- coordinates -------------------------------------------------------------------------
    def _uv_attribute(self):
        a = self.attribute("uv")
        if a is None:
            zero = np.zeros((self.n, 3))
            return zero, zero, zero
        pad = [(0, 0), (0, 1)]
        return np.pad(a.value, pad), np.pad(a.du, pad), np.pad(a.dv, pad)

    def uv(self):
        return self._uv_attribute()[0]

    def uv_du(self):
        return self._uv_attribute()[1]

    def uv_dv(self):
        return self._uv_attribute()[2]

    def generated(self):
        return self.attribute("generated").value

    def generated_du(self):
        return self.attribute("generated").du

    def generated_dv(self):
        return self.attribute("generated").dv

    def instancer_generated(self):
        return np.zeros((self.n, 3))

    def instancer_uv(self):
        return np.zeros((self.n, 3))

    def object(self):
        return np.einsum("nk,nkc->nc", self.weights, self.co[self.verts])

    def world_from_object(self):
        return np.broadcast_to(self.world_from_object_m, (self.n, 4, 4))

    def object_from_world(self):
        return np.broadcast_to(self.object_from_world_m, (self.n, 4, 4))

    def world_from_camera(self):
        return self.camera_frame

    def camera_from_world(self):
        return np.linalg.inv(self.camera_frame)

    def camera(self):
        m = self.camera_from_world()
        return self.P() @ m[:3, :3].T + m[:3, 3]

    def ndc_from_world(self):
        return _ndc_from_world(self.camera_ob, self.camera_from_world())

    def window(self):
        m = self.ndc_from_world()
        h = self.P() @ m.T[:3] + m[:, 3]
        return np.stack([h[:, 0] / h[:, 3], h[:, 1] / h[:, 3], np.zeros(self.n)], axis=1)

    # --- object, material, path -------------------------------------------------------------
    def object_color(self):
        return np.tile(np.array(self.ob.color[:3], np.float64), (self.n, 1))

    def object_alpha(self):
        return np.full(self.n, float(self.ob.color[3]))

    def object_index(self):
        return np.full(self.n, float(self.ob.pass_index))

    def object_random(self):
        return np.full(self.n, object_random(self.ob.name))

    def material_index(self):
        index = np.empty(len(self.mesh.polygons), np.int64)
        self.mesh.polygons.foreach_get("material_index", index)
        slots = [s.material for s in self.ob.material_slots] or [None]
        passes = np.array([float(m.pass_index) if m is not None else 0.0 for m in slots])
        return passes[np.clip(index[self.faces], 0, len(passes) - 1)]

    def path_flag(self):  # what path_state_init_integrator gives a bake's path
        return np.full(self.n, light_path.CAMERA | light_path.MIS_SKIP | light_path.TRANSPARENT_BACKGROUND,
                       np.uint32)

    def _zero_count(self):
        return np.zeros(self.n, np.int64)

    bounce = diffuse_bounce = glossy_bounce = transmission_bounce = transparent_bounce = portal_bounce = _zero_count

    # --- named attributes --------------------------------------------------------------------
    def attribute(self, name: str):
        for prefix in ("\x01object:", "\x01instancer:"):
            if name.startswith(prefix):  # not an instance: the object, then its data
                value = object_attribute(self.ob, name[len(prefix):])
                return Attribute("float4", np.asarray(value, np.float64))
        found = self.attributes.get(name)
        return None if found is None else self._point_attribute(*found)


def _state(ob, size: int, camera, world_from_camera, view_from: str) -> ShadingState:
    """The ShadingState at the texels the object's bake covers (all of them on a plane)."""
    surface = _Surface(ob, size, camera, world_from_camera, view_from)
    return ShadingState(surface.n, source=surface)


def bake(cases: dict, size: int = SIZE, view_from: str = "ABOVE_SURFACE", columns: int | None = None) -> dict:
    """{name: (cycles (S*S,3), ember (S*S,3))} for cases {name: build(node_tree) -> socket, or
    Placed(build, ...)}; view_from: the baker's ABOVE_SURFACE (rays down the normal) or
    ACTIVE_CAMERA (rays from the scene's camera). The objects stand in a row along x, or in
    rows of `columns` centred on the origin: nearer it, as Cycles computes positions in float32
    (far from the origin their rounding shows in the true normal, and in a Bump node's finite
    differences of heights that depend on the position)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 1
    scene.render.bake.view_from = view_from
    scene.render.bake.margin = 0  # texels no triangle covers stay black
    camera = _camera()
    mesh = _plane_mesh()
    made = {}
    for k, (name, case) in enumerate(cases.items()):
        ob, build = _plane(k, case, mesh, _slot(k, len(cases), columns))
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
        surface = _Surface(ob, size, camera, world_from_camera, view_from)
        ember = np.zeros((size * size, 3))
        ember[surface.covered] = evaluate(out, ShadingState(surface.n, source=surface))
        results[name] = (cycles, ember)
    log_conformance(results)
    return results


def log_conformance(results: dict) -> None:
    """With EMBER_CONFORMANCE_LOG set to a file, append a line per case: its name, the share of
    texels in agreement and the largest difference (bench/nodes_conformance.py tabulates them)."""
    path = os.environ.get("EMBER_CONFORMANCE_LOG")
    if not path:
        return
    test = os.environ.get("PYTEST_CURRENT_TEST", "").split(" ")[0]
    with open(path, "a", encoding="utf-8") as f:
        for name, (cycles, ember) in results.items():
            diff = float(np.max(np.abs(cycles - ember))) if len(cycles) else 0.0
            f.write(json.dumps({"test": test, "case": str(name), "agreement": agreement(cycles, ember),
                                "max_diff": diff, "max_value": float(np.max(np.abs(cycles)))}) + "\n")


def evaluate(output_node, state: ShadingState) -> np.ndarray:
    """Ember's emitted radiance (N,3) of a material output node's Surface at the state's points.
    A material displaced as bump (Cycles' Bump Only, or Displacement and Bump) has its shading
    normal set first by the bump of its Displacement, as Cycles does before the surface."""
    warnings = []
    sockets = {"surface": output_node.inputs["Surface"]}
    material = next((m for m in bpy.data.materials if m.node_tree == output_node.id_data), None)
    method = getattr(material, "displacement_method", "BUMP")
    if output_node.inputs["Displacement"].is_linked and method in ("BUMP", "BOTH"):
        sockets["displacement"] = output_node.inputs["Displacement"]
    graph = export_graph(sockets, warnings.append)
    if "displacement" in sockets:
        graph = bump_from_displacement(graph, object_space=method == "BOTH")
        bumped = compile(graph, {"normal": "vector"})
        assert not bumped.warnings, bumped.warnings
        state = ShadingState(state.n, source=state._source, N=bumped.run(state)["normal"])
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
