"""Sampling controls through Blender: properties, presets, the animated seed per frame,
validation messages."""
import atexit
import os
import shutil
import tempfile

import pytest

if "bpy" not in __import__("sys").modules:  # keep bpy out of the user's Blender config
    _tmp = tempfile.mkdtemp(prefix="ember_bpy_")
    atexit.register(shutil.rmtree, _tmp, ignore_errors=True)
    os.environ.setdefault("BLENDER_USER_RESOURCES", os.path.join(_tmp, "user"))
bpy = pytest.importorskip("bpy")

import ember  # noqa: E402
from ember.engine.blender.export_settings import export_settings  # noqa: E402
from ember.engine.errors import EmberError  # noqa: E402
from ember.ui.presets import PRESETS  # noqa: E402

pytestmark = pytest.mark.blender


@pytest.fixture(scope="module", autouse=True)
def addon():
    ember.register()
    yield
    ember.unregister()


@pytest.fixture
def scene():
    sc = bpy.data.scenes.new("EmberSampling")
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 32, 32, 100
    yield sc
    bpy.data.scenes.remove(sc)


def test_sampling_properties_are_cycles_like(scene):
    e = scene.ember
    assert (e.use_adaptive_sampling, e.adaptive_threshold, e.adaptive_min_samples, e.use_animated_seed) == \
        (False, pytest.approx(0.01), 0, False)
    props = type(e).bl_rna.properties
    # The declared ranges are the sliders' (soft) ones: a value outside is refused at render, never clamped.
    assert (props["adaptive_threshold"].soft_min, props["adaptive_threshold"].soft_max) == (pytest.approx(0.001), 1.0)
    assert (props["adaptive_min_samples"].soft_min, props["adaptive_min_samples"].soft_max) == (0, 4096)
    e.use_adaptive_sampling, e.adaptive_threshold, e.adaptive_min_samples = True, 0.05, 32
    s = export_settings(scene)
    assert (s.adaptive, s.adaptive_threshold, s.adaptive_min_samples) == (True, pytest.approx(0.05), 32)


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_each_preset_sets_what_it_says(scene, name):
    """Every value of the preset lands, from settings far from it, through the operator the
    Sampling panel's preset menu calls; the exported Settings follow."""
    e = scene.ember
    e.samples, e.use_adaptive_sampling, e.adaptive_threshold, e.adaptive_min_samples = 3, False, 0.5, 77
    e.time_limit, e.noise_target, e.max_depth = 9.0, 0.05, 3
    window_scene = bpy.context.window.scene if bpy.context.window else None
    with bpy.context.temp_override(scene=scene):
        assert bpy.ops.render.ember_sampling_preset(preset=name) == {'FINISHED'}
    for prop, value in PRESETS[name].items():
        assert getattr(e, prop) == pytest.approx(value), prop
    s = export_settings(scene)
    assert (s.samples, s.adaptive, s.adaptive_threshold, s.max_depth, s.time_limit) == (
        PRESETS[name]["samples"], True, pytest.approx(PRESETS[name]["adaptive_threshold"]),
        PRESETS[name]["max_depth"], 0.0)
    if window_scene is not None:
        assert bpy.context.window.scene == window_scene


def test_presets_differ_as_their_names_say():
    assert PRESETS["PREVIEW"]["adaptive_threshold"] > PRESETS["FINAL"]["adaptive_threshold"]
    assert PRESETS["PREVIEW"]["samples"] < PRESETS["FINAL"]["samples"]


def test_animated_seed_gives_each_frame_its_seed(scene):
    """Off (the default): the same seed on every frame. On: a hash of seed and frame, so
    frames 1 and 2 differ and frame 1 always gets the same one."""
    scene.ember.seed = 4
    seeds = []
    for frame in (1, 2, 1):
        scene.frame_set(frame)
        seeds.append(export_settings(scene).seed)
    assert seeds == [4, 4, 4]
    scene.ember.use_animated_seed = True
    seeds = []
    for frame in (1, 2, 1):
        scene.frame_set(frame)
        seeds.append(export_settings(scene).seed)
    assert seeds[0] == seeds[2] != seeds[1] and 4 not in seeds


@pytest.mark.parametrize("override, words", [
    (dict(adaptive_threshold=1.5), "adaptive threshold must be at most 1 \\(got 1.5\\)"),
    (dict(adaptive_threshold=float("nan")), "adaptive threshold must be a finite number"),
    (dict(adaptive_min_samples=-1), "adaptive min samples must be at least 0"),
])
def test_bad_adaptive_values_get_a_clear_message(scene, override, words):
    with pytest.raises(EmberError, match=words):
        export_settings(scene, overrides=override)
