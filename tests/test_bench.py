"""bench/'s own logic on synthetic data: the error metrics, the equal-time interpolation, the
scene list, the snapshot ladder and the memory probe. (The benchmark itself is not a test:
it measures time, `python bench/run.py`.)"""
from __future__ import annotations

import os
from types import SimpleNamespace

import numpy as np
import pytest

from bench import metrics, report, scenes


def test_relmse_pins_epsilon_and_formula():
    assert metrics.EPS == 1e-2
    ref = np.ones((4, 5, 3))
    assert metrics.rel_mse(ref * 1.1, ref) == pytest.approx(0.01 / 1.01, rel=1e-12)
    dark = np.zeros((4, 5, 3))
    assert metrics.rel_mse(dark + 0.1, dark) == pytest.approx(0.01 / 0.01, rel=1e-12)  # eps keeps it finite


def test_relmse_mask_selects_pixels():
    ref = np.ones((2, 2, 3))
    img = ref.copy()
    img[0, 0] = 2.0
    mask = np.ones((2, 2), bool)
    assert metrics.rel_mse(img, ref) == pytest.approx(1 / 1.01 / 4)
    mask[0, 0] = False
    assert metrics.rel_mse(img, ref, mask) == 0.0


def test_rmse_and_nan_count():
    ref = np.full((8, 8, 3), 0.5)
    assert metrics.rmse(ref + 0.1, ref) == pytest.approx(0.1, rel=1e-12)
    img = ref.copy()
    img[0, 0, 0] = np.nan
    img[1, 1, :2] = np.nan  # one pixel, two channels
    img[2, 2, 2] = np.inf
    assert metrics.nan_count(img) == 3
    # non-finite values count as 0: each contributes (0 - 0.5)^2 / (0.25 + eps)
    expected = 4 * 0.25 / 0.26 / img.size
    assert metrics.rel_mse(img, ref) == pytest.approx(expected, rel=1e-12)


def test_reference_noise_is_subtracted_in_expectation():
    """Unbiased image and reference, independent noise: the measured relMSE is the sum of
    both noises; subtracting the reference's own share leaves the image's."""
    rng = np.random.default_rng(1)
    truth = np.full((256, 256, 3), 0.5)
    s_ref, s_img = 0.01, 0.05
    ref = truth + rng.normal(0, s_ref, truth.shape)
    img = truth + rng.normal(0, s_img, truth.shape)
    m = metrics.evaluate(img, ref, np.full(truth.shape, s_ref ** 2))
    assert m["relmse_ref"] == pytest.approx(s_ref ** 2 / 0.26, rel=0.02)
    assert m["relmse"] == pytest.approx((s_img ** 2 + s_ref ** 2) / 0.26, rel=0.03)
    assert m["relmse_corrected"] == pytest.approx(s_img ** 2 / 0.26, rel=0.03)


def test_hdr_flip_orders_errors():
    rng = np.random.default_rng(2)
    ref = rng.uniform(0.1, 2.0, (64, 64, 3))
    small = metrics.hdr_flip(ref * rng.normal(1, 0.02, ref.shape), ref)
    large = metrics.hdr_flip(ref * rng.normal(1, 0.3, ref.shape), ref)
    assert metrics.hdr_flip(ref, ref) == pytest.approx(0.0, abs=1e-6)
    assert 0 < small < large <= 1
    broken = ref.copy()
    broken[3, 3] = np.nan
    assert np.isfinite(metrics.hdr_flip(broken, ref))


def test_cycles_at_interpolates_log_log():
    pts = [{"seconds": 1.0, "relmse": 1e-2}, {"seconds": 4.0, "relmse": 2.5e-3}]
    assert report.cycles_at(pts, 2.0) == pytest.approx(5e-3)
    assert report.cycles_at(pts, 8.0) == pytest.approx(1.25e-3)  # slope -1 past the last point
    assert report.cycles_at(pts, 0.5) == pytest.approx(2e-2)
    corrected = [dict(p, relmse_corrected=p["relmse"] / 2) for p in pts]
    assert report.cycles_at(corrected, 2.0) == pytest.approx(2.5e-3)


def test_scene_list_skips_missing_files_with_a_note(monkeypatch):
    fake = scenes.BenchScene("nowhere", "no_such_file.blend", "scenes/nothing.py", quick=True)
    monkeypatch.setattr(scenes, "SCENES", scenes.SCENES + (fake,))
    run, notes = scenes.available(["cornell_box", "nowhere", "bogus"])
    assert [s.name for s in run] == ["cornell_box"]
    assert any("nowhere: skipped" in n and "scenes/nothing.py" in n for n in notes)
    assert any("unknown scene 'bogus'" in n for n in notes)
    quick, _ = scenes.available(quick=True)
    assert all(s.quick for s in quick)


