"""Merging partial renders of one frame: disjoint sample ranges and tiles (render borders).

A render of samples [K, K + N) (Settings.sample_offset) stores, per pixel of its border, the
mean of those N samples. Every sample is a function of (seed, pixel, sample index) only, so the
mean over a union of disjoint ranges is the sample-count-weighted mean of the parts' means:

    merged(p) = sum_i n_i(p) m_i(p) / sum_i n_i(p),    n_i(p) = N_i inside part i's border, else 0

equal to the render of all the samples at once up to float32 rounding of the stored means.
The counts and borders come from the parts' EXR metadata (render.py writes them). Parts must
show the same scene and settings (scene digest, engine.scene.scene_digest) and seed, and no
pixel may get the same sample twice.
"""
from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np


class MergeError(ValueError):
    """Parts that cannot be merged: the message names them and says why."""


@dataclass(frozen=True)
class Part:
    name: str
    rgb: np.ndarray  # (H, W, 3) float32 means, zero outside the border
    samples: int
    offset: int
    seed: int
    digest: str
    border: tuple  # (x0, y0, x1, y1) pixels, top-left origin, half-open
    header: dict

    @classmethod
    def from_exr(cls, name: str, channels: dict, header: dict) -> "Part":
        if header.get("ember/engine") != "Ember" or "ember/sceneDigest" not in header:
            raise MergeError(f"{name} is not a render.py EXR (it has no Ember metadata)")
        if "ember/crop" in header:
            raise MergeError(f"{name} is cropped to its render border: render tiles without "
                             "'crop to render region' to merge them")
        stopped = header.get("ember/stoppedBy", "done")
        if stopped != "done":
            raise MergeError(f"{name} stopped early ({stopped}): its pixels have unequal sample counts")
        if "ember/samplesPerPixel" in header or str(header.get("ember/sampleRange", "")).count("[") > 1:
            raise MergeError(f"{name} is a merge whose pixels or sample ranges are uneven: merge its parts instead")
        if not header["ember/sceneDigest"]:
            raise MergeError(f"{name} has no scene digest")
        missing = [c for c in "RGB" if c not in channels]
        if missing:
            raise MergeError(f"{name} has no {', '.join(missing)} channel")
        rgb = np.stack([channels[c] for c in "RGB"], axis=-1).astype(np.float32)
        border = tuple(int(v) for v in json.loads(header["ember/border"]))
        return cls(name, rgb, int(header["ember/samples"]), int(header["ember/sampleOffset"]),
                   int(header["ember/seed"]), header["ember/sceneDigest"], border, header)

    def weights(self) -> np.ndarray:
        """(H, W) samples per pixel: N inside the border, 0 outside."""
        w = np.zeros(self.rgb.shape[:2])
        x0, y0, x1, y1 = self.border
        w[y0:y1, x0:x1] = self.samples
        return w


def _check(parts: list[Part]) -> None:
    if not parts:
        raise MergeError("nothing to merge")
    first = parts[0]
    for p in parts[1:]:
        if p.seed != first.seed:
            raise MergeError(f"{p.name} has seed {p.seed} but {first.name} seed {first.seed}: parts of one "
                             "frame must share the seed (they are different sample sequences)")
        if p.digest != first.digest or p.rgb.shape != first.rgb.shape:
            raise MergeError(f"{p.name} and {first.name} show different scenes or settings "
                             "(their scene digests differ): parts must come from the same frame of one .blend")
    for i, a in enumerate(parts):
        for b in parts[i + 1:]:
            ax0, ay0, ax1, ay1 = a.border
            bx0, by0, bx1, by1 = b.border
            pixels_shared = ax0 < bx1 and bx0 < ax1 and ay0 < by1 and by0 < ay1
            samples_shared = a.offset < b.offset + b.samples and b.offset < a.offset + a.samples
            if pixels_shared and samples_shared:
                raise MergeError(f"{a.name} (samples [{a.offset}, {a.offset + a.samples})) and {b.name} "
                                 f"(samples [{b.offset}, {b.offset + b.samples})) took the same samples of "
                                 "the same pixels: give each part its own --sample-offset range")


def _ranges(parts: list[Part]) -> str:
    """The union of the parts' sample ranges as text, e.g. '[0, 64)' or '[0, 16) [32, 48)'."""
    spans = sorted({(p.offset, p.offset + p.samples) for p in parts})
    merged = [list(spans[0])]
    for a, b in spans[1:]:
        if a <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], b)
        else:
            merged.append([a, b])
    return " ".join(f"[{a}, {b})" for a, b in merged)


def merge(parts: list[Part]) -> tuple[np.ndarray, dict]:
    """(H, W, 4) float32 RGBA (alpha 1 where any part rendered) and the merged metadata."""
    _check(parts)
    total = np.zeros(parts[0].rgb.shape[:2])
    acc = np.zeros(parts[0].rgb.shape)
    for p in parts:
        w = p.weights()
        total += w
        acc += w[..., None] * p.rgb.astype(np.float64)
    rgba = np.zeros(parts[0].rgb.shape[:2] + (4,), np.float32)
    rendered = total > 0
    rgba[..., :3] = np.where(rendered[..., None], acc / np.maximum(total, 1)[..., None], 0.0)
    rgba[..., 3] = rendered
    ys, xs = np.nonzero(rendered)
    counts = np.unique(total[rendered])
    header = {k: v for k, v in parts[0].header.items() if k.startswith("ember/")}
    header.update({
        "ember/samples": int(counts.min()) if len(counts) else 0,
        "ember/sampleOffset": min(p.offset for p in parts),
        "ember/sampleRange": _ranges(parts),
        "ember/renderSeconds": float(sum(float(p.header.get("ember/renderSeconds", 0.0)) for p in parts)),
        "ember/border": [int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1] if len(xs) else [0, 0, 0, 0],
        "ember/mergedParts": len(parts),
    })
    if len(counts) > 1:
        header["ember/samplesPerPixel"] = f"{int(counts.min())}..{int(counts.max())} (parts cover pixels unequally)"
    return rgba, header
