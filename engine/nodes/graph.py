"""A shader node tree as plain data: what engine/blender/export_nodes.py reads from Blender and
engine/nodes/program.py compiles. Knows nothing of Blender.

A Graph is flat: node groups are inlined, reroutes removed and muted nodes bypassed at export,
so every node here is one that computes. Sockets are named by Blender's identifiers (a Math
node's inputs are "Value", "Value_001", "Value_002"), values are scene-linear floats, and
socket types are Blender's, lower-cased: "value", "int", "boolean", "vector", "rgba",
"shader". A link remembers the type of the socket it leaves, so the compiler converts as
Cycles does (colour -> float by luminance, vector -> float by the average, float -> grey).
"""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Link:
    """The output `socket` (identifier) of node `node` (index into Graph.nodes), of type `type`."""

    node: int
    socket: str
    type: str


@dataclass(frozen=True)
class Input:
    """An input socket: its identifier, type and value where nothing is linked (a float, or a
    tuple of 3 for vectors and colours), and the link feeding it, if any."""

    name: str
    type: str
    value: object = 0.0
    link: Link | None = None


@dataclass(frozen=True)
class Node:
    """One node: `kind` is Blender's bl_idname (ShaderNodeMath, ...), `label` its name in the
    file (inside groups: "Group/Node"), `props` its settings as sorted (name, value) pairs of
    plain values (enum identifiers, numbers, tuples: a colour ramp's stops, a curve's samples,
    an image's index), `inputs` its input sockets, `outputs` (identifier, type) of its outputs."""

    kind: str
    label: str
    props: tuple = ()
    inputs: tuple = ()
    outputs: tuple = ()

    def prop(self, name: str, default=None):
        for key, value in self.props:
            if key == name:
                return value
        return default

    def input(self, name: str) -> Input | None:
        for socket in self.inputs:
            if socket.name == name:
                return socket
        return None


@dataclass(frozen=True)
class Graph:
    """Nodes, and the graph's outputs: (name, Input) pairs such as ("surface", ...) of a
    material's output node, each a constant or a link into the nodes."""

    nodes: tuple = ()
    outputs: tuple = field(default_factory=tuple)

    def output(self, name: str) -> Input | None:
        for key, socket in self.outputs:
            if key == name:
                return socket
        return None
