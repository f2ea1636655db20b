"""depsgraph -> Scene export, checked against numbers computed here and against Blender."""
import math
import os
import tempfile

import numpy as np
import pytest

os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))
bpy = pytest.importorskip("bpy")

from ember.engine import scene as S  # noqa: E402
from ember.engine.blender.export import export_scene  # noqa: E402
from ember.engine.blender.export_camera import camera_window  # noqa: E402
from ember.engine.errors import Cancelled, EmberError  # noqa: E402

pytestmark = pytest.mark.blender


# --- helpers ----------------------------------------------------------------------------
def new_scene(camera=True, res=(64, 48)):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.resolution_x, sc.render.resolution_y = res
    sc.render.resolution_percentage = 100
    if camera:
        cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
        cam.location = (0.0, -10.0, 0.0)
        cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
        sc.collection.objects.link(cam)
        sc.camera = cam
    return sc


def export(**kw):
    return export_scene(bpy.context.evaluated_depsgraph_get(), **kw)


def cube(location=(0, 0, 0), size=2.0, **kw):
    bpy.ops.mesh.primitive_cube_add(size=size, location=location, **kw)
    return bpy.context.active_object


def add_light(kind, name=None, location=(0, 0, 0), rotation=(0, 0, 0), scale=(1, 1, 1), **props):
    data = bpy.data.lights.new(name or kind, kind)
    for k, v in props.items():
        setattr(data, k, v)
    ob = bpy.data.objects.new(name or kind, data)
    ob.location, ob.rotation_euler, ob.scale = location, rotation, scale
    bpy.context.scene.collection.objects.link(ob)
    return ob


def diffuse_material(name, color):
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    d = tree.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (*color, 1.0)
    tree.links.new(d.outputs[0], out.inputs["Surface"])
    return mat


def winding_normals(mesh):
    v = mesh.vertices.astype(np.float64)[mesh.triangles]
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    return n / np.linalg.norm(n, axis=1)[:, None]


def world_vertices(ob):
    """Blender's own evaluated vertices of `ob` in world space."""
    dg = bpy.context.evaluated_depsgraph_get()
    ev = ob.evaluated_get(dg)
    me = ev.to_mesh()
    co = np.array([(ev.matrix_world @ v.co)[:] for v in me.vertices])
    ev.to_mesh_clear()
    return co


def sort_rows(a):
    a = np.round(np.asarray(a, np.float64), 4)
    return a[np.lexsort(a.T[::-1])]


# --- meshes -----------------------------------------------------------------------------
def test_cube_with_modifier_and_transform():
    new_scene()
    ob = cube(location=(1, 2, 3), rotation=(0, 0, math.pi / 2), scale=(2, 1, 1))
    mod = ob.modifiers.new("sub", "SUBSURF")
    mod.subdivision_type, mod.levels, mod.render_levels = "SIMPLE", 1, 1
    sc, warnings = export()
    m = sc.mesh
    assert m.n_triangles == 6 * 4 * 2  # 24 quads after one simple subdivision
    assert m.vertices.dtype == np.float32 and m.triangles.dtype == np.int32
    assert m.normals.shape == (48, 3, 3) and m.material.shape == (48,)
    # Local [-1,1]^3, scale x2 along local x, rotated 90 deg about z, moved to (1,2,3).
    np.testing.assert_allclose(m.vertices.min(0), [0, 0, 2], atol=1e-5)
    np.testing.assert_allclose(m.vertices.max(0), [2, 4, 4], atol=1e-5)
    np.testing.assert_allclose(sort_rows(m.vertices), sort_rows(world_vertices(ob)), atol=1e-4)
    # Flat cube: every corner normal equals the outward winding normal.
    wn = winding_normals(m)
    centre = m.vertices[m.triangles].mean(1) - np.array([1, 2, 3])
    assert np.all(np.einsum("ij,ij->i", wn, centre) > 0)
    np.testing.assert_allclose(m.normals, np.repeat(wn[:, None], 3, 1), atol=1e-5)
    assert np.all(m.material == 0) and sc.materials.names == ("default",)
    assert warnings == []


