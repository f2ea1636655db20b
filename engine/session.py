"""A render: build the acceleration structures once, then progressive full-frame passes.

Each pass gives every pixel of the border one more sample; a pass is split into batches
of `Settings.batch_size` paths, traced by a pool of worker threads (embreex and most
NumPy kernels release the GIL, so both cores work). Results are added to the film in
batch order, so the same seed gives the same image whatever the thread timing.

The caller's thread is the only one that calls `on_update` and `should_stop` (Blender's
API is not thread-safe), at least every `UPDATE_INTERVAL` seconds.
"""
from __future__ import annotations

import os
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass

import numpy as np

from .accel import Accel
from .errors import Cancelled, EmberError
from .film import Film
from .integrators.path import PathTracer
from .lights.light_set import LightSet
from .rng import Sampler
from .scene import FILTERS, INTEGRATORS, Scene

UPDATE_INTERVAL = 0.25


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

    def summary(self) -> str:
        state = "cancelled" if self.cancelled else "done"
        noise = f" | noise {self.noise:.4f}" if self.noise is not None and np.isfinite(self.noise) else ""
        return (f"Ember {state}: {self.samples} samples in {self.elapsed:.2f} s | "
                f"{self.rays_per_second / 1e6:.2f} M rays/s | Embree {self.embree_share:.0%} of render time{noise}")

    @property
    def embree_share(self) -> float:
        return self.embree_seconds / max(self.elapsed, 1e-9)


def validate(scene: Scene) -> None:
    s = scene.settings
    problems = []
    if s.width < 1 or s.height < 1:
        problems.append(f"resolution must be at least 1x1 (got {s.width}x{s.height})")
    x0, y0, x1, y1 = s.border
    if not (0 <= x0 < x1 <= s.width and 0 <= y0 < y1 <= s.height):
        problems.append(f"render border {s.border} is empty or outside the {s.width}x{s.height} frame")
    if s.samples < 1:
        problems.append(f"samples must be at least 1 (got {s.samples})")
    if s.max_depth < 0:
        problems.append(f"max depth must be >= 0 (got {s.max_depth})")
    if s.time_limit < 0:
        problems.append(f"time limit must be >= 0 (got {s.time_limit})")
    if s.batch_size < 1:
        problems.append(f"batch size must be positive (got {s.batch_size})")
    if s.filter not in FILTERS:
        problems.append(f"unknown pixel filter {s.filter!r} (use one of {', '.join(FILTERS)})")
    if not s.filter_width > 0:
        problems.append(f"filter width must be positive (got {s.filter_width})")
    if s.integrator not in INTEGRATORS:
        problems.append(f"unknown integrator {s.integrator!r} (use one of {', '.join(INTEGRATORS)})")
    if problems:
        raise EmberError("Invalid render settings: " + "; ".join(problems))


class RenderSession:
    def __init__(self, scene: Scene):
        validate(scene)
        t0 = time.perf_counter()
        self.scene = scene
        s = scene.settings
        self.warnings: list[str] = []
        self.accel = Accel(scene.mesh)
        self.lights = LightSet(scene.lights, scene.mesh, scene.materials, self.accel, self.accel.scene_radius)
        if self.lights.empty and not np.max(scene.world.color) > 0:
            self.warnings.append("The scene has no lights, no emissive materials and a black world: "
                                 "the image will be black.")
        self.integrator = PathTracer(scene, self.accel, self.lights)
        self.film = Film(s.width, s.height)
        x0, y0, x1, y1 = s.border
        ys, xs = np.mgrid[y0:y1, x0:x1]
        self.px, self.py = xs.ravel(), ys.ravel()
        self.pixel = self.py * s.width + self.px
        n = len(self.px)
        self.batches = [(i, min(i + s.batch_size, n)) for i in range(0, n, s.batch_size)]
        self.threads = s.threads or os.cpu_count() or 1
        self.build_seconds = time.perf_counter() - t0

    def _trace(self, pass_index: int, batch_index: int, stop: threading.Event):
        a, b = self.batches[batch_index]
        sampler = Sampler(self.scene.settings.seed, pass_index, batch_index)
        return self.integrator.render(sampler, self.px[a:b], self.py[a:b], stop)

    def run(self, on_update=None, should_stop=None) -> RenderStats:
        s = self.scene.settings
        n_batches = len(self.batches)
        jobs = ((p, b) for p in range(s.samples) for b in range(n_batches))
        total_jobs = s.samples * n_batches
        stop = threading.Event()
        pending = {}  # future -> job sequence number
        finished = {}  # sequence number -> result, waiting for its turn
        next_add = 0
        submitted = 0
        samples_done = 0
        cancelled = False
        t0 = time.perf_counter()
        last_update = t0
        rays0 = self.accel.rays
        noise = None

        def report(pass_completed):
            nonlocal last_update
            if on_update is None:
                return
            elapsed = time.perf_counter() - t0
            rays = self.accel.rays - rays0
            on_update(Progress(samples_done, s.samples, next_add / total_jobs, elapsed, rays,
                               rays / max(elapsed, 1e-9), pass_completed, noise, self.film))
            last_update = time.perf_counter()

        with ThreadPoolExecutor(max_workers=self.threads, thread_name_prefix="ember") as pool:
            while next_add < total_jobs:
                out_of_time = s.time_limit > 0 and time.perf_counter() - t0 >= s.time_limit
                if should_stop is not None and should_stop():
                    cancelled = True
                    stop.set()
                if not stop.is_set() and not out_of_time:
                    while len(pending) < 2 * self.threads and submitted < total_jobs:
                        job = next(jobs)
                        pending[pool.submit(self._trace, *job, stop)] = submitted
                        submitted += 1
                if not pending:
                    break
                done, _ = wait(pending, timeout=UPDATE_INTERVAL, return_when=FIRST_COMPLETED)
                for fut in done:
                    seq = pending.pop(fut)
                    try:
                        finished[seq] = fut.result()
                    except Cancelled:
                        finished[seq] = None
                pass_completed = False
                while next_add in finished:
                    L = finished.pop(next_add)
                    if L is None:  # cancelled mid-batch: nothing after it is added either
                        next_add = total_jobs
                        break
                    a, b = self.batches[next_add % n_batches]
                    self.film.add(self.pixel[a:b], L)
                    next_add += 1
                    if next_add % n_batches == 0:
                        samples_done += 1
                        pass_completed = True
                if stop.is_set() and not pending:
                    break
                if pass_completed:
                    noise = self.film.noise()
                if pass_completed or time.perf_counter() - last_update >= UPDATE_INTERVAL:
                    report(pass_completed)
                if (stop.is_set() or out_of_time) and not pending:
                    break
        elapsed = time.perf_counter() - t0
        rays = self.accel.rays - rays0
        if noise is None and samples_done:
            noise = self.film.noise()
        return RenderStats(samples=samples_done, elapsed=elapsed, rays=rays, rays_per_second=rays / max(elapsed, 1e-9),
                           embree_seconds=self.accel.embree_seconds, build_seconds=self.build_seconds,
                           cancelled=cancelled, noise=noise, nonfinite=self.film.nonfinite)
