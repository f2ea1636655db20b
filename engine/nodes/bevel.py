"""Bevel (svm/bevel.h): a shading normal rounded over the object's edges, the weighted mean of
the normals of the surface near the point, found by probe rays as in BSSRDF sampling
(King et al., "BSSRDF Importance Sampling", SIGGRAPH 2013 talk).

Per sample, as Cycles: an axis of the frame about Ng is picked (Ng with probability 1/2, each
tangent with 1/4), a point on the disk across it is drawn at radius r from the cubic profile
(Rm - r)^3 of radius Rm = Radius (its CDF, a quintic, inverted by Newton's method), and a probe
ray crosses the disk's chord of height h = sqrt(Rm^2 - r^2) along the axis, from h above to h
below. Each hit of the point's own object adds its smooth normal weighted by the power
heuristic over the three axes' probabilities (|axis . Ng_hit| each) and by the profile at the
hit's true distance over the profile at r; a probe meeting more than four hits keeps four of
them at random, each weighted by hits / 4. The result is the normalised sum, turned to the
side the ray came from; with a Normal input linked, that input moved by the bevel's change,
normalize(Normal + bevel - N). N itself comes back where nothing was found, where Radius or
samples are 0, for paths whose smallest BSDF pdf so far is below 8 (blurry indirect rays), and
where no ray queries are given (a bake; the photon integrators).
"""
from __future__ import annotations

import numpy as np

from ..vec import dot
from .base import column, node, scalar, triple
from .rays import BEVEL, BEVEL_HITS, make_orthonormals
from .vector_math import safe_normalize

LOCAL_MAX_HITS = 4
MIN_RAY_PDF = 8.0


def cubic_pdf(radius, r):
    """The planar cubic profile 10 (R - r)^3 / (pi R^5) for r < R, else 0."""
    radius = np.asarray(radius, np.float64)
    f = np.maximum(radius - r, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(r < radius, 10.0 * f ** 3 / (radius ** 5 * np.pi), 0.0)


def cubic_sample(radius, xi):
    """(r, h): the disk radius whose profile CDF is xi (10x^2 - 20x^3 + 15x^4 - 4x^5 = xi, x = r/R,
    by Newton's method from x = 1/4 as Cycles) and the chord height sqrt(R^2 - r^2)."""
    x = np.full(np.shape(xi), 0.25)
    for _ in range(10):
        x2, nx = x * x, 1.0 - x
        f = 10.0 * x2 - 20.0 * x2 * x + 15.0 * x2 * x2 - 4.0 * x2 * x2 * x - xi
        df = 20.0 * (x * nx) * (nx * nx)
        step = np.where((np.abs(f) < 1e-6) | (df == 0.0), 0.0, f / np.where(df == 0.0, 1.0, df))
        x = np.clip(x - step, 0.0, 1.0)
    r = x * radius
    return r, np.sqrt(np.maximum(radius * radius - r * r, 0.0))


def _pick(u, ng, t, b):
    """The disk's axis and tangents by u (N,) and their picking probabilities, and u rescaled
    to [0, 1) within its third (Cycles' axis choice)."""
    first, second = u < 0.5, (u >= 0.5) & (u < 0.75)
    third = ~(first | second)
    axis = np.where(first[:, None], ng, np.where(second[:, None], t, b))
    tangent = np.where(second[:, None], ng, t)
    bitangent = np.where(third[:, None], ng, b)
    pick = tuple(np.where(m, 0.5, 0.25) for m in (first, second, third))
    u = np.where(first, 2.0 * u, np.where(second, (u - 0.5) * 4.0, (u - 0.75) * 4.0))
    return axis, tangent, bitangent, pick, u


def bevel_normal(state, radius, samples: int) -> np.ndarray:
    """(N,3) Cycles' svm_bevel at the state's points (N where it does not bevel)."""
    n = state.n
    base = state.unshifted
    queries = base.ray_queries
    N = np.broadcast_to(np.asarray(state.N, np.float64), (n, 3))
    radius = np.broadcast_to(scalar(radius), (n,))
    if queries is None or samples < 1:
        return N
    active = (radius > 0.0) & (np.asarray(base.min_ray_pdf) >= MIN_RAY_PDF)
    if not active.any():
        return N
    p, ng = np.asarray(base.P, np.float64), np.asarray(base.Ng, np.float64)
    t, b = make_orthonormals(ng)
    total = np.zeros((n, 3))
    for k in range(samples):
        u = queries.uniform(BEVEL, k, samples)
        axis, tangent, bitangent, pick, ux = _pick(u[:, 0], ng, t, b)
        phi = 2.0 * np.pi * ux
        r, h = cubic_sample(radius, u[:, 1])
        disk = tangent * column(r * np.cos(phi)) + bitangent * column(r * np.sin(phi))
        origin = p + axis * column(h) + disk
        tmax = np.where(active, 2.0 * h, 0.0)
        (rows, prim, dist, bary, order), count = queries.local_hits(origin, -axis, tmax)
        if len(rows) == 0:
            continue
        # More hits than Cycles keeps: four of them, each hit equally likely (a random start
        # in the ray's list of hits, wrapped), weighted up by hits / 4.
        c = count[rows]
        start = np.floor(queries.uniform(BEVEL_HITS, k, samples)[:, 0] * count)[rows]
        keep = (c <= LOCAL_MAX_HITS) | (np.mod(order - start, c) < LOCAL_MAX_HITS)
        rows, prim, dist, bary, c = rows[keep], prim[keep], dist[keep], bary[keep], c[keep]
        hit_p = origin[rows] - axis[rows] * column(dist)
        hit_ng, hit_n = queries.normals(prim, bary)
        pdfs = [pk[rows] * np.abs(dot(a[rows], hit_ng)) for pk, a in zip(pick, (axis, tangent, bitangent))]
        with np.errstate(divide="ignore", invalid="ignore"):
            w = pdfs[0] / (pdfs[0] ** 2 + pdfs[1] ** 2 + pdfs[2] ** 2)
            w = np.where(c > LOCAL_MAX_HITS, w * c / LOCAL_MAX_HITS, w)
            w = w * cubic_pdf(radius[rows], np.linalg.norm(hit_p - p[rows], axis=1)) / cubic_pdf(radius[rows], r[rows])
        w = np.where(np.isfinite(w), w, 0.0)
        for j in range(3):
            total[:, j] += np.bincount(rows, w * hit_n[:, j], minlength=n)
    out = safe_normalize(total)
    found = np.any(out != 0.0, axis=1) & active
    out = np.where(np.asarray(base.backfacing)[:, None], -out, out)
    return np.where(found[:, None], out, N)


@node("ShaderNodeBevel", "Input", reads=("ray_queries", "min_ray_pdf", "P", "N", "Ng", "backfacing"))
def bevel(node, inputs, state):
    socket = node.input("Normal")
    if socket is not None and socket.link is not None:
        ref = triple(inputs["Normal"])
        normal = bevel_normal(state, inputs["Radius"], int(node.prop("samples", 4)))
        return {"Normal": safe_normalize(ref + (normal - np.asarray(state.N, np.float64)))}  # moved by the bevel
    return {"Normal": bevel_normal(state, inputs["Radius"], int(node.prop("samples", 4)))}


NODES = (bevel,)
