"""Attributes Cycles computes from a mesh on the host, and attributes read at hit points.

Cycles' Blender sync (intern/cycles/blender/mesh.cpp, object.cpp) derives some of what the
Geometry and Object Info nodes output before rendering; these are the same computations on
plain arrays, for Ember's mesh export and for the conformance harness:
- pointiness: per vertex, the angle between the vertex normal and the mean direction of its
  edges, over pi, blurred once over the edge neighbours (attr_create_pointiness), coincident
  vertices welded first;
- random_per_island: per triangle, a hash of the root vertex of its island (the vertices joined
  by edges, found by a union-find in edge order: attr_create_random_per_island);
- object_random: hash_uint2(hash_string(name), 0) (blender/object.cpp) times 2^-32;
- srgb_to_linear: byte colours as Cycles linearises them (util/color.h).
`at_hits` interpolates any per-element attribute at hit points as Cycles' triangle_attribute
does, with the derivatives a Bump node's offset evaluations need.
"""
from __future__ import annotations

import numpy as np

from .hash import hash_uint, hash_uint2, uint_to_float

_F32 = np.float32
_EPS = _F32(np.finfo(np.float32).eps)  # FLT_EPSILON


def _weld(positions):
    """vert_orig_index: each vertex's first coincident vertex (|a - b|^2 < FLT_EPSILON among
    vertices whose coordinate sums lie within 3 FLT_EPSILON), chains followed to their end."""
    p = np.asarray(positions, _F32)
    n = len(p)
    total = (p[:, 0] + p[:, 1]) + p[:, 2]
    # Sorted by the sum, equal vertices by descending index (VertexAverageComparator).
    order = np.lexsort((-np.arange(n), total))
    s = total[order]
    orig = np.arange(n)
    open_ = np.ones(n, bool)  # sorted positions still looking for a duplicate
    k = 1
    while True:
        within = np.zeros(n, bool)  # the k-th next sorted vertex is still within the window
        within[: max(n - k, 0)] = (s[k:] - s[: n - k]) <= _F32(3.0) * _EPS
        open_ &= within  # the sums only grow: past the window, no duplicate further on
        if not open_.any():
            break
        i = np.nonzero(open_)[0]
        d = p[order[i + k]] - p[order[i]]
        hit = ((d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) + d[:, 2] * d[:, 2]) < _EPS
        orig[order[i[hit]]] = order[i[hit] + k]
        open_[i[hit]] = False
        k += 1
    while True:
        nxt = orig[orig]
        if np.array_equal(nxt, orig):
            return orig
        orig = nxt


def _unique_edges(v0, v1):
    """The edges once each, unordered (Cycles' EdgeMap), in their first order."""
    key = np.minimum(v0, v1).astype(np.int64) * (1 << 32) + np.maximum(v0, v1)
    _, first = np.unique(key, return_index=True)
    first.sort()
    return v0[first], v1[first]


def _normalize32(v):
    length = np.sqrt(np.sum(v * v, axis=-1, dtype=_F32)).astype(_F32)
    with np.errstate(all="ignore"):
        return (v / length[:, None]).astype(_F32)


def pointiness(positions, vertex_normals, edges) -> np.ndarray:
    """Cycles' pointiness per vertex (float32, as its sync computes it) from object-space vertex
    positions (V,3), Blender's vertex normals (V,3) and the edges (E,2)."""
    p = np.asarray(positions, _F32)
    n = len(p)
    if n == 0:
        return np.zeros(0, _F32)
    orig = _weld(p)
    acc = np.zeros((n, 3), _F32)
    np.add.at(acc, orig, np.asarray(vertex_normals, _F32))
    normal = _normalize32(acc[orig])
    e = np.asarray(edges, np.int64).reshape(-1, 2)
    v0, v1 = _unique_edges(orig[e[:, 0]], orig[e[:, 1]])
    d = (p[v1] - p[v0]).astype(_F32)
    length = np.sqrt(np.sum(d * d, axis=1, dtype=_F32)).astype(_F32)
    with np.errstate(all="ignore"):
        edge = np.where(length[:, None] != 0.0, d / np.where(length != 0.0, length, 1.0)[:, None], 0.0).astype(_F32)
    accum = np.zeros((n, 3), _F32)
    np.add.at(accum, v0, edge)
    np.add.at(accum, v1, -edge)
    count = np.bincount(v0, minlength=n) + np.bincount(v1, minlength=n)
    raw = np.zeros(n, _F32)
    own = (orig == np.arange(n)) & (count > 0)
    mean = accum[own] / count[own, None].astype(_F32)
    cos = np.clip(np.sum(normal[own] * mean, axis=1, dtype=_F32), -1.0, 1.0)
    raw[own] = (np.arccos(cos).astype(_F32) * _F32(1.0 / np.pi)).astype(_F32)
    data = raw.copy()
    np.add.at(data, v0, raw[v1])
    np.add.at(data, v1, raw[v0])
    data = (data / (count + 1).astype(_F32)).astype(_F32)
    return data[orig]


