"""Named attributes: Attribute, Color Attribute, UV Map (svm/attribute.h, svm/vertex_color.h,
scene/shader_nodes.cpp), and the Volume, Point and Curves Info nodes, which read attributes and
primitive data that a mesh surface does not have.

An attribute comes from ShadingState.attribute(name) (state.py): its Cycles type and its value
at the points. The outputs follow svm_node_attr_store: a float f gives Fac f, Color and Vector
(f, f, f); a float2 (x, y) gives Fac x, Color (x, y, 0); a float3 gives Fac its average; a float4
or colour gives Fac the average of its first three, Alpha its fourth; Alpha is 1 for types
without one. A missing attribute reads as zero, except Attribute's Alpha, which reads 1 (Cycles
takes the requested output's type for the missing attribute's type, and its float3 path stores
Alpha as 1); Color Attribute gives colour and alpha 0 when its attribute is missing.
Attribute names are Cycles': Object and Instancer attributes carry the prefixes Cycles' sync
gives them (blender/shader.cpp); View Layer attributes are constants folded into the graph at
export (engine/blender/export_nodes.py), as Cycles folds them.
"""
from __future__ import annotations

import numpy as np

from .base import node, scalar, triple

OBJECT_PREFIX = "\x01object:"
INSTANCER_PREFIX = "\x01instancer:"
_PREFIXES = {"GEOMETRY": "", "OBJECT": OBJECT_PREFIX, "INSTANCER": INSTANCER_PREFIX}


def channels(attribute):
    """(rgb (N,3) or (3,), fac, alpha) of an attribute as svm_node_attr_store reads it."""
    v = np.asarray(attribute.value, np.float64)
    columns = v.shape[-1]
    if attribute.type == "float" or columns == 1:
        f = v[..., 0]
        return np.stack([f, f, f], axis=-1), f, np.ones_like(f)
    if attribute.type == "float2":
        rgb = np.concatenate([v[..., :2], np.zeros_like(v[..., :1])], axis=-1)
        return rgb, v[..., 0], np.ones_like(v[..., 0])
    rgb = v[..., :3]
    # average() of a float3 sums left to right and divides by 3 (util/math_float3.h)
    fac = ((rgb[..., 0] + rgb[..., 1]) + rgb[..., 2]) * (1.0 / 3.0)
    alpha = v[..., 3] if columns > 3 and attribute.type in ("float4", "rgba") else np.ones_like(fac)
    return rgb, fac, alpha


def attribute_name(node) -> str:
    """The Cycles name of an Attribute node's attribute: its name with its type's prefix."""
    return _PREFIXES.get(node.prop("attribute_type", "GEOMETRY"), "") + node.prop("attribute_name", "")


def _attribute_reads(node, outputs):
    name = attribute_name(node)
    return (f"attribute:{name}",) + (("object",) if name == "generated" else ())


@node("ShaderNodeAttribute", "Input", reads=_attribute_reads)
def attribute(node, inputs, state):
    name = attribute_name(node)
    found = state.attribute(name) if name else None
    if found is None and name == "generated":  # no generated coordinates: object space (Cycles)
        p = triple(state.object)
        return {"Color": p, "Vector": p, "Fac": p.mean(axis=-1), "Alpha": np.ones(p.shape[:-1])}
    if found is None:
        zero = np.zeros((state.n, 3))
        return {"Color": zero, "Vector": zero, "Fac": np.zeros(state.n), "Alpha": np.ones(state.n)}
    rgb, fac, alpha = channels(found)
    return {"Color": rgb, "Vector": rgb, "Fac": fac, "Alpha": alpha}


def _color_name(node) -> str:
    return node.prop("layer_name", "") or "vertex_color"


@node("ShaderNodeVertexColor", "Input", reads=lambda node, outputs: (f"attribute:{_color_name(node)}",))
def color_attribute(node, inputs, state):
    """svm_node_vertex_color: a colour (float4) attribute's RGB and alpha, a float3 one's value and
    alpha 1; colour and alpha 0 where the mesh has no such attribute. No name: the mesh's active
    render colour attribute."""
    found = state.attribute(_color_name(node))
    if found is None:
        return {"Color": np.zeros((state.n, 3)), "Alpha": np.zeros(state.n)}
    v = np.asarray(found.value, np.float64)
    if found.type in ("float4", "rgba"):
        return {"Color": v[..., :3], "Alpha": v[..., 3]}
    rgb = channels(found)[0]
    return {"Color": rgb, "Alpha": np.ones(rgb.shape[:-1])}


def _uv_reads(node, outputs):
    if node.prop("from_instancer", False):
        return ("instancer_uv",)
    name = node.prop("uv_map", "")
    return (f"attribute:{name}",) if name else ("uv",)


@node("ShaderNodeUVMap", "Input", reads=_uv_reads)
def uv_map(node, inputs, state):
    """The named UV map as (u, v, 0) (zero where the mesh has no map of that name), the active
    render map without a name, the instancer's UV with From Instancer."""
    if node.prop("from_instancer", False):
        return {"UV": triple(state.instancer_uv)}
    name = node.prop("uv_map", "")
    if not name:
        return {"UV": triple(state.uv)}
    found = state.attribute(name)
    return {"UV": channels(found)[0] if found is not None else np.zeros((state.n, 3))}


# Volume Info expands to Attribute nodes of Cycles' volume grid names (scene/shader_nodes.cpp
# VolumeInfoNode::expand), which a mesh surface never has: its surface values are zeros.
@node("ShaderNodeVolumeInfo", "Input")
def volume_info(node, inputs, state):
    return {"Color": np.zeros(3), "Density": scalar(0.0), "Flame": scalar(0.0), "Temperature": scalar(0.0)}


# Point Info reads the point primitive (geom/point.h point_position, point_radius: zero for other
# primitives) and the "point_random" attribute (points only): zeros on mesh surfaces.
@node("ShaderNodePointInfo", "Input")
def point_info(node, inputs, state):
    return {"Position": np.zeros(3), "Radius": scalar(0.0), "Random": scalar(0.0)}


# Curves Info (svm/geometry.h svm_node_hair_info, geom/curve.h): Is Strand tests the curve
# primitive, Thickness and Tangent Normal are zero off curves, Intercept, Length and Random are
# curve attributes: zeros on mesh surfaces.
@node("ShaderNodeHairInfo", "Input")
def curves_info(node, inputs, state):
    return {"Is Strand": scalar(0.0), "Intercept": scalar(0.0), "Length": scalar(0.0), "Thickness": scalar(0.0),
            "Tangent Normal": np.zeros(3), "Random": scalar(0.0)}


NODES = (attribute, color_attribute, uv_map, volume_info, point_info, curves_info)
