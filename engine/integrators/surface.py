"""Shading frames at ray hits, shared by every integrator (two-sided, like Cycles)."""
from __future__ import annotations

import numpy as np

from ..nodes.hits import SurfaceHits
from ..sampling import frame_from_z
from ..scene import Mesh
from ..vec import dot, interpolate, length, scale, take


def flat_normals(mesh: Mesh):
    """(T,3) unit normals when every triangle's corner normals are equal (flat shading: no
    interpolation needed), else None."""
    normals = mesh.normals  # compared as stored: a float64 copy of every corner is slow on big meshes
    if len(normals) and np.all(normals == normals[:, :1]):
        n0 = normals[:, 0].astype(np.float64)
        return n0 / np.maximum(length(n0), 1e-300)[:, None]
    return None


def towards(n: np.ndarray, w: np.ndarray) -> np.ndarray:
    """n flipped to the side of w (reflection leaves on the normal's side, refraction not)."""
    return scale(n, np.where(dot(n, w) >= 0, 1.0, -1.0))


def shading_frame(mesh: Mesh, flat_normal, prim, bary, ng, wo):
    """(ng_f, ns): the geometric and shading normals (N,3) flipped to the side of wo; a shading
    normal that is degenerate or below the surface is replaced by ng_f."""
    side = np.where(dot(ng, wo) >= 0, 1.0, -1.0)
    ng_f = scale(ng, side)
    ns = interpolate(bary, take(mesh.normals, prim)) if flat_normal is None else take(flat_normal, prim)
    ns_len = length(ns)
    ns = scale(ns, side / np.maximum(ns_len, 1e-300))
    bad = (ns_len <= 1e-12) | (dot(ns, ng_f) <= 0)
    if bad.any():
        ns[bad] = ng_f[bad]
    return ng_f, ns


# Triangles up to which flat_frames tabulates (192 bytes each: 12 MB at this count).
FLAT_FRAMES_MAX = 1 << 16


def flat_frames(mesh: Mesh, flat_normal, ng: np.ndarray):
    """Tables (ng_f, ns, t, b), each (2T,3): row 2 i + s holds triangle i's geometric and
    shading normals and ns's tangent frame seen from its front (s = 0) or back (s = 1),
    exactly as shading_frame and sampling.frame_from_z compute them per hit (every step is per
    triangle, and flipping a side only flips signs, which is exact): a flat-shaded mesh's hits
    then read rows instead of rebuilding them. None for smooth shading or more than
    FLAT_FRAMES_MAX triangles (the tables' memory); ng (T,3) the unit geometric normals (Accel.ng)."""
    if flat_normal is None or len(flat_normal) > FLAT_FRAMES_MAX:
        return None
    tables = np.empty((4, len(flat_normal), 2, 3))
    for s, side in enumerate((1.0, -1.0)):
        ng_f, ns = shading_frame(mesh, flat_normal, np.arange(len(flat_normal)), None, ng,
                                 np.asarray(ng, np.float64) * side)
        tables[:, :, s] = (ng_f, ns, *frame_from_z(ns))
    return tuple(tables.reshape(4, -1, 3))


def flat_frame_rows(tables, prim: np.ndarray, ng: np.ndarray, wo: np.ndarray):
    """(ng_f, ns, t, b) (N,3) each from flat_frames' tables for hits on triangles prim (N,) with
    geometric normals ng (N,3), seen from wo (N,3): the side shading_frame picks (dot(ng, wo)
    >= 0 is the front)."""
    row = 2 * prim + (dot(ng, wo) < 0).view(np.int8)
    return tuple(take(table, row) for table in tables)


def emitted(scene, programs, flat_normal, Le: np.ndarray, hit, d: np.ndarray, ray=None) -> np.ndarray:
    """Le (K,3) of K emissive hits (an accel Hit) of rays along d (K,3), with the node programs'
    radiance where a material's emission varies over the surface (a textured emitter),
    evaluated at the hit points; Le itself where none does. ray: the paths' record at the hits
    (engine/nodes/hits.py RayState), or None (camera rays' first hits)."""
    mat = scene.mesh.material[hit.prim]
    rows = np.flatnonzero(programs.varying_emission[mat])
    if len(rows) == 0:
        return Le
    h = hit.take(rows)
    wo = -d[rows]
    ng, ns = shading_frame(scene.mesh, flat_normal, h.prim, h.b, h.ng, wo)
    Le = Le.copy()
    ray = None if ray is None else ray.take(rows)
    Le[rows] = programs.emission(mat[rows], SurfaceHits(scene, h.prim, h.b, h.p, ns, ng, wo, h.t, ray))
    return Le
