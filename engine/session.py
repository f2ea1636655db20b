"""A render: build once, then run the integrator's stages until it is done or stopped.

An integrator (engine/integrators/) is a sequence of rounds of stages. Each stage is a
number of independent work items, run by worker processes (one per core,
engine/parallel/workers.py) or, for small renders, by one thread of this process. A film
stage's items are batches of `Settings.batch_size` flat path indices (the path tracer's: 4
batches, traced one batch wide with path regeneration; pass-major: every pixel of the border
gets one more sample per pass); their radiance goes to the film in item order. A publish
stage's results are reduced in item order by the integrator and the arrays published
read-only to every worker (shared memory) before the next stage starts. Random
numbers depend only on (seed, domain, stage, item/pixel, sample), so the same seed gives the
same image whatever the timing or the number of workers.

The caller's thread is the only one that calls `on_update` and `should_stop` (Blender's
API is not thread-safe), at least every runner.UPDATE_INTERVAL seconds. Which items start, the
film's passes and the stops (time limit, noise target, adaptive sampling) are
engine/runner.py's; this module builds the render, runs the rounds and owns the backends.
"""
from __future__ import annotations

import threading
import time
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass, field

import numpy as np

from . import choice, integrators
from .film import Film
from .integrators.base import Stage
from .integrators.first_hit import computes_alpha
from .parallel import workers
from .parallel.shared import Publisher
from .runner import Runner
from .scene import Scene, recentred
from . import tracer as tracer_mod
from .tracer import Tracer
from .validation import has_light, path_only_warnings, validate, volume_warnings


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
    # Integrator `auto`: the choice with its reasons (first line), the scene analysis and what
    # was left out and why (engine/choice/); empty for an integrator chosen by name.
    auto: tuple = ()

    def summary(self) -> str:
        state = {"cancel": "cancelled", "": "done"}.get(self.stopped_by, f"stopped at the {self.stopped_by}")
        noise = f" | noise {self.noise:.4f}" if self.noise is not None and np.isfinite(self.noise) else ""
        stages = ""
        if len(self.stage_seconds) > 1:
            stages = " | " + ", ".join(f"{name} {sec:.2f} s" for name, sec in self.stage_seconds.items())
        counters = "".join(f" | {text}" for text in self.counters.values())
        if self.auto:
            counters = f" | {self.auto[0]}{counters}"
        return (f"Ember {state}: {self.samples} samples in {self.elapsed:.2f} s | "
                f"{self.rays_per_second / 1e6:.2f} M rays/s | Embree {self.embree_share:.0%} of render time{noise}"
                f"{stages}{counters} | {self.nonfinite} non-finite samples")

    @property
    def embree_share(self) -> float:
        """Share of the workers' time spent inside Embree (CPU seconds over worker-seconds)."""
        return self.embree_seconds / max(self.elapsed * max(self.processes, 1), 1e-9)


