"""Bump against Cycles (tests/node_bake.py), and the Material Output's displacement as bump.

Cycles evaluates a Bump node's Height at the point and at the point moved along the ray
differential, by copies of the Height subgraph whose coordinate nodes read the moved point; a
bake's differential is the texel's footprint (init_from_bake.h), which the harness reproduces.
Heights here are built from every kind of coordinate that moves (texture coordinates, UV maps,
attributes, Geometry's Position and Parametric, Wireframe, an unlinked texture's Generated) and
from ones that do not (Camera Data, Geometry's Normal), curved enough that the moved samples
differ by more than a plane would (so the differential's size matters, not only its
direction), on planes, turned planes and height grids, with every setting of the node."""
import itertools

import numpy as np
import pytest

pytestmark = pytest.mark.blender

import bpy  # noqa: E402
import node_bake  # noqa: E402
from node_bake import Placed  # noqa: E402
from test_nodes_inputs import TURNED, _check, attribute_mesh, grid_mesh  # noqa: E402

COLUMNS = 8


def _bake(cases: dict, **kwargs) -> dict:
    return node_bake.bake(cases, columns=COLUMNS, **kwargs)


def _wave(nt, vector, frequency=(9.0, 7.0, 5.0)):
    """sin(f . v) of a vector socket: a height that curves within a texel's footprint."""
    dot = nt.nodes.new("ShaderNodeVectorMath")
    dot.operation = "DOT_PRODUCT"
    dot.inputs[1].default_value = frequency
    nt.links.new(vector, dot.inputs[0])
    sine = nt.nodes.new("ShaderNodeMath")
    sine.operation = "SINE"
    nt.links.new(dot.outputs["Value"], sine.inputs[0])
    return sine.outputs[0]


def _source(nt, name: str, frequency=None):
    """The Height's source by name: a socket of some node feeding the wave (or the Height)."""
    def node(kind, **props):
        n = nt.nodes.new(kind)
        for key, value in props.items():
            setattr(n, key, value)
        return n
    if name.startswith("texcoord_"):
        return _wave(nt, node("ShaderNodeTexCoord").outputs[name[len("texcoord_"):]], frequency or (9.0, 7.0, 5.0))
    if name.startswith("geometry_"):
        return _wave(nt, node("ShaderNodeNewGeometry").outputs[name[len("geometry_"):]])
    if name == "uv_second":
        return _wave(nt, node("ShaderNodeUVMap", uv_map="Second").outputs["UV"])
    if name == "attribute":
        return _wave(nt, node("ShaderNodeAttribute", attribute_name="v_point").outputs["Vector"], (1.5, 2.0, 1.0))
    if name == "color_attribute":
        return _wave(nt, node("ShaderNodeVertexColor", layer_name="col_float").outputs["Color"], (2.0, 3.0, 1.0))
    if name == "camera":
        return _wave(nt, node("ShaderNodeCameraData").outputs["View Vector"], (30.0, 20.0, 10.0))
    if name == "noise":  # unlinked Vector: the texture reads Generated
        noise = node("ShaderNodeTexNoise")
        noise.inputs["Scale"].default_value = 6.0
        return noise.outputs["Fac"]
    if name == "wireframe":
        wire = node("ShaderNodeWireframe")
        wire.inputs["Size"].default_value = 0.3
        return wire.outputs["Fac"]
    if name == "pointiness":
        return _wave(nt, node("ShaderNodeNewGeometry").outputs["Pointiness"], (20.0, 0.0, 0.0))
    raise KeyError(name)


