"""Where film work goes: samples x border pixels in pass-major order (flat path index k:
pass k // pixels, pixel k % pixels), cut into fixed-size batches (cheap; the render process
needs only this when workers trace). An adaptive pass covers only the pixels still active
(engine/adaptive.py): its stage says so (`Stage.active`, the version of the list published to
every process) and k runs over that list instead.
"""
from __future__ import annotations

import numpy as np

from .scene import Scene


class BatchLayout:
    def __init__(self, scene: Scene, batch_size: int | None = None):
        """batch_size: paths per film item (default Settings.batch_size)."""
        s = scene.settings
        self.batch_size = batch_size or s.batch_size
        x0, y0, x1, y1 = s.border
        ys, xs = np.mgrid[y0:y1, x0:x1]
        self.px, self.py = xs.ravel(), ys.ravel()
        self.pixel = self.py * s.width + self.px
        self.n_pixels = len(self.px)
        self.total_paths = s.samples * self.n_pixels
        self.first_path = s.sample_offset * self.n_pixels  # samples [offset, offset + samples)
        self.n_batches = -(-self.total_paths // self.batch_size)
        self.active = (0, None)  # (version, (M,) border-pixel indices) of the adaptive pixel list

    def paths(self, stage, item: int) -> np.ndarray:
        """Flat path indices k of item `item` of a film stage."""
        first = stage.start + item * self.batch_size
        return np.arange(first, min(first + self.batch_size, stage.stop))

    def pixels(self, stage) -> np.ndarray | None:
        """The border-pixel indices a pass of `stage` covers (None: all of them)."""
        if not stage.active:
            return None
        version, active = self.active
        assert version == stage.active, "a stage over an active-pixel list that was not installed"
        return active

    def locate(self, stage, item: int) -> tuple[np.ndarray, np.ndarray]:
        """(j, sample) of item `item`'s paths: j (N,) border-pixel indices (px[j], pixel[j]),
        sample (N,) the pass each path belongs to."""
        k = self.paths(stage, item)
        active = self.pixels(stage)
        if active is None:
            return k % self.n_pixels, k // self.n_pixels
        return active[k % len(active)], k // len(active)

    def install(self, version: int, arrays: dict) -> None:
        if "layout.active" in arrays:
            self.active = (version, arrays["layout.active"])
