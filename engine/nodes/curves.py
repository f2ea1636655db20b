"""Colour Ramp, RGB Curves, Vector Curves and Float Curve, as Cycles evaluates them: Blender's
ramp or curve is sampled into a table on the host (engine/blender/export_nodes.py builds the
same table Cycles' sync does: props `color_ramp` and `mapping`, each with a `table`), and the
kernel interpolates the table (svm/ramp.h): the ramp's Constant interpolation is therefore
stepped at the table's resolution, and curves beyond their points' range follow the table's
end segments when extrapolating.

Where all of a node's inputs are constant, Blender folds the node before Cycles sees it, with
its own evaluation of the ramp or curve (inferred from the bake: a Constant ramp read at a
constant just past a stop gives the stop's colour, which the table would give only 1/256
later; a Float Curve past its last point follows the curve's end slope, not the table's).
Ember's compile-time folding (state None) does the same: the ramp from its stops as Blender's
colorband.cc evaluates them, the curves from Blender's own curve tables (exported as `curves`).
"""
from __future__ import annotations

import numpy as np

from .base import column, components, node, scalar, stack, triple
from .color import hsl_to_rgb, hsv_to_rgb, rgb_to_hsl, rgb_to_hsv


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
    if f.ndim == 1 and table.ndim == 2 and not extrapolate:  # per point, rows of channels
        return _lookup_columns(table, i, x - i, interpolate)
    t = (x - i)[pad]
    out = table[i]
    if interpolate:
        out = np.where(t > 0.0, (1.0 - t) * out + t * table[np.minimum(i + 1, size - 1)], out)
    if extrapolate:
        low = table[0] + (table[0] - table[1]) * (-f)[pad] * (size - 1)
        high = table[-1] + (table[-1] - table[-2]) * (f - 1.0)[pad] * (size - 1)
        out = np.where((f < 0.0)[pad], low, np.where((f > 1.0)[pad], high, out))
    return out


def _lookup_columns(table, i, t, interpolate: bool):
    """ramp_lookup's rows (N, C) at entries i (N,) and fractions t (N,): one channel at a time,
    each gathered from its own contiguous column (a gather of short rows is several times
    slower in NumPy), the same values."""
    i1 = np.minimum(i + 1, len(table) - 1) if interpolate else None
    up = t > 0.0
    out = np.empty((len(i), table.shape[1]))
    for c in range(table.shape[1]):
        column_ = np.ascontiguousarray(table[:, c])
        value = column_.take(i)
        if interpolate:
            value = np.where(up, (1.0 - t) * value + t * column_.take(i1), value)
        out[:, c] = value
    return out


def _settings(node, name: str) -> dict:
    return dict(node.prop(name, ()))


def _spline_weights(t, kind: str):
    """Blender's key_curve_position_weights: weights of the stops (right of right, right,
    left, left of left) at t in [0, 1] from the right stop to the left one."""
    t2, t3 = t * t, t * t * t
    if kind == "CARDINAL":
        fc = 0.71
        return (-fc * t3 + 2.0 * fc * t2 - fc * t, (2.0 - fc) * t3 + (fc - 3.0) * t2 + 1.0,
                (fc - 2.0) * t3 + (3.0 - 2.0 * fc) * t2 + fc * t, fc * t3 - fc * t2)
    return (-t3 / 6.0 + 0.5 * t2 - 0.5 * t + 1.0 / 6.0, 0.5 * t3 - t2 + 2.0 / 3.0,
            -0.5 * t3 + 0.5 * t2 + 0.5 * t + 1.0 / 6.0, t3 / 6.0)


def _hue_mix(mode: str, w_right, w_left, h_right, h_left):
    """Blender's colorband_hue_interp: hue from the right stop's to the left one's, going the
    near or far way round, or clockwise or counter-clockwise."""
    h1 = np.where(h_right < 1.0, h_right, h_right - 1.0)
    h2 = np.where(h_left < 1.0, h_left, h_left - 1.0)
    if mode == "NEAR":
        wrap = np.where((h1 < h2) & (h2 - h1 > 0.5), 1, np.where((h1 > h2) & (h2 - h1 < -0.5), 2, 0))
    elif mode == "FAR":
        wrap = np.where(h1 == h2, 1, np.where((h1 < h2) & (h2 - h1 < 0.5), 1,
                                              np.where((h1 > h2) & (h2 - h1 > -0.5), 2, 0)))
    elif mode == "CCW":
        wrap = np.where(h1 > h2, 2, 0)
    else:  # CW
        wrap = np.where(h1 < h2, 1, 0)
    h = w_right * (h1 + (wrap == 1)) + w_left * (h2 + (wrap == 2))
    return np.where((wrap != 0) & (h >= 1.0), h - 1.0, h)


_MODELS = {"HSV": (rgb_to_hsv, hsv_to_rgb), "HSL": (rgb_to_hsl, hsl_to_rgb)}


