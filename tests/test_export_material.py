"""Shader nodes -> Materials lobes, textures, normal maps, UVs, Phong (engine/blender/export_material.py,
export_mesh.py UVs, ui/material.py), checked against the numbers Cycles' closure setup gives."""
import math
import os
import tempfile

import numpy as np
import pytest

os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))
bpy = pytest.importorskip("bpy")

import ember  # noqa: E402
from ember.engine import scene as S  # noqa: E402
from ember.engine.blender.export import export_scene  # noqa: E402
from ember.engine.blender.export_material import f0_from_ior, ior_from_f0  # noqa: E402

pytestmark = pytest.mark.blender


@pytest.fixture(scope="module", autouse=True)
def addon():
    ember.register()
    yield
    ember.unregister()


def new_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location, cam.rotation_euler = (0.0, -10.0, 0.0), (math.pi / 2, 0.0, 0.0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    return sc


def material(name, build):
    """A material whose tree is made by build(nodes, links, output)."""
    mat = bpy.data.materials.new(name)
    tree = mat.node_tree
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    build(tree.nodes, tree.links, out)
    return mat


def export_with(*materials):
    """A plane per material; returns (scene, warnings, {name: its lobe rows})."""
    for i, mat in enumerate(materials):
        bpy.ops.mesh.primitive_plane_add(location=(3.0 * i, 0.0, 0.0))
        bpy.context.active_object.data.materials.append(mat)
    sc, warnings = export_scene(bpy.context.evaluated_depsgraph_get())
    m = sc.materials
    rows = {name: np.flatnonzero(m.lobe_material == i) for i, name in enumerate(m.names)}
    return sc, warnings, rows


def test_principled_is_split_like_cycles():
    new_scene()

    def build(nodes, links, out):
        p = nodes.new("ShaderNodeBsdfPrincipled")
        for key, value in (("Base Color", (0.2, 0.4, 0.6, 1.0)), ("Roughness", 0.3), ("Metallic", 0.25),
                           ("Transmission Weight", 0.4), ("IOR", 1.45), ("Alpha", 0.8),
                           ("Emission Color", (1.0, 0.5, 0.25, 1.0)), ("Emission Strength", 2.0),
                           ("Specular Tint", (1.0, 0.9, 0.8, 1.0))):
            p.inputs[key].default_value = value
        links.new(p.outputs[0], out.inputs["Surface"])

    def level(nodes, links, out):
        p = nodes.new("ShaderNodeBsdfPrincipled")
        p.inputs["Specular IOR Level"].default_value = 0.25
        p.inputs["IOR"].default_value = 1.45
        links.new(p.outputs[0], out.inputs["Surface"])

    sc, warnings, rows = export_with(material("P", build), material("Level", level))
    m = sc.materials
    r = rows["P"]
    assert m.lobe_kind[r].tolist() == [S.LOBE_TRANSPARENT, S.LOBE_MICROFACET, S.LOBE_DIELECTRIC,
                                       S.LOBE_MICROFACET, S.LOBE_DIFFUSE]
    # alpha 0.8: transparent 0.2; metallic 0.8 x 0.25; transmission 0.8 x 0.75 x 0.4; the rest
    # (0.8 x 0.75 x 0.6) to the specular layer and the diffuse base under it.
    np.testing.assert_allclose(m.lobe_weight[r, 0], [0.2, 0.2, 0.24, 0.36, 0.36], rtol=1e-6)
    transparent, metal, glass, spec, diffuse = r
    assert m.lobe_fresnel[metal] == S.FRESNEL_F82 and m.lobe_fresnel[spec] == S.FRESNEL_DIELECTRIC
    np.testing.assert_allclose(m.lobe_color[metal], [0.2, 0.4, 0.6], rtol=1e-6)  # F0 = base colour
    np.testing.assert_allclose(m.lobe_tint[metal], [1.0, 0.9, 0.8], rtol=1e-6)  # F82 = specular tint
    # Refraction tinted sqrt(base colour) (the table's flag or the value itself), reflection white.
    refraction = np.sqrt(m.lobe_color[glass]) if m.lobe_color_sqrt[glass] else m.lobe_color[glass]
    np.testing.assert_allclose(refraction, np.sqrt([0.2, 0.4, 0.6]), rtol=1e-6)
    # Its Fresnel's F0 tinted by Specular Tint (Cycles' generalised Schlick on the glass lobe).
    assert m.lobe_fresnel[glass] == S.FRESNEL_DIELECTRIC and not m.lobe_tint_is_color[glass]
    np.testing.assert_allclose(m.lobe_tint[glass], [1.0, 0.9, 0.8], rtol=1e-6)
    np.testing.assert_allclose(m.lobe_ior[[glass, spec]], 1.45, rtol=1e-6)
    np.testing.assert_allclose(m.lobe_tint[spec], [1.0, 0.9, 0.8], rtol=1e-6)
    assert m.lobe_layer[diffuse] == spec and m.lobe_layer[spec] == -1
    np.testing.assert_allclose(m.lobe_roughness[[metal, glass, spec]], 0.3, rtol=1e-6)
    np.testing.assert_allclose(m.emission[m.names.index("P")], [1.6, 0.8, 0.4], rtol=1e-6)  # x alpha
    # Specular IOR Level 0.25 halves F0 and moves the IOR with it.
    spec_level = rows["Level"][0]
    assert m.lobe_ior[spec_level] == pytest.approx(ior_from_f0(0.5 * f0_from_ior(1.45)), rel=1e-6)
    assert warnings == []


def test_mix_add_glossy_glass_transparent_and_emission():
    new_scene()

    def build(nodes, links, out):
        diffuse = nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Color"].default_value = (1.0, 0.0, 0.0, 1.0)
        glossy = nodes.new("ShaderNodeBsdfGlossy")
        glossy.inputs["Roughness"].default_value = 0.2
        mix = nodes.new("ShaderNodeMixShader")
        mix.inputs["Fac"].default_value = 0.3
        links.new(diffuse.outputs[0], mix.inputs[1])
        links.new(glossy.outputs[0], mix.inputs[2])
        glass = nodes.new("ShaderNodeBsdfGlass")
        glass.inputs["Color"].default_value = (0.9, 1.0, 0.9, 1.0)
        glass.inputs["IOR"].default_value = 1.33
        add = nodes.new("ShaderNodeAddShader")
        links.new(mix.outputs[0], add.inputs[0])
        em = nodes.new("ShaderNodeEmission")
        em.inputs["Strength"].default_value = 3.0
        add2 = nodes.new("ShaderNodeAddShader")
        links.new(glass.outputs[0], add2.inputs[0])
        links.new(em.outputs[0], add2.inputs[1])
        links.new(add2.outputs[0], add.inputs[1])
        mix2 = nodes.new("ShaderNodeMixShader")
        mix2.inputs["Fac"].default_value = 0.5
        links.new(add.outputs[0], mix2.inputs[1])
        links.new(nodes.new("ShaderNodeBsdfTransparent").outputs[0], mix2.inputs[2])
        links.new(mix2.outputs[0], out.inputs["Surface"])

    sc, warnings, rows = export_with(material("Mixed", build))
    m = sc.materials
    r = rows["Mixed"]
    assert m.lobe_kind[r].tolist() == [S.LOBE_DIFFUSE, S.LOBE_MICROFACET, S.LOBE_DIELECTRIC, S.LOBE_TRANSPARENT]
    np.testing.assert_allclose(m.lobe_weight[r, 0], [0.35, 0.15, 0.5, 0.5], rtol=1e-6)
    assert m.lobe_fresnel[r[1]] == S.FRESNEL_NONE and m.lobe_roughness[r[1]] == pytest.approx(0.2)
    assert m.lobe_tint_is_color[r[2]] and m.lobe_ior[r[2]] == pytest.approx(1.33)
    np.testing.assert_allclose(m.emission[0], [1.5, 1.5, 1.5], rtol=1e-6)  # white x 3 x 0.5
    assert warnings == []


def test_image_textures_mapping_and_normal_map():
    new_scene()
    byte = bpy.data.images.new("Byte", 4, 2)
    texels = np.random.default_rng(3).random((2, 4, 4)).astype(np.float32)
    byte.pixels.foreach_set(texels.ravel())
    data = bpy.data.images.new("Data", 2, 2, float_buffer=True)
    data.colorspace_settings.name = "Non-Color"
    data.pixels.foreach_set(np.linspace(0, 1, 16, dtype=np.float32))

    def build(nodes, links, out):
        p = nodes.new("ShaderNodeBsdfPrincipled")
        links.new(p.outputs[0], out.inputs["Surface"])
        tex = nodes.new("ShaderNodeTexImage")
        tex.image, tex.extension, tex.interpolation = byte, "EXTEND", "Closest"
        mapping = nodes.new("ShaderNodeMapping")
        mapping.inputs["Location"].default_value = (0.1, 0.2, 0.0)
        mapping.inputs["Scale"].default_value = (2.0, 3.0, 1.0)
        links.new(nodes.new("ShaderNodeTexCoord").outputs["UV"], mapping.inputs["Vector"])
        links.new(mapping.outputs[0], tex.inputs["Vector"])
        links.new(tex.outputs["Color"], p.inputs["Base Color"])
        links.new(tex.outputs["Alpha"], p.inputs["Alpha"])
        rough = nodes.new("ShaderNodeTexImage")
        rough.image = data
        links.new(rough.outputs["Color"], p.inputs["Roughness"])
        nmap = nodes.new("ShaderNodeNormalMap")
        nmap.inputs["Strength"].default_value = 0.7
        normal_tex = nodes.new("ShaderNodeTexImage")
        normal_tex.image = data
        links.new(normal_tex.outputs["Color"], nmap.inputs["Color"])
        links.new(nmap.outputs[0], p.inputs["Normal"])

    sc, warnings, rows = export_with(material("Tex", build))
    m = sc.materials
    assert warnings == []
    assert m.image_names == ("Byte", "Data")  # "Data" read once for two nodes
    assert m.image_srgb.tolist() == [True, False]  # byte sRGB: decoded after interpolation
    np.testing.assert_allclose(m.image_texels[:8], texels.reshape(-1, 4), atol=0.5 / 255)  # bottom row first
    spec, diffuse = rows["Tex"][-2:]
    slot = m.lobe_color_tex[diffuse]
    assert m.tex_image[slot] == 0 and m.tex_output[slot] == S.TEX_COLOR
    assert m.tex_extension[slot] == S.EXT_EXTEND and m.tex_interpolation[slot] == S.INTERP_CLOSEST
    np.testing.assert_allclose(m.tex_transform[slot], [[2, 0, 0.1], [0, 3, 0.2]], atol=1e-6)
    alpha = m.lobe_opacity_tex[diffuse]
    assert m.tex_output[alpha] == S.TEX_ALPHA and m.lobe_opacity_tex[spec] == alpha
    transparent = rows["Tex"][0]
    assert m.lobe_kind[transparent] == S.LOBE_TRANSPARENT and m.lobe_opacity_invert[transparent]
    assert m.tex_image[m.lobe_roughness_tex[spec]] == 1
    assert m.tex_image[m.normal_tex[0]] == 1 and m.normal_strength[0] == pytest.approx(0.7)


def test_unsupported_nodes_fall_back_and_warn_once_per_material():
    new_scene()

    def sss(nodes, links, out):
        s = nodes.new("ShaderNodeSubsurfaceScattering")
        s.inputs["Color"].default_value = (0.3, 0.6, 0.9, 1.0)
        links.new(s.outputs[0], out.inputs["Surface"])

    def noisy(nodes, links, out):
        d = nodes.new("ShaderNodeBsdfDiffuse")
        d.inputs["Color"].default_value = (0.1, 0.2, 0.3, 1.0)
        links.new(nodes.new("ShaderNodeTexNoise").outputs["Color"], d.inputs["Color"])
        d2 = nodes.new("ShaderNodeBsdfRefraction")
        mix = nodes.new("ShaderNodeMixShader")
        links.new(d.outputs[0], mix.inputs[1])
        links.new(d2.outputs[0], mix.inputs[2])
        links.new(mix.outputs[0], out.inputs["Surface"])

    sc, warnings, rows = export_with(material("SSS", sss), material("Noisy", noisy))
    m = sc.materials
    r = rows["SSS"]
    assert m.lobe_kind[r].tolist() == [S.LOBE_DIFFUSE]
    np.testing.assert_allclose(m.lobe_color[r[0]], [0.3, 0.6, 0.9], rtol=1e-6)
    r = rows["Noisy"]
    assert m.lobe_kind[r].tolist() == [S.LOBE_DIFFUSE, S.LOBE_DIELECTRIC]
    # The noise is evaluated per point (the material keeps its node graph); the Refraction BSDF
    # is refraction only, with its Beckmann distribution: nothing approximated.
    assert m.graphs[m.names.index("Noisy")] is not None and m.graphs[m.names.index("SSS")] is None
    assert m.lobe_refract_only[r].tolist() == [False, True]
    assert m.lobe_distribution[r[1]] == S.DISTRIBUTIONS[bpy.data.materials["Noisy"].node_tree.nodes[
        "Refraction BSDF"].distribution]
    assert len(warnings) == 1
    sss_warning = next(w for w in warnings if "'SSS'" in w)
    assert "Subsurface Scattering" in sss_warning


def test_uvs_follow_the_corners_also_under_negative_scale():
    new_scene()
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(0.0, 0.0, 0.0))
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(5.0, 0.0, 0.0))
    bpy.context.active_object.scale = (-1.0, 1.0, 1.0)  # a mirroring instance transform
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(10.0, 0.0, 0.0))
    me = bpy.context.active_object.data
    me.uv_layers.remove(me.uv_layers[0])
    me.update()
    sc, _ = export_scene(bpy.context.evaluated_depsgraph_get())
    mesh = sc.mesh
    p = mesh.vertices[mesh.triangles]  # (T,3,3) corner positions
    assert mesh.uvs.shape == (6, 3, 2) and mesh.uvs.dtype == np.float32
    # The plane's UVs are (x + 1) / 2, (y + 1) / 2 in its local frame (x mirrored for the second).
    local_x = np.where(p[:, :, 0] > 7.5, p[:, :, 0] - 10.0, np.where(p[:, :, 0] > 2.5, 5.0 - p[:, :, 0], p[:, :, 0]))
    expected = np.stack([(local_x + 1) / 2, (p[:, :, 1] + 1) / 2], axis=-1)
    no_uv = p[:, 0, 0] > 7.5
    np.testing.assert_allclose(mesh.uvs[~no_uv], expected[~no_uv], atol=1e-6)
    assert np.all(mesh.uvs[no_uv] == 0)  # no UV map: zeros, as Cycles


