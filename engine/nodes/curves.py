"""Colour Ramp, RGB Curves, Vector Curves and Float Curve, as Cycles evaluates them: Blender's
ramp or curve is sampled into a table on the host (engine/blender/export_nodes.py builds the
same table Cycles' sync does: props `color_ramp` and `mapping`, each with a `table`), and the
kernel interpolates the table (svm/ramp.h): the ramp's Constant interpolation is therefore
stepped at the table's resolution, and curves beyond their points' range follow the table's
end segments when extrapolating.
"""
from __future__ import annotations

import numpy as np

from .base import column, components, node, scalar, stack, triple


def ramp_lookup(table, f, interpolate: bool = True, extrapolate: bool = False):
    """svm/ramp.h rgb_ramp_lookup / float_ramp_lookup: table (S, ...) read at f in [0, 1]
    (clamped, or continued along the end segments if `extrapolate`); between entries linear
    if `interpolate`, else the entry below. f (N,) or 0-d; the result has f's shape and
    then the table's row shape."""
    table = np.asarray(table, np.float64)
    size = len(table)
    f = scalar(f)
    pad = (slice(None),) * f.ndim + (None,) * (table.ndim - 1)  # f's axes, then a row's
    x = np.clip(np.nan_to_num(f, nan=0.0), 0.0, 1.0) * (size - 1)
    i = np.clip(np.trunc(x), 0, size - 1).astype(np.int64)
    t = (x - i)[pad]
    out = table[i]
    if interpolate:
        out = np.where(t > 0.0, (1.0 - t) * out + t * table[np.minimum(i + 1, size - 1)], out)
    if extrapolate:
        low = table[0] + (table[0] - table[1]) * (-f)[pad] * (size - 1)
        high = table[-1] + (table[-1] - table[-2]) * (f - 1.0)[pad] * (size - 1)
        out = np.where((f < 0.0)[pad], low, np.where((f > 1.0)[pad], high, out))
    return out


def _settings(node, name: str) -> dict:
    return dict(node.prop(name, ()))


@node("ShaderNodeValToRGB", "Converter")
def color_ramp(node, inputs, state):
    """svm/ramp.h svm_node_rgb_ramp: the RGBA table looked up at Fac, linearly unless the
    ramp's interpolation is Constant; never extrapolated."""
    ramp = _settings(node, "color_ramp")
    rgba = ramp_lookup(ramp["table"], inputs["Fac"], interpolate=ramp["interpolation"] != "CONSTANT")
    return {"Color": rgba[..., :3], "Alpha": rgba[..., 3]}


def _curves(node, inputs, value_name: str):
    """svm/ramp.h svm_node_curves: each component looked up in its own column of the table at
    its position relative to the curves' range, then mixed with the input by Fac."""
    curves = _settings(node, "mapping")
    lo, hi = curves["range"]
    color = triple(inputs[value_name])
    rel = (color - lo) / (hi - lo)
    table = np.asarray(curves["table"], np.float64)
    mapped = stack(*(ramp_lookup(table[:, k], c, True, curves["extrapolate"]) for k, c in enumerate(components(rel))))
    fac = column(inputs["Fac"])
    return (1.0 - fac) * color + fac * mapped


@node("ShaderNodeRGBCurve", "Color")
def rgb_curves(node, inputs, state):
    return {"Color": _curves(node, inputs, "Color")}


@node("ShaderNodeVectorCurve", "Vector")
def vector_curves(node, inputs, state):
    return {"Vector": _curves(node, inputs, "Vector")}


@node("ShaderNodeFloatCurve", "Converter")
def float_curve(node, inputs, state):
    """svm/ramp.h svm_node_curve: the value looked up in the table at its position relative to
    the curve's range, mixed with the input by Factor."""
    curve = _settings(node, "mapping")
    lo, hi = curve["range"]
    value = scalar(inputs["Value"])
    table = np.asarray(curve["table"], np.float64)[:, 0]
    mapped = ramp_lookup(table, (value - lo) / (hi - lo), True, curve["extrapolate"])
    fac = scalar(inputs["Factor"])
    return {"Value": scalar((1.0 - fac) * value + fac * mapped)}


NODES = (color_ramp, rgb_curves, vector_curves, float_curve)
