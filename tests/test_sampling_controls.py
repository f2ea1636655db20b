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


# --- adaptive sampling ------------------------------------------------------------------------
def test_half_buffers_split_every_aligned_block_of_four_evenly():
    a = np.array([adaptive.class_a(i) for i in range(1024)])
    assert np.all(a.reshape(-1, 4).sum(axis=1) == 2)
    # and every aligned block of 2^k >= 4 samples: half and half
    assert all(np.all(a.reshape(-1, 2 ** k).sum(axis=1) == 2 ** (k - 1)) for k in range(2, 11))


def test_pixel_error_is_cycles_formula():
    """n = 4 samples of (1, 2, 3) and class A (twice its sum) of (2, 2, 6): error
    sum|I - A| / n / (1e-4 + sqrt(sum I / n)) = (2 + 0 + 6) / 4 / (1e-4 + sqrt(24 / 4))."""
    I, A = np.array([[4.0, 8.0, 12.0]]), np.array([[2.0, 8.0, 18.0]])
    e = adaptive.pixel_error(I, A, np.array([4]))
    assert e[0] == pytest.approx((2 + 0 + 6) / 4 / (1e-4 + np.sqrt(24 / 4)))


def test_dilation_is_three_by_three():
    m = np.zeros((5, 6), bool)
    m[2, 3] = True
    d = adaptive.dilate(m)
    assert d.sum() == 9 and d[1:4, 2:5].all()


def test_min_samples_and_threshold_defaults_follow_cycles():
    s = sphere_with_point_light().settings
    assert adaptive.min_samples(s.replace(adaptive_threshold=0.1)) == 32
    assert adaptive.min_samples(s.replace(adaptive_threshold=0.01)) == 64
    assert adaptive.min_samples(s.replace(adaptive_threshold=0.001)) == 128
    assert adaptive.min_samples(s.replace(adaptive_min_samples=2)) == 4
    assert adaptive.threshold(s.replace(adaptive_threshold=0.0, samples=4096)) == 0.001
    assert adaptive.threshold(s.replace(adaptive_threshold=0.0, samples=64)) == 1 / 64


def half_emitter_scene(**kw):
    """Left half of the view: a black emitter of radiance 1 (no noise at all); right half: a
    diffuse wall lit by a small sphere light (noisy). 24 x 24 pixels, box filter."""
    from core_scenes import perspective, quads_mesh, settings
    from ember.engine.scene import MAT_DIFFUSE, MAT_EMISSION_ONLY, Lights, Materials, Scene, World

    quads = [[(-3, 0, -3), (0, 0, -3), (0, 0, 3), (-3, 0, 3)], [(0, 0, -3), (3, 0, -3), (3, 0, 3), (0, 0, 3)]]
    mats = Materials.make([dict(kind=MAT_EMISSION_ONLY, base_color=(0, 0, 0), emission=(1, 1, 1)),
                           dict(kind=MAT_DIFFUSE, base_color=(0.5, 0.5, 0.5))])
    lights = Lights.make([dict(kind=0, position=(1.5, -0.6, 0.5), radius=0.3, Le=(20.0,) * 3)])
    base = dict(width=24, height=24, samples=64, adaptive=True, adaptive_threshold=1e-4, adaptive_min_samples=16)
    base.update(kw)
    return Scene(quads_mesh(quads, [0, 1]), mats, lights, World(), perspective((0, -3, 0), (0, 0, 0), 50),
                 settings(**base))


def test_noise_free_pixels_stop_at_the_first_check_and_noisy_ones_go_on():
    """Emitter pixels (columns 0-11) have error 0: they stop after the minimum samples (16),
    except column 11, next to the wall: the 3x3 dilation keeps it active; the wall's pixels
    (threshold 1e-4) get all 64."""
    session, stats = _render(half_emitter_scene())
    count = session.film.count.reshape(24, 24)
    L = session.film.mean()
    assert stats.samples == 64
    assert np.all(L[:, :12] == 1.0) and not np.any(L[:, 12:] == 1.0)  # the emitter exactly, then the wall
    assert np.all(count[:, :11] == 16), count[0]
    assert np.all(count[:, 11] == 64), count[0]  # the dilated edge
    assert np.all(count[:, 12:] == 64), count[0]


def test_nothing_converged_is_the_uniform_image():
    """A threshold no pixel meets: adaptive sampling runs every pass over every pixel and gives
    the uniform render's image bit for bit (passes, units and half buffers change nothing)."""
    scene = sphere_with_point_light(radius=0.3, samples=40, width=12, height=12, adaptive_min_samples=8)
    uniform, _ = _render(scene)
    adapted, stats = _render(scene, adaptive=True, adaptive_threshold=1e-6)
    assert stats.counters["adaptive"].startswith("adaptive: 144 of 144 pixels active")
    assert np.array_equal(uniform.film.mean(), adapted.film.mean())


def test_adaptive_image_does_not_depend_on_batches_or_workers():
    scene = half_emitter_scene(adaptive_threshold=0.02, samples=300)
    one, _ = _render(scene)
    small, _ = _render(scene, batch_size=100)  # a pass of several items
    two = RenderSession(scene.replace(settings=scene.settings.replace(threads=2, batch_size=256)))
    assert two.processes == 2
    two.run()
    assert np.array_equal(one.film.count, small.film.count) and np.array_equal(one.film.count, two.film.count)
    assert np.array_equal(one.film.mean(), small.film.mean()) and np.array_equal(one.film.mean(), two.film.mean())
    assert len(np.unique(one.film.count)) >= 3  # pixels stopped at different checks


def test_adaptive_with_a_time_limit_equals_the_same_number_of_passes():
    """The adaptive checks wait for every earlier pass; with the fake clock of
    tests/test_time_limit.py (1e-4 s per path) the limit falls after several checks."""
    from test_time_limit import SimulatedSession

    scene = half_emitter_scene(adaptive_threshold=0.02, samples=100000, time_limit=4.0, batch_size=2048)
    limited = SimulatedSession(scene, startup=0.3, seconds=lambda stage, paths, start: 1e-4 * paths)
    stats = limited.run()
    assert stats.stopped_by == "time limit" and stats.elapsed <= 4.0 and stats.samples > 48
    exact, _ = _render(scene, time_limit=0.0, samples=stats.samples)
    assert np.array_equal(limited.film.count, exact.film.count)
    assert np.array_equal(limited.film.mean(), exact.film.mean())


def test_adaptive_applies_to_path_and_photon_only():
    scene = furnace_box(samples=4, integrator="ppm", photons=1000, adaptive=True)
    session = RenderSession(scene.replace(settings=scene.settings.replace(threads=1)))
    assert any("Adaptive sampling does not apply" in w for w in session.warnings)
    assert not session.scene.settings.adaptive


@pytest.mark.parametrize("kw, words", [(dict(adaptive_threshold=2.0), "adaptive threshold"),
                                       (dict(adaptive_min_samples=-3), "min samples")])
def test_bad_adaptive_settings_are_refused(kw, words):
    with pytest.raises(EmberError, match=words):
        RenderSession(furnace_box(**kw))