def test_instances_collection_array_and_geometry_nodes(monkeypatch):
    from ember.engine.blender import export_mesh

    extracted = []
    real_extract = export_mesh.extract_mesh
    monkeypatch.setattr(export_mesh, "extract_mesh", lambda ob: extracted.append(ob.name) or real_extract(ob))
    sc = new_scene()
    col = bpy.data.collections.new("Proto")
    proto = cube(size=1.0)
    for c in proto.users_collection:
        c.objects.unlink(proto)
    col.objects.link(proto)
    for i, x in enumerate((10.0, 20.0)):
        e = bpy.data.objects.new(f"inst{i}", None)
        e.instance_type, e.instance_collection, e.location = "COLLECTION", col, (x, 0, 0)
        sc.collection.objects.link(e)
    arr = cube(location=(0, 5, 0), size=1.0)
    a = arr.modifiers.new("arr", "ARRAY")
    a.count, a.use_relative_offset, a.relative_offset_displace = 3, True, (2.0, 0, 0)

    # Geometry nodes: instance an icosphere (20 triangles) on the 4 corners of a plane.
    bpy.ops.mesh.primitive_plane_add(location=(0, -5, 0))
    plane = bpy.context.active_object
    ng = bpy.data.node_groups.new("inst", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    gi, go = ng.nodes.new("NodeGroupInput"), ng.nodes.new("NodeGroupOutput")
    iop, ico = ng.nodes.new("GeometryNodeInstanceOnPoints"), ng.nodes.new("GeometryNodeMeshIcoSphere")
    ng.links.new(gi.outputs[0], iop.inputs["Points"])
    ng.links.new(ico.outputs["Mesh"], iop.inputs["Instance"])
    ng.links.new(iop.outputs[0], go.inputs[0])
    plane.modifiers.new("gn", "NODES").node_group = ng

    m = export()[0].mesh
    assert m.n_triangles == 12 * 2 + 12 * 3 + 20 * 4
    # Each distinct evaluated mesh is extracted once: the collection cube (2 instances),
    # the arrayed cube, the plane's own (now empty) mesh and the icosphere (4 instances,
    # reported under the instancer's name).
    assert extracted == [proto.name, arr.name, plane.name, plane.name]
    xs = m.vertices[:, 0]
    # The two collection instances sit around x = 10 and x = 20 (cube of size 1).
    assert np.count_nonzero(np.abs(xs - 10) <= 0.5 + 1e-6) == 8
    assert np.count_nonzero(np.abs(xs - 20) <= 0.5 + 1e-6) == 8
    # Array: 3 cubes along x at 0, 2, 4 around y = 5.
    sel = np.abs(m.vertices[:, 1] - 5) <= 0.5 + 1e-6
    np.testing.assert_allclose(sorted(set(np.round(xs[sel], 4))), [-0.5, 0.5, 1.5, 2.5, 3.5, 4.5])
    # Icospheres (radius 1, 12 vertices each) centred on the plane's corners (+-1, -5 +-1, 0).
    ico_v = m.vertices[m.vertices[:, 1] < -3].astype(np.float64)
    assert len(ico_v) == 4 * 12
    centres = np.array([(x, -5 + y, 0) for x in (-1, 1) for y in (-1, 1)], np.float64)
    d = np.linalg.norm(ico_v[:, None] - centres[None], axis=2)
    np.testing.assert_allclose(d.min(1), 1.0, atol=1e-4)
    assert np.all(np.bincount(d.argmin(1), minlength=4) == 12)


@pytest.mark.parametrize("scale", [(-1.0, 2.0, 1.0), (-2.0, 2.0, 2.0)])  # general / similarity path
def test_negative_scale_keeps_normals_consistent(scale):
    new_scene()
    ob = cube(location=(0, 0, 0))
    bpy.ops.object.shade_smooth()  # corner normals differ from face normals (auto smooth off)
    ob.scale = scale
    m = export()[0].mesh
    wn = winding_normals(m)
    mean_n = m.normals.mean(1)
    mean_n /= np.linalg.norm(mean_n, axis=1)[:, None]
    # Winding normal and shading normals agree, and both point outwards.
    assert np.all(np.einsum("ij,ij->i", wn, mean_n) > 0.5)
    centre = m.vertices[m.triangles].mean(1)
    assert np.all(np.einsum("ij,ij->i", wn, centre) > 0)
    assert np.all(np.einsum("tcj,tj->tc", m.normals, centre) > 0)
    np.testing.assert_allclose(np.linalg.norm(m.normals, axis=2), 1.0, atol=1e-5)


def test_smooth_sphere_corner_normals():
    new_scene()
    bpy.ops.mesh.primitive_uv_sphere_add(radius=2.0, location=(1, 0, 0), segments=32, ring_count=16)
    bpy.ops.object.shade_smooth()
    ob = bpy.context.active_object
    m = export()[0].mesh
    p = m.vertices[m.triangles].astype(np.float64)  # (T,3,3) corner positions
    radial = (p - np.array([1, 0, 0])) / 2.0
    np.testing.assert_allclose(np.linalg.norm(radial, axis=2), 1.0, atol=1e-5)
    cos = np.einsum("tcj,tcj->tc", m.normals, radial)
    assert cos.min() > 0.999  # smooth vertex normals of a UV sphere are radial

    # Non-uniform scale: normals follow the inverse transpose (ellipsoid normal ~ x/a^2).
    ob.scale = (1.0, 1.0, 3.0)
    m = export()[0].mesh
    q = m.vertices[m.triangles].astype(np.float64) - np.array([1, 0, 0])
    grad = q / np.array([2.0, 2.0, 6.0]) ** 2
    grad /= np.linalg.norm(grad, axis=2)[..., None]
    assert np.einsum("tcj,tcj->tc", m.normals, grad).min() > 0.99


def test_fast_corner_triangles_match_blender(monkeypatch):
    from ember.engine.blender import export_mesh

    new_scene()
    rng = np.random.default_rng(1)
    me = bpy.data.meshes.new("mixed")
    verts = [(x, y, rng.uniform(-0.3, 0.3)) for y in range(4) for x in range(4)]  # non-planar quads
    faces = [(y * 4 + x, y * 4 + x + 1, y * 4 + x + 5, y * 4 + x + 4) for y in range(3) for x in range(2)]
    faces += [(2, 3, 7), (7, 6, 2), (6, 7, 11, 10), (10, 11, 15, 14)]
    base = len(verts)  # a concave, non-planar hexagon and a pentagon
    verts += [(10, 0, 0), (12, 0, 0.2), (12, 2, 0), (11, 1, 0.1), (10, 2, 0), (9, 1, 0.3)]
    faces.append(tuple(range(base, base + 6)))
    base = len(verts)
    verts += [(20, 0, 0), (21, 0, 0), (21.5, 1, 0.2), (20.5, 2, 0), (19.5, 1, -0.1)]
    faces.append(tuple(range(base, base + 5)))
    me.from_pydata(verts, [], faces)
    ob = bpy.data.objects.new("mixed", me)
    bpy.context.scene.collection.objects.link(ob)
    bpy.ops.mesh.primitive_circle_add(fill_type="NGON", vertices=12, location=(0, 10, 0))
    bpy.ops.mesh.primitive_monkey_add(location=(0, -10, 0))  # has concave (flipped) quads
    folded = bpy.data.meshes.new("folded")  # quads folded by various angles, one degenerate
    fv, ff = [], []
    for i, ang in enumerate(np.linspace(0.0, 3.0, 13)):
        o = len(fv)
        fv += [(3 * i, 0, 0), (3 * i + 1, -1, 0), (3 * i + 2, 0, 0), (3 * i + 1, np.cos(ang), np.sin(ang))]
        ff.append((o, o + 1, o + 2, o + 3))
    fv += [(50, 0, 0), (51, 0, 0), (52, 0, 0), (51, 1, 0)]  # v1 on the 0-2 diagonal
    ff.append((len(fv) - 4, len(fv) - 3, len(fv) - 2, len(fv) - 1))
    folded.from_pydata(fv, [], ff)
    bpy.context.scene.collection.objects.link(bpy.data.objects.new("folded", folded))
    dg = bpy.context.evaluated_depsgraph_get()
    for name in ("mixed", "Circle", "Suzanne", "folded"):
        ev = bpy.data.objects[name].evaluated_get(dg)
        m = ev.to_mesh()
        m.calc_loop_triangles()
        want = export_mesh.corner_tris_blender(m)
        np.testing.assert_array_equal(export_mesh.corner_tris(m), want, err_msg=name)
        monkeypatch.setattr(export_mesh, "PER_ELEMENT_LIMIT", 0)
        np.testing.assert_array_equal(export_mesh.corner_tris(m), want, err_msg=name)
        monkeypatch.undo()
        ev.to_mesh_clear()
    n, warnings = export()
    assert n.mesh.n_triangles == sum(len(f) - 2 for f in faces) + 10 + 968 + 2 * 14 - 1
    assert warnings == ["1 zero-area triangle(s) were dropped."]


def test_zero_area_triangles_dropped_with_one_warning():
    new_scene()
    me = bpy.data.meshes.new("degenerate")
    verts = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (2, 0, 0), (3, 0, 0), (4, 0, 0), (5, 0, 0), (6, 0, 0), (7, 0, 0)]
    me.from_pydata(verts, [], [(0, 1, 2), (3, 4, 5), (6, 7, 8)])
    ob = bpy.data.objects.new("deg", me)
    bpy.context.scene.collection.objects.link(ob)
    sc, warnings = export()
    assert sc.mesh.n_triangles == 1
    assert [w for w in warnings if "zero-area" in w] == ["2 zero-area triangle(s) were dropped."]


