"""Image error against a reference: relative MSE, the metric Ember reports and bench plots.

    relMSE = mean over pixels and channels of (x - r)^2 / (r^2 + EPS)

EPS = 1e-2 stabilises dark pixels of [0,1]-scaled images (algorithms.md section 3 pins it
and asks that it be stated next to every number). No outlier rejection: fireflies count.
"""
from __future__ import annotations

import numpy as np

EPS = 1e-2


def rel_mse(image: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None) -> float:
    """relMSE of image against reference, both (H,W,C) linear; mask (H,W) bool selects the
    pixels that count (None = all). Non-finite image values count as 0."""
    x = np.nan_to_num(np.asarray(image, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    r = np.asarray(reference, np.float64)
    err = (x - r) ** 2 / (r * r + EPS)
    if mask is not None:
        err = err[mask]
    return float(np.mean(err)) if err.size else float("nan")
