"""The shading state of rendered hits (engine/nodes/hits.py) and materials that read it, against
Cycles.

First the state itself: objects exported as a render exports them (engine/blender/export.py:
the Mesh carries what their material's programs read) give at points of their triangles the
same state as the bake harness builds from Blender's data (tests/node_bake.py _Surface, which
the input-node tests hold to Cycles' bakes): the hit's triangle in Cycles' corner order also
on a negatively scaled instance, the normals' and coordinates' derivatives, named attributes
of every domain, Object Info, the material's pass index.

Then renders, Ember against Cycles as in tests/test_nodes_render.py (SEEDS renders each, the
image's and quadrants' means within TOL plus the noise band), of scenes whose quadrants each
show one use of the state: colour attributes (byte and float), a named second UV map, Object
Info's colour, random and pass index over several objects, a tangent-space Normal Map from an
image, a Bump from a noise texture, displacement as bump, Backfacing, and a Light Path mix that
the camera sees in one colour and a mirror reflects in another."""
import math
import pickle

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

import ember  # noqa: E402
import node_bake  # noqa: E402
from cycles_scenes import new_scene, node_material  # noqa: E402
from ember.engine.blender.export import export_scene  # noqa: E402
from ember.engine.nodes.hits import RayState, SurfaceHits  # noqa: E402
from ember.engine.nodes.material import MaterialPrograms  # noqa: E402
from ember.engine.nodes.state import ShadingState  # noqa: E402
from ember.engine.scene import Scene, part_digest, recentred, scene_from_plain, to_plain  # noqa: E402
from cycles_renders import agree, cycles_image, ember_image  # noqa: E402

pytestmark = pytest.mark.blender


@pytest.fixture(scope="module", autouse=True)
def addon():
    ember.register()
    yield
    ember.unregister()


# --- the state at hits ---------------------------------------------------------------------------
def _height(x, y):
    return 0.35 * np.sin(2.1 * x + 0.4) * np.cos(1.7 * y - 0.3) + 0.1 * x * y


def grid(name: str, cells: int = 6, smooth: bool = True, height=_height, colors: bool = True):
    """A mesh over [-1, 1]^2 of cells x cells quads lifted by height(x, y), with the UV map
    "UVMap" over the unit square (active, rendered), a second map "Second", a byte colour
    attribute "Col" per corner, a float colour "FCol" per vertex and a float "Weight" per face."""
    verts, faces, uvs = [], [], []
    for i in range(cells + 1):
        for j in range(cells + 1):
            x, y = -1.0 + 2.0 * i / cells, -1.0 + 2.0 * j / cells
            verts.append((x, y, float(height(x, y))))
    for i in range(cells):
        for j in range(cells):
            quad = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]
            faces.append(tuple(a * (cells + 1) + b for a, b in quad))
            uvs.append([(a / cells, b / cells) for a, b in quad])
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    flat = np.array(uvs, np.float64).reshape(-1, 2)
    mesh.uv_layers.new(name="UVMap").data.foreach_set("uv", flat.ravel())
    second = np.stack([0.2 + 0.5 * flat[:, 1] + 0.1 * flat[:, 0], 0.9 - 0.6 * flat[:, 0] + 0.05 * flat[:, 1]], axis=1)
    mesh.uv_layers.new(name="Second").data.foreach_set("uv", second.ravel())
    mesh.uv_layers.active = mesh.uv_layers["UVMap"]
    mesh.uv_layers["UVMap"].active_render = True
    n_loops = len(mesh.loops)
    corner = np.stack([0.5 + 0.4 * np.sin(7.0 * flat[:, 0]), 0.5 + 0.4 * np.cos(5.0 * flat[:, 1]),
                       np.linspace(0.1, 0.9, n_loops), np.linspace(1.0, 0.3, n_loops)], axis=1)
    if colors:
        mesh.color_attributes.new("Col", "BYTE_COLOR", "CORNER").data.foreach_set("color", corner.ravel())
    co = np.array(verts)
    point = np.stack([0.5 + 0.5 * co[:, 0], 0.5 - 0.3 * co[:, 1], 0.3 + co[:, 2], np.full(len(co), 0.7)], axis=1)
    mesh.color_attributes.new("FCol", "FLOAT_COLOR", "POINT").data.foreach_set("color", point.ravel())
    mesh.attributes.new("Weight", "FLOAT", "FACE").data.foreach_set("value", np.linspace(0, 1, len(faces)))
    mesh.polygons.foreach_set("use_smooth", [smooth] * len(faces))
    mesh.update()
    return mesh


