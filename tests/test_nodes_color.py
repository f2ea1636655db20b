"""Colour nodes against Cycles (tests/node_bake.py): Mix (every data type and blend mode),
Mix RGB, Colour Ramp, RGB/Vector/Float Curves, Hue/Saturation/Value, Invert, Gamma,
Bright/Contrast, RGB to BW, Separate/Combine Color, Blackbody, Wavelength, Light Falloff.

Inputs are affine functions of the plane's UV (a u + b v + c), so one case meets negative,
zero-crossing, > 1 and (for colours) every hue ordering of the channels; factors run outside
[0, 1] where the node does not clamp them.
"""
import numpy as np
import pytest

from ember.engine.blender.export_nodes import PROPS
from ember.engine.nodes import color as color_nodes
from ember.engine.nodes.curves import blender_curve, colorband
from ember.engine.nodes.color import BLENDS
from ember.engine.nodes.graph import Node

pytestmark = pytest.mark.blender

import node_bake  # noqa: E402


def _uv(nt):
    split = nt.nodes.get("uv_split")
    if split is None:
        coord = nt.nodes.new("ShaderNodeTexCoord")
        split = nt.nodes.new("ShaderNodeSeparateXYZ")
        split.name = "uv_split"
        nt.links.new(coord.outputs["UV"], split.inputs["Vector"])
    return split.outputs["X"], split.outputs["Y"]


def _affine(nt, a: float, b: float, c: float):
    """a u + b v + c over the plane."""
    u, v = _uv(nt)
    inner = nt.nodes.new("ShaderNodeMath")
    inner.operation = "MULTIPLY_ADD"
    nt.links.new(v, inner.inputs[0])
    inner.inputs[1].default_value, inner.inputs[2].default_value = b, c
    outer = nt.nodes.new("ShaderNodeMath")
    outer.operation = "MULTIPLY_ADD"
    nt.links.new(u, outer.inputs[0])
    outer.inputs[1].default_value = a
    nt.links.new(inner.outputs[0], outer.inputs[2])
    return outer.outputs[0]


def _triple(nt, rows):
    """A vector of three affine functions ((a, b, c) per component)."""
    comb = nt.nodes.new("ShaderNodeCombineXYZ")
    for k, row in enumerate(rows):
        nt.links.new(_affine(nt, *row), comb.inputs[k])
    return comb.outputs[0]


# Two colours crossing each other and 0 and 1 with every ordering of their channels.
COLOR_A = ((2.0, 0.0, -0.5), (0.0, 2.0, -0.5), (-1.2, 1.0, 0.9))
COLOR_B = ((0.0, -1.8, 1.4), (1.6, 0.3, -0.3), (1.1, -1.3, 0.6))
FACTOR_SWEEP = (1.0, 1.0, -0.5)  # -0.5 .. 1.5


def _in(node, identifier):
    """A node's input by identifier (the Mix node's sockets share their names)."""
    return next(s for s in node.inputs if s.identifier == identifier)


def _out(node, identifier):
    return next(s for s in node.outputs if s.identifier == identifier)


def _link(nt, node, name, value):
    """Set input `name` (identifier) to a constant or link it to a socket."""
    if isinstance(value, (int, float)):
        _in(node, name).default_value = value
    else:
        nt.links.new(value, _in(node, name))


def _check(cases):
    results = node_bake.bake(cases)
    assert len(results) == len(cases)
    scores = {name: node_bake.agreement(c, e) for name, (c, e) in results.items()}
    bad = {name: score for name, score in scores.items() if score < 0.999}
    assert bad == {}
    return results


# Mix -------------------------------------------------------------------------------------

def _mix_color(mode, factor, clamp_factor=True, clamp_result=False):
    def build(nt):
        m = nt.nodes.new("ShaderNodeMix")
        m.data_type, m.blend_type = "RGBA", mode
        m.clamp_factor, m.clamp_result = clamp_factor, clamp_result
        fac = factor if isinstance(factor, float) else _affine(nt, *factor)
        _link(nt, m, "Factor_Float", fac)
        nt.links.new(_triple(nt, COLOR_A), _in(m, "A_Color"))
        nt.links.new(_triple(nt, COLOR_B), _in(m, "B_Color"))
        return _out(m, "Result_Color")
    return build


