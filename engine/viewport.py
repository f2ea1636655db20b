"""Interactive rendering for a viewport: progressive, restartable, on a thread of its own.

    view = ViewportSession(pixel_size=2)
    view.update(scene)                  # from Blender's main thread, as often as edits come
    version, buffer = view.latest()     # the drawing side: (H*W*4,) float32, rows bottom-up
    view.close()

The thread renders the newest scene it was given: first one sample at 1/`pixel_size` of the
resolution (so an edit shows within a fraction of a second), then full resolution, one pass
after another up to the scene's sample count. An update stops the running render at its next
check and starts over.

Tracing happens in worker processes (engine/parallel/workers.py) that this session starts once
and keeps until `close`: every render loads its scene into them, sending only the parts that
changed, and each worker rebuilds only what those parts invalidate (Embree for new geometry,
light tables for new lights, materials or world: engine/tracer.py). An update cancels the
items in flight through the pool's cancel counter - a running item stops at its next bounce -
so the workers are free for the new scene at once. Stages whose results do not depend on the
view (photon maps) are kept across camera moves (engine/stage_cache.py). Where workers cannot
start (one core, Blender's own binary) the session traces in this process. Nothing here
touches Blender.
"""
from __future__ import annotations

import threading
import time

import numpy as np

from . import tracer as tracer_mod
from .parallel import workers
from .scene import Scene
from .session import RenderSession
from .stage_cache import StageCache

HALF_MAX = 65504.0  # the draw texture is half float: larger values would become inf
# Triangles up to which the first coarse image is traced in this process while the workers
# start (beyond, a third Embree build beside the workers' two would delay everything).
IN_PROCESS_FIRST = 1 << 17


def draw_buffer(image: np.ndarray) -> np.ndarray:
    """(H,W,4) top-down film image -> flat float32 RGBA, rows bottom-up (GPU texture order),
    non-finite values 0 and everything clamped to [-HALF_MAX, HALF_MAX)."""
    flipped = np.ascontiguousarray(image[::-1], dtype=np.float32)
    flipped = np.nan_to_num(flipped, nan=0.0, posinf=HALF_MAX, neginf=-HALF_MAX)
    top = np.nextafter(np.float32(HALF_MAX), np.float32(0))
    return np.clip(flipped, -top, top).reshape(-1)


def upscale(image: np.ndarray, factor: int, height: int, width: int) -> np.ndarray:
    """A coarse image (h,w,C) blown up by pixel repetition and cropped to (height, width)."""
    return np.repeat(np.repeat(image, factor, axis=0), factor, axis=1)[:height, :width]


