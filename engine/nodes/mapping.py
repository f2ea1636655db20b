"""Mapping and Vector Rotate: vectors moved, turned and scaled by the node's inputs
(svm/mapping_util.h svm_mapping, svm/vector_rotate.h). Rotations are Blender's Euler XYZ:
X first, then Y, then Z, about the fixed axes (util/transform.h euler_to_transform)."""
from __future__ import annotations

import numpy as np

from .base import column, components, node, scalar, triple
from .math import safe_divide
from .vector_math import dot, length, safe_normalize, transform_direction, transform_direction_transposed


def euler_to_matrix(rotation) -> np.ndarray:
    """Euler XYZ angles (..,3) -> the rotation Rz Ry Rx as (..,3,3) matrices."""
    cx, cy, cz = (np.cos(a) for a in components(rotation))
    sx, sy, sz = (np.sin(a) for a in components(rotation))
    rows = ((cy * cz, sy * sx * cz - cx * sz, sy * cx * cz + sx * sz),
            (cy * sz, sy * sx * sz + cx * cz, sy * cx * sz - sx * cz),
            (-sy, cy * sx, cy * cx))
    rows = [np.stack(np.broadcast_arrays(*row), axis=-1) for row in rows]
    return np.stack(rows, axis=-2)


def rotate_around_axis(p, axis, angle):
    """p turned by `angle` about the unit `axis`, right-handed (Rodrigues' formula, as
    util/math_float3.h rotate_around_axis)."""
    c, s = column(np.cos(angle)), column(np.sin(angle))
    return c * p + (1.0 - c) * column(dot(axis, p)) * axis + s * np.cross(axis, p)


def mapping(kind: str, vector, location, rotation, scale):
    """svm_mapping: Point scales, turns, then moves; Texture is its inverse (so a texture
    mapped through it moves with the inputs); Vector ignores Location; Normal scales by the
    inverse and renormalises, as normals transform."""
    r = euler_to_matrix(rotation)
    if kind == "POINT":
        return transform_direction(r, vector * scale) + location
    if kind == "TEXTURE":
        return safe_divide(transform_direction_transposed(r, vector - location), scale)
    if kind == "VECTOR":
        return transform_direction(r, vector * scale)
    if kind == "NORMAL":
        return safe_normalize(transform_direction(r, safe_divide(vector, scale)))
    return np.zeros(3)


@node("ShaderNodeMapping", "Utilities")
def mapping_node(node, inputs, state):
    args = (triple(inputs[k]) for k in ("Vector", "Location", "Rotation", "Scale"))
    return {"Vector": mapping(node.prop("vector_type", "POINT"), *args)}


_AXES = {"X_AXIS": np.array([1.0, 0.0, 0.0]), "Y_AXIS": np.array([0.0, 1.0, 0.0]),
         "Z_AXIS": np.array([0.0, 0.0, 1.0])}


def vector_rotate(kind: str, invert: bool, vector, center, axis, angle, rotation):
    """svm_node_vector_rotate: about Center; Invert turns the other way (the transposed
    Euler matrix, the negated angle). A zero Axis leaves the vector where it is."""
    p = vector - center
    if kind == "EULER_XYZ":
        r = euler_to_matrix(rotation)
        turned = transform_direction_transposed(r, p) if invert else transform_direction(r, p)
        return turned + center
    angle = -angle if invert else angle
    if kind in _AXES:
        return rotate_around_axis(p, _AXES[kind], angle) + center
    n = column(length(axis))
    unit = axis / np.where(n != 0.0, n, 1.0)
    return np.where(n != 0.0, rotate_around_axis(p, unit, angle) + center, vector)


@node("ShaderNodeVectorRotate", "Utilities")
def vector_rotate_node(node, inputs, state):
    vector, center, axis, rotation = (triple(inputs[k]) for k in ("Vector", "Center", "Axis", "Rotation"))
    kind, invert = node.prop("rotation_type", "AXIS_ANGLE"), node.prop("invert", False)
    return {"Vector": vector_rotate(kind, invert, vector, center, axis, scalar(inputs["Angle"]), rotation)}


NODES = (mapping_node, vector_rotate_node)
