"""Shading frames at ray hits, shared by every integrator (two-sided, like Cycles)."""
from __future__ import annotations

import numpy as np

from ..scene import Mesh
from ..vec import dot, interpolate, length, scale, take


def flat_normals(mesh: Mesh):
    """(T,3) unit normals when every triangle's corner normals are equal (flat shading: no
    interpolation needed), else None."""
    normals = mesh.normals  # compared as stored: a float64 copy of every corner costs 0.2 s per 1M triangles
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