# --- materials --------------------------------------------------------------------------
def test_material_mapping_and_fallback_warnings():
    new_scene()
    red = diffuse_material("Red", (1.0, 0.0, 0.0))
    lamp = bpy.data.materials.new("Lamp")
    tree = lamp.node_tree
    tree.nodes.clear()
    out, em = tree.nodes.new("ShaderNodeOutputMaterial"), tree.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (1.0, 0.5, 0.25, 1.0)
    em.inputs["Strength"].default_value = 4.0
    tree.links.new(em.outputs[0], out.inputs["Surface"])
    tex = bpy.data.materials.new("Textured")  # Principled with an image texture on Base Color
    img = tex.node_tree.nodes.new("ShaderNodeTexImage")
    bsdf = tex.node_tree.nodes["Principled BSDF"]
    tex.node_tree.links.new(img.outputs["Color"], bsdf.inputs["Base Color"])
    glossy = bpy.data.materials.new("Glossy")
    gt = glossy.node_tree
    gt.nodes.clear()
    g_out, g = gt.nodes.new("ShaderNodeOutputMaterial"), gt.nodes.new("ShaderNodeBsdfGlossy")
    gt.links.new(g.outputs[0], g_out.inputs["Surface"])
    princ = bpy.data.materials.new("Plain")
    pb = princ.node_tree.nodes["Principled BSDF"]
    pb.inputs["Base Color"].default_value = (0.1, 0.2, 0.3, 1.0)
    pb.inputs["Emission Color"].default_value = (1.0, 1.0, 0.0, 1.0)
    pb.inputs["Emission Strength"].default_value = 2.0

    a = cube(location=(0, 0, 0))
    for mat in (red, lamp, tex, None, glossy, princ):
        a.data.materials.append(mat)
    # 6 faces -> slots 0..5 (slot 3 is empty -> default grey).
    a.data.polygons.foreach_set("material_index", [0, 1, 2, 3, 4, 5])
    a.data.update()
    # Second object shares the mesh; its object-linked slot 0 overrides Red with Textured.
    b = bpy.data.objects.new("B", a.data)
    b.location = (5, 0, 0)
    bpy.context.scene.collection.objects.link(b)
    b.material_slots[0].link = "OBJECT"
    b.material_slots[0].material = tex

    sc, warnings = export()
    mats, m = sc.materials, sc.mesh
    names = mats.names
    idx = {n: i for i, n in enumerate(names)}
    assert set(names) == {"Red", "Lamp", "Textured", "default", "Glossy", "Plain"}
    assert mats.kind[idx["Red"]] == S.MAT_DIFFUSE
    np.testing.assert_allclose(mats.base_color[idx["Red"]], [1, 0, 0])
    assert mats.kind[idx["Lamp"]] == S.MAT_EMISSION_ONLY
    np.testing.assert_allclose(mats.emission[idx["Lamp"]], [4.0, 2.0, 1.0])
    # No material: Cycles' default surface, a default Principled (specular over a 0.8 base).
    default_lobes = mats.lobe_kind[mats.lobe_material == idx["default"]]
    assert mats.kind[idx["default"]] == S.MAT_NODES and default_lobes.tolist() == [S.LOBE_MICROFACET, S.LOBE_DIFFUSE]
    np.testing.assert_allclose(mats.base_color[idx["default"]], [0.8, 0.8, 0.8], atol=1e-6)
    # Glossy BSDF: one GGX lobe (tests/test_export_material.py covers the node mapping).
    glossy_lobes = mats.lobe_kind[mats.lobe_material == idx["Glossy"]]
    assert mats.kind[idx["Glossy"]] == S.MAT_NODES and glossy_lobes.tolist() == [S.LOBE_MICROFACET]
    np.testing.assert_allclose(mats.base_color[idx["Plain"]], [0.1, 0.2, 0.3], atol=1e-6)
    np.testing.assert_allclose(mats.emission[idx["Plain"]], [2.0, 2.0, 0.0])
    # Exactly one warning for the image node without an image, naming material and node.
    assert len([w for w in warnings if "'Textured'" in w]) == 1
    assert any("Image Texture" in w and "no image" in w and "magenta" in w for w in warnings if "'Textured'" in w)
    assert len(warnings) == 1
    # Per-face mapping: 2 triangles per face, object a then b.
    centre = m.vertices[m.triangles].mean(1)
    on_a = centre[:, 0] < 2.5
    expected_a = ["Red", "Lamp", "Textured", "default", "Glossy", "Plain"]
    expected_b = ["Textured", "Lamp", "Textured", "default", "Glossy", "Plain"]
    for on, expected in ((on_a, expected_a), (~on_a, expected_b)):
        got = [names[i] for i in m.material[on]]
        assert sorted(got) == sorted(n for n in expected for _ in range(2))
    # The face at +x of cube a is face index 2 or so; check one concrete face: slot 0 face.
    a_normals = winding_normals(m)[on_a]
    a_mats = np.array([names[i] for i in m.material[on_a]])
    poly0 = np.array(a.data.polygons[0].normal)
    assert set(a_mats[np.abs(a_normals @ poly0 - 1) < 1e-5]) == {"Red"}


