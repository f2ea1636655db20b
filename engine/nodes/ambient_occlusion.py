"""Ambient Occlusion (svm/ao.h): the share of `samples` cosine-distributed rays about the normal
that travel Distance without meeting anything, and Color times it.

As Cycles: the Normal input where it is linked, else the shading normal N, normalised; Inside
turns it round (the rays go into the object); Only Local counts only the point's own object as
an occluder, otherwise whatever casts shadows does; the rays leave from the point, its own
triangle never blocking them. A Distance of 0 or less, no samples, or no ray queries (a bake,
a world or light shader, the photon integrators: the state's ray_queries is None) give 1, as
Cycles gives where it cannot trace. Each sample's direction comes from the path's numbers
(engine/nodes/rays.py), so the estimate is unbiased and the image reproducible.
"""
from __future__ import annotations

import numpy as np

from ..sampling import to_world
from .base import column, node, scalar, triple
from .rays import AO, make_orthonormals, sample_uniform_disk
from .vector_math import safe_normalize


def occlusion(state, normal, distance, samples: int, inside: bool, only_local: bool) -> np.ndarray:
    """(N,) the unoccluded share of `samples` cosine rays about `normal()` (N,3) up to
    `distance` (N,) from the state's points, or ones where nothing can be traced."""
    n = state.n
    queries = state.unshifted.ray_queries
    distance = np.broadcast_to(scalar(distance), (n,))
    if queries is None or samples < 1 or not np.any(distance > 0.0):
        return np.ones(n)
    normal = np.broadcast_to(safe_normalize(triple(normal())), (n, 3))
    if inside:
        normal = -normal
    t, b = make_orthonormals(normal)
    p, ng = np.asarray(state.P, np.float64), np.asarray(state.Ng, np.float64)
    free = np.zeros(n)
    for k in range(samples):
        disk = sample_uniform_disk(queries.uniform(AO, k, samples))
        up = np.sqrt(np.maximum(1.0 - disk[:, 0] ** 2 - disk[:, 1] ** 2, 0.0))
        d = to_world(np.stack([disk[:, 0], disk[:, 1], up], axis=1), t, b, normal)
        free += ~queries.occluded(p, ng, d, distance, local=only_local)
    return np.where(distance > 0.0, free / samples, 1.0)


@node("ShaderNodeAmbientOcclusion", "Input", reads=("ray_queries", "P", "N", "Ng"))
def ambient_occlusion(node, inputs, state):
    socket = node.input("Normal")
    linked = socket is not None and socket.link is not None
    normal = (lambda: inputs["Normal"]) if linked else (lambda: state.N)
    ao = occlusion(state, normal, inputs["Distance"], int(node.prop("samples", 16)), bool(node.prop("inside", False)),
                   bool(node.prop("only_local", False)))
    return {"AO": ao, "Color": column(ao) * triple(inputs["Color"])}


NODES = (ambient_occlusion,)
