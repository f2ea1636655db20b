"""Vector and utility nodes against Cycles (tests/node_bake.py): Vector Math (every operation),
Map Range (Float and Vector, every interpolation, clamped or not), Clamp, Mapping, Vector
Rotate, Vector Transform, Normal, Texture Coordinate.

Inputs are affine fields of the plane's UV, a*u + b*v + c per component (`_field`), chosen so
each mode meets negative, zero-crossing and fractional values, both signs of the dot products
it branches on, and the guards (empty ranges, zero axes and scales, total internal reflection)
at constant inputs. Nodes that read the object's or the camera's frame bake on planes moved,
turned and scaled (node_bake.Placed), and with rays from the camera (view_from)."""
import itertools

import numpy as np
import pytest

from ember.engine.nodes.vector_math import VALUE_OPERATIONS, VECTOR_OPERATIONS

pytestmark = pytest.mark.blender

import node_bake  # noqa: E402
from node_bake import Placed  # noqa: E402

# An object transform with rotation about every axis, non-uniform scale and an offset.
TURNED = dict(location=(0.3, 0.5, -0.4), rotation=(0.4, -0.7, 1.1), scale=(1.3, 0.6, 0.9))


def _uv(nt):
    """The Separate XYZ of the UV, one per material."""
    split = nt.nodes.get("uv")
    if split is None:
        coord = nt.nodes.new("ShaderNodeTexCoord")
        split = nt.nodes.new("ShaderNodeSeparateXYZ")
        split.name = "uv"
        nt.links.new(coord.outputs["UV"], split.inputs["Vector"])
    return split


def _scalar(nt, a: float, b: float, c: float):
    """The output socket of a*u + b*v + c over the plane."""
    split = _uv(nt)
    au = nt.nodes.new("ShaderNodeMath")
    au.operation = "MULTIPLY_ADD"
    nt.links.new(split.outputs["X"], au.inputs[0])
    au.inputs[1].default_value, au.inputs[2].default_value = a, c
    bv = nt.nodes.new("ShaderNodeMath")
    bv.operation = "MULTIPLY_ADD"
    nt.links.new(split.outputs["Y"], bv.inputs[0])
    bv.inputs[1].default_value = b
    nt.links.new(au.outputs[0], bv.inputs[2])
    return bv.outputs[0]


def _field(nt, *rows):
    """A vector of three components a*u + b*v + c, one (a, b, c) row each."""
    combine = nt.nodes.new("ShaderNodeCombineXYZ")
    for i, row in enumerate(rows):
        nt.links.new(_scalar(nt, *row), combine.inputs[i])
    return combine.outputs[0]


def _set(nt, socket, value):
    """An input: a constant (number or triple) or a field spec (a tuple of (a, b, c) rows,
    one row for a scalar socket)."""
    if isinstance(value, tuple) and value and isinstance(value[0], tuple):
        src = _field(nt, *value) if len(value) == 3 else _scalar(nt, *value[0])
        nt.links.new(src, socket)
    else:
        socket.default_value = value


def _node(kind: str, output: str, props: dict, inputs: dict):
    """A case: a node of `kind` with `props`, inputs by identifier, its output `output`."""
    def build(nt):
        n = nt.nodes.new(kind)
        for key, value in props.items():
            setattr(n, key, value)
        for key, value in inputs.items():
            _set(nt, next(s for s in n.inputs if s.identifier == key), value)
        return next(s for s in n.outputs if s.identifier == output)
    return build


def _check(results: dict, count: int):
    agreement = {name: node_bake.agreement(c, e) for name, (c, e) in results.items()}
    assert {name: a for name, a in agreement.items() if a < 0.999} == {}
    assert len(results) == count


# Vector fields over [-3, 3], each component along another direction of the plane.
A = ((6.0, 0.0, -3.0), (0.0, 6.0, -3.0), (3.0, 3.0, -3.0))
B = ((0.0, -5.0, 2.2), (4.0, 1.0, -2.4), (-3.0, 4.0, -0.3))
C = ((2.0, 2.0, -1.7), (-4.0, 1.0, 1.3), (1.0, -5.0, 2.1))

