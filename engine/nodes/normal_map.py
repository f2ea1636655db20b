"""Normal Map (svm/tex_coord.h svm_node_normal_map): a normal from a colour, (2 c - 1) in the
tangent frame of the point's UV map (Tangent Space), or as an object- or world-space direction
(Object, World; the Blender variants negate y and z first).

Tangent space reads the MikkTSpace tangent and its sign of the node's UV map (the active render
map when none is named: the "undisplaced_tangent" and "undisplaced_tangent_sign" attributes, the
tangents before displacement, which are the tangents of a mesh Ember does not displace) and
builds the frame in object space from them and the interpolated, unnormalised vertex normal
(smooth faces) or the true normal (flat faces). Strength scales the frame's x and y and mixes z
toward 1 there; elsewhere it blends the result with N linearly. Where the tangents are missing,
or the result is zero or not finite, the output is N.
"""
from __future__ import annotations

import numpy as np

from .base import column, node, scalar, stack, triple
from .geometry import object_normal_to_world
from .vector_math import safe_normalize, transform_direction_transposed


def _names(node):
    uv = node.prop("uv_map", "")
    prefix = f"{uv}." if uv else ""
    return prefix + "undisplaced_tangent", prefix + "undisplaced_tangent_sign"


def _reads(node, outputs):
    fields = ("N", "backfacing", "object_from_world")
    if node.prop("space", "TANGENT") == "TANGENT":
        tangent, sign = _names(node)
        fields += (f"attribute:{tangent}", f"attribute:{sign}", "smooth", "vertex_normal", "Ng",
                   "world_from_object")
    return fields


def _value(attribute):
    return np.asarray(attribute.value, np.float64)


def tangent_space(color, strength, state, tangent, sign):
    """The tangent-space normal in world space (not yet flipped for backfacing hits)."""
    base = state.unshifted
    flipped = column(np.where(base.backfacing, -1.0, 1.0))
    flat = safe_normalize(transform_direction_transposed(base.world_from_object, base.Ng * flipped))
    normal = np.where(column(base.smooth), base.vertex_normal, flat)
    s = scalar(strength)
    color = stack(color[..., 0] * s, color[..., 1] * s, 1.0 + (color[..., 2] - 1.0) * np.clip(s, 0.0, 1.0))
    bitangent = column(sign) * np.cross(normal, tangent)
    n = color[..., 0:1] * tangent + color[..., 1:2] * bitangent + color[..., 2:3] * normal
    return object_normal_to_world(base.object_from_world, safe_normalize(n))


@node("ShaderNodeNormalMap", "Vector", reads=_reads)
def normal_map(node, inputs, state):
    base = state.unshifted
    space = node.prop("space", "TANGENT")
    color = 2.0 * (triple(inputs["Color"]) - 0.5)
    strength = scalar(inputs["Strength"])
    flip = column(np.where(base.backfacing, -1.0, 1.0))
    linear = True
    if space == "TANGENT":
        names = _names(node)
        tangent, sign = (base.attribute(name) for name in names)
        if tangent is None or sign is None:
            return {"Normal": base.N}
        n = tangent_space(color, strength, state, _value(tangent)[..., :3], _value(sign)[..., 0]) * flip
        linear = False
    else:
        if space in ("BLENDER_OBJECT", "BLENDER_WORLD"):
            color = stack(color[..., 0], -color[..., 1], -color[..., 2])
        if space in ("OBJECT", "BLENDER_OBJECT"):
            n = object_normal_to_world(base.object_from_world, color)
        else:
            n = safe_normalize(color)
        n = n * flip
    if linear:
        s = np.maximum(strength, 0.0)
        blended = safe_normalize(base.N + (n - base.N) * column(s))
        n = np.where(column(strength != 1.0), blended, n)
    n = np.broadcast_to(n, np.broadcast_shapes(np.shape(n), np.shape(base.N)))
    bad = np.all(n == 0.0, axis=-1) | ~np.all(np.isfinite(n), axis=-1)
    return {"Normal": np.where(column(bad), base.N, n)}


NODES = (normal_map,)