def test_phong_material_and_render_glossy_with_phong():
    sc = new_scene()
    assert sc.ember.glossy_as_phong is False

    phong = bpy.data.materials.new("Phong")
    phong.ember.model = "PHONG"
    phong.ember.diffuse_color = (0.2, 0.3, 0.4)
    phong.ember.specular_color = (0.5, 0.5, 0.5)
    phong.ember.exponent = 250.0

    def glossy(nodes, links, out):
        g = nodes.new("ShaderNodeBsdfGlossy")
        g.inputs["Roughness"].default_value = math.sqrt(0.05)
        g.inputs["Color"].default_value = (0.3, 0.3, 0.3, 1.0)
        links.new(g.outputs[0], out.inputs["Surface"])

    sc.ember.glossy_as_phong = True
    scene, warnings, rows = export_with(phong, material("Plate", glossy))
    m = scene.materials
    r = rows["Phong"][0]
    assert m.kind[m.names.index("Phong")] == S.MAT_PHONG and m.lobe_kind[r] == S.LOBE_PHONG
    np.testing.assert_allclose(m.lobe_color[r], [0.2, 0.3, 0.4], rtol=1e-6)
    np.testing.assert_allclose(m.lobe_tint[r], [0.5, 0.5, 0.5], rtol=1e-6)
    assert m.lobe_exponent[r] == pytest.approx(250.0)
    r = rows["Plate"][0]
    assert m.lobe_kind[r] == S.LOBE_PHONG
    assert m.lobe_exponent[r] == pytest.approx(2 / 0.05**2 - 2, rel=1e-5)  # Beckmann alpha 0.05 -> 798
    np.testing.assert_allclose(m.lobe_tint[r], [0.3, 0.3, 0.3], rtol=1e-6)
    assert warnings == []