# Operation -> inputs beyond A and B where the defaults would miss what it does.
_VECTOR_MATH_INPUTS = {
    "MULTIPLY_ADD": {"Vector_002": C},
    "FACEFORWARD": {"Vector_002": C},
    "WRAP": {"Vector_001": ((1.0, 2.0, 0.5), (0.0, 3.0, 1.0), (2.0, 0.0, 0.7)),
             "Vector_002": ((-1.0, 0.0, -0.4), (1.0, -1.0, -0.6), (0.0, 0.0, -1.0))},
    "SCALE": {"Scale": ((3.0, -2.0, -0.4),)},
    # Unit-ish incident directions against a normal whose tilt changes; eta across 1 gives
    # total internal reflection on part of the plane.
    "REFRACT": {"Vector": ((1.6, 0.0, -0.8), (0.0, 1.2, -0.3), (0.0, 0.0, -0.7)),
                "Vector_001": ((0.0, 0.0, 0.2), (0.0, 0.0, -0.1), (0.0, 0.0, 1.0)),
                "Scale": ((0.0, 1.5, 0.5),)},
    # Bases cross 0 between texels: a base of 1e-4 in float32 is too rough for 1e-4 agreement.
    "POWER": {"Vector": ((4.0, 0.0, -2.0), (0.0, 4.0, -2.0), (2.0, 2.0, -1.1)),
              "Vector_001": ((0.0, 6.0, -3.0), (3.0, 0.0, -1.5), (2.0, -2.0, 0.5))},
}


def _vector_math_cases():
    cases = {}
    for op in list(VECTOR_OPERATIONS) + list(VALUE_OPERATIONS):
        inputs = {"Vector": A, "Vector_001": B, "Vector_002": (0.0, 0.0, 0.0), "Scale": 1.0}
        inputs.update(_VECTOR_MATH_INPUTS.get(op, {}))
        output = "Value" if op in VALUE_OPERATIONS else "Vector"
        cases[op] = _node("ShaderNodeVectorMath", output, {"operation": op}, inputs)
    # The guards at constant inputs (folded on both sides): a zero vector normalised, projected
    # onto, reflected about; a division and a modulo by zero components; an empty wrap range.
    zero = (0.0, 0.0, 0.0)
    guards = {"NORMALIZE": {"Vector": zero}, "PROJECT": {"Vector_001": zero}, "REFLECT": {"Vector_001": zero},
              "DIVIDE": {"Vector_001": (0.0, 2.0, 0.0)}, "MODULO": {"Vector_001": (0.0, 2.0, 0.0)},
              "SNAP": {"Vector_001": (0.0, 0.5, 0.0)},
              "WRAP": {"Vector_001": (1.0, 1.0, 2.0), "Vector_002": (1.0, -1.0, 2.0)},
              "REFRACT": {"Vector_001": zero, "Scale": 1.3}}
    for op, extra in guards.items():
        inputs = {"Vector": A, "Vector_001": B, "Vector_002": (0.0, 0.0, 0.0), "Scale": 1.0}
        inputs.update(extra)
        cases[f"{op}_guard"] = _node("ShaderNodeVectorMath", "Vector", {"operation": op}, inputs)
    return cases


def test_every_vector_math_operation_matches_cycles():
    cases = _vector_math_cases()
    _check(node_bake.bake(cases), len(cases))


