"""The time limit, against a fake clock: no real timing, only counts of passes.

The render runs its real items in this process, but on simulated workers: each item "takes"
a + b x paths fake seconds on one of W workers, and its result is handed back when the fake
clock reaches its end. The session reads only that clock, so the number of passes it
completes within a limit is exact and reproducible.
"""
from concurrent.futures import Future

import numpy as np
import pytest

from core_scenes import furnace_box, sphere_with_point_light
from ember.engine.session import RenderSession


class FakeClock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


class SimulatedWorkers:
    """A backend whose items take `seconds(stage, paths, start)` of fake time on `workers`
    workers (each item on the one free first); start-up costs `startup` fake seconds."""

    in_flight_per_worker = 2

    def __init__(self, tracer, clock, workers, startup, seconds):
        self.tracer, self.clock, self.seconds = tracer, clock, seconds
        self.processes = workers
        self.in_flight = self.in_flight_per_worker * workers
        clock.t += startup
        self.free = [clock.t] * workers
        self.submitted = 0

    def submit(self, stage, item):
        data, rays, embree, _ = self.tracer.run(stage, item)
        paths = len(data["L"] if isinstance(data, dict) else data) if stage.film else 0
        w = self.free.index(min(self.free))
        start = max(self.clock.t, self.free[w])
        seconds = self.seconds(stage, paths, start)
        self.free[w] = start + seconds
        fut = Future()
        fut.end, fut.value = self.free[w], (data, rays, embree, seconds)
        self.submitted += 1
        return fut

    def wait(self, pending, timeout):
        t_next = min(f.end for f in pending)
        if t_next > self.clock.t + timeout:
            self.clock.t += timeout
            return set()
        self.clock.t = max(self.clock.t, t_next)
        done = {f for f in pending if f.end <= self.clock.t}
        for f in done:
            f.set_result(f.value)
        return done

    def install(self, version, arrays, publisher):
        for a in arrays.values():
            a.flags.writeable = False
        self.tracer.install(version, arrays)

    def close(self, kill, keep=False):
        pass


class SimulatedSession(RenderSession):
    def __init__(self, scene, workers=2, startup=0.5, seconds=None):
        self.fake = FakeClock()
        super().__init__(scene.replace(settings=scene.settings.replace(threads=1)), clock=self.fake)
        self.sim = (workers, startup, seconds)

    def _backend(self, stop):
        workers, startup, seconds = self.sim
        self.backend = SimulatedWorkers(self.tracer, self.fake, workers, startup, seconds)
        return self.backend


N = 8 * 8  # pixels
B = 1e-3  # fake seconds per path: a pass takes N * B = 0.064 s on one worker


def linear(a=0.0, b=B):
    return lambda stage, paths, start: a + b * paths


@pytest.mark.parametrize("limit, startup", [(2.0, 0.5), (1.3, 1.0), (5.0, 0.2)])
def test_time_limit_ends_within_one_pass_of_the_limit(limit, startup):
    """W workers of N B seconds per pass complete at most W (L - S) / (N B) passes by the
    limit L after a start-up S; the render ends by the limit, idling at most one pass per
    worker (units start as single passes and double; 64 passes per batch)."""
    scene = furnace_box(samples=100000, width=8, height=8, batch_size=4096, time_limit=limit)
    session = SimulatedSession(scene, startup=startup, seconds=linear())
    stats = session.run()
    ideal = int(2 * (limit - startup) / (N * B))
    assert stats.stopped_by == "time limit"
    assert stats.elapsed <= limit
    assert ideal - 2 <= stats.samples <= ideal, (stats.samples, ideal)
    assert session.film.passes == stats.samples and np.all(session.film.count == stats.samples)


def test_per_item_overhead_is_predicted():
    """Items with a fixed overhead (0.05 s, nearly a pass): the line a + b paths through the
    measured times keeps units from ending past the limit, and big units keep the overhead
    small (a pass costs N B + 0.05 / passes per unit)."""
    limit, startup = 3.0, 0.5
    scene = furnace_box(samples=100000, width=8, height=8, batch_size=4096, time_limit=limit)
    session = SimulatedSession(scene, startup=startup, seconds=linear(a=0.05))
    stats = session.run()
    ideal = int(2 * (limit - startup) / (N * B))  # without any overhead
    assert stats.elapsed <= limit
    assert 0.85 * ideal <= stats.samples <= ideal, (stats.samples, ideal)


