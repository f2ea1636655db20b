"""A node graph compiled once into a program of vectorised operations, run per batch.

compile() keeps only the nodes that reach the requested outputs, orders them so every input
is computed before it is read, and evaluates at once every node whose inputs are all constant
and that reads no shading state (constant folding: a material of constant sockets becomes a
program of no operations). What is left runs over a batch of shading points in one pass per
node, each node's NumPy implementation over all the points at once (engine/nodes/base.py has
the value conventions). A node kind the registry does not know is reported once in
`warnings`, with its fallback: its outputs are zero (value, vector, colour) or nothing
(shader).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import convert
from .graph import Graph, Input
from .registry import REGISTRY


@dataclass(frozen=True)
class _Const:
    value: object


@dataclass(frozen=True)
class _Slot:
    node: int
    socket: str


@dataclass(frozen=True)
class Op:
    """Node `index` of the graph: its kind and node, and per input (identifier, reference,
    source type, socket type)."""

    index: int
    node: object
    type: object
    inputs: tuple
    used: tuple = ()  # output identifiers some input or graph output reads


def _zero(kind: str):
    if kind == "shader":
        return ()
    return np.zeros(3) if kind in ("vector", "rgba") else np.float64(0.0)


class Program:
    def __init__(self, ops, results, reads, warnings):
        self.ops = tuple(ops)
        self.results = dict(results)  # output name -> (reference, source type, wanted type)
        self.reads = frozenset(reads)
        self.warnings = tuple(warnings)

    @property
    def constant(self) -> bool:
        return not self.ops

    def run(self, state=None) -> dict:
        """{output name: value} at the points of `state` (engine/nodes/state.py); constant
        outputs stay constants (0-d or (3,)), per-point ones are (N,) or (N,3)."""
        env: dict = {}
        for op in self.ops:
            args = {name: _value(ref, env, src, dst) for name, ref, src, dst in op.inputs}
            out = op.type.run(op.node, args, state, op.used) if op.type is not None else {}
            for name, kind in op.node.outputs:
                env[(op.index, name)] = out[name] if name in out else _zero(kind)
            for name in op.used:  # lazily computed outputs that are read
                if callable(env[(op.index, name)]):
                    env[(op.index, name)] = env[(op.index, name)]()
        return {name: _value(ref, env, src, dst) for name, (ref, src, dst) in self.results.items()}


def _value(ref, env, src, dst):
    value = ref.value if isinstance(ref, _Const) else env[(ref.node, ref.socket)]
    return convert(value, src, dst)


def compile(graph: Graph, outputs: dict) -> Program:
    """The program computing `outputs` {name: wanted type} from the graph's outputs of those
    names (a name the graph does not have is the zero of its type)."""
    order = _needed(graph, [graph.output(name) for name in outputs])
    used = _used(graph, order, [graph.output(name) for name in outputs])
    consts: dict = {}  # (node, socket) -> value, for folded nodes
    ops, reads, warnings = [], set(), []

    def ref_of(socket: Input):
        if socket.link is None:
            return _Const(socket.value), socket.type
        key = (socket.link.node, socket.link.socket)
        if key in consts:
            return _Const(consts[key]), socket.link.type
        return _Slot(*key), socket.link.type

    for i in order:
        node = graph.nodes[i]
        kind = REGISTRY.get(node.kind)
        inputs = []
        for socket in node.inputs:
            ref, src = ref_of(socket)
            inputs.append((socket.name, ref, src, socket.type))
        if kind is None:
            warnings.append(f"{node.label} ({node.kind}) is not supported: its outputs are zero")
        elif kind.notes is not None:
            warnings += [f"{node.label}: {text}" for text in kind.notes(node)]
        fields = kind.fields(used[i], node) if kind is not None else set()
        if kind is None or (not fields and all(isinstance(ref, _Const) for _, ref, _, _ in inputs)):
            out = {}
            if kind is not None:
                args = {name: convert(ref.value, src, dst) for name, ref, src, dst in inputs}
                out = kind.run(node, args, None, used[i])
            for name, socket_type in node.outputs:
                value = out[name] if name in out else _zero(socket_type)
                consts[(i, name)] = value() if callable(value) and name in used[i] else value
            continue
        reads.update(fields)
        ops.append(Op(i, node, kind, tuple(inputs), tuple(sorted(used[i]))))
    results = {}
    for name, wanted in outputs.items():
        socket = graph.output(name)
        if socket is None:
            results[name] = (_Const(_zero(wanted)), wanted, wanted)
        else:
            ref, src = ref_of(socket)
            results[name] = (ref, src, wanted)
    return Program(ops, results, reads, warnings)


def _used(graph: Graph, order, sockets) -> dict:
    """{node index: output identifiers read by the nodes in `order` or by `sockets`}."""
    used = {i: set() for i in order}
    links = [s.link for i in order for s in graph.nodes[i].inputs] + [s.link for s in sockets if s is not None]
    for link in links:
        if link is not None and link.node in used:
            used[link.node].add(link.socket)
    return used


def _needed(graph: Graph, sockets) -> list:
    """Indices of the nodes the sockets depend on, each after every node it reads."""
    order, state = [], {}

    def visit(i):
        if state.get(i) == 2:
            return
        if state.get(i) == 1:
            raise ValueError(f"node graph has a cycle through {graph.nodes[i].label}")
        state[i] = 1
        for socket in graph.nodes[i].inputs:
            if socket.link is not None:
                visit(socket.link.node)
        state[i] = 2
        order.append(i)

    for socket in sockets:
        if socket is not None and socket.link is not None:
            visit(socket.link.node)
    return order