# Value over [-0.6, 1.6] against From [0.1, 0.9] (reversed in some cases), so the ends clamp.
VALUE = ((2.2, 0.0, -0.6),)
INTERPOLATIONS = ("LINEAR", "STEPPED", "SMOOTHSTEP", "SMOOTHERSTEP")
# Name -> the inputs beyond Value: ordinary, both ranges reversed, per-point bounds and steps
# (through 0), an empty source range.
_FLOAT_RANGES = {
    "plain": {"From Min": 0.1, "From Max": 0.9, "To Min": -1.0, "To Max": 2.0, "Steps": 4.0},
    "reversed": {"From Min": 0.9, "From Max": 0.1, "To Min": 2.0, "To Max": -1.0, "Steps": 3.0},
    "fields": {"From Min": ((0.0, 0.6, -0.2),), "From Max": ((0.5, -0.4, 0.8),), "To Min": ((1.0, 1.0, -1.0),),
               "To Max": ((-2.0, 0.5, 1.5),), "Steps": ((0.0, 7.0, -1.2),)},
    "empty": {"From Min": 0.4, "From Max": 0.4, "To Min": 0.3, "To Max": 2.0, "Steps": 4.0},
}
_VECTOR_RANGES = {
    "plain": {"From_Min_FLOAT3": (0.1, 0.2, -0.3), "From_Max_FLOAT3": (0.9, 0.7, 1.2),
              "To_Min_FLOAT3": (-1.0, 0.0, 2.0), "To_Max_FLOAT3": (2.0, 1.0, 3.0), "Steps_FLOAT3": (4.0, 2.0, 5.0)},
    "reversed": {"From_Min_FLOAT3": (0.9, 0.2, 1.2), "From_Max_FLOAT3": (0.1, 0.7, -0.3),
                 "To_Min_FLOAT3": (2.0, 1.0, 3.0), "To_Max_FLOAT3": (-1.0, 0.0, 2.0), "Steps_FLOAT3": (3.0, 0.0, -2.0)},
    "fields": {"From_Min_FLOAT3": ((0.0, 0.6, -0.2), (0.3, 0.0, 0.0), (0.0, 0.0, 0.8)),
               "From_Max_FLOAT3": ((0.5, -0.4, 0.8), (0.0, 0.0, 0.9), (-1.0, 0.0, 0.5)),
               "To_Min_FLOAT3": ((1.0, 1.0, -1.0), (0.0, 0.0, 0.0), (0.0, 2.0, -1.0)),
               "To_Max_FLOAT3": ((-2.0, 0.5, 1.5), (0.0, 0.0, 1.0), (1.0, 1.0, 0.0)),
               "Steps_FLOAT3": ((0.0, 7.0, -1.2), (3.0, 0.0, 1.0), (0.0, 0.0, 2.0))},
    "empty": {"From_Min_FLOAT3": (0.4, 0.1, 0.4), "From_Max_FLOAT3": (0.4, 0.9, 0.4),
              "To_Min_FLOAT3": (0.3, 0.0, -1.0), "To_Max_FLOAT3": (2.0, 1.0, 1.0), "Steps_FLOAT3": (4.0, 4.0, 4.0)},
}
VECTOR_VALUE = ((2.2, 0.0, -0.6), (0.0, 2.2, -0.6), (1.1, 1.1, -0.6))


def _map_range_cases():
    cases = {}
    for kind, clamp, (name, ranges) in itertools.product(INTERPOLATIONS, (False, True), _FLOAT_RANGES.items()):
        props = {"data_type": "FLOAT", "interpolation_type": kind, "clamp": clamp}
        cases[f"FLOAT_{kind}_{name}_{clamp}"] = _node("ShaderNodeMapRange", "Result", props,
                                                       {"Value": VALUE, **ranges})
    for kind, clamp, (name, ranges) in itertools.product(INTERPOLATIONS, (False, True), _VECTOR_RANGES.items()):
        props = {"data_type": "FLOAT_VECTOR", "interpolation_type": kind, "clamp": clamp}
        cases[f"VECTOR_{kind}_{name}_{clamp}"] = _node("ShaderNodeMapRange", "Vector", props,
                                                        {"Vector": VECTOR_VALUE, **ranges})
    return cases


def _clamp_cases():
    cases = {}
    for kind in ("MINMAX", "RANGE"):
        # Min crosses Max over the plane; and constant bounds either way round.
        cases[f"{kind}_fields"] = _node("ShaderNodeClamp", "Result", {"clamp_type": kind},
                                        {"Value": ((0.0, 3.0, -1.0),), "Min": ((2.0, 0.0, -0.5),), "Max": 0.6})
        for lo, hi in ((0.2, 0.7), (0.7, 0.2)):
            cases[f"{kind}_{lo}_{hi}"] = _node("ShaderNodeClamp", "Result", {"clamp_type": kind},
                                               {"Value": VALUE, "Min": lo, "Max": hi})
    return cases


def test_map_range_and_clamp_match_cycles():
    cases = {**{f"map_range_{k}": v for k, v in _map_range_cases().items()},
             **{f"clamp_{k}": v for k, v in _clamp_cases().items()}}
    _check(node_bake.bake(cases), len(cases))


MAPPING_TYPES = ("POINT", "TEXTURE", "VECTOR", "NORMAL")


def _mapping_cases():
    cases = {}
    for kind in MAPPING_TYPES:
        cases[f"{kind}_constant"] = _node("ShaderNodeMapping", "Vector", {"vector_type": kind},
                                          {"Vector": A, "Location": (0.3, -1.2, 0.7), "Rotation": (0.5, -1.1, 2.3),
                                           "Scale": (1.5, -0.7, 2.0)})
        # Rotation and scale per point; a zero scale component tests the safe division.
        cases[f"{kind}_fields"] = _node("ShaderNodeMapping", "Vector", {"vector_type": kind},
                                        {"Vector": B, "Location": C,
                                         "Rotation": ((3.0, 0.0, -1.5), (0.0, -2.0, 0.4), (1.0, 1.0, 0.2)),
                                         "Scale": ((0.0, 2.0, -1.0), (1.0, 0.0, 0.5), (0.0, 0.0, 0.0))})
    return cases


