"""Image regions the bench reports separately: the caustic under the glass sphere.

A region is a boolean (H,W) mask made once from the *reference* by a fixed rule, so every
renderer is measured on the same pixels and anyone re-running the bench gets the same mask:

1. the caustic's seed pixel (row, column) is fixed per scene in CAUSTIC_SEEDS: where the line
   from the light's centre through the glass sphere's centre meets the floor, seen by the
   camera (caustic.blend and caustic_point.blend share geometry and camera, so one seed);
2. the lit floor's level is the LEVEL_PERCENTILE-th percentile of the reference's luminance
   in a square of half-size WINDOW around the seed (the window holds the sphere's shadow,
   the lit floor and the sphere's foot; the caustic is a few % of it, so the percentile is
   the lit floor's brightness, not the caustic's);
3. the region is the 8-connected set of pixels whose reference luminance exceeds FACTOR x
   that level and that contains the brightest such pixel within SEARCH pixels of the seed.

Metrics inside the region (`region_metrics`): relMSE over the region's pixels and channels
(the same formula as the whole image: mean((x - r)^2 / (r^2 + EPS))), the same with the
reference's own expected relMSE there subtracted, and the ratio of the region's mean
(all channels) to the reference's: the caustic's energy, the figure the 3 % target is
about.
"""
from __future__ import annotations

import numpy as np

from .metrics import EPS, rel_mse

FACTOR = 2.0
LEVEL_PERCENTILE = 90.0
WINDOW = 12
SEARCH = 5
# (row from the top, column) at 64x64: the floor point (-0.375, -0.292, 0) on the line from
# the light (0.9, 0.7, 1.7) through the sphere's centre (0, 0, 0.501), projected by the
# scenes' camera; checked against the reference (the caustic's brightest pixels are there).
CAUSTIC_SEEDS = {"caustic": (40, 28), "caustic_point": (40, 28)}
CAUSTIC_SCENES = tuple(CAUSTIC_SEEDS)


def luminance(image) -> np.ndarray:
    return np.asarray(image, np.float64).mean(axis=-1)


def _component(mask: np.ndarray, start) -> np.ndarray:
    """8-connected component of `mask` containing `start` (flood fill, no SciPy needed)."""
    out = np.zeros_like(mask)
    stack = [tuple(start)]
    h, w = mask.shape
    while stack:
        r, c = stack.pop()
        if not (0 <= r < h and 0 <= c < w) or out[r, c] or not mask[r, c]:
            continue
        out[r, c] = True
        stack.extend((r + dr, c + dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if dr or dc)
    return out


def bright_region(reference, seed, factor=FACTOR, window=WINDOW, search=SEARCH,
                  percentile=LEVEL_PERCENTILE) -> np.ndarray:
    """The rule above on an (H,W,3) or (H,W) reference; an empty mask when no pixel within
    `search` of `seed` exceeds factor x the window's level."""
    lum = luminance(reference) if np.ndim(reference) == 3 else np.asarray(reference, np.float64)
    h, w = lum.shape
    r0, c0 = seed
    win = lum[max(r0 - window, 0):r0 + window + 1, max(c0 - window, 0):c0 + window + 1]
    level = float(np.percentile(win, percentile))
    bright = lum > factor * level
    rs, cs = np.mgrid[max(r0 - search, 0):min(r0 + search + 1, h), max(c0 - search, 0):min(c0 + search + 1, w)]
    near = bright[rs, cs]
    if not near.any():
        return np.zeros_like(bright)
    k = np.argmax(np.where(near, lum[rs, cs], -np.inf))
    return _component(bright, (rs.flat[k], cs.flat[k]))


def caustic_region(scene_name: str, reference) -> np.ndarray | None:
    """The caustic mask of a bench scene from its reference, None for scenes without one."""
    seed = CAUSTIC_SEEDS.get(scene_name)
    if seed is None:
        return None
    h = np.shape(reference)[0]
    scale = h / 64.0  # seeds are given at the bench's 64x64
    return bright_region(reference, (int(seed[0] * scale), int(seed[1] * scale)))


def region_metrics(image, reference, mask, variance=None) -> dict:
    """relMSE inside `mask`, the same less the reference's own expected relMSE there, and the
    region's mean over the reference's (non-finite pixels count as 0)."""
    x = np.nan_to_num(np.asarray(image, np.float64), nan=0.0, posinf=0.0, neginf=0.0)[mask]
    r = np.asarray(reference, np.float64)[mask]
    out = {"pixels": int(mask.sum()),
           "relmse": rel_mse(image, reference, mask),
           "mean_ratio": float(x.mean() / r.mean()) if r.mean() > 0 else float("nan")}
    if variance is not None:
        ref_own = float(np.mean(np.asarray(variance, np.float64)[mask] / (r * r + EPS)))
        out["relmse_ref"] = ref_own
        out["relmse_corrected"] = out["relmse"] - ref_own
        # the reference's own uncertainty of the region mean, relative (1 sigma)
        out["ref_mean_rel_sigma"] = float(np.sqrt(np.asarray(variance, np.float64)[mask].sum()) / r.sum())
    return out