def colorband(ramp: dict, x):
    """The ramp at positions x as Blender evaluates it from its stops (blenkernel colorband.cc
    BKE_colorband_evaluate): RGBA, (..., 4). Outside the stops Linear, Ease and Constant hold
    the end colours, B-Spline and Cardinal run on against stops repeated at 0 and 1; HSV and
    HSL ramps interpolate linearly in their model, hue by the ramp's hue interpolation."""
    pos = np.array([p for p, _ in ramp["elements"]], np.float64)
    col = np.array([c for _, c in ramp["elements"]], np.float64)
    n = len(pos)
    x = scalar(x).astype(np.float32).astype(np.float64)  # Blender's float: at a stop is at it
    rgb_mode = ramp["color_mode"] == "RGB"
    kind = ramp["interpolation"] if rgb_mode else "LINEAR"
    a = np.searchsorted(pos, x, side="right")  # the first stop right of x
    right, left = np.minimum(a, n - 1), np.maximum(a - 1, 0)
    p_right = np.where(a < n, pos[right], 1.0)
    p_left = np.where(a > 0, pos[left], 0.0)
    same = p_left == p_right
    with np.errstate(all="ignore"):
        w = np.where(same, np.where(a != n, 0.0, 1.0), (x - p_right) / np.where(same, 1.0, p_left - p_right))
    wcol = w[..., None]
    if kind in ("B_SPLINE", "CARDINAL"):
        k = _spline_weights(np.clip(w, 0.0, 1.0), kind)
        stops = (col[np.minimum(a + 1, n - 1)], col[right], col[left], col[np.maximum(a - 2, 0)])
        out = sum(wk[..., None] * c for wk, c in zip(k, stops))
        out = np.clip(out, 0.0, 1.0)
    elif kind == "CONSTANT":
        out = col[left]
    else:
        if kind == "EASE":
            wcol = wcol * wcol * (3.0 - 2.0 * wcol)
            w = wcol[..., 0]
        if rgb_mode:
            out = (1.0 - wcol) * col[right] + wcol * col[left]
        else:
            to_model, from_model = _MODELS[ramp["color_mode"]]
            m_right, m_left = to_model(col[right][..., :3]), to_model(col[left][..., :3])
            hue = _hue_mix(ramp["hue_interpolation"], 1.0 - w, w, m_right[..., 0], m_left[..., 0])
            rest = (1.0 - wcol) * m_right[..., 1:] + wcol * m_left[..., 1:]
            rgb = from_model(stack(hue, rest[..., 0], rest[..., 1]))
            alpha = (1.0 - w) * col[right][..., 3] + w * col[left][..., 3]
            out = np.concatenate([rgb, alpha[..., None]], axis=-1)
    if kind in ("LINEAR", "EASE", "CONSTANT"):
        out = np.where((x <= pos[0])[..., None], col[0], np.where((a == n)[..., None], col[-1], out))
    return np.broadcast_to(col[0], out.shape).copy() if n == 1 else out  # one stop: its colour


@node("ShaderNodeValToRGB", "Color")
def color_ramp(node, inputs, state):
    """svm/ramp.h svm_node_rgb_ramp: the RGBA table looked up at Fac, linearly unless the
    ramp's interpolation is Constant; never extrapolated. A constant Fac: Blender's evaluation."""
    ramp = _settings(node, "color_ramp")
    if state is None:
        rgba = colorband(ramp, inputs["Fac"])
    else:
        rgba = ramp_lookup(ramp["table"], inputs["Fac"], interpolate=ramp["interpolation"] != "CONSTANT")
    return {"Color": rgba[..., :3], "Alpha": rgba[..., 3]}


def blender_curve(samples, x):
    """One curve at x as Blender evaluates it (BKE_curvemap_evaluateF), from the export's
    samples (engine/blender/export_nodes.py _curve_samples)."""
    x0, x1, knots, below, above = samples
    x = scalar(x)
    inside = np.interp(x, np.linspace(x0, x1, len(knots)), np.asarray(knots, np.float64))
    return np.where(x < x0, below[0] + below[1] * x, np.where(x > x1, above[0] + above[1] * x, inside))


def _curves(node, inputs, state, value_name: str):
    """svm/ramp.h svm_node_curves: each component looked up in its own column of the table at
    its position relative to the curves' range, then mixed with the input by Fac."""
    curves = _settings(node, "mapping")
    color = triple(inputs[value_name])
    fac = column(inputs["Fac"])
    if state is None:  # Blender's evaluation; RGB Curves' R, G, B after the combined curve C
        each = curves["curves"]
        parts = components(color)
        if len(each) == 4:
            parts = [blender_curve(each[3], c) for c in parts]
        return (1.0 - fac) * color + fac * stack(*(blender_curve(each[k], c) for k, c in enumerate(parts)))
    lo, hi = curves["range"]
    rel = (color - lo) / (hi - lo)
    table = np.asarray(curves["table"], np.float64)
    mapped = stack(*(ramp_lookup(table[:, k], c, True, curves["extrapolate"]) for k, c in enumerate(components(rel))))
    return (1.0 - fac) * color + fac * mapped


@node("ShaderNodeRGBCurve", "Color")
def rgb_curves(node, inputs, state):
    return {"Color": _curves(node, inputs, state, "Color")}


@node("ShaderNodeVectorCurve", "Vector")
def vector_curves(node, inputs, state):
    return {"Vector": _curves(node, inputs, state, "Vector")}


@node("ShaderNodeFloatCurve", "Utilities")
def float_curve(node, inputs, state):
    """svm/ramp.h svm_node_curve: the value looked up in the table at its position relative to
    the curve's range, mixed with the input by Factor."""
    curve = _settings(node, "mapping")
    lo, hi = curve["range"]
    value = scalar(inputs["Value"])
    if state is None:
        mapped = blender_curve(curve["curves"][0], value)
    else:
        table = np.asarray(curve["table"], np.float64)[:, 0]
        mapped = ramp_lookup(table, (value - lo) / (hi - lo), True, curve["extrapolate"])
    fac = scalar(inputs["Factor"])
    return {"Value": scalar((1.0 - fac) * value + fac * mapped)}


NODES = (color_ramp, rgb_curves, vector_curves, float_curve)
