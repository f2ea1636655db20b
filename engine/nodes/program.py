"""A node graph compiled once into a program of vectorised operations, run per batch.

compile() keeps only the nodes that reach the requested outputs, orders them so every input
is computed before it is read, and evaluates at once every node whose inputs are all constant
and that reads no shading state (constant folding: a material of constant sockets becomes a
program of no operations). What is left runs over a batch of shading points in one pass per
node, each node's NumPy implementation over all the points at once (engine/nodes/base.py has
the value conventions). A node kind the registry does not know is reported once in
`warnings`, with its fallback: its outputs are zero (value, vector, colour) or nothing
(shader).

A Bump node needs its Height at the point and at the point moved along the ray differential
(engine/nodes/bump.py): the nodes Height depends on are compiled twice more, as Cycles' compiler
copies them (scene/shader_graph.cpp refine_bump_nodes), the copies running on the moved point
(differentials.OffsetState) and feeding the Bump node's SampleX and SampleY inputs.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from . import bump as _bump
from .base import convert
from .differentials import AXES, OffsetState, offset_reads
from .graph import Graph, Input
from .registry import REGISTRY


@dataclass(frozen=True)
class _Const:
    value: object


@dataclass(frozen=True)
class _Slot:
    node: object  # a node's index, or (index, bump node, axis) for a Bump node's offset copy
    socket: str


@dataclass(frozen=True)
class Op:
    """Node `index` of the graph: its kind and node, and per input (identifier, reference,
    source type, socket type). `key` names its outputs (the index, or (index, bump node, axis)
    for a copy evaluating a Bump node's Height at the moved point), `shift` is None or (axis,
    filter width) of such a copy."""

    index: int
    node: object
    type: object
    inputs: tuple
    used: tuple = ()  # output identifiers some input or graph output reads
    key: object = None
    shift: tuple | None = None


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
        moved: dict = {}  # (axis, width) -> the state seen from the moved point
        for op in self.ops:
            args = {name: _value(ref, env, src, dst) for name, ref, src, dst in op.inputs}
            at = state
            if op.shift is not None:
                at = moved.setdefault(op.shift, OffsetState(state, *op.shift))
            out = op.type.run(op.node, args, at, op.used) if op.type is not None else {}
            key = op.index if op.key is None else op.key
            for name, kind in op.node.outputs:
                env[(key, name)] = out[name] if name in out else _zero(kind)
            for name in op.used:  # lazily computed outputs that are read
                if callable(env[(key, name)]):
                    env[(key, name)] = env[(key, name)]()
        return {name: _value(ref, env, src, dst) for name, (ref, src, dst) in self.results.items()}


def _value(ref, env, src, dst):
    value = ref.value if isinstance(ref, _Const) else env[(ref.node, ref.socket)]
    return convert(value, src, dst)


def compile(graph: Graph, outputs: dict) -> Program:
    """The program computing `outputs` {name: wanted type} from the graph's outputs of those
    names (a name the graph does not have is the zero of its type)."""
    graph = _without_inert(graph)
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
        if node.kind == _bump.KIND:
            inputs += _bump_samples(graph, i, order, consts, ops, reads)
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


def _without_inert(graph: Graph) -> Graph:
    """The graph with every link leaving an inert node kind (one Cycles builds nothing for)
    removed: the socket it fed keeps its own value, as in Cycles."""
    inert = {i for i, n in enumerate(graph.nodes) if getattr(REGISTRY.get(n.kind), "inert", False)}
    if not inert:
        return graph

    def cut(socket: Input) -> Input:
        return replace(socket, link=None) if socket.link is not None and socket.link.node in inert else socket

    nodes = tuple(replace(n, inputs=tuple(cut(s) for s in n.inputs)) for n in graph.nodes)
    return replace(graph, nodes=nodes, outputs=tuple((name, cut(s)) for name, s in graph.outputs))


def _bump_samples(graph: Graph, b: int, order, consts: dict, ops: list, reads: set) -> list:
    """For Bump node `b`: append to `ops` the two copies of what its Height depends on, run at the
    point moved along each axis of the differential, and return the node's extra inputs
    (SampleX, SampleY) reading them; none where Height is constant."""
    node = graph.nodes[b]
    height = node.input("Height")
    if height is None or height.link is None or (height.link.node, height.link.socket) in consts:
        return []
    deps = _height_nodes(graph, height)
    width = node.input("Filter Width")
    ref = None if width is None else (consts.get((width.link.node, width.link.socket)) if width.link else width.value)
    shift_width = _bump.filter_width(node, ref)
    # The Height's nodes that were not folded to constants, in order (a folded one is the same
    # constant at the moved point).
    sub = [j for j in order if j in deps and not all((j, name) in consts for name, _ in graph.nodes[j].outputs)]
    used = _used(graph, sub, [height])
    extra = []
    for axis, sample in zip(AXES, _bump.SAMPLES):
        for j in sub:
            inner = graph.nodes[j]
            kind = REGISTRY.get(inner.kind)
            inputs = []
            for socket in inner.inputs:
                if socket.link is None:
                    inputs.append((socket.name, _Const(socket.value), socket.type, socket.type))
                    continue
                key = (socket.link.node, socket.link.socket)
                if key in consts:
                    ref = _Const(consts[key])
                elif socket.link.node in deps:
                    ref = _Slot((socket.link.node, b, axis), socket.link.socket)
                else:  # a Bump inside the Height: its normal as at the point
                    ref = _Slot(*key)
                inputs.append((socket.name, ref, socket.link.type, socket.type))
            fields = kind.fields(used[j], inner) if kind is not None else set()
            reads.update(offset_reads(fields))
            ops.append(Op(j, inner, kind, tuple(inputs), tuple(sorted(used[j])), key=(j, b, axis),
                          shift=(axis, shift_width)))
        source = (height.link.node, b, axis) if height.link.node in deps else height.link.node
        extra.append((sample, _Slot(source, height.link.socket), height.link.type, "value"))
    return extra


def _height_nodes(graph: Graph, height: Input) -> set:
    """The nodes a Bump node's Height depends on, up to another Bump node: a Bump inside the
    Height gives its normal at the point in the offset evaluations too (Cycles' bake shows the
    outer Bump's slope taken from the rest of the Height alone)."""
    found, todo = set(), [height.link.node]
    while todo:
        j = todo.pop()
        if j in found or graph.nodes[j].kind == _bump.KIND:
            continue
        found.add(j)
        todo.extend(s.link.node for s in graph.nodes[j].inputs if s.link is not None)
    return found


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