def _bump(source: str, strength=1.0, distance=0.1, filter_width=0.1, invert=False, normal=False, frequency=None):
    def build(nt):
        bump = nt.nodes.new("ShaderNodeBump")
        bump.invert = invert
        bump.inputs["Strength"].default_value = strength
        bump.inputs["Distance"].default_value = distance
        bump.inputs["Filter Width"].default_value = filter_width
        nt.links.new(_source(nt, source, frequency), bump.inputs["Height"])
        if normal:  # a tilted normal field into Normal
            coord = nt.nodes.new("ShaderNodeTexCoord")
            tilt = nt.nodes.new("ShaderNodeVectorMath")
            tilt.operation = "MULTIPLY_ADD"
            tilt.inputs[1].default_value = (0.6, -0.5, 0.0)
            tilt.inputs[2].default_value = (-0.3, 0.2, 1.0)
            nt.links.new(coord.outputs["UV"], tilt.inputs[0])
            unit = nt.nodes.new("ShaderNodeVectorMath")
            unit.operation = "NORMALIZE"
            nt.links.new(tilt.outputs[0], unit.inputs[0])
            nt.links.new(unit.outputs[0], bump.inputs["Normal"])
        return bump.outputs["Normal"]
    return build


SHAPES = {"plane": {}, "turned": TURNED, "smooth": dict(mesh=grid_mesh(smooth=True), **TURNED),
          "flat": dict(mesh=grid_mesh(smooth=False))}
SOURCES = ("texcoord_UV", "texcoord_Generated", "texcoord_Object", "texcoord_Camera", "texcoord_Window",
           "texcoord_Normal", "texcoord_Reflection", "geometry_Position", "geometry_Parametric", "geometry_Normal",
           "noise", "wireframe", "camera")
# Heights of the position (in any space): Cycles' float32 position carries a rounding of about
# 1e-7 of its distance from the origin (or the camera) into both samples, which their difference
# over filter_width * dP (0.006 at 0.1) magnifies toward 1e-4; a wider filter keeps it small.
# Wireframe's height steps: a wider filter puts more texels' samples across a step.
WIDTHS = {"texcoord_Object": 1.0, "texcoord_Camera": 1.0, "texcoord_Window": 1.0, "geometry_Position": 1.0,
          "wireframe": 1.0}


@pytest.mark.parametrize("view_from", ["ABOVE_SURFACE", "ACTIVE_CAMERA"])
def test_bump_heights_match_cycles(view_from):
    """Every kind of Height source on every shape. Sources Cycles reads at the unmoved point
    (Camera Data, Geometry's Normal, Texture Coordinate's Reflection) give no bump."""
    cases = {f"{source}_{shape}": Placed(_bump(source, filter_width=WIDTHS.get(source, 0.1)), **place)
             for source, (shape, place) in itertools.product(SOURCES, SHAPES.items())}
    results = _bake(cases, view_from=view_from)
    _check(results, len(cases))
    flat_normal = np.array([0.0, 0.0, 1.0])
    for source in ("texcoord_UV", "texcoord_Camera", "geometry_Position", "wireframe"):  # the bumps tilt
        assert np.abs(results[f"{source}_plane"][0] - flat_normal).max() > 0.1, source
    for source in ("camera", "geometry_Normal", "texcoord_Reflection"):  # no bump variant: h_x = h_c
        assert np.abs(results[f"{source}_plane"][0] - flat_normal).max() < 1e-6, source


def test_bump_attribute_heights_match_cycles():
    """Heights from attributes (by name, a colour attribute, the second UV map, pointiness)."""
    place = dict(mesh=attribute_mesh(), **TURNED)
    cases = {source: Placed(_bump(source), **place)
             for source in ("attribute", "color_attribute", "uv_second", "pointiness", "texcoord_UV")}
    _check(_bake(cases), len(cases))


# (strength, distance, filter width, invert, Normal linked)
SETTINGS = ((0.5, 0.1, 0.1, False, False), (1.6, 0.1, 0.1, False, False), (-0.4, 0.1, 0.1, False, False),
            (1.0, -0.3, 0.1, False, False), (1.0, 0.2, 0.1, True, False), (1.0, 0.1, 1.0, False, False),
            (1.0, 0.1, 0.05, False, False), (1.0, 0.1, 3.0, True, False), (0.8, 0.15, 0.1, False, True))