def _mix_rgb(mode, clamp):
    def build(nt):
        m = nt.nodes.new("ShaderNodeMixRGB")
        m.blend_type, m.use_clamp = mode, clamp
        nt.links.new(_affine(nt, *FACTOR_SWEEP), _in(m, "Fac"))
        nt.links.new(_triple(nt, COLOR_A), _in(m, "Color1"))
        nt.links.new(_triple(nt, COLOR_B), _in(m, "Color2"))
        return _out(m, "Color")
    return build


def test_mix_color_every_blend_mode_matches_cycles():
    cases = {}
    for mode in BLENDS:
        cases[f"{mode}_fac0.35"] = _mix_color(mode, 0.35)
        cases[f"{mode}_sweep_unclamped"] = _mix_color(mode, FACTOR_SWEEP, clamp_factor=False)
        cases[f"{mode}_sweep_clamped_both"] = _mix_color(mode, FACTOR_SWEEP, True, True)
    assert len(BLENDS) == 19
    _check(cases)


def _mix_rgb_alpha(nt):
    """Use Alpha (Color2's alpha scaling the factor in Blender's own shaders) is ignored by Cycles."""
    m = nt.nodes.new("ShaderNodeMixRGB")
    m.use_alpha, m.blend_type = True, "MIX"
    m.inputs["Fac"].default_value = 0.8
    m.inputs["Color2"].default_value = (1.0, 0.5, 0.2, 0.25)
    nt.links.new(_triple(nt, COLOR_A), m.inputs["Color1"])
    return m.outputs["Color"]


def test_legacy_mix_rgb_matches_cycles():
    cases = {f"{mode}_{clamp}": _mix_rgb(mode, clamp) for mode in BLENDS for clamp in (False, True)}
    cases["use_alpha_ignored"] = _mix_rgb_alpha
    _check(cases)


def _mix_float(clamp_factor, clamp_result=False):
    def build(nt):
        m = nt.nodes.new("ShaderNodeMix")
        m.data_type, m.clamp_factor, m.clamp_result = "FLOAT", clamp_factor, clamp_result
        nt.links.new(_affine(nt, *FACTOR_SWEEP), _in(m, "Factor_Float"))
        nt.links.new(_affine(nt, 3.0, -1.0, -1.0), _in(m, "A_Float"))
        nt.links.new(_affine(nt, -2.0, 2.5, 0.5), _in(m, "B_Float"))
        return _out(m, "Result_Float")
    return build


def _mix_vector(mode, clamp_factor):
    def build(nt):
        m = nt.nodes.new("ShaderNodeMix")
        m.data_type, m.factor_mode, m.clamp_factor = "VECTOR", mode, clamp_factor
        if mode == "UNIFORM":
            nt.links.new(_affine(nt, *FACTOR_SWEEP), _in(m, "Factor_Float"))
        else:
            nt.links.new(_triple(nt, ((1.0, 1.0, -0.5), (-2.0, 0.5, 1.2), (0.3, 1.4, -0.2))), _in(m, "Factor_Vector"))
        nt.links.new(_triple(nt, COLOR_A), _in(m, "A_Vector"))
        nt.links.new(_triple(nt, COLOR_B), _in(m, "B_Vector"))
        return _out(m, "Result_Vector")
    return build


def test_mix_float_and_vector_match_cycles():
    cases = {f"float_{c}": _mix_float(c) for c in (False, True)}
    cases["float_clamp_result_ignored"] = _mix_float(False, True)
    cases.update({f"vector_{m}_{c}": _mix_vector(m, c) for m in ("UNIFORM", "NON_UNIFORM") for c in (False, True)})
    _check(cases)


# Colour Ramp -----------------------------------------------------------------------------

