"""Adaptive sampling per pixel, as Cycles decides it (intern/cycles: integrator.cpp
get_adaptive_sampling, film/adaptive_sampling.h).

Samples of a pixel fall into two classes (class A: an odd number of ones in the odd bits of
the sample index; Christensen et al., "Progressive Multi-Jittered Sample Sequences", 2018,
section 10.2.1 - each class of an aligned block of 2^k Sobol samples is itself well spread).
The film keeps twice the sum of the class-A samples beside the sum of all of them, so per
pixel, with n samples, I their sum and A twice the class-A sum,

    error = sum_c |I_c - A_c| / n  /  (1e-4 + sqrt(sum_c I_c / n))

is the half-difference of the two half-buffers' means, relative to the square root of the
pixel's brightness. A pixel converges when error < 5 x threshold (Cycles' scale factor).

The check runs only at pass boundaries - at the first multiple of STEP from `min_samples`
on, then every STEP passes - on the film of exactly those passes, so which pixels stay active
depends only on the pass count, never on timing or the number of workers. One difference from
Cycles: once few pixels are active, checks come less often (every power of two >= STEP
passes that gives CHECK_PATHS paths between checks), because a work item has a fixed cost
in Python and a few hundred pixels x 16 passes would be mostly that (measured in
bench/results/adaptive/report.md); the interval depends only on the number of active pixels,
so images still depend only on the pass count. A converged pixel is not checked again, but
every pixel within one pixel (3x3) of an active one is active (Cycles' filter_x / filter_y),
so edges of noisy regions keep sampling.
"""
from __future__ import annotations

import math

import numpy as np

STEP = 16  # passes between checks (Cycles' adaptive_step)
CHECK_PATHS = 1 << 16  # paths between checks at least, once few pixels are active
ERROR_SCALE = 5.0  # Cycles: "threshold *= 5", so thresholds read like its older ones


def class_a(sample: int) -> bool:
    """Whether sample index `sample` is in half-buffer A (parity of its odd bits)."""
    return bool(bin(int(sample) & 0xAAAAAAAA).count("1") & 1)


def threshold(settings) -> float:
    """The noise threshold; 0 means automatic from the sample count (Cycles:
    max(0.001, 1 / samples))."""
    t = settings.adaptive_threshold
    return t if t > 0 else max(0.001, 1.0 / max(settings.samples, 1))


def min_samples(settings) -> int:
    """Passes before the first check; 0 means automatic (Cycles: 16 / threshold^0.3, so
    0.1 -> 32, 0.01 -> 64, 0.001 -> 128), and never fewer than 4."""
    if settings.adaptive_min_samples > 0:
        return max(4, settings.adaptive_min_samples)
    return max(4, math.ceil(16.0 / threshold(settings) ** 0.3))


def first_check(min_samples: int) -> int:
    """The pass count of the first check: the first multiple of STEP from min_samples on."""
    return -(-min_samples // STEP) * STEP


def next_check(passes: int, active: int) -> int:
    """The pass count of the check after the one at `passes` that left `active` pixels."""
    step = STEP
    while step * active < CHECK_PATHS:
        step *= 2
    return (passes // step + 1) * step


def pixel_error(sum_all: np.ndarray, sum_a2: np.ndarray, count: np.ndarray) -> np.ndarray:
    """Cycles' per-pixel error (module docstring); sum_all, sum_a2 (N,3), count (N,)."""
    n = np.maximum(count, 1).astype(np.float64)
    difference = np.abs(sum_all - sum_a2).sum(axis=1) / n
    brightness = np.sqrt(np.maximum(sum_all.sum(axis=1), 0.0) / n)
    return difference / (1e-4 + brightness)


def dilate(mask: np.ndarray) -> np.ndarray:
    """3x3 dilation of a (H, W) bool mask (a row pass, then a column pass)."""
    out = mask.copy()
    out[:, 1:] |= mask[:, :-1]
    out[:, :-1] |= mask[:, 1:]
    rows = out.copy()
    out[1:] |= rows[:-1]
    out[:-1] |= rows[1:]
    return out


class ActivePixels:
    """Which border pixels an adaptive render still samples (render process)."""

    def __init__(self, settings, layout):
        x0, y0, x1, y1 = settings.border
        self.shape = (y1 - y0, x1 - x0)
        self.pixel = layout.pixel  # border index -> film pixel
        self.threshold = ERROR_SCALE * threshold(settings)
        self.first = min_samples(settings)
        self.converged = np.zeros(layout.n_pixels, bool)

    def update(self, film) -> np.ndarray:
        """Check the pixels not yet converged on `film`; the border indices still active."""
        check = np.flatnonzero(~self.converged)
        p = self.pixel[check]
        self.converged[check] = pixel_error(film.sum[p], film.sum_a[p], film.count[p]) < self.threshold
        active = dilate(~self.converged.reshape(self.shape)).ravel()
        self.converged = ~active
        return np.flatnonzero(active)