def test_bump_settings_match_cycles():
    """Strength (blended, beyond 1, negative: clamped to 0), Distance (negative too), Invert,
    Filter Width (the differential's size: a wrong footprint moves the samples elsewhere on the
    curved height), the Normal input linked, a constant Height (the normal passes through).
    The height's frequency is lower here: Cycles' float32 difference of nearby samples stays
    well within the tolerance at the stronger distances and the narrower filter."""
    cases = {}
    for shape, place in (("plane", {}), ("turned", TURNED), ("smooth", SHAPES["smooth"])):
        for strength, distance, width, invert, normal in SETTINGS:
            name = f"{shape}_{strength}_{distance}_{width}_{invert}_{normal}"
            cases[name] = Placed(_bump("texcoord_Generated", strength, distance, width, invert, normal,
                                       frequency=(4.0, 3.0, 2.0)), **place)

        def constant(nt, normal=False):
            bump = nt.nodes.new("ShaderNodeBump")
            bump.inputs["Height"].default_value = 0.7
            return bump.outputs["Normal"]
        cases[f"{shape}_constant"] = Placed(constant, **place)
    _check(_bake(cases), len(cases))


def _chained(nt):
    """One Bump's normal into another's Normal; the first's Height feeds the second's too."""
    first = _bump("texcoord_UV", distance=0.05)(nt)
    second = nt.nodes.new("ShaderNodeBump")
    second.inputs["Distance"].default_value = 0.2
    nt.links.new(first, second.inputs["Normal"])
    nt.links.new(_source(nt, "texcoord_Generated", (4.0, 3.0, 2.0)), second.inputs["Height"])
    return second.outputs["Normal"]


def _nested(nt, direct=False):
    """A Bump's normal inside another Bump's Height (with a Generated wave, or alone)."""
    inner = _bump("texcoord_UV", distance=0.3)(nt)
    dot = nt.nodes.new("ShaderNodeVectorMath")
    dot.operation = "DOT_PRODUCT"
    dot.inputs[1].default_value = (0.5, 0.3, 0.2)
    nt.links.new(inner, dot.inputs[0])
    outer = nt.nodes.new("ShaderNodeBump")
    outer.inputs["Distance"].default_value = 0.2
    if direct:
        nt.links.new(dot.outputs["Value"], outer.inputs["Height"])
    else:
        add = nt.nodes.new("ShaderNodeMath")
        nt.links.new(dot.outputs["Value"], add.inputs[0])
        nt.links.new(_source(nt, "texcoord_Generated", (4.0, 3.0, 2.0)), add.inputs[1])
        nt.links.new(add.outputs[0], outer.inputs["Height"])
    return outer.outputs["Normal"]


def test_bump_chains_match_cycles():
    """A Bump's normal into another's Normal input, and into another's Height: Cycles' offset
    evaluations of the outer Height see the inner Bump's normal as at the point."""
    cases = {"chain_plane": _chained, "chain_turned": Placed(_chained, **TURNED),
             "chain_smooth": Placed(_chained, **SHAPES["smooth"]),
             "nested_plane": _nested, "nested_turned": Placed(_nested, **TURNED),
             "nested_direct": lambda nt: _nested(nt, direct=True)}
    _check(_bake(cases), len(cases))


def _displaced(method: str, source: str, scale: float = 0.3):
    """A material displaced by `method` (BUMP or BOTH) through a Displacement node, emitting its
    shading normal (Geometry's Normal reads the bumped normal)."""
    def build(nt):
        material = next(m for m in bpy.data.materials if m.node_tree == nt)
        material.displacement_method = method
        out = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
        disp = nt.nodes.new("ShaderNodeDisplacement")
        disp.inputs["Scale"].default_value = scale
        nt.links.new(_source(nt, source), disp.inputs["Height"])
        nt.links.new(disp.outputs["Displacement"], out.inputs["Displacement"])
        return nt.nodes.new("ShaderNodeNewGeometry").outputs["Normal"]
    return build


def test_displacement_as_bump_matches_cycles():
    """Cycles' "Bump Only" displacement: the Displacement output's height along N bumps the
    shading normal every node then reads."""
    cases = {}
    for (shape, place), source in itertools.product(SHAPES.items(), ("texcoord_UV", "noise")):
        cases[f"bump_{shape}_{source}"] = Placed(_displaced("BUMP", source), **place)
    results = _bake(cases)
    _check(results, len(cases))
    assert np.abs(results["bump_plane_noise"][0] - np.array([0.0, 0.0, 1.0])).max() > 0.05
