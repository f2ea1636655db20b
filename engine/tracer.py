"""Everything built once per render to trace batches: Embree scene, lights, integrator,
and the batch layout (samples x border pixels in pass-major order, fixed-size batches).

Used in the render process and, identically, in every worker process.
"""
from __future__ import annotations

import numpy as np

from .accel import Accel
from .integrators.path import PathTracer
from .lights.light_set import LightSet
from .rng import Sampler
from .scene import Scene


class BatchTracer:
    def __init__(self, scene: Scene):
        s = scene.settings
        self.scene = scene
        self.accel = Accel(scene.mesh)
        self.lights = LightSet(scene.lights, scene.mesh, scene.materials, scene.world, self.accel,
                               self.accel.scene_radius, s.strategy)
        self.integrator = PathTracer(scene, self.accel, self.lights)
        x0, y0, x1, y1 = s.border
        ys, xs = np.mgrid[y0:y1, x0:x1]
        self.px, self.py = xs.ravel(), ys.ravel()
        self.pixel = self.py * s.width + self.px
        self.n_pixels = len(self.px)
        self.total_paths = s.samples * self.n_pixels
        self.n_batches = -(-self.total_paths // s.batch_size)

    def batch_paths(self, batch: int) -> np.ndarray:
        """Flat work indices k (pass = k // n_pixels, pixel = k % n_pixels) of a batch."""
        b = self.scene.settings.batch_size
        return np.arange(batch * b, min((batch + 1) * b, self.total_paths))

    def trace(self, batch: int, stop=None) -> np.ndarray:
        """Radiance (N,3) of the batch's paths."""
        k = self.batch_paths(batch)
        j = k % self.n_pixels
        sampler = Sampler(self.scene.settings.seed, self.pixel[j], k // self.n_pixels)
        return self.integrator.render(sampler, self.px[j], self.py[j], stop)
