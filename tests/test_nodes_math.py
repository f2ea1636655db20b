"""Math node, every operation, against Cycles (tests/node_bake.py): inputs sweep [-3, 3] over
the plane (a from u, b from v, c a constant), so each operation meets negative, zero-crossing
and fractional arguments; division and logarithm by values near 0 included."""
import pytest

from ember.engine.nodes.math import OPERATIONS

pytestmark = pytest.mark.blender

import node_bake  # noqa: E402


def _sweep(nt, axis: str, lo: float, hi: float):
    coord = nt.nodes.new("ShaderNodeTexCoord")
    split = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(coord.outputs["UV"], split.inputs["Vector"])
    m = nt.nodes.new("ShaderNodeMath")
    m.operation = "MULTIPLY_ADD"
    nt.links.new(split.outputs[axis], m.inputs[0])
    m.inputs[1].default_value, m.inputs[2].default_value = hi - lo, lo
    return m.outputs[0]


def _case(operation: str, clamp: bool = False):
    def build(nt):
        m = nt.nodes.new("ShaderNodeMath")
        m.operation, m.use_clamp = operation, clamp
        nt.links.new(_sweep(nt, "X", -3.0, 3.0), m.inputs[0])
        nt.links.new(_sweep(nt, "Y", -3.0, 3.0), m.inputs[1])
        m.inputs[2].default_value = 0.7
        return m.outputs[0]
    return build


def test_every_math_operation_matches_cycles():
    cases = {op: _case(op) for op in OPERATIONS}
    cases["ADD_CLAMPED"] = _case("ADD", clamp=True)
    results = node_bake.bake(cases)
    bad = {name: node_bake.agreement(c, e) for name, (c, e) in results.items() if node_bake.agreement(c, e) < 0.999}
    assert bad == {}
    assert len(results) == len(OPERATIONS) + 1