# --- lights -----------------------------------------------------------------------------
def _light(sc, name):
    i = sc.lights.names.index(name)
    return {f: getattr(sc.lights, f)[i] for f in ("kind", "position", "frame", "size", "radius", "Le",
                                                  "spot_cos_half", "spot_smooth", "sun_half_angle", "visible", "soft")}


def test_lights_in_cycles_units():
    new_scene()
    cube()
    col = (1.0, 0.5, 0.25)
    add_light("POINT", "Point", location=(1, 2, 3), energy=100.0, color=col, shadow_soft_size=0.1, exposure=1.0)
    add_light("POINT", "Delta", energy=100.0, color=col, shadow_soft_size=0.0)
    add_light("POINT", "Raw", energy=100.0, color=col, shadow_soft_size=0.1, normalize=False,
              use_soft_falloff=False)
    add_light("SPOT", "Spot", rotation=(math.pi / 2, 0, 0), energy=50.0, shadow_soft_size=0.0,
              spot_size=math.radians(60), spot_blend=0.25)
    add_light("SUN", "Sun", energy=3.0, angle=math.radians(10))
    add_light("SUN", "SharpSun", energy=3.0, angle=0.0)
    add_light("AREA", "Rect", rotation=(0, 0, math.pi / 2), scale=(2, 3, 1), energy=60.0,
              shape="RECTANGLE", size=2.0, size_y=0.5)
    add_light("AREA", "Ellipse", energy=10.0, shape="ELLIPSE", size=1.0, size_y=2.0)
    add_light("AREA", "Square", energy=10.0, shape="SQUARE", size=0.5)
    add_light("POINT", "Warm", energy=10.0, use_temperature=True, temperature=3000.0, shadow_soft_size=0.0)
    add_light("POINT", "Off", energy=0.0)  # contributes nothing -> dropped
    bpy.data.objects["Point"].visible_camera = True
    bpy.data.objects["Delta"].visible_camera = False
    sc, warnings = export()
    assert "Off" not in sc.lights.names and len(sc.lights) == 10
    c = np.array(col)

    p = _light(sc, "Point")
    assert p["kind"] == S.LIGHT_POINT and p["radius"] == pytest.approx(0.1) and p["visible"]
    assert p["soft"] and not _light(sc, "Raw")["soft"]  # Blender's default is Soft Falloff on
    np.testing.assert_allclose(p["position"], [1, 2, 3], atol=1e-6)
    np.testing.assert_allclose(p["Le"], c * 200.0 / (math.pi * 4 * math.pi * 0.01), rtol=1e-5)
    d = _light(sc, "Delta")
    assert d["radius"] == 0 and not d["visible"]
    np.testing.assert_allclose(d["Le"], c * 100.0 / (4 * math.pi), rtol=1e-6)  # W/sr
    np.testing.assert_allclose(_light(sc, "Raw")["Le"], c * 100.0 / math.pi, rtol=1e-6)

    s = _light(sc, "Spot")
    assert s["kind"] == S.LIGHT_SPOT
    assert s["spot_cos_half"] == pytest.approx(math.cos(math.radians(30)), rel=1e-6)
    assert s["spot_smooth"] == pytest.approx((1 - math.cos(math.radians(30))) * 0.25, rel=1e-5)
    np.testing.assert_allclose(s["Le"], np.full(3, 50.0 / (4 * math.pi)), rtol=1e-6)
    # Rotated 90 deg about x: local -z (the beam) points along world +y.
    np.testing.assert_allclose(-s["frame"][2], [0, 1, 0], atol=1e-6)
    np.testing.assert_allclose(s["frame"] @ s["frame"].T, np.eye(3), atol=1e-6)

    sun = _light(sc, "Sun")
    assert sun["kind"] == S.LIGHT_SUN and sun["sun_half_angle"] == pytest.approx(math.radians(5), rel=1e-6)
    np.testing.assert_allclose(sun["Le"], 3.0 / (math.pi * math.sin(math.radians(5)) ** 2), rtol=1e-5)
    np.testing.assert_allclose(_light(sc, "SharpSun")["Le"], 3.0, rtol=1e-6)  # irradiance

    r = _light(sc, "Rect")
    assert r["kind"] == S.LIGHT_RECT
    np.testing.assert_allclose(r["size"], [2.0, 0.75], rtol=1e-6)  # half extents incl. scale
    np.testing.assert_allclose(r["Le"], 60.0 / (math.pi * 4.0 * 1.5), rtol=1e-5)
    np.testing.assert_allclose(r["frame"][0], [0, 1, 0], atol=1e-6)  # unit axes, rotated
    np.testing.assert_allclose(r["frame"][1], [-1, 0, 0], atol=1e-6)
    e = _light(sc, "Ellipse")
    assert e["kind"] == S.LIGHT_DISK
    np.testing.assert_allclose(e["size"], [0.5, 1.0])
    np.testing.assert_allclose(e["Le"], 10.0 / (math.pi * math.pi / 4 * 2.0), rtol=1e-5)
    sq = _light(sc, "Square")
    np.testing.assert_allclose(sq["size"], [0.25, 0.25])
    np.testing.assert_allclose(sq["Le"], 10.0 / (math.pi * 0.25), rtol=1e-5)

    warm = _light(sc, "Warm")
    tc = np.array(bpy.data.lights["Warm"].temperature_color[:3])
    assert tc[0] > tc[2]  # 3000 K is reddish
    np.testing.assert_allclose(warm["Le"], tc * 10.0 / (4 * math.pi), rtol=1e-5)
    assert warnings == []


