"""A bpy node tree -> engine.nodes.graph.Graph: flat, plain data the core compiles.

Walks back from the requested output sockets, so only what reaches them is exported, and
resolves on the way what Blender's own evaluation resolves: reroutes; muted links (the input
reads its own value, as unlinked) and muted nodes (each output passes the input Blender's internal links give it, else
its type's zero); node groups at any depth (a group's output is the inner Group Output's input,
an inner Group Input's output the group node's input outside), so the core never sees a group.
A node's settings become plain props: every enum, number, boolean, string and vector property
it adds to a plain ShaderNode, and what its datablock pointers hold (`PROPS` exporters:
colour ramps, curves, images, objects, texture mappings).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import bpy
import numpy as np

from ..nodes.base import convert
from ..nodes.graph import Graph, Input, Link, Node
from .export_attributes import view_layer_attribute
from .export_image import image_texels

_GROUP_KINDS = {"ShaderNodeGroup", "NodeGroup"}
_BASE_PROPS = None  # the properties every ShaderNode has (name, location, ...): not settings
_PLAIN = {"ENUM", "BOOLEAN", "INT", "FLOAT", "STRING"}
MAX_DEPTH = 256  # reroutes and group levels followed from one socket


def socket_type(socket) -> str:
    return str(socket.type).lower()


def socket_value(socket):
    """A socket's own value as plain data: float, or a tuple of 3 (colours lose alpha)."""
    value = getattr(socket, "default_value", None)
    if value is None:
        return 0.0
    try:
        values = tuple(float(v) for v in value)
    except TypeError:
        return float(value) if isinstance(value, (int, float, bool)) else 0.0
    return values[:3] if len(values) >= 3 else values


def _base_props() -> set:
    global _BASE_PROPS
    if _BASE_PROPS is None:
        _BASE_PROPS = {p.identifier for p in bpy.types.ShaderNode.bl_rna.properties}
    return _BASE_PROPS


@dataclass(frozen=True)
class PropContext:
    """What a PROPS exporter may need beyond the pointer's value: the bpy node holding it (an
    image's ImageUser), the group nodes it sits in, and warn(text) for what it cannot export."""

    node: object
    path: tuple
    warn: Callable


def _props(node, context) -> tuple:
    out = {}
    for prop in node.bl_rna.properties:
        key = prop.identifier
        if key in _base_props() or key in ("node_tree",):
            continue
        if prop.type in _PLAIN:
            value = getattr(node, key)
            if prop.type == "FLOAT" and getattr(prop, "array_length", 0):
                value = tuple(float(v) for v in value)
            elif prop.type == "ENUM" and getattr(prop, "is_enum_flag", False):
                value = tuple(sorted(value))
            out[key] = value
        elif prop.type == "POINTER" and key in PROPS:
            out[key] = PROPS[key](getattr(node, key), context)
    if node.bl_idname == "ShaderNodeValue":
        out["value"] = float(node.outputs[0].default_value)
    elif node.bl_idname == "ShaderNodeRGB":
        out["color"] = socket_value(node.outputs[0])
    elif node.bl_idname == "ShaderNodeNormal":  # its direction is its output's own value
        out["direction"] = socket_value(node.outputs[0])
    return tuple(sorted(out.items()))


# Cycles' ramp and curve tables: the kernel interpolates these samples, not the ramp or curve
# itself (engine/nodes/curves.py). Cycles' RAMP_TABLE_SIZE is 256, and its sync samples one
# more: 257 entries at i / 256 (inferred from the bake: a Constant ramp's steps fall at
# multiples of 1/256 wherever its stops are).
RAMP_TABLE_SIZE = 257


def _color_ramp(ramp, context):
    """The ramp's settings and stops, and `table`: RGBA at RAMP_TABLE_SIZE even positions over
    [0, 1] from Blender's own evaluation, as Cycles' sync samples it."""
    positions = np.arange(RAMP_TABLE_SIZE, dtype=np.float32) / np.float32(RAMP_TABLE_SIZE - 1)
    return (("interpolation", ramp.interpolation), ("color_mode", ramp.color_mode),
            ("hue_interpolation", ramp.hue_interpolation),
            ("elements", tuple((float(e.position), tuple(float(c) for c in e.color)) for e in ramp.elements)),
            ("table", tuple(tuple(float(c) for c in ramp.evaluate(float(x))) for x in positions)))


