"""Ember as Blender runs it: the add-on registered in the bpy module, tiny scenes built in
memory, rendered with bpy.ops.render.render and read back from the Render Result (saved as
float EXR). Also the final-render loop (engine/blender/final.py) driven by a fake engine
object for cancel and error handling, and the panels/properties registration.
"""
from __future__ import annotations

import atexit
import os
import shutil
import tempfile
import types
import warnings

import numpy as np
import pytest

pytestmark = pytest.mark.blender

if "bpy" not in __import__("sys").modules:  # keep bpy out of the user's Blender config
    _tmp = tempfile.mkdtemp(prefix="ember_bpy_")
    atexit.register(shutil.rmtree, _tmp, ignore_errors=True)
    os.environ.setdefault("BLENDER_USER_RESOURCES", os.path.join(_tmp, "user"))
    os.environ.setdefault("TMPDIR", _tmp)
bpy = pytest.importorskip("bpy")
import mathutils  # noqa: E402

import ember  # noqa: E402  (tests/conftest.py loads the repo as the package `ember`)
from ember.engine import imageio  # noqa: E402
from ember.engine.blender import final, result  # noqa: E402
from ember.engine.blender.registration import register, unregister  # noqa: E402
from ember.ui import panels  # noqa: E402

STOCK_PANELS = ("RENDER_PT_format", "RENDER_PT_output", "DATA_PT_lens",
                "EEVEE_MATERIAL_PT_context_material", "EEVEE_MATERIAL_PT_surface",
                "EEVEE_WORLD_PT_surface", "DATA_PT_EEVEE_light", "DATA_PT_camera_dof",
                "DATA_PT_camera_dof_aperture", "RENDER_PT_color_management")
OWN_PANELS = ("EMBER_RENDER_PT_sampling", "EMBER_RENDER_PT_light_paths", "EMBER_RENDER_PT_performance",
              "EMBER_RENDER_PT_motion_blur", "EMBER_OBJECT_PT_visibility", "EMBER_WORLD_PT_visibility")


@pytest.fixture(scope="module", autouse=True)
def addon():
    ember.register()
    yield
    ember.unregister()


# --- scene building ------------------------------------------------------------------------
_counter = [0]


def _look_at(ob, target):
    ob.rotation_euler = (mathutils.Vector(target) - ob.location).to_track_quat('-Z', 'Y').to_euler()


def _material(name, *, base=None, emission=None, strength=1.0):
    m = bpy.data.materials.new(name)
    if m.node_tree is None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            m.use_nodes = True
    nt = m.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    if emission is not None:
        node = nt.nodes.new("ShaderNodeEmission")
        node.inputs["Color"].default_value = (*emission, 1.0)
        node.inputs["Strength"].default_value = strength
    else:
        node = nt.nodes.new("ShaderNodeBsdfDiffuse")
        node.inputs["Color"].default_value = (*(base or (0.8, 0.8, 0.8)), 1.0)
    nt.links.new(node.outputs[0], out.inputs["Surface"])
    return m


def _mesh(sc, name, verts, faces, mat=None):
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], faces)
    me.update()
    if mat is not None:
        me.materials.append(mat)
    ob = bpy.data.objects.new(name, me)
    sc.collection.objects.link(ob)
    return ob