def test_light_warnings_once():
    new_scene()
    cube()
    add_light("AREA", "Narrow", energy=10.0, spread=math.radians(30))
    add_light("AREA", "Narrow2", energy=10.0, spread=math.radians(30))
    bpy.data.lights["Narrow2"].use_shadow = False
    _, warnings = export()
    spread = [w for w in warnings if "spread" in w]
    assert len(spread) == 1 and "'Narrow'" in spread[0] and "'Narrow2'" in spread[0]
    assert len(warnings) == 1  # a light without shadows is rendered as one (no blockers)


# --- world ------------------------------------------------------------------------------
def test_world_background():
    sc = new_scene()
    cube()
    np.testing.assert_allclose(export()[0].world.color, 0.0)  # no world: black
    sc.world = bpy.data.worlds.new("W2")
    bg = sc.world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.5, 0.25, 1.0, 1.0)
    bg.inputs["Strength"].default_value = 2.0
    w, warnings = export()
    np.testing.assert_allclose(w.world.color, [1.0, 0.5, 2.0])
    assert w.world.visible and warnings == []
    sc.render.film_transparent = True
    assert not export()[0].world.visible
    sc.render.film_transparent = False
    sc.world.cycles_visibility.camera = False
    assert not export()[0].world.visible
    sky = sc.world.node_tree.nodes.new("ShaderNodeTexSky")
    sc.world.node_tree.links.new(sky.outputs[0], bg.inputs["Color"])
    w, warnings = export()  # a Sky Texture: the world's node graph (engine/lights/world.py)
    assert w.world.graph and w.world.graph[0].nodes[0].kind == "ShaderNodeTexSky" and warnings == []
    # The view layer's Environment toggle off: no background at all (as Cycles).
    bpy.context.view_layer.use_sky = False
    np.testing.assert_allclose(export()[0].world.color, 0.0)


# --- camera -----------------------------------------------------------------------------
def _window_from_projection(P, ortho):
    P = np.array(P)
    if ortho:
        l_plus_r, r_minus_l = -P[0, 3] * 2 / P[0, 0], 2 / P[0, 0]
        b_plus_t, t_minus_b = -P[1, 3] * 2 / P[1, 1], 2 / P[1, 1]
    else:  # at z = -1 (near = 1 after normalising)
        r_minus_l, l_plus_r = 2 / P[0, 0], P[0, 2] * 2 / P[0, 0]
        t_minus_b, b_plus_t = 2 / P[1, 1], P[1, 2] * 2 / P[1, 1]
    return np.array([(l_plus_r - r_minus_l) / 2, (l_plus_r + r_minus_l) / 2,
                     (b_plus_t - t_minus_b) / 2, (b_plus_t + t_minus_b) / 2])


