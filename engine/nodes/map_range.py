"""Map Range (Float and Vector) and Clamp: a value carried from one range to another
(svm/map_range.h) and held inside one (svm/clamp.h)."""
from __future__ import annotations

import numpy as np

from .base import node, scalar, triple
from .math import safe_divide


def clamp(value, lo, hi):
    """Cycles' clamp: min(max(value, lo), hi), so hi wins where lo > hi."""
    return np.minimum(np.maximum(value, lo), hi)


def clamp_range(value, a, b):
    """value held between a and b, whichever is larger (Clamp's Range mode)."""
    return np.where(a > b, clamp(value, b, a), clamp(value, a, b))


def _smoothstep(e0, e1, x):
    """util/math_base.h smoothstep: 0 below e0, 1 from e1 on, the cubic between."""
    with np.errstate(all="ignore"):
        t = (x - e0) / (e1 - e0)
    return np.where(x < e0, 0.0, np.where(x >= e1, 1.0, (3.0 - 2.0 * t) * t * t))


def _smootherstep(e0, e1, x):
    t = np.clip(safe_divide(x - e0, e1 - e0), 0.0, 1.0)
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


def _stepped(factor, steps):
    steps_safe = np.where(steps > 0.0, steps, 1.0)
    return np.where(steps > 0.0, np.floor(factor * (steps + 1.0)) / steps_safe, 0.0)


def map_range_float(value, from_min, from_max, to_min, to_max, steps, kind: str, use_clamp: bool):
    """svm_node_map_range: 0 where the source range is empty. A reversed source range makes
    the smooth steps mirror (1 - step(max, min, x)). Clamping holds the result inside the
    target range whichever way it runs: Cycles adds a Range-mode Clamp node after Map Range
    on the host (inferred from the bake: results past To Min > To Max are held)."""
    span = from_max - from_min
    with np.errstate(all="ignore"):
        linear = (value - from_min) / np.where(span != 0.0, span, 1.0)
        if kind == "STEPPED":
            factor = _stepped(linear, steps)
        elif kind == "SMOOTHSTEP":
            factor = np.where(from_min > from_max, 1.0 - _smoothstep(from_max, from_min, value),
                              _smoothstep(from_min, from_max, value))
        elif kind == "SMOOTHERSTEP":
            factor = np.where(from_min > from_max, 1.0 - _smootherstep(from_max, from_min, value),
                              _smootherstep(from_min, from_max, value))
        else:
            factor = linear
        result = np.where(span != 0.0, to_min + factor * (to_max - to_min), 0.0)
    return clamp_range(result, to_min, to_max) if use_clamp else result


def map_range_vector(value, from_min, from_max, to_min, to_max, steps, kind: str, use_clamp: bool):
    """svm_node_vector_map_range, per component: the factor is a safe division (0 where the
    source range is empty, so the result is To Min), the smooth steps clamp the factor to
    [0, 1] and ignore the Clamp option."""
    factor = safe_divide(value - from_min, from_max - from_min)
    if kind == "STEPPED":
        factor = _stepped(factor, steps)
    elif kind == "SMOOTHSTEP":
        factor = np.clip(factor, 0.0, 1.0)
        factor = (3.0 - 2.0 * factor) * factor * factor
    elif kind == "SMOOTHERSTEP":
        factor = np.clip(factor, 0.0, 1.0)
        factor = factor * factor * factor * (factor * (factor * 6.0 - 15.0) + 10.0)
    result = to_min + factor * (to_max - to_min)
    if use_clamp and kind in ("LINEAR", "STEPPED"):
        result = clamp_range(result, to_min, to_max)
    return result


_FLOAT_INPUTS = ("Value", "From Min", "From Max", "To Min", "To Max", "Steps")
_VECTOR_INPUTS = ("Vector", "From_Min_FLOAT3", "From_Max_FLOAT3", "To_Min_FLOAT3", "To_Max_FLOAT3", "Steps_FLOAT3")


@node("ShaderNodeMapRange", "Utilities")
def map_range(node, inputs, state):
    kind, use_clamp = node.prop("interpolation_type", "LINEAR"), node.prop("clamp", True)
    if node.prop("data_type", "FLOAT") == "FLOAT_VECTOR":
        args = (triple(inputs[k]) for k in _VECTOR_INPUTS)
        return {"Vector": map_range_vector(*args, kind, use_clamp)}
    args = (scalar(inputs[k]) for k in _FLOAT_INPUTS)
    return {"Result": scalar(map_range_float(*args, kind, use_clamp))}


@node("ShaderNodeClamp", "Utilities")
def clamp_node(node, inputs, state):
    value, lo, hi = (scalar(inputs[k]) for k in ("Value", "Min", "Max"))
    if node.prop("clamp_type", "MINMAX") == "RANGE":
        return {"Result": scalar(clamp_range(value, lo, hi))}
    return {"Result": scalar(clamp(value, lo, hi))}


NODES = (map_range, clamp_node)
