"""A material made by Blender's own glTF importer renders as Cycles renders it.

A textured Principled material is built here (images made in code: a base colour, a
metallic-roughness map read through Separate Color, a tangent-space normal map, an emissive
map at Emission Strength above 1, which the exporter writes as KHR_materials_emissive_strength;
a Mapping node on the base colour's UVs, written as KHR_texture_transform),
exported with `bpy.ops.export_scene.gltf` and imported again with `bpy.ops.import_scene.gltf`,
so the material is the importer's graph, whatever it puts between the images and the BSDF.

- Every Principled input the importer links is baked by Cycles (tests/node_bake.py: routed
  to Emission, exact values at texel centres) and evaluated by Ember's node programs at the
  same points: they agree texel for texel.
- Ember exports the imported scene without any "approximated" / "not supported" warning.
- Rendered (a plane under an area light and a dim world, seen at an angle so the normal map,
  the roughness and the metal show): SEEDS independent renders each; the image's and its
  quadrants' means agree within TOL plus the Sidak-corrected noise band (a t-test), and the
  relMSE of one mean image against the other is what the renders' noise explains.

The imported Principled BSDF keeps the importer's distribution, Multiscatter GGX.
"""
import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

import ember  # noqa: E402
from ember.engine.blender.export import export_scene  # noqa: E402

import node_bake  # noqa: E402

from cycles_renders import agree, cycles_image, ember_image  # noqa: E402

pytestmark = pytest.mark.blender
TEXELS = 16  # the images' size
EMISSION_STRENGTH = 2.5
SIZE = 24  # the render's
SEEDS = 3
EMBER_SAMPLES = 32
CYCLES_SAMPLES = 64
TOL = 0.01
EPS = 1e-2  # relMSE's (engine/metrics.py)
NOISE_RATIO = 1.5


@pytest.fixture(scope="module", autouse=True)
def addon():
    ember.register()
    yield
    ember.unregister()


def _image(name, pixels, non_color):
    """An image datablock from (T,T,4) values in [0, 1], rows bottom-up as Blender keeps them."""
    img = bpy.data.images.new(name, TEXELS, TEXELS, alpha=True)
    if non_color:  # first: changing it regenerates a generated image's pixels
        img.colorspace_settings.name = "Non-Color"
    img.pixels.foreach_set(np.ascontiguousarray(pixels, np.float32).ravel())
    img.pack()
    return img


def _images():
    """Base colour, metallic-roughness (G roughness, B metallic as glTF packs them), normal and
    emissive maps; the roughness and the metal vary along different axes, so that a channel
    swap shows."""
    t = (np.arange(TEXELS) + 0.5) / TEXELS
    u, v = np.meshgrid(t, t)  # u across a row, v up the rows
    one = np.ones_like(u)
    base = np.stack([0.2 + 0.7 * u, 0.3 + 0.5 * v, 0.8 - 0.6 * u * v, one], axis=-1)
    checker = ((np.floor(u * 4) + np.floor(v * 4)) % 2)
    mr = np.stack([one, 0.15 + 0.8 * v, checker, one], axis=-1)
    slope = 0.45 * np.sin(2.0 * math.pi * 2.0 * u)
    n = np.stack([slope, 0.25 * np.cos(2.0 * math.pi * v), one], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    normal = np.concatenate([0.5 + 0.5 * n, one[..., None]], axis=-1)
    spot = ((u - 0.7) ** 2 + (v - 0.3) ** 2 < 0.04).astype(float)
    emissive = np.stack([spot, 0.6 * spot, 0.2 * spot, one], axis=-1)
    return {name: _image(name, px, nc) for name, px, nc in (
        ("base", base, False), ("metal_roughness", mr, True), ("normal", normal, True), ("emissive", emissive, False))}


def _material():
    mat = bpy.data.materials.new("Textured")
    nt = mat.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    images = _images()
    tex = {}
    for name, img in images.items():
        tex[name] = nt.nodes.new("ShaderNodeTexImage")
        tex[name].image = img
    sep = nt.nodes.new("ShaderNodeSeparateColor")
    nmap = nt.nodes.new("ShaderNodeNormalMap")
    nt.links.new(tex["base"].outputs["Color"], bsdf.inputs["Base Color"])
    # A Mapping node on UVs: the exporter writes KHR_texture_transform, the importer a Mapping.
    uv = nt.nodes.new("ShaderNodeUVMap")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Location"].default_value = (0.1, -0.2, 0.0)
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, 0.4)
    mapping.inputs["Scale"].default_value = (1.5, 0.8, 1.0)
    nt.links.new(uv.outputs["UV"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], tex["base"].inputs["Vector"])
    nt.links.new(tex["metal_roughness"].outputs["Color"], sep.inputs["Color"])
    nt.links.new(sep.outputs["Green"], bsdf.inputs["Roughness"])
    nt.links.new(sep.outputs["Blue"], bsdf.inputs["Metallic"])
    nt.links.new(tex["normal"].outputs["Color"], nmap.inputs["Color"])
    nt.links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    nt.links.new(tex["emissive"].outputs["Color"], bsdf.inputs["Emission Color"])
    bsdf.inputs["Emission Strength"].default_value = EMISSION_STRENGTH
    return mat


