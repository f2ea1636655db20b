"""Mesh instances -> one world-space triangle soup (Mesh).

Each distinct evaluated mesh (keyed by the evaluated mesh datablock, so objects sharing a
mesh, collection instances and geometry-nodes instances of one geometry share it) is
extracted once with to_mesh() + foreach_get into preallocated float32/int32 arrays, with
the corner UVs of its active render UV map (zeros without one, as Cycles).
Instances are grouped per (mesh, material slots) and transformed with NumPy in chunks:
positions by the 4x4, corner normals by the inverse transpose (renormalised). A
negative-determinant transform reverses the triangle winding (and the corner order) so
the winding normal keeps agreeing with the shading normals, as Cycles does for
negatively scaled objects. Zero-area triangles are dropped (counted, one warning);
triangles with NaN or infinite vertex coordinates and instances with a non-finite or
singular transform are dropped too, and reported as such, naming the objects.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..errors import EmberError
from ..nodes.hash import uint_to_float
from ..nodes.mesh_attributes import object_random
from ..scene import ATTRIBUTE_TYPES, LINK_ALL, RAY_ALL, Mesh
from .export_attributes import MeshAttributes, object_attribute, triangle_values

# A triangle is degenerate when |e1 x e2| <= EPS_SIN * |e1| |e2| (collinear in float32).
EPS_SIN = 1e-7
# Work arrays per transform chunk stay around this many vertices/corners.
CHUNK_ELEMENTS = 1 << 21


class _Proto:
    __slots__ = ("positions", "triangles", "normals", "uvs", "slot", "n_dropped", "n_nonfinite", "name", "texspace",
                 "kept", "attributes")

    def __init__(self, positions, triangles, normals, uvs, slot, n_dropped, n_nonfinite=0, name="", kept=None):
        self.positions = positions  # (V,3) float32 local
        self.triangles = triangles  # (T,3) int32, degenerate ones removed
        self.normals = normals  # (T,3,3) float32 local corner normals
        self.uvs = uvs  # (T,3,2) float32 corner UVs
        self.slot = slot  # (T,) int32 material slot index
        self.n_dropped = n_dropped  # zero-area triangles removed
        self.n_nonfinite = n_nonfinite  # triangles with a NaN/Inf vertex removed
        self.name = name  # the object it was first extracted from (for messages)
        self.texspace = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])  # (location, size): Generated's box
        self.kept = kept  # (T,) the loop triangles kept, or None: all of them
        # Named attributes node programs read (Cycles' names): name -> (type, (T,3,c) per corner or
        # (T,c) per triangle, float32), or None where the mesh has no such attribute.
        self.attributes: dict = {}


def _ints(collection, prop, n) -> np.ndarray:
    a = np.empty(n, np.int32)
    collection.foreach_get(prop, a)
    return a


def corner_tris_blender(me) -> np.ndarray:
    """(T,3) corner (loop) indices of the loop triangles, straight from Blender (slow: it
    computes LoopTriangle properties per element, bench/results/viewport/report.md)."""
    return _ints(me.loop_triangles, "loops", 3 * len(me.loop_triangles)).reshape(-1, 3)


PER_ELEMENT_LIMIT = 20000  # triangles read one by one from Blender before giving up
QUAD_FOLD_COS = -0.5  # quads folded or concave beyond this are read from Blender


def corner_tris(me, positions=None, corner_vert=None) -> np.ndarray:
    """(T,3) corner indices of the loop triangles, identical to Blender's (a test checks
    it): triangles come in face order, face i starting at triangle loop_start[i] - 2i;
    triangles are (0,1,2), quads (0,1,2), (0,2,3) unless Blender flips a concave or folded
    quad to the 1-3 diagonal. N-gon triangles (polyfill) and every quad that is folded or
    concave enough for the two flip tests Blender uses to possibly disagree with this one
    are read from Blender itself, one by one."""
    n_tri, n_loop, n_poly = len(me.loop_triangles), len(me.loops), len(me.polygons)
    if positions is None:
        positions = np.empty(3 * len(me.vertices), np.float32)
        me.attributes["position"].data.foreach_get("vector", positions)
    if corner_vert is None:
        corner_vert = _ints(me.loops, "vertex_index", n_loop)
    positions = positions.reshape(-1, 3)
    tri_poly = _ints(me.loop_triangle_polygons, "value", n_tri)
    start = _ints(me.polygons, "loop_start", n_poly)
    size = np.diff(np.append(start, n_loop))
    if int((size - 2).sum()) != n_tri:  # unexpected layout: trust Blender
        return corner_tris_blender(me)
    s = start[tri_poly]
    j = np.arange(n_tri, dtype=np.int32) - (start - 2 * np.arange(n_poly, dtype=np.int32))[tri_poly]
    tris = np.stack([s, s + 1 + j, s + 2 + j], axis=1)
    tri_size = size[tri_poly]
    ask = [np.flatnonzero(tri_size > 4)]
    first = np.flatnonzero((tri_size == 4) & (j == 0))  # first triangle of each quad
    if len(first):
        q = s[first][:, None] + np.arange(4, dtype=np.int32)
        v = positions[corner_vert[q]].astype(np.float64)  # (Q,4,3)
        d13 = v[:, 2] - v[:, 0]
        ca = np.cross(v[:, 1] - v[:, 0], d13)
        cb = np.cross(v[:, 3] - v[:, 0], d13)
        with np.errstate(invalid="ignore", divide="ignore"):
            cos = np.einsum("ij,ij->i", ca, cb) / np.sqrt(np.einsum("ij,ij->i", ca, ca) * np.einsum("ij,ij->i", cb, cb))
        unsure = first[~(cos < QUAD_FOLD_COS)]  # NaN (degenerate) counts as unsure
        ask += [unsure, unsure + 1]
    ask = np.concatenate(ask)
    if len(ask) > PER_ELEMENT_LIMIT:
        return corner_tris_blender(me)
    if len(ask):
        lt = me.loop_triangles
        tris[ask] = [tuple(lt[i].loops) for i in ask.tolist()]
    return tris


def _corners(me, pos=None):
    """(corner_vert (L,), loops (T,3)): each corner's vertex and the loop triangles' corners."""
    n_loop = len(me.loops)
    if pos is None:
        pos = np.empty(len(me.vertices) * 3, np.float32)
        me.attributes["position"].data.foreach_get("vector", pos)
    cv = me.attributes.get(".corner_vert")
    if cv is not None and cv.domain == "CORNER" and len(cv.data) == n_loop:
        corner_vert = _ints(cv.data, "value", n_loop)
    else:
        corner_vert = _ints(me.loops, "vertex_index", n_loop)
    return corner_vert, corner_tris(me, pos, corner_vert)


def extract_mesh(ob) -> _Proto | None:
    """Triangles of an evaluated object (modifiers applied). None if it has none."""
    me = ob.to_mesh()
    try:
        if me is None:
            return None
        me.calc_loop_triangles()
        n_tri, n_vert, n_loop = len(me.loop_triangles), len(me.vertices), len(me.loops)
        if n_tri == 0:
            return None
        attrs = me.attributes
        pos = np.empty(n_vert * 3, np.float32)
        attrs["position"].data.foreach_get("vector", pos)
        corner_vert, loops = _corners(me, pos)
        mi = attrs.get("material_index")
        if mi is not None and mi.domain == "FACE" and mi.data_type == "INT":
            tri_poly = _ints(me.loop_triangle_polygons, "value", n_tri)
            slot = _ints(mi.data, "value", len(me.polygons))[tri_poly]
        else:
            slot = np.zeros(n_tri, np.int32)
        corner = np.empty(n_loop * 3, np.float32)
        me.corner_normals.foreach_get("vector", corner)
        corner_uv = _corner_uvs(me, n_loop)
        texspace = _texspace(ob, me)
    finally:
        ob.to_mesh_clear()
    tris = corner_vert[loops]
    normals = corner.reshape(-1, 3)[loops]
    proto = _finish_proto(pos.reshape(-1, 3), tris, normals, corner_uv[loops], slot)
    proto.name, proto.texspace = ob.name, texspace
    return proto


def add_attributes(proto: _Proto, ob, names) -> None:
    """The named attributes `names` (Cycles' names) node programs read, into proto.attributes,
    from the evaluated object the proto was extracted from (or another of the same mesh). Apart
    from extract_mesh: which materials an object has, and so what they read, is known only once
    the mesh is known to have triangles (an object without any converts no material)."""
    me = ob.to_mesh()
    try:
        if me is None:
            return
        me.calc_loop_triangles()
        corner_vert, loops = _corners(me)
        found = MeshAttributes(me, loops, corner_vert)
        for name in names:
            value = found.get(name)
            proto.attributes[name] = None if value is None else triangle_values(value, found, proto.kept)
    finally:
        ob.to_mesh_clear()


def _texspace(ob, me) -> np.ndarray:
    """(2,3) the object's texture space (location, size: Generated maps location - size ..
    location + size to [0, 1]), as Cycles reads it from the original mesh (its own box, or the
    box auto texture space computes from the evaluated geometry)."""
    data = getattr(ob, "data", None)
    src = data if data is not None and hasattr(data, "texspace_location") else me
    loc = np.array(src.texspace_location, np.float64)
    size = np.array(src.texspace_size, np.float64)
    return np.array([loc, np.where(size != 0.0, size, 1.0)])


def _corner_uvs(me, n_loop) -> np.ndarray:
    """(n_loop, 2) float32 UVs of the active render UV map (Cycles' default "UV"), or zeros."""
    layers = me.uv_layers
    layer = next((uv for uv in layers if uv.active_render), None) or layers.active
    uv = np.zeros(n_loop * 2, np.float32)
    if layer is not None:
        layer.uv.foreach_get("vector", uv)
    return uv.reshape(-1, 2)


def _sin2(e1, e2):
    """(|e1 x e2|^2, |e1|^2 |e2|^2) per row."""
    cx = e1[:, 1] * e2[:, 2] - e1[:, 2] * e2[:, 1]
    cy = e1[:, 2] * e2[:, 0] - e1[:, 0] * e2[:, 2]
    cz = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    return cx * cx + cy * cy + cz * cz, (e1 * e1).sum(1) * (e2 * e2).sum(1)


def _finish_proto(pos, tris, normals, uvs, slot) -> _Proto:
    """Drop degenerate triangles and repair bad corner normals. pos (V,3) float32."""
    n_tri = len(tris)
    finite_vertex = np.isfinite(pos).all(axis=1)
    finite_tri = finite_vertex[tris].all(axis=1)
    n_nonfinite = int(n_tri - np.count_nonzero(finite_tri))
    if n_nonfinite:  # their triangles are dropped; zero the coordinates so no NaN reaches
        pos = np.where(finite_vertex[:, None], pos, np.float32(0.0))  # the bounds or Embree
    a, b, c = pos[tris[:, 0]], pos[tris[:, 1]], pos[tris[:, 2]]
    # Fast float32 pass; float32 rounding of the cross product is a few 1e-8 |e1||e2|,
    # so only triangles with sin(angle) below 1e-6 need the exact float64 test.
    c2, l2 = _sin2(b - a, c - a)
    with np.errstate(invalid="ignore", over="ignore"):
        valid = c2 > np.float32(1e-12) * l2
    unsure = np.flatnonzero(~valid)
    if len(unsure):
        i0, i1, i2 = (pos[tris[unsure, k]].astype(np.float64) for k in range(3))
        c2u, l2u = _sin2(i1 - i0, i2 - i0)
        valid[unsure] = (c2u > (EPS_SIN * EPS_SIN) * l2u) & np.isfinite(c2u) & np.isfinite(l2u)
    valid &= finite_tri
    n_dropped = int(n_tri - np.count_nonzero(valid)) - n_nonfinite
    kept = None
    if n_dropped:
        kept = np.flatnonzero(valid)
        tris, normals, uvs, slot = tris[valid], normals[valid], uvs[valid], slot[valid]
        a, b, c = a[valid], b[valid], c[valid]
    # Guard against zero/non-finite corner normals: use the face normal there.
    n2 = np.einsum("ijk,ijk->ij", normals, normals)
    bad = ~(n2 > 0.5)  # corner normals from Blender are unit; catches 0 and NaN
    if bad.any():
        ti, ci = np.nonzero(bad)
        face = np.cross((b[ti] - a[ti]).astype(np.float64), (c[ti] - a[ti]).astype(np.float64))
        normals[ti, ci] = face / np.linalg.norm(face, axis=1)[:, None]
    return _Proto(pos, np.ascontiguousarray(tris, np.int32), np.ascontiguousarray(normals, np.float32),
                  np.ascontiguousarray(uvs, np.float32), np.ascontiguousarray(slot, np.int32), n_dropped,
                  n_nonfinite, kept=kept)


def _shifted(M: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """World-from-object matrices (k,4,4) with the world moved by -shift (the render origin)."""
    M = M.copy()
    M[:, :3, 3] -= shift
    return M


def _normalize_rows(v: np.ndarray) -> np.ndarray:
    n = np.sqrt(np.einsum("...i,...i->...", v, v))
    return v / np.where(n > 0, n, 1.0)[..., None]


# What node programs read (engine/nodes/state.py) that the export carries in the Mesh; the
# rest is computed at hits from the mesh's own arrays ("uv", "generated": Mesh.uvs, the
# object transforms and texture spaces).
_OBJECT_INFO = frozenset(("object_color", "object_alpha", "object_index", "object_random"))
_FROM_HITS = frozenset(("", "uv", "generated"))
_OBJECT_PREFIXES = ("\x01object:", "\x01instancer:")


class Needs(NamedTuple):
    """What a set of materials' programs read that the export must carry: named mesh
    attributes, Object / Instancer attributes (Cycles' prefixed names), Object Info's per-object
    values (object_info), the materials' Pass Index."""

    mesh: frozenset = frozenset()
    objects: frozenset = frozenset()
    info: bool = False
    material_index: bool = False

    @staticmethod
    def of(reads) -> "Needs":
        """From the fields programs read (engine/nodes/program.py Program.reads)."""
        names = {r[len("attribute:"):] for r in reads if r.startswith("attribute:")}
        objects = frozenset(n for n in names if n.startswith(_OBJECT_PREFIXES))
        return Needs(frozenset(names - objects - _FROM_HITS), objects, bool(_OBJECT_INFO & set(reads)),
                     "material_index" in reads)

    def __or__(self, other: "Needs") -> "Needs":
        return Needs(self.mesh | other.mesh, self.objects | other.objects, self.info or other.info,
                     self.material_index or other.material_index)

    @property
    def per_object(self) -> bool:
        return bool(self.objects) or self.info


def _link_fields(links) -> dict:
    """Mesh.link_sets and link_membership from the plan entries' (k,4) LinkSets rows."""
    if not links:
        return {}
    rows = np.concatenate(links)
    return dict(link_sets=rows[:, :2].astype(np.uint8), link_membership=np.ascontiguousarray(rows[:, 2:]))


def _terminator(ob) -> tuple:
    """The object's shadow terminator Geometry Offset and Shading Offset (Cycles reads them
    from the object, instances from their object)."""
    return (float(getattr(ob, "shadow_terminator_geometry_offset", 0.0)),
            float(getattr(ob, "shadow_terminator_shading_offset", 0.0)))


def _object_record(ob, inst, needs: Needs):
    """(object_info (6,) or None, {attribute name: RGBA}) of an instance, as Cycles' object sync
    sets them (blender/object.cpp): Color, Pass Index and the random number (the depsgraph
    instance's random_id for an instance, else the hash of the object's name), the Object and
    Instancer attributes (export_attributes.object_attribute)."""
    info = None
    is_instance = inst is not None and bool(inst.is_instance)
    if needs.info:
        if is_instance:
            random = float(uint_to_float(np.uint32(int(inst.random_id) & 0xFFFFFFFF)))
        else:
            random = object_random(ob.name)
        info = tuple(float(c) for c in ob.color) + (float(ob.pass_index), random)
    attrs = {}
    for name in needs.objects:
        if name.startswith(_OBJECT_PREFIXES[1]) and is_instance:
            system = inst.particle_system
            attrs[name] = object_attribute(ob, name[len(_OBJECT_PREFIXES[1]):], inst.parent,
                                           system.settings if system is not None else None)
        else:
            prefix = next(p for p in _OBJECT_PREFIXES if name.startswith(p))
            attrs[name] = object_attribute(ob, name[len(prefix):])
    return info, attrs


class MeshCollector:
    """Fed with every visible MESH instance during the depsgraph walk, then `build()`."""

    def __init__(self, materials, warn, material_override=None, protos: dict | None = None, links=None):
        """protos: extracted meshes by evaluated mesh pointer, from an earlier export of the
        same geometry (the viewport's), added to here. materials: the MaterialTable; its
        `reads(i)` (the fields material i's node programs read, if it has that method) decides
        what the Mesh carries for node programs (Mesh.attributes, object_info, ...)."""
        self._materials = materials
        self._warn = warn
        self._override = material_override  # view layer material override (as Cycles)
        self._protos: dict[int, _Proto | None] = {} if protos is None else protos
        self._groups: dict[tuple, list] = {}
        self._records: dict[tuple, list] = {}  # per group, per instance: _object_record or None
        self._terminator: dict[tuple, list] = {}  # per group, per instance: _terminator(ob)
        self._linking = links  # export_linking.LinkSets, or None: no light linking
        self._links: dict[tuple, list] = {}  # per group, per instance: LinkSets.of_object(ob)
        self._slot_cache: dict[tuple, tuple] = {}
        self._needs_cache: dict[tuple, Needs] = {}
        self._needs = Needs()  # everything any material read so far
        self._passes: dict[int, float] = {}  # material index -> its Pass Index

    @property
    def n_meshes(self) -> int:
        return sum(p is not None for p in self._protos.values())

    def _slots(self, ob, data_key) -> tuple:
        key = (ob.original.as_pointer(), data_key)
        mats = self._slot_cache.get(key)
        if mats is None:
            slots = ob.material_slots
            if self._override is not None:
                bl = (self._override,)
            elif len(slots):
                bl = tuple(s.material for s in slots)
            else:
                bl = tuple(ob.data.materials)
            mats = tuple(self._materials.index(m) for m in bl)
            for i, m in zip(mats, bl):
                self._passes.setdefault(i, float(m.pass_index) if m is not None else 0.0)
            self._slot_cache[key] = mats
        return mats

    def _needs_of(self, mats: tuple) -> Needs:
        needs = self._needs_cache.get(mats)
        if needs is None:
            reads = getattr(self._materials, "reads", None)
            needs = Needs()
            for i in (dict.fromkeys(mats) if reads is not None else ()):
                needs = needs | Needs.of(reads(i))
            self._needs_cache[mats] = needs
            self._needs = self._needs | needs
        return needs

    def add(self, ob, matrix_world, visibility: int = RAY_ALL, inst=None) -> None:
        """ob: evaluated MESH object of the current instance; matrix_world: a copy;
        visibility: RAY_* bits (+ HOLDOUT) of the object (Mesh.visibility); inst: the depsgraph
        instance (its random id, instancer and particle system), read now if the object's
        materials read Object Info or Object / Instancer attributes."""
        data_key = ob.data.as_pointer()
        proto = self._protos.get(data_key, False)
        if proto is False:
            proto = self._protos[data_key] = extract_mesh(ob)
        if proto is None:
            return
        mats = self._slots(ob, data_key)
        needs = self._needs_of(mats)
        missing = [name for name in sorted(needs.mesh) if name not in proto.attributes]
        if missing:
            add_attributes(proto, ob, missing)
        group = (data_key, mats, visibility)
        lst = self._groups.get(group)
        if lst is None:
            lst = self._groups[group] = []
            self._records[group] = []
        lst.append(matrix_world)
        self._records[group].append(_object_record(ob, inst, needs) if needs.per_object else None)
        self._terminator.setdefault(group, []).append(_terminator(ob))
        if self._linking is not None:
            self._links.setdefault(group, []).append(self._linking.of_object(ob))

    def bounds(self) -> np.ndarray:
        """(2,3) float64 world bounding box (min, max) of every collected instance, from the
        8 corners of each mesh's local box (for the scene's origin); empty (0,3) if none."""
        lo, hi = [], []
        for (data_key, _, _), matrices in self._groups.items():
            proto = self._protos[data_key]
            p = proto.positions[np.all(np.isfinite(proto.positions), axis=1)].astype(np.float64)
            if len(p) == 0:
                continue
            a, b = p.min(axis=0), p.max(axis=0)
            corners = np.array([[(a, b)[i][0], (a, b)[j][1], (a, b)[k][2]]
                                for i in (0, 1) for j in (0, 1) for k in (0, 1)])
            M = np.array(matrices, np.float64).reshape(-1, 4, 4)
            w = np.einsum("kij,cj->kci", M[:, :3, :3], corners) + M[:, None, :3, 3]
            w = w.reshape(-1, 3)
            w = w[np.all(np.isfinite(w), axis=1)]
            if len(w):
                lo.append(w.min(axis=0))
                hi.append(w.max(axis=0))
        if not lo:
            return np.zeros((0, 3))
        return np.array([np.min(lo, axis=0), np.max(hi, axis=0)])

    def build(self, check=lambda: None, report=lambda msg: None, origin=None, placed: dict | None = None) -> Mesh:
        """The world-space triangle soup; with `origin` (3,) the world is shifted so that it
        becomes (0, 0, 0), in float64 before the float32 store (precision far from 0).
        placed: the last build's mesh and where each group went in it (the viewport's; read
        and replaced here): a group of the same mesh, materials and transforms is copied from
        there instead of transformed again."""
        shift = np.zeros(3) if origin is None else np.asarray(origin, np.float64)
        plan = []  # (proto, material lookup, visibility, matrices (k,4,4), det (k,))
        placed_records = []  # per plan entry, per instance: _object_record or None
        terminator = []  # per plan entry: (k,2) its instances' shadow terminator offsets
        links = []  # per plan entry: (k,4) its instances' LinkSets.of_object
        n_vert = n_tri = 0
        dropped = 0
        nonfinite, bad_transform = [], []  # object names
        for group, matrices in self._groups.items():
            data_key, mats, vis = group
            records = self._records.get(group) or [None] * len(matrices)
            offsets = np.array(self._terminator.get(group) or [(0.0, 0.0)] * len(matrices), np.float32).reshape(-1, 2)
            linked = np.array(self._links.get(group) or [(0, 0, LINK_ALL, LINK_ALL)] * len(matrices),
                              np.uint64).reshape(-1, 4)
            proto = self._protos[data_key]
            M = np.array(matrices, np.float64).reshape(-1, 4, 4)
            det = np.linalg.det(M[:, :3, :3])
            ok = np.isfinite(det) & (det != 0.0) & np.all(np.isfinite(M.reshape(len(M), -1)), axis=1)
            dropped += proto.n_dropped * len(M)
            if proto.n_nonfinite:
                nonfinite.append(proto.name)
            if not ok.all():
                finite = np.all(np.isfinite(M.reshape(len(M), -1)), axis=1)
                if not finite.all():
                    bad_transform.append(proto.name)
                dropped += len(proto.triangles) * int(np.count_nonzero(~ok & finite))  # scaled to 0
                M, det = M[ok], det[ok]
                records = [r for r, keep in zip(records, ok) if keep]
                offsets, linked = offsets[ok], linked[ok]
            if len(M) == 0 or len(proto.triangles) == 0:
                continue
            plan.append((proto, mats, vis, M, det))
            placed_records.append(records)
            terminator.append(offsets)
            links.append(linked)
            n_vert += len(M) * len(proto.positions)
            n_tri += len(M) * len(proto.triangles)

        if n_vert >= 2**31:
            raise EmberError(f"The scene has {n_vert} vertices after instancing; at most 2^31 are supported.")
        vertices = np.empty((n_vert, 3), np.float32)
        triangles = np.empty((n_tri, 3), np.int32)
        normals = np.empty((n_tri, 3, 3), np.float32)
        uvs = np.empty((n_tri, 3, 2), np.float32)
        material = np.empty(n_tri, np.int32)
        visibility = np.empty(n_tri, np.uint8)

        default = None
        v0 = t0 = 0
        starts, object_matrix, object_texspace = [], [], []
        last = placed.get("mesh") if placed is not None else None
        was, now = (placed.get("groups", {}) if placed is not None else {}), {}
        for gi, (proto, mats, vis, M, det) in enumerate(plan):
            check()
            report(f"Export: meshes {gi + 1}/{len(plan)}")
            V, T = len(proto.positions), len(proto.triangles)
            key = (mats, vis, M.tobytes(), shift.tobytes())
            now[key] = (proto, v0, t0)
            old = was.get(key)
            if last is not None and old is not None and old[0] is proto:  # placed as before: copy
                _, pv, pt = old
                nv, nt = len(M) * V, len(M) * T
                vertices[v0:v0 + nv] = last.vertices[pv:pv + nv]
                triangles[t0:t0 + nt] = last.triangles[pt:pt + nt] + (v0 - pv)
                normals[t0:t0 + nt], uvs[t0:t0 + nt] = last.normals[pt:pt + nt], last.uvs[pt:pt + nt]
                material[t0:t0 + nt] = last.material[pt:pt + nt]
                visibility[t0:t0 + nt] = vis
                starts.extend(t0 + T * np.arange(len(M)))
                object_matrix.append(_shifted(M, shift))
                object_texspace.append(np.broadcast_to(proto.texspace, (len(M), 2, 3)))
                v0, t0 = v0 + nv, t0 + nt
                continue
            if mats:
                lut = np.array(mats, np.int32)
                mat_local = lut[np.clip(proto.slot, 0, len(lut) - 1)]
            else:
                if default is None:
                    default = self._materials.index(None)
                mat_local = np.full(T, default, np.int32)
            flipped_tris = proto.triangles[:, [0, 2, 1]]
            flipped_uvs = proto.uvs[:, [0, 2, 1]]
            corners = proto.normals.reshape(-1, 3)
            chunk = max(1, CHUNK_ELEMENTS // max(V, 3 * T))
            for s in range(0, len(M), chunk):
                Mc, dc = M[s:s + chunk], det[s:s + chunk]
                k = len(Mc)
                R = Mc[:, :3, :3]
                P = np.matmul(proto.positions[None], R.transpose(0, 2, 1)) + (Mc[:, None, :3, 3] - shift)
                vertices[v0:v0 + k * V] = P.reshape(-1, 3)
                # Corner normals by the inverse transpose: row vector n -> n R^-1. For a
                # rotation times uniform scale s, R^-1 = R^T / s^2: n R^T is unit already.
                RtR = np.matmul(R.transpose(0, 2, 1), R)
                s2 = np.trace(RtR, axis1=1, axis2=2) / 3.0
                dev = np.abs(RtR - s2[:, None, None] * np.eye(3)).max(axis=(1, 2))
                if np.all(dev <= 1e-6 * s2):
                    Nt = (R / np.sqrt(s2)[:, None, None]).transpose(0, 2, 1).astype(np.float32)
                    N = np.matmul(corners[None], Nt).reshape(k, T, 3, 3)
                else:
                    Rinv = np.linalg.inv(R).astype(np.float32)
                    N = _normalize_rows(np.matmul(corners[None], Rinv)).reshape(k, T, 3, 3)
                starts.extend(t0 + T * np.arange(k))  # each instance is an object (Mesh.objects)
                object_matrix.append(_shifted(Mc, shift))
                object_texspace.append(np.broadcast_to(proto.texspace, (k, 2, 3)))
                offs = (v0 + V * np.arange(k, dtype=np.int64))[:, None, None]
                neg = dc < 0
                tri = np.where(neg[:, None, None], flipped_tris[None], proto.triangles[None]) + offs
                if neg.any():
                    N[neg] = N[neg][:, :, [0, 2, 1]]
                triangles[t0:t0 + k * T] = tri.reshape(-1, 3)
                normals[t0:t0 + k * T] = N.reshape(-1, 3, 3)
                uvs[t0:t0 + k * T] = np.where(neg[:, None, None, None], flipped_uvs[None], proto.uvs[None]).reshape(-1, 3, 2)
                material[t0:t0 + k * T] = np.tile(mat_local, k)
                visibility[t0:t0 + k * T] = vis
                v0 += k * V
                t0 += k * T
        if dropped:
            self._warn(f"{dropped} zero-area triangle(s) were dropped.")
        for what, names in (("Triangles with NaN or infinite vertex coordinates were dropped", nonfinite),
                            ("Instances with a NaN or infinite transform were dropped", bad_transform)):
            for name in dict.fromkeys(names):
                group = getattr(self._warn, "group", None)
                if group is not None:
                    group(what, name)
                else:
                    self._warn(f"{what}: '{name}'.")
        everything = bool(np.all(visibility == RAY_ALL))  # the common case: no array to carry
        mesh = Mesh(vertices=vertices, triangles=triangles, normals=normals, material=material, uvs=uvs,
                    visibility=None if everything else visibility,
                    objects=np.array(starts + [n_tri], np.int64) if starts else None,
                    object_matrix=np.concatenate(object_matrix) if starts else None,
                    object_texspace=np.concatenate(object_texspace) if starts else None,
                    terminator=np.concatenate(terminator) if starts else None,
                    **_link_fields(links if starts and self._linking is not None else None),
                    **self._program_data(plan, placed_records, n_tri))
        if placed is not None:
            placed.update(mesh=mesh, groups=now)
        return mesh

    def _program_data(self, plan, records, n_tri: int) -> dict:
        """The Mesh fields node programs read (Mesh.attributes, object_attributes, object_info,
        material_pass_index), laid out as build lays out the triangles and objects: plan entry
        after plan entry, instance after instance; None for what no material reads."""
        needs = self._needs
        out = {}
        n_objects = sum(len(M) for _, _, _, M, _ in plan)
        if needs.mesh:
            out["attributes"] = {name: _attribute(name, plan, n_tri, n_objects) for name in sorted(needs.mesh)}
        flat = [r for rs in records for r in rs]
        if needs.info:
            info = np.zeros((n_objects, 6))
            for b, r in enumerate(flat):
                if r is not None and r[0] is not None:
                    info[b] = r[0]
            out["object_info"] = info
        if needs.objects:
            out["object_attributes"] = {
                name: np.array([r[1][name] if r is not None and name in r[1] else (0.0, 0.0, 0.0, 0.0) for r in flat],
                               np.float64).reshape(n_objects, 4) for name in sorted(needs.objects)}
        if needs.material_index:
            out["material_pass_index"] = np.array([self._passes.get(i, 0.0) for i in range(len(self._materials))],
                                                  np.float64)
        return out


def _attribute(name: str, plan, n_tri: int, n_objects: int):
    """(values, types) of one named attribute over the whole soup (Mesh.attributes): per corner
    (T,3,c) where some mesh has it per corner (a per-face value then on all three), else per
    triangle (T,c); c the most channels any mesh has; the corners of a negatively scaled
    instance in its flipped order; zeros and type -1 where a mesh lacks it."""
    found = [p.attributes.get(name) for p, _, _, _, _ in plan]
    arrays = [f[1] for f in found if f is not None]
    if not arrays:
        return np.zeros((n_tri, 1), np.float32), np.full(n_objects, -1, np.int8)
    corner = any(a.ndim == 3 for a in arrays)
    c = max(a.shape[-1] for a in arrays)
    values = np.zeros((n_tri, 3, c) if corner else (n_tri, c), np.float32)
    types = np.full(n_objects, -1, np.int8)
    t0 = b0 = 0
    for (proto, _, _, M, det), f in zip(plan, found):
        k, T = len(M), len(proto.triangles)
        if f is not None:
            types[b0:b0 + k] = ATTRIBUTE_TYPES.index(f[0])
            a = f[1]
            w = a.shape[-1]
            block = values[t0:t0 + k * T].reshape((k, T) + values.shape[1:])
            if corner:
                a = np.broadcast_to(a[:, None, :], (T, 3, w)) if a.ndim == 2 else a
                neg = det < 0
                block[~neg, :, :, :w] = a
                if neg.any():  # the export flips these instances' corners 1 and 2
                    block[neg, :, :, :w] = a[:, [0, 2, 1]]
            else:
                block[:, :, :w] = a
        t0 += k * T
        b0 += k
    return values, types