# Stops whose hues (0.01, 0.38, 0.65, 0.13) are nowhere half a turn apart, where Near and Far
# would be decided by float rounding.
RAMP_STOPS = ((0.12, (0.9, 0.1, 0.05, 1.0)), (0.35, (0.1, 0.8, 0.3, 0.2)), (0.62, (0.2, 0.3, 1.0, 0.7)),
              (0.88, (1.0, 0.8, 0.2, 0.4)))


def _ramp(interpolation, color_mode="RGB", hue="NEAR", output="Color"):
    def build(nt):
        n = nt.nodes.new("ShaderNodeValToRGB")
        ramp = n.color_ramp
        ramp.color_mode, ramp.interpolation = color_mode, interpolation
        if color_mode != "RGB":
            ramp.hue_interpolation = hue
        ramp.elements[0].position, ramp.elements[0].color = RAMP_STOPS[0]
        ramp.elements[1].position, ramp.elements[1].color = RAMP_STOPS[-1]
        for position, rgba in RAMP_STOPS[1:-1]:
            ramp.elements.new(position).color = rgba
        nt.links.new(_affine(nt, 1.1, 0.3, -0.2), n.inputs["Fac"])  # -0.2 .. 1.2
        return n.outputs[output]
    return build


def test_color_ramp_every_interpolation_and_colour_mode_matches_cycles():
    cases = {}
    for interpolation in ("CONSTANT", "LINEAR", "EASE", "B_SPLINE", "CARDINAL"):
        cases[f"{interpolation}_RGB"] = _ramp(interpolation)
        cases[f"{interpolation}_alpha"] = _ramp(interpolation, output="Alpha")
        for mode in ("HSV", "HSL"):
            for hue in ("NEAR", "FAR", "CW", "CCW"):
                cases[f"{interpolation}_{mode}_{hue}"] = _ramp(interpolation, mode, hue)
    _check(cases)


# Curves ----------------------------------------------------------------------------------

def _shape(curve, points, handles=("AUTO",)):
    """Replace a curve's points by `points` ((x, y), ...) with the given handle types."""
    while len(curve.points) > 2:
        curve.points.remove(curve.points[1])
    curve.points[0].location, curve.points[1].location = points[0], points[-1]
    for x, y in points[1:-1]:
        curve.points.new(x, y)
    for k, p in enumerate(curve.points):
        p.handle_type = handles[k % len(handles)]


def _rgb_curves(extend, fac=0.8):
    def build(nt):
        n = nt.nodes.new("ShaderNodeRGBCurve")
        m = n.mapping
        _shape(m.curves[3], ((0.0, 0.1), (0.4, 0.6), (1.0, 0.9)))
        _shape(m.curves[0], ((0.1, 0.0), (0.5, 0.8), (0.9, 1.0)), ("AUTO_CLAMPED",))
        _shape(m.curves[1], ((-0.2, 0.2), (0.3, 0.1), (0.7, 0.9), (1.2, 0.7)), ("VECTOR", "AUTO"))
        _shape(m.curves[2], ((0.0, 1.0), (1.0, 0.0)))
        m.extend = extend
        m.update()
        _link(nt, n, "Fac", fac if isinstance(fac, float) else _affine(nt, *fac))
        nt.links.new(_triple(nt, ((2.0, 0.0, -0.5), (0.0, 2.0, -0.5), (1.0, 1.0, -0.5))), n.inputs["Color"])
        return n.outputs["Color"]
    return build


def _vector_curves(extend):
    def build(nt):
        n = nt.nodes.new("ShaderNodeVectorCurve")
        m = n.mapping
        _shape(m.curves[0], ((-1.0, -0.5), (0.0, 0.4), (1.0, 1.0)))
        _shape(m.curves[1], ((-0.8, 1.0), (0.2, -0.6), (0.6, 0.2)), ("VECTOR",))
        _shape(m.curves[2], ((-1.0, 0.0), (1.0, 0.3)))
        m.extend = extend
        m.update()
        n.inputs["Fac"].default_value = 0.9
        nt.links.new(_triple(nt, ((3.0, 0.0, -1.5), (0.0, 3.0, -1.5), (-2.0, 1.0, 0.4))), n.inputs["Vector"])
        return n.outputs["Vector"]
    return build


