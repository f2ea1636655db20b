"""Merging partial renders of one frame: disjoint sample ranges and tiles (render borders).

A render of samples [K, K + N) (Settings.sample_offset) stores, per pixel of its border, the
mean of those N samples. Every sample is a function of (seed, pixel, sample index) only, so the
mean over a union of disjoint ranges is the sample-count-weighted mean of the parts' means:

    merged(p) = sum_i n_i(p) m_i(p) / sum_i n_i(p),    n_i(p) = N_i inside part i's border, else 0

equal to the render of all the samples at once up to float32 rounding of the stored means.
Every channel merges so: colour and alpha (a transparent film's coverage is a mean too), and
each render pass of a multilayer part, with the pass's own inverse where it is not stored as
a plain mean (engine/passes.py: Direct and Indirect are divided by their Color, Depth holds
DEPTH_MISS where no sample hit, the variance of a mean combines with weights n_i^2 / N^2).
The counts and borders come from the parts' EXR metadata (render.py writes them). Parts must
show the same scene and settings (scene digest, engine.scene.scene_digest) and seed, and no
pixel may get the same sample twice.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np

from .passes import COMBINED, DEPTH_MISS, LOBE_CLASSES


class MergeError(ValueError):
    """Parts that cannot be merged: the message names them and says why."""


def _whole(header: dict, key: str, name: str, minimum: int) -> int:
    """A whole-number metadata entry of at least `minimum`, or MergeError naming it."""
    value = header.get(key)
    if value is None:
        raise MergeError(f"{name} has no {key} metadata")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise MergeError(f"{name} has a malformed {key} ({value!r}): expected a whole number") from None
    if not (math.isfinite(number) and number == int(number)):
        raise MergeError(f"{name} has a malformed {key} ({value!r}): expected a whole number")
    if number < minimum:
        raise MergeError(f"{name} has {key} {int(number)}: it must be at least {minimum}")
    return int(number)


def _border(header: dict, name: str, shape: tuple) -> tuple:
    """(x0, y0, x1, y1) pixels of ember/border inside the (H, W) image, or MergeError."""
    text = header.get("ember/border")
    try:
        values = json.loads(text) if isinstance(text, str) else text
        border = tuple(int(v) for v in values)
        if len(border) != 4 or any(b != v for b, v in zip(border, values)):
            raise ValueError
    except (TypeError, ValueError):
        raise MergeError(f"{name} has a malformed ember/border ({text!r}): expected [x0, y0, x1, y1]") from None
    x0, y0, x1, y1 = border
    h, w = shape
    if not (0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h):
        raise MergeError(f"{name} has ember/border {list(border)} outside its {w}x{h} image or empty")
    return border


def _combined_prefix(channels: dict) -> str:
    """'' for a plain RGBA file, '<layer>.Combined.' for a multilayer one."""
    if all(c in channels for c in "RGB"):
        return ""
    layers = sorted({n[:-len(".Combined.R")] for n in channels if n.endswith(".Combined.R")})
    return f"{layers[0]}.{COMBINED.name}." if len(layers) == 1 else ""


@dataclass(frozen=True)
class Part:
    name: str
    channels: dict  # channel name -> (H, W) float32 means, zero outside the border
    prefix: str  # of the Combined channels: '' (R, G, B, A) or '<layer>.Combined.'
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
        prefix = _combined_prefix(channels)
        missing = [c for c in "RGB" if prefix + c not in channels]
        if missing:
            raise MergeError(f"{name} has no {', '.join(prefix + c for c in missing)} channel")
        shape = channels[prefix + "R"].shape
        if any(np.shape(c) != shape for c in channels.values()):
            raise MergeError(f"{name} has channels of different sizes")
        border = _border(header, name, shape)
        for c in channels:
            layer, pass_name = _pass_of(c)
            kind, _, part = pass_name.rpartition(" ")
            if part in ("Direct", "Indirect") and kind in LOBE_CLASSES and f"{layer}{kind} Color.R" not in channels:
                raise MergeError(f"{name} has the {pass_name} pass without {kind} Color, which it is divided by: "
                                 "it cannot be merged exactly (render the parts again with this version)")
        samples = _whole(header, "ember/samples", name, 1)
        offset = _whole(header, "ember/sampleOffset", name, 0)
        seed = _whole(header, "ember/seed", name, 0)
        data = {c: np.asarray(v, np.float32) for c, v in channels.items()}
        if prefix + "A" not in data:  # written before alpha was kept: opaque where rendered
            data[prefix + "A"] = np.zeros(shape, np.float32)
            x0, y0, x1, y1 = border
            data[prefix + "A"][y0:y1, x0:x1] = 1.0
        return cls(name, data, prefix, samples, offset, seed, header["ember/sceneDigest"], border, header)

    @property
    def shape(self) -> tuple:
        return self.channels[self.prefix + "R"].shape

    def weights(self) -> np.ndarray:
        """(H, W) samples per pixel: N inside the border, 0 outside."""
        w = np.zeros(self.shape)
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
        if p.digest != first.digest or p.shape != first.shape:
            raise MergeError(f"{p.name} and {first.name} show different scenes or settings "
                             "(their scene digests differ): parts must come from the same frame of one .blend")
        if set(p.channels) != set(first.channels):
            raise MergeError(f"{p.name} and {first.name} hold different channels or passes: render every part "
                             "with the same passes")
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


def _pass_of(channel: str) -> tuple[str, str]:
    """('<layer>.', pass name) of a multilayer channel '<layer>.<pass>.<c>', ('', '') else."""
    head, _, _ = channel.rpartition(".")
    layer, dot, name = head.rpartition(".")
    return (layer + dot, name) if dot else ("", "")


def _as_mean(channels: dict) -> dict:
    """The channels as plain per-sample means (the inverse of Film.pass_image's forms)."""
    out = dict(channels)
    for c, v in channels.items():
        layer, name = _pass_of(c)
        if name == "Depth":
            out[c] = np.where(v >= DEPTH_MISS, 0.0, v)
        elif name.rsplit(" ", 1)[-1] in ("Direct", "Indirect") and name.split(" ")[0] in LOBE_CLASSES:
            color = channels.get(f"{layer}{name.rsplit(' ', 1)[0]} Color{c[c.rfind('.'):]}")
            if color is not None:
                out[c] = v * color
    return out


def _from_mean(channels: dict) -> dict:
    """Film.pass_image's forms from plain means (after merging)."""
    out = dict(channels)
    for c, v in channels.items():
        layer, name = _pass_of(c)
        if name == "Depth":
            out[c] = np.where(v > 0, v, DEPTH_MISS)
        elif name.rsplit(" ", 1)[-1] in ("Direct", "Indirect") and name.split(" ")[0] in LOBE_CLASSES:
            color = channels.get(f"{layer}{name.rsplit(' ', 1)[0]} Color{c[c.rfind('.'):]}")
            if color is not None:
                out[c] = np.divide(v, color, out=np.zeros_like(v), where=color > 0)
    return out


def merge_channels(parts: list[Part]) -> tuple[dict, dict]:
    """({channel: (H, W) float32}, merged metadata): every channel of the parts merged."""
    _check(parts)
    total = np.zeros(parts[0].shape)
    total_sq = np.zeros(parts[0].shape)
    acc = {c: np.zeros(parts[0].shape) for c in parts[0].channels}
    for p in parts:
        w = p.weights()
        total += w
        total_sq += w * w
        for c, v in _as_mean(p.channels).items():
            weight = w * w if _pass_of(c)[1] == "Debug Variance" else w
            acc[c] += weight * v.astype(np.float64)
    rendered = total > 0
    merged = {}
    for c, a in acc.items():
        norm = total * total if _pass_of(c)[1] == "Debug Variance" else total
        merged[c] = np.where(rendered, a / np.maximum(norm, 1), 0.0)
    merged = {c: v.astype(np.float32) for c, v in _from_mean(merged).items()}
    ys, xs = np.nonzero(rendered)
    counts = np.unique(total[rendered])
    header = {k: v for k, v in parts[0].header.items() if k.startswith("ember/")}
    header.update({
        "ember/samples": int(counts.min()) if len(counts) else 0,
        "ember/sampleOffset": min(p.offset for p in parts),
        "ember/sampleRange": _ranges(parts),
        "ember/renderSeconds": float(sum(_seconds(p.header) for p in parts)),
        "ember/border": [int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1] if len(xs) else [0, 0, 0, 0],
        "ember/mergedParts": len(parts),
    })
    if len(counts) > 1:
        header["ember/samplesPerPixel"] = f"{int(counts.min())}..{int(counts.max())} (parts cover pixels unequally)"
    return merged, header


def _seconds(header: dict) -> float:
    try:
        value = float(header.get("ember/renderSeconds", 0.0))
    except (TypeError, ValueError):
        return 0.0
    return value if math.isfinite(value) else 0.0


def merge(parts: list[Part]) -> tuple[np.ndarray, dict]:
    """(H, W, 4) float32 RGBA of the parts' Combined channels and the merged metadata."""
    channels, header = merge_channels(parts)
    prefix = parts[0].prefix
    return np.stack([channels[prefix + c] for c in "RGBA"], axis=-1), header