ROTATE_TYPES = ("AXIS_ANGLE", "X_AXIS", "Y_AXIS", "Z_AXIS", "EULER_XYZ")


def _vector_rotate_cases():
    cases = {}
    for kind, invert in itertools.product(ROTATE_TYPES, (False, True)):
        props = {"rotation_type": kind, "invert": invert}
        cases[f"{kind}_{invert}"] = _node("ShaderNodeVectorRotate", "Vector", props,
                                          {"Vector": A, "Center": (0.4, -0.3, 0.8), "Axis": (1.0, -2.0, 0.5),
                                           "Angle": ((4.0, -3.0, 0.3),), "Rotation": (0.7, -0.4, 1.9)})
        cases[f"{kind}_{invert}_fields"] = _node("ShaderNodeVectorRotate", "Vector", props,
                                                 {"Vector": B, "Center": C, "Axis": A, "Angle": ((-2.0, 5.0, -1.0),),
                                                  "Rotation": ((3.0, 0.0, -1.5), (0.0, -2.0, 0.4), (1.0, 1.0, 0.2))})
    cases["AXIS_ANGLE_zero_axis"] = _node("ShaderNodeVectorRotate", "Vector", {"rotation_type": "AXIS_ANGLE"},
                                          {"Vector": A, "Center": (0.4, -0.3, 0.8), "Axis": (0.0, 0.0, 0.0),
                                           "Angle": 1.0})
    return cases


def test_mapping_and_vector_rotate_match_cycles():
    cases = {**{f"mapping_{k}": v for k, v in _mapping_cases().items()},
             **{f"rotate_{k}": v for k, v in _vector_rotate_cases().items()}}
    _check(node_bake.bake(cases), len(cases))


SPACES = ("WORLD", "OBJECT", "CAMERA")


def test_vector_transform_matches_cycles():
    """Every type between every pair of spaces, on a plane turned and scaled non-uniformly (the
    object's frame is then neither orthonormal nor the world's), and the camera off-axis."""
    cases = {}
    for kind, source, target in itertools.product(("POINT", "VECTOR", "NORMAL"), SPACES, SPACES):
        props = {"vector_type": kind, "convert_from": source, "convert_to": target}
        cases[f"{kind}_{source}_{target}"] = Placed(_node("ShaderNodeVectorTransform", "Vector", props,
                                                          {"Vector": A}), **TURNED)
    _check(node_bake.bake(cases), len(cases))


def test_normal_node_matches_cycles():
    cases = {}
    for direction in ((0.0, 0.0, 1.0), (0.6, -1.5, 0.4)):
        for output in ("Normal", "Dot"):
            def build(nt, direction=direction, output=output):
                n = nt.nodes.new("ShaderNodeNormal")
                n.outputs["Normal"].default_value = direction
                nt.links.new(_field(nt, *A), n.inputs["Normal"])
                return n.outputs[output]
            cases[f"{output}_{direction}"] = build
    _check(node_bake.bake(cases), len(cases))


# Reflection first: its plane is nearest the camera, whose rays then meet it at the widest spread.
TEXCOORD_OUTPUTS = ("Reflection", "Generated", "Normal", "UV", "Object", "Camera", "Window")


def _texcoord(output: str, instancer: bool = False, other=None):
    def build(nt):
        import bpy
        t = nt.nodes.new("ShaderNodeTexCoord")
        t.from_instancer = instancer
        if other is not None:  # an empty elsewhere, turned and scaled, as the Object output's frame
            empty = bpy.data.objects.new("frame", None)
            bpy.context.scene.collection.objects.link(empty)
            empty.location, empty.rotation_euler, empty.scale = other
            t.object = empty
        return t.outputs[output]
    return build