def _float_curve(extend):
    def build(nt):
        n = nt.nodes.new("ShaderNodeFloatCurve")
        m = n.mapping
        _shape(m.curves[0], ((0.2, 0.3), (0.45, 0.9), (0.7, 0.2), (1.3, 0.6)), ("AUTO", "VECTOR"))
        m.extend = extend
        m.update()
        nt.links.new(_affine(nt, 0.0, 1.0, 0.0), n.inputs["Factor"])
        nt.links.new(_affine(nt, 2.0, 0.0, -0.3), n.inputs["Value"])
        return n.outputs["Value"]
    return build


def test_curves_match_cycles():
    cases = {}
    for extend in ("EXTRAPOLATED", "HORIZONTAL"):
        cases[f"rgb_{extend}"] = _rgb_curves(extend)
        cases[f"rgb_{extend}_fac_sweep"] = _rgb_curves(extend, FACTOR_SWEEP)
        cases[f"vector_{extend}"] = _vector_curves(extend)
        cases[f"float_{extend}"] = _float_curve(extend)
    _check(cases)


# Colour adjustments ----------------------------------------------------------------------

def _node(kind, output, **inputs):
    """A node of `kind` with inputs set: floats/tuples as constants, ("affine", a, b, c) and
    ("triple", rows) as UV functions."""
    def build(nt):
        n = nt.nodes.new(kind)
        for name, value in inputs.items():
            if isinstance(value, tuple) and value and value[0] == "affine":
                nt.links.new(_affine(nt, *value[1:]), n.inputs[name])
            elif isinstance(value, tuple) and value and value[0] == "triple":
                nt.links.new(_triple(nt, value[1]), n.inputs[name])
            else:
                n.inputs[name].default_value = value
        return n.outputs[output]
    return build


def _sweep(a, b, c):
    return ("affine", a, b, c)


A = ("triple", COLOR_A)
HUE_SAT_CASES = {
    "hue_sweep": dict(Hue=_sweep(1.5, 0.0, -0.25), Saturation=1.3, Value=1.1, Fac=1.0, Color=A),
    "sat_sweep": dict(Hue=0.6, Saturation=_sweep(0.0, 2.5, -0.2), Value=0.8, Fac=0.9, Color=A),
    "value_fac_sweep": dict(Hue=0.3, Saturation=0.7, Value=_sweep(2.0, 0.0, -0.3), Fac=_sweep(0.0, 1.4, -0.2), Color=A),
}


def test_colour_adjustments_match_cycles():
    cases = {f"hsv_{k}": _node("ShaderNodeHueSaturation", "Color", **v) for k, v in HUE_SAT_CASES.items()}
    cases["invert"] = _node("ShaderNodeInvert", "Color", Fac=_sweep(1.0, 1.0, -0.5), Color=A)
    cases["gamma_sweep"] = _node("ShaderNodeGamma", "Color", Color=A, Gamma=_sweep(0.0, 4.0, -1.0))
    cases["gamma_zero"] = _node("ShaderNodeGamma", "Color", Color=A, Gamma=0.0)
    ramps = ("triple", ((1.5, 0.0, 0.0), (0.0, 3.0, 0.01), (1.0, 1.0, -0.2)))
    cases["gamma_2.2"] = _node("ShaderNodeGamma", "Color", Color=ramps, Gamma=2.2)
    cases["bright_contrast"] = _node("ShaderNodeBrightContrast", "Color", Color=A, Bright=_sweep(1.0, 0.0, -0.5),
                                     Contrast=_sweep(0.0, 2.0, -1.0))
    cases["rgb_to_bw"] = _node("ShaderNodeRGBToBW", "Val", Color=A)
    _check(cases)


# HSL's saturation divides by cmax + cmin and by 2 - cmax - cmin: this colour keeps both at
# least 0.009 from 0 at every texel (float32 inputs would otherwise decide the digits there)
# while still crossing 0 and 1.
COLOR_HSL = ((1.7, 0.0, -0.45), (0.0, 1.7, -0.25), (-1.2, 1.0, 0.5))


