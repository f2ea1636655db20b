"""A texture node's own mapping (its TexMapping: the Vector's translation, rotation, scale and
axis remap, set in the node's side panel), applied to the texture coordinate before the
texture, as Cycles' TextureMapping does (scene/shader_nodes.cpp compute_transform, the
kernel's svm_node_texture_mapping).

Cycles reads the mapping's type, translation, rotation, scale and axis mapping (blender/
shader.cpp get_tex_mapping); its min/max clamp and projection are not synced and have no
effect, nor has the node's ColorMapping. engine/blender/export_nodes.py exports the mapping as
(type, translation, rotation, scale, (x, y, z axis)) and None where Cycles skips it
(identity), so a node without one costs nothing.
"""
from __future__ import annotations

import numpy as np

from .base import triple

_AXIS = {"NONE": None, "X": 0, "Y": 1, "Z": 2}


def _rotation(euler) -> np.ndarray:
    """Cycles' transform_euler: Rz Ry Rx (x applied first)."""
    cx, cy, cz = np.cos(euler)
    sx, sy, sz = np.sin(euler)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def matrix(mapping) -> np.ndarray:
    """The 3x4 affine transform (rows: output x, y, z) of an exported mapping."""
    kind, translation, rotation, scale, axes = mapping
    remap = np.zeros((4, 4))
    remap[3, 3] = 1.0
    for row, axis in enumerate(axes):
        if _AXIS[axis] is not None:
            remap[row, _AXIS[axis]] = 1.0
    scale = np.array(scale, np.float64)
    if kind in ("TEXTURE", "NORMAL"):  # kept invertible, as Cycles clamps it
        small = np.abs(scale) < 1e-5
        scale = np.where(small, np.sign(scale) * 1e-5, scale)
    linear = np.eye(4)
    linear[:3, :3] = _rotation(np.array(rotation, np.float64)) @ np.diag(scale)
    full = linear.copy()
    full[:3, 3] = translation
    if kind == "TEXTURE":
        m = np.linalg.inv(full)
    elif kind == "POINT":
        m = full
    elif kind == "VECTOR":
        m = linear
    else:  # NORMAL: the inverse transpose, no translation
        m = np.eye(4)
        m[:3, :3] = np.linalg.inv(linear[:3, :3]).T
    return (m @ remap)[:3]


def apply(vector, mapping):
    """`vector` ((N,3) or (3,)) through the exported mapping (None: unchanged)."""
    if mapping is None:
        return vector
    m = matrix(mapping)
    out = vector @ m[:, :3].T + m[:, 3]
    if mapping[0] == "NORMAL":  # Cycles normalises after the mapping (a zero vector stays zero)
        length = np.linalg.norm(out, axis=-1, keepdims=True)
        out = np.where(length > 0.0, out / np.where(length > 0.0, length, 1.0), 0.0)
    return out


def unlinked_reads(field: str):
    """A NodeType's reads for a texture whose unlinked Vector reads shading-state `field`."""
    def reads(node, outputs) -> tuple:
        socket = node.input("Vector")
        return () if socket is not None and socket.link is not None else (field,)
    return reads


def coordinate(node, inputs, state, field: str = "generated"):
    """A texture's coordinate: its Vector input where linked, else the shading state's `field`
    (Cycles' default link of the texture), through the node's own mapping."""
    socket = node.input("Vector")
    linked = socket is not None and socket.link is not None
    return apply(triple(inputs["Vector"]) if linked else triple(getattr(state, field)), node.prop("texture_mapping"))
