"""Bump (svm/displace.h svm_node_set_bump) and bump from the Material Output's displacement
(scene/shader_graph.cpp bump_from_displacement).

The node perturbs a normal by the gradient of its Height over the surface, taken by finite
differences: Height at the point (h_c) and at the point moved by filter_width times the ray
differential along two axes (h_x, h_y). The compiler evaluates the Height subgraph three times
for this (engine/nodes/program.py: the subgraph's nodes are copied, and the copies run on the
moved point, differentials.OffsetState) and hands the two extra values to the node as its
SampleX and SampleY inputs, Cycles' names for them. With a constant Height the node passes its
Normal input through (BumpNode::constant_fold). A Bump inside another's Height is not copied:
the outer offset evaluations read its normal as at the point (what Cycles' bake gives).

With dPdx, dPdy the differential's two axes (the compact dP along make_orthonormals(Ng)) and n
the input normal: Rx = dPdy x n, Ry = n x dPdx, det = dPdx . Rx, and the perturbed normal is
normalize(filter_width |det| n - distance sign(det) ((h_x - h_c) Rx + (h_y - h_c) Ry)) (Invert
negates the distance), blended with n by Strength.
"""
from __future__ import annotations

import numpy as np

from .base import column, node, scalar
from .differentials import from_compact
from .fresnel import normal_input
from .graph import Graph, Input, Link, Node
from .vector_math import dot, normalize, safe_normalize, transform_direction, transform_direction_transposed

KIND = "ShaderNodeBump"
SAMPLES = ("SampleX", "SampleY")  # the offset evaluations of Height, added by the compiler
DEFAULT_FILTER_WIDTH = 0.1  # Cycles' BumpNode default, used for bump from displacement


def filter_width(node, value=None) -> float:
    """The node's filter width: the value reaching its Filter Width socket where that is a
    constant (folded), else the socket's own value. Cycles reads it when compiling the Height
    copies, so a per-point Filter Width is not per point there either."""
    if value is not None and np.ndim(value) == 0:
        return float(value)
    socket = node.input("Filter Width")
    return float(socket.value) if socket is not None else DEFAULT_FILTER_WIDTH


def bump_normal(normal_in, h_c, h_x, h_y, dpdx, dpdy, width, distance, strength):
    """svm_node_set_bump's normal from the three Height samples (object-space handling aside)."""
    rx = np.cross(dpdy, normal_in)
    ry = np.cross(normal_in, dpdx)
    det = dot(dpdx, rx)
    surfgrad = column(scalar(h_x) - h_c) * rx + column(scalar(h_y) - h_c) * ry
    sign = np.where(det < 0.0, -1.0, 1.0)
    out = safe_normalize(width * column(np.abs(det)) * normal_in - column(distance * sign) * surfgrad)
    strength = column(np.maximum(strength, 0.0))
    mixed = normalize(strength * out + (1.0 - strength) * normal_in)
    return np.where(column(np.all(out == 0.0, axis=-1)), normal_in, mixed)


def _reads(node, outputs):
    socket = node.input("Normal")
    linked = socket is not None and socket.link is not None
    fields = ("Ng", "dP") + (() if linked else ("N",))
    return fields + (("world_from_object",) if node.prop("use_object_space", False) else ())


@node(KIND, "Vector", reads=_reads)
def bump(node, inputs, state):
    base = state.unshifted
    normal_in = np.broadcast_to(normal_input(node, inputs, base), (base.n, 3))
    if any(name not in inputs for name in SAMPLES):
        return {"Normal": normal_in}
    dpdx, dpdy = from_compact(base.Ng, base.dP)
    object_space = bool(node.prop("use_object_space", False))
    if object_space:  # in object space: the normal by M^T, the differentials by M^-1
        m = base.world_from_object
        inv = np.linalg.inv(m)
        normal_in = safe_normalize(transform_direction_transposed(m, normal_in))
        dpdx, dpdy = transform_direction(inv, dpdx), transform_direction(inv, dpdy)
    distance = scalar(inputs["Distance"]) * (-1.0 if node.prop("invert", False) else 1.0)
    out = bump_normal(normal_in, scalar(inputs["Height"]), inputs["SampleX"], inputs["SampleY"], dpdx, dpdy,
                      filter_width(node, inputs["Filter Width"]), distance, scalar(inputs["Strength"]))
    if object_space:
        out = normalize(transform_direction_transposed(np.linalg.inv(base.world_from_object), out))
    return {"Normal": out}


def bump_from_displacement(graph: Graph, object_space: bool = False, output: str = "displacement") -> Graph:
    """The graph with an output "normal": the shading normal Cycles' "Bump Only" displacement
    gives the surface, a Bump node (distance 1, filter width 0.1) over the height
    dot(displacement, N). The renderer evaluates it first and shades the surface with N set to
    it, as Cycles' set_normal does before the surface shader runs. object_space: Cycles' bump
    for "Displacement and Bump". The graph is unchanged where `output` is not linked."""
    socket = graph.output(output)
    if socket is None or socket.link is None:
        return graph
    nodes = list(graph.nodes)
    geometry = len(nodes)
    nodes.append(Node("ShaderNodeNewGeometry", "displacement bump/geometry", (),
                      (), (("Normal", "vector"),)))
    normal = Link(geometry, "Normal", "vector")
    dot_index = len(nodes)
    nodes.append(Node("ShaderNodeVectorMath", "displacement bump/dot", (("operation", "DOT_PRODUCT"),),
                      (Input("Vector", "vector", (0.0, 0.0, 0.0), socket.link),
                       Input("Vector_001", "vector", (0.0, 0.0, 0.0), normal),
                       Input("Vector_002", "vector", (0.0, 0.0, 0.0)), Input("Scale", "value", 1.0)),
                      (("Vector", "vector"), ("Value", "value"))))
    bump_index = len(nodes)
    props = (("invert", False), ("use_object_space", bool(object_space)))
    nodes.append(Node(KIND, "displacement bump/bump", props,
                      (Input("Strength", "value", 1.0), Input("Distance", "value", 1.0),
                       Input("Filter Width", "value", DEFAULT_FILTER_WIDTH),
                       Input("Height", "value", 0.0, Link(dot_index, "Value", "value")),
                       Input("Normal", "vector", (0.0, 0.0, 0.0), normal)),
                      (("Normal", "vector"),)))
    outputs = tuple((k, v) for k, v in graph.outputs if k != "normal")
    return Graph(tuple(nodes), outputs + (("normal", Input("normal", "vector", (0.0, 0.0, 0.0),
                                                           Link(bump_index, "Normal", "vector"))),))


NODES = (bump,)