def _separate(mode):
    def build(nt):
        n = nt.nodes.new("ShaderNodeSeparateColor")
        n.mode = mode
        nt.links.new(_triple(nt, COLOR_HSL if mode == "HSL" else COLOR_A), n.inputs["Color"])
        comb = nt.nodes.new("ShaderNodeCombineXYZ")
        for k, name in enumerate(("Red", "Green", "Blue")):
            nt.links.new(n.outputs[name], comb.inputs[k])
        return comb.outputs[0]
    return build


def _combine(mode):
    def build(nt):
        n = nt.nodes.new("ShaderNodeCombineColor")
        n.mode = mode
        nt.links.new(_affine(nt, 2.0, 0.0, -0.5), n.inputs["Red"])  # hue -0.5 .. 1.5
        nt.links.new(_affine(nt, 0.0, 1.4, -0.2), n.inputs["Green"])
        nt.links.new(_affine(nt, 0.5, 1.0, -0.1), n.inputs["Blue"])
        return n.outputs["Color"]
    return build


def test_separate_and_combine_color_match_cycles():
    cases = {f"separate_{m}": _separate(m) for m in ("RGB", "HSV", "HSL")}
    cases.update({f"combine_{m}": _combine(m) for m in ("RGB", "HSV", "HSL")})
    _check(cases)


def test_blackbody_and_wavelength_match_cycles():
    cases = {
        "blackbody_wide": _node("ShaderNodeBlackbody", "Color", Temperature=_sweep(12000.0, 600.0, 300.0)),
        "blackbody_low": _node("ShaderNodeBlackbody", "Color", Temperature=_sweep(700.0, 30.0, 700.0)),
        "blackbody_bands": _node("ShaderNodeBlackbody", "Color", Temperature=_sweep(6000.0, 400.0, 900.0)),
        "wavelength_wide": _node("ShaderNodeWavelength", "Color", Wavelength=_sweep(420.0, 20.0, 365.0)),
        "wavelength_ends": _node("ShaderNodeWavelength", "Color", Wavelength=_sweep(12.0, 0.5, 372.0)),
        "wavelength_red_end": _node("ShaderNodeWavelength", "Color", Wavelength=_sweep(20.0, 0.5, 770.0)),
    }
    _check(cases)


# Light Falloff ---------------------------------------------------------------------------
# Cycles' baker shoots its ray from P + N toward -N (kernel/integrator/init_from_bake.h), so
# every baked point has ray_length 1, as node_bake's state says: the bake checks the Strength
# and Smooth handling; the powers of the ray length are checked directly below.

def test_light_falloff_matches_cycles_at_the_bakes_ray_length():
    cases = {f"{out}_{k}": _node("ShaderNodeLightFalloff", out, Strength=_sweep(4.0, 0.0, -1.0), Smooth=smooth)
             for out in ("Quadratic", "Linear", "Constant") for k, smooth in
             enumerate((0.0, 0.7, _sweep(0.0, 3.0, -1.0)))}
    _check(cases)


def test_light_falloff_powers_of_ray_length():
    from ember.engine.nodes.state import ShadingState
    r = np.array([0.5, 2.0, 3.0, np.finfo(np.float32).max])
    state = ShadingState(len(r), ray_length=r)
    node = Node("ShaderNodeLightFalloff", "falloff")
    strength, smooth = np.float64(2.0), np.float64(0.5)
    out = color_nodes.light_falloff.evaluate(node, {"Strength": strength, "Smooth": smooth}, state)
    soft = r[:3] ** 2 / (0.5 + r[:3] ** 2)
    for name, power in (("Quadratic", 0), ("Linear", 1), ("Constant", 2)):
        value = out[name]()
        np.testing.assert_allclose(value[:3], 2.0 * r[:3] ** power * soft)
        assert value[3] == 2.0  # distant lights: Strength unchanged


# Constants -------------------------------------------------------------------------------
# Nodes whose inputs are all constant are evaluated once at compile time, on 0-d and (3,)
# values; a per-point factor between constant colours mixes the two shapes.

CONST_A, CONST_B = (0.8, 0.3, -0.2, 1.0), (0.2, 0.9, 0.5, 1.0)


