"""What a node kind is to the evaluator, and the value conventions its implementations share.

Values flowing between nodes, over a batch of N shading points:
- scalars (value, int, boolean sockets): float64 arrays (N,), or 0-d arrays where constant;
- vectors and colours: float64 arrays (N,3), or (3,) where constant (alpha is dropped, as
  Cycles keeps colours as float3);
- closures (shader sockets): engine/nodes/closures.py.
Constants broadcast against per-point arrays by NumPy's rules once scalars are made columns
(`column`), so an implementation is written once for both.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

SCALAR_TYPES = ("value", "int", "boolean")
TRIPLE_TYPES = ("vector", "rgba")
# Cycles' linear_rgb_to_gray for Blender's default scene-linear space (Linear Rec.709):
# the luminance weights OpenColorIO's config gives Cycles (kernel_data.film.rgb_to_y).
LUMINANCE = np.array([0.2126729, 0.7151522, 0.0721750])


@dataclass(frozen=True)
class NodeType:
    """One node kind. `evaluate(node, inputs, state)` returns {output identifier: value} for the
    outputs it computes (missing ones are zero; a value may be a function of no arguments,
    called only if the output is read); `inputs` maps every input identifier to its value,
    converted to the socket's type. `reads`: the shading-state fields it uses
    (engine/nodes/state.py), or {output: fields} where they depend on the output read, or a
    function (node, outputs used) -> fields where they depend on the node's links; a node
    that reads none is evaluated at compile time when all its inputs are constant. `menu`:
    Blender's Add menu it sits in (the coverage table). `uses_links`: evaluate takes a fourth
    argument, the identifiers of the outputs the graph reads, for a node whose values depend on
    which of its outputs are linked (Cycles decides some settings when it compiles a node).
    `inert`: Cycles builds nothing for this kind, so a socket linked to it keeps its own value
    (engine/nodes/program.py drops such links before compiling).
    `notes(node)`: what this node of the graph renders differently from Cycles (approximations,
    each a short phrase), reported once per material; None when it renders as Cycles does."""

    kind: str
    menu: str
    evaluate: Callable
    reads: object = ()
    uses_links: bool = False
    notes: Callable = None
    inert: bool = False

    def run(self, node, inputs, state, used) -> dict:
        """evaluate(), told the outputs used where it asks for them."""
        if self.uses_links:
            return self.evaluate(node, inputs, state, frozenset(used))
        return self.evaluate(node, inputs, state)

    def fields(self, outputs, node=None) -> set:
        """The shading-state fields read when `outputs` (identifiers) of `node` are used."""
        if callable(self.reads):
            return set(self.reads(node, outputs))
        if isinstance(self.reads, dict):
            return {f for name in outputs for f in self.reads.get(name, ())}
        return set(self.reads)


def node(kind: str, menu: str, reads=(), uses_links: bool = False, notes: Callable = None, inert: bool = False):
    """Decorator: the function becomes a NodeType (collected by engine/nodes/registry.py)."""
    def make(fn):
        return NodeType(kind, menu, fn, reads if isinstance(reads, dict) or callable(reads) else tuple(reads),
                        uses_links, notes, inert)
    return make


def scalar(x) -> np.ndarray:
    return np.asarray(x, np.float64)


def triple(x) -> np.ndarray:
    """A vector or colour value as (N,3) or (3,) float64 (a constant colour's alpha dropped)."""
    return np.asarray(x, np.float64)[..., :3]


def grey(x) -> np.ndarray:
    """A scalar value as a triple of three equal components."""
    x = scalar(x)
    return np.full(3, float(x)) if x.ndim == 0 else np.repeat(x[:, None], 3, axis=1)


def column(x) -> np.ndarray:
    """A scalar value shaped to broadcast against triples: (N,) -> (N,1); 0-d stays 0-d."""
    x = np.asarray(x, np.float64)
    return x[:, None] if x.ndim == 1 else x


def components(v):
    """The three components of a triple, each (N,) or 0-d."""
    v = np.asarray(v)
    return v[..., 0], v[..., 1], v[..., 2]


def stack(x, y, z) -> np.ndarray:
    """A triple from three scalars (any mix of (N,) and 0-d)."""
    x, y, z = np.broadcast_arrays(scalar(x), scalar(y), scalar(z))
    return np.stack([x, y, z], axis=-1)


def convert(value, src: str, dst: str):
    """A socket value of type src as type dst, as Cycles converts implicitly (svm/convert.h):
    colour -> scalar by luminance, vector -> scalar by the average, scalar -> grey triple."""
    if src == dst or dst == "shader":
        return value
    if dst in SCALAR_TYPES:
        if src in SCALAR_TYPES:
            out = scalar(value)
            return np.trunc(out) if dst == "int" else out
        v = triple(value)
        if src == "rgba":
            return v @ LUMINANCE if v.ndim == 2 else scalar(float(v @ LUMINANCE))
        return v.mean(axis=-1) if v.ndim == 2 else scalar(float(v.mean()))
    if dst in TRIPLE_TYPES:
        return grey(value) if src in SCALAR_TYPES else triple(value)
    return value