_NAMES = ("Col", "FCol", "Weight", "Second", "Second.tangent", "Second.tangent_sign", "pointiness",
          "random_per_island", "\x01object:prop", "uv", "generated", "Nothing")


def _reading_material(name: str, pass_index: int):
    """A material whose emission sums everything the state test compares: each named attribute,
    Object Info, the Geometry node, the UV and generated coordinates (what decides what the
    export carries)."""
    mat = bpy.data.materials.new(name)
    mat.pass_index = pass_index
    nt = mat.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    emission = nt.nodes.new("ShaderNodeEmission")
    nt.links.new(emission.outputs[0], out.inputs["Surface"])
    sockets = []
    for attr in _NAMES:
        node = nt.nodes.new("ShaderNodeAttribute")
        node.attribute_type, node.attribute_name = ("OBJECT", attr[len("\x01object:"):]) if attr.startswith("\x01") \
            else ("GEOMETRY", attr)
        sockets += [node.outputs["Vector"], node.outputs["Alpha"]]
    info = nt.nodes.new("ShaderNodeObjectInfo")
    sockets += [info.outputs["Color"], info.outputs["Random"], info.outputs["Object Index"],
                info.outputs["Material Index"], info.outputs["Alpha"]]
    geometry = nt.nodes.new("ShaderNodeNewGeometry")
    sockets += [geometry.outputs["Parametric"], geometry.outputs["Backfacing"]]
    total = sockets[0]
    for socket in sockets[1:]:
        add = nt.nodes.new("ShaderNodeVectorMath")
        nt.links.new(total, add.inputs[0])
        nt.links.new(socket, add.inputs[1])
        total = add.outputs["Vector"]
    nt.links.new(total, emission.inputs["Color"])
    return mat


def _object(mesh, name, location, rotation, scale, color, pass_index, prop):
    ob = bpy.data.objects.new(name, mesh)
    bpy.context.collection.objects.link(ob)
    ob.location, ob.rotation_euler, ob.scale = location, rotation, scale
    ob.color, ob.pass_index = color, pass_index
    ob["prop"] = prop
    return ob