def test_material_panel_and_settings_register_and_unregister():
    assert hasattr(bpy.types, "EMBER_MATERIAL_PT_model") and hasattr(bpy.types, "EMBER_RENDER_PT_materials")
    mat = bpy.data.materials.new("Settings")
    assert mat.ember.model == "NODES" and mat.ember.exponent == pytest.approx(100.0)
    ember.unregister()
    try:
        assert not hasattr(bpy.types.Material, "ember")
        assert not hasattr(bpy.types, "EMBER_MATERIAL_PT_model")
    finally:
        ember.register()
    assert hasattr(bpy.context.scene.ember, "glossy_as_phong")


def test_veach_blend_renders_its_plates_with_phong():
    """scenes/veach_mis.blend asks for Phong (scene.ember.glossy_as_phong) and direct light
    only: the Glossy plates of roughness sqrt(alpha) export as n = 2 / alpha^2 - 2."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    bpy.ops.wm.open_mainfile(filepath=os.path.join(root, "scenes", "veach_mis.blend"))
    sc, warnings = export_scene(bpy.context.evaluated_depsgraph_get())
    m = sc.materials
    plates = [m.names.index(f"Plate{i}") for i in range(4)]
    assert m.lobe_kind[plates].tolist() == [S.LOBE_PHONG] * 4
    np.testing.assert_allclose(m.lobe_exponent[plates], [19998, 798, 198, 30], rtol=1e-5)
    assert sc.settings.max_depth == 1 and warnings == []


@pytest.mark.parametrize("hidden_from", ["Is Camera Ray", "Is Shadow Ray"], ids=["camera", "shadow"])
def test_an_emitter_hidden_from_some_rays_still_emits(hidden_from):
    """Emission mixed to black by a Light Path output (black to camera rays, as the caustic
    reference scenes make their lamp): the material still emits, so light sampling and rays
    other than those find it; its program says where."""
    new_scene()

    def build(nodes, links, out):
        em = nodes.new("ShaderNodeEmission")
        em.inputs["Strength"].default_value = 4.0
        black = nodes.new("ShaderNodeEmission")
        black.inputs["Strength"].default_value = 0.0
        path = nodes.new("ShaderNodeLightPath")
        mix = nodes.new("ShaderNodeMixShader")
        links.new(path.outputs[hidden_from], mix.inputs["Fac"])
        links.new(em.outputs[0], mix.inputs[1])
        links.new(black.outputs[0], mix.inputs[2])
        links.new(mix.outputs[0], out.inputs["Surface"])

    sc, warnings, _ = export_with(material("Lamp", build))
    np.testing.assert_allclose(sc.materials.emission[0], [4.0, 4.0, 4.0], rtol=1e-6)
    assert sc.materials.graphs and sc.materials.graphs[0] is not None
    assert warnings == []


def test_default_surface_is_a_default_principled():
    """An object without a material renders with Cycles' default surface: the defaults of a
    Principled BSDF made in Blender (the table must follow Blender's), exported to the same
    lobes as a new material's node tree."""
    from ember.engine.nodes.default_surface import PRINCIPLED_DEFAULTS, PRINCIPLED_PROPS
    new_scene()
    fresh = bpy.data.materials.new("Fresh")  # Blender's new material: Principled BSDF -> Output
    node = next(n for n in fresh.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    table = {name: (kind, value) for name, kind, value in PRINCIPLED_DEFAULTS}
    assert set(table) == {s.identifier for s in node.inputs}
    for s in node.inputs:
        kind, value = table[s.identifier]
        assert kind == s.type.lower()
        own = np.ravel(s.default_value)[:3] if kind in ("rgba", "vector") else s.default_value
        assert np.allclose(own, value, rtol=0, atol=1e-6), s.identifier
    assert all(getattr(node, key) == value for key, value in PRINCIPLED_PROPS)

    bpy.ops.mesh.primitive_plane_add(location=(0.0, 0.0, 0.0))  # no material
    bpy.ops.mesh.primitive_plane_add(location=(3.0, 0.0, 0.0))
    bpy.context.active_object.data.materials.append(fresh)
    sc, warnings = export_scene(bpy.context.evaluated_depsgraph_get())
    m = sc.materials
    default, made = (np.flatnonzero(m.lobe_material == m.names.index(n)) for n in ("default", "Fresh"))
    assert len(default) == len(made) >= 2  # a specular layer over a diffuse base
    for field in ("lobe_kind", "lobe_weight", "lobe_color", "lobe_tint", "lobe_roughness", "lobe_ior",
                  "lobe_fresnel", "lobe_distribution"):
        a, b = getattr(m, field)[default], getattr(m, field)[made]
        assert np.allclose(a, b, rtol=0, atol=1e-6), field  # Blender keeps float32 defaults
    assert not any("default" in w for w in warnings)
