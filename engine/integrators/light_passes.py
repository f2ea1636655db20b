"""The path tracer's radiance split into Blender's light passes (engine/passes.py).

Every contribution a path adds is filed by where it was found:
- by the camera ray itself: Emission (surfaces, lights), Environment (the world, suns);
- after the first bounce: Direct if it is the light of that one bounce (next-event
  estimation at the first hit, or emission the first bounce's ray finds), else Indirect,
  shared among the lobe classes (diffuse, glossy, transmission) of the first hit.
The share is exact per channel: a next-event sample at the first hit splits by f_class / f
at the light's direction; a path continued from the first hit carries f_class / f at the
sampled direction (for a delta lobe: all of it to the class of that lobe). So the passes sum
to the radiance, sample by sample (Cycles splits the same way, bsdf_eval by closure type).
The Color passes are the first hit's lobe albedos (Closure.albedo_by_class).
"""
from __future__ import annotations

import numpy as np

from .. import passes as passes_mod
from ..vec import dot, take


class LightTally:
    def __init__(self, n: int, wanted):
        """n paths; wanted: pass names to return (others are not kept). Rows passed to the
        methods are unique within a call (one entry per live path)."""
        self.n = n
        self.wanted = tuple(w for w in wanted if w in passes_mod.LIGHT)
        self.emission = np.zeros((n, 3))
        self.environment = np.zeros((n, 3))
        self.direct = np.zeros((n, 3, 3))  # (path, class, channel)
        self.indirect = np.zeros((n, 3, 3))
        self.color = np.zeros((n, 3, 3))
        self.share = np.zeros((n, 3, 3))  # per path: its throughput's share per class after bounce 1

    def emitted(self, depth: int, rows: np.ndarray, c: np.ndarray, escaped: bool = False) -> None:
        """Radiance c (K,3) that the rays of bounce `depth` found for paths rows (K,)."""
        if depth == 0:
            (self.environment if escaped else self.emission)[rows] += c
        else:
            target = self.direct if depth == 1 else self.indirect
            target[rows] += self.share[rows] * c[:, None, :]

    def light_sample(self, depth: int, rows: np.ndarray, c: np.ndarray, f_by_class=None) -> None:
        """Next-event radiance c (K,3) at bounce `depth`; at the first hit f_by_class (K,3,3)
        is the BSDF per class at the light's direction."""
        if depth == 0:
            self.direct[rows] += _split(f_by_class) * c[:, None, :]
        else:
            self.indirect[rows] += self.share[rows] * c[:, None, :]

    def first_hit(self, rows: np.ndarray, bsdf) -> None:
        """Colour passes at the camera rays' hits (paths rows)."""
        self.color[rows] = bsdf.albedo_by_class()

    def first_bounce(self, rows: np.ndarray, bsdf, sample) -> None:
        """How the continuation of paths rows (all points of the first hit) splits by class."""
        share = _split(bsdf.eval_by_class(sample.wi, np.arange(len(rows))))
        d = np.flatnonzero(sample.delta)
        if len(d):  # a delta lobe: glossy if it reflects, transmission if it crosses
            crosses = dot(take(sample.wi, d), take(bsdf.ng, d)) < 0
            share[d] = 0.0
            share[d, np.where(crosses, 2, 1)] = 1.0
        self.share[rows] = share

    def passes(self) -> dict:
        out = {"Emission": self.emission, "Environment": self.environment}
        for k, cls in enumerate(passes_mod.LOBE_CLASSES):
            out[f"{cls} Direct"] = self.direct[:, k]
            out[f"{cls} Indirect"] = self.indirect[:, k]
            out[f"{cls} Color"] = self.color[:, k]
        return {name: out[name] for name in self.wanted}


def _split(f_by_class: np.ndarray) -> np.ndarray:
    """Per-channel shares f_class / f (K,3,3) (0 where f is 0)."""
    total = f_by_class.sum(axis=1, keepdims=True)
    return np.divide(f_by_class, total, out=np.zeros_like(f_by_class), where=total != 0)
