"""Math and Value: scalar arithmetic with Cycles' guards (svm/math_util.h svm_math and
util/math_base.h: a division by zero gives 0, pow of a negative base by a non-integer gives 0,
...), so a graph tuned in Cycles gives the same numbers here.
"""
from __future__ import annotations

import numpy as np

from .base import node, scalar

_FLT_EPSILON = np.finfo(np.float32).eps


def safe_divide(a, b):
    b_safe = np.where(b != 0.0, b, 1.0)
    return np.where(b != 0.0, a / b_safe, 0.0)


def safe_pow(a, b):
    """Cycles' safe_powf: 0 for a negative base with a non-integer exponent; x^0 = 1, 0^y = 0."""
    a, b = np.broadcast_arrays(scalar(a), scalar(b))
    bad = (a < 0.0) & (b != np.trunc(b))
    with np.errstate(all="ignore"):
        p = np.power(np.where(bad, 1.0, a), b)
    return np.where(b == 0.0, 1.0, np.where((a == 0.0) | bad, 0.0, p))


def safe_log(a, b):
    ok = (a > 0.0) & (b > 0.0)
    with np.errstate(all="ignore"):
        return np.where(ok, safe_divide(np.log(np.where(ok, a, 1.0)), np.log(np.where(ok, b, 2.0))), 0.0)


def safe_modulo(a, b):
    with np.errstate(all="ignore"):
        return np.where(b != 0.0, np.fmod(a, np.where(b != 0.0, b, 1.0)), 0.0)


def floored_modulo(a, b):
    b_safe = np.where(b != 0.0, b, 1.0)
    return np.where(b != 0.0, a - np.floor(a / b_safe) * b_safe, 0.0)


def wrap(value, high, low):
    """Cycles' wrapf: value wrapped into [low, high), low where the range is empty."""
    span = high - low
    span_safe = np.where(span != 0.0, span, 1.0)
    return np.where(span != 0.0, value - span * np.floor((value - low) / span_safe), low)


def pingpong(a, b):
    b_safe = np.where(b != 0.0, b, 1.0)
    x = (a - b) / (b_safe * 2.0)
    return np.where(b != 0.0, np.abs((x - np.floor(x)) * b * 2.0 - b), 0.0)


def smooth_min(a, b, k):
    k_safe = np.where(k != 0.0, k, 1.0)
    h = np.maximum(k - np.abs(a - b), 0.0) / k_safe
    return np.where(k != 0.0, np.minimum(a, b) - h * h * h * k * (1.0 / 6.0), np.minimum(a, b))


def sign(a):
    return np.sign(a)


def atan2(y, x):
    return np.where((x == 0.0) & (y == 0.0), 0.0, np.arctan2(y, x))


def _inverse_sqrt(a):
    with np.errstate(all="ignore"):
        return np.where(a > 0.0, 1.0 / np.sqrt(np.maximum(a, 1e-300)), 0.0)


def _compare(a, b, c):
    return np.where((a == b) | (np.abs(a - b) <= np.maximum(c, _FLT_EPSILON)), 1.0, 0.0)


def _trunc(a):
    return np.where(a >= 0.0, np.floor(a), np.ceil(a))


# Operation -> f(a, b, c), as svm_math.
OPERATIONS = {
    "ADD": lambda a, b, c: a + b,
    "SUBTRACT": lambda a, b, c: a - b,
    "MULTIPLY": lambda a, b, c: a * b,
    "DIVIDE": lambda a, b, c: safe_divide(a, b),
    "MULTIPLY_ADD": lambda a, b, c: a * b + c,
    "POWER": lambda a, b, c: safe_pow(a, b),
    "LOGARITHM": lambda a, b, c: safe_log(a, b),
    "SQRT": lambda a, b, c: np.sqrt(np.maximum(a, 0.0)),
    "INVERSE_SQRT": lambda a, b, c: _inverse_sqrt(a),
    "ABSOLUTE": lambda a, b, c: np.abs(a),
    "EXPONENT": lambda a, b, c: np.exp(a),
    "MINIMUM": lambda a, b, c: np.minimum(a, b),
    "MAXIMUM": lambda a, b, c: np.maximum(a, b),
    "LESS_THAN": lambda a, b, c: (a < b).astype(np.float64),
    "GREATER_THAN": lambda a, b, c: (a > b).astype(np.float64),
    "SIGN": lambda a, b, c: sign(a),
    "COMPARE": _compare,
    "SMOOTH_MIN": smooth_min,
    "SMOOTH_MAX": lambda a, b, c: -smooth_min(-a, -b, c),
    "ROUND": lambda a, b, c: np.floor(a + 0.5),
    "FLOOR": lambda a, b, c: np.floor(a),
    "CEIL": lambda a, b, c: np.ceil(a),
    "TRUNC": lambda a, b, c: _trunc(a),
    "FRACT": lambda a, b, c: a - np.floor(a),
    "MODULO": lambda a, b, c: safe_modulo(a, b),
    "FLOORED_MODULO": lambda a, b, c: floored_modulo(a, b),
    "WRAP": wrap,
    "SNAP": lambda a, b, c: np.floor(safe_divide(a, b)) * b,
    "PINGPONG": lambda a, b, c: pingpong(a, b),
    "SINE": lambda a, b, c: np.sin(a),
    "COSINE": lambda a, b, c: np.cos(a),
    "TANGENT": lambda a, b, c: np.tan(a),
    "ARCSINE": lambda a, b, c: np.arcsin(np.clip(a, -1.0, 1.0)),
    "ARCCOSINE": lambda a, b, c: np.arccos(np.clip(a, -1.0, 1.0)),
    "ARCTANGENT": lambda a, b, c: np.arctan(a),
    "ARCTAN2": lambda a, b, c: atan2(a, b),
    "SINH": lambda a, b, c: np.sinh(a),
    "COSH": lambda a, b, c: np.cosh(a),
    "TANH": lambda a, b, c: np.tanh(a),
    "RADIANS": lambda a, b, c: a * (np.pi / 180.0),
    "DEGREES": lambda a, b, c: a * (180.0 / np.pi),
}


@node("ShaderNodeMath", "Utilities")
def math(node, inputs, state):
    a, b, c = (scalar(inputs[k]) for k in ("Value", "Value_001", "Value_002"))
    with np.errstate(all="ignore"):
        value = OPERATIONS[node.prop("operation", "ADD")](a, b, c)
    if node.prop("use_clamp", False):
        value = np.clip(value, 0.0, 1.0)
    return {"Value": scalar(value)}


@node("ShaderNodeValue", "Input")
def value(node, inputs, state):
    return {"Value": scalar(node.prop("value", 0.0))}


NODES = (math, value)
