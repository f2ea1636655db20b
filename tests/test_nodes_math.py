"""Math node, every operation, against Cycles (tests/node_bake.py): inputs sweep [-3, 3] over
the plane (a from u, b from v, c a constant), so each operation meets negative, zero-crossing
and fractional arguments; division and logarithm by values near 0 included. Squeeze Value (Legacy), which Cycles
does not evaluate: what it feeds keeps its own value."""
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


def _squeezed(target: str):
    """Squeeze Value of varying inputs feeding a Math node's first input (its own value 0.25), or
    the Emission's Color (its own value (0.2, 0.4, 0.6))."""
    def build(nt):
        squeeze = nt.nodes.new("ShaderNodeSqueeze")
        nt.links.new(_sweep(nt, "X", -3.0, 3.0), squeeze.inputs["Value"])
        nt.links.new(_sweep(nt, "Y", 0.5, 4.0), squeeze.inputs["Width"])
        squeeze.inputs["Center"].default_value = 0.3
        if target == "color":
            nt.nodes["Emission"].inputs["Color"].default_value = (0.2, 0.4, 0.6, 1.0)
            return squeeze.outputs[0]
        m = nt.nodes.new("ShaderNodeMath")
        m.operation = "ADD"
        m.inputs[0].default_value, m.inputs[1].default_value = 0.25, 0.125
        nt.links.new(squeeze.outputs[0], m.inputs[0])
        return m.outputs[0]
    return build


def test_squeeze_value_is_dropped_as_in_cycles():
    results = node_bake.bake({target: _squeezed(target) for target in ("math", "color")}, size=8)
    for name, (cycles, ember) in results.items():
        assert node_bake.agreement(cycles, ember) == 1.0, name
    assert abs(results["math"][0] - 0.375).max() < 1e-6


def _emission_sign(shader: str, color: tuple, strength: float | None = None):
    """A shader's emission (Principled or the Emission node) routed to the Surface: its Strength
    swept over [-3, 3] along u and a constant colour, or with `strength` a constant Strength
    and the colour swept over [0, 3] along u."""
    def build(nt):
        out = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
        if shader == "principled":
            node = nt.nodes.new("ShaderNodeBsdfPrincipled")
            node.inputs["Base Color"].default_value = (0.0, 0.0, 0.0, 1.0)
            node.inputs["Specular IOR Level"].default_value = 0.0
            strength_in, color_in = node.inputs["Emission Strength"], node.inputs["Emission Color"]
        else:
            node = nt.nodes.new("ShaderNodeEmission")
            strength_in, color_in = node.inputs["Strength"], node.inputs["Color"]
        if strength is None:
            color_in.default_value = (*color, 1.0)
            nt.links.new(_sweep(nt, "X", -3.0, 3.0), strength_in)
        else:
            strength_in.default_value = strength
            nt.links.new(_sweep(nt, "X", 0.0, 3.0), color_in)
        nt.links.new(node.outputs[0], out.inputs["Surface"])
        return None
    return build


def test_negative_emission_strength_as_cycles():
    """Cycles' Principled BSDF emits nothing where its Emission Strength or Color is a constant
    not above the closure cutoff (a negative constant strength: tests/test_robustness.py), and
    as computed where they are linked, negative too; the Emission node likewise by its colour.
    Ember agrees on every texel of the sweep."""
    cases = {f"{shader}_{'neg' if color[0] < 0 else 'pos'}": _emission_sign(shader, color)
             for shader in ("principled", "emission") for color in ((1.0, 0.5, 0.25), (-1.0, -0.5, -0.25))}
    cases.update({f"{shader}_constant_negative_strength": _emission_sign(shader, (), -2.0)
                  for shader in ("principled", "emission")})
    results = node_bake.bake(cases)
    for name, (cycles, ember) in results.items():
        assert node_bake.agreement(cycles, ember) > 0.999, (name, cycles.min(), ember.min(), cycles.max(), ember.max())
    assert results["emission_pos"][0].min() < -1.0 and results["principled_pos"][0].min() < -1.0  # linked: as is
    assert not results["principled_neg"][0].any() and not results["emission_neg"][0].any()  # a constant colour <= 0
    assert not results["principled_constant_negative_strength"][0].any()  # ... or strength
    assert results["emission_constant_negative_strength"][0].min() < -1.0  # the Emission node emits it
