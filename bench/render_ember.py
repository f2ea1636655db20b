"""One progressive Ember render through bpy.ops.render.render (the F12 path), snapshotted at
a ladder of times: error against time from a single run.

The render stops at the largest budget (scene.ember.time_limit). The clock starts when
export ends, so a point's time is what it took to reach that image from the exported scene:
Embree build, worker start-up and tracing. A snapshot is the film's mean at the first
progress update (each completed batch, at least every 0.25 s) with an image at or past a
budget (budgets that pass before the first image share it); the image at the end is one
more point. Phases: export, build (RenderStats.build_seconds, worker start-up included),
tracing (the rest of the session) and the rest of the wall time (Blender's result handling).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

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
    snapshots: list  # the first image past each budget (one image can stand for several), the end image
    stats: object  # engine.session.RenderStats
    export_seconds: float  # render call to the end of export
    session_seconds: float  # end of export to the layer's end: build + tracing
    wall_seconds: float  # the whole render call


class _Snapshots:
    """A final.listeners entry."""

    def __init__(self, budgets, clock=time.perf_counter):
        self.budgets = sorted(budgets)
        self.clock = clock
        self.taken = []  # (largest budget passed, seconds since export, samples, image)
        self.reached = 0  # budgets passed by the last snapshot
        self.start = clock()
        self.export_done = self.layer_done = None
        self.stats = self.film = None
        self.errors = []

    def on_export(self, layer, text):
        self.export_done = self.clock()

    def on_progress(self, layer, progress):
        self.film = progress.film
        t = self.clock() - (self.export_done or self.start)
        passed = sum(b <= t for b in self.budgets)
        if passed > self.reached and self.film.count.any():
            self.reached = passed
            self.taken.append((self.budgets[passed - 1], t, float(self.film.count.mean()),
                               self.film.mean().astype(np.float32)))

    def on_layer_done(self, layer, stats, image, border):
        self.stats, self.layer_done = stats, self.clock()

    def on_error(self, layer, message, user_error):
        self.errors.append(message)


def render(scene, integrator: str, budgets, seed: int = 0, overrides=None) -> EmberRun:
    """Render the open .blend's `scene` with Ember for max(budgets) seconds; overrides:
    scene.ember property -> value (a labelled variant, e.g. radiance_photons=False)."""
    scene.render.engine = "EMBER"
    e = scene.ember
    e.integrator = integrator.upper()
    e.samples = 1 << 20  # the time limit stops it
    e.max_depth = MAX_DEPTH
    # Cycles renders Glossy as GGX; so must Ember here (veach_mis.blend asks for Phong, the
    # seed's model, which is a different BRDF: comparing it with Cycles would measure that).
    if hasattr(e, "glossy_as_phong"):
        e.glossy_as_phong = False
    e.time_limit = float(max(budgets))
    e.noise_target = 0.0
    e.seed = seed
    for k, v in (overrides or {}).items():
        if not hasattr(e, k):
            raise RuntimeError(f"scene.ember has no setting '{k}'")
        setattr(e, k, type(getattr(e, k))(v))
    shots = _Snapshots(budgets)
    final.listeners.append(shots)
    try:
        bpy.ops.render.render(write_still=False)
    finally:
        final.listeners.remove(shots)
    wall = time.perf_counter() - shots.start
    if shots.errors or shots.stats is None:
        raise RuntimeError("; ".join(shots.errors) or "Ember rendered nothing")
    export_done = shots.export_done or shots.start
    session = shots.layer_done - export_done
    taken = list(shots.taken)
    film = shots.film
    if film is not None and film.count.any() and (not taken or film.count.mean() > taken[-1][2]):
        # The run ends after its in-flight batches, past the last update: the end image, what
        # a render with time limit = the largest budget gives.
        taken.append((None, session, float(film.count.mean()), film.mean().astype(np.float32)))
    snaps = [Snapshot(budget=b, seconds=t, samples=n, image=img) for b, t, n, img in taken]
    return EmberRun(integrator=integrator, snapshots=snaps, stats=shots.stats,
                    export_seconds=export_done - shots.start, session_seconds=session, wall_seconds=wall)
