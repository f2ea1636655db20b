"""Vectors and colours in and out, and between spaces: RGB, Combine/Separate XYZ, Texture
Coordinate (svm/tex_coord.h), Normal (svm/normal.h), Vector Transform (svm/vector_transform.h)."""
from __future__ import annotations

import numpy as np

from .base import components, node, scalar, stack, triple
from .vector_math import (dot, normalize, safe_normalize, transform_direction, transform_direction_transposed,
                          transform_point)


@node("ShaderNodeRGB", "Input")
def rgb(node, inputs, state):
    return {"Color": triple(node.prop("color", (0.5, 0.5, 0.5)))}


@node("ShaderNodeCombineXYZ", "Utilities")
def combine_xyz(node, inputs, state):
    return {"Vector": stack(inputs["X"], inputs["Y"], inputs["Z"])}


@node("ShaderNodeSeparateXYZ", "Utilities")
def separate_xyz(node, inputs, state):
    x, y, z = components(triple(inputs["Vector"]))
    return {"X": x, "Y": y, "Z": z}


# Per output, every field it may read: Generated and UV come from the instancer with "From
# Instancer", Object from P with an Object set. Normal reads texcoord_normal, N itself except in
# a Bump node's offset evaluations (differentials.py).
_TEXCOORD_READS = {"Generated": ("generated", "instancer_generated"),
                   "Normal": ("texcoord_normal", "world_from_object"),
                   "UV": ("uv", "instancer_uv"), "Object": ("object", "P"), "Camera": ("camera",),
                   "Window": ("window",), "Reflection": ("I", "N")}


@node("ShaderNodeTexCoord", "Input", reads=_TEXCOORD_READS)
def texture_coordinate(node, inputs, state):
    instancer = node.prop("from_instancer", False)
    world_from_other = node.prop("object")
    return {"Generated": lambda: state.instancer_generated if instancer else state.generated,
            "Normal": lambda: _object_normal(state.world_from_object, state.texcoord_normal),
            "UV": lambda: state.instancer_uv if instancer else state.uv,
            "Object": lambda: state.object if world_from_other is None else _in_frame(world_from_other, state.P),
            "Camera": lambda: state.camera, "Window": lambda: state.window,
            "Reflection": lambda: _reflect(state.I, state.N)}


def _object_normal(world_from_object, n):
    """N in object space: a normal goes back by M^T (object_inverse_normal_transform)."""
    return safe_normalize(transform_direction_transposed(world_from_object, n))


def _in_frame(world_from_other, P):
    """P in the space of another object, its world matrix given as 16 row-major floats (Cycles
    inverts it on the host: NODE_TEXCO_OBJECT_WITH_TRANSFORM)."""
    other_from_world = np.linalg.inv(np.asarray(world_from_other, np.float64).reshape(4, 4))
    return transform_point(other_from_world, P)


def _reflect(incoming, n):
    """I reflected about N: 2 (I.N) N - I (Cycles' tex_coord: reflect(-I, N) with I toward the eye)."""
    d = np.sum(incoming * n, axis=-1, keepdims=True)
    return 2.0 * d * n - incoming


@node("ShaderNodeNormal", "Utilities")
def normal(node, inputs, state):
    """The node's own direction, normalised, and its dot product with the normalised input."""
    direction = normalize(triple(node.prop("direction", (0.0, 0.0, 1.0))))
    return {"Normal": direction, "Dot": scalar(dot(direction, normalize(triple(inputs["Normal"]))))}


_SPACES = ("world_from_object", "object_from_world", "world_from_camera", "camera_from_world")


def _from_world(kind, v, world_from_x, x_from_world, guarded):
    """v from world space into frame x. A normal goes by the inverse transpose of x_from_world,
    (world_from_x)^T, and is renormalised: safe_normalize into object space, the plain
    normalize into camera space (`guarded`), as Cycles."""
    if kind == "NORMAL":
        n = transform_direction_transposed(world_from_x, v)
        return safe_normalize(n) if guarded else normalize(n)
    return transform_direction(x_from_world, v) if kind == "VECTOR" else transform_point(x_from_world, v)


def _to_world(kind, v, world_from_x, x_from_world):
    """v from frame x into world space (a normal by (x_from_world)^T, renormalised)."""
    if kind == "NORMAL":
        return normalize(transform_direction_transposed(x_from_world, v))
    return transform_direction(world_from_x, v) if kind == "VECTOR" else transform_point(world_from_x, v)


def vector_transform(kind: str, source: str, target: str, v, state):
    """svm_node_vector_transform: through world space, one frame at a time. Object <-> camera
    goes by world space; a space to itself leaves the vector as it is."""
    if source == target:
        return v
    if source == "OBJECT":
        v = _to_world(kind, v, state.world_from_object, state.object_from_world)
    elif source == "CAMERA":
        v = _to_world(kind, v, state.world_from_camera, state.camera_from_world)
    if target == "OBJECT":
        v = _from_world(kind, v, state.world_from_object, state.object_from_world, guarded=True)
    elif target == "CAMERA":
        v = _from_world(kind, v, state.world_from_camera, state.camera_from_world, guarded=False)
    return v


@node("ShaderNodeVectorTransform", "Utilities", reads=_SPACES)
def vector_transform_node(node, inputs, state):
    kind = node.prop("vector_type", "VECTOR")
    source, target = node.prop("convert_from", "WORLD"), node.prop("convert_to", "OBJECT")
    with np.errstate(all="ignore"):
        return {"Vector": vector_transform(kind, source, target, triple(inputs["Vector"]), state)}


NODES = (rgb, combine_xyz, separate_xyz, texture_coordinate, normal, vector_transform_node)