def test_hits_give_the_state_the_bake_harness_builds():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    camera = node_bake._camera()
    smooth, flat, plain = grid("smooth"), grid("flat", smooth=False), grid("plain", colors=False)
    for mesh, k in ((smooth, 3), (flat, 5)):
        mesh.materials.append(_reading_material(f"reads{k}", k))
    plain.materials.append(smooth.materials[0])  # one material over meshes with and without "Col"
    objects = [_object(smooth, "Turned", (0.3, 0.5, -0.4), (0.4, -0.7, 1.1), (1.3, 0.6, 0.9), (0.9, 0.2, 0.1, 0.8), 2,
                       (0.25, 0.5, 0.75)),
               _object(smooth, "Mirrored", (-2.5, 0.2, 0.3), (0.2, 0.3, -0.5), (-1.2, 0.8, 1.0), (0.1, 0.7, 0.3, 1.0),
                       7, 0.5),
               _object(flat, "Flat \u00e9", (2.4, -0.5, 0.1), (-0.3, 0.1, 0.2), (0.9, 1.1, -0.7), (0.3, 0.3, 0.9, 0.5),
                       4, (1.0, 2.0)),
               _object(plain, "Plain", (0.0, 2.6, 0.0), (0.0, 0.0, 0.3), (1.0, 1.0, 1.0), (1.0, 1.0, 1.0, 1.0), 0, 2.0)]
    bpy.context.view_layer.update()
    scene, _ = export_scene(bpy.context.evaluated_depsgraph_get())
    mesh = scene.mesh
    assert set(mesh.attributes) == set(_NAMES) - {"\x01object:prop", "uv", "generated"}
    world_from_camera = node_bake._world_from_camera(camera)
    batch, wanted = [], []
    for ob in objects:
        b = next(i for i, m in enumerate(mesh.object_matrix) if np.allclose(m, np.array(ob.matrix_world)))
        for side in (1.0, -1.0):  # seen from the camera's side, then from behind (backfacing hits)
            surface = node_bake._Surface(ob, 16, camera, world_from_camera, "ACTIVE_CAMERA")
            seen = surface._incoming_unflipped
            surface._incoming_unflipped = lambda seen=seen, side=side: seen() * side
            hits = _compare(scene, b, ob, surface)
            assert surface.backfacing().all() == (side < 0)
            batch.append(hits)
            out = ob.material_slots[0].material.node_tree.nodes["Material Output"]
            wanted.append(node_bake.evaluate(out, ShadingState(surface.n, source=surface)))
    # The materials' programs over all those points in one batch (split where a mesh lacks "Col")
    # emit what the bake harness's evaluation of each object's points gives.
    one = SurfaceHits(scene, *(np.concatenate([getattr(h, k) for h in batch]) for k in ("prim", "bary")),
                      *(np.concatenate([getattr(h, k)() for h in batch]) for k in ("P", "N", "Ng", "I")))
    got = MaterialPrograms.of(scene.materials).emission(mesh.material[one.prim], one)
    assert np.allclose(got, np.concatenate(wanted), atol=1e-4, rtol=1e-4), np.abs(got - np.concatenate(wanted)).max()


def _compare(scene, b, ob, surface):
    """SurfaceHits at the bake harness's points of object b against its state."""
    mesh = scene.mesh
    flipped = np.linalg.det(np.array(ob.matrix_world)[:3, :3]) < 0
    w = surface.weights
    bary = w[:, [0, 2, 1]] if flipped else w
    hits = SurfaceHits(scene, mesh.objects[b] + surface.tri, bary, surface.P(), surface.N(), surface.Ng(),
                       surface.I(), ray=RayState(surface.path_flag(), dP=surface.dP()))
    for field in ("backfacing", "barycentric", "triangle", "dPdu", "dPdv", "smooth", "vertex_normal", "N_du", "N_dv",
                  "uv", "uv_du", "uv_dv", "generated", "generated_du", "generated_dv", "object", "object_color",
                  "object_alpha", "object_index", "object_random", "material_index"):
        got, want = np.asarray(getattr(hits, field)(), np.float64), np.asarray(getattr(surface, field)(), np.float64)
        if field == "vertex_normal":  # read on smooth faces only (Normal Map's frame)
            got, want = got[surface.smooth_m], want[surface.smooth_m]
        assert got.shape == want.shape, (ob.name, field)
        assert np.allclose(got, want, atol=2e-5, rtol=2e-5), (ob.name, field, np.abs(got - want).max())
    for name in _NAMES:
        got, want = hits.attribute(name), surface.attribute(name)
        assert (got is None) == (want is None), (ob.name, name)
        if got is None:
            continue
        assert got.type == want.type, (ob.name, name)
        value = np.broadcast_to(want.value, got.value.shape)
        assert np.allclose(got.value, value, atol=2e-5), (ob.name, name, np.abs(got.value - value).max())
        for d in ("du", "dv"):
            g, r = getattr(got, d), getattr(want, d)
            assert (g is None) == (r is None), (ob.name, name, d)
            if g is not None:
                assert np.allclose(g, r, atol=2e-5), (ob.name, name, d, np.abs(g - r).max())
    return hits