def _plane():
    mesh = bpy.data.meshes.new("plane")
    mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    for loop, corner in zip(uv.data, ((0, 0), (1, 0), (1, 1), (0, 1))):
        loop.uv = corner
    ob = bpy.data.objects.new("Textured", mesh)
    bpy.context.scene.collection.objects.link(ob)
    mesh.materials.append(_material())
    return ob


@pytest.fixture(scope="module")
def gltf_file(tmp_path_factory):
    """The material on a plane, written by Blender's glTF exporter."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    _plane()
    path = tmp_path_factory.mktemp("gltf") / "textured.glb"
    bpy.ops.export_scene.gltf(filepath=str(path), export_format="GLB")
    return path


def _import(path):
    """A fresh scene with the file imported; (the plane, its material's Principled BSDF)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=str(path))
    ob = next(o for o in bpy.context.scene.objects if o.type == "MESH")
    bsdf = next(n for n in ob.active_material.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    return ob, bsdf


def test_the_importer_links_what_the_material_had(gltf_file):
    """The round trip keeps every map, and the emission strength above 1 (else the test
    below would not see them)."""
    _, bsdf = _import(gltf_file)
    linked = {s.name for s in bsdf.inputs if s.is_linked}
    assert {"Base Color", "Roughness", "Metallic", "Normal", "Emission Color"} <= linked, linked
    kinds = {n.bl_idname for n in bsdf.id_data.nodes}
    assert {"ShaderNodeSeparateColor", "ShaderNodeNormalMap", "ShaderNodeMapping"} <= kinds, kinds
    assert bsdf.inputs["Emission Strength"].default_value == pytest.approx(EMISSION_STRENGTH)


def test_imported_inputs_evaluate_as_cycles_bakes_them(gltf_file):
    """Each linked Principled input baked by Cycles and evaluated by Ember at the same texels:
    the bake's material gets a copy of the importer's nodes feeding that input."""
    _, bsdf = _import(gltf_file)
    sockets = [s.name for s in bsdf.inputs if s.is_linked]
    strength = bsdf.inputs["Emission Strength"].default_value
    assert strength > 1.0
    imported = {}

    def tree():  # imported once into the bake's scene (the bake starts from an empty file)
        if "tree" not in imported:
            before = set(bpy.data.materials)
            bpy.ops.import_scene.gltf(filepath=str(gltf_file))
            mat = next(m for m in bpy.data.materials if m not in before)
            for ob in [o for o in bpy.context.scene.objects if o.active_material == mat]:
                bpy.data.objects.remove(ob)
            imported["tree"] = mat.node_tree
        return imported["tree"]

    cases = {name: (lambda nt, name=name: _upstream(tree(), name, nt)) for name in sockets}
    cases["emitted"] = lambda nt: _whole_bsdf(tree(), nt)
    results = node_bake.bake(cases, size=TEXELS)
    for name, (cycles, ember_values) in results.items():
        assert np.abs(cycles).max() > 0.0, name
        share = node_bake.agreement(cycles, ember_values, tol=2e-4)
        assert share == 1.0, (name, share, float(np.abs(cycles - ember_values).max()))
    # The strength reaches the emission, past the texture's range.
    assert results["emitted"][0].max() == pytest.approx(strength * results["Emission Color"][0].max(), rel=1e-4)


def _copy(node, dst_tree, copies):
    """A copy of `node` in dst_tree with its settings, unlinked input values and everything
    upstream of it (copied once each, kept in `copies` by name)."""
    if node.name in copies:
        return copies[node.name]
    new = dst_tree.nodes.new(node.bl_idname)
    if node.bl_idname == "ShaderNodeGroup":
        new.node_tree = node.node_tree
    for prop in node.bl_rna.properties:
        key = prop.identifier
        if prop.is_readonly or key in ("name", "label", "location", "width", "parent", "select"):
            continue
        try:
            setattr(new, key, getattr(node, key))
        except (AttributeError, TypeError):
            pass
    for i, s in enumerate(node.inputs):
        if hasattr(s, "default_value"):
            try:
                new.inputs[i].default_value = s.default_value
            except (AttributeError, TypeError, ValueError):
                pass
    copies[node.name] = new
    for i, s in enumerate(node.inputs):
        if s.is_linked:
            up = s.links[0]
            src = _copy(up.from_node, dst_tree, copies)
            dst_tree.links.new(src.outputs[list(up.from_node.outputs).index(up.from_socket)], new.inputs[i])
    return new


def _upstream(src_tree, socket_name, dst_tree):
    """In dst_tree, a copy of what feeds the Principled input `socket_name` of src_tree; the
    copied socket that fed it."""
    bsdf = next(n for n in src_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    link = bsdf.inputs[socket_name].links[0]
    node = _copy(link.from_node, dst_tree, {})
    return node.outputs[list(link.from_node.outputs).index(link.from_socket)]


def _whole_bsdf(src_tree, dst_tree):
    """The Principled BSDF itself (with everything upstream) as the bake's surface: the bake
    takes its emission, Emission Color x Strength."""
    bsdf = next(n for n in src_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    out = next(n for n in dst_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    dst_tree.links.new(_copy(bsdf, dst_tree, {}).outputs["BSDF"], out.inputs["Surface"])
    return None


def test_ember_exports_the_imported_material_without_warnings(gltf_file):
    _import(gltf_file)
    sc = bpy.context.scene
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    sc.collection.objects.link(cam)
    sc.camera = cam
    cam.location = (0.0, -3.0, 2.0)
    sc.render.engine = "EMBER"
    scene, warnings = export_scene(bpy.context.evaluated_depsgraph_get())
    bad = [w for w in warnings if "approximated" in w or "not supported" in w or "ignored" in w]
    assert not bad, bad
    # The material goes through the node evaluator, with its graph (its inputs vary).
    assert scene.materials.graphs and any(g is not None for g in scene.materials.graphs)


# --- rendered ---------------------------------------------------------------------------------
def _render_scene(path):
    ob, bsdf = _import(path)
    assert bsdf.distribution == "MULTI_GGX"
    sc = bpy.context.scene
    world = bpy.data.worlds.new("World")
    world.color = (0.05, 0.05, 0.06)
    sc.world = world
    light = bpy.data.objects.new("Light", bpy.data.lights.new("Light", "AREA"))
    light.data.energy, light.data.size = 60.0, 1.0
    light.location, light.rotation_euler = (1.2, -1.0, 2.0), (0.5, 0.4, 0.0)
    sc.collection.objects.link(light)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.angle = math.radians(55.0)
    cam.location, cam.rotation_euler = (0.0, -1.5, 2.0), (math.radians(37.0), 0.0, 0.0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    sc.render.resolution_x = sc.render.resolution_y = SIZE
    sc.render.resolution_percentage = 100
    sc.cycles.pixel_filter_type = "BOX"
    sc.cycles.device = "CPU"
    sc.cycles.use_denoising = False
    sc.cycles.use_adaptive_sampling = False
    return sc


def test_the_imported_material_renders_as_cycles(gltf_file, tmp_path):
    sc = _render_scene(gltf_file)
    cycles = np.array([cycles_image(sc, CYCLES_SAMPLES, 100 + k, tmp_path / f"cycles{k}.exr") for k in range(SEEDS)])
    ember_images = np.array([ember_image(sc, "PATH", EMBER_SAMPLES, k) for k in range(SEEDS)])
    agree(ember_images, cycles, 1, TOL)
    # Per pixel: the squared difference of the two means, relative as relMSE weighs it, is
    # what their noise explains (its expectation from the between-seed variances), within
    # NOISE_RATIO: a pattern wrong in places (a swapped map, a lost normal map) shows here.
    em, cm = ember_images.mean(0), cycles.mean(0)
    weight = 1.0 / (cm * cm + EPS)
    measured = float(np.mean((em - cm) ** 2 * weight))
    expected = float(np.mean((ember_images.var(0, ddof=1) + cycles.var(0, ddof=1)) / SEEDS * weight))
    assert measured <= NOISE_RATIO * expected, (measured, expected)