def test_camera_window_matches_blender_projection():
    sc = new_scene()
    cube()
    cam_ob = sc.camera
    cam = cam_ob.data
    cam.lens, cam.sensor_width, cam.sensor_height, cam.ortho_scale = 42.0, 36.0, 20.0, 7.0
    checked = 0
    for kind in ("PERSP", "ORTHO"):
        for fit in ("AUTO", "HORIZONTAL", "VERTICAL"):
            for (w, h) in ((64, 48), (30, 80), (50, 50)):
                for shift in ((0.0, 0.0), (0.2, -0.1)):
                    for aspect in ((1.0, 1.0), (2.0, 1.0), (1.0, 3.0)):
                        cam.type, cam.sensor_fit = kind, fit
                        cam.shift_x, cam.shift_y = shift
                        sc.render.resolution_x, sc.render.resolution_y = w, h
                        sc.render.pixel_aspect_x, sc.render.pixel_aspect_y = aspect
                        dg = bpy.context.evaluated_depsgraph_get()
                        P = cam_ob.evaluated_get(dg).calc_matrix_camera(
                            dg, x=w, y=h, scale_x=aspect[0], scale_y=aspect[1])
                        expected = _window_from_projection(P, kind == "ORTHO")
                        window = camera_window(
                            ortho=kind == "ORTHO", lens=cam.lens, sensor_width=cam.sensor_width,
                            sensor_height=cam.sensor_height, sensor_fit=fit, ortho_scale=cam.ortho_scale,
                            shift_x=shift[0], shift_y=shift[1], width=w, height=h,
                            pixel_aspect_x=aspect[0], pixel_aspect_y=aspect[1])
                        np.testing.assert_allclose(window, expected, rtol=1e-5, atol=1e-6,
                                                   err_msg=f"{kind} {fit} {w}x{h} {shift} {aspect}")
                        checked += 1
    assert checked == 108
    # Through the full export: camera frame without scale, window for the final resolution.
    cam.type, cam.sensor_fit, cam.shift_x, cam.shift_y = "PERSP", "AUTO", 0.0, 0.0
    sc.render.resolution_x, sc.render.resolution_y = 64, 32
    sc.render.pixel_aspect_x = sc.render.pixel_aspect_y = 1.0
    cam_ob.scale = (2.0, 2.0, 2.0)
    c = export()[0].camera
    assert not c.ortho
    np.testing.assert_allclose(c.window, [-18 / 42, 18 / 42, -9 / 42, 9 / 42], rtol=1e-6)
    np.testing.assert_allclose(c.world_from_camera[:3, :3].T @ c.world_from_camera[:3, :3], np.eye(3), atol=1e-6)
    np.testing.assert_allclose(c.world_from_camera[:3, 2], [0, -1, 0], atol=1e-6)  # looks down -z = +y
    np.testing.assert_allclose(c.world_from_camera[:3, 3], [0, -10, 0], atol=1e-6)


# --- settings, view layers, errors, cancel ---------------------------------------------------
_rendered = []


class _ExportTestEngine(bpy.types.RenderEngine):
    """Calls export_scene from a real render (RENDER-mode depsgraph, one call per view layer)."""

    bl_idname = "EMBER_EXPORT_TEST"
    bl_label = "Ember export test"

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)

    def render(self, depsgraph):
        res = self.begin_result(0, 0, self.resolution_x, self.resolution_y, layer=depsgraph.view_layer.name)
        pixels = None if res is None else len(res.layers[0].passes["Combined"].rect)
        self.end_result(res)
        try:
            _rendered.append((depsgraph.view_layer.name, pixels, export_scene(depsgraph)))
        except Exception as exc:  # noqa: BLE001 - reported by the test
            _rendered.append((depsgraph.view_layer.name, pixels, exc))


@pytest.fixture(scope="module")
def test_engine():
    bpy.utils.register_class(_ExportTestEngine)
    yield _rendered
    bpy.utils.unregister_class(_ExportTestEngine)


def test_resolution_percentage_and_border(test_engine):
    sc = new_scene(res=(101, 75))
    cube()
    sc.render.resolution_percentage = 50
    s = export()[0].settings
    assert (s.width, s.height, s.border) == (50, 37, (0, 0, 50, 37))
    sc.render.use_border = True
    sc.render.border_min_x, sc.render.border_max_x = 0.1, 0.5
    sc.render.border_min_y, sc.render.border_max_y = 0.25, 0.75  # measured from the bottom
    s = export()[0].settings
    # x: int(0.1*50)=5 .. int(0.5*50)=25; y (bottom-up): int(0.25*37)=9 .. int(0.75*37)=27
    assert s.border == (5, 37 - 27, 25, 37 - 9)
    # Blender's own border result has exactly that many pixels.
    sc.render.engine = "EMBER_EXPORT_TEST"
    test_engine.clear()
    bpy.ops.render.render()
    (layer, pixels, result), = test_engine
    x0, y0, x1, y1 = result[0].settings.border
    assert pixels == (x1 - x0) * (y1 - y0) == 20 * 18
    # Ember settings defaults without the add-on, and overrides winning.
    assert (s.samples, s.max_depth, s.seed, s.filter, s.filter_width) == (16, 64, 0, "BLACKMAN_HARRIS", 1.5)
    sc.cycles.pixel_filter_type, sc.cycles.filter_width = "GAUSSIAN", 2.0
    s = export(overrides=dict(width=200, height=100, samples=7, seed=3, integrator="PATH", time_limit=None))[0].settings
    assert (s.width, s.height, s.samples, s.seed, s.integrator) == (200, 100, 7, 3, "path")
    assert (s.filter, s.filter_width) == ("GAUSSIAN", 2.0)
    assert s.border == (20, 100 - 75, 100, 100 - 25)  # border fractions applied to the new size
    with pytest.raises(EmberError, match="Unknown setting"):
        export(overrides=dict(sampels=4))


