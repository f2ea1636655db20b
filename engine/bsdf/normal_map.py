"""Normal maps: the shading normal replaced by a tangent-space normal map's (per-triangle
tangents from the UVs), bent toward ng so that the mirror direction of wo stays above the
surface (Cycles' ensure_valid_specular_reflection)."""
from __future__ import annotations

import numpy as np

from .. import textures
from ..vec import dot, normalize


def normal_map(scene, mat: np.ndarray, ns: np.ndarray, ng: np.ndarray, wo: np.ndarray, prim: np.ndarray,
               uv: np.ndarray, outward: np.ndarray) -> np.ndarray:
    """Shading normals (N,3) perturbed by tangent-space normal maps (Cycles' Normal Map node):
    mat (N,) materials, ns, ng (N,3) unit normals on wo's side, wo (N,3), prim (N,) triangles,
    uv (N,2) their UVs, outward (N,3) the triangles' winding normals."""
    m = scene.materials
    rows = np.flatnonzero(m.normal_tex[mat] >= 0)
    side = np.where(dot(ng[rows], outward[rows]) >= 0, 1.0, -1.0)[:, None]
    n_auth = ns[rows] * side  # the smooth normal in its authored orientation
    c = 2.0 * textures.color(m, m.normal_tex[mat[rows]], uv[rows]) - 1.0
    # Per-triangle tangent frame from the UV parametrisation: dp/du, dp/dv.
    tri = scene.mesh.triangles[prim[rows]]
    p = scene.mesh.vertices[tri].astype(np.float64)
    t_uv = scene.mesh.uvs[prim[rows]].astype(np.float64)
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    d1, d2 = t_uv[:, 1] - t_uv[:, 0], t_uv[:, 2] - t_uv[:, 0]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    inv = np.divide(1.0, det, out=np.zeros(len(det)), where=det != 0)[:, None]
    dpdu = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * inv
    dpdv = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * inv
    tangent = normalize(dpdu - n_auth * dot(dpdu, n_auth)[:, None])
    sign = np.where(dot(np.cross(n_auth, tangent), dpdv) < 0, -1.0, 1.0)[:, None]
    bitangent = sign * np.cross(n_auth, tangent)
    mapped = normalize(c[:, 0:1] * tangent + c[:, 1:2] * bitangent + c[:, 2:3] * n_auth)
    strength = np.maximum(m.normal_strength[mat[rows]], 0.0)[:, None]
    mapped = normalize(n_auth + (mapped - n_auth) * strength)
    ok = (det != 0)[:, None] & (dot(mapped, mapped) > 0)[:, None]
    out = ns.copy()
    out[rows] = valid_reflection_normal(ng[rows], wo[rows], np.where(ok, mapped, n_auth) * side)
    return out


def valid_reflection_normal(ng: np.ndarray, wo: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Shading normals (K,3) tilted toward ng just enough that the mirror direction of wo stays
    min(0.9 wo.ng, 0.01) above the surface (Cycles bsdf_util.h ensure_valid_specular_reflection:
    the root of 4 a Nz^4 - 2 b Nz^2 + c = 0 in the plane of n and ng)."""
    R = 2.0 * dot(n, wo)[:, None] * n - wo
    iz = dot(wo, ng)
    threshold = np.minimum(0.9 * iz, 0.01)
    bad = dot(ng, R) < threshold
    if not bad.any():
        return n
    x = n - dot(n, ng)[:, None] * ng
    x_len = np.sqrt(dot(x, x))
    x = np.where((x_len > 0)[:, None], x / np.maximum(x_len, 1e-300)[:, None], n)
    ix = dot(wo, x)
    a = ix * ix + iz * iz
    b = 2.0 * (a + iz * threshold)
    c = (threshold + iz) ** 2
    root = np.sqrt(np.maximum(b * b - 4.0 * a * c, 0.0))
    nz2 = 0.25 * np.divide(np.where(ix < 0, b + root, b - root), a, out=np.ones(len(a)), where=a > 0)
    nz2 = np.clip(nz2, 0.0, 1.0)
    bent = np.sqrt(1.0 - nz2)[:, None] * x + np.sqrt(nz2)[:, None] * ng
    return np.where(bad[:, None], bent, n)
