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
from .scene import FILTERS, INTEGRATORS, STRATEGIES, Scene

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
    stopped_by: str = ""  # "", "cancel", "time limit" or "noise target"

    def summary(self) -> str:
        state = {"cancel": "cancelled", "": "done"}.get(self.stopped_by, f"stopped at the {self.stopped_by}")
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
    if s.strategy not in STRATEGIES:
        problems.append(f"unknown strategy {s.strategy!r} (use one of {', '.join(STRATEGIES)})")
    if not s.noise_target >= 0:
        problems.append(f"noise target must be >= 0 (got {s.noise_target})")
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
        self.lights = LightSet(scene.lights, scene.mesh, scene.materials, scene.world, self.accel,
                               self.accel.scene_radius)
        if self.lights.empty and not np.max(scene.world.color) > 0:
            self.warnings.append("The scene has no lights, no emissive materials and a black world: "
                                 "the image will be black.")
        self.integrator = PathTracer(scene, self.accel, self.lights)
        self.film = Film(s.width, s.height)
        x0, y0, x1, y1 = s.border
        ys, xs = np.mgrid[y0:y1, x0:x1]
        self.px, self.py = xs.ravel(), ys.ravel()
        self.pixel = self.py * s.width + self.px
        # Work = samples x pixels in pass-major order, cut into fixed-size batches (a batch
        # may span several passes of a small image, so per-bounce overhead stays amortised).
        self.n_pixels = len(self.px)
        self.total_paths = s.samples * self.n_pixels
        self.n_batches = -(-self.total_paths // s.batch_size)
        self.threads = s.threads or os.cpu_count() or 1
        self.build_seconds = time.perf_counter() - t0

    def _trace(self, batch_index: int, stop: threading.Event):
        s = self.scene.settings
        k = np.arange(batch_index * s.batch_size, min((batch_index + 1) * s.batch_size, self.total_paths))
        j = k % self.n_pixels
        sampler = Sampler(s.seed, self.pixel[j], k // self.n_pixels)
        return self.integrator.render(sampler, self.px[j], self.py[j], stop)

    def _add(self, batch_index: int, L: np.ndarray) -> None:
        """Add a batch to the film, one pass segment at a time (pixels unique per segment)."""
        s = self.scene.settings
        start = batch_index * s.batch_size
        end = start + len(L)
        cut = start
        while cut < end:
            seg_end = min(end, (cut // self.n_pixels + 1) * self.n_pixels)
            j = np.arange(cut, seg_end) % self.n_pixels
            self.film.add(self.pixel[j], L[cut - start:seg_end - start])
            cut = seg_end

    def run(self, on_update=None, should_stop=None) -> RenderStats:
        s = self.scene.settings
        stop = threading.Event()
        pending = {}  # future -> batch index
        finished = {}  # batch index -> radiance, waiting for its turn (film order is fixed)
        next_add = submitted = 0
        paths_added = 0
        cancelled = False
        t0 = time.perf_counter()
        last_update = t0
        rays0 = self.accel.rays
        noise = None

        def samples_done():
            return paths_added // self.n_pixels

        def report(pass_completed):
            nonlocal last_update
            if on_update is not None:
                elapsed = time.perf_counter() - t0
                rays = self.accel.rays - rays0
                on_update(Progress(samples_done(), s.samples, paths_added / self.total_paths, elapsed, rays,
                                   rays / max(elapsed, 1e-9), pass_completed, noise, self.film))
            last_update = time.perf_counter()

        with ThreadPoolExecutor(max_workers=self.threads, thread_name_prefix="ember") as pool:
            while next_add < self.n_batches:
                if should_stop is not None and not cancelled and should_stop():
                    cancelled = True
                    stop.set()
                out_of_time = s.time_limit > 0 and time.perf_counter() - t0 >= s.time_limit
                # The noise estimate needs a few passes to mean anything.
                out_of_time |= s.noise_target > 0 and samples_done() >= 4 and noise is not None and noise <= s.noise_target
                if not stop.is_set() and not out_of_time:
                    while len(pending) < 2 * self.threads and submitted < self.n_batches:
                        pending[pool.submit(self._trace, submitted, stop)] = submitted
                        submitted += 1
                if not pending:
                    break
                done, _ = wait(pending, timeout=UPDATE_INTERVAL, return_when=FIRST_COMPLETED)
                for fut in done:
                    b = pending.pop(fut)
                    try:
                        finished[b] = fut.result()
                    except Cancelled:
                        finished[b] = None
                before = samples_done()
                while next_add in finished:
                    L = finished.pop(next_add)
                    if L is None:  # cancelled mid-batch: nothing after it is added either
                        next_add = self.n_batches
                        break
                    self._add(next_add, L)
                    paths_added += len(L)
                    next_add += 1
                pass_completed = samples_done() > before
                if pass_completed:
                    noise = self.film.noise()
                if pass_completed or time.perf_counter() - last_update >= UPDATE_INTERVAL:
                    report(pass_completed)
        elapsed = time.perf_counter() - t0
        rays = self.accel.rays - rays0
        stopped_by = ""
        if cancelled:
            stopped_by = "cancel"
        elif paths_added < self.total_paths:
            stopped_by = "noise target" if s.noise_target > 0 and noise is not None and noise <= s.noise_target else "time limit"
        if samples_done() and noise is None:
            noise = self.film.noise()
        return RenderStats(samples=samples_done(), elapsed=elapsed, rays=rays, rays_per_second=rays / max(elapsed, 1e-9),
                           embree_seconds=self.accel.embree_seconds, build_seconds=self.build_seconds,
                           cancelled=cancelled, noise=noise, nonfinite=self.film.nonfinite, stopped_by=stopped_by)