class RenderSession:
    def __init__(self, scene: Scene, clock=time.perf_counter, pool=None, stage_cache=None):
        """clock: seconds (tests give a fake one); the time limit counts from here. pool: a
        workers.WorkerPool its owner keeps across renders (the viewport's): items run there
        whatever their number, and a stop cancels them without ending the workers.
        stage_cache: a StageCache (engine/stage_cache.py) whose stored stage results this
        render reuses where the scene parts they depend on are unchanged."""
        self.clock = clock
        self.pool, self.stage_cache = pool, stage_cache
        self.t_start = clock()
        validate(scene)
        scene = recentred(scene)  # far from the world origin: render about the scene's centre
        t0 = time.perf_counter()
        self.auto, self.analysis_seconds = (), 0.0
        if scene.settings.integrator == integrators.auto.AutoIntegrator.name:  # analyse and choose, once
            resolved = choice.resolve(scene)
            scene, self.auto = resolved.scene, resolved.lines
            self.analysis_seconds = time.perf_counter() - t0
        self.warnings: list[str] = []
        if scene.settings.noise_target > 0 and not integrators.REGISTRY[scene.settings.integrator].noise_target:
            self.warnings.append(f"The noise target does not apply to the '{scene.settings.integrator}' integrator "
                                 "(its passes are not independent samples of one image); it is ignored.")
            scene = scene.replace(settings=scene.settings.replace(noise_target=0.0))
        self.warnings += path_only_warnings(scene) + volume_warnings(scene)
        if scene.settings.adaptive and not integrators.REGISTRY[scene.settings.integrator].adaptive:
            self.warnings.append(f"Adaptive sampling does not apply to the '{scene.settings.integrator}' integrator "
                                 "(every pass covers every pixel); it samples uniformly.")
            scene = scene.replace(settings=scene.settings.replace(adaptive=False))
        self.scene = scene
        s = scene.settings
        self.integrator = integrators.create(scene)  # the render-process side: stages, reduce
        self.layout = self.integrator.layout
        self.film = Film(s.width, s.height, s.passes, computes_alpha(scene), adaptive=s.adaptive)
        cores = s.threads or workers.available_cores()
        # Worker processes are slow to start (bench/results/pipeline/report.md); worth it only
        # for renders of several items.
        self.processes = (cores if cores > 1 and self.integrator.work_items() >= 2 * cores and workers.can_spawn()
                          else 0)
        if pool is not None:
            self.processes = pool.n
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

    def _backend(self, stop: threading.Event):
        """Where items run: worker processes, or a thread of this process."""
        if self.processes:
            return _Processes(self.scene, self.processes, self.pool)
        return _InProcess(self.tracer, stop)

    def run(self, on_update=None, should_stop=None) -> RenderStats:
        t0 = time.perf_counter()
        run = Runner(self, on_update, should_stop, self.clock)
        self.publisher = Publisher()
        self.version = 0  # of the arrays published to every process
        backend = None
        completed = False
        try:
            backend = self._backend(run.stop)
            builds = getattr(backend, "builds", None)  # worker processes report what they built
            if builds is None:
                builds = {k: v - self._builds0[0][k] for k, v in tracer_mod.BUILDS.items()}
            self.build_seconds += time.perf_counter() - t0
            round_ = 0
            while not run.ended:
                stages = self.integrator.stages(round_)
                if not stages:
                    break
                for stage in stages:
                    t_stage = time.perf_counter()
                    cache = self.stage_cache
                    results = cache.get(self, round_, stage) if cache is not None else None
                    if results is None:
                        results = run.stage(stage, backend)
                        if cache is not None and results is not None:
                            cache.put(self, round_, stage, results)
                    run.stage_seconds[stage.name] = run.stage_seconds.get(stage.name, 0.0) + time.perf_counter() - t_stage
                    if results is None:  # stopped: cancel, time limit or noise target
                        break
                    if stage.publish:
                        arrays = self.integrator.reduce(stage, results)
                        self.version += 1
                        backend.install(self.version, arrays, self.publisher)
                    self.film.overlay = self.integrator.overlay()
                    if stage.film and stage.publish:
                        run.report(stage, pass_completed=True)
                round_ += 1
            completed = True
        finally:
            if backend is not None:
                backend.close(kill=run.cancelled or run.ended, keep=self.scene.settings.persistent and completed)
            self.publisher.release()
        elapsed = self.clock() - self.t_start
        noise = self.film.noise() if run.passes else run.noise
        counters = self.integrator.counters()
        if run.active is not None:
            left = int((~run.active.converged).sum())
            counters["adaptive"] = (f"adaptive: {left} of {self.layout.n_pixels} pixels active at the end, "
                                    f"{self.film.count[self.layout.pixel].mean():.1f} samples per pixel on average")
        if self.auto:  # the analysis ran in __init__, before any stage
            run.stage_seconds = {"analysis": self.analysis_seconds, **run.stage_seconds}
        return RenderStats(samples=run.passes, elapsed=elapsed, rays=run.rays,
                           rays_per_second=run.rays / max(elapsed, 1e-9), embree_seconds=run.embree_seconds,
                           build_seconds=self.build_seconds, cancelled=run.cancelled, noise=noise,
                           nonfinite=self.film.nonfinite, stopped_by=run.stopped_by if run.ended else "",
                           processes=self.processes, stage_seconds=run.stage_seconds, counters=counters,
                           settings=self.scene.settings, builds=dict(builds, workers=workers.STARTED[0] - self._builds0[1]),
                           auto=self.auto)


class _InProcess:
    """Items run one at a time on a thread of this process (small renders, Blender's binary)."""

    processes = 0
    in_flight = 2

    def __init__(self, tracer: Tracer, stop: threading.Event):
        self.tracer, self.stop = tracer, stop
        self.pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="ember")

    def submit(self, stage: Stage, item: int):
        return self.pool.submit(self.tracer.run, stage, item, self.stop)

    def wait(self, pending, timeout: float) -> set:
        return wait(pending, timeout=timeout, return_when=FIRST_COMPLETED)[0]

    def install(self, version: int, arrays: dict, publisher) -> None:
        for a in arrays.values():
            a.flags.writeable = False  # the same contract as shared memory
        self.tracer.install(version, arrays)

    def close(self, kill: bool, keep: bool = False) -> None:
        self.stop.set()
        self.pool.shutdown(wait=True)


class _Processes:
    """Items run in worker processes; published arrays go through shared memory."""

    def __init__(self, scene: Scene, n: int, owned=None):
        self.owned = owned  # a pool its owner keeps (never closed here)
        if owned is not None:
            self.pool = owned
        elif scene.settings.persistent:
            tracer_mod.forget()  # the workers trace: no tracer kept here
            self.pool = workers.pool_for(n)
        else:
            self.pool = workers.WorkerPool(n)
        try:
            self.builds = self.pool.load(scene)
        except BaseException:
            if owned is None:
                self.pool.close(kill=True)
            raise
        self.processes = n
        self.in_flight = 2 * n

    def submit(self, stage: Stage, item: int):
        return self.pool.submit(stage, item)

    def wait(self, pending, timeout: float) -> set:
        return wait(pending, timeout=timeout, return_when=FIRST_COMPLETED)[0]

    def install(self, version: int, arrays: dict, publisher: Publisher) -> None:
        self.pool.install(version, publisher.publish(arrays))

    def close(self, kill: bool, keep: bool = False) -> None:
        if self.owned is not None:  # stop what is in flight; the owner keeps the workers
            if not self.pool.cancel():
                self.pool.close(kill=True)
        elif keep and not kill and self.pool.alive():
            workers.keep(self.pool)
        else:
            self.pool.close(kill=kill)
