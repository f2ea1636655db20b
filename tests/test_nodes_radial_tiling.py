"""Radial Tiling against Cycles (tests/node_bake.py): every output, with and without Normalize,
over whole and fractional numbers of sides (below 2, exactly 2, odd, even), roundness at 0, 1,
between and outside [0, 1], at the points of [-2, 2]^2 (the origin and the axes included: the
grid is offset from them by the bake's nudge), and with Sides and Roundness varying over the
plane, so that neighbouring points take different parts of the kernel.

Two sides (or fewer) with a roundness strictly between 0 and 1 are left out: a 2-gon's corner
arcs start at tan(pi/2), and Cycles' values there are its float32 rounding (widths of -5e6)."""
import itertools

import pytest

pytestmark = pytest.mark.blender

import node_bake  # noqa: E402

SIDES = (1.5, 2.0, 3.0, 6.0, 2.4, 4.5, 7.7)
ROUNDNESS = (0.0, 0.35, 0.8, 1.0, -0.5, 1.5)


def _coordinate(nt):
    """(4 u - 2, 4 v - 2, 0): the plane's UV over [-2, 2]^2."""
    coord = nt.nodes.new("ShaderNodeTexCoord")
    m = nt.nodes.new("ShaderNodeVectorMath")
    m.operation = "MULTIPLY_ADD"
    nt.links.new(coord.outputs["UV"], m.inputs[0])
    m.inputs[1].default_value, m.inputs[2].default_value = (4.0, 4.0, 0.0), (-2.0, -2.0, 0.0)
    return m.outputs[0]


def _field(nt, axis: str, lo: float, hi: float):
    """lo + (hi - lo) * u (or v) over the plane."""
    coord = nt.nodes.new("ShaderNodeTexCoord")
    split = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(coord.outputs["UV"], split.inputs[0])
    m = nt.nodes.new("ShaderNodeMath")
    m.operation = "MULTIPLY_ADD"
    nt.links.new(split.outputs[axis], m.inputs[0])
    m.inputs[1].default_value, m.inputs[2].default_value = hi - lo, lo
    return m.outputs[0]


def _case(sides, roundness, normalize: bool, outputs: str):
    """The node's outputs as one colour: "coords" its Segment Coordinates (x, y) and Segment
    Width, "ids" its Segment ID, Segment Rotation and Width again. Sides or roundness given as
    (lo, hi) vary over the plane (sides along v, roundness along u)."""
    def build(nt):
        n = nt.nodes.new("ShaderNodeRadialTiling")
        n.normalize = normalize
        nt.links.new(_coordinate(nt), n.inputs["Vector"])
        for socket, value, axis in (("Sides", sides, "Y"), ("Roundness", roundness, "X")):
            if isinstance(value, tuple):
                nt.links.new(_field(nt, axis, *value), n.inputs[socket])
            else:
                n.inputs[socket].default_value = value
        combine = nt.nodes.new("ShaderNodeCombineXYZ")
        if outputs == "coords":
            split = nt.nodes.new("ShaderNodeSeparateXYZ")
            nt.links.new(n.outputs["Segment Coordinates"], split.inputs[0])
            nt.links.new(split.outputs["X"], combine.inputs[0])
            nt.links.new(split.outputs["Y"], combine.inputs[1])
        else:
            nt.links.new(n.outputs["Segment ID"], combine.inputs[0])
            nt.links.new(n.outputs["Segment Rotation"], combine.inputs[1])
        nt.links.new(n.outputs["Segment Width"], combine.inputs[2])
        return combine.outputs[0]
    return build


def _cases():
    cases = {}
    for sides, roundness, normalize, outputs in itertools.product(SIDES, ROUNDNESS, (False, True), ("coords", "ids")):
        if sides <= 2.0 and 0.0 < roundness < 1.0:
            continue
        cases[f"{sides}-{roundness}-{normalize}-{outputs}"] = _case(sides, roundness, normalize, outputs)
    for normalize, outputs in itertools.product((False, True), ("coords", "ids")):
        cases[f"varying-{normalize}-{outputs}"] = _case((2.2, 9.0), (-0.2, 1.2), normalize, outputs)
    return cases


def test_radial_tiling_matches_cycles():
    cases = _cases()
    results = node_bake.bake(cases, columns=16)
    agreement = {name: node_bake.agreement(c, e) for name, (c, e) in results.items()}
    assert {name: a for name, a in agreement.items() if a < 0.999} == {}
    assert len(results) == len(cases)
