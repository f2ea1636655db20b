"""Input nodes against Cycles (tests/node_bake.py): Geometry, Object Info, Attribute, Color
Attribute, UV Map, Tangent, Camera Data, Fresnel, Layer Weight, Light Path, Wireframe, Normal
Map, Displacement, Vector Displacement, and the Point, Volume, Curves and Particle Info nodes.

Besides the plane, cases bake on grids whose heights vary (smooth or flat shaded: their
normals, pointiness and tangents vary), on grids cut into islands with coincident vertices
along the cuts (Random Per Island, pointiness' welding), with a second UV map, colour and
generic attributes on every domain, and on objects moved, turned and scaled non-uniformly with
colours, pass indices and custom properties. What a bake cannot set up (rays other than a
camera ray, backfacing hits, path depths) is checked against Cycles' formulas directly."""
import itertools
import math

import numpy as np
import pytest

pytestmark = pytest.mark.blender

import bpy  # noqa: E402
import node_bake  # noqa: E402
from node_bake import Placed  # noqa: E402

# An object transform with rotation about every axis, non-uniform scale and an offset.
TURNED = dict(location=(0.3, 0.5, -0.4), rotation=(0.4, -0.7, 1.1), scale=(1.3, 0.6, 0.9))


def _height(x, y):
    return 0.35 * np.sin(2.1 * x + 0.4) * np.cos(1.7 * y - 0.3) + 0.1 * x * y


def grid_mesh(cells: int = 6, height=_height, smooth: bool = False, islands: int = 1, second_uv: bool = False,
              render_uv: str = "UVMap"):
    """A mesh over [-1, 1]^2 of cells x cells quads lifted by height(x, y), its UV map "UVMap"
    spanning the unit square (the bake's). islands > 1 cuts it into islands x islands blocks
    whose border vertices are separate but coincident. second_uv adds a map "Second" (turned and
    scaled); render_uv names the map Cycles renders with."""
    def make():
        step = cells // islands
        verts, faces, uvs = [], [], []
        for bi, bj in itertools.product(range(islands), repeat=2):
            index = {}
            rows, columns = range(bi * step, bi * step + step + 1), range(bj * step, bj * step + step + 1)
            for i, j in itertools.product(rows, columns):
                x, y = -1.0 + 2.0 * i / cells, -1.0 + 2.0 * j / cells
                index[i, j] = len(verts)
                verts.append((x, y, float(height(x, y)) if height is not None else 0.0))
            for i, j in itertools.product(range(bi * step, bi * step + step), range(bj * step, bj * step + step)):
                quad = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]
                faces.append(tuple(index[c] for c in quad))
                uvs.append([(a / cells, b / cells) for a, b in quad])
        mesh = bpy.data.meshes.new("grid")
        mesh.from_pydata(verts, [], faces)
        uv = mesh.uv_layers.new(name="UVMap")
        flat = [c for face in uvs for corner in face for c in corner]
        uv.data.foreach_set("uv", flat)
        if second_uv:
            second = mesh.uv_layers.new(name="Second")
            turned = []
            for face in uvs:
                for a, b in face:
                    turned += [0.2 + 0.5 * b + 0.1 * a, 0.9 - 0.6 * a + 0.05 * b]
            second.data.foreach_set("uv", turned)
        mesh.uv_layers.active = mesh.uv_layers["UVMap"]
        mesh.uv_layers[render_uv].active_render = True
        mesh.polygons.foreach_set("use_smooth", [smooth] * len(mesh.polygons))
        mesh.update()
        return mesh
    return make


COLUMNS = 8  # objects per row: near the origin (node_bake.bake)


def _bake(cases: dict, **kwargs) -> dict:
    return node_bake.bake(cases, columns=COLUMNS, **kwargs)


def _check(results: dict, count: int):
    agreement = {name: node_bake.agreement(c, e) for name, (c, e) in results.items()}
    assert {name: a for name, a in agreement.items() if a < 0.999} == {}
    assert len(results) == count


def _output(kind: str, output: str, props: dict | None = None, inputs: dict | None = None):
    """A case: a node of `kind` with `props` and constant `inputs`, its output `output`."""
    def build(nt):
        n = nt.nodes.new(kind)
        for key, value in (props or {}).items():
            setattr(n, key, value)
        for key, value in (inputs or {}).items():
            next(s for s in n.inputs if s.identifier == key).default_value = value
        return next(s for s in n.outputs if s.identifier == output)
    return build


