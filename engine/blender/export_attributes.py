"""What the Attribute, Color Attribute, UV Map, Tangent and Geometry nodes read from Blender
data, by Cycles' attribute names, as Cycles' sync exports it (intern/cycles/blender/mesh.cpp,
object.cpp, shader.cpp; engine/nodes/state.py lists the names).

MeshAttributes(mesh).get(name) gives (type, domain, values): type as Cycles stores it ("float",
"float2", "float3", "float4", "rgba"), domain "point", "corner", "face", "triangle" (one value
per loop triangle) or "mesh" (one value), values an array per element. engine/nodes/
mesh_attributes.at_hits interpolates it at hit points. Object and Instancer attributes are
single values per object (object_attribute), View Layer attributes single values per render
(view_layer_attribute, folded into the node graph at export as Cycles folds them).
"""
from __future__ import annotations

import numpy as np

from ..nodes.mesh_attributes import bytes_to_linear, pointiness, random_per_island

# Blender attribute types -> (Cycles type, channels read from Blender's `data`), as Cycles'
# AttributeConverter maps them; other types (INT32_2D, FLOAT4X4, STRING, ...) are not exported.
_TYPES = {"FLOAT": ("float", "value"), "INT": ("float", "value"), "BOOLEAN": ("float", "value"),
          "INT8": ("float", "value"), "FLOAT2": ("float2", "vector"), "FLOAT_VECTOR": ("float3", "vector"),
          "FLOAT_COLOR": ("rgba", "color"), "BYTE_COLOR": ("rgba", "color_srgb"),
          "QUATERNION": ("float4", "value")}
_DOMAINS = {"POINT": "point", "CORNER": "corner", "FACE": "face", "EDGE": "edge"}
_TANGENT_SUFFIXES = (".undisplaced_tangent_sign", ".undisplaced_tangent", ".tangent_sign", ".tangent")
# Cycles' standard attribute names (scene/attribute.cpp Attribute::standard_name): a node asking
# for one of these gets the standard attribute, never a mesh attribute that happens to share the
# name; those a mesh surface does not have (volume grids, curves, points, ...) are not found.
STANDARD_NAMES = frozenset((
    "P", "radius", "N", "uv", "generated", "generated_transform", "tangent", "tangent_sign", "undisplaced_tangent",
    "undisplaced_tangent_sign", "vertex_color", "undeformed", "undisplaced", "undisplaced_N", "particle",
    "curve_intercept", "curve_length", "curve_random", "point_random", "ptex_face_id", "ptex_uv", "density", "color",
    "flame", "heat", "temperature", "velocity", "velocity_x", "velocity_y", "velocity_z", "pointiness",
    "random_per_island", "shadow_transparency"))


def _read(collection, key: str, count: int, width: int) -> np.ndarray:
    out = np.empty(count * width, np.float64)
    collection.foreach_get(key, out)
    return out.reshape(count, width) if width > 1 else out


