"""Render passes through Blender: registered under the pass list's names, written into the
render result, Blender's multilayer EXR with Ember's metadata, the denoising passes against
Cycles' on the Cornell box, and the compositor's Denoise node (OpenImageDenoise) on Ember's
image with them."""
from __future__ import annotations

import pathlib
import types

import numpy as np
import pytest

pytestmark = pytest.mark.blender
bpy = pytest.importorskip("bpy")

import ember  # noqa: E402
from ember.engine import imageio, metrics  # noqa: E402
from ember.engine import passes as passes_mod  # noqa: E402
from ember.engine.blender import passes as blender_passes  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
CORNELL = ROOT / "scenes" / "cornell_box.blend"
ALL_BUT_INTEGRATOR = [p.name for p in passes_mod.PASSES if p.group != "integrator"]
HEADER = ("ember/engine", "ember/version", "ember/integrator", "ember/samples", "ember/seed", "ember/renderSeconds")


@pytest.fixture(scope="module", autouse=True)
def addon():
    ember.register()
    yield
    ember.unregister()


def _enable_all(view_layer):
    for p in passes_mod.PASSES:
        if p.prop.startswith("ember."):
            setattr(view_layer.ember, p.prop[len("ember."):], True)
        else:
            setattr(view_layer, p.prop, True)


def _cornell(engine="EMBER", size=32, samples=4):
    bpy.ops.wm.open_mainfile(filepath=str(CORNELL), load_ui=False)
    sc = bpy.context.scene
    sc.render.engine = engine
    sc.render.resolution_x = sc.render.resolution_y = size
    sc.render.resolution_percentage = 100
    sc.ember.samples = samples
    sc.ember.seed = 3
    sc.ember.integrator = 'PATH'  # the passes' integrator (auto, the default, picks icache for the Cornell box)
    return sc


def _read_multilayer(path, layer="ViewLayer"):
    """{pass name: (H, W, C)} and the header of a multilayer EXR (Blender's or render.py's)."""
    import OpenEXR
    out, header = {}, {}
    with OpenEXR.File(str(path), separate_channels=True) as f:
        for part in f.parts:
            header.update(part.header)
            for name, ch in part.channels.items():
                _, pass_name, letter = name.split(".", 2) if name.count(".") >= 2 else (None, name, "")
                out.setdefault(pass_name, {})[letter] = ch.pixels
    images = {}
    for name, chans in out.items():
        order = passes_mod.BY_NAME[name].chan_id if name in passes_mod.BY_NAME else sorted(chans)
        images[name] = np.stack([chans[c] for c in order], axis=-1).astype(np.float64)
    return images, header


def test_registered_names_match_the_pass_list():
    """update_render_passes registers exactly the enabled passes of engine/passes.py, with
    their channels; Caustics only for an integrator that writes it (none yet)."""
    sc = bpy.data.scenes.new("PassNames")
    vl = sc.view_layers[0]
    calls = []
    fake = types.SimpleNamespace(register_pass=lambda *a: calls.append(a[2:]))
    for p in passes_mod.PASSES:  # all off (Combined stays)
        if not p.prop.startswith("ember."):
            setattr(vl, p.prop, False)
    blender_passes.register_passes(fake, sc, vl)
    assert [c[0] for c in calls] == ["Combined"]
    _enable_all(vl)
    calls.clear()
    blender_passes.register_passes(fake, sc, vl)
    assert [c[0] for c in calls] == ALL_BUT_INTEGRATOR
    for name, channels, chan_id, kind in calls:
        p = passes_mod.BY_NAME[name]
        assert (channels, chan_id, kind) == (p.channels, p.chan_id, p.kind)
    sc.ember.integrator = 'PHOTON'  # an integrator with its own pass
    calls.clear()
    blender_passes.register_passes(fake, sc, vl)
    assert [c[0] for c in calls] == [p.name for p in passes_mod.PASSES
                                     if p.group not in ("light", "color")]  # light passes: path only
    sc.ember.integrator = 'PATH'
    # Cycles' own switches work too (a .blend set up for Cycles).
    vl.ember.denoising_store_passes = False
    vl.cycles.denoising_store_passes = True
    assert "Denoising Albedo" in blender_passes.enabled_passes(vl)
    bpy.data.scenes.remove(sc)