def random_per_island(vertex_count: int, edges, triangle_first_vertex) -> np.ndarray:
    """Cycles' Random Per Island per triangle: hash_uint_to_float of the union-find root of the
    triangle's first corner's vertex, the sets joined edge by edge (util/disjoint_set.h: union
    by rank, the first set's root kept on ties). The roots depend on the edge order, so the
    union runs in that order (host-side, once per mesh)."""
    parent = list(range(vertex_count))
    rank = [0] * vertex_count

    def find(x):
        root = x
        while parent[root] != root:
            root = parent[root]
        while parent[x] != root:
            parent[x], x = root, parent[x]
        return root

    for a, b in np.asarray(edges, np.int64).reshape(-1, 2).tolist():
        ra, rb = find(a), find(b)
        if ra == rb:
            continue
        if rank[ra] < rank[rb]:
            ra, rb = rb, ra
        parent[rb] = ra
        if rank[ra] == rank[rb]:
            rank[ra] += 1
    roots = np.array([find(v) for v in range(vertex_count)], np.uint32)
    first = np.asarray(triangle_first_vertex, np.int64)
    return uint_to_float(hash_uint(roots[first]))


def hash_string(name: str) -> int:
    """util/hash.h hash_string: i = i * 37 + c over the name's UTF-8 bytes, wrapped to 32 bits
    (each byte as an unsigned value: a name past ASCII shows it in Cycles' bake)."""
    i = 0
    for b in name.encode("utf-8"):
        i = (i * 37 + b) & 0xFFFFFFFF
    return i


def object_random(name: str) -> float:
    """Object Info's Random for an object that is not an instance: hash_uint2(hash_string(name),
    0) as float32 times 2^-32 (scene/object.cpp random_number)."""
    return float(uint_to_float(hash_uint2(np.uint32(hash_string(name)), np.uint32(0))))


def srgb_to_linear(c) -> np.ndarray:
    """util/color.h color_srgb_to_linear in float32: c / 12.92 below 0.04045 (0 below 0), else
    ((c + 0.055) / 1.055)^2.4."""
    c = np.asarray(c, _F32)
    low = np.where(c < 0.0, _F32(0.0), c * _F32(1.0 / 12.92))
    high = np.power((c + _F32(0.055)) * _F32(1.0 / 1.055), _F32(2.4)).astype(_F32)
    return np.where(c < _F32(0.04045), low, high).astype(_F32)


def bytes_to_linear(rgba_bytes) -> np.ndarray:
    """A byte colour (.., 4) as Cycles reads it: each byte / 255, RGB linearised, alpha kept."""
    c = np.asarray(rgba_bytes, _F32) * _F32(1.0 / 255.0)
    out = c.copy()
    out[..., :3] = srgb_to_linear(c[..., :3])
    return out


def at_hits(values, domain: str, corners, verts, faces, triangles, weights):
    """A per-element attribute at hit points, (value, du, dv) as Cycles' triangle_attribute:
    value = (1 - u - v) f0 + u f1 + v f2 over the triangle's corners for "point" (values per
    vertex, indexed by `verts` (N,3)) and "corner" (per face corner, by `corners` (N,3));
    du = f1 - f0, dv = f2 - f0; "triangle_corner" values are per corner of each Cycles triangle
    (3 t + k). "face" values are per polygon (by `faces` (N,)), "triangle" values per Cycles
    triangle (by `triangles` (N,)), "mesh" one value: no derivatives.
    weights (N,3) are the corners' weights (1 - u - v, u, v)."""
    values = np.asarray(values, np.float64)
    values = values[:, None] if values.ndim == 1 else values
    if domain == "mesh":
        return values.reshape(-1), None, None
    if domain in ("face", "triangle"):
        return values[faces if domain == "face" else triangles], None, None
    if domain == "triangle_corner":
        f = values[np.asarray(triangles)[:, None] * 3 + np.arange(3)]
    else:
        f = values[verts if domain == "point" else corners]  # (N,3,c)
    value = np.einsum("nk,nkc->nc", weights, f)
    return value, f[:, 1] - f[:, 0], f[:, 2] - f[:, 0]