def _mix_const(mode, factor):
    def build(nt):
        m = nt.nodes.new("ShaderNodeMix")
        m.data_type, m.blend_type, m.clamp_factor = "RGBA", mode, False
        _link(nt, m, "Factor_Float", factor if isinstance(factor, float) else _affine(nt, *factor))
        _in(m, "A_Color").default_value, _in(m, "B_Color").default_value = CONST_A, CONST_B
        return _out(m, "Result_Color")
    return build


def _const_curves(kind, output, **inputs):
    shaped = {"ShaderNodeRGBCurve": _rgb_curves("EXTRAPOLATED"), "ShaderNodeVectorCurve": _vector_curves("HORIZONTAL"),
              "ShaderNodeFloatCurve": _float_curve("EXTRAPOLATED")}[kind]

    def build(nt):
        out = shaped(nt)
        n = out.node
        for link in list(nt.links):
            if link.to_node == n:
                nt.links.remove(link)
        for name, value in inputs.items():
            n.inputs[name].default_value = value
        return n.outputs[output]
    return build


def _mix_data(kind, factor_mode="UNIFORM"):
    def build(nt):
        m = nt.nodes.new("ShaderNodeMix")
        m.data_type, m.factor_mode, m.clamp_factor = kind, factor_mode, False
        _in(m, "Factor_Float").default_value = 1.3
        _in(m, "Factor_Vector").default_value = (0.2, -0.4, 1.5)
        _in(m, "A_Float").default_value, _in(m, "B_Float").default_value = -0.4, 2.0
        _in(m, "A_Vector").default_value, _in(m, "B_Vector").default_value = (1.0, -2.0, 0.5), (0.0, 3.0, -1.0)
        return _out(m, {"FLOAT": "Result_Float", "VECTOR": "Result_Vector"}[kind])
    return build


def test_constant_inputs_match_cycles():
    cases = {f"mix_{mode}": _mix_const(mode, 0.6) for mode in BLENDS}
    cases.update({f"mix_{mode}_point_factor": _mix_const(mode, FACTOR_SWEEP) for mode in BLENDS})
    cases["mix_float"] = _mix_data("FLOAT")
    cases["mix_vector"] = _mix_data("VECTOR")
    cases["mix_vector_non_uniform"] = _mix_data("VECTOR", "NON_UNIFORM")
    for interpolation, mode, hue in _ramp_modes():
        for fac in (-0.1, 0.34, 0.6205, 0.95):  # 0.6205: just past a stop, before the table's step
            cases[f"ramp_{interpolation}_{mode}_{hue}_{fac}"] = _ramp_const(interpolation, mode, hue, fac)
    cases["rgb_curves"] = _const_curves("ShaderNodeRGBCurve", "Color", Fac=0.7, Color=(1.3, 0.4, -0.2, 1.0))
    cases["vector_curves"] = _const_curves("ShaderNodeVectorCurve", "Vector", Vector=(0.3, -0.7, 1.4))
    cases["float_curve"] = _const_curves("ShaderNodeFloatCurve", "Value", Factor=0.9, Value=1.6)
    cases["hue_saturation"] = _node("ShaderNodeHueSaturation", "Color", Hue=0.7, Saturation=1.4, Value=0.9, Fac=0.8,
                                    Color=CONST_A)
    cases["invert"] = _node("ShaderNodeInvert", "Color", Fac=0.3, Color=CONST_A)
    cases["gamma"] = _node("ShaderNodeGamma", "Color", Color=CONST_A, Gamma=1.7)
    cases["bright_contrast"] = _node("ShaderNodeBrightContrast", "Color", Color=CONST_A, Bright=0.1, Contrast=0.4)
    cases["rgb_to_bw"] = _node("ShaderNodeRGBToBW", "Val", Color=CONST_A)
    for kelvin in (799.0, 800.0, 965.0, 1167.0, 1449.0, 1902.0, 2700.0, 3315.0, 6365.0, 11999.0, 12000.0):
        cases[f"blackbody_{kelvin}"] = _node("ShaderNodeBlackbody", "Color", Temperature=kelvin)  # the fit's bands
    cases["wavelength"] = _node("ShaderNodeWavelength", "Color", Wavelength=555.0)
    cases["light_falloff"] = _node("ShaderNodeLightFalloff", "Linear", Strength=3.0, Smooth=0.4)
    for mode in ("RGB", "HSV", "HSL"):
        cases[f"combine_{mode}"] = _combine_const(mode)
        cases[f"separate_{mode}"] = _separate_const(mode)
    _check(cases)


