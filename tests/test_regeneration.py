"""Path regeneration (engine/integrators/path.py, PathTracer.render): an item's camera paths
run in a pool of REFILL_POOL x the batch size live paths, topped up with the item's next
camera paths as paths end. Every path draws its own numbers (a pure function of seed, pixel,
sample and dimension; with regeneration the dimension comes from the path's own bounce) and
sums its own terms in its own order, so the image is the same bit for bit with and without
regeneration, and with it across batch sizes and worker counts."""
import numpy as np
import pytest

from ember.engine.integrators import path as path_mod
from ember.engine.session import RenderSession

from core_scenes import perspective
from stats import z_test_images
from test_batch_independence import open_box


@pytest.fixture
def refills(monkeypatch):
    """Counts the paths handed out to top up a pool (in this process)."""
    count = []
    take = path_mod._Refill.take

    def counted(self, k):
        if self.next:
            count.append(k)
        return take(self, k)

    monkeypatch.setattr(path_mod._Refill, "take", counted)
    return count


def _session(scene, **kw):
    session = RenderSession(scene.replace(settings=scene.settings.replace(**kw)) if kw else scene)
    session.stats = session.run()
    return session


@pytest.mark.parametrize("overrides", [dict(), dict(pattern="random"), dict(diffuse_bounces=2, max_depth=6),
                                       dict(rr_depth=0, transparent_bounces=2), dict(clamp_indirect=0.5)])
def test_regeneration_changes_no_pixel(monkeypatch, refills, overrides):
    """The same image bit for bit with regeneration (items of 512 paths in pools of 256) and
    without it (a pool larger than any item): uniform bounce counts, independent numbers,
    per-type bounce limits, transparency limits, clamping (per-path bounce counts)."""
    scene = open_box(**overrides)
    with_refill = _session(scene)
    assert sum(refills) > 0.3 * scene.settings.samples * 256  # regeneration did run
    monkeypatch.setattr(path_mod, "REFILL_POOL", 1e9)
    without = _session(scene)
    assert with_refill.film.mean().min() > 0
    assert np.array_equal(with_refill.film.mean(), without.film.mean())
    assert with_refill.stats.rays == without.stats.rays


def test_regeneration_with_pools_that_all_escape(monkeypatch, refills):
    """A camera that looks away from the box: every path of a pool escapes at its first ray
    while the item still has paths to hand out; the image is the sky's, as without refills."""
    scene = open_box()
    scene = scene.replace(camera=perspective((0, -3.5, 0), (0, -9, 0), 45))
    with_refill = _session(scene)
    assert sum(refills) > 0
    monkeypatch.setattr(path_mod, "REFILL_POOL", 1e9)
    assert np.array_equal(with_refill.film.mean(), _session(scene).film.mean())


def test_regenerated_image_does_not_depend_on_batches_or_workers(refills):
    """With regeneration, batch sizes 512 (pools of 256), 200 and 56 (items of part of a
    pass), 4096 (one item of 3072 paths in a pool of 2048) and two worker processes give the
    same image bit for bit."""
    scene = open_box(diffuse_bounces=3)
    first = _session(scene).film.mean()
    for kw in (dict(batch_size=200), dict(batch_size=56), dict(batch_size=4096), dict(threads=2)):
        s = _session(scene, **kw)
        if "threads" in kw:
            assert s.processes == 2
        assert np.array_equal(first, s.film.mean()), kw
    assert sum(refills) > 0.3 * 12 * 256 * 4  # the in-process renders refilled their pools


def test_regeneration_agrees_statistically(monkeypatch, refills):
    """Independent estimates (i.i.d. numbers, two seeds) with and without regeneration agree
    per pixel: two-sided z-tests on the pixel means with their sample variances (honest for
    i.i.d. samples), Sidak-corrected over the 32x32x3 values at alpha 0.01."""
    scene = open_box(width=32, height=32, samples=32, pattern="random", batch_size=2048)
    a = _session(scene, seed=1)
    assert sum(refills) > 0.3 * 32 * 1024
    monkeypatch.setattr(path_mod, "REFILL_POOL", 1e9)
    b = _session(scene, seed=2)
    assert not np.array_equal(a.film.mean(), b.film.mean())
    passed = z_test_images(a.film.mean(), a.film.variance_of_mean(), b.film.mean(), b.film.variance_of_mean())
    assert passed >= 0.9975, passed
