"""Film: per-pixel running sums of radiance samples, full frame, rows from the top.

Filter importance sampling puts each sample into exactly one pixel with weight 1, so a
pixel's value is the plain mean of its samples and its variance is the sample variance
(the statistical tests use it).

The noise estimate compares blocks of passes: at every power of two M of completed passes,
the mean of passes [0, M/2) against that of [M/2, M). Their half-difference estimates the
error of the M-pass mean for any sample pattern - Sobol's aligned blocks of 2^k samples are
each a well-stratified net, while the sample variance ignores that stratification and
overstates Sobol's error. Between powers of two the estimate
is scaled by sqrt(M / N), the slowest (independent-sample) rate.

With adaptive sampling pixels have different sample counts, so the blocks of passes do not
line up; the film then also keeps twice the sum of each pixel's class-A samples (half of
every aligned block of four, engine/adaptive.py), and |2 sum_A - sum| / n, the half-difference
of the two half-buffers' means, is each pixel's error estimate (Cycles' adaptive sampling
uses the same buffer).
"""
from __future__ import annotations

import threading

import numpy as np

from . import passes as passes_mod


class Film:
    def __init__(self, width: int, height: int, passes: tuple = (), transparent: bool = False,
                 adaptive: bool = False):
        """passes: render pass names (engine/passes.py) besides Combined; transparent: alpha is
        the mean of the samples' "alpha" (film transparency), else 1 where sampled; adaptive:
        keep the class-A half buffer (adaptive sampling)."""
        self.width, self.height = width, height
        # Per-pass running sums (H*W, channels) of what the samples return under that name;
        # debug passes are derived from the radiance sums.
        self.pass_sum = {name: np.zeros((height * width, passes_mod.BY_NAME[name].channels))
                         for name in passes_mod.needed(passes) if passes_mod.BY_NAME[name].group != "debug"}
        self.passes_wanted = tuple(passes)
        if transparent:
            self.pass_sum["alpha"] = np.zeros((height * width, 1))
        self.sum = np.zeros((height * width, 3))
        self.sum_sq = np.zeros((height * width, 3))
        self.count = np.zeros(height * width, np.int64)
        self.nonfinite = 0  # samples dropped because they were NaN/Inf (should stay 0)
        self._lock = threading.Lock()
        self.passes = 0  # completed passes (end_pass)
        self._snapshot = None  # (passes, sum) at the last power of two; float32 halves its memory
        self._block_noise = None  # (M, noise of the M-pass mean) from the last two snapshots
        # (H*W,3) radiance added to the mean (an integrator's term that is not a mean of
        # samples: progressive photon mapping's photon estimate), or None.
        self.overlay = None
        self.sum_a = np.zeros((height * width, 3)) if adaptive else None  # 2 x sum of class-A samples

    def add(self, pixel: np.ndarray, L: np.ndarray, passes: dict | None = None, class_a: bool = False) -> None:
        """Add one sample per entry; pixel (N,) flat indices (unique within one call); passes:
        name -> (N, channels) values of the same samples (names the film does not keep are
        ignored); class_a: the samples are of class A (adaptive.class_a of their pass)."""
        finite = np.isfinite(L)
        bad = 0
        if not finite.all():
            rows = ~finite.all(axis=1)
            bad = int(rows.sum())
            L = np.where(rows[:, None], 0.0, L)
        # A pass over a full frame (or a border row) is a run of consecutive pixels: slices
        # then replace the much slower fancy-indexed read-modify-write.
        if len(pixel) and pixel[-1] - pixel[0] == len(pixel) - 1 and np.all(np.diff(pixel) == 1):
            pixel = slice(int(pixel[0]), int(pixel[-1]) + 1)
        with self._lock:
            self.nonfinite += bad
            self.sum[pixel] += L
            self.sum_sq[pixel] += L * L
            self.count[pixel] += 1
            for name, values in (passes or {}).items():
                acc = self.pass_sum.get(name)
                if acc is not None:
                    acc[pixel] += np.where(np.isfinite(values), values, 0.0).reshape(len(L), -1)
            if class_a and self.sum_a is not None:
                self.sum_a[pixel] += 2.0 * L

    def mean(self) -> np.ndarray:
        """(H,W,3) float64 mean radiance (0 where no samples)."""
        with self._lock:
            m = self.sum / np.maximum(self.count, 1)[:, None]
            if self.overlay is not None:
                m += self.overlay
        return m.reshape(self.height, self.width, 3)

    def variance_of_mean(self) -> np.ndarray:
        """(H,W,3) estimated variance of each pixel's mean (inf with < 2 samples)."""
        with self._lock:
            n = self.count[:, None].astype(np.float64)
            mean = self.sum / np.maximum(n, 1)
            var = (self.sum_sq - n * mean * mean) / np.maximum(n - 1, 1)
            v = np.where(n >= 2, np.maximum(var, 0.0) / np.maximum(n, 1), np.inf)
        return v.reshape(self.height, self.width, 3)

    def image(self) -> np.ndarray:
        """(H,W,4) float32 RGBA, alpha 1 where sampled (transparent film: the share of camera
        rays that hit something; the colour is then premultiplied, as Cycles')."""
        rgba = np.zeros((self.height, self.width, 4), np.float32)
        rgba[..., :3] = self.mean()
        if "alpha" in self.pass_sum:
            rgba[..., 3] = self._mean_of("alpha")[..., 0]
        else:
            rgba[..., 3] = (self.count.reshape(self.height, self.width) > 0)
        return rgba

    def _mean_of(self, name: str) -> np.ndarray:
        with self._lock:
            m = self.pass_sum[name] / np.maximum(self.count, 1)[:, None]
        return m.reshape(self.height, self.width, -1)

    def pass_image(self, name: str) -> np.ndarray:
        """(H,W,channels) float32 pass `name` as Blender defines it (engine/passes.py)."""
        if name == passes_mod.COMBINED.name:
            return self.image()
        shape = (self.height, self.width, -1)
        if name == "Debug Sample Count":  # as Cycles: the share of the samples taken (1 = all)
            return (self.count / max(int(self.count.max()), 1)).reshape(shape).astype(np.float32)
        if name == "Debug Variance":
            v = self.variance_of_mean()
            v = np.where(np.isfinite(v), v, 0.0).mean(axis=2, keepdims=True)
            return v.astype(np.float32)
        m = self._mean_of(name)
        if name == "Depth":  # Cycles' value where no sample hit anything
            return np.where(m > 0, m, passes_mod.DEPTH_MISS).astype(np.float32)
        part = name.rsplit(" ", 1)[-1]
        if part in ("Direct", "Indirect"):  # stored divided by the colour, as Cycles
            color = self._mean_of(name.rsplit(" ", 1)[0] + " Color")
            m = np.divide(m, color, out=np.zeros_like(m), where=color > 0)
        return m.astype(np.float32)

    def end_pass(self, passes: int) -> None:
        """Passes 0 .. passes-1 are complete on every rendered pixel."""
        self.passes = passes
        if passes & (passes - 1):
            return  # not a power of two
        with self._lock:
            if self._snapshot is not None and self._snapshot[0] * 2 == passes:
                half = passes // 2
                first = self._snapshot[1].astype(np.float64) / half
                second = (self.sum - self._snapshot[1]) / half
                self._block_noise = (passes, _relative_rms(0.5 * (first + second), 0.25 * (first - second) ** 2,
                                                           self.count > 0))
            self._snapshot = (passes, self.sum.astype(np.float32))

    def noise(self) -> float:
        """Relative noise estimate of the image: RMS over pixels of the estimated error of the
        mean over (mean + 0.01). From blocks of passes (see the module docstring) once four
        passes are complete, before that from the sample variance within each pixel."""
        if self.sum_a is not None and self.passes >= 4:
            with self._lock:
                n = np.maximum(self.count, 1)[:, None]
                mean, err = self.sum / n, (self.sum_a - self.sum) / n
            return _relative_rms(mean, err * err, self.count > 0)
        if self._block_noise is not None and self.passes >= 4:
            m, e = self._block_noise
            return float(e * np.sqrt(m / self.passes))
        return _relative_rms(self.mean().reshape(-1, 3), self.variance_of_mean().reshape(-1, 3), self.count > 0)


def _relative_rms(mean: np.ndarray, err2: np.ndarray, rendered: np.ndarray) -> float:
    """sqrt(mean over rendered pixels with finite err2 of err2 / (mean + 0.01)^2), channel-averaged."""
    m = (mean[:, 0] + mean[:, 1] + mean[:, 2]) / 3.0
    v = (err2[:, 0] + err2[:, 1] + err2[:, 2]) / 3.0
    ok = rendered & np.isfinite(v)
    if not ok.any():
        return float("inf")
    return float(np.sqrt(np.mean(v[ok] / (m[ok] + 1e-2) ** 2)))