def _ramp_const(interpolation, mode, hue, fac):
    shaped = _ramp(interpolation, mode, hue)

    def build(nt):
        n = shaped(nt).node
        for link in list(nt.links):
            if link.to_node == n:
                nt.links.remove(link)
        n.inputs["Fac"].default_value = fac
        return n.outputs["Color"]
    return build


def _combine_const(mode):
    def build(nt):
        n = nt.nodes.new("ShaderNodeCombineColor")
        n.mode = mode
        n.inputs[0].default_value, n.inputs[1].default_value, n.inputs[2].default_value = 0.7, 0.6, 0.4
        return n.outputs["Color"]
    return build


def _separate_const(mode):
    def build(nt):
        n = nt.nodes.new("ShaderNodeSeparateColor")
        n.mode = mode
        n.inputs["Color"].default_value = CONST_A
        comb = nt.nodes.new("ShaderNodeCombineXYZ")
        for k, name in enumerate(("Red", "Green", "Blue")):
            nt.links.new(n.outputs[name], comb.inputs[k])
        return comb.outputs[0]
    return build


# Blender's own evaluation, which folds constant inputs: Ember's against bpy's, point by point.

def _ramp_modes():
    for interpolation in ("CONSTANT", "LINEAR", "EASE", "B_SPLINE", "CARDINAL"):
        yield interpolation, "RGB", "NEAR"
    for mode in ("HSV", "HSL"):
        for hue in ("NEAR", "FAR", "CW", "CCW"):
            yield "LINEAR", mode, hue


def test_colorband_is_blenders_ramp_evaluation():
    import bpy
    nt = bpy.data.materials.new("colorband").node_tree
    x = np.concatenate([np.linspace(-0.3, 1.3, 1601), [p for p, _ in RAMP_STOPS]])
    for interpolation, mode, hue in _ramp_modes():
        for stops in (RAMP_STOPS, RAMP_STOPS[1:2], ((0.3, (0.2, 0.4, 0.9, 1.0)), (0.3, (0.9, 0.1, 0.2, 0.5)),
                                                    (0.7, (0.5, 0.5, 0.5, 1.0)))):
            build = _ramp(interpolation, mode, hue)
            n = build(nt).node
            ramp = n.color_ramp
            while len(ramp.elements) > len(stops):
                ramp.elements.remove(ramp.elements[-1])
            for e, (p, c) in zip(ramp.elements, stops):
                e.position, e.color = p, c
            expected = np.array([ramp.evaluate(float(v)) for v in x])
            got = colorband(dict(PROPS["color_ramp"](ramp, ())), x)
            np.testing.assert_allclose(got, expected, atol=2e-6, err_msg=f"{interpolation} {mode} {hue} {len(stops)}")


def test_curve_samples_are_blenders_curve_evaluation():
    import bpy
    nt = bpy.data.materials.new("curves").node_tree
    x = np.linspace(-3.0, 3.0, 2401)
    for build in (_rgb_curves("EXTRAPOLATED"), _rgb_curves("HORIZONTAL"), _vector_curves("EXTRAPOLATED"),
                  _vector_curves("HORIZONTAL"), _float_curve("EXTRAPOLATED"), _float_curve("HORIZONTAL")):
        mapping = build(nt).node.mapping
        exported = dict(PROPS["mapping"](mapping, ()))
        for curve, samples in zip(mapping.curves, exported["curves"]):
            expected = np.array([mapping.evaluate(curve, float(v)) for v in x])
            np.testing.assert_allclose(blender_curve(samples, x), expected, atol=2e-6)
