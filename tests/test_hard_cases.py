"""Hard-case suite: numerically hostile scenes render with no NaN/Inf, no
negative values, no rejected non-finite samples, and means within statistical tolerance of
their reference: analytic (scenes/build_hard.py, rendered in the core without bpy), an
untranslated twin, or Cycles (bench/references/hard_*_64.exr of scenes/build_bench.py's
.blend files, rendered through Blender).

Statistics: independent samples (pattern 'random'), so a pixel's sample variance is an honest
variance of its mean and pixels are independent; a region's (or the image's) mean error over
sqrt(sum of both renderers' variances) is a z-score. All z-tests of the module share one
Sidak-corrected threshold (ALPHA over N_TESTS). Pixels that see a small emitter directly are
left out of the Cycles comparisons: their values are rare enormous samples on both sides."""
from __future__ import annotations

import os
import pathlib
import sys
import tempfile

import numpy as np
import pytest
from scipy import stats as scipy_stats

from ember.engine.session import RenderSession

from stats import sidak_alpha

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scenes"))
import build_hard as hard  # noqa: E402

ALPHA = 0.01
N_TESTS = 400  # an upper bound on the z-tests below (6 Cycles scenes x 51, analytic ones)
Z_MAX = float(scipy_stats.norm.isf(sidak_alpha(ALPHA, N_TESTS) / 2))  # ~4.1


def _render(scene):
    session = RenderSession(scene)
    stats = session.run()
    return session.film.mean(), session.film.variance_of_mean(), stats


def _sane(mean, stats):
    assert stats.nonfinite == 0, f"{stats.nonfinite} non-finite samples rejected"
    assert np.all(np.isfinite(mean)) and np.all(mean >= 0)


def _z(diff_sum, var_sum):
    return diff_sum / np.sqrt(np.maximum(var_sum, 1e-300))


# ---- analytic scenes (no bpy) ---------------------------------------------------------------
@pytest.mark.parametrize("lobe", ["phong", "ggx"])
def test_near_mirror_lobes_reflect_albedo_times_enclosure(lobe):
    """Phong n = 1e6 and GGX roughness 0.001 seen at normal incidence inside a uniformly
    emitting enclosure: every pixel's expectation is albedo x L0."""
    scene, expected = hard.glossy_enclosure(lobe, samples=32)
    mean, var, stats = _render(scene)
    _sane(mean, stats)
    z = _z((mean - expected).sum(axis=(0, 1)), var.sum(axis=(0, 1)))
    assert np.all(np.abs(z) < Z_MAX), z
    assert np.allclose(mean.mean(axis=(0, 1)), expected, rtol=2e-3)


@pytest.mark.parametrize("offset, recentre", [
    (1e4, False),  # the core as is: 0.6 mm float32 steps
    (1e6, True),   # 6 cm steps: rendered about the scene's centre (what the export does)
    (1e6, False),  # the core scene as is: RenderSession renders it about its own centre
])
def test_translated_scene_equals_untranslated(offset, recentre):
    from ember.engine.blender.export import recentred
    base_mean, base_var, _ = _render(hard.room(0.0, seed=1, samples=64))
    scene = hard.room(offset, seed=2, samples=64)  # independent samples
    if recentre:
        scene = recentred(scene)
    mean, var, stats = _render(scene)
    _sane(mean, stats)
    d, v = mean - base_mean, var + base_var
    assert np.all(np.abs(_z(d.sum(axis=(0, 1)), v.sum(axis=(0, 1)))) < Z_MAX)
    blocks = lambda a: a.reshape(4, 8, 4, 8, 3).sum(axis=(1, 3))  # noqa: E731
    assert np.all(np.abs(_z(blocks(d), blocks(v))) < Z_MAX)


def test_recentring_moves_everything_together():
    from ember.engine.blender.export import recentred, scene_origin
    near, far = hard.room(0.0), hard.room(1e6)
    moved = recentred(far)
    shift = moved.mesh.vertices.astype(np.float64) - near.mesh.vertices
    assert np.all(shift == shift[0]) and np.all(np.abs(shift[0]) <= 2)  # exact: a 0.5 m grid
    cam_shift = moved.camera.world_from_camera[:3, 3] - near.camera.world_from_camera[:3, 3]
    assert np.allclose(cam_shift, shift[0], atol=1e-9)
    assert np.array_equal(moved.camera.world_from_camera[:3, :3], near.camera.world_from_camera[:3, :3])
    assert recentred(near) is near  # near the origin nothing changes
    assert np.array_equal(scene_origin(np.array([[1e6, 2e6, 0.0], [1e6 + 4, 2e6, 2.0]])), [1e6 + 2, 2e6, 1.0])


def _mixtures(mean, lo, hi, n):
    """Each sample is exactly lo or hi: the pixel mean is lo + (hi - lo) k / n, k integer."""
    k = (mean - lo) / (hi - lo) * n
    return np.all(np.abs(k - np.round(k)) < 1e-6) and np.all(mean >= lo - 1e-12) and np.all(mean <= hi + 1e-12)


