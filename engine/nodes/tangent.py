"""Tangent (svm/tex_coord.h svm_node_tangent): a direction in the surface, from the UV map's
MikkTSpace tangent (the "tangent" attribute of the active render map, "<map>.tangent" of a named
one; zero where the mesh has none) or around an axis of the texture space (Radial: the tangent
of a cylinder about X, Y or Z through the generated coordinates' centre, the position itself
where there are none).

Both are object-space directions Cycles takes to world space as normals, then makes
perpendicular to N. Cycles' node has no bump variant: a Bump node's offset evaluations read the
unmoved point.
"""
from __future__ import annotations

import numpy as np

from .attribute import channels
from .base import node, stack
from .geometry import object_normal_to_world
from .vector_math import normalize


def _attribute_name(node) -> str:
    if node.prop("direction_type", "RADIAL") == "UV_MAP":
        uv = node.prop("uv_map", "")
        return f"{uv}.tangent" if uv else "tangent"
    return "generated"


def radial(g, axis: str):
    """The tangent about `axis` at generated coordinates g (centred on 0.5)."""
    x, y, z = g[..., 0] - 0.5, g[..., 1] - 0.5, g[..., 2] - 0.5
    zero = np.zeros_like(x)
    if axis == "X":
        return stack(zero, -z, y)
    if axis == "Y":
        return stack(-z, zero, x)
    return stack(-y, x, zero)


def _reads(node, outputs):
    return (f"attribute:{_attribute_name(node)}", "N", "object_from_world", "P")


@node("ShaderNodeTangent", "Input", reads=_reads)
def tangent(node, inputs, state):
    base = state.unshifted
    found = base.attribute(_attribute_name(node))
    value = channels(found)[0] if found is not None else None  # a float2 reads as (x, y, 0)
    if node.prop("direction_type", "RADIAL") == "UV_MAP":
        if value is None:
            return {"Tangent": np.zeros((state.n, 3))}
        t = value
    else:
        t = radial(np.asarray(value if value is not None else base.P, np.float64), node.prop("axis", "X"))
    t = object_normal_to_world(base.object_from_world, t)
    n = base.N
    return {"Tangent": np.cross(n, normalize(np.cross(t, n)))}


NODES = (tangent,)
