"""Node groups, reroutes and muted nodes against Cycles (tests/node_bake.py): Blender's own
node-group assets (datafiles/assets/nodes/shading_nodes_essentials.blend), groups nested two
deep with reroutes inside and a group input left at its default, muted nodes and muted links.
A grouped graph also gives exactly what the same nodes give laid out flat: the export leaves no
trace of the groups."""
import numpy as np
import pytest

pytestmark = pytest.mark.blender

import bpy  # noqa: E402

import node_bake  # noqa: E402

ASSETS = ("Separate Spherical", "Separate Cylindrical", "Combine Spherical", "Combine Cylindrical")


def _essentials():
    """The shading essentials' node groups, appended once per bake (a bake reads factory
    settings, which drops them)."""
    path = bpy.utils.resource_path("LOCAL") + "/datafiles/assets/nodes/shading_nodes_essentials.blend"
    missing = [name for name in ASSETS if name not in bpy.data.node_groups]
    if missing:
        with bpy.data.libraries.load(path) as (src, dst):
            dst.node_groups = [name for name in src.node_groups if name in missing]
    return bpy.data.node_groups


def _uv(nt):
    """(u, v) of the plane as two float sockets."""
    coord = nt.nodes.new("ShaderNodeTexCoord")
    split = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(coord.outputs["UV"], split.inputs["Vector"])
    return split.outputs["X"], split.outputs["Y"]


def _affine(nt, socket, a: float, b: float):
    m = nt.nodes.new("ShaderNodeMath")
    m.operation = "MULTIPLY_ADD"
    nt.links.new(socket, m.inputs[0])
    m.inputs[1].default_value, m.inputs[2].default_value = a, b
    return m.outputs[0]


def _combine(nt, x, y, z):
    c = nt.nodes.new("ShaderNodeCombineXYZ")
    for socket, value in zip(c.inputs, (x, y, z)):
        nt.links.new(value, socket)
    return c.outputs["Vector"]


def _asset_case(name: str):
    """A point (2u - 1, 2v - 1, u - v) through Separate, or (2u, 6v - 3, 3u) through Combine:
    every output over a sweep that crosses each axis."""
    def build(nt):
        node = nt.nodes.new("ShaderNodeGroup")
        node.node_tree = _essentials()[name]
        u, v = _uv(nt)
        if name.startswith("Separate"):
            diff = nt.nodes.new("ShaderNodeMath")
            diff.operation = "SUBTRACT"
            nt.links.new(u, diff.inputs[0])
            nt.links.new(v, diff.inputs[1])
            nt.links.new(_combine(nt, _affine(nt, u, 2.0, -1.0), _affine(nt, v, 2.0, -1.0), diff.outputs[0]),
                         node.inputs["Vector"])
            return _combine(nt, *node.outputs[:3])
        for socket, value in zip(node.inputs, (_affine(nt, u, 2.0, 0.0), _affine(nt, v, 6.0, -3.0),
                                               _affine(nt, u, 3.0, 0.0))):
            nt.links.new(value, socket)
        return node.outputs["Vector"]
    return build


def _inner_group():
    """Inner: Mix (Fac a x 2 through a reroute) of colour c and its inverse, output as a
    colour and the Fac as a float."""
    g = bpy.data.node_groups.get("inner") or bpy.data.node_groups.new("inner", "ShaderNodeTree")
    g.nodes.clear()
    g.interface.clear()
    g.interface.new_socket("A", in_out="INPUT", socket_type="NodeSocketFloat")
    g.interface.new_socket("C", in_out="INPUT", socket_type="NodeSocketColor")
    g.interface.new_socket("Color", in_out="OUTPUT", socket_type="NodeSocketColor")
    g.interface.new_socket("Fac", in_out="OUTPUT", socket_type="NodeSocketFloat")
    gi, go = g.nodes.new("NodeGroupInput"), g.nodes.new("NodeGroupOutput")
    double = g.nodes.new("ShaderNodeMath")
    double.operation = "MULTIPLY"
    double.inputs[1].default_value = 2.0
    g.links.new(gi.outputs["A"], double.inputs[0])
    reroute = g.nodes.new("NodeReroute")
    g.links.new(double.outputs[0], reroute.inputs[0])
    invert = g.nodes.new("ShaderNodeInvert")
    g.links.new(gi.outputs["C"], invert.inputs["Color"])
    mix = g.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    g.links.new(reroute.outputs[0], mix.inputs["Factor"])
    g.links.new(gi.outputs["C"], mix.inputs["A"])
    g.links.new(invert.outputs["Color"], mix.inputs["B"])
    g.links.new(mix.outputs["Result"], go.inputs["Color"])
    g.links.new(reroute.outputs[0], go.inputs["Fac"])
    return g


def _outer_group():
    """Outer: the inner group fed by its own inputs A and C (C left at the group node's default
    where the material does not link it), its Color hue-shifted by the inner Fac."""
    inner = _inner_group()
    g = bpy.data.node_groups.get("outer") or bpy.data.node_groups.new("outer", "ShaderNodeTree")
    g.nodes.clear()
    g.interface.clear()
    g.interface.new_socket("A", in_out="INPUT", socket_type="NodeSocketFloat")
    g.interface.new_socket("C", in_out="INPUT", socket_type="NodeSocketColor")
    g.interface.new_socket("Color", in_out="OUTPUT", socket_type="NodeSocketColor")
    gi, go = g.nodes.new("NodeGroupInput"), g.nodes.new("NodeGroupOutput")
    node = g.nodes.new("ShaderNodeGroup")
    node.node_tree = inner
    reroute = g.nodes.new("NodeReroute")
    g.links.new(gi.outputs["A"], reroute.inputs[0])
    g.links.new(reroute.outputs[0], node.inputs["A"])
    g.links.new(gi.outputs["C"], node.inputs["C"])
    hue = g.nodes.new("ShaderNodeHueSaturation")
    g.links.new(node.outputs["Fac"], hue.inputs["Hue"])
    g.links.new(node.outputs["Color"], hue.inputs["Color"])
    g.links.new(hue.outputs["Color"], go.inputs["Color"])
    return g