GEOMETRY_OUTPUTS = ("Position", "Normal", "Tangent", "True Normal", "Incoming", "Parametric", "Backfacing",
                    "Pointiness", "Random Per Island")
SHAPES = {"plane": {}, "turned": TURNED,
          "smooth": dict(mesh=grid_mesh(smooth=True)), "flat": dict(mesh=grid_mesh(smooth=False)),
          "smooth_turned": dict(mesh=grid_mesh(smooth=True), **TURNED)}


@pytest.mark.parametrize("view_from", ["ABOVE_SURFACE", "ACTIVE_CAMERA"])
def test_geometry_matches_cycles(view_from):
    cases = {}
    for output, (shape, place) in itertools.product(GEOMETRY_OUTPUTS, SHAPES.items()):
        cases[f"{output}_{shape}"] = Placed(_output("ShaderNodeNewGeometry", output), **place)
    for islands, smooth in ((3, True), (2, False)):  # coincident vertices along the cuts
        mesh = grid_mesh(cells=6, islands=islands, smooth=smooth)
        for output in ("Pointiness", "Random Per Island", "Normal", "Parametric"):
            cases[f"{output}_islands{islands}"] = Placed(_output("ShaderNodeNewGeometry", output), mesh=mesh)
    results = _bake(cases, view_from=view_from)
    _check(results, len(cases))
    assert np.ptp(results["Random Per Island_islands3"][0][:, 0]) > 0.1  # the islands differ
    assert np.ptp(results["Pointiness_smooth"][0][:, 0]) > 0.05


def _object_setup(ob):
    ob.color = (0.8, -0.25, 1.7, 0.35)
    ob.pass_index = 7


def _material_of(nt):
    return next(m for m in bpy.data.materials if m.node_tree == nt)


def _material_index(output):
    def build(nt):
        _material_of(nt).pass_index = 11
        return _output("ShaderNodeObjectInfo", output)(nt)
    return build


def test_object_info_and_camera_data_match_cycles():
    cases = {}
    for output in ("Location", "Color", "Alpha", "Object Index", "Material Index", "Random"):
        cases[f"object_{output}"] = Placed(_material_index(output), setup=_object_setup, **TURNED)
        cases[f"object_{output}_plain"] = _material_index(output)
    # A name past ASCII: Cycles hashes its UTF-8 bytes as signed chars.
    cases["object_Random_unicode"] = Placed(_output("ShaderNodeObjectInfo", "Random"),
                                            setup=lambda ob: setattr(ob, "name", "Objekt_Größe_ø"))
    for output in ("View Vector", "View Z Depth", "View Distance"):
        cases[f"camera_{output}"] = _output("ShaderNodeCameraData", output)
        cases[f"camera_{output}_turned"] = Placed(_output("ShaderNodeCameraData", output), **TURNED)
        cases[f"camera_{output}_smooth"] = Placed(_output("ShaderNodeCameraData", output), mesh=grid_mesh(smooth=True))
    results = _bake(cases)
    _check(results, len(cases))
    randoms = {results[f"object_Random{s}"][0][0, 0] for s in ("", "_plain", "_unicode")}
    assert len(randoms) == 3  # the objects' names differ, and so do their random numbers


@pytest.mark.parametrize("view_from", ["ABOVE_SURFACE", "ACTIVE_CAMERA"])
def test_wireframe_matches_cycles(view_from):
    """World and pixel widths on the plane (its diagonal is an edge: Cycles draws triangles), a
    scaled and turned plane, and grids; the pixel width follows the bake's differentials."""
    cases = {}
    for pixel, size in itertools.product((False, True), (0.02, 0.15, 0.6)):
        size_value = size if not pixel else size * 8.0
        for shape, place in SHAPES.items():
            cases[f"{pixel}_{size}_{shape}"] = Placed(
                _output("ShaderNodeWireframe", "Fac", {"use_pixel_size": pixel}, {"Size": size_value}), **place)
    results = _bake(cases, view_from=view_from)
    _check(results, len(cases))
    for name in ("False_0.15_plane", "True_0.15_plane", "True_0.15_smooth"):  # lines, not all or nothing
        assert 0.02 < results[name][0][:, 0].mean() < 0.9, name


