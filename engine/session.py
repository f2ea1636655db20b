"""A render: build once, then run the integrator's stages until it is done or stopped.

An integrator (engine/integrators/) is a sequence of rounds of stages. Each stage is a
number of independent work items, run by worker processes (one per core,
engine/parallel/workers.py) or, for small renders, by one thread of this process. A film
stage's items are batches of `Settings.batch_size` flat path indices (pass-major: every
pixel of the border gets one more sample per pass); their radiance goes to the film in item
order. A publish stage's results are reduced in item order by the integrator and the arrays
published read-only to every worker (shared memory) before the next stage starts. Random
numbers depend only on (seed, domain, stage, item/pixel, sample), so the same seed gives the
same image whatever the timing or the number of workers.

The caller's thread is the only one that calls `on_update` and `should_stop` (Blender's
API is not thread-safe), at least every `UPDATE_INTERVAL` seconds.
"""
from __future__ import annotations

import threading
import time
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass, field

import numpy as np

from . import integrators
from .errors import Cancelled
from .film import Film
from .integrators.base import Stage
from .parallel import workers
from .parallel.shared import Publisher
from .scene import Scene, recentred
from . import tracer as tracer_mod
from .tracer import Tracer
from .validation import has_light, path_only_warnings, validate

UPDATE_INTERVAL = 0.25
NOISE_INTERVAL = 1.0


@dataclass
class Progress:
    samples_done: int
    samples_target: int
    fraction: float
    elapsed: float
    rays: int
    rays_per_second: float
    pass_completed: bool
    noise: float | None
    film: Film
    stage: str = "pixels"  # the stage running now


@dataclass
class RenderStats:
    samples: int
    elapsed: float
    rays: int
    rays_per_second: float
    embree_seconds: float
    build_seconds: float
    cancelled: bool
    noise: float | None
    nonfinite: int
    stopped_by: str = ""  # "", "cancel", "time limit" or "noise target"
    processes: int = 0  # worker processes used (0: traced in the render process)
    stage_seconds: dict = field(default_factory=dict)  # stage name -> wall seconds (all rounds)
    counters: dict = field(default_factory=dict)  # the integrator's figures (photons stored, ...)
    settings: object = None  # the scene's Settings as rendered (integrator, seed, sample range)
    # What this render built: {"workers": processes started, "embree": Embree scenes, "lights":
    # light tables} (in one worker; all 0 on a frame that persistent data served whole).
    builds: dict = field(default_factory=dict)

    def summary(self) -> str:
        state = {"cancel": "cancelled", "": "done"}.get(self.stopped_by, f"stopped at the {self.stopped_by}")
        noise = f" | noise {self.noise:.4f}" if self.noise is not None and np.isfinite(self.noise) else ""
        stages = ""
        if len(self.stage_seconds) > 1:
            stages = " | " + ", ".join(f"{name} {sec:.2f} s" for name, sec in self.stage_seconds.items())
        counters = "".join(f" | {text}" for text in self.counters.values())
        return (f"Ember {state}: {self.samples} samples in {self.elapsed:.2f} s | "
                f"{self.rays_per_second / 1e6:.2f} M rays/s | Embree {self.embree_share:.0%} of render time{noise}"
                f"{stages}{counters} | {self.nonfinite} non-finite samples")

    @property
    def embree_share(self) -> float:
        """Share of the workers' time spent inside Embree (CPU seconds over worker-seconds)."""
        return self.embree_seconds / max(self.elapsed * max(self.processes, 1), 1e-9)