def _curve_mapping(mapping, context):
    """A curve mapping as Cycles' sync tables it (intern/cycles/blender/util.h
    curvemapping_*_to_array): `range` (min_x, max_x) from the first and last point of each
    curve, `table` each curve evaluated at RAMP_TABLE_SIZE even positions over that range (4
    curves, RGB Curves: R, G and B applied after the combined curve C; 3, Vector Curves: X, Y,
    Z; 1, Float Curve: a single column), `extrapolate` whether the ends extend linearly."""
    curves = list(mapping.curves)
    lo = min(float(c.points[0].location[0]) for c in curves)
    hi = max(float(c.points[-1].location[0]) for c in curves)
    mapping.update()
    step = np.arange(RAMP_TABLE_SIZE, dtype=np.float32) / np.float32(RAMP_TABLE_SIZE - 1)
    xs = (np.float32(lo) + step * (np.float32(hi) - np.float32(lo))).astype(np.float32)
    if len(curves) == 4:
        rows = []
        for x in xs:
            c = mapping.evaluate(curves[3], float(x))
            rows.append(tuple(float(mapping.evaluate(curves[k], c)) for k in range(3)))
    else:
        rows = [tuple(float(mapping.evaluate(curve, float(x))) for curve in curves) for x in xs]
    return (("extrapolate", mapping.extend == "EXTRAPOLATED"), ("range", (lo, hi)), ("table", tuple(rows)),
            ("curves", tuple(_curve_samples(mapping, curve) for curve in curves)))


def _curve_samples(mapping, curve):
    """One curve as Blender evaluates it (BKE_curvemap_evaluateF), for constant inputs, which
    Blender folds with its own evaluation: linear between its CM_TABLE + 1 = 257 table knots,
    evenly spaced over the clipping range widened to the points, and a line beyond each end
    (the extrapolated slope, or flat). Returns (x0, x1, knot values, (a, b) below x0,
    (a, b) above x1), a line being a + b x, fitted through two evaluations past the end."""
    x0 = min(float(mapping.clip_min_x), float(curve.points[0].location[0]))
    x1 = max(float(mapping.clip_max_x), float(curve.points[-1].location[0]))
    xs = np.float32(x0) + np.arange(257, dtype=np.float32) * np.float32((x1 - x0) / 256.0)
    knots = tuple(float(mapping.evaluate(curve, float(x))) for x in xs)

    def line(xa, xb):
        ya, yb = mapping.evaluate(curve, xa), mapping.evaluate(curve, xb)
        slope = (yb - ya) / (xb - xa)
        return (ya - slope * xa, slope)
    return (x0, x1, knots, line(x0 - 2.0, x0 - 1.0), line(x1 + 1.0, x1 + 2.0))


def _object(ob, context):
    """An object's world_from_object matrix as 16 row-major floats (None: no object)."""
    if ob is None:
        return None
    return tuple(float(v) for row in ob.matrix_world for v in row)


def _texture_mapping(mapping, context):
    """A texture node's TexMapping as Cycles syncs it (type, translation, rotation, scale, axis
    mapping: engine/nodes/texture_mapping.py), None where Cycles skips it as the identity."""
    if mapping is None:
        return None
    t, r, s = (tuple(float(v) for v in x) for x in (mapping.translation, mapping.rotation, mapping.scale))
    axes = (mapping.mapping_x, mapping.mapping_y, mapping.mapping_z)
    if t == (0.0, 0.0, 0.0) and r == (0.0, 0.0, 0.0) and s == (1.0, 1.0, 1.0) and axes == ("X", "Y", "Z"):
        return None
    return (mapping.vector_type, t, r, s, axes)


def _ies_text(text, context):
    """An IES Texture's profile as text (engine/nodes/ies.py parses it): its Text datablock, or
    in External mode its file, as Cycles' sync reads them; None where there is none."""
    node = context.node
    if getattr(node, "mode", "INTERNAL") == "EXTERNAL":
        path = bpy.path.abspath(node.filepath)
        try:
            with open(path, encoding="utf-8", errors="replace") as f:
                return f.read()
        except OSError:
            context.warn(f"{node.name}: IES file '{path}' cannot be read")
            return None
    return text.as_string() if text is not None else None


# Pointer properties by name -> exporter(value, PropContext) of plain data.
PROPS = {"color_ramp": _color_ramp, "image": image_texels, "mapping": _curve_mapping, "object": _object,
         "texture_mapping": _texture_mapping, "ies": _ies_text}