def attribute_mesh(render_uv: str = "UVMap"):
    """A smooth height grid with a second UV map and attributes of every type on every domain,
    a colour attribute named like Cycles' standard "color" (which Cycles never finds by that
    name), and "col_byte" as the render colour attribute."""
    base = grid_mesh(cells=4, smooth=True, second_uv=True, render_uv=render_uv)

    def make():
        mesh = base()
        rng = np.random.default_rng(3)
        sizes = {"POINT": len(mesh.vertices), "FACE": len(mesh.polygons), "CORNER": len(mesh.loops),
                 "EDGE": len(mesh.edges)}
        specs = [("f_point", "FLOAT", "POINT"), ("f_face", "FLOAT", "FACE"), ("f_corner", "FLOAT", "CORNER"),
                 ("f_edge", "FLOAT", "EDGE"), ("v_point", "FLOAT_VECTOR", "POINT"), ("v2_corner", "FLOAT2", "CORNER"),
                 ("i_face", "INT", "FACE"), ("b_point", "BOOLEAN", "POINT"), ("i8_point", "INT8", "POINT"),
                 ("q_face", "QUATERNION", "FACE"), ("col_float", "FLOAT_COLOR", "POINT"),
                 ("col_byte", "BYTE_COLOR", "CORNER"), ("color", "BYTE_COLOR", "POINT")]
        for name, kind, domain in specs:
            a = mesh.attributes.new(name, kind, domain)
            n = sizes[domain]
            if kind in ("FLOAT_COLOR", "BYTE_COLOR"):
                values = rng.uniform(0.0, 1.0, (n, 4)) if kind == "BYTE_COLOR" else rng.uniform(-0.5, 2.0, (n, 4))
                a.data.foreach_set("color_srgb" if kind == "BYTE_COLOR" else "color", values.ravel())
            elif kind == "FLOAT_VECTOR":
                a.data.foreach_set("vector", rng.uniform(-2.0, 2.0, n * 3))
            elif kind == "FLOAT2":
                a.data.foreach_set("vector", rng.uniform(-2.0, 2.0, n * 2))
            elif kind == "QUATERNION":
                a.data.foreach_set("value", rng.uniform(-1.0, 1.0, n * 4))
            elif kind in ("INT", "INT8"):
                a.data.foreach_set("value", rng.integers(-5, 6, n).tolist())
            elif kind == "BOOLEAN":
                a.data.foreach_set("value", (rng.uniform(size=n) > 0.5).tolist())
            else:
                a.data.foreach_set("value", rng.uniform(-3.0, 3.0, n))
        mesh.color_attributes.render_color_index = mesh.color_attributes.find("col_byte")
        mesh.color_attributes.active_color = mesh.color_attributes["col_byte"]
        return mesh
    return make


def _custom_properties(ob):
    ob.color = (0.3, 0.6, 0.9, 0.25)
    ob.pass_index = 5
    ob["prop_float"] = 2.5
    ob["prop_array"] = [0.2, -1.5, 3.0]
    ob["prop_int"] = 4
    ob["prop_bool"] = True
    ob["prop_int_array"] = [3, -2]
    ob.data["data_prop"] = [0.7, 0.1, -0.4, 0.5]


GEOMETRY_ATTRIBUTES = ("UVMap", "Second", "col_byte", "col_float", "f_point", "f_face", "f_corner", "f_edge",
                       "v_point", "v2_corner", "i_face", "b_point", "i8_point", "q_face", "position", "color",
                       "missing", "uv", "generated", "pointiness", "random_per_island", "vertex_color", "N", "tangent",
                       "tangent_sign", "Second.tangent", "Second.tangent_sign", "undisplaced_tangent", "P")
OBJECT_ATTRIBUTES = ("prop_float", "prop_array", "prop_int", "prop_bool", "prop_int_array", "data_prop", "location",
                     "color", "pass_index", "missing")


def test_attribute_matches_cycles():
    cases = {}
    attribute_place = dict(mesh=attribute_mesh(), setup=_custom_properties, **TURNED)
    for name, output in itertools.product(GEOMETRY_ATTRIBUTES, ("Color", "Fac", "Alpha")):
        props = {"attribute_type": "GEOMETRY", "attribute_name": name}
        cases[f"geometry_{name}_{output}"] = Placed(_output("ShaderNodeAttribute", output, props), **attribute_place)
    for kind, name, output in itertools.product(("OBJECT", "INSTANCER"), OBJECT_ATTRIBUTES, ("Color", "Fac", "Alpha")):
        props = {"attribute_type": kind, "attribute_name": name}
        cases[f"{kind}_{name}_{output}"] = Placed(_output("ShaderNodeAttribute", output, props), **attribute_place)
    cases["geometry_f_point_Vector"] = Placed(_output("ShaderNodeAttribute", "Vector", {"attribute_name": "f_point"}),
                                              **attribute_place)
    cases["geometry_uv_Color_plane"] = _output("ShaderNodeAttribute", "Color", {"attribute_name": "UVMap"})
    results = _bake(cases)
    _check(results, len(cases))
    assert np.ptp(results["geometry_col_byte_Color"][0]) > 0.3
    assert np.all(results["geometry_color_Color"][0] == 0.0)  # a standard name: not the mesh's "color"