class RenderSession:
    def __init__(self, scene: Scene):
        validate(scene)
        scene = recentred(scene)  # far from the world origin: render about the scene's centre
        t0 = time.perf_counter()
        self.warnings: list[str] = []
        if scene.settings.noise_target > 0 and not integrators.REGISTRY[scene.settings.integrator].noise_target:
            self.warnings.append(f"The noise target does not apply to the '{scene.settings.integrator}' integrator "
                                 "(its passes are not independent samples of one image); it is ignored.")
            scene = scene.replace(settings=scene.settings.replace(noise_target=0.0))
        self.warnings += path_only_warnings(scene)
        self.scene = scene
        s = scene.settings
        self.integrator = integrators.create(scene)  # the render-process side: stages, reduce
        self.layout = self.integrator.layout
        self.film = Film(s.width, s.height, s.passes, s.film_transparent)
        cores = s.threads or workers.available_cores()
        # Worker processes pay ~1 s to start; worth it only for renders of several items.
        self.processes = (cores if cores > 1 and self.integrator.work_items() >= 2 * cores and workers.can_spawn()
                          else 0)
        # Embree, light tables and the integrator's tracing side live where the tracing
        # happens: here, or in each worker only (not here too: an 8k environment table is
        # hundreds of MB).
        # Persistent data (Settings.persistent): the last render's tracer or worker pool
        # is reused, rebuilding only what changed; without it nothing is kept.
        self._builds0 = (dict(tracer_mod.BUILDS), workers.STARTED[0])
        if not s.persistent:
            workers.release_kept()
            tracer_mod.forget()
        self.tracer = None if self.processes else tracer_mod.tracer_for(scene)
        if not has_light(scene):
            self.warnings.append("The scene has no lights, no emissive materials and a black world: "
                                 "the image will be black.")
        self.build_seconds = time.perf_counter() - t0

    def _add(self, stage: Stage, item: int, L: np.ndarray, passes: dict | None = None) -> None:
        """Add a film item to the film, one pass segment at a time (pixels unique per segment);
        passes: render-pass name -> (N, channels) values of the same paths."""
        n_pixels = self.layout.n_pixels
        k = self.layout.paths(stage, item)
        cut = 0
        while cut < len(k):
            seg_end = min(len(k), cut + n_pixels - k[cut] % n_pixels)
            self.film.add(self.layout.pixel[k[cut:seg_end] % n_pixels], L[cut:seg_end],
                          {name: v[cut:seg_end] for name, v in passes.items()} if passes else None)
            if (k[seg_end - 1] + 1) % n_pixels == 0:  # the segment completed a pass
                self.film.end_pass(int(k[seg_end - 1] + 1) // n_pixels - self.scene.settings.sample_offset)
            cut = seg_end

    def run(self, on_update=None, should_stop=None) -> RenderStats:
        t0 = time.perf_counter()
        run = _Run(self, on_update, should_stop, t0)
        if self.processes:
            backend = _Processes(self.scene, self.processes)
            builds = backend.builds
        else:
            builds = {k: v - self._builds0[0][k] for k, v in tracer_mod.BUILDS.items()}
            backend = _InProcess(self.tracer, run.stop)
        publisher = Publisher()
        self.build_seconds += time.perf_counter() - t0
        completed = False
        try:
            version, round_ = 0, 0
            while not run.ended:
                stages = self.integrator.stages(round_)
                if not stages:
                    break
                for stage in stages:
                    t_stage = time.perf_counter()
                    results = run.stage(stage, backend)
                    run.stage_seconds[stage.name] = run.stage_seconds.get(stage.name, 0.0) + time.perf_counter() - t_stage
                    if results is None:  # stopped: cancel, time limit or noise target
                        break
                    if stage.publish:
                        arrays = self.integrator.reduce(stage, results)
                        version += 1
                        backend.install(version, arrays, publisher)
                    self.film.overlay = self.integrator.overlay()
                    if stage.film and stage.publish:
                        run.report(stage, pass_completed=True)
                round_ += 1
            completed = True
        finally:
            backend.close(kill=run.cancelled or run.ended, keep=self.scene.settings.persistent and completed)
            publisher.release()
        elapsed = time.perf_counter() - t0
        stopped_by = ""
        if run.cancelled:
            stopped_by = "cancel"
        elif run.ended:
            stopped_by = "noise target" if run.noise_reached() else "time limit"
        noise = self.film.noise() if run.samples_done() else run.noise
        return RenderStats(samples=run.samples_done(), elapsed=elapsed, rays=run.rays,
                           rays_per_second=run.rays / max(elapsed, 1e-9), embree_seconds=run.embree_seconds,
                           build_seconds=self.build_seconds, cancelled=run.cancelled, noise=noise,
                           nonfinite=self.film.nonfinite, stopped_by=stopped_by, processes=self.processes,
                           stage_seconds=run.stage_seconds, counters=self.integrator.counters(),
                           settings=self.scene.settings,
                           builds=dict(builds, workers=workers.STARTED[0] - self._builds0[1]))


class _Run:
    """The bookkeeping of one RenderSession.run: stops, progress, the film's order."""

    def __init__(self, session: RenderSession, on_update, should_stop, t0: float):
        self.session, self.on_update, self.should_stop, self.t0 = session, on_update, should_stop, t0
        self.settings = session.scene.settings
        self.stop = threading.Event()
        self.cancelled = False
        self.ended = False  # stopped before the integrator was done (cancel, time, noise)
        self.paths_added = self.rays = 0
        self.embree_seconds = 0.0
        self.noise, self.noise_time = None, t0
        self.last_update = t0
        self.stage_seconds: dict[str, float] = {}

    def samples_done(self) -> int:
        return self.paths_added // self.session.layout.n_pixels

    def noise_reached(self) -> bool:
        s = self.settings
        return s.noise_target > 0 and self.noise is not None and self.noise <= s.noise_target

    def report(self, stage: Stage, pass_completed: bool) -> None:
        if self.on_update is not None:
            elapsed = time.perf_counter() - self.t0
            fraction = self.paths_added / max(self.session.integrator.film_paths(), 1)
            self.on_update(Progress(self.samples_done(), self.settings.samples, fraction, elapsed, self.rays,
                                    self.rays / max(elapsed, 1e-9), pass_completed, self.noise, self.session.film,
                                    stage.name))
        self.last_update = time.perf_counter()

    def stage(self, stage: Stage, backend) -> list | None:
        """Run every item of `stage`; the items' results in order (film stages: []), or None
        if the render stopped before the stage was complete."""
        s, film = self.settings, self.session.film
        pending = {}  # future -> item
        finished = {}  # item -> result, waiting for its turn (order is fixed)
        results = []
        next_done = submitted = 0
        while next_done < stage.items:
            if self.should_stop is not None and not self.cancelled and self.should_stop():
                self.cancelled = self.ended = True
                self.stop.set()
                if backend.processes:
                    break  # workers are killed by the caller; nothing more is used
            out_of_time = s.time_limit > 0 and time.perf_counter() - self.t0 >= s.time_limit
            # The noise estimate needs a few passes to mean anything.
            out_of_time |= self.samples_done() >= 4 and self.noise_reached()
            if not self.stop.is_set() and not out_of_time:
                while len(pending) < backend.in_flight and submitted < stage.items:
                    pending[backend.submit(stage, submitted)] = submitted
                    submitted += 1
            if not pending:
                break
            done, _ = wait(pending, timeout=UPDATE_INTERVAL, return_when=FIRST_COMPLETED)
            for fut in done:
                item = pending.pop(fut)
                try:
                    finished[item] = fut.result()
                except Cancelled:
                    finished[item] = None
            before = self.samples_done()
            while next_done in finished:
                result = finished.pop(next_done)
                if result is None:  # cancelled mid-item: nothing after it is used either
                    self.ended = True
                    next_done = stage.items + 1
                    break
                data, item_rays, item_embree = result
                if stage.film:
                    passes = data.pop("passes", None) if isinstance(data, dict) else None
                    L = data.pop("L") if isinstance(data, dict) else data  # dict: L + arrays to reduce
                    self.session._add(stage, next_done, L, passes)
                    self.paths_added += len(L)
                if stage.publish:
                    results.append(data)
                self.rays += item_rays
                self.embree_seconds += item_embree
                next_done += 1
            # A film stage that also publishes (ppm) completes its pass only once reduced:
            # RenderSession.run reports it then, with the film's overlay up to date.
            pass_completed = self.samples_done() > before and not stage.publish
            # The estimate costs a pass over the film: every pass when it can stop the
            # render, else at most once per NOISE_INTERVAL (it is only shown).
            if pass_completed and (s.noise_target > 0 or time.perf_counter() - self.noise_time >= NOISE_INTERVAL):
                self.noise, self.noise_time = film.noise(), time.perf_counter()
            if pass_completed or time.perf_counter() - self.last_update >= UPDATE_INTERVAL:
                self.report(stage, pass_completed)
        if next_done != stage.items:
            self.ended = True
            return None
        return results


class _InProcess:
    """Items run one at a time on a thread of this process (small renders, Blender's binary)."""

    processes = 0
    in_flight = 2

    def __init__(self, tracer: Tracer, stop: threading.Event):
        self.tracer, self.stop = tracer, stop
        self.pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="ember")

    def submit(self, stage: Stage, item: int):
        return self.pool.submit(self.tracer.run, stage, item, self.stop)

    def install(self, version: int, arrays: dict, publisher) -> None:
        for a in arrays.values():
            a.flags.writeable = False  # the same contract as shared memory
        self.tracer.integrator.install(version, arrays)

    def close(self, kill: bool, keep: bool = False) -> None:
        self.stop.set()
        self.pool.shutdown(wait=True)


class _Processes:
    """Items run in worker processes; published arrays go through shared memory."""

    def __init__(self, scene: Scene, n: int):
        if scene.settings.persistent:
            tracer_mod.forget()  # the workers trace: no tracer kept here
            self.pool = workers.pool_for(n)
        else:
            self.pool = workers.WorkerPool(n)
        try:
            self.builds = self.pool.load(scene)
        except BaseException:
            self.pool.close(kill=True)
            raise
        self.processes = n
        self.in_flight = 2 * n

    def submit(self, stage: Stage, item: int):
        return self.pool.submit(stage, item)

    def install(self, version: int, arrays: dict, publisher: Publisher) -> None:
        self.pool.install(version, publisher.publish(arrays))

    def close(self, kill: bool, keep: bool = False) -> None:
        if keep and not kill and self.pool.alive():
            workers.keep(self.pool)
        else:
            self.pool.close(kill=kill)
