"""One progressive Ember render through bpy.ops.render.render (the F12 path), snapshotted at
a ladder of times: error against time from a single run.

The render stops at the largest budget (scene.ember.time_limit). A snapshot is the film's
mean at the first progress update (each completed batch, at least every 0.25 s) with an image
at or past a budget (budgets that pass before the first image share it), stamped with the render's own clock plus its build time, so a point's time is what
it took to reach that image after export (the Embree build and, for the path tracer, the
worker start-up included). Phases: export, build, render (RenderStats) and the rest of the
wall time (Blender's result handling).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

import bpy

from ember.engine.blender import final

# The references and the Cycles runs use every bounce limit 64 (scenes/reference.py), so
# Ember does too, whatever the scene's own setting (veach_mis.blend is direct-only).
MAX_DEPTH = 64


@dataclass
class Snapshot:
    budget: float | None  # the largest budget this image is the first past (None: the end image)
    seconds: float  # build + render time to this image
    samples: float  # mean samples per pixel in the image
    image: np.ndarray  # (H,W,3) float32


@dataclass
class EmberRun:
    integrator: str
    snapshots: list  # the first image past each budget (one image can stand for several)
    stats: object  # engine.session.RenderStats
    export_seconds: float
    wall_seconds: float
    film_nonfinite: int
    warnings: list = field(default_factory=list)


class _Snapshots:
    """A final.listeners entry."""

    def __init__(self, budgets):
        self.budgets = sorted(budgets)
        self.taken = []  # (largest budget passed, render seconds, samples, image)
        self.reached = 0  # budgets passed by the last snapshot
        self.t0 = time.perf_counter()
        self.export_done = None
        self.stats = self.image = self.film = None
        self.errors = []

    def on_export(self, layer, text):
        self.export_done = time.perf_counter() - self.t0

    def on_progress(self, layer, progress):
        self.film = progress.film
        passed = sum(b <= progress.elapsed for b in self.budgets)
        if passed > self.reached and self.film.count.any():
            self.reached = passed
            self.taken.append((self.budgets[passed - 1], progress.elapsed, float(self.film.count.mean()),
                               self.film.mean().astype(np.float32)))

    def on_layer_done(self, layer, stats, image, border):
        self.stats, self.image = stats, image

    def on_error(self, layer, message, user_error):
        self.errors.append(message)


def render(scene, integrator: str, budgets, seed: int = 0) -> EmberRun:
    """Render the open .blend's `scene` with Ember for max(budgets) seconds."""
    scene.render.engine = "EMBER"
    e = scene.ember
    e.integrator = integrator.upper()
    e.samples = 1 << 20  # the time limit stops it
    e.max_depth = MAX_DEPTH
    e.time_limit = float(max(budgets))
    e.noise_target = 0.0
    e.seed = seed
    shots = _Snapshots(budgets)
    final.listeners.append(shots)
    try:
        bpy.ops.render.render(write_still=False)
    finally:
        final.listeners.remove(shots)
    wall = time.perf_counter() - shots.t0
    if shots.errors or shots.stats is None:
        raise RuntimeError("; ".join(shots.errors) or "Ember rendered nothing")
    st = shots.stats
    taken = list(shots.taken)
    film = shots.film
    if film is not None and film.count.any() and (not taken or film.count.mean() > taken[-1][2]):
        # The run ends after its in-flight batches, past the last update: the end image, what
        # a render with time limit = the largest budget gives.
        taken.append((None, st.elapsed, float(film.count.mean()), film.mean().astype(np.float32)))
    snaps = [Snapshot(budget=b, seconds=st.build_seconds + t, samples=n, image=img) for b, t, n, img in taken]
    return EmberRun(integrator=integrator, snapshots=snaps, stats=st,
                    export_seconds=shots.export_done or 0.0, wall_seconds=wall,
                    film_nonfinite=int(st.nonfinite))