def _view_layer_case(name: str, output: str, into: str):
    """A View Layer attribute's output into a colour (Emission) or through a float socket."""
    def build(nt):
        scene = bpy.context.scene
        if scene.world is None:
            scene.world = bpy.data.worlds.new("world")
        bpy.context.view_layer["vl_prop"] = [0.9, 0.2, -0.3]
        scene["sc_prop"] = 1.75
        scene.world["w_prop"] = [0.1, 0.4, 0.6, 0.3]
        attr = nt.nodes.new("ShaderNodeAttribute")
        attr.attribute_type, attr.attribute_name = "VIEW_LAYER", name
        if into == "color":
            return attr.outputs[output]
        math_node = nt.nodes.new("ShaderNodeMath")
        math_node.operation = "ADD"
        math_node.inputs[1].default_value = 0.25
        nt.links.new(attr.outputs[output], math_node.inputs[0])
        return math_node.outputs[0]
    return build


def test_view_layer_attributes_fold_as_in_cycles():
    """The view layer's, the scene's, then the world's properties, folded into the graph; through
    a float socket a colour is averaged (not taken by luminance), as Cycles folds it."""
    cases = {f"{name}_{output}_{into}": _view_layer_case(name, output, into)
             for name in ("vl_prop", "sc_prop", "w_prop", "missing", "resolution_x")
             for output in ("Color", "Vector", "Fac", "Alpha") for into in ("color", "float")}
    _check(_bake(cases), len(cases))


def test_color_attribute_and_uv_map_match_cycles():
    cases = {}
    for render in ("UVMap", "Second"):
        place = dict(mesh=attribute_mesh(render_uv=render), setup=_custom_properties, **TURNED)
        for name in ("", "col_byte", "col_float", "missing"):
            for output in ("Color", "Alpha"):
                cases[f"color_{name}_{output}_{render}"] = Placed(
                    _output("ShaderNodeVertexColor", output, {"layer_name": name}), **place)
        for name, instancer in (("", False), ("UVMap", False), ("Second", False), ("missing", False), ("", True)):
            cases[f"uv_{name}_{instancer}_{render}"] = Placed(
                _output("ShaderNodeUVMap", "UV", {"uv_map": name, "from_instancer": instancer}), **place)
        cases[f"texcoord_uv_{render}"] = Placed(_output("ShaderNodeTexCoord", "UV"), **place)
    cases["color_plane"] = _output("ShaderNodeVertexColor", "Color")  # no colour attributes: black
    results = _bake(cases)
    _check(results, len(cases))
    assert not np.allclose(results["uv__False_Second"][0], results["uv__False_UVMap"][0])


def test_tangent_matches_cycles():
    """Radial about each axis and the UV map's MikkTSpace tangent (active render map and a
    named one), on the plane, a turned plane and turned smooth and flat height grids. (Radial
    about X or Y on a flat plane in XY is parallel to its normal: no tangent to compare.)"""
    cases = {}
    shapes = {"plane": {}, "turned": TURNED, "smooth": dict(mesh=grid_mesh(smooth=True, second_uv=True), **TURNED),
              "flat": dict(mesh=grid_mesh(smooth=False, second_uv=True), **TURNED)}
    for (shape, place), axis in itertools.product(shapes.items(), ("X", "Y", "Z")):
        if axis != "Z" and shape in ("plane", "turned"):
            continue
        props = {"direction_type": "RADIAL", "axis": axis}
        cases[f"radial_{axis}_{shape}"] = Placed(_output("ShaderNodeTangent", "Tangent", props), **place)
    for (shape, place), uv in itertools.product(shapes.items(), ("", "UVMap", "Second", "missing")):
        if uv == "Second" and shape in ("plane", "turned"):
            continue
        props = {"direction_type": "UV_MAP", "uv_map": uv}
        cases[f"uv_{uv}_{shape}"] = Placed(_output("ShaderNodeTangent", "Tangent", props), **place)
    _check(_bake(cases), len(cases))