@pytest.mark.blender
def test_snapshots_take_the_first_image_past_each_budget():
    pytest.importorskip("bpy")
    from bench.render_ember import _Snapshots

    class Film:
        def __init__(self, n):
            self.count = np.full(4, n)

        def mean(self):
            return np.full((2, 2, 3), float(self.count[0]))

    now = [0.0]
    shots = _Snapshots([1.0, 2.0, 4.0], clock=lambda: now[0])
    now[0] = 0.3
    shots.on_export("ViewLayer", "done")  # the clock starts here
    for t, n in [(0.5, 1), (1.2, 0), (1.4, 2), (1.6, 3), (4.5, 8), (5.0, 9)]:
        now[0] = 0.3 + t
        shots.on_progress("ViewLayer", SimpleNamespace(film=Film(n)))
    # 1.2 s has no samples yet; 1.4 s is the first image past 1 s; 4.5 s passes 2 and 4 at once
    assert [(b, round(t, 9), n) for b, t, n, _ in shots.taken] == [(1.0, 1.4, 2.0), (4.0, 4.5, 8.0)]


def test_memory_probe_reads_this_process():
    from bench import memory
    assert memory.tree_rss_kib(os.getpid()) > 10_000  # Python + NumPy: well over 10 MB


def _floor_with_caustic():
    """64x64 synthetic caustic scene: lit floor 0.5, a shadow 0.05 around the seed, a 3x4
    caustic of 6.0 inside the shadow, and a bright highlight (20.0) elsewhere that must not
    join the region."""
    from bench import regions
    img = np.full((64, 64, 3), 0.5)
    img[30:50, 15:40] = 0.05  # shadow
    img[39:42, 26:30] = 6.0  # caustic
    img[10:13, 50:53] = 20.0  # a highlight far from the seed
    truth = np.zeros((64, 64), bool)
    truth[39:42, 26:30] = True
    return img, truth, regions


def test_caustic_region_is_the_bright_blob_at_the_seed():
    img, truth, regions = _floor_with_caustic()
    mask = regions.caustic_region("caustic", img)
    assert mask.dtype == bool and (mask == truth).all()
    assert regions.caustic_region("cornell_box", img) is None
    # the same rule at 128x128: the seed scales with the image
    big = img.repeat(2, 0).repeat(2, 1)
    assert (regions.caustic_region("caustic", big) == truth.repeat(2, 0).repeat(2, 1)).all()
    # a floor without a blob gives no region
    flat = np.full((64, 64, 3), 0.5)
    assert not regions.caustic_region("caustic", flat).any()


def test_caustic_region_ignores_a_dim_halo_and_uses_the_lit_floor_level():
    img, truth, regions = _floor_with_caustic()
    img[38, 25:31] = 0.9  # brighter than the shadow but under 2x the lit floor's 0.5
    assert (regions.caustic_region("caustic", img) == truth).all()
    img[38, 25:31] = 1.2  # above 2x the lit floor, touching the caustic: joins it
    grown = truth.copy()
    grown[38, 25:31] = True
    assert (regions.caustic_region("caustic", img) == grown).all()


def test_region_metrics_relmse_and_mean_ratio():
    img, truth, regions = _floor_with_caustic()
    render = img.copy()
    render[truth] *= 0.9  # 10 % dark in the caustic, exact elsewhere
    render[0, 0] = np.nan  # outside the region: does not count
    m = regions.region_metrics(render, img, truth)
    assert m["pixels"] == truth.sum()
    assert m["mean_ratio"] == pytest.approx(0.9, rel=1e-12)
    assert m["relmse"] == pytest.approx(0.36 / (36 + metrics.EPS), rel=1e-12)
    var = np.full(img.shape, 0.36)
    m = regions.region_metrics(render, img, truth, var)
    assert m["relmse_ref"] == pytest.approx(0.36 / (36 + metrics.EPS), rel=1e-12)
    assert m["relmse_corrected"] == pytest.approx(0.0, abs=1e-15)
    # non-finite pixels inside the region count as 0
    render[39, 26] = np.inf
    assert regions.region_metrics(render, img, truth)["mean_ratio"] < 0.9


def test_variant_labels_parse_settings():
    from bench import run
    assert run.parse_variant("photon_no_rp=photon:radiance_photons=0") == ("photon_no_rp", "photon", {"radiance_photons": 0})
    assert run.parse_variant("x=ppm:photons=50000,ppm_alpha=0.5") == ("x", "ppm", {"photons": 50000, "ppm_alpha": 0.5})
    assert run.parse_variant("y=path") == ("y", "path", {})
    with pytest.raises(run.BenchError):
        run.parse_variant("no-label")
