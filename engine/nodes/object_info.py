"""What the object and the camera give a point: Object Info (svm/geometry.h svm_node_object_info,
geom/object.h) and Camera Data (svm/camera.h).

Object Info's values are per object (and per material for Material Index): the object's
location (its transform's translation), Color and alpha, Pass Index, the material's Pass Index,
and Cycles' per-object random number (engine/nodes/mesh_attributes.object_random). A point of
no object (a world shader) reads zeros. Camera Data reads the point in camera space; Cycles'
node has no bump variant, so a Bump node's offset evaluations read the unmoved point.
"""
from __future__ import annotations

import numpy as np

from .base import node, scalar
from .vector_math import length, normalize, transform_point

_OBJECT_READS = {"Location": ("world_from_object",), "Color": ("object_color",), "Alpha": ("object_alpha",),
                 "Object Index": ("object_index",), "Material Index": ("material_index",),
                 "Random": ("object_random",)}


@node("ShaderNodeObjectInfo", "Input", reads=_OBJECT_READS)
def object_info(node, inputs, state):
    base = state.unshifted
    return {"Location": lambda: np.asarray(base.world_from_object, np.float64)[..., :3, 3],
            "Color": lambda: np.asarray(base.object_color, np.float64),
            "Alpha": lambda: scalar(base.object_alpha), "Object Index": lambda: scalar(base.object_index),
            "Material Index": lambda: scalar(base.material_index), "Random": lambda: scalar(base.object_random)}


@node("ShaderNodeCameraData", "Input", reads=("P", "camera_from_world"))
def camera_data(node, inputs, state):
    """The point in camera space (z forward): its direction normalised, its depth z and its
    distance from the camera."""
    base = state.unshifted
    v = transform_point(np.asarray(base.camera_from_world, np.float64), base.P)
    return {"View Vector": normalize(v), "View Z Depth": v[..., 2], "View Distance": length(v)}


NODES = (object_info, camera_data)