def _with_normal(kind: str, output: str, inputs: dict, normal: bool):
    """A Fresnel or Layer Weight case, its Normal input a tilting field where `normal`."""
    def build(nt):
        n = nt.nodes.new(kind)
        for key, value in inputs.items():
            n.inputs[key].default_value = value
        if normal:
            coord = nt.nodes.new("ShaderNodeTexCoord")
            mapping = nt.nodes.new("ShaderNodeVectorMath")
            mapping.operation = "MULTIPLY_ADD"
            mapping.inputs[1].default_value = (1.4, -0.9, 0.0)
            mapping.inputs[2].default_value = (-0.7, 0.45, 1.0)
            nt.links.new(coord.outputs["UV"], mapping.inputs[0])
            norm = nt.nodes.new("ShaderNodeVectorMath")
            norm.operation = "NORMALIZE"
            nt.links.new(mapping.outputs[0], norm.inputs[0])
            nt.links.new(norm.outputs[0], n.inputs["Normal"])
        return n.outputs[output]
    return build


def test_fresnel_and_layer_weight_match_cycles():
    """Seen from the camera, so that the incoming direction varies over each plane; planes
    turned toward grazing; IORs around 1 and below; every Blend regime; Normal linked."""
    cases = {}
    places = {"plain": {}, "grazing": dict(rotation=(-1.2, 0.0, 0.3)), "smooth": dict(mesh=grid_mesh(smooth=True))}
    for (shape, place), normal in itertools.product(places.items(), (False, True)):
        for ior in (1.5, 1.0, 0.7, 3.0):
            cases[f"fresnel_{ior}_{shape}_{normal}"] = Placed(
                _with_normal("ShaderNodeFresnel", "Fac", {"IOR": ior}, normal), **place)
        for blend, output in itertools.product((0.0, 0.2, 0.5, 0.75, 0.98, 1.0), ("Fresnel", "Facing")):
            if blend == 1.0 and normal and output == "Facing":
                # Facing raises |cos| to 49932 here: where the linked normal faces the camera
                # within 1e-5, Cycles' float32 cosine alone moves the result by 1e-3.
                continue
            cases[f"layer_{output}_{blend}_{shape}_{normal}"] = Placed(
                _with_normal("ShaderNodeLayerWeight", output, {"Blend": blend}, normal), **place)
    results = _bake(cases, view_from="ACTIVE_CAMERA")
    _check(results, len(cases))
    assert np.ptp(results["fresnel_1.5_smooth_False"][0][:, 0]) > 0.02
    assert np.ptp(results["layer_Facing_0.2_plain_False"][0][:, 0]) > 0.02


LIGHT_PATH_OUTPUTS = ("Is Camera Ray", "Is Shadow Ray", "Is Diffuse Ray", "Is Glossy Ray", "Is Singular Ray",
                      "Is Reflection Ray", "Is Transmission Ray", "Is Volume Scatter Ray", "Ray Length", "Ray Depth",
                      "Diffuse Depth", "Glossy Depth", "Transparent Depth", "Transmission Depth", "Portal Depth")


def test_light_path_matches_cycles_bake():
    """A bake's path is a camera ray that has not bounced, its ray 1 long (init_from_bake.h)."""
    cases = {output: _output("ShaderNodeLightPath", output) for output in LIGHT_PATH_OUTPUTS}
    results = _bake(cases, size=8)
    _check(results, len(cases))
    assert results["Is Camera Ray"][0].min() == 1.0


def test_info_nodes_on_surfaces_match_cycles():
    """Point, Volume, Curves and Particle Info read what a mesh surface has not: zeros, and for
    Particle Info Cycles' dummy particle (its Random is the hash of index 0, not 0)."""
    cases = {}
    for kind, outputs in (("ShaderNodePointInfo", ("Position", "Radius", "Random")),
                          ("ShaderNodeVolumeInfo", ("Color", "Density", "Flame", "Temperature")),
                          ("ShaderNodeHairInfo", ("Is Strand", "Intercept", "Length", "Thickness", "Tangent Normal",
                                                  "Random")),
                          ("ShaderNodeParticleInfo", ("Index", "Random", "Age", "Lifetime", "Location", "Size",
                                                      "Velocity", "Angular Velocity"))):
        for output in outputs:
            cases[f"{kind}_{output}"] = Placed(_output(kind, output), mesh=attribute_mesh())
    results = _bake(cases, size=8)
    _check(results, len(cases))
    assert results["ShaderNodeParticleInfo_Random"][0].min() > 0.5


