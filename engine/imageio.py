"""EXR reading and writing on the `OpenEXR` Python package (v3 API, `OpenEXR.File`).

Row order: arrays are **top-down**, row 0 = top of the image. That is how EXR itself
stores scanlines (y grows downwards, line order INCREASING_Y), so no flip happens here.
Blender's render-result `rect` is bottom-up; flip with `np.flipud` at that boundary only.

Pixels are float32 (FLOAT) unless a channel is asked for as half (HALF, float16).
Files are single-part scanline images, ZIP compressed (lossless).

Header attributes (`header=` of `write_exr`): str stays a string attribute; bool and int
(within int32) become int attributes; float becomes an EXR float attribute, which is
**float32** (OpenEXR's Python binding has no scalar double) - pass a string when more
digits matter; lists, tuples and dicts are stored as JSON strings; other ints as strings.
Names the EXR format owns (channels, compression, dataWindow, ...) cannot be set.
"""
from __future__ import annotations

import json
import os
from typing import Iterable

import numpy as np

__all__ = ["write_exr", "read_exr", "write_rgba_exr", "read_rgb"]

# Attributes that write_exr sets itself or the format derives from the pixels.
_RESERVED = {"channels", "compression", "dataWindow", "displayWindow", "lineOrder",
             "pixelAspectRatio", "screenWindowCenter", "screenWindowWidth", "type",
             "tiles", "name", "version", "chunkCount"}

_INT32 = (-(2 ** 31), 2 ** 31 - 1)


def _openexr():
    import OpenEXR  # imported lazily: only I/O needs it
    return OpenEXR


def _attribute(key: str, value):
    """Python value -> something the OpenEXR binding stores without loss of type."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, int):
        return value if _INT32[0] <= value <= _INT32[1] else str(value)
    if isinstance(value, float):
        return value
    if isinstance(value, (list, tuple, dict)):
        return json.dumps(value)
    raise TypeError(f"EXR header attribute {key!r}: unsupported type {type(value).__name__}")


def write_exr(path: str | os.PathLike, channels: dict[str, np.ndarray],
              header: dict | None = None, half: bool | Iterable[str] = False) -> None:
    """Write a single-part scanline EXR.

    channels: name -> (H, W) array, top-down rows (row 0 = top); all the same shape.
        Names are free ("R", "G", "B", "A", "var.R", "Depth.Z", ...).
    header: extra attributes, converted as the module docstring says.
    half: True to store every channel as half (float16), or an iterable of channel
        names to store as half; the rest are float32. Values are converted, not clipped
        (half overflows to inf above 65504).
    """
    exr = _openexr()
    if not channels:
        raise ValueError("write_exr: no channels")
    half_names = set(channels) if half is True else set(half or ())
    unknown = half_names - set(channels)
    if unknown:
        raise ValueError(f"write_exr: half requested for unknown channels {sorted(unknown)}")
    shape = None
    pixels = {}
    for name, arr in channels.items():
        a = np.asarray(arr)
        if a.ndim != 2:
            raise ValueError(f"write_exr: channel {name!r} has shape {a.shape}, want (H, W)")
        if shape is None:
            shape = a.shape
        elif a.shape != shape:
            raise ValueError(f"write_exr: channel {name!r} has shape {a.shape}, others {shape}")
        dtype = np.float16 if name in half_names else np.float32
        pixels[name] = np.ascontiguousarray(a, dtype=dtype)
    attrs = {"compression": exr.ZIP_COMPRESSION, "type": exr.scanlineimage}
    for key, value in (header or {}).items():
        if key in _RESERVED:
            raise ValueError(f"write_exr: header attribute {key!r} is reserved")
        attrs[key] = _attribute(key, value)
    with exr.File(attrs, pixels) as f:
        f.write(str(path))


def read_exr(path: str | os.PathLike) -> tuple[dict[str, np.ndarray], dict]:
    """Read the first part of an EXR.

    Returns (channels, header): channels maps each channel name to an (H, W) array,
    top-down rows, dtype float32 for FLOAT channels and float16 for HALF (uint32 for
    UINT); header is the attribute dict as the OpenEXR binding returns it (strings,
    ints, floats, plus the format's own entries such as 'dataWindow').
    """
    exr = _openexr()
    with exr.File(str(path), separate_channels=True) as f:
        header = dict(f.header())
        channels = {name: np.array(ch.pixels, copy=True) for name, ch in f.channels().items()}
    return channels, header


def write_rgba_exr(path: str | os.PathLike, image: np.ndarray, header: dict | None = None,
                   half: bool = False) -> None:
    """Write an (H, W, 4) RGBA or (H, W, 3) RGB image (top-down rows) as channels R,G,B[,A]."""
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] not in (3, 4):
        raise ValueError(f"write_rgba_exr: image shape {img.shape}, want (H, W, 3|4)")
    names = "RGBA"[: img.shape[2]]
    write_exr(path, {n: img[:, :, i] for i, n in enumerate(names)}, header, half=half)


def read_rgb(path: str | os.PathLike, prefix: str = "") -> np.ndarray:
    """Read channels prefix+R, G, B as an (H, W, 3) float32 image, top-down rows.

    prefix selects a layer of a multi-channel file, e.g. "ViewLayer.Combined.".
    """
    channels, _ = read_exr(path)
    missing = [prefix + c for c in "RGB" if prefix + c not in channels]
    if missing:
        raise KeyError(f"{path}: no channels {missing}; has {sorted(channels)}")
    return np.stack([channels[prefix + c].astype(np.float32) for c in "RGB"], axis=-1)
