"""Stage results kept across the renders of a changing scene (the viewport): a stage that does
not depend on the view - photon maps, radiance photons - is not run again when only the
camera, the resolution or the sample count changed.

An integrator names such stages (`Integrator.view_independent`). Their work items are pure
functions of (seed, stage, item, scene), and the scene they see is the same but for the camera
and the VIEW_ONLY settings, so stored results are exactly what a new run would return: the
image does not change, only the time to it. The cache holds the results of one scene (a
change to anything else - geometry, a material, a light, the world, the seed, the photon
count - empties it) up to MAX_BYTES. The render process still reduces and publishes them
(engine/session.py): each render's workers build their indexes again.
"""
from __future__ import annotations

import collections
import dataclasses

import numpy as np

from .scene import digest, part_digests

# Settings that say where the camera's samples go and how many, not what the stages before
# the camera pass compute.
VIEW_ONLY = ("width", "height", "border", "samples", "sample_offset", "time_limit", "noise_target", "threads",
             "batch_size", "persistent", "passes", "adaptive", "adaptive_threshold", "adaptive_min_samples")
MAX_BYTES = 256 << 20  # ppm's per-pass photon maps would otherwise grow with the viewport's passes


def scene_key(scene) -> str:
    """Digest of everything but the camera and the VIEW_ONLY settings."""
    parts = part_digests(scene)
    settings = {k: v for k, v in dataclasses.asdict(scene.settings).items() if k not in VIEW_ONLY}
    return digest([parts[name] for name in ("mesh", "materials", "lights", "world")] + [settings])


def _nbytes(value) -> int:
    if isinstance(value, np.ndarray):
        return value.nbytes
    if isinstance(value, dict):
        return sum(_nbytes(v) for v in value.values())
    if isinstance(value, (list, tuple)):
        return sum(_nbytes(v) for v in value)
    return 0


class StageCache:
    def __init__(self):
        self.key = None
        self.results: dict = {}  # (round, stage) -> item results in order
        self.bytes = 0
        self.runs = collections.Counter()  # stage name -> times it ran to completion
        self.reused = collections.Counter()  # stage name -> times its stored results served

    def _lookup(self, session, round_: int, stage):
        if stage.name not in session.integrator.view_independent:
            return None
        key = scene_key(session.scene)
        if key != self.key:
            self.key, self.results, self.bytes = key, {}, 0
        return (round_, stage)

    def get(self, session, round_: int, stage) -> list | None:
        """The stored results of `stage` in round `round_` of this scene, or None."""
        slot = self._lookup(session, round_, stage)
        results = self.results.get(slot) if slot is not None else None
        if results is None:
            return None
        self.reused[stage.name] += 1
        return [dict(r) if isinstance(r, dict) else r for r in results]  # reduce may take keys out

    def put(self, session, round_: int, stage, results: list) -> None:
        """A stage that ran to completion (also counted when it cannot be stored)."""
        self.runs[stage.name] += 1
        slot = self._lookup(session, round_, stage)
        size = _nbytes(results)
        if slot is not None and self.bytes + size <= MAX_BYTES:
            self.results[slot] = results
            self.bytes += size