def test_the_mesh_carries_what_programs_read_and_survives_every_copy(tmp_path):
    """A scene whose materials read nothing of this has none of the new arrays; one that reads
    them keeps them through pickling, the workers' plain form, .npz and recentring (they are
    object-space or per object: nothing moves but the transforms)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    node_bake._camera()
    mesh_data = grid("plain", colors=True)
    _object(mesh_data, "Plain", (0.0, 0.0, 0.0), (0.1, 0.2, 0.3), (1.0, 2.0, 1.0), (1, 1, 1, 1), 0, 1.0)
    bpy.context.view_layer.update()
    plain, _ = export_scene(bpy.context.evaluated_depsgraph_get())
    for name in ("attributes", "object_attributes", "object_info", "material_pass_index"):
        assert getattr(plain.mesh, name) is None, name
    mesh_data.materials.append(_reading_material("reads", 3))
    bpy.context.view_layer.update()
    scene, _ = export_scene(bpy.context.evaluated_depsgraph_get())
    mesh = scene.mesh
    assert mesh.attributes["Col"][0].shape == (mesh.n_triangles, 3, 4) and mesh.attributes["Col"][0].dtype == np.float32
    assert mesh.attributes["Weight"][0].shape == (mesh.n_triangles, 1)  # a face attribute: per triangle
    assert mesh.object_info.shape == (1, 6) and mesh.material_pass_index.tolist() == [3.0]
    path = tmp_path / "scene.npz"
    scene.save(path)
    copies = [pickle.loads(pickle.dumps(scene)), scene_from_plain(to_plain(scene)), Scene.load(path)]
    for copy in copies:
        assert part_digest(copy.mesh) == part_digest(mesh)
    far = recentred(scene, np.array([3000.0, -2000.0, 500.0]))
    assert part_digest(far.mesh) != part_digest(mesh)
    rng = np.random.default_rng(3)
    prim = rng.integers(0, mesh.n_triangles, 50)
    bary = rng.dirichlet(np.ones(3), 50)
    for s in (scene, far):
        v = s.mesh.vertices[s.mesh.triangles[prim]].astype(np.float64)
        p = np.einsum("nk,nkc->nc", bary, v)
        n = np.tile([0.0, 0.0, 1.0], (50, 1))
        hits = SurfaceHits(s, prim, bary, p, n, n, n)
        values = [hits.generated(), hits.object(), hits.attribute("Col").value, hits.object_random()]
        if s is scene:
            near = values
    for a, b in zip(near, values):
        assert np.allclose(a, b, atol=1e-3)


# --- renders against Cycles ----------------------------------------------------------------------
SIZE = 32
SEEDS = 4
EMBER_SAMPLES = 64  # per seed
CYCLES_SAMPLES = 256  # per seed
TOL = 0.01


def _diffuse(name, color=None):
    """A Diffuse BSDF material; color: a function (node tree) -> the socket its Color reads."""
    mat, nt, out = node_material(name)
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    nt.links.new(d.outputs[0], out.inputs["Surface"])
    if color is not None:
        nt.links.new(color(nt), d.inputs["Color"])
    return mat, nt, d


def _tile(mesh, quadrant: int, material=None, name=None, scale=(1.0, 1.0, 1.0), rotation=(0.0, 0.0, 0.0)):
    """An object of `mesh` (spanning [-1, 1]^2) in quadrant 0..3 (top left, top right, bottom left,
    bottom right of a top-down view) of the floor, seen by _top_camera."""
    ob = bpy.data.objects.new(name or f"tile{quadrant}", mesh)
    bpy.context.collection.objects.link(ob)
    ob.location = (-1.02 if quadrant % 2 == 0 else 1.02, 1.02 if quadrant < 2 else -1.02, 0.0)
    ob.scale, ob.rotation_euler = scale, rotation
    if material is not None:
        ob.data.materials.append(material) if not ob.data.materials else None
        ob.material_slots[0].link = "OBJECT"
        ob.material_slots[0].material = material
    return ob


def _top_camera(sc, height=5.6):
    bpy.ops.object.camera_add(location=(0.0, 0.0, height), rotation=(0.0, 0.0, 0.0))
    sc.camera = bpy.context.active_object
    sc.camera.data.lens = 36.0


def _sun(strength=3.0, rotation=(0.6, 0.3, 0.0)):
    bpy.ops.object.light_add(type="SUN", rotation=rotation)
    light = bpy.context.active_object
    light.data.energy = strength
    return light


def _tile_mesh(name, cells=8, second_uv=False):
    """A flat tile over [-1, 1]^2 of cells x cells quads (grid() without heights)."""
    return grid(name, cells=cells, height=lambda x, y: 0.0 * x)


def attributes_scene():
    """Colour attributes (byte per corner, float per vertex), a face attribute through a ramp and
    a named second UV map (on a mirrored tile), each on a diffuse tile."""
    sc = new_scene(SIZE, world=(0.04, 0.04, 0.05))
    mesh = _tile_mesh("tile")

    def attribute(name, output="Color", kind="ShaderNodeAttribute"):
        def build(nt):
            node = nt.nodes.new(kind)
            if kind == "ShaderNodeVertexColor":
                node.layer_name = name
            else:
                node.attribute_name = name
            return node.outputs[output]
        return build

    def weight_ramp(nt):
        ramp = nt.nodes.new("ShaderNodeValToRGB")
        ramp.color_ramp.elements[0].color = (0.9, 0.2, 0.1, 1)
        ramp.color_ramp.elements[1].color = (0.1, 0.4, 0.9, 1)
        nt.links.new(attribute("Weight", "Fac")(nt), ramp.inputs["Fac"])
        return ramp.outputs["Color"]

    def second_uv(nt):
        uv = nt.nodes.new("ShaderNodeUVMap")
        uv.uv_map = "Second"
        sep = nt.nodes.new("ShaderNodeSeparateXYZ")
        comb = nt.nodes.new("ShaderNodeCombineColor")
        nt.links.new(uv.outputs["UV"], sep.inputs[0])
        nt.links.new(sep.outputs["X"], comb.inputs[0])
        nt.links.new(sep.outputs["Y"], comb.inputs[1])
        comb.inputs[2].default_value = 0.25
        return comb.outputs[0]

    _tile(mesh, 0, _diffuse("byte", attribute("Col", kind="ShaderNodeVertexColor"))[0])
    _tile(mesh, 1, _diffuse("float", attribute("FCol"))[0])
    _tile(mesh, 2, _diffuse("second", second_uv)[0], scale=(-1.0, 1.0, 1.0))
    _tile(mesh, 3, _diffuse("weight", weight_ramp)[0])
    _sun()
    _top_camera(sc)
    return sc


def objects_scene():
    """One material over four objects reading Object Info: colour times a factor of the random
    number, plus the pass indices of the object and the material; two objects share a mesh and
    one is a collection instance (its random number the instance's)."""
    sc = new_scene(SIZE, world=(0.04, 0.04, 0.05))
    mat, nt, d = _diffuse("info")
    mat.pass_index = 3
    info = nt.nodes.new("ShaderNodeObjectInfo")
    factor = nt.nodes.new("ShaderNodeMapRange")
    factor.inputs["To Min"].default_value, factor.inputs["To Max"].default_value = 0.3, 1.0
    nt.links.new(info.outputs["Random"], factor.inputs["Value"])
    mix = nt.nodes.new("ShaderNodeMix")
    mix.data_type, mix.blend_type = "RGBA", "MULTIPLY"
    mix.inputs["Factor"].default_value = 1.0
    nt.links.new(info.outputs["Color"], mix.inputs["A"])
    nt.links.new(factor.outputs["Result"], mix.inputs["B"])
    index = nt.nodes.new("ShaderNodeMath")
    index.operation = "MULTIPLY_ADD"
    nt.links.new(info.outputs["Object Index"], index.inputs[0])
    index.inputs[1].default_value = 0.04
    nt.links.new(info.outputs["Material Index"], index.inputs[2])
    scaled = nt.nodes.new("ShaderNodeMath")
    scaled.operation = "MULTIPLY"
    nt.links.new(index.outputs[0], scaled.inputs[0])
    scaled.inputs[1].default_value = 0.05
    add = nt.nodes.new("ShaderNodeMix")
    add.data_type, add.blend_type = "RGBA", "ADD"
    add.inputs["Factor"].default_value = 1.0
    nt.links.new(mix.outputs["Result"], add.inputs["A"])
    nt.links.new(scaled.outputs[0], add.inputs["B"])
    nt.links.new(add.outputs["Result"], d.inputs["Color"])
    shared = _tile_mesh("shared", cells=2)
    colours = [(0.9, 0.3, 0.2, 1), (0.2, 0.8, 0.3, 1), (0.3, 0.4, 0.9, 1), (0.8, 0.8, 0.2, 1)]
    for q, (name, colour, index_) in enumerate(zip(("Ann", "Bea", "Cyd"), colours, (1, 5, 2))):
        ob = _tile(shared if q < 2 else _tile_mesh(name, cells=2), q, mat, name=name)
        ob.color, ob.pass_index = colour, index_
    # The fourth tile: an instance of a collection holding one tile object.
    hidden = bpy.data.collections.new("Source")
    ob = bpy.data.objects.new("Dee", _tile_mesh("dee", cells=2))
    hidden.objects.link(ob)
    ob.data.materials.append(mat)
    ob.color, ob.pass_index = colours[3], 7
    inst = bpy.data.objects.new("Instancer", None)
    inst.instance_type, inst.instance_collection = "COLLECTION", hidden
    inst.location = (1.02, -1.02, 0.0)
    bpy.context.collection.objects.link(inst)
    _sun()
    _top_camera(sc)
    return sc


def _normal_image(size=64):
    """A tangent-space normal map whose normals lean along +x (u) with a wave along y."""
    y, x = np.mgrid[0:size, 0:size] / size
    n = np.stack([0.45 + 0.2 * np.sin(2 * np.pi * 3 * y), 0.25 * np.cos(2 * np.pi * 2 * x), np.ones_like(x)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    img = bpy.data.images.new("normals", size, size, float_buffer=True)
    img.colorspace_settings.name = "Non-Color"
    rgba = np.concatenate([0.5 * n + 0.5, np.ones((size, size, 1))], axis=-1)
    img.pixels.foreach_set(rgba.astype(np.float32).ravel())
    img.pack()
    return img


def normals_scene():
    """Normals from nodes on diffuse tiles lit at an angle: a tangent-space Normal Map from an
    image (on a mirrored tile: its tangent sign), a Bump from a Noise Texture, the Material
    Output's displacement as bump, and a tile seen from behind coloured by Backfacing."""
    sc = new_scene(SIZE, world=(0.04, 0.04, 0.05))
    mesh = _tile_mesh("tile", cells=4)
    mat, nt, d = _diffuse("normal map")
    d.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1)
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = _normal_image()
    nm = nt.nodes.new("ShaderNodeNormalMap")
    nm.uv_map = "Second"
    nt.links.new(tex.outputs["Color"], nm.inputs["Color"])
    nt.links.new(nm.outputs["Normal"], d.inputs["Normal"])
    _tile(mesh, 0, mat, scale=(-1.0, 1.0, 1.0))

    mat, nt, d = _diffuse("bump")
    d.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1)
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 3.0
    bump = nt.nodes.new("ShaderNodeBump")
    bump.inputs["Distance"].default_value = 0.4
    nt.links.new(noise.outputs["Fac"], bump.inputs["Height"])
    nt.links.new(bump.outputs["Normal"], d.inputs["Normal"])
    _tile(mesh, 1, mat)

    mat, nt, d = _diffuse("displaced")
    d.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1)
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 4.0
    disp = nt.nodes.new("ShaderNodeDisplacement")
    disp.inputs["Scale"].default_value = 0.3
    nt.links.new(noise.outputs["Fac"], disp.inputs["Height"])
    nt.links.new(disp.outputs["Displacement"], nt.nodes["Material Output"].inputs["Displacement"])
    _tile(mesh, 2, mat)

    mat, nt, d = _diffuse("backfacing")
    geometry = nt.nodes.new("ShaderNodeNewGeometry")
    mix = nt.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.inputs["A"].default_value, mix.inputs["B"].default_value = (0.9, 0.2, 0.2, 1), (0.2, 0.3, 0.9, 1)
    nt.links.new(geometry.outputs["Backfacing"], mix.inputs["Factor"])
    nt.links.new(mix.outputs["Result"], d.inputs["Color"])
    _tile(mesh, 3, mat, rotation=(math.pi, 0.0, 0.0))
    # Light 29 degrees off the normal: a perturbed normal facing it more than the true normal
    # does is darkened by Cycles' bump shadowing term (closure/bsdf.h bump_shadowing_term), which
    # Ember's lobes leave out: 0.4 % in the Normal Map's quadrant here, 1.2 % at 52 degrees.
    _sun(rotation=(0.5, 0.0, 0.5))
    _top_camera(sc)
    return sc