def test_work_in_flight_is_cancelled_at_the_limit():
    """Items that start after 1.25 s run 8x slower: units predicted to fit run past the limit
    and are cancelled at it; the film keeps the passes complete by then, every pixel the same
    count (without the cancel the render would end at 3 s)."""
    limit, startup = 2.0, 0.5

    def seconds(stage, paths, start):
        return B * paths * (8.0 if start > 1.25 else 1.0)

    scene = furnace_box(samples=100000, width=8, height=8, batch_size=4096, time_limit=limit)
    session = SimulatedSession(scene, startup=startup, seconds=seconds)
    stats = session.run()
    assert stats.elapsed == limit and stats.stopped_by == "time limit"
    assert max(session.backend.free) > limit  # work was in flight
    assert np.all(session.film.count == stats.samples)
    # At least what was complete at 1.25 s, at most what the full speed gives.
    assert int(2 * 0.75 / (N * B)) - 2 <= stats.samples <= int(2 * (limit - startup) / (N * B))


@pytest.mark.parametrize("batch_size, offset", [(4096, 0), (24, 0), (4096, 7)])
def test_time_limited_image_equals_the_same_number_of_passes(batch_size, offset):
    """The image depends only on the pass count: a render stopped by the limit equals, bit for
    bit, a render of that many samples (the incomplete pass and the items in flight are
    dropped; batch 24: a pass is three items; offset 7: samples from the 8th on, a part of a
    split render)."""
    scene = sphere_with_point_light(radius=0.3, samples=100000, width=8, height=8, batch_size=batch_size,
                                    time_limit=1.5, sample_offset=offset)
    # Items slow down near the end, so the limit cancels work in flight (a pass half done).
    limited = SimulatedSession(scene, startup=0.3, seconds=lambda stage, paths, start: B * paths * (
        8.0 if start > 1.2 else 1.0))
    stats = limited.run()
    assert stats.elapsed <= 1.5
    assert 4 < stats.samples < 100000
    exact = RenderSession(scene.replace(settings=scene.settings.replace(time_limit=0.0, samples=stats.samples,
                                                                         threads=1)))
    exact.run()
    assert np.array_equal(limited.film.mean(), exact.film.mean())


def test_ppm_starts_a_round_only_if_it_ends_before_the_limit():
    """ppm: a round is a photon stage (one item, 0.3 s) and a pixel pass (N B): R = 0.364 s;
    after a start-up S it completes exactly floor((L - S) / R) rounds by the limit."""
    limit, startup = 3.0, 0.4

    def seconds(stage, paths, start):
        return 0.3 if stage.name == "photons" else B * paths

    scene = furnace_box(samples=1000, width=8, height=8, batch_size=4096, time_limit=limit,
                        integrator="ppm", photons=2000)
    session = SimulatedSession(scene, startup=startup, seconds=seconds)
    stats = session.run()
    assert stats.stopped_by == "time limit"
    assert stats.samples == int((limit - startup) / (0.3 + N * B)) == 7
    assert stats.elapsed == pytest.approx(startup + 7 * (0.3 + N * B))  # no eighth round started


@pytest.mark.parametrize("integrator", ["photon", "ppm"])
def test_stages_before_the_first_pass_and_the_first_pass_always_run(integrator):
    """Photon tracing that alone takes longer than the limit: the maps are built and one pass
    is rendered (an image needs both), then the render stops."""
    def seconds(stage, paths, start):
        return 5.0 if not stage.film else B * paths

    scene = furnace_box(samples=1000, width=8, height=8, batch_size=4096, time_limit=1.0,
                        integrator=integrator, photons=2000, caustic_photons=0, gather_rays=2)
    session = SimulatedSession(scene, startup=0.2, seconds=seconds)
    stats = session.run()
    before = 0.2 + 5.0 * (2 if integrator == "photon" else 1)  # photons (+ radiance photons)
    assert stats.stopped_by == "time limit" and stats.samples >= 1
    assert stats.elapsed <= before + N * B + 1e-9  # then one pass (on each worker)
    assert np.all(session.film.count == stats.samples)


def test_small_renders_are_shared_among_the_workers():
    """The path tracer's items hold several batches, more than a small render: its passes are
    still shared out, 64 passes of 8x8 pixels as two units of 32 (not one of 64), and a single
    pass of 64x64 pixels in two halves."""
    for samples, size, unit_paths in ((64, 8, 32 * 64), (1, 64, 2048)):
        scene = furnace_box(samples=samples, width=size, height=size, batch_size=4096)
        session = SimulatedSession(scene, startup=0.5, seconds=linear())
        stats = session.run()
        assert session.backend.submitted == 2
        assert stats.elapsed == pytest.approx(0.5 + unit_paths * B)
        assert np.all(session.film.count == samples)