def test_settings_from_ember_properties():
    from types import SimpleNamespace as NS

    from ember.engine.blender.export_settings import export_settings

    render = NS(resolution_x=320, resolution_y=240, resolution_percentage=25, use_border=False)
    ember = NS(integrator="PATH", samples=128, max_depth=8, seed=5, time_limit=2.5, batch_size=1024)
    s = export_settings(NS(render=render, ember=ember))
    assert (s.width, s.height, s.border) == (80, 60, (0, 0, 80, 60))
    assert (s.integrator, s.samples, s.max_depth, s.seed, s.time_limit, s.batch_size) == ("path", 128, 8, 5, 2.5, 1024)
    assert (s.filter, s.filter_width) == ("BLACKMAN_HARRIS", 1.5)  # no scene.cycles
    assert s.pattern == "sobol"  # the default, also without scene.ember.pattern
    assert export_settings(NS(render=render, ember=NS(pattern="RANDOM"))).pattern == "random"
    with pytest.raises(EmberError, match="pattern"):
        export_settings(NS(render=render), overrides=dict(pattern="halton"))
    s = export_settings(NS(render=render, ember=ember), overrides=dict(samples=3, max_depth=2))
    assert (s.samples, s.max_depth, s.seed) == (3, 2, 5)
    with pytest.raises(EmberError, match="integrator must be one of: path, .* \\(got 'nope'\\)"):
        export_settings(NS(render=render, ember=NS(integrator="NOPE")))
    with pytest.raises(EmberError, match="samples must be at least 1"):
        export_settings(NS(render=render), overrides=dict(samples=0))


def test_view_layers_and_hide_render(test_engine):
    sc = new_scene()
    sc.render.engine = "EMBER_EXPORT_TEST"
    extra = bpy.data.collections.new("Extra")
    sc.collection.children.link(extra)
    cube(location=(0, 0, 0))
    hidden = cube(location=(0, 0, 5))
    hidden.hide_render = True
    other = cube(location=(4, 0, 0))
    for c in other.users_collection:
        c.objects.unlink(other)
    extra.objects.link(other)
    second = sc.view_layers.new("Second")
    second.layer_collection.children["Extra"].exclude = True
    second.material_override = diffuse_material("Override", (0.0, 1.0, 0.0))
    test_engine.clear()
    bpy.ops.render.render()
    by_layer = {name: result for name, _, result in test_engine}
    assert set(by_layer) == {"ViewLayer", "Second"}
    for r in by_layer.values():
        assert not isinstance(r, Exception), r
    assert by_layer["ViewLayer"][0].mesh.n_triangles == 24  # hide_render cube dropped
    assert by_layer["Second"][0].mesh.n_triangles == 12
    assert by_layer["ViewLayer"][0].mesh.vertices[:, 2].max() < 2
    assert by_layer["ViewLayer"][0].materials.names == ("default",)
    second_scene = by_layer["Second"][0]
    assert second_scene.materials.names == ("Override",)
    assert np.all(second_scene.mesh.material == 0)
    np.testing.assert_allclose(second_scene.materials.base_color[0], [0, 1, 0])


def test_errors_for_unrenderable_scenes():
    new_scene(camera=False)
    cube()
    with pytest.raises(EmberError, match="no camera"):
        export()
    new_scene()
    with pytest.raises(EmberError, match="Nothing to render"):
        export()
    sc = new_scene()
    cube()
    sc.camera.data.type = "PANO"  # panoramic cameras export (tests/test_panorama.py)...
    sc.camera.data.panorama_type = "EQUIRECTANGULAR"
    assert export()[0].camera.panorama == "EQUIRECTANGULAR"
    sc.camera.data.latitude_min = sc.camera.data.latitude_max = 0.3  # ... unless their range is empty
    with pytest.raises(EmberError, match="empty panorama range"):
        export()
    # Objects invisible to every ray type are skipped; a light alone is renderable.
    sc = new_scene()
    ob = cube()
    for f in ("visible_camera", "visible_diffuse", "visible_glossy", "visible_transmission", "visible_shadow"):
        setattr(ob, f, False)
    with pytest.raises(EmberError, match="Nothing to render"):
        export()
    add_light("POINT")
    scene, _ = export()
    assert scene.mesh.n_triangles == 0 and len(scene.lights) == 1
    # Partly visible objects are rendered, their ray visibility per triangle.
    ob.visible_shadow = True
    cube(location=(3, 0, 0)).visible_camera = False
    scene, warnings = export()
    assert scene.mesh.n_triangles == 24 and not warnings
    assert sorted(set(scene.mesh.visibility.tolist())) == [S.RAY_SHADOW, S.RAY_ALL & ~S.RAY_CAMERA]


