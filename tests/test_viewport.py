"""The viewport's core without Blender or a GPU (engine/viewport.py): the buffer handed to
drawing, and a session that renders progressively, restarts on change and stops cleanly."""
import time

import numpy as np
import pytest

from ember.engine import viewport
from ember.engine.integrators import NAMES
from ember.engine.parallel import workers
from ember.engine.session import RenderSession

from core_scenes import furnace_box, perspective, sphere_with_point_light

needs_workers = pytest.mark.skipif(not workers.can_spawn(), reason="no worker processes can be started here")


def test_draw_buffer_is_bottom_up_float32_and_below_half_overflow():
    image = np.zeros((2, 3, 4), np.float32)
    image[0, :, 0] = 1.0  # top row red
    image[1, 2] = [1e6, np.nan, np.inf, -np.inf]
    buf = viewport.draw_buffer(image)
    assert buf.dtype == np.float32 and buf.shape == (2 * 3 * 4,)
    rows = buf.reshape(2, 3, 4)
    assert np.all(rows[1, :, 0] == 1.0)  # the top row comes last (GPU textures start at the bottom)
    assert rows[0, 2, 1] == 0.0  # NaN -> 0
    assert 6e4 < rows[0, 2, 0] < viewport.HALF_MAX and rows[0, 2, 2] < viewport.HALF_MAX
    assert np.isfinite(rows.astype(np.float16)).all()  # survives the half-float texture


def test_upscale_and_coarse_scene():
    coarse = viewport.coarse_scene(furnace_box(width=10, height=7, samples=8), 4)
    assert (coarse.settings.width, coarse.settings.height, coarse.settings.samples) == (3, 2, 1)
    img = np.arange(6, dtype=np.float32).reshape(2, 3, 1)
    up = viewport.upscale(img, 4, 7, 10)
    assert up.shape == (7, 10, 1) and up[6, 9, 0] == 5 and up[0, 3, 0] == 0 and up[0, 4, 0] == 1


def _wait(view, samples, timeout=60.0):
    t0 = time.time()
    while time.time() - t0 < timeout:
        latest = view.latest()
        if latest is not None and latest[4] >= samples and not view.busy():
            return latest
        assert view.error is None, view.error
        time.sleep(0.02)
    raise AssertionError("the viewport did not finish")


def test_session_renders_restarts_on_change_and_stops_cleanly():
    """The final buffer of each update is exactly the image a RenderSession of that scene makes
    (same seed): the coarse first image and restarts leave no trace; the Embree scene is kept
    for a light change and rebuilt for a geometry change (persistent data)."""
    first = sphere_with_point_light(width=24, height=16, samples=4)
    reference = RenderSession(first)  # before the viewport: a render without persistent data drops kept data
    reference.run()
    view = viewport.ViewportSession(pixel_size=4)
    try:
        view.update(first)
        version, buf, w, h, n = _wait(view, 4)
        assert (w, h) == (24, 16)
        assert view.stats[-1]["first_image"] is not None
        np.testing.assert_array_equal(buf, viewport.draw_buffer(reference.film.image()))
        # A light change: restart, same Embree scene, the new scene's image.
        brighter = first.replace(lights=first.lights.__class__(**{**first.lights.__dict__,
                                                                   "Le": first.lights.Le * 2}))
        view.update(brighter)
        version2, buf2, *_ = _wait(view, 4)
        assert version2 > version and view.stats[-1]["builds"]["embree"] == 0
        assert view.stats[-1]["builds"]["lights"] == 1  # built for the coarse image, kept for the full one
        np.testing.assert_allclose(buf2.reshape(-1, 4)[:, :3], 2 * buf.reshape(-1, 4)[:, :3], rtol=1e-6)
        # Restart in the middle of a long render: it stops at once and starts over.
        slow = first.replace(settings=first.settings.replace(samples=100000))
        view.update(slow)
        time.sleep(0.3)
        t0 = time.perf_counter()
        bigger = sphere_with_point_light(width=24, height=16, samples=4)
        bigger = bigger.replace(mesh=bigger.mesh.__class__(bigger.mesh.vertices * 1.01, bigger.mesh.triangles,
                                                           bigger.mesh.normals, bigger.mesh.material))
        view.update(bigger)
        _wait(view, 4)
        assert time.perf_counter() - t0 < 5.0
        assert view.stats[-1]["builds"]["embree"] == 1  # new geometry: rebuilt once, kept for the full image
    finally:
        view.close()
    assert not view._thread.is_alive()


