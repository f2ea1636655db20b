"""Vectors and colours in and out: RGB, Combine/Separate XYZ, Texture Coordinate."""
from __future__ import annotations

import numpy as np

from .base import components, node, stack, triple


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


_TEXCOORD_READS = {"Generated": ("generated",), "Normal": ("N",), "UV": ("uv",), "Object": ("object",),
                   "Camera": ("camera",), "Window": ("window",), "Reflection": ("I", "N")}


@node("ShaderNodeTexCoord", "Input", reads=_TEXCOORD_READS)
def texture_coordinate(node, inputs, state):
    return {"Generated": lambda: state.generated, "Normal": lambda: state.N, "UV": lambda: state.uv,
            "Object": lambda: state.object, "Camera": lambda: state.camera, "Window": lambda: state.window,
            "Reflection": lambda: _reflect(state.I, state.N)}


def _reflect(incoming, n):
    """I reflected about N: 2 (I.N) N - I (Cycles' tex_coord: reflect(-I, N) with I toward the eye)."""
    d = np.sum(incoming * n, axis=-1, keepdims=True)
    return 2.0 * d * n - incoming


NODES = (rgb, combine_xyz, separate_xyz, texture_coordinate)
