"""Path regeneration (engine/integrators/path.py, PathTracer.render): an item's camera paths
(ITEM_BATCHES batches) run in a pool of one batch of live paths, topped up with the item's
next camera paths as paths end. Every path draws its own numbers (a pure function of seed, pixel,
sample and dimension; with regeneration the dimension comes from the path's own bounce) and
sums its own terms in its own order, so the image is the same bit for bit with and without
regeneration, and with it across batch sizes and worker counts."""
import numpy as np
import pytest
from scipy import stats as scipy_stats

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
    """The same image bit for bit with regeneration (items of 2048 paths in pools of 512) and
    without it (items of one pool): uniform bounce counts, independent numbers,
    per-type bounce limits, transparency limits, clamping (per-path bounce counts)."""
    scene = open_box(**overrides)
    with_refill = _session(scene)
    assert sum(refills) > 0.3 * scene.settings.samples * 256  # regeneration did run
    monkeypatch.setattr(path_mod, "ITEM_BATCHES", 1)  # items of one pool
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
    monkeypatch.setattr(path_mod, "ITEM_BATCHES", 1)  # items of one pool
    assert np.array_equal(with_refill.film.mean(), _session(scene).film.mean())


def test_regenerated_image_does_not_depend_on_batches_or_workers(refills):
    """With regeneration, batch sizes 512 (pools of 512 in items of 2048), 200 and 56 (pools
    of part of a pass), 4096 (all 3072 paths in one pool: no refill) and two worker processes
    (units split among them) give the same image bit for bit."""
    scene = open_box(diffuse_bounces=3)
    first = _session(scene).film.mean()
    for kw in (dict(batch_size=200), dict(batch_size=56), dict(batch_size=4096), dict(threads=2)):
        s = _session(scene, **kw)
        if "threads" in kw:
            assert s.processes == 2
        assert np.array_equal(first, s.film.mean()), kw
    assert sum(refills) > 0.3 * 12 * 256 * 4  # the in-process renders refilled their pools


def _welch_chi2_p(a, b, n: int) -> float:
    """p-value that two independent images of n i.i.d. samples a pixel (film.Film) share their
    means: per value Welch's t (sample variances of the means; Welch-Satterthwaite degrees of
    freedom) turned into the normal z of the same tail probability, and sum z^2 against
    chi-square with one degree per value (plain sum t^2 would overstate it by ~(n-1)/(n-3))."""
    va, vb = a.variance_of_mean(), b.variance_of_mean()
    var = np.maximum(va + vb, 1e-12)  # deterministic values (the sky) agree exactly: t = 0
    t = (a.mean() - b.mean()) / np.sqrt(var)
    df = var ** 2 / np.maximum((va ** 2 + vb ** 2) / (n - 1), 1e-300)
    z = scipy_stats.norm.isf(scipy_stats.t.sf(np.abs(t), df))
    return float(scipy_stats.chi2.sf(np.sum(z ** 2), z.size))


def test_regeneration_agrees_statistically(monkeypatch, refills):
    """Independent estimates (i.i.d. numbers, two seeds, 32 samples a pixel) with and without
    regeneration agree: per pixel, two-sided z-tests with the sample variances of the means,
    Sidak-corrected over the 32x32x3 values at alpha 0.01; over the image, chi-square of the
    per-value Welch statistics at alpha 0.001 (this one sees a bias of a few percent that no
    single pixel shows)."""
    n = 32
    scene = open_box(width=32, height=32, samples=n, pattern="random", batch_size=2048)
    a = _session(scene, seed=1).film
    assert sum(refills) > 0.3 * n * 1024
    monkeypatch.setattr(path_mod, "ITEM_BATCHES", 1)  # items of one pool
    b = _session(scene, seed=2).film
    assert not np.array_equal(a.mean(), b.mean())
    passed = z_test_images(a.mean(), a.variance_of_mean(), b.mean(), b.variance_of_mean())
    assert passed >= 0.9975, passed
    p = _welch_chi2_p(a, b, n)
    assert p > 1e-3, p
