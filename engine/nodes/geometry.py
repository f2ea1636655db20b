"""The hit point's geometry: Geometry (svm/geometry.h svm_node_geometry, geom/primitive.h
primitive_tangent) and Wireframe (svm/wireframe.h).

Geometry's Pointiness and Random Per Island are attributes Cycles computes from the mesh
(engine/nodes/mesh_attributes.py), read like any attribute. In a Bump node's offset evaluations
Position, Parametric and those two attributes move with the point; Normal, Tangent, True Normal,
Incoming and Backfacing do not (Cycles' svm_node_geometry_bump_dx moves P and uv only).
"""
from __future__ import annotations

import numpy as np

from .base import column, node, scalar, stack
from .differentials import from_compact
from .vector_math import dot, normalize, transform_direction_transposed

_GEOMETRY_READS = {"Position": ("P",), "Normal": ("N",), "Tangent": ("generated", "N", "object_from_world"),
                   "True Normal": ("Ng",), "Incoming": ("I",), "Parametric": ("barycentric",),
                   "Backfacing": ("backfacing",), "Pointiness": ("attribute:pointiness",),
                   "Random Per Island": ("attribute:random_per_island",)}


def object_normal_to_world(object_from_world, n):
    """object_normal_transform: a normal from object to world space, by (M^-1)^T, normalised."""
    return normalize(transform_direction_transposed(object_from_world, n))


def surface_tangent(generated, n, object_from_world):
    """primitive_tangent on a mesh: the tangent of a sphere around the texture space's centre,
    about its z axis, (-(g.y - 0.5), g.x - 0.5, 0), taken to world space as a normal and made
    perpendicular to N: cross(N, normalize(cross(t, N)))."""
    g = np.asarray(generated, np.float64)
    t = stack(-(g[..., 1] - 0.5), g[..., 0] - 0.5, np.zeros_like(g[..., 0]))
    t = object_normal_to_world(object_from_world, t)
    return np.cross(n, normalize(np.cross(t, n)))


def _float_attribute(state, name):
    found = state.attribute(name)
    if found is None:
        return np.zeros(state.n)
    return np.asarray(found.value, np.float64)[..., 0]


@node("ShaderNodeNewGeometry", "Input", reads=_GEOMETRY_READS)
def geometry(node, inputs, state):
    base = state.unshifted  # what Cycles' bump variant of this node does not move

    def parametric():
        uv = np.asarray(state.barycentric, np.float64)
        return stack(1.0 - uv[..., 0] - uv[..., 1], uv[..., 0], np.zeros_like(uv[..., 0]))

    return {"Position": lambda: state.P, "Normal": lambda: base.N,
            "Tangent": lambda: surface_tangent(base.generated, base.N, base.object_from_world),
            "True Normal": lambda: base.Ng, "Incoming": lambda: base.I, "Parametric": parametric,
            "Backfacing": lambda: np.where(base.backfacing, 1.0, 0.0),
            "Pointiness": lambda: _float_attribute(state, "pointiness"),
            "Random Per Island": lambda: _float_attribute(state, "random_per_island")}


def wireframe_fac(P, triangle, ng, dp, incoming, size, pixel_size: bool):
    """svm/wireframe.h wireframe: 1 where P lies within half the width of an edge of its
    triangle (the neighbour draws the other half), the width `size` in world units, or in
    pixels: size times the footprint of the compact differential (dP along Ng's orthonormals)
    projected onto the plane facing the incoming ray."""
    width = 0.5 * scalar(size)
    if pixel_size:
        dx, dy = from_compact(ng, dp)
        wx = np.linalg.norm(dx - column(dot(dx, incoming)) * incoming, axis=-1)
        wy = np.linalg.norm(dy - column(dot(dy, incoming)) * incoming, axis=-1)
        width = width * ((wx + wy) * 0.5)
    width2 = width * width
    hit = np.zeros(np.shape(P)[:-1], bool)
    for i in range(3):
        corner, previous = triangle[..., i, :], triangle[..., i - 1, :]
        edge = corner - previous
        crs = np.cross(edge, P - corner)
        hit |= dot(crs, crs) < dot(edge, edge) * width2
    return np.where(hit, 1.0, 0.0)


_WIREFRAME_READS = ("P", "triangle", "Ng", "dP", "I")


@node("ShaderNodeWireframe", "Input", reads=_WIREFRAME_READS)
def wireframe(node, inputs, state):
    base = state.unshifted  # the footprint is the unmoved point's; P moves in offset evaluations
    pixel = bool(node.prop("use_pixel_size", False))
    return {"Fac": wireframe_fac(state.P, base.triangle, base.Ng, base.dP, base.I, inputs["Size"], pixel)}


NODES = (geometry, wireframe)