def _color_field(nt, location=(0.15, 0.8, 0.75), rotation=(0.9, -0.4, 0.3), scale=(0.7, -0.6, 0.5)):
    """A colour varying over the surface: the UV through a Mapping (turned, so z varies too)."""
    coord = nt.nodes.new("ShaderNodeTexCoord")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Location"].default_value = location
    mapping.inputs["Rotation"].default_value = rotation
    mapping.inputs["Scale"].default_value = scale
    nt.links.new(coord.outputs["UV"], mapping.inputs["Vector"])
    return mapping.outputs["Vector"]


def _normal_map(space: str, strength: float, uv_map: str = ""):
    def build(nt):
        n = nt.nodes.new("ShaderNodeNormalMap")
        n.space, n.uv_map = space, uv_map
        n.inputs["Strength"].default_value = strength
        nt.links.new(_color_field(nt), n.inputs["Color"])
        return n.outputs["Normal"]
    return build


NORMAL_MAP_SPACES = ("TANGENT", "OBJECT", "WORLD", "BLENDER_OBJECT", "BLENDER_WORLD")


def test_normal_map_matches_cycles():
    cases = {}
    shapes = {"plane": {}, "turned": TURNED, "smooth": dict(mesh=grid_mesh(smooth=True, second_uv=True), **TURNED),
              "flat": dict(mesh=grid_mesh(smooth=False, second_uv=True), **TURNED)}
    for (shape, place), space, strength in itertools.product(shapes.items(), NORMAL_MAP_SPACES,
                                                               (1.0, 0.4, 2.5, 0.0, -0.5)):
        cases[f"{space}_{strength}_{shape}"] = Placed(_normal_map(space, strength), **place)
    for shape in ("smooth", "flat"):
        for uv in ("Second", "missing"):
            cases[f"TANGENT_{uv}_{shape}"] = Placed(_normal_map("TANGENT", 0.7, uv), **shapes[shape])
    _check(_bake(cases), len(cases))


def _displacement(kind: str, space: str, inputs: dict, field: str | None, normal: bool = False):
    """A (Vector) Displacement case, the input named `field` fed a varying colour/vector."""
    def build(nt):
        n = nt.nodes.new(kind)
        n.space = space
        for key, value in inputs.items():
            n.inputs[key].default_value = value
        if field is not None:
            source = _color_field(nt)
            if n.inputs[field].type == "VALUE":
                split = nt.nodes.new("ShaderNodeSeparateXYZ")
                nt.links.new(source, split.inputs[0])
                source = split.outputs["Y"]
            nt.links.new(source, n.inputs[field])
        if normal:
            nt.links.new(_color_field(nt, location=(0.1, -0.3, 0.9), rotation=(0.2, 0.5, -0.7)), n.inputs["Normal"])
        return n.outputs["Displacement"]
    return build


def test_displacement_vectors_match_cycles():
    cases = {}
    shapes = {"turned": TURNED, "smooth": dict(mesh=grid_mesh(smooth=True), **TURNED)}
    for (shape, place), space in itertools.product(shapes.items(), ("OBJECT", "WORLD")):
        for normal in (False, True):
            cases[f"disp_{space}_{shape}_{normal}"] = Placed(
                _displacement("ShaderNodeDisplacement", space, {"Midlevel": 0.3, "Scale": 1.7}, "Height", normal),
                **place)
        cases[f"disp_{space}_{shape}_const"] = Placed(
            _displacement("ShaderNodeDisplacement", space, {"Height": 0.9, "Midlevel": 0.5, "Scale": -2.0}, None),
            **place)
    vector_shapes = {**shapes, "flat": dict(mesh=grid_mesh(smooth=False), **TURNED), "plane": {}}
    for (shape, place), space in itertools.product(vector_shapes.items(), ("TANGENT", "OBJECT", "WORLD")):
        cases[f"vector_{space}_{shape}"] = Placed(
            _displacement("ShaderNodeVectorDisplacement", space, {"Midlevel": 0.4, "Scale": 1.3}, "Vector"), **place)
    _check(_bake(cases), len(cases))


# --- what a bake cannot set up: checked against Cycles' formulas ------------------------------

