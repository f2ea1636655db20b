"""Light shaders that vary: a light's node program evaluated at each of its samples and hits.

Cycles evaluates a light's shader wherever it is sampled or hit (light/sample.h
light_sample_shader_eval, with PATH_RAY_EMISSION) and multiplies the light's strength x
eval_fac by the emission the shader makes; Ember folds a shader that does not vary into the
light's radiance (engine/blender/export_light.py) and keeps the others' graphs
(Lights.graphs), whose value this module gives per sample as a factor on Lights.Le.

The shading state of a point on a light (geom/shader_data.h shader_setup_from_sample, the
light kinds' *_light_sample in light/*.h):
  P      the point on the light; a sun's: the direction it shines along (-wi)
  N, Ng  soft point / spot (a disk facing the receiver) and delta lights: -wi; sphere lights:
         outward from the centre; area lights: the emitting side (-z); suns: -wi
  I      -wi: from the light toward the receiver
  ray_length  the distance from the receiver (FLT_MAX for suns)
  object, generated  P in the light object's space (Cycles has no Generated attribute on
         lights and falls back to object coordinates); world_from_object its transform
  uv     zero (the light's parametric u, v are not modelled)
with wi the unit direction from the receiver toward the light. The path flag is
PATH_RAY_EMISSION, no bounce (Light Path reads the receiving path's counts in Cycles).
"""
from __future__ import annotations

import numpy as np

from ..nodes.closures import closures
from ..nodes.hits import EMISSION_RAY, PathFields
from ..nodes.program import compile
from ..nodes.state import ShadingState
from ..scene import LIGHT_DISK, LIGHT_POINT, LIGHT_RECT, LIGHT_SPOT, LIGHT_SUN, Lights
from ..vec import normalize
from .world import ZeroFields

_FLT_MAX = float(np.finfo(np.float32).max)


class _LightPoints(ZeroFields, PathFields):
    """State source of N points on one light (see the module docstring)."""

    ray = EMISSION_RAY  # Cycles evaluates a light's shader with PATH_RAY_EMISSION, no bounce

    def __init__(self, lights: Lights, i: int, P, Ng, I, t):
        self._lights, self._i = lights, i
        self._P, self._Ng, self._I, self._t = P, Ng, I, t

    def __len__(self):
        return len(self._P)

    def P(self):
        return self._P

    def N(self):
        return self._Ng

    def Ng(self):
        return self._Ng

    def I(self):  # noqa: E743 (Cycles' name)
        return self._I

    def ray_length(self):
        return np.where(np.isfinite(self._t), self._t, _FLT_MAX)

    def backfacing(self):
        return np.zeros(len(self._P), bool)

    def uv(self):
        return np.zeros_like(self._P)

    instancer_generated = instancer_uv = uv

    def _frame(self):
        m = np.eye(4)
        m[:3, :3] = self._lights.matrix[self._i]
        m[:3, 3] = self._lights.position[self._i]
        return m

    def world_from_object(self):
        return np.broadcast_to(self._frame(), (len(self._P), 4, 4))

    def object_from_world(self):
        return np.broadcast_to(np.linalg.inv(self._frame()), (len(self._P), 4, 4))

    def object(self):
        inv = np.linalg.inv(self._frame())
        return self._P @ inv[:3, :3].T + inv[:3, 3]

    generated = object



class LightShaders:
    """The programs of the lights whose shader varies (Lights.graphs), compiled once per
    process; `factor` gives their emission at points on them."""

    def __init__(self, lights: Lights):
        self.lights = lights
        graphs = lights.graphs or ()
        self.programs = {i: compile(g, {"surface": "shader"}) for i, g in enumerate(graphs) if g is not None}
        self.has = np.zeros(len(lights), bool)
        self.has[list(self.programs)] = True

    def __bool__(self) -> bool:
        return bool(self.programs)

    def normal(self, i: int, P, wi) -> np.ndarray:
        """Ng (N,3) of points P (N,3) on light i seen along wi (N,3) (the module docstring)."""
        kind, lights = int(self.lights.kind[i]), self.lights
        if kind in (LIGHT_RECT, LIGHT_DISK):
            return np.broadcast_to(-lights.frame[i, 2], P.shape)
        if kind in (LIGHT_POINT, LIGHT_SPOT) and lights.radius[i] > 0 and not lights.soft[i]:
            return normalize(P - lights.position[i])
        return -wi

    def factor(self, i: int, P, wi, t) -> np.ndarray:
        """(N,3) emission of light i's shader at N points P (N,3) on it, seen from receivers
        along unit wi (N,3) (receiver -> light) at distances t (N,) (inf for suns)."""
        if len(P) == 0:
            return np.zeros((0, 3))
        if int(self.lights.kind[i]) == LIGHT_SUN:
            P = -wi
        state = ShadingState(len(P), source=_LightPoints(self.lights, i, P, self.normal(i, P, wi), -wi, t))
        total = np.zeros((len(P), 3))
        for c in closures(self.programs[i].run(state)["surface"]):
            if c.kind in ("emission", "background"):
                total = total + c.weight
        return np.where(np.isfinite(total), total, 0.0)

    def apply(self, index, p, wi, Le, target, finite) -> np.ndarray:
        """Le (N,3) of light samples (lights `index` (N,), receivers p, directions wi, points
        target, finite: not a sun) times their lights' shader factors where they have one."""
        if not self.has[index].any():
            return Le
        Le = np.array(Le, np.float64)
        t = np.where(finite, np.linalg.norm(target - p, axis=1), np.inf)
        for i in np.unique(index[self.has[index]]).tolist():
            rows = np.flatnonzero(index == i)
            Le[rows] *= self.factor(i, target[rows], wi[rows], t[rows])
        return Le
