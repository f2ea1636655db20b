"""Fresnel and Layer Weight (svm/fresnel.h): the dielectric Fresnel reflectance and the facing
ratio of the incoming direction against a normal (the node's Normal input where linked, else
the shading normal N), flipped for backfacing hits as Cycles flips them.

The incoming direction is the ray's (state.I): a bake looking from the camera gives each texel
its own (integrator/init_from_bake.h).
"""
from __future__ import annotations

import numpy as np

from .base import node, scalar, triple
from .vector_math import dot


def fresnel_dielectric_cos(cosi, eta):
    """closure/bsdf_util.h fresnel_dielectric_cos: unpolarised reflectance at |cosi| for relative
    IOR eta, without the refracted direction; 1 for total internal reflection."""
    c = np.abs(cosi)
    g = eta * eta - 1.0 + c * c
    root = np.sqrt(np.maximum(g, 0.0))
    with np.errstate(all="ignore"):
        a = (root - c) / (root + c)
        b = (c * (root + c) - 1.0) / (c * (root - c) + 1.0)
        f = 0.5 * a * a * (1.0 + b * b)
    return np.where(g > 0.0, f, 1.0)


def normal_input(node, inputs, state):
    """A hidden Normal input: its link where linked, else N (Cycles' default link)."""
    socket = node.input("Normal")
    return triple(inputs["Normal"]) if socket is not None and socket.link is not None else state.N


def _reads(extra):
    def reads(node, outputs):
        socket = node.input("Normal")
        linked = socket is not None and socket.link is not None
        return extra + (() if linked else ("N",))
    return reads


@node("ShaderNodeFresnel", "Input", reads=_reads(("I", "backfacing")))
def fresnel(node, inputs, state):
    eta = np.maximum(scalar(inputs["IOR"]), 1e-5)
    eta = np.where(state.backfacing, 1.0 / eta, eta)
    return {"Fac": fresnel_dielectric_cos(dot(state.I, normal_input(node, inputs, state)), eta)}


def facing(cosi, blend):
    """Layer Weight's Facing: 1 - |cos|^p with p = 2 blend below 0.5 and 0.5 / (1 - blend) above
    (blend clamped to [0, 1 - 1e-5]); p = 1 at blend 0.5 exactly."""
    f = np.abs(cosi)
    # The exponent in float32: near blend 1 it is 0.5 / (1 - 0.99999f), which float32 makes
    # 49932 rather than 50000, and f^p shows the difference.
    b = np.clip(np.asarray(blend, np.float64).astype(np.float32), np.float32(0.0), np.float32(1.0 - 1e-5))
    p = np.where(b < 0.5, np.float32(2.0) * b, np.float32(0.5) / (np.float32(1.0) - b)).astype(np.float64)
    return 1.0 - np.where(blend != 0.5, f ** p, f)


@node("ShaderNodeLayerWeight", "Input", reads=_reads(("I", "backfacing")))
def layer_weight(node, inputs, state):
    blend = scalar(inputs["Blend"])
    cosi = dot(state.I, normal_input(node, inputs, state))

    def fresnel_out():
        eta = np.maximum(1.0 - blend, 1e-5)
        eta = np.where(state.backfacing, eta, 1.0 / eta)
        return fresnel_dielectric_cos(cosi, eta)

    return {"Fresnel": fresnel_out, "Facing": lambda: facing(cosi, blend)}


NODES = (fresnel, layer_weight)
