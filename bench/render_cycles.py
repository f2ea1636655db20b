"""Cycles on the same machine, in the same run, with the settings of the references
(scenes/reference.py: CPU, unbiased, the scene's pixel filter, every bounce limit 64).

Cycles' images cannot be snapshotted mid-render from Python, so each point of its ladder is
a render of its own: a warm-up render syncs the scene (persistent data keeps the BVH for the
rest), two calibration renders measure samples per second and the fixed cost of a render,
then budget b gets round(rate * (b - fixed cost)) samples. A point's time is that render's wall time from render_pre to
render_post (BVH build and scene sync excluded after the warm-up: Cycles' analogue of
Ember's export).
"""
from __future__ import annotations

import os
import tempfile
import time
from dataclasses import dataclass

import numpy as np

import bpy

from ember.engine import imageio

from .render_ember import Snapshot
from .scenes import ROOT

import importlib.util

_spec = importlib.util.spec_from_file_location("ember_scenes_reference", ROOT / "scenes" / "reference.py")
cycles_reference = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(cycles_reference)

CALIBRATION_SECONDS = 0.5


@dataclass
class CyclesRun:
    snapshots: list
    samples_per_second: float
    settings: dict
    sync_seconds: float


class _Clock:
    def __init__(self):
        self.pre = self.post = None

    def __enter__(self):
        bpy.app.handlers.render_pre.append(self._pre)
        bpy.app.handlers.render_post.append(self._post)
        return self

    def __exit__(self, *exc):
        bpy.app.handlers.render_pre.remove(self._pre)
        bpy.app.handlers.render_post.remove(self._post)

    def _pre(self, *args):
        self.pre = time.perf_counter()

    def _post(self, *args):
        self.post = time.perf_counter()


def render_samples(scene, samples: int, seed: int, path: str) -> tuple[np.ndarray, float]:
    """One Cycles render; ((H,W,3) float32 linear, seconds from render_pre to render_post)."""
    scene.cycles.samples = samples
    scene.cycles.seed = seed
    cycles_reference.exr_output(scene, path)
    with _Clock() as clock:
        bpy.ops.render.render(write_still=True)
    return imageio.read_rgb(path), clock.post - clock.pre


def render(scene, budgets, seed: int = 0, extra_samples=()) -> CyclesRun:
    """Cycles ladder on the open .blend's `scene`: one render per budget (seconds) and one per
    entry of extra_samples (samples, e.g. Ember's count for an equal-samples point)."""
    settings = cycles_reference.unbiased_cycles(scene, 1)
    snaps = []
    with tempfile.TemporaryDirectory(prefix="ember_bench_") as tmp:
        path = os.path.join(tmp, "cycles.exr")
        _, sync = render_samples(scene, 1, seed + 1000, path)  # scene sync and BVH
        # time = overhead + samples / rate: two renders, the second 4x the first and long
        # enough to time, give both.
        n, t = 1, 0.0
        while t < CALIBRATION_SECONDS:
            n *= 4
            _, t_small = render_samples(scene, n // 4, seed + 1001, path)
            _, t = render_samples(scene, n, seed + 1002, path)
        rate = (n - n // 4) / max(t - t_small, 1e-3)
        overhead = max(t_small - (n // 4) / rate, 0.0)
        plan = [max(1, int(round(rate * (b - overhead)))) for b in sorted(budgets)] + [int(s) for s in extra_samples]
        labels = sorted(budgets) + [None] * len(extra_samples)
        for i, (spp, b) in enumerate(zip(plan, labels)):
            img, t = render_samples(scene, spp, seed + i, path)
            snaps.append(Snapshot(budget=b, seconds=t, samples=float(spp), image=img))
    return CyclesRun(snapshots=snaps, samples_per_second=rate, settings=settings, sync_seconds=sync)