def _evaluate(kind: str, props: dict, inputs: dict, state, links=(), outputs=None):
    """The outputs of a node of `kind` evaluated on `state` ({output: value}, lazy ones called,
    only those in `outputs` if given); `links` names inputs to treat as linked."""
    from ember.engine.nodes.graph import Input, Link, Node
    from ember.engine.nodes.registry import REGISTRY

    sockets = tuple(Input(k, "vector" if np.ndim(v) else "value", 0.0, Link(0, "x", "vector") if k in links else None)
                    for k, v in inputs.items())
    node = Node(kind, "n", tuple(sorted(props.items())), sockets)
    out = REGISTRY[kind].evaluate(node, inputs, state)
    return {k: (v() if callable(v) else v) for k, v in out.items() if outputs is None or k in outputs}


def test_light_path_every_ray_kind():
    """Cycles' svm_node_light_path over the ray kinds a path tracer sets (kernel/types.h bits):
    each Is output tests its bits, Ray Depth counts one more for shadow rays and emission, the
    depths read the path's counters."""
    from ember.engine.nodes import light_path as lp
    from ember.engine.nodes.state import ShadingState

    kinds = [lp.CAMERA, lp.REFLECT | lp.DIFFUSE, lp.REFLECT | lp.GLOSSY, lp.REFLECT | lp.GLOSSY | lp.SINGULAR,
             lp.TRANSMIT | lp.GLOSSY, lp.TRANSMIT | lp.GLOSSY | lp.SINGULAR, lp.VOLUME_SCATTER, lp.SHADOW_OPAQUE,
             lp.SHADOW_TRANSPARENT | lp.DIFFUSE, lp.EMISSION | lp.REFLECT | lp.DIFFUSE, lp.TRANSPARENT,
             lp.EMISSION | lp.SHADOW_OPAQUE]
    n = len(kinds)
    rng = np.random.default_rng(5)
    counts = {f: rng.integers(0, 9, n) for f in ("bounce", "diffuse_bounce", "glossy_bounce", "transmission_bounce",
                                                 "transparent_bounce", "portal_bounce")}
    state = ShadingState(n, path_flag=np.array(kinds, np.uint32), ray_length=rng.uniform(0.1, 50.0, n), **counts)
    out = _evaluate("ShaderNodeLightPath", {}, {}, state)
    bits = {"Is Camera Ray": 1, "Is Shadow Ray": (1 << 9) | (1 << 10), "Is Diffuse Ray": 1 << 3,
            "Is Glossy Ray": 1 << 4, "Is Singular Ray": 1 << 5, "Is Reflection Ray": 1 << 1,
            "Is Transmission Ray": 1 << 2, "Is Volume Scatter Ray": 1 << 7}
    for name, mask in bits.items():
        np.testing.assert_array_equal(out[name], [1.0 if k & mask else 0.0 for k in kinds], err_msg=name)
    extra = [1.0 if k & ((1 << 9) | (1 << 10) | (1 << 20)) else 0.0 for k in kinds]
    np.testing.assert_array_equal(out["Ray Depth"], counts["bounce"] + np.array(extra))
    for name, field in (("Diffuse Depth", "diffuse_bounce"), ("Glossy Depth", "glossy_bounce"),
                        ("Transmission Depth", "transmission_bounce"), ("Transparent Depth", "transparent_bounce"),
                        ("Portal Depth", "portal_bounce")):
        np.testing.assert_array_equal(out[name], counts[field], err_msg=name)
    np.testing.assert_array_equal(out["Ray Length"], state.ray_length)


def _fresnel(cosi, eta):
    """The unpolarised dielectric reflectance, from the refracted cosine (reference)."""
    c = abs(cosi)
    sin_t2 = (1.0 - c * c) / (eta * eta)
    if sin_t2 >= 1.0:
        return 1.0
    t = math.sqrt(1.0 - sin_t2)
    rs = (c - eta * t) / (c + eta * t)
    rp = (eta * c - t) / (eta * c + t)
    return 0.5 * (rs * rs + rp * rp)