def test_blender_multilayer_exr_holds_every_pass_and_the_metadata(tmp_path):
    sc = _cornell()
    _enable_all(sc.view_layers[0])
    bpy.ops.render.render()
    sc.render.image_settings.media_type = 'MULTI_LAYER_IMAGE'
    sc.render.image_settings.file_format = 'OPEN_EXR_MULTILAYER'
    sc.render.image_settings.color_depth = '32'
    path = tmp_path / "passes.exr"
    bpy.data.images["Render Result"].save_render(str(path), scene=sc)
    images, header = _read_multilayer(path)
    assert set(ALL_BUT_INTEGRATOR) <= set(images)
    for key in HEADER:
        assert key in header, key
    assert header["ember/samples"] == "4" and header["ember/integrator"] == "path"
    # The light passes of Blender's file recombine into its Combined (Cycles' formula).
    total = images["Emission"] + images["Environment"]
    for cls in passes_mod.LOBE_CLASSES:
        total += (images[f"{cls} Direct"] + images[f"{cls} Indirect"]) * images[f"{cls} Color"]
    np.testing.assert_allclose(total, images["Combined"][..., :3], rtol=1e-4, atol=1e-5)
    assert np.all(images["Debug Sample Count"] == 1)  # Cycles' scale: the share of the samples


def _denoising_passes(engine, samples):
    sc = _cornell(engine, size=32, samples=samples)
    vl = sc.view_layers[0]
    if engine == "CYCLES":
        sc.cycles.samples = samples
        sc.cycles.use_denoising = False
        vl.cycles.denoising_store_passes = True
    else:
        vl.ember.denoising_store_passes = True
    bpy.ops.render.render()
    rr = bpy.data.images["Render Result"]
    sc.render.image_settings.media_type = 'MULTI_LAYER_IMAGE'
    sc.render.image_settings.file_format = 'OPEN_EXR_MULTILAYER'
    sc.render.image_settings.color_depth = '32'
    path = pathlib.Path(bpy.app.tempdir or "/tmp") / f"denoising_{engine}.exr"
    rr.save_render(str(path), scene=sc)
    images, _ = _read_multilayer(path)
    return images["Denoising Albedo"], images["Denoising Normal"]


def test_denoising_albedo_and_normal_match_cycles_and_are_noise_free():
    """Cornell box (diffuse, 32x32): away from edges Ember's albedo and normal are the same at
    2 and 16 spp (noise-free) and equal Cycles' (16 spp; its denoising normal is in camera
    space) to float precision in most pixels; the rest are edge pixels, where the renderers'
    filter samples differ (the margins: bench/results/denoise/report.md)."""
    albedo_2, normal_2 = _denoising_passes("EMBER", 2)
    albedo, normal = _denoising_passes("EMBER", 16)
    c_albedo, c_normal = _denoising_passes("CYCLES", 16)
    for mine, few in ((albedo, albedo_2), (normal, normal_2)):
        assert np.all(np.abs(mine - few) < 1e-6, axis=-1).mean() > 0.5
    for mine, theirs in ((albedo, c_albedo), (normal, c_normal)):
        err = np.abs(mine - theirs).max(axis=-1)
        assert (err < 1e-5).mean() > 0.6, (err < 1e-5).mean()
        assert np.quantile(err, 0.95) < 0.15, np.quantile(err, 0.95)


def _denoise_tree(sc):
    """Render Layers -> Denoise (Image, Albedo, Normal) -> group output, Blender 5's compositor."""
    tree = bpy.data.node_groups.new("EmberDenoise", "CompositorNodeTree")
    sc.compositing_node_group = tree
    layers = tree.nodes.new("CompositorNodeRLayers")
    layers.scene = sc
    denoise = tree.nodes.new("CompositorNodeDenoise")
    out = tree.nodes.new("NodeGroupOutput")
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    tree.links.new(layers.outputs["Image"], denoise.inputs["Image"])
    tree.links.new(layers.outputs["Denoising Albedo"], denoise.inputs["Albedo"])
    tree.links.new(layers.outputs["Denoising Normal"], denoise.inputs["Normal"])
    tree.links.new(denoise.outputs["Image"], out.inputs[0])


def _render_rgb(sc, path):
    bpy.ops.render.render()
    s = sc.render.image_settings
    s.media_type = 'IMAGE'
    s.file_format, s.color_depth, s.color_mode = 'OPEN_EXR', '32', 'RGBA'
    bpy.data.images["Render Result"].save_render(str(path), scene=sc)
    ch, _ = imageio.read_exr(path)
    return np.stack([ch[c] for c in "RGB"], axis=-1).astype(np.float64)


