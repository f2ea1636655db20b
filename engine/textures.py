"""Image texture lookups at shading points, all slots and images at once (no per-point loop).

Matches Cycles' CPU image sampling (intern/cycles/kernel/device/cpu/image.h, svm/image.h):
- Linear: bilinear between the four texels around u W - 1/2, v H - 1/2 (texel centres at
  (i + 1/2) / W); Closest: texel floor(u W);
- extension per texel index: Repeat wraps, Extend clamps, Clip reads 0 outside the image,
  Mirror reflects;
- sRGB byte images are interpolated as stored (bytes / 255) and decoded to linear afterwards
  (Cycles' "compress as sRGB"); float and non-colour images are linear as they are.
UVs are Blender's: u to the right, v up, texel rows stored bottom-up.
"""
from __future__ import annotations

import numpy as np

from .scene import (EXT_CLIP, EXT_MIRROR, EXT_REPEAT, INTERP_CLOSEST, TEX_ALPHA,
                    Materials)

# Rec. 709 luminance: what Cycles uses to turn a colour into a float socket value (rgb_to_y).
LUMINANCE = np.array([0.2126729, 0.7151522, 0.0721750])


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """sRGB-encoded values -> linear (the IEC 61966-2-1 curve, negative values -> 0)."""
    c = np.asarray(c, np.float64)
    return np.where(c < 0.04045, np.maximum(c, 0.0) / 12.92, ((np.maximum(c, 0.04045) + 0.055) / 1.055) ** 2.4)


def _wrap(i: np.ndarray, n: np.ndarray, extension: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Texel indices (K,) wrapped into [0, n) per extension; second array: inside (for Clip)."""
    inside = (i >= 0) & (i < n)
    repeat = np.mod(i, n)
    period = np.mod(i, 2 * n)
    mirror = np.where(period < n, period, 2 * n - 1 - period)
    clamped = np.clip(i, 0, n - 1)
    out = np.where(extension == EXT_REPEAT, repeat,
                   np.where(extension == EXT_MIRROR, mirror, clamped))
    return out, inside | (extension != EXT_CLIP)


def _texel(m: Materials, image: np.ndarray, ix, iy, extension) -> np.ndarray:
    """RGBA (K,4) of texel (ix, iy) of `image` (K,), 0 where Clip leaves the image."""
    w, h = m.image_size[image, 0].astype(np.int64), m.image_size[image, 1].astype(np.int64)
    x, x_in = _wrap(ix, w, extension)
    y, y_in = _wrap(iy, h, extension)
    rgba = m.image_texels[m.image_offset[image] + y * w + x].astype(np.float64)
    return np.where((x_in & y_in)[:, None], rgba, 0.0)


def lookup(m: Materials, slot: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Linear RGBA (K,4) float64 of texture slots `slot` (K,) at mesh UVs `uv` (K,2)."""
    slot = np.asarray(slot, np.int64)
    A = m.tex_transform[slot]
    u = A[:, 0, 0] * uv[:, 0] + A[:, 0, 1] * uv[:, 1] + A[:, 0, 2]
    v = A[:, 1, 0] * uv[:, 0] + A[:, 1, 1] * uv[:, 1] + A[:, 1, 2]
    image = m.tex_image[slot]
    extension = m.tex_extension[slot]
    w = m.image_size[image, 0].astype(np.float64)
    h = m.image_size[image, 1].astype(np.float64)
    closest = m.tex_interpolation[slot] == INTERP_CLOSEST
    # Closest reads the texel containing (u, v); Linear blends the four around it.
    x = np.where(closest, u * w, u * w - 0.5)
    y = np.where(closest, v * h, v * h - 0.5)
    ix, iy = np.floor(x), np.floor(y)
    tx = np.where(closest, 0.0, x - ix)[:, None]
    ty = np.where(closest, 0.0, y - iy)[:, None]
    ix, iy = ix.astype(np.int64), iy.astype(np.int64)
    rgba = (1 - ty) * ((1 - tx) * _texel(m, image, ix, iy, extension) + tx * _texel(m, image, ix + 1, iy, extension)) \
        + ty * ((1 - tx) * _texel(m, image, ix, iy + 1, extension) + tx * _texel(m, image, ix + 1, iy + 1, extension))
    srgb = m.image_srgb[image]
    if srgb.any():
        rgba[:, :3] = np.where(srgb[:, None], srgb_to_linear(rgba[:, :3]), rgba[:, :3])
    return rgba


def color(m: Materials, slot: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """The colour (K,3) a slot feeds into a colour input (alpha output: grey)."""
    rgba = lookup(m, slot, uv)
    return np.where((m.tex_output[slot] == TEX_ALPHA)[:, None], rgba[:, 3:4], rgba[:, :3])


def scalar(m: Materials, slot: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """The value (K,) a slot feeds into a float input: alpha, or the colour's luminance."""
    rgba = lookup(m, slot, uv)
    return np.where(m.tex_output[slot] == TEX_ALPHA, rgba[:, 3], rgba[:, :3] @ LUMINANCE)


def mesh_uv(uvs: np.ndarray, prim: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """Interpolated UVs (N,2) float64 at hits (prim (N,), barycentrics (N,3)) of Mesh.uvs."""
    c = uvs[prim].astype(np.float64)
    return bary[:, 0:1] * c[:, 0] + bary[:, 1:2] * c[:, 1] + bary[:, 2:3] * c[:, 2]