class _Export:
    def __init__(self, warn=None):
        self.nodes: list[Node] = []
        self.index: dict = {}  # (group path, node name) -> index in self.nodes
        self.warn = warn or (lambda text: None)

    def source(self, socket, path: tuple, depth: int = 0) -> Input:
        """The value arriving at input `socket` (inside groups `path`, a tuple of group nodes)."""
        me = Input(socket.identifier, socket_type(socket), socket_value(socket))
        if depth > MAX_DEPTH:
            self.warn(f"node links nest deeper than {MAX_DEPTH} levels at '{socket.node.name}'")
            return me
        links = [l for l in socket.links if not getattr(l, "is_muted", False) and getattr(l, "is_valid", True)]
        if not links:  # unlinked, or its links muted or invalid
            return me
        return self.output(links[0].from_socket, path, me, depth + 1)

    def output(self, out, path: tuple, into: Input, depth: int) -> Input:
        """The value of output socket `out` as seen by input `into`."""
        node = out.node
        if node.bl_idname == "NodeReroute":
            return _arriving(into, self.source(node.inputs[0], path, depth))
        if node.mute:
            for link in node.internal_links:
                if link.to_socket == out:
                    inner = self.source(link.from_socket, path, depth)
                    return _arriving(into, inner)
            return Input(into.name, into.type, _zero(into.type))
        if node.bl_idname in _GROUP_KINDS:
            tree = node.node_tree
            inner_out = _group_output(tree) if tree is not None else None
            if inner_out is None:
                return Input(into.name, into.type, _zero(into.type))
            socket = next((s for s in inner_out.inputs if s.identifier == out.identifier), None)
            if socket is None:
                return Input(into.name, into.type, _zero(into.type))
            inner = self.source(socket, path + (node,), depth)
            return _arriving(into, inner)
        if node.bl_idname == "NodeGroupInput":
            if not path:
                return Input(into.name, into.type, _zero(into.type))
            group = path[-1]
            socket = next((s for s in group.inputs if s.identifier == out.identifier), None)
            if socket is None:
                return Input(into.name, into.type, _zero(into.type))
            inner = self.source(socket, path[:-1], depth)
            return _arriving(into, inner)
        if node.bl_idname == "ShaderNodeAttribute" and node.attribute_type == "VIEW_LAYER":
            return Input(into.name, into.type, _view_layer_value(node, out, into.type))
        i = self.add(node, path, depth)
        return Input(into.name, into.type, into.value, Link(i, out.identifier, socket_type(out)))

    def add(self, node, path: tuple, depth: int) -> int:
        key = (tuple(g.name for g in path), node.name)
        if key in self.index:
            return self.index[key]
        self.index[key] = -1  # a cycle would come back here: Blender's trees have none
        inputs = tuple(self.source(s, path, depth) for s in node.inputs)
        label = "/".join(key[0] + (node.name,))
        outputs = tuple((s.identifier, socket_type(s)) for s in node.outputs)
        props = _props(node, PropContext(node, path, self.warn))
        self.nodes.append(Node(node.bl_idname, label, props, inputs, outputs))
        self.index[key] = len(self.nodes) - 1
        return self.index[key]


def _arriving(into: Input, inner: Input) -> Input:
    """What arrives at input `into` through a reroute, muted node or group socket: inner's link,
    or its constant converted to into's type."""
    if inner.link:
        return Input(into.name, into.type, inner.value, inner.link)
    return Input(into.name, into.type, _convert_const(inner.value, inner.type, into.type))


def _view_layer_value(node, out, into_type: str):
    """A View Layer attribute as the constant Cycles folds into the graph (blender/shader.cpp
    resolve_view_layer_attributes): Alpha its w, Fac the average of x, y, z, Color and Vector
    (x, y, z); converted to the socket it feeds as any link is (Cycles' conversion nodes)."""
    x, y, z, w = view_layer_attribute(bpy.context.scene, bpy.context.view_layer, node.attribute_name)
    if out.identifier == "Alpha":
        value = w
    elif socket_type(out) == "value":
        value = (x + y + z) / 3.0
    else:
        value = (x, y, z)
    return _convert_const(value, socket_type(out), into_type)


def _group_output(tree):
    outs = [n for n in tree.nodes if n.bl_idname == "NodeGroupOutput"]
    return next((n for n in outs if getattr(n, "is_active_output", False)), outs[0] if outs else None)


def _zero(kind: str):
    return (0.0, 0.0, 0.0) if kind in ("vector", "rgba") else 0.0


def _convert_const(value, src: str, dst: str):
    """A constant passed through a muted node or a group socket of another type (the core
    converts linked values; constants are converted here, as plain data)."""
    out = convert(value, src, dst)
    try:
        return tuple(float(v) for v in out)
    except TypeError:
        return float(out)


def export_graph(sockets: dict, warn=None) -> Graph:
    """Graph of the bpy input sockets `sockets` {output name: socket} (e.g. {"surface": the
    Material Output's Surface input}); warn(text) hears what could not be followed."""
    ex = _Export(warn)
    outputs = tuple((name, ex.source(socket, ())) for name, socket in sockets.items() if socket is not None)
    return Graph(tuple(ex.nodes), outputs)