class MeshAttributes:
    """A Blender mesh's attributes by Cycles' names (module docstring). Computed on first use
    and kept: the loop triangles, tangents, pointiness and islands.

    triangle_loops (T,3), corner_vert (L,), triangle_faces (T,): the loop triangles' corners,
    each corner's vertex and each triangle's face where the caller has them already (the mesh
    export computes them faster than Blender's per-element loop triangle properties); read
    from the mesh otherwise."""

    def __init__(self, mesh, triangle_loops=None, corner_vert=None, triangle_faces=None):
        self.mesh = mesh
        self._cache: dict = {}
        tris = mesh.loop_triangles
        t = len(tris)
        if triangle_loops is None:
            self.triangle_loops = _read(tris, "loops", t, 3).astype(np.int64)
            self.triangle_verts = _read(tris, "vertices", t, 3).astype(np.int64)
        else:
            self.triangle_loops = np.asarray(triangle_loops, np.int64).reshape(-1, 3)
            if corner_vert is None:
                corner_vert = _read(mesh.loops, "vertex_index", len(mesh.loops), 1).astype(np.int64)
            self.triangle_verts = np.asarray(corner_vert, np.int64)[self.triangle_loops]
        if triangle_faces is None:
            triangle_faces = _read(mesh.loop_triangle_polygons, "value", t, 1)
        self.triangle_faces = np.asarray(triangle_faces, np.int64).reshape(-1)

    def render_uv_name(self) -> str | None:
        for layer in self.mesh.uv_layers:
            if layer.active_render:
                return layer.name
        return None

    def get(self, name: str):
        if name not in self._cache:
            self._cache[name] = self._make(name)
        return self._cache[name]

    def _make(self, name: str):
        mesh = self.mesh
        if name == "uv":
            render = self.render_uv_name()
            return None if render is None else self._generic(render)
        if name == "generated":
            co = _read(mesh.vertices, "co", len(mesh.vertices), 3)
            loc = np.asarray(mesh.texspace_location, np.float64)
            half = np.asarray(mesh.texspace_size, np.float64)
            return "float3", "point", (co - loc + half) / (2.0 * half)
        if name == "N":  # the vertex normals, object space
            return "float3", "point", _read(mesh.vertex_normals, "vector", len(mesh.vertices), 3)
        if name == "vertex_color":
            default = mesh.attributes.default_color_name
            return None if not default else self._generic(default)
        if name == "pointiness":
            n = len(mesh.vertices)
            co = _read(mesh.vertices, "co", n, 3)
            normals = _read(mesh.vertex_normals, "vector", n, 3)
            edges = _read(mesh.edges, "vertices", len(mesh.edges), 2).astype(np.int64)
            return "float", "point", pointiness(co, normals, edges).astype(np.float64)
        if name == "random_per_island":
            edges = _read(mesh.edges, "vertices", len(mesh.edges), 2).astype(np.int64)
            return "float", "triangle", random_per_island(len(mesh.vertices), edges, self.triangle_verts[:, 0])
        for std in ("undisplaced_tangent_sign", "undisplaced_tangent", "tangent_sign", "tangent"):
            if name == std:
                render = self.render_uv_name()
                return None if render is None else self._tangent(render, std.endswith("sign"))
        if name in STANDARD_NAMES:
            return None
        for suffix in _TANGENT_SUFFIXES:
            if name.endswith(suffix) and name[: -len(suffix)] in mesh.uv_layers:
                return self._tangent(name[: -len(suffix)], suffix.endswith("sign"))
        return self._generic(name)

    def _tangent(self, uv_name: str, sign: bool):
        """MikkTSpace tangents as Cycles computes them (scene/mesh.cpp mikk_compute_tangents): over
        its triangles (the loop triangles), with the original vertex normals on smooth triangles
        and each triangle's own normal on flat ones, in object space; the unit tangent or the
        bitangent sign per triangle corner. Blender's calc_tangents runs the same MikkTSpace: on a
        copy made of those triangles, those normals given as its custom normals."""
        key = ("tangents", uv_name)
        if key not in self._cache:
            self._cache[key] = self._mikktspace(uv_name)
        tangent, signs = self._cache[key]
        return ("float", "triangle_corner", signs) if sign else ("float3", "triangle_corner", tangent)

    def _mikktspace(self, uv_name: str):
        import bpy

        mesh = self.mesh
        co = _read(mesh.vertices, "co", len(mesh.vertices), 3).astype(np.float32)
        # The corner normals: the vertex normals where the mesh's normals are per vertex, and what
        # Cycles' vertex normals become where they are per corner (it splits the mesh's edges
        # there: blender/mesh.cpp mesh_split_edges_for_corner_normals).
        normals = _read(mesh.corner_normals, "vector", len(mesh.loops), 3)
        verts = self.triangle_verts
        smooth = _read(mesh.polygons, "use_smooth", len(mesh.polygons), 1).astype(bool)[self.triangle_faces]
        p = co[verts].astype(np.float32)
        cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]).astype(np.float32)
        length = np.linalg.norm(cross, axis=1).astype(np.float32)[:, None]
        flat = np.where(length > 0.0, cross / np.where(length > 0.0, length, 1.0), np.array([1.0, 0.0, 0.0]))
        corner_normals = np.where(smooth[:, None, None], normals[self.triangle_loops], flat[:, None, :]).reshape(-1, 3)
        uv = _read(mesh.uv_layers[uv_name].data, "uv", len(mesh.loops), 2)[self.triangle_loops].reshape(-1, 2)
        tri = bpy.data.meshes.new("ember_mikktspace")
        try:
            tri.from_pydata(co.tolist(), [], verts.tolist())
            tri.polygons.foreach_set("use_smooth", smooth.tolist())
            layer = tri.uv_layers.new(name="uv")
            layer.data.foreach_set("uv", uv.ravel())
            custom = tri.attributes.new("custom_normal", "FLOAT_VECTOR", "CORNER")
            custom.data.foreach_set("vector", corner_normals.ravel())
            tri.update()
            tri.calc_tangents(uvmap="uv")
            n = len(tri.loops)
            return _read(tri.loops, "tangent", n, 3), _read(tri.loops, "bitangent_sign", n, 1)
        finally:
            bpy.data.meshes.remove(tri)

    def _generic(self, name: str):
        attribute = self.mesh.attributes.get(name)
        if attribute is None or attribute.data_type not in _TYPES or attribute.domain not in _DOMAINS:
            return None
        kind, key = _TYPES[attribute.data_type]
        width = {"float": 1, "float2": 2, "float3": 3}.get(kind, 4)  # a quaternion reads (w, x, y, z)
        values = _read(attribute.data, key, len(attribute.data), width)
        if attribute.data_type == "BYTE_COLOR":  # the stored bytes, linearised as Cycles does
            values = bytes_to_linear(np.round(values * 255.0)).astype(np.float64)
        domain = _DOMAINS[attribute.domain]
        if domain == "edge":  # Blender's domain interpolation: each vertex averages its edges
            values, domain = self._edges_to_points(values), "point"
        return kind, domain, values

    def _edges_to_points(self, values):
        edges = _read(self.mesh.edges, "vertices", len(self.mesh.edges), 2).astype(np.int64)
        n = len(self.mesh.vertices)
        v = values.reshape(len(edges), -1)
        total = np.zeros((n, v.shape[1]))
        np.add.at(total, edges[:, 0], v)
        np.add.at(total, edges[:, 1], v)
        count = np.bincount(edges.ravel(), minlength=n)[:, None]
        out = np.where(count > 0, total / np.maximum(count, 1), 0.0)
        return out[:, 0] if values.ndim == 1 else out