@pytest.mark.parametrize("name", NAMES)
def test_session_works_with_every_integrator(name):
    """Each registered integrator renders in the viewport and its final buffer is
    RenderSession's image."""
    scene = sphere_with_point_light(width=12, height=8, samples=2)
    scene = scene.replace(settings=scene.settings.replace(integrator=name, photons=2000, caustic_photons=0,
                                                          gather_rays=2))
    view = viewport.ViewportSession(pixel_size=2)
    try:
        view.update(scene)
        _, buf, *_ = _wait(view, 2)
    finally:
        view.close()
    reference = RenderSession(scene)
    reference.run()
    np.testing.assert_array_equal(buf, viewport.draw_buffer(reference.film.image()), err_msg=name)


def _pids(view):
    return [w.proc.pid for w in view.pool.workers]


@needs_workers
def test_session_traces_on_workers_kept_across_updates_and_restarts():
    """Two worker processes trace every update: started once, and the same processes
    serve a light change and a restart in the middle of a long render (cancelled, not
    killed); the new scene's Embree scene is not rebuilt for a light change. The image is
    the one RenderSession makes in this process."""
    scene = sphere_with_point_light(width=24, height=16, samples=3, threads=2)
    view = viewport.ViewportSession(pixel_size=2)
    started = workers.STARTED[0]
    try:
        view.update(scene.replace(settings=scene.settings.replace(samples=100000)))
        while view.latest() is None or view.latest()[4] < 2:
            assert view.error is None, view.error
            time.sleep(0.02)
        assert view.stats[-1]["processes"] == 2
        pids = _pids(view)
        brighter = scene.replace(lights=scene.lights.__class__(**{**scene.lights.__dict__, "Le": scene.lights.Le * 2}))
        view.update(brighter)  # a restart while items are in flight
        version, buf, *_ = _wait(view, 3)
        assert view.stats[-1]["processes"] == 2 and view.stats[-1]["builds"]["embree"] == 0
        assert _pids(view) == pids and view.pool.alive()
        assert workers.STARTED[0] - started == 2
        assert [record["builds"]["workers"] for record in view.stats] == [2, 0]
    finally:
        view.close()
    assert view.pool is None and not view._thread.is_alive()
    reference = RenderSession(brighter.replace(settings=brighter.settings.replace(threads=1)))
    reference.run()
    np.testing.assert_array_equal(buf, viewport.draw_buffer(reference.film.image()))


@pytest.mark.parametrize("name", ["photon", "icache"])
def test_photon_maps_survive_a_camera_move(name):
    """The photon stages run once for a scene and are reused (not run) when only the camera
    moves - also by the full-resolution level after the coarse one; a light change runs them
    again. The moved view's image equals a fresh RenderSession's (stored results are exact).
    icache (with photon-map gathers: it builds a global map) runs its view-dependent records again (not counted here)."""
    scene = sphere_with_point_light(width=12, height=8, samples=2, threads=2)
    scene = scene.replace(settings=scene.settings.replace(integrator=name, photons=3000, caustic_photons=0,
                                                          gather_rays=2, icache_rays=50, icache_gather="photon"))
    view = viewport.ViewportSession(pixel_size=2)
    cache = view.stage_cache
    try:
        view.update(scene)
        _wait(view, 2)
        assert cache.runs["photons"] == 1 and cache.reused["photons"] == 1  # coarse ran, full reused
        moved = scene.replace(camera=perspective((0.1, 0.3, 0.05), (0, 1, 0), 50, aspect=1.5))
        view.update(moved)
        _, buf, *_ = _wait(view, 2)
        assert cache.runs["photons"] == 1 and cache.reused["photons"] == 3
        if name == "photon":
            assert cache.runs["radiance"] == 1 and cache.reused["radiance"] == 3
        view.update(scene.replace(lights=scene.lights.__class__(**{**scene.lights.__dict__,
                                                                    "Le": scene.lights.Le * 2})))
        _wait(view, 2)
        assert cache.runs["photons"] == 2
    finally:
        view.close()
    reference = RenderSession(moved)
    reference.run()
    np.testing.assert_array_equal(buf, viewport.draw_buffer(reference.film.image()))
