"""Sampling controls in the core: the animated seed and adaptive sampling."""
import numpy as np
import pytest

from core_scenes import furnace_box, sphere_with_point_light
from ember.engine import adaptive
from ember.engine.errors import EmberError
from ember.engine.rng import animated_seed
from ember.engine.session import RenderSession


def _render(scene, **kw):
    session = RenderSession(scene.replace(settings=scene.settings.replace(threads=1, **kw)))
    stats = session.run()
    return session, stats


# --- animated seed ----------------------------------------------------------------------------
def test_animated_seed_is_a_hash_of_seed_and_frame():
    seeds = {animated_seed(7, f) for f in range(1, 200)}
    assert len(seeds) == 199 and all(0 <= s < 2 ** 31 for s in seeds)
    assert animated_seed(7, 5) == animated_seed(7, 5) != animated_seed(8, 5)
    assert animated_seed(7, 5, 0.5) != animated_seed(7, 5)


def test_animated_seed_changes_the_noise_between_frames_and_nothing_else():
    """A static scene rendered at frames 1 and 2 with the animated seed: the two images differ
    (another noise pattern) but only by noise - the pooled z-test of their difference against 0,
    with each image's own variance of the mean, passes; per pixel the differences are as large
    as the noise says (chi-square per pixel near 1)."""
    scene = sphere_with_point_light(radius=0.3, samples=16, width=24, height=24)
    one, _ = _render(scene, seed=animated_seed(3, 1))
    two, _ = _render(scene, seed=animated_seed(3, 2))
    m1, m2 = one.film.mean(), two.film.mean()
    var = one.film.variance_of_mean() + two.film.variance_of_mean()
    d = m1 - m2
    assert np.count_nonzero(d) > 0.9 * d.size  # another noise pattern in nearly every pixel
    z = d.sum() / np.sqrt(var.sum())
    assert abs(z) < 4.0, z
    chi2_per_pixel = float(np.mean(d * d / var))
    assert 0.3 < chi2_per_pixel < 1.5, chi2_per_pixel  # Sobol: the sample variance overstates a little


def test_same_seed_same_image():
    scene = sphere_with_point_light(radius=0.3, samples=4, width=12, height=12)
    one, _ = _render(scene, seed=animated_seed(3, 1))
    two, _ = _render(scene, seed=animated_seed(3, 1))
    assert np.array_equal(one.film.mean(), two.film.mean())