def triangle_values(found, attributes: MeshAttributes, kept=None):
    """An attribute of MeshAttributes.get, (type, domain, values), as the mesh export carries
    it: (type, (T,3,c) float32 per corner of each loop triangle in Blender's corner order, or
    (T,c) float32 per triangle). kept (T,): the loop triangles the export keeps (None: all)."""
    kind, domain, values = found
    v = np.asarray(values)
    v = v.reshape(len(v), -1)
    loops, verts, faces = attributes.triangle_loops, attributes.triangle_verts, attributes.triangle_faces
    rows = np.arange(len(loops)) if kept is None else np.asarray(kept, np.int64)
    if domain == "point":
        out = v[verts[rows]]
    elif domain == "corner":
        out = v[loops[rows]]
    elif domain == "triangle_corner":
        out = v.reshape(len(loops), 3, -1)[rows]
    elif domain == "face":
        out = v[faces[rows]]
    elif domain == "triangle":
        out = v[rows]
    else:  # one value for the mesh
        out = np.broadcast_to(v.reshape(1, -1), (len(rows), v.size))
    return kind, np.ascontiguousarray(out, np.float32)


def _rgba(value):
    """An RNA or custom property value as RGBA, as Blender's find_property_rgba converts it: a
    number v as (v, v, v, 1), up to 4 floats or ints over (0, 0, 0, 1); None otherwise."""
    if isinstance(value, bool):
        return (1.0 if value else 0.0,) * 3 + (1.0,)
    if isinstance(value, (int, float)):
        return (float(value),) * 3 + (1.0,)
    try:
        items = list(value)
    except TypeError:
        return None
    if not 0 < len(items) <= 4 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in items):
        return None
    out = [0.0, 0.0, 0.0, 1.0]
    out[: len(items)] = [float(v) for v in items]
    return tuple(out)


def property_rgba(owner, name: str):
    """find_property_rgba: the custom property `name` of the ID (or struct), else the RNA path
    `name`, as RGBA; None where neither resolves to a convertible value."""
    if owner is None:
        return None
    try:
        if name in owner.keys():
            return _rgba(owner[name])
    except (TypeError, AttributeError):
        pass
    try:
        return _rgba(owner.path_resolve(name))
    except (ValueError, AttributeError, TypeError):
        return None


def object_attribute(ob, name: str, parent=None, particle_settings=None) -> tuple:
    """An Object or Instancer attribute (BKE_object_dupli_find_rgba_attribute): the particle
    settings and the instancer first (Instancer type only), then the object and its data;
    (0, 0, 0, 0) where none has it."""
    for owner in (particle_settings, parent, ob, getattr(ob, "data", None)):
        value = property_rgba(owner, name)
        if value is not None:
            return value
    return (0.0, 0.0, 0.0, 0.0)


def view_layer_attribute(scene, view_layer, name: str) -> tuple:
    """A View Layer attribute (BKE_view_layer_find_rgba_attribute): the view layer, the scene,
    then the scene's world; (0, 0, 0, 0) where none has it."""
    for owner in (view_layer, scene, getattr(scene, "world", None)):
        value = property_rgba(owner, name)
        if value is not None:
            return value
    return (0.0, 0.0, 0.0, 0.0)
