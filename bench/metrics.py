"""Error of a render against a reference: relMSE, RMSE, HDR-FLIP, NaN count.

relMSE uses EPS = 1e-2 (engine/metrics.py; stated in every table and plot) and no outlier
rejection. A reference is itself a noisy mean; its own expected relMSE,
mean(var_ref / (ref^2 + EPS)), adds to every measured value in expectation (the two are
independent), so tables give it and `relmse_corrected` subtracts it: that is the error
against the true image, unbiased, and it can come out slightly negative when the render is as
good as the reference. HDR-FLIP (NVIDIA's `flip-evaluator`, 67 pixels per degree, exposure
range chosen from the reference) sees linear, non-negative, finite RGB.
"""
from __future__ import annotations

import numpy as np

from ember.engine.metrics import EPS, rel_mse

__all__ = ["EPS", "rel_mse", "reference_rel_mse", "rmse", "hdr_flip", "nan_count", "evaluate"]


def reference_rel_mse(reference: np.ndarray, variance: np.ndarray) -> float:
    """The reference's own expected relMSE from the variance of its mean (H,W,3)."""
    r = np.asarray(reference, np.float64)
    return float(np.mean(np.asarray(variance, np.float64) / (r * r + EPS)))


def rmse(image: np.ndarray, reference: np.ndarray) -> float:
    """Root mean squared error, in the image's units (non-finite values count as 0)."""
    x = np.nan_to_num(np.asarray(image, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    return float(np.sqrt(np.mean((x - np.asarray(reference, np.float64)) ** 2)))


def _flip_input(image) -> np.ndarray:
    x = np.nan_to_num(np.asarray(image, np.float32), nan=0.0, posinf=0.0, neginf=0.0)
    return np.ascontiguousarray(np.maximum(x, 0.0))


def hdr_flip(image: np.ndarray, reference: np.ndarray) -> float:
    """Mean HDR-FLIP error of image against reference, both (H,W,3) linear RGB."""
    import flip_evaluator
    _, mean, _ = flip_evaluator.evaluate(_flip_input(reference), _flip_input(image), "HDR",
                                         applyMagma=False)
    return float(mean)


def nan_count(image: np.ndarray) -> int:
    """Pixels with any non-finite channel."""
    return int((~np.isfinite(np.asarray(image))).any(axis=-1).sum())


def evaluate(image: np.ndarray, reference: np.ndarray, variance=None) -> dict:
    """All metrics of an (H,W,3) image; the variance of the reference's mean (optional) gives
    the reference's own relMSE and the corrected relMSE."""
    out = {"relmse": rel_mse(image, reference), "rmse": rmse(image, reference),
           "flip": hdr_flip(image, reference), "nan": nan_count(image)}
    if variance is not None:
        out["relmse_ref"] = reference_rel_mse(reference, variance)
        out["relmse_corrected"] = out["relmse"] - out["relmse_ref"]
    return out