COLOUR = (0.7, 0.25, 0.1, 1.0)


def _nested(nt):
    node = nt.nodes.new("ShaderNodeGroup")
    node.node_tree = _outer_group()
    u, _ = _uv(nt)
    nt.links.new(u, node.inputs["A"])
    node.inputs["C"].default_value = COLOUR
    return node.outputs["Color"]


def _flat(nt):
    """The nested groups' nodes laid out in the material itself."""
    u, _ = _uv(nt)
    double = nt.nodes.new("ShaderNodeMath")
    double.operation = "MULTIPLY"
    double.inputs[1].default_value = 2.0
    nt.links.new(u, double.inputs[0])
    invert = nt.nodes.new("ShaderNodeInvert")
    invert.inputs["Color"].default_value = COLOUR
    mix = nt.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    nt.links.new(double.outputs[0], mix.inputs["Factor"])
    mix.inputs["A"].default_value = COLOUR
    nt.links.new(invert.outputs["Color"], mix.inputs["B"])
    hue = nt.nodes.new("ShaderNodeHueSaturation")
    nt.links.new(double.outputs[0], hue.inputs["Hue"])
    nt.links.new(mix.outputs["Result"], hue.inputs["Color"])
    return hue.outputs["Color"]


def _muted_math(nt):
    """A muted Math passes its first input (Blender's internal link)."""
    u, v = _uv(nt)
    m = nt.nodes.new("ShaderNodeMath")
    m.operation = "ADD"
    nt.links.new(v, m.inputs[0])
    nt.links.new(u, m.inputs[1])
    m.mute = True
    return _combine(nt, m.outputs[0], u, v)


def _muted_mix(nt):
    """A muted colour Mix passes its A."""
    u, v = _uv(nt)
    mix = nt.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    nt.links.new(u, mix.inputs["Factor"])
    nt.links.new(_combine(nt, v, u, v), mix.inputs["A"])
    mix.inputs["B"].default_value = (1.0, 0.0, 0.0, 1.0)
    mix.mute = True
    return mix.outputs["Result"]


def _muted_texture(nt):
    """A muted Noise Texture: its Color passes nothing (no input of its type), its Fac what
    the internal link gives."""
    u, v = _uv(nt)
    noise = nt.nodes.new("ShaderNodeTexNoise")
    nt.links.new(_combine(nt, u, v, u), noise.inputs["Vector"])
    noise.mute = True
    return _combine(nt, noise.outputs["Fac"], noise.outputs["Color"], v)


def _muted_link(nt):
    """A muted link: the input reads its own default value."""
    u, v = _uv(nt)
    m = nt.nodes.new("ShaderNodeMath")
    m.operation = "ADD"
    m.inputs[0].default_value = 0.25
    link = nt.links.new(u, m.inputs[0])
    link.is_muted = True
    nt.links.new(v, m.inputs[1])
    return _combine(nt, m.outputs[0], v, u)


def _converting(nt):
    """A group whose colour input, left at the group node's constant, feeds a float socket
    inside: Blender's colour-to-float conversion (the luminance) applies as for a link."""
    g = bpy.data.node_groups.get("converting") or bpy.data.node_groups.new("converting", "ShaderNodeTree")
    g.nodes.clear()
    g.interface.clear()
    g.interface.new_socket("C", in_out="INPUT", socket_type="NodeSocketColor")
    g.interface.new_socket("A", in_out="INPUT", socket_type="NodeSocketFloat")
    g.interface.new_socket("F", in_out="OUTPUT", socket_type="NodeSocketFloat")
    gi, go = g.nodes.new("NodeGroupInput"), g.nodes.new("NodeGroupOutput")
    add = g.nodes.new("ShaderNodeMath")
    add.operation = "ADD"
    g.links.new(gi.outputs["C"], add.inputs[0])
    g.links.new(gi.outputs["A"], add.inputs[1])
    g.links.new(add.outputs[0], go.inputs["F"])
    node = nt.nodes.new("ShaderNodeGroup")
    node.node_tree = g
    node.inputs["C"].default_value = COLOUR
    u, v = _uv(nt)
    nt.links.new(u, node.inputs["A"])
    return _combine(nt, node.outputs["F"], u, v)


CASES = {**{name: _asset_case(name) for name in ASSETS}, "nested": _nested, "flat": _flat,
         "muted_math": _muted_math, "muted_mix": _muted_mix, "muted_texture": _muted_texture,
         "muted_link": _muted_link, "converting": _converting}


@pytest.fixture(scope="module")
def results():
    return node_bake.bake(CASES)


@pytest.mark.parametrize("name", list(CASES))
def test_groups_reroutes_and_muting_match_cycles(results, name):
    cycles, ember = results[name]
    assert np.abs(cycles).max() > 0.05  # the case baked something
    assert node_bake.agreement(cycles, ember) >= 0.999


def test_nested_groups_give_exactly_the_flat_graph(results):
    np.testing.assert_array_equal(results["nested"][1], results["flat"][1])
    assert np.ptp(results["flat"][1]) > 0.1
