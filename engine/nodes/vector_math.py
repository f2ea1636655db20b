"""Vector Math, every operation, with Cycles' guards (svm/math_util.h svm_vector_math and
util/math_float3.h: a division by a zero component gives 0 there, a zero vector normalises to
itself, refraction past the critical angle gives the zero vector, ...). Also the vector helpers
the other vector nodes share (dot, length, safe_normalize, transform_*)."""
from __future__ import annotations

import numpy as np

from .base import column, node, scalar, triple
from .math import safe_divide, safe_modulo, safe_pow


def dot(a, b):
    """a . b over the last axis: (N,) for per-point triples, 0-d for constants."""
    return np.sum(a * b, axis=-1)


def length(a):
    return np.sqrt(dot(a, a))


def safe_normalize(a):
    """a / |a|, and a itself where |a| is 0 (math_float3.h safe_normalize)."""
    n = column(length(a))
    with np.errstate(all="ignore"):
        return np.where(n != 0.0, a / np.where(n != 0.0, n, 1.0), a)


def normalize(a):
    """a / |a| where Cycles calls the unguarded normalize: its 0/0 (NaN) for a zero vector is
    given as the zero vector here."""
    n = column(length(a))
    with np.errstate(all="ignore"):
        return np.where(n != 0.0, a / np.where(n != 0.0, n, 1.0), 0.0)


def transform_point(m, p):
    """M (..,4,4) applied to points p (..,3): util/transform.h transform_point."""
    return np.einsum("...ij,...j->...i", m[..., :3, :3], p) + m[..., :3, 3]


def transform_direction(m, d):
    """The linear part of M (..,4,4 or ..,3,3) applied to d (..,3): transform_direction."""
    return np.einsum("...ij,...j->...i", m[..., :3, :3], d)


def transform_direction_transposed(m, d):
    """The transposed linear part of M applied to d: transform_direction_transposed (a normal
    goes by M^-T, so a normal's inverse transform is M^T)."""
    return np.einsum("...ji,...j->...i", m[..., :3, :3], d)


def _project(a, b):
    bb = dot(b, b)
    return np.where(column(bb) != 0.0, column(safe_divide(dot(a, b), bb)) * b, 0.0)


def _reflect(a, b):
    n = safe_normalize(b)
    return a - 2.0 * n * column(dot(a, n))


def _refract(a, b, eta):
    """math_float3.h refract with the unit normal safe_normalize(b): zero past the critical angle."""
    n = safe_normalize(b)
    eta = column(eta)
    ni = column(dot(n, a))
    k = 1.0 - eta * eta * (1.0 - ni * ni)
    return np.where(k < 0.0, 0.0, eta * a - (eta * ni + np.sqrt(np.maximum(k, 0.0))) * n)


def _faceforward(a, b, c):
    return np.where(column(dot(c, b)) < 0.0, a, -a)


def _wrap(a, hi, lo):
    """math_float3.h wrap: (a - lo) floored-modulo (hi - lo), + lo; lo where hi == lo."""
    span = hi - lo
    span_safe = np.where(span != 0.0, span, 1.0)
    return np.where(span != 0.0, (a - lo) - np.floor((a - lo) / span_safe) * span, 0.0) + lo


# Operation -> f(a, b, c, scale) of triples (and `scale` a column), as svm_vector_math.
VECTOR_OPERATIONS = {
    "ADD": lambda a, b, c, s: a + b,
    "SUBTRACT": lambda a, b, c, s: a - b,
    "MULTIPLY": lambda a, b, c, s: a * b,
    "DIVIDE": lambda a, b, c, s: safe_divide(a, b),
    "MULTIPLY_ADD": lambda a, b, c, s: a * b + c,
    "CROSS_PRODUCT": lambda a, b, c, s: np.cross(a, b),
    "PROJECT": lambda a, b, c, s: _project(a, b),
    "REFLECT": lambda a, b, c, s: _reflect(a, b),
    "REFRACT": lambda a, b, c, s: _refract(a, b, s),
    "FACEFORWARD": lambda a, b, c, s: _faceforward(a, b, c),
    "SCALE": lambda a, b, c, s: a * s,
    "NORMALIZE": lambda a, b, c, s: safe_normalize(a),
    "ABSOLUTE": lambda a, b, c, s: np.abs(a),
    "POWER": lambda a, b, c, s: safe_pow(a, b),
    "SIGN": lambda a, b, c, s: np.sign(a),
    "MINIMUM": lambda a, b, c, s: np.minimum(a, b),
    "MAXIMUM": lambda a, b, c, s: np.maximum(a, b),
    "FLOOR": lambda a, b, c, s: np.floor(a),
    "CEIL": lambda a, b, c, s: np.ceil(a),
    "FRACTION": lambda a, b, c, s: a - np.floor(a),
    "MODULO": lambda a, b, c, s: safe_modulo(a, b),
    "WRAP": lambda a, b, c, s: _wrap(a, b, c),
    "SNAP": lambda a, b, c, s: np.floor(safe_divide(a, b)) * b,
    "SINE": lambda a, b, c, s: np.sin(a),
    "COSINE": lambda a, b, c, s: np.cos(a),
    "TANGENT": lambda a, b, c, s: np.tan(a),
}
# The operations whose result is the scalar Value output (the Vector output is then 0).
VALUE_OPERATIONS = {
    "DOT_PRODUCT": lambda a, b: dot(a, b),
    "DISTANCE": lambda a, b: length(a - b),
    "LENGTH": lambda a, b: length(a),
}


@node("ShaderNodeVectorMath", "Utilities")
def vector_math(node, inputs, state):
    a, b, c = (triple(inputs[k]) for k in ("Vector", "Vector_001", "Vector_002"))
    operation = node.prop("operation", "ADD")
    with np.errstate(all="ignore"):
        if operation in VALUE_OPERATIONS:
            return {"Value": scalar(VALUE_OPERATIONS[operation](a, b))}
        vector = VECTOR_OPERATIONS[operation](a, b, c, column(inputs["Scale"]))
    return {"Vector": np.asarray(vector, np.float64)}


NODES = (vector_math,)
