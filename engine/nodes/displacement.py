"""Displacement and Vector Displacement (svm/displace.h svm_node_displacement,
svm_node_vector_displacement): the world-space offset of the surface their inputs describe.

Displacement moves along a normal (its Normal input where linked, else N) by (height - midlevel)
* scale: in object space (the normal taken to object space and renormalised, the offset taken
back as a direction, so the object's scale stretches it) or in world space. Vector Displacement
offsets by (vector - midlevel) * scale in tangent space (x along the active render UV map's
tangent, y along the object-space normal, z along their cross product times the tangent's sign;
without tangents, normalize(dPdu)), in object space, or in world space.

Ember does not move vertices: the Material Output's displacement is rendered as bump
(bump.bump_from_displacement, Cycles' "Bump Only" method); these nodes give its vectors.
"""
from __future__ import annotations

import numpy as np

from .base import column, node, scalar, triple
from .fresnel import normal_input
from .vector_math import normalize, safe_normalize, transform_direction, transform_direction_transposed


def _displacement_reads(node, outputs):
    socket = node.input("Normal")
    linked = socket is not None and socket.link is not None
    return (() if linked else ("N",)) + ("world_from_object",)


@node("ShaderNodeDisplacement", "Vector", reads=_displacement_reads)
def displacement(node, inputs, state):
    normal = normal_input(node, inputs, state)
    amount = column((scalar(inputs["Height"]) - scalar(inputs["Midlevel"])) * scalar(inputs["Scale"]))
    if node.prop("space", "OBJECT") == "OBJECT":
        m = state.unshifted.world_from_object
        object_normal = safe_normalize(transform_direction_transposed(m, normal))
        return {"Displacement": transform_direction(m, object_normal * amount)}
    return {"Displacement": normal * amount}


_TANGENT = ("attribute:undisplaced_tangent", "attribute:undisplaced_tangent_sign", "N", "dPdu")


@node("ShaderNodeVectorDisplacement", "Vector",
      reads=lambda node, outputs: (_TANGENT if node.prop("space", "TANGENT") == "TANGENT" else ())
      + (("world_from_object",) if node.prop("space", "TANGENT") != "WORLD" else ()))
def vector_displacement(node, inputs, state):
    space = node.prop("space", "TANGENT")
    d = (triple(inputs["Vector"]) - column(scalar(inputs["Midlevel"]))) * column(scalar(inputs["Scale"]))
    if space == "WORLD":
        return {"Displacement": d}
    base = state.unshifted
    m = base.world_from_object
    if space == "TANGENT":
        normal = safe_normalize(transform_direction_transposed(m, base.N))
        found = base.attribute("undisplaced_tangent")
        tangent = np.asarray(found.value, np.float64)[..., :3] if found is not None else normalize(base.dPdu)
        bitangent = safe_normalize(np.cross(normal, tangent))
        sign = base.attribute("undisplaced_tangent_sign")
        if sign is not None:
            bitangent = bitangent * column(np.asarray(sign.value, np.float64)[..., 0])
        d = tangent * d[..., 0:1] + normal * d[..., 1:2] + bitangent * d[..., 2:3]
    return {"Displacement": transform_direction(m, d)}


NODES = (displacement, vector_displacement)