def light_path_scene():
    """Two balls the camera sees red and a mirror floor reflects blue, by a Light Path node's Is
    Camera Ray: on the left mixing two diffuse shaders (lit by an area light), on the right two
    emission shaders (the emission found by camera rays and by rays off the mirror)."""
    sc = new_scene(SIZE, world=(0.0, 0.0, 0.0))
    # The mirror's caustics on the balls (lit through it by the area light): not what this is about.
    sc.cycles.caustics_reflective = sc.ember.caustics_reflective = False
    bpy.ops.mesh.primitive_plane_add(size=12)
    floor = bpy.context.active_object
    mat, nt, out = node_material("mirror")
    g = nt.nodes.new("ShaderNodeBsdfAnisotropic")
    g.distribution = "GGX"
    g.inputs["Roughness"].default_value = 0.0
    nt.links.new(g.outputs[0], out.inputs["Surface"])
    floor.data.materials.append(mat)
    for x, shader, strength in ((-1.1, "ShaderNodeBsdfDiffuse", None), (1.1, "ShaderNodeEmission", 1.5)):
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.9, location=(x, 0, 1.0), segments=32, ring_count=16)
        bpy.ops.object.shade_smooth()
        ball = bpy.context.active_object
        mat, nt, out = node_material(f"camera red {shader}")
        red, blue = nt.nodes.new(shader), nt.nodes.new(shader)
        red.inputs["Color"].default_value, blue.inputs["Color"].default_value = (0.8, 0.1, 0.1, 1), (0.1, 0.2, 0.8, 1)
        if strength is not None:
            red.inputs["Strength"].default_value = blue.inputs["Strength"].default_value = strength
        path = nt.nodes.new("ShaderNodeLightPath")
        mix = nt.nodes.new("ShaderNodeMixShader")
        nt.links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
        nt.links.new(blue.outputs[0], mix.inputs[1])
        nt.links.new(red.outputs[0], mix.inputs[2])
        nt.links.new(mix.outputs[0], out.inputs["Surface"])
        ball.data.materials.append(mat)
    bpy.ops.object.light_add(type="AREA", location=(-1.5, -3.0, 4.0), rotation=(0.6, -0.2, 0.0))
    light = bpy.context.active_object
    light.data.energy, light.data.size = 300.0, 2.0
    bpy.ops.object.camera_add(location=(0.0, -6.5, 1.0), rotation=(math.pi / 2, 0.0, 0.0))
    sc.camera = bpy.context.active_object
    return sc


SCENES = {"attributes": attributes_scene, "objects": objects_scene, "normals": normals_scene,
          "light_path": light_path_scene}


@pytest.mark.parametrize("name", list(SCENES))
def test_materials_reading_the_state_render_as_cycles(name, tmp_path):
    sc = SCENES[name]()
    cycles = [cycles_image(sc, CYCLES_SAMPLES, 100 + k, tmp_path / f"cycles{k}.exr") for k in range(SEEDS)]
    ember_images = [ember_image(sc, "PATH", EMBER_SAMPLES, k) for k in range(SEEDS)]
    agree(ember_images, cycles, len(SCENES), TOL)