def test_grazing_camera_over_a_kilometre_plane():
    """5 cm above a 1 km plane, looking 0.5 degrees down: each path that meets the plane
    returns a L exactly (it sees only sky), so no acne, no leak, no lost sample shows as
    anything but a or 1 times the sky."""
    scene, (lo, hi) = hard.grazing_plane(samples=16)
    mean, var, stats = _render(scene)
    _sane(mean, stats)
    assert _mixtures(mean, lo, hi, 16)
    below = mean[-10:]  # the lower third of the frame is ground up to ~50 m away
    assert np.allclose(below, lo, rtol=1e-12, atol=0) and np.allclose(mean[:10], hi, rtol=1e-12, atol=0)


@pytest.mark.parametrize("kind", ["texel", "delta"])
def test_sun_1e5_brighter_than_the_sky(kind):
    scene, expected = hard.sun_and_sky(kind, samples=32)
    mean, var, stats = _render(scene)
    _sane(mean, stats)
    d, v = (mean - expected).sum(axis=(0, 1)), var.sum(axis=(0, 1))
    assert np.all(np.abs(d) <= Z_MAX * np.sqrt(v) + 1e-9 * expected * mean.shape[0] * mean.shape[1]), (
        mean.mean(axis=(0, 1)), expected, _z(d, v))


def test_light_inside_a_closed_box_does_not_leak():
    """A 1 MW point light inside a closed box: outside, the box shows a x sky exactly."""
    scene, (lo, hi) = hard.light_in_box(samples=16)
    mean, var, stats = _render(scene)
    _sane(mean, stats)
    assert _mixtures(mean, lo, hi, 16), mean.max()


def test_camera_inside_an_object_sees_black():
    mean, var, stats = _render(hard.camera_in_box(samples=8))
    _sane(mean, stats)
    assert np.all(mean == 0)


# ---- against Cycles, through Blender --------------------------------------------------------
CYCLES = ["hard_tiny_light", "hard_light_near_wall", "hard_degenerate", "hard_phong", "hard_far_origin",
          "hard_grazing"]
SAMPLES = 256


@pytest.fixture(scope="module")
def blender():
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))
    bpy = pytest.importorskip("bpy")
    import ember
    ember.register()
    yield bpy
    ember.unregister()


class _Grab:
    def on_progress(self, layer, progress):
        self.film = progress.film

    def on_layer_done(self, layer, stats, image, border):
        self.stats = stats


def _render_blend(bpy, blend, size, samples, seed=1):
    from ember.engine.blender import final
    bpy.ops.wm.open_mainfile(filepath=str(blend), load_ui=False)
    sc = bpy.context.scene
    sc.render.engine = "EMBER"
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = size[1], size[0], 100
    sc.ember.samples, sc.ember.seed, sc.ember.pattern = samples, seed, "RANDOM"
    sc.ember.integrator = 'PATH'  # the unbiased one these z-tests are for (the default, auto, may choose photon)
    grab = _Grab()
    final.listeners.append(grab)
    try:
        bpy.ops.render.render()
    finally:
        final.listeners.remove(grab)
    return grab.film.mean(), grab.film.variance_of_mean(), grab.stats


@pytest.mark.blender
@pytest.mark.parametrize("name", CYCLES)
def test_matches_cycles(blender, name):
    from ember.engine import imageio
    ch, _ = imageio.read_exr(ROOT / "bench" / "references" / f"{name}_64.exr")
    ref = np.stack([ch[c] for c in "RGB"], -1).astype(np.float64)
    ref_var = np.stack([ch["var." + c] for c in "RGB"], -1).astype(np.float64)
    mean, var, stats = _render_blend(blender, ROOT / "scenes" / f"{name}.blend", ref.shape[:2], SAMPLES)
    _sane(mean, stats)
    lum = ref.mean(axis=2)
    keep = (lum <= 50 * np.median(lum))[..., None]  # not a directly seen small emitter
    d = np.where(keep, mean - ref, 0.0)
    v = np.where(keep, np.where(np.isfinite(var), var, 0.0) + ref_var, 0.0)
    z_image = _z(d.sum(axis=(0, 1)), v.sum(axis=(0, 1)))
    blocks = lambda a: a.reshape(4, 16, 4, 16, 3).sum(axis=(1, 3))  # noqa: E731
    z_blocks = _z(blocks(d), blocks(v))
    z_blocks = np.where(blocks(v) > 0, z_blocks, 0.0)
    assert np.all(np.abs(z_image) < Z_MAX), f"{name}: image mean z = {z_image}"
    worst = np.unravel_index(np.abs(z_blocks).argmax(), z_blocks.shape)
    assert np.abs(z_blocks).max() < Z_MAX, f"{name}: block {worst[:2]} channel {worst[2]} z = {z_blocks[worst]:.2f}"