@pytest.mark.parametrize("view_from", ["ABOVE_SURFACE", "ACTIVE_CAMERA"])
def test_texture_coordinate_matches_cycles(view_from):
    """Every output on a plain and on a turned plane; From Instancer on objects that are not
    instances (zero); the Object output in another object's frame. With rays from the camera,
    the incoming direction varies over the plane, and so does Reflection."""
    cases = {}
    for output in TEXCOORD_OUTPUTS:
        cases[output] = _texcoord(output)
        cases[f"{output}_turned"] = Placed(_texcoord(output), **TURNED)
        if output == "Reflection":  # seen from the camera at grazing angles, and from behind
            cases["Reflection_grazing"] = Placed(_texcoord(output), rotation=(-0.5, 0.0, 0.0))
            cases["Reflection_behind"] = Placed(_texcoord(output), rotation=(3.0, 0.0, 0.0))
    for output in ("Generated", "UV"):
        cases[f"{output}_instancer"] = _texcoord(output, instancer=True)
    frame = ((1.0, -2.0, 0.5), (0.3, 0.9, -0.6), (2.0, 0.5, 1.2))
    cases["Object_in_frame"] = _texcoord("Object", other=frame)
    cases["Object_in_frame_turned"] = Placed(_texcoord("Object", other=frame), **TURNED)
    results = node_bake.bake(cases, view_from=view_from)
    _check(results, len(cases))
    if view_from == "ACTIVE_CAMERA":  # the camera's rays do meet the plane from many directions
        assert np.ptp(results["Reflection"][0], axis=0).max() > 0.1


# Input identifiers by kind, True for triples: for the shape check below.
_SOCKETS = {
    "ShaderNodeVectorMath": {"Vector": True, "Vector_001": True, "Vector_002": True, "Scale": False},
    "ShaderNodeMapRange": {**{k: False for k in ("Value", "From Min", "From Max", "To Min", "To Max", "Steps")},
                           **{k: True for k in ("Vector", "From_Min_FLOAT3", "From_Max_FLOAT3", "To_Min_FLOAT3",
                                                "To_Max_FLOAT3", "Steps_FLOAT3")}},
    "ShaderNodeClamp": {"Value": False, "Min": False, "Max": False},
    "ShaderNodeMapping": {"Vector": True, "Location": True, "Rotation": True, "Scale": True},
    "ShaderNodeVectorRotate": {"Vector": True, "Center": True, "Axis": True, "Rotation": True, "Angle": False},
    "ShaderNodeNormal": {"Normal": True},
}
_MODES = {
    "ShaderNodeVectorMath": [{"operation": op} for op in list(VECTOR_OPERATIONS) + list(VALUE_OPERATIONS)],
    "ShaderNodeMapRange": [{"data_type": d, "interpolation_type": k, "clamp": c}
                           for d in ("FLOAT", "FLOAT_VECTOR") for k in INTERPOLATIONS for c in (False, True)],
    "ShaderNodeClamp": [{"clamp_type": k} for k in ("MINMAX", "RANGE")],
    "ShaderNodeMapping": [{"vector_type": k} for k in MAPPING_TYPES],
    "ShaderNodeVectorRotate": [{"rotation_type": k, "invert": i} for k in ROTATE_TYPES for i in (False, True)],
    "ShaderNodeNormal": [{"direction": (0.3, -0.8, 0.5)}],
}


@pytest.mark.parametrize("kind", sorted(_SOCKETS))
def test_constant_and_per_point_inputs_agree(kind):
    """Constant folding evaluates a node with 0-d and (3,) inputs: any mix of constant and
    per-point inputs gives, at each point, what the all-constant evaluation gives there."""
    from ember.engine.nodes.graph import Node
    from ember.engine.nodes.registry import REGISTRY

    rng = np.random.default_rng(7)
    n = 6
    for props in _MODES[kind]:
        node = Node(kind, "n", tuple(sorted(props.items())))
        for trial in range(4):
            values = {k: rng.uniform(-2.0, 2.0, (n, 3) if is_triple else n) for k, is_triple in _SOCKETS[kind].items()}
            for k in values:  # some inputs the same at every point, given as constants
                if rng.random() < 0.5:
                    values[k][:] = values[k][0]
            mixed = {k: (v if np.ptp(v) > 0.0 else v[0]) for k, v in values.items()}
            together = REGISTRY[kind].evaluate(node, mixed, None)
            for i in range(n):
                alone = REGISTRY[kind].evaluate(node, {k: v[i] for k, v in values.items()}, None)
                for name, value in alone.items():
                    assert np.shape(value) == (3,) or np.ndim(value) == 0, (props, name)
                    got = np.broadcast_to(together[name], (n,) + np.shape(value))[i]
                    np.testing.assert_allclose(got, value, rtol=1e-12, atol=1e-12, err_msg=f"{props} {name}")