def test_compositor_denoise_brings_ember_closer_to_the_reference(tmp_path):
    """Cornell box 64x64 at 16 spp through bpy.ops.render.render and the compositor's Denoise
    node fed Ember's albedo and normal: relMSE against the Cycles reference falls well below
    the noisy image's (bench/results/denoise/report.md)."""
    sc = _cornell(size=64, samples=16)
    sc.view_layers[0].ember.denoising_store_passes = True
    reference = imageio.read_rgb(ROOT / "tests" / "data" / "cornell_box_cycles.exr")
    sc.render.use_compositing = False
    noisy = metrics.rel_mse(_render_rgb(sc, tmp_path / "noisy.exr"), reference)
    _denoise_tree(sc)
    sc.render.use_compositing = True
    denoised = metrics.rel_mse(_render_rgb(sc, tmp_path / "denoised.exr"), reference)
    print(f"relMSE at 16 spp: noisy {noisy:.3e}, denoised {denoised:.3e}")
    assert denoised < 0.4 * noisy


def test_transparent_film_through_blender(tmp_path):
    """Render > Film > Transparent: alpha 0 where the camera sees the sky, 1 on the floor,
    no world colour in the sky's pixels; the world still lights the floor."""
    sc = bpy.data.scenes.new("Transparent")
    sc.render.engine = 'EMBER'
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 16, 16, 100
    sc.ember.samples = 4
    me = bpy.data.meshes.new("floor")
    me.from_pydata([(-50, -50, 0), (50, -50, 0), (50, 50, 0), (-50, 50, 0)], [], [(0, 1, 2, 3)])
    sc.collection.objects.link(bpy.data.objects.new("floor", me))
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    cam.location, cam.rotation_euler = (0, 0, 1), (np.radians(90), 0, 0)  # horizon across the middle
    sc.collection.objects.link(cam)
    sc.camera = cam
    sc.world = bpy.data.worlds.new("sky")
    sc.world.use_nodes = True
    sc.world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.2, 0.4, 0.8, 1)
    sc.render.film_transparent = True
    bpy.ops.render.render(scene=sc.name)
    s = sc.render.image_settings
    s.media_type = 'IMAGE'
    s.file_format, s.color_depth, s.color_mode = 'OPEN_EXR', '32', 'RGBA'
    bpy.data.images["Render Result"].save_render(str(tmp_path / "t.exr"), scene=sc)
    ch, _ = imageio.read_exr(tmp_path / "t.exr")
    rgba = np.stack([ch[c] for c in "RGBA"], axis=-1)
    assert np.all(rgba[:6, :, 3] == 0) and np.all(rgba[:6, :, :3] == 0)
    assert np.all(rgba[-6:, :, 3] == 1) and np.all(rgba[-6:, :, :3] > 0.05)
    bpy.data.scenes.remove(sc)


def test_film_and_passes_panels_are_registered():
    from ember.ui import panels
    for name in ("EMBER_RENDER_PT_film", "EMBER_VIEWLAYER_PT_passes"):
        cls = getattr(bpy.types, name)
        assert cls.COMPAT_ENGINES == {"EMBER"} and cls in panels.classes
    assert bpy.types.EMBER_VIEWLAYER_PT_passes.bl_context == "view_layer"


def test_depth_position_normal_match_cycles():
    """Cornell box 32x32, 16 spp: Depth, Position and Normal, means over the pixel's samples
    as Cycles writes them, agree with Cycles' in the median pixel (Depth and Position to a few
    centimetres, Normal to float precision); edge pixels differ by the renderers' own filter
    samples. The first sample's hit instead of the mean would be far off (measured in
    bench/results/denoise/report.md)."""
    images = {}
    for engine in ("EMBER", "CYCLES"):
        sc = _cornell(engine, size=32, samples=16)
        sc.cycles.samples = 16
        vl = sc.view_layers[0]
        vl.use_pass_z = vl.use_pass_normal = vl.use_pass_position = True
        bpy.ops.render.render()
        s = sc.render.image_settings
        s.media_type, s.file_format, s.color_depth = 'MULTI_LAYER_IMAGE', 'OPEN_EXR_MULTILAYER', '32'
        path = pathlib.Path(bpy.app.tempdir or "/tmp") / f"hit_{engine}.exr"
        bpy.data.images["Render Result"].save_render(str(path), scene=sc)
        images[engine] = _read_multilayer(path)[0]
    for name, bound in (("Depth", 0.03), ("Position", 0.03), ("Normal", 1e-5)):
        err = np.abs(images["EMBER"][name] - images["CYCLES"][name]).max(axis=-1)
        assert np.median(err) < bound, (name, np.median(err))
