"""A render: build the acceleration structures once, then progressive full-frame passes.

Each pass gives every pixel of the border one more sample; the work (samples x pixels) is
cut into batches of `Settings.batch_size` paths, traced by worker processes (one per core,
engine/workers.py) or, for small renders, by one thread of this process. Results are added
to the film in batch order, and random numbers depend only on (seed, pixel, sample), so the
same seed gives the same image whatever the timing or the number of workers.

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

from . import workers
from .errors import Cancelled
from .validation import has_light, validate
from .film import Film
from .scene import Scene
from .tracer import BatchLayout, BatchTracer

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

    def summary(self) -> str:
        state = {"cancel": "cancelled", "": "done"}.get(self.stopped_by, f"stopped at the {self.stopped_by}")
        noise = f" | noise {self.noise:.4f}" if self.noise is not None and np.isfinite(self.noise) else ""
        return (f"Ember {state}: {self.samples} samples in {self.elapsed:.2f} s | "
                f"{self.rays_per_second / 1e6:.2f} M rays/s | Embree {self.embree_share:.0%} of render time{noise}")

    @property
    def embree_share(self) -> float:
        """Share of the workers' time spent inside Embree (CPU seconds over worker-seconds)."""
        return self.embree_seconds / max(self.elapsed * max(self.processes, 1), 1e-9)


class RenderSession:
    def __init__(self, scene: Scene):
        validate(scene)
        t0 = time.perf_counter()
        self.scene = scene
        s = scene.settings
        self.warnings: list[str] = []
        self.layout = BatchLayout(scene)
        self.film = Film(s.width, s.height)
        cores = s.threads or os.cpu_count() or 1
        # Worker processes pay ~1 s to start; worth it only for renders of several batches.
        self.processes = cores if cores > 1 and self.layout.n_batches >= 2 * cores and workers.can_spawn() else 0
        # Embree, light tables and the integrator live where the tracing happens: here, or in
        # each worker only (not here too: an 8k environment table is hundreds of MB).
        self.tracer = None if self.processes else BatchTracer(scene)
        if not has_light(scene):
            self.warnings.append("The scene has no lights, no emissive materials and a black world: "
                                 "the image will be black.")
        self.build_seconds = time.perf_counter() - t0

    def _add(self, batch: int, L: np.ndarray) -> None:
        """Add a batch to the film, one pass segment at a time (pixels unique per segment)."""
        n_pixels = self.layout.n_pixels
        k = self.layout.batch_paths(batch)
        cut = 0
        while cut < len(k):
            seg_end = min(len(k), cut + n_pixels - k[cut] % n_pixels)
            self.film.add(self.layout.pixel[k[cut:seg_end] % n_pixels], L[cut:seg_end])
            if (k[seg_end - 1] + 1) % n_pixels == 0:  # the segment completed a pass
                self.film.end_pass(int(k[seg_end - 1] + 1) // n_pixels)
            cut = seg_end

    def run(self, on_update=None, should_stop=None) -> RenderStats:
        s = self.scene.settings
        layout = self.layout
        stop = threading.Event()
        t0 = time.perf_counter()
        if self.processes:
            pool = workers.WorkerPool(self.scene, self.processes)
            submit, in_flight = pool.submit, 2 * self.processes
        else:
            pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="ember")

            def submit(batch):
                return pool.submit(self._trace_here, batch, stop)
            in_flight = 2
        self.build_seconds += time.perf_counter() - t0
        pending = {}  # future -> batch index
        finished = {}  # batch index -> radiance, waiting for its turn (film order is fixed)
        next_add = submitted = paths_added = rays = 0
        embree_seconds = 0.0
        cancelled = False
        last_update = t0
        noise, noise_time = None, t0

        def samples_done():
            return paths_added // layout.n_pixels

        def report(pass_completed):
            nonlocal last_update
            if on_update is not None:
                elapsed = time.perf_counter() - t0
                on_update(Progress(samples_done(), s.samples, paths_added / layout.total_paths, elapsed, rays,
                                   rays / max(elapsed, 1e-9), pass_completed, noise, self.film))
            last_update = time.perf_counter()

        try:
            while next_add < layout.n_batches:
                if should_stop is not None and not cancelled and should_stop():
                    cancelled = True
                    stop.set()
                    if self.processes:
                        break  # workers are killed below; nothing more is added
                out_of_time = s.time_limit > 0 and time.perf_counter() - t0 >= s.time_limit
                # The noise estimate needs a few passes to mean anything.
                out_of_time |= s.noise_target > 0 and samples_done() >= 4 and noise is not None and noise <= s.noise_target
                if not stop.is_set() and not out_of_time:
                    while len(pending) < in_flight and submitted < layout.n_batches:
                        pending[submit(submitted)] = submitted
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
                    result = finished.pop(next_add)
                    if result is None:  # cancelled mid-batch: nothing after it is added either
                        next_add = layout.n_batches
                        break
                    L, batch_rays, batch_embree = result
                    self._add(next_add, L)
                    paths_added += len(L)
                    rays += batch_rays
                    embree_seconds += batch_embree
                    next_add += 1
                pass_completed = samples_done() > before
                # The estimate costs a pass over the film: every pass when it can stop the
                # render, else at most once per NOISE_INTERVAL (it is only shown).
                if pass_completed and (s.noise_target > 0 or time.perf_counter() - noise_time >= NOISE_INTERVAL):
                    noise, noise_time = self.film.noise(), time.perf_counter()
                if pass_completed or time.perf_counter() - last_update >= UPDATE_INTERVAL:
                    report(pass_completed)
        finally:
            if self.processes:
                pool.close(kill=cancelled or bool(pending))
            else:
                stop.set()
                pool.shutdown(wait=True)
        elapsed = time.perf_counter() - t0
        stopped_by = ""
        if cancelled:
            stopped_by = "cancel"
        elif paths_added < layout.total_paths:
            stopped_by = "noise target" if s.noise_target > 0 and noise is not None and noise <= s.noise_target else "time limit"
        if samples_done():
            noise = self.film.noise()
        return RenderStats(samples=samples_done(), elapsed=elapsed, rays=rays, rays_per_second=rays / max(elapsed, 1e-9),
                           embree_seconds=embree_seconds, build_seconds=self.build_seconds, cancelled=cancelled,
                           noise=noise, nonfinite=self.film.nonfinite, stopped_by=stopped_by,
                           processes=self.processes)

    def _trace_here(self, batch: int, stop: threading.Event):
        accel = self.tracer.accel
        rays0, embree0 = accel.rays, accel.embree_seconds
        L = self.tracer.trace(batch, stop)
        return L, accel.rays - rays0, accel.embree_seconds - embree0