def _cube(sc, name, center, half, mat=None):
    cx, cy, cz = center
    v = [(cx + sx * half, cy + sy * half, cz + sz * half)
         for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    f = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return _mesh(sc, name, v, f, mat)


def make_scene(*, camera=True, geometry=True, light=True, emissive=False,
               size=(40, 30), samples=4, seed=0):
    """plane + cube + point light + camera (each optional). emissive=True: emission-only
    materials and no light, so every pixel whose footprint sees one surface is exact."""
    _counter[0] += 1
    sc = bpy.data.scenes.new(f"EmberTest{_counter[0]}")
    sc.render.engine = 'EMBER'
    sc.render.resolution_x, sc.render.resolution_y = size
    sc.render.resolution_percentage = 100
    sc.ember.samples = samples
    sc.ember.seed = seed
    if geometry:
        if emissive:
            plane_mat = _material("plane_e", emission=(1.0, 0.5, 0.25), strength=1.0)
            cube_mat = _material("cube_e", emission=(0.2, 0.6, 1.0), strength=3.0)
        else:
            plane_mat = cube_mat = None
        _mesh(sc, "plane", [(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], [(0, 1, 2, 3)], plane_mat)
        _cube(sc, "cube", (0.3, 0.2, 0.6), 0.6, cube_mat)
    if light and not emissive:
        ld = bpy.data.lights.new("lamp", 'POINT')
        ld.energy = 800.0
        lo = bpy.data.objects.new("lamp", ld)
        lo.location = (2.0, -2.0, 4.0)
        sc.collection.objects.link(lo)
    if camera:
        cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
        cam.location = (1.0, -6.0, 4.5)
        sc.collection.objects.link(cam)
        _look_at(cam, (0.0, 0.0, 0.3))
        sc.camera = cam
    return sc


class Recorder:
    """A final.listeners entry that keeps what each layer produced."""

    def __init__(self):
        self.layers, self.errors, self.progress = {}, [], []

    def on_layer_done(self, layer, stats, image, border):
        self.layers[layer] = (stats, image, border)

    def on_error(self, layer, message, user_error):
        self.errors.append((layer, message, user_error))

    def on_progress(self, layer, progress):
        self.progress.append((layer, progress.samples_done, progress.pass_completed))


@pytest.fixture
def recorder():
    rec = Recorder()
    final.listeners.append(rec)
    yield rec
    final.listeners.remove(rec)


def render_and_read(sc, tmp_path, name="out.exr"):
    """bpy.ops.render.render for sc, then the Render Result as float EXR -> (H, W, 4) top-down."""
    bpy.ops.render.render(scene=sc.name)
    settings = sc.render.image_settings
    settings.file_format = 'OPEN_EXR'
    settings.color_depth = '32'
    settings.color_mode = 'RGBA'
    path = str(tmp_path / name)
    bpy.data.images["Render Result"].save_render(path, scene=sc)
    ch, _ = imageio.read_exr(path)
    return np.stack([ch[c].astype(np.float32) for c in "RGBA"], axis=-1)


# --- through bpy.ops.render.render -----------------------------------------------------------
def test_render_lit_scene(tmp_path, recorder):
    sc = make_scene(samples=4)
    img = render_and_read(sc, tmp_path)
    assert img.shape == (30, 40, 4)
    assert np.isfinite(img).all()
    assert (img[..., :3] >= 0).all()
    lum = img[..., :3].mean(axis=2)
    assert (lum > 0.01).mean() > 0.3  # plane and cube are lit
    assert np.allclose(img[..., 3], 1.0)
    stats, film, border = recorder.layers["ViewLayer"]
    assert stats.samples == 4 and not stats.cancelled
    assert border == (0, 0, 40, 30)
    # the result holds the film exactly, right way up (rect rows are bottom-up)
    assert np.array_equal(img, film)
    assert recorder.progress and recorder.progress[-1][1] == 4
    assert recorder.errors == []


def test_resolution_percentage(tmp_path, recorder):
    sc = make_scene(size=(40, 30), samples=1)
    sc.render.resolution_percentage = 50
    img = render_and_read(sc, tmp_path)
    assert img.shape == (15, 20, 4)


@pytest.mark.parametrize("crop", [True, False])
def test_border_is_border_sized_and_matches_full_frame(tmp_path, recorder, crop):
    """Emission-only scene: a pixel whose filter footprint sees one surface has an exact
    value whatever the random numbers, so such pixels must match the full render exactly."""
    sc = make_scene(emissive=True, size=(48, 36), samples=4, seed=7)
    full = render_and_read(sc, tmp_path, "full.exr")
    sc.render.use_border = True
    sc.render.use_crop_to_border = crop
    sc.render.border_min_x, sc.render.border_max_x = 0.26, 0.71
    sc.render.border_min_y, sc.render.border_max_y = 0.13, 0.58
    part = render_and_read(sc, tmp_path, "border.exr")
    x0, y0, x1, y1 = result.blender_border(sc.render, 48, 36)
    assert (x1 - x0, y1 - y0) == (int(0.71 * 48) - int(0.26 * 48), int(0.58 * 36) - int(0.13 * 36))
    assert recorder.layers["ViewLayer"][2] == (x0, y0, x1, y1)
    if crop:
        assert part.shape == (y1 - y0, x1 - x0, 4)
        crop_part = part
    else:  # uncropped: the border sits in a transparent full frame
        assert part.shape == full.shape
        outside = np.ones(full.shape[:2], bool)
        outside[y0:y1, x0:x1] = False
        assert (part[outside] == 0).all()
        crop_part = part[y0:y1, x0:x1]
    ref = full[y0:y1, x0:x1]
    assert np.isfinite(crop_part).all() and (crop_part[..., :3] > 0).any()
    # pixels whose 5x5 neighbourhood in the full render is uniform are exact in both renders
    lum = full[..., :3].sum(axis=2)
    pad = np.pad(lum, 2, mode="edge")
    uniform = np.ones_like(lum, bool)
    for dy in range(5):
        for dx in range(5):
            uniform &= pad[dy:dy + lum.shape[0], dx:dx + lum.shape[1]] == lum
    mask = uniform[y0:y1, x0:x1]
    assert mask.sum() > 0.3 * mask.size
    assert np.array_equal(crop_part[mask], ref[mask])
    # with both surfaces and the background in the border, the crop is not trivially flat
    assert len(np.unique(ref[mask][:, 0])) >= 2


def test_border_equals_full_frame_crop_exactly(tmp_path):
    sc = make_scene(size=(32, 24), samples=2, seed=3)
    full = render_and_read(sc, tmp_path, "full.exr")
    sc.render.use_border = True
    sc.render.use_crop_to_border = True
    sc.render.border_min_x, sc.render.border_max_x = 0.25, 0.75
    sc.render.border_min_y, sc.render.border_max_y = 0.25, 0.75
    part = render_and_read(sc, tmp_path, "border.exr")
    x0, y0, x1, y1 = result.blender_border(sc.render, 32, 24)
    assert np.array_equal(part, full[y0:y1, x0:x1])


def test_two_view_layers(tmp_path, recorder):
    sc = make_scene(samples=2)
    sc.view_layers[0].name = "Front"
    sc.view_layers.new("Back")
    bpy.ops.render.render(scene=sc.name)
    assert set(recorder.layers) == {"Front", "Back"}
    for layer, (stats, film, _) in recorder.layers.items():
        assert stats.samples == 2
        assert np.isfinite(film).all() and (film[..., :3] > 0.01).any(), layer
    # Both layers are in the Render Result: a multilayer EXR has one part per layer.pass
    settings = sc.render.image_settings
    settings.media_type = 'MULTI_LAYER_IMAGE'
    settings.color_depth = '32'
    path = str(tmp_path / "layers.exr")
    bpy.data.images["Render Result"].save_render(path, scene=sc)
    import OpenEXR
    found = {}
    with OpenEXR.File(path, separate_channels=True) as f:
        for part in f.parts:
            for name, ch in part.channels.items():
                found[(part.name(), name)] = np.asarray(ch.pixels, np.float32)
    for layer in ("Front", "Back"):
        red = [px for (part, name), px in found.items()
               if (part + "." + name).startswith(layer + ".") and "Combined" in part + name
               and name.endswith("R")]
        assert len(red) == 1, (layer, sorted(found))
        assert red[0].shape == (30, 40)
        assert np.isfinite(red[0]).all() and (red[0] > 0.01).any(), layer


def test_missing_camera_reports_error():
    sc = make_scene(camera=False)
    with pytest.raises(RuntimeError, match="(?i)camera"):
        bpy.ops.render.render(scene=sc.name)


def test_empty_scene_reports_error(recorder):
    sc = make_scene(geometry=False, light=False)
    with pytest.raises(RuntimeError, match="Nothing to render"):
        bpy.ops.render.render(scene=sc.name)
    assert recorder.errors and recorder.errors[0][2] is True  # a user error


# --- final.render with a fake engine ---------------------------------------------------------
class FakePass:
    def __init__(self, n):
        self.rect = types.SimpleNamespace(data=None)
        self.rect.foreach_set = lambda a: setattr(self.rect, "data", np.array(a, copy=True))


class FakeEngine:
    """What final.render uses of a RenderEngine; test_break turns True after `break_after` calls."""

    def __init__(self, width, height, break_after=None):
        self.resolution_x, self.resolution_y = width, height
        self.break_after = break_after
        self.breaks = 0
        self.reports, self.errors, self.stats, self.progress = [], [], [], []
        self.begun = self.ended = self.updates = 0
        self.result = None

    def test_break(self):
        self.breaks += 1
        return self.break_after is not None and self.breaks > self.break_after

    def begin_result(self, x, y, w, h, layer=""):
        self.begun += 1
        combined = FakePass(w * h)
        self.result = types.SimpleNamespace(
            resolution_x=w, resolution_y=h,
            layers=[types.SimpleNamespace(name=layer, passes={"Combined": combined})])
        self.combined = combined
        return self.result

    def update_result(self, res):
        self.updates += 1

    def end_result(self, res, cancel=False, **kw):
        self.ended += 1

    def update_stats(self, stats, info):
        self.stats.append((stats, info))

    def update_progress(self, value):
        self.progress.append(value)

    def report(self, kind, message):
        self.reports.append((set(kind), message))

    def error_set(self, message):
        self.errors.append(message)


def _depsgraph(sc):
    dg = sc.view_layers[0].depsgraph
    dg.update()
    return dg


class _CountingEngine(FakeEngine):
    """Records how many test_break calls happen before the session starts."""

    def update_stats(self, stats, info):
        super().update_stats(stats, info)
        if info == "Building" and not hasattr(self, "calls_before_session"):
            self.calls_before_session = self.breaks


def test_cancel_stops_the_render_early():
    sc = make_scene(samples=10000, size=(16, 12))
    dg = _depsgraph(sc)
    sc.ember.samples = 1
    probe = _CountingEngine(16, 12)
    final.render(probe, _depsgraph(sc))  # how many polls export makes
    sc.ember.samples = 10000
    n = probe.calls_before_session + 3
    eng = FakeEngine(16, 12, break_after=n)  # True from call n + 1 on: 3 polls into the run
    stats = final.render(eng, _depsgraph(sc))
    assert stats is not None and stats.cancelled
    assert stats.samples < 10000
    assert eng.breaks == n + 1  # stopped at the first True, no more polls
    assert eng.errors == [] and not [r for r in eng.reports if 'ERROR' in r[0]]
    assert eng.begun == 1 and eng.ended == 1
    assert eng.combined.rect.data is not None and eng.combined.rect.data.size == 16 * 12 * 4
    assert eng.progress[-1] < 1.0


def test_cancel_during_export_is_quiet():
    sc = make_scene(size=(16, 12))
    eng = FakeEngine(16, 12, break_after=0)
    assert final.render(eng, _depsgraph(sc)) is None
    assert eng.errors == [] and eng.reports == []
    assert eng.begun == eng.ended == 1  # the result is closed (written black)


def test_fake_engine_render_writes_every_pass(recorder):
    sc = make_scene(samples=3, size=(16, 12))
    eng = FakeEngine(16, 12)
    stats = final.render(eng, _depsgraph(sc))
    assert stats.samples == 3 and not stats.cancelled
    completed = [p for p in recorder.progress if p[2]]
    assert completed and completed[-1][1] == 3
    assert eng.updates >= len(completed) + 1  # a write per completed pass, plus the final one
    info = [i for s, i in eng.stats if i.startswith("Sample ")]
    assert info and info[-1].startswith("Sample 3/3 | ") and "rays/s" in info[-1]
    assert any(s == "Ember" and i.startswith("Export: ") for s, i in eng.stats)
    assert eng.progress[-1] == 1.0
    img = result.image_from_rect(eng.combined.rect.data, 16, 12)
    assert np.isfinite(img).all() and (img[..., :3] > 0).any()


def test_errors_are_reported_with_a_clear_message():
    eng = FakeEngine(40, 30)
    final.render(eng, _depsgraph(make_scene(geometry=False, light=False)))
    assert len(eng.errors) == 1 and "Nothing to render" in eng.errors[0]
    assert eng.reports == [({'ERROR'}, eng.errors[0])]
    assert eng.ended == eng.begun

    eng = FakeEngine(40, 30)
    final.render(eng, _depsgraph(make_scene(camera=False)))
    assert len(eng.errors) == 1 and "camera" in eng.errors[0].lower()
    assert eng.reports == [({'ERROR'}, eng.errors[0])]


def test_unexpected_exception_short_message_traceback_on_console(monkeypatch, capsys):
    def boom(scene):
        raise ValueError("kaputt")
    monkeypatch.setattr(final, "RenderSession", boom)
    eng = FakeEngine(16, 12)
    assert final.render(eng, _depsgraph(make_scene(size=(16, 12)))) is None
    assert len(eng.errors) == 1
    msg = eng.errors[0]
    assert "ValueError: kaputt" in msg and "Traceback" not in msg and "\n" not in msg
    assert "Traceback" in capsys.readouterr().err
    assert eng.ended == 1


def test_export_warnings_reported_once_per_job(monkeypatch):
    real = final.export_scene

    def export(depsgraph, **kw):
        scene, warns = real(depsgraph, **kw)
        return scene, warns + ["Something is approximated.", "Something is approximated."]
    monkeypatch.setattr(final, "export_scene", export)
    sc = make_scene(samples=1, size=(8, 6))
    eng = FakeEngine(8, 6)
    dg = _depsgraph(sc)
    final.render(eng, dg)
    final.render(eng, dg)  # a second view layer of the same job
    warns = [m for k, m in eng.reports if k == {'WARNING'}]
    assert warns.count("Something is approximated.") == 1


def test_scene_is_not_modified():
    sc = make_scene(samples=2, size=(16, 12))
    before = (sc.ember.samples, sc.render.resolution_x, len(sc.objects), sc.camera.name,
              tuple(sc.camera.location), bpy.data.is_dirty)
    final.render(FakeEngine(16, 12), _depsgraph(sc))
    after = (sc.ember.samples, sc.render.resolution_x, len(sc.objects), sc.camera.name,
             tuple(sc.camera.location), bpy.data.is_dirty)
    assert before == after


# --- pure pieces ------------------------------------------------------------------------------
def test_blender_border_matches_measured_results():
    # (fractions, frame) -> result size Blender 5.0.1 produced for these (measured)
    r = types.SimpleNamespace(use_border=True, border_min_x=0.1, border_max_x=0.55,
                              border_min_y=0.2, border_max_y=0.77)
    x0, y0, x1, y1 = result.blender_border(r, 101, 67)
    assert (x1 - x0, y1 - y0) == (45, 38)
    assert (x0, x1) == (10, 55) and (y0, y1) == (67 - 51, 67 - 13)
    r = types.SimpleNamespace(use_border=True, border_min_x=0.333, border_max_x=0.6667,
                              border_min_y=0.123, border_max_y=0.499)
    b = result.blender_border(r, 101, 67)
    assert (b[2] - b[0], b[3] - b[1]) == (34, 25)
    b = result.blender_border(r, 50, 33)
    assert (b[2] - b[0], b[3] - b[1]) == (17, 12)
    assert result.blender_border(types.SimpleNamespace(use_border=False), 7, 5) == (0, 0, 7, 5)


def test_rect_from_image_crops_and_flips():
    img = np.arange(5 * 7 * 4, dtype=np.float64).reshape(5, 7, 4)
    flat = result.rect_from_image(img, (2, 1, 6, 4))
    assert flat.dtype == np.float32 and flat.shape == (4 * 3 * 4,)
    rect = flat.reshape(3, 4, 4)
    assert np.array_equal(rect[0], img[3, 2:6])  # first rect row = bottom row of the crop
    assert np.array_equal(rect[-1], img[1, 2:6])
    assert np.array_equal(result.image_from_rect(flat, 4, 3), img[1:4, 2:6].astype(np.float32))


# --- registration --------------------------------------------------------------------------------
def test_engine_class_flags():
    from ember.engine.blender.engine import EmberRenderEngine as E
    assert E.bl_idname == "EMBER" and E.bl_label == "Ember"
    assert E.bl_use_shading_nodes_custom is False and E.bl_use_postprocess is True
    assert E.bl_use_eevee_viewport is True and E.bl_use_preview is False
    assert E.is_registered


def test_properties_defaults_and_limits():
    sc = bpy.data.scenes.new("EmberProps")
    try:
        e = sc.ember
        assert (e.integrator, e.samples, e.max_depth, e.seed, e.time_limit, e.batch_size, e.pattern) == \
            ('AUTO', 64, 64, 0, 0.0, 131072, 'SOBOL')
        props = type(e).bl_rna.properties
        # The declared range is the soft one: Blender keeps any value, Ember refuses it.
        assert props["samples"].soft_min == 1
        assert (props["max_depth"].soft_min, props["max_depth"].soft_max) == (0, 1024)  # one range, as the core's
        assert props["time_limit"].soft_min == 0.0
        assert props["batch_size"].soft_min == 1024
        assert [i.identifier for i in props["integrator"].enum_items] == ['PATH', 'PHOTON', 'PPM', 'ICACHE', 'PATH_CAUSTIC', 'AUTO']  # the registry's order
        e.samples = 0
        assert e.samples == 0  # not clamped: the render refuses it
        from ember.engine.blender.export_settings import export_settings
        from ember.engine.errors import EmberError
        with pytest.raises(EmberError, match=r"samples must be at least 1 \(got 0\)"):
            export_settings(sc)
    finally:
        bpy.data.scenes.remove(sc)


def _engines(name):
    return getattr(bpy.types, name).COMPAT_ENGINES


def test_panels_opt_in_and_out_and_reregister():
    for name in OWN_PANELS:
        assert hasattr(bpy.types, name)
    for name in STOCK_PANELS:
        assert 'EMBER' in _engines(name), name
    assert 'EMBER' not in _engines("DATA_PT_light")  # DATA_PT_EEVEE_light draws its type row
    n_opted = len(panels.stock_panels())
    assert n_opted > 100
    unregister()
    try:
        for name in STOCK_PANELS:
            assert 'EMBER' not in _engines(name), name
        assert 'BLENDER_EEVEE' in _engines("DATA_PT_EEVEE_light")
        for name in OWN_PANELS:
            assert not hasattr(bpy.types, name)
        assert not hasattr(bpy.types.Scene, "ember")
        from ember.engine.blender.engine import EmberRenderEngine
        assert not EmberRenderEngine.is_registered
    finally:
        register()
    for name in STOCK_PANELS:
        assert 'EMBER' in _engines(name), name
    register()  # registering twice is harmless
    assert hasattr(bpy.types.Scene, "ember")


def test_status_text_names_the_stage():
    from types import SimpleNamespace as NS
    p = NS(samples_done=0, samples_target=16, elapsed=1.5, rays_per_second=2e6, noise=None, stage="photons")
    assert final.stats_text(p).startswith("Photons | Sample 0/16 | 1.5 s")
    assert final.stats_text(NS(**{**vars(p), "stage": "pixels"})).startswith("Sample 0/16")