def test_backfacing_hits():
    """A bake never hits a back face; Cycles flips for one: Geometry's Backfacing is 1, Fresnel
    inverts its IOR, Layer Weight's Fresnel does not, an object-space normal map turns over."""
    from ember.engine.nodes.state import ShadingState

    rng = np.random.default_rng(9)
    n = 64
    N = rng.normal(size=(n, 3))
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    I = N + rng.normal(scale=0.6, size=(n, 3))
    I /= np.linalg.norm(I, axis=1, keepdims=True)
    back = rng.uniform(size=n) < 0.5
    m = np.eye(4)
    m[:3, :3] = [[1.3, 0.2, 0.0], [-0.1, 0.6, 0.3], [0.0, 0.4, 0.9]]
    state = ShadingState(n, N=N, I=I, backfacing=back, world_from_object=np.broadcast_to(m, (n, 4, 4)),
                         object_from_world=np.broadcast_to(np.linalg.inv(m), (n, 4, 4)))
    geometry = _evaluate("ShaderNodeNewGeometry", {}, {}, state, outputs=("Backfacing",))
    np.testing.assert_array_equal(geometry["Backfacing"], back.astype(float))
    fresnel = _evaluate("ShaderNodeFresnel", {}, {"IOR": 1.45, "Normal": 0.0}, state)["Fac"]
    cos = np.sum(I * N, axis=1)
    expected = [_fresnel(c, 1.0 / 1.45 if b else 1.45) for c, b in zip(cos, back)]
    np.testing.assert_allclose(fresnel, expected, atol=1e-9)
    layer = _evaluate("ShaderNodeLayerWeight", {}, {"Blend": 0.3, "Normal": 0.0}, state,
                      outputs=("Fresnel",))["Fresnel"]
    expected = [_fresnel(c, 0.7 if b else 1.0 / 0.7) for c, b in zip(cos, back)]
    np.testing.assert_allclose(layer, expected, atol=1e-9)
    color = np.array([0.8, 0.3, 0.6])
    normal = _evaluate("ShaderNodeNormalMap", {"space": "OBJECT"}, {"Strength": 1.0, "Color": color}, state)["Normal"]
    world = np.linalg.inv(m)[:3, :3].T @ (2.0 * color - 1.0)
    world /= np.linalg.norm(world)
    np.testing.assert_allclose(normal, np.where(back[:, None], -world, world), atol=1e-12)


def test_offset_state_moves_along_the_differential():
    """differentials.OffsetState on triangles facing every axis, front and back: the moved P is
    P + width dP a (a, b = make_orthonormals(Ng): Cycles' dPdx from the solved du, dv), and an
    attribute moves as its barycentric interpolation at the moved point does; on a back face
    at the point moved the other way (Cycles solves du, dv against the negated dPdu, dPdv)."""
    from ember.engine.nodes.differentials import OffsetState, make_orthonormals
    from ember.engine.nodes.state import Attribute, ShadingState

    rng = np.random.default_rng(11)
    n = 300
    corners = rng.normal(size=(n, 3, 3)) * rng.uniform(0.1, 3.0, (n, 1, 3))
    edges = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    ng = np.cross(*edges)
    ng /= np.linalg.norm(ng, axis=1, keepdims=True)
    flip = np.where(rng.uniform(size=n) < 0.5, -1.0, 1.0)[:, None]  # backfacing: Ng, dPdu, dPdv negated
    w = rng.dirichlet((1.0, 1.0, 1.0), n)
    P = np.einsum("nk,nkc->nc", w, corners)
    values = rng.normal(size=(n, 3, 2))
    value = np.einsum("nk,nkc->nc", w, values)

    class Source:
        def attribute(self, name):
            return Attribute("float2", value, values[:, 1] - values[:, 0], values[:, 2] - values[:, 0])

    dp = rng.uniform(0.001, 0.05, n)
    state = ShadingState(n, source=Source(), P=P, Ng=ng * flip, dP=dp, dPdu=edges[0] * flip, dPdv=edges[1] * flip,
                         barycentric=w[:, 1:])
    for axis, width in (("dx", 0.1), ("dy", 2.0)):
        moved = OffsetState(state, axis, width)
        a, b = make_orthonormals(ng * flip)
        step = (a if axis == "dx" else b) * (dp * width)[:, None]
        np.testing.assert_allclose(moved.P, P + step, atol=1e-9)
        # the moved point's weights, solved in the triangle's plane
        uv = moved.barycentric
        w_moved = np.stack([1.0 - uv[:, 0] - uv[:, 1], uv[:, 0], uv[:, 1]], axis=1)
        np.testing.assert_allclose(np.einsum("nk,nkc->nc", w_moved, corners), P + step * flip, atol=1e-9)
        np.testing.assert_allclose(moved.attribute("x").value, np.einsum("nk,nkc->nc", w_moved, values), atol=1e-9)