def test_ray_visibility_of_objects_lights_and_world():
    """Cycles' visibility checkboxes (Object > Visibility > Ray Visibility, the world's Ray
    Visibility) and Holdout become RAY_* bits; a scene without any has no per-triangle array."""
    sc = new_scene()
    ob = cube()
    light = add_light("POINT")
    scene, _ = export()
    assert scene.mesh.visibility is None and scene.world.ray_visibility == S.RAY_ALL
    assert scene.lights.ray_visibility.tolist() == [S.RAY_ALL & ~S.RAY_CAMERA]  # Blender's default for lights
    light.visible_camera = True
    assert export()[0].lights.ray_visibility.tolist() == [S.RAY_ALL]
    ob.visible_glossy = False
    ob.is_holdout = True
    light.visible_diffuse = False
    light.visible_camera = False
    sc.world = bpy.data.worlds.new("W")
    sc.world.cycles_visibility.transmission = False
    scene, warnings = export()
    assert not warnings
    assert set(scene.mesh.visibility.tolist()) == {(S.RAY_ALL & ~S.RAY_GLOSSY) | S.HOLDOUT}
    assert scene.lights.ray_visibility.tolist() == [S.RAY_ALL & ~S.RAY_DIFFUSE & ~S.RAY_CAMERA]
    assert not scene.lights.visible[0]
    assert scene.world.ray_visibility == S.RAY_ALL & ~S.RAY_TRANSMIT


def test_depth_of_field_as_cycles_reads_it():
    """Aperture radius lens / (2 f-stop) in metres (Cycles' blender/camera.cpp), the focus
    object's distance along the view axis, 0 blades meaning round."""
    sc = new_scene()
    cube()
    cam = sc.camera
    assert export()[0].camera.aperture_radius == 0.0  # DOF off: a pinhole
    cam.data.lens = 50.0
    dof = cam.data.dof
    dof.use_dof, dof.aperture_fstop, dof.focus_distance = True, 2.0, 7.5
    dof.aperture_blades, dof.aperture_rotation, dof.aperture_ratio = 0, 0.5, 1.5
    c = export()[0].camera
    assert c.aperture_radius == pytest.approx(0.05 / 4.0)
    assert (c.focus_distance, c.blades, c.blade_rotation, c.aperture_ratio) == (7.5, 0, 0.5, 1.5)
    dof.aperture_blades = 6
    target = bpy.data.objects.new("Target", None)
    sc.collection.objects.link(target)
    target.location = cam.matrix_world @ __import__("mathutils").Vector((1.0, 0.5, -3.0))  # 3 m ahead, off axis
    bpy.context.view_layer.update()
    c = export()[0].camera
    assert c.blades == 6
    dof.focus_object = target
    bpy.context.view_layer.update()
    assert export()[0].camera.focus_distance == pytest.approx(3.0, rel=1e-5)
    cam.data.type = "ORTHO"
    assert export()[0].camera.aperture_radius == pytest.approx(1.0 / 4.0)


def test_cancel_and_progress():
    new_scene()
    cube()
    with pytest.raises(Cancelled):
        export(test_break=lambda: True)
    # Many instances: cancellation is polled during the instance walk too.
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=50, y_subdivisions=50)
    grid = bpy.context.active_object
    grid.instance_type = "VERTS"
    src = cube(location=(0, 0, 3), size=0.01)
    src.parent = grid
    calls = []

    def stop_on_third():
        calls.append(1)
        return len(calls) >= 3

    messages = []
    with pytest.raises(Cancelled):
        export(test_break=stop_on_third, progress=messages.append)
    assert len(calls) == 3
    messages.clear()
    sc, _ = export(progress=messages.append)
    n_verts, n_quads = len(grid.data.vertices), len(grid.data.polygons)
    assert n_verts > 2000
    # One small cube per grid vertex plus the child itself, the first cube, the grid.
    assert sc.mesh.n_triangles == 12 * (n_verts + 1) + 12 + 2 * n_quads
    assert any(m.startswith("Export: meshes") for m in messages)
    assert sc.materials.names == ("default",)


def test_photon_settings_from_ember_properties():
    from types import SimpleNamespace as NS

    from ember.engine.blender.export_settings import export_settings

    render = NS(resolution_x=64, resolution_y=64, resolution_percentage=100, use_border=False)
    ember = NS(integrator="PPM", photons=1234, caustic_photons=0, photon_k=20, global_radius=0.5, caustic_radius=0.1,
               gather_rays=4, radiance_photons=False, ppm_radius=0.25, ppm_alpha=0.5, photon_view="CAUSTIC",
               photon_kernel="EPANECHNIKOV")
    s = export_settings(NS(render=render, ember=ember))
    assert (s.integrator, s.photons, s.caustic_photons, s.photon_k, s.gather_rays) == ("ppm", 1234, 0, 20, 4)
    assert (s.global_radius, s.caustic_radius, s.radiance_photons, s.ppm_radius, s.ppm_alpha) == (0.5, 0.1, False, 0.25, 0.5)
    assert (s.photon_view, s.photon_kernel) == ("caustic", "epanechnikov")
    with pytest.raises(EmberError, match="alpha"):
        export_settings(NS(render=render, ember=NS(ppm_alpha=1.5)))
