"""Shader values: what a shader socket carries, a weighted list of closures.

A BSDF, emission or background node makes one closure (its kind, its colour weight and the
parameters it read); Mix Shader scales two lists by (1 - fac) and fac, Add Shader joins them,
as Cycles' SVM accumulates closures with weights (svm/closure.h). What a material renders is
the list at its output: engine/nodes/material.py turns it into lobes and emission.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .base import column, node, scalar, triple


@dataclass(frozen=True)
class Closure:
    """kind: "emission", "background", or a lobe's (engine/nodes/shaders.py); weight: (N,3) or
    (3,) colour weight (mix factors included); params: the node's inputs it needs, by name; tag:
    unique among the closures of one graph (the node's label and part), how layers name
    the closure they lie under."""

    kind: str
    weight: np.ndarray
    params: dict = field(default_factory=dict)
    tag: str = ""

    def scaled(self, f) -> "Closure":
        return Closure(self.kind, triple(self.weight) * column(f), self.params, self.tag)


def closures(value) -> tuple:
    """A shader socket's value as a tuple of Closure (unlinked shader sockets hold nothing)."""
    return value if isinstance(value, tuple) else ()


@node("ShaderNodeEmission", "Shader")
def emission(node, inputs, state):
    return {"Emission": (Closure("emission", triple(inputs["Color"]) * column(inputs["Strength"])),)}


@node("ShaderNodeBackground", "Shader")
def background(node, inputs, state):
    return {"Background": (Closure("background", triple(inputs["Color"]) * column(inputs["Strength"])),)}


@node("ShaderNodeMixShader", "Shader")
def mix_shader(node, inputs, state):
    fac = np.clip(scalar(inputs["Fac"]), 0.0, 1.0)
    first = tuple(c.scaled(1.0 - fac) for c in closures(inputs["Shader"]))
    second = tuple(c.scaled(fac) for c in closures(inputs["Shader_001"]))
    return {"Shader": first + second}


@node("ShaderNodeAddShader", "Shader")
def add_shader(node, inputs, state):
    return {"Shader": closures(inputs["Shader"]) + closures(inputs["Shader_001"])}


NODES = (emission, background, mix_shader, add_shader)
