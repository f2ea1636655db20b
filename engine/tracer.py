"""Work layout and batch tracing.

`BatchLayout`: the render's work is samples x border pixels in pass-major order, cut into
fixed-size batches (cheap; the render process needs only this when workers trace).
`BatchTracer`: everything built once to trace batches - Embree scene, lights, integrator -
in the render process or, identically, in every worker process.
"""
from __future__ import annotations

import numpy as np

from .accel import Accel
from .allocator import keep_freed_memory
from .integrators.path import PathTracer
from .lights.light_set import LightSet
from .rng import Sampler
from .scene import Scene


class BatchLayout:
    def __init__(self, scene: Scene):
        s = scene.settings
        self.batch_size = s.batch_size
        x0, y0, x1, y1 = s.border
        ys, xs = np.mgrid[y0:y1, x0:x1]
        self.px, self.py = xs.ravel(), ys.ravel()
        self.pixel = self.py * s.width + self.px
        self.n_pixels = len(self.px)
        self.total_paths = s.samples * self.n_pixels
        self.n_batches = -(-self.total_paths // s.batch_size)

    def batch_paths(self, batch: int) -> np.ndarray:
        """Flat work indices k (pass = k // n_pixels, pixel = k % n_pixels) of a batch."""
        return np.arange(batch * self.batch_size, min((batch + 1) * self.batch_size, self.total_paths))


class BatchTracer:
    def __init__(self, scene: Scene):
        keep_freed_memory()  # in whichever process traces
        s = scene.settings
        self.scene = scene
        self.layout = BatchLayout(scene)
        self.accel = Accel(scene.mesh)
        self.lights = LightSet(scene.lights, scene.mesh, scene.materials, scene.world, self.accel,
                               self.accel.scene_radius, s.strategy)
        self.integrator = PathTracer(scene, self.accel, self.lights)

    def trace(self, batch: int, stop=None) -> np.ndarray:
        """Radiance (N,3) of the batch's paths."""
        layout = self.layout
        k = layout.batch_paths(batch)
        j = k % layout.n_pixels
        s = self.scene.settings
        sampler = Sampler(s.seed, layout.pixel[j], k // layout.n_pixels, s.pattern)
        return self.integrator.render(sampler, layout.px[j], layout.py[j], stop)