def coarse_scene(scene: Scene, factor: int) -> Scene:
    """The scene at 1/factor of its resolution, one sample (the same camera window)."""
    s = scene.settings
    w, h = -(-s.width // factor), -(-s.height // factor)
    return scene.replace(settings=s.replace(width=w, height=h, border=(0, 0, w, h), samples=1, time_limit=0.0,
                                            noise_target=0.0))


class ViewportSession:
    def __init__(self, pixel_size: int = 2, on_image=None):
        """pixel_size: the first image's pixel size (Blender's preview_pixel_size, at least 2
        to pay off); on_image(): called on the render thread after each new image."""
        self.pixel_size = max(2, int(pixel_size))
        self.on_image = on_image
        self._cond = threading.Condition()
        self._job = None  # the scene waiting to start
        self._restart = threading.Event()
        self._closed = False
        self._buffer = None  # (version, flat float32 RGBA, width, height, samples)
        self._version = 0
        self.stats = []  # per update: dict(builds, first_image, samples, stopped) (bench/viewport.py, tests)
        self.error = None  # the last render's exception message, if it failed
        self.pool = None  # the worker processes, kept across updates (render thread)
        self.stage_cache = StageCache()
        self._thread = threading.Thread(target=self._loop, name="ember-viewport", daemon=True)
        self._thread.start()

    # --- main thread ------------------------------------------------------------------------
    def update(self, scene: Scene) -> None:
        """Render `scene` from now on (recentred like the last one: the exporter's origin)."""
        with self._cond:
            self._job = scene
            self._updated = time.perf_counter()
            self._restart.set()
            self._cond.notify()
        self._interrupt()

    def latest(self):
        """(version, flat float32 RGBA rows bottom-up, width, height, samples) of the newest
        image, or None before the first."""
        return self._buffer

    def busy(self) -> bool:
        """Whether a render is running or waiting (the viewport keeps redrawing meanwhile)."""
        with self._cond:
            return self._job is not None or self._running

    def close(self, timeout: float = 10.0) -> None:
        with self._cond:
            self._closed = True
            self._restart.set()
            self._cond.notify()
        self._interrupt()
        self._thread.join(timeout)
        if self.pool is not None:
            self.pool.close(kill=True)
            self.pool = None

    def _interrupt(self) -> None:
        """Stop the workers' items in flight at their next bounce; the render thread's session
        sees the restart and cancels whatever it sends after this."""
        with self._cond:
            pool = self.pool
        epoch = pool.epoch if pool is not None else None
        if epoch is not None:
            epoch[0] += 1

    # --- render thread ----------------------------------------------------------------------
    _running = False

    def _stop(self) -> bool:
        return self._restart.is_set()

    def _loop(self) -> None:
        while True:
            with self._cond:
                while self._job is None and not self._closed:
                    self._cond.wait()
                if self._closed:
                    return
                scene, self._job, updated = self._job, None, self._updated
                self._restart.clear()
                self._running = True
            try:
                self._render(scene, updated)
            except Exception as e:  # shown by the engine; the thread must survive bad scenes
                self.error = f"{type(e).__name__}: {e}"
            finally:
                with self._cond:
                    self._running = False

    def _render(self, scene: Scene, updated: float) -> None:
        """updated: the clock of the update that asked for it (times count from there)."""
        t0 = updated
        # stopped: seconds from the update until the last render had stopped (cancel latency)
        record = dict(builds={}, first_image=None, samples=[], stopped=time.perf_counter() - updated)
        started = workers.STARTED[0]
        self.stats.append(record)
        self.error = None
        s = scene.settings
        for factor in (self.pixel_size, 1):
            if self._stop():
                return
            starting = self.pool is None
            pool = self._pool(s.threads)
            if starting and factor > 1 and scene.mesh.n_triangles < IN_PROCESS_FIRST:
                # The workers take a second to start and load the scene: the first coarse image
                # of a small scene is traced here meanwhile (and the tracer dropped after it).
                pool = None
            level = coarse_scene(scene, factor) if factor > 1 else scene
            ls = level.settings
            # Without workers this process traces alone (threads=1: no pool of its own either);
            # the runner shares the one-sample image's pass among the workers.
            ls = ls.replace(persistent=True, threads=s.threads if pool else 1)
            level = level.replace(settings=ls)
            session = RenderSession(level, pool=pool, stage_cache=self.stage_cache)

            def publish(progress, factor=factor):
                if not progress.pass_completed:
                    return
                image = progress.film.image()
                if factor > 1:
                    image = upscale(image, factor, s.height, s.width)
                self._version += 1
                self._buffer = (self._version, draw_buffer(image), s.width, s.height, progress.samples_done)
                elapsed = time.perf_counter() - t0
                if record["first_image"] is None:
                    record["first_image"] = elapsed
                if factor == 1:
                    record["samples"].append((progress.samples_done, elapsed))
                if self.on_image is not None:
                    self.on_image()

            record["processes"] = session.processes
            try:
                stats = session.run(on_update=publish, should_stop=self._stop)
            finally:
                if pool is None and self.pool is not None:  # the workers trace from now on
                    tracer_mod.forget()
            for key, n in stats.builds.items():
                record["builds"][key] = record["builds"].get(key, 0) + n
            record["builds"]["workers"] = workers.STARTED[0] - started

    def _pool(self, threads: int):
        """The session's worker pool (started on first use, again if a worker died or the
        thread count changed), or None where workers cannot run."""
        n = threads or workers.available_cores()
        if n < 2 or not workers.can_spawn():
            n = 0
        pool = self.pool
        if pool is not None and (pool.n != n or not pool.alive()):
            pool.close(kill=True)
            pool = None
        if pool is None and n:
            pool = workers.WorkerPool(n)
        with self._cond:
            self.pool = pool
        return pool
