"""Images as Cycles' kernel reads them: texels stored as Cycles stores them, looked up with its
interpolations and extensions (kernel/device/cpu/image.h, TextureInterpolator::interp and its
closest, linear and cubic B-spline lookups; svm/image.h svm_image_texture).

Texel (0, 0) is the bottom-left one and texel centres sit at ((i + 0.5) / width,
(j + 0.5) / height): an image's v grows upward, as Blender stores its pixels. Texture
coordinates are scaled to texels in float32, as the kernel does, so which texel Closest picks
at a boundary is the kernel's choice. Smart interpolation is cubic here, as in Cycles' SVM on
the CPU (interp's default case).

A UDIM image is Tiles: Texels per tile, the tile chosen from the integer part of the texture
coordinate (svm/image.h svm_node_tex_image).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

F32 = np.float32
# Cycles' colour for an image it has no pixels of (util/texture.h TEX_IMAGE_MISSING_*), RGBA.
MISSING = np.array([1.0, 0.0, 1.0, 1.0])


@dataclass(frozen=True, eq=False)
class Texels:
    """An image's texels as Cycles keeps them for its kernel. `pixels`: (height, width, 4), row 0
    at the bottom: float32, or uint8 (uint16) values k read as k / 255 (k / 65535), as Cycles
    keeps byte (ushort) textures in a quarter (half) of the memory; `srgb`: the texels are sRGB
    values that the kernel interpolates as they are and converts to linear after the lookup
    (Cycles' NODE_IMAGE_COMPRESS_AS_SRGB), else they are scene linear; `associated`: the colour is
    associated with alpha, and an Image Texture whose Alpha output is linked divides it out
    (NODE_IMAGE_ALPHA_UNASSOCIATE: not for data colour spaces, Channel Packed or None alpha).
    Compared by identity (a node's props stay hashable): one Texels per image per export."""

    name: str
    pixels: np.ndarray
    srgb: bool = False
    associated: bool = True

    @property
    def size(self) -> tuple:
        return self.pixels.shape[1], self.pixels.shape[0]


def _floor(x):
    """Cycles' frac(): (x - i, i) with i = int(x) - (x < 0). For a negative whole x this is
    x - 1 with a fraction of 1, not floor(x) (the same texel weights, but Closest reads i)."""
    i = np.trunc(x).astype(np.int64) - (x < 0)
    return x - i.astype(x.dtype), i


def _wrap(i, n: int, extension: str):
    """Texel indices `i` of a row of n under the extension; CLIP leaves them for _read."""
    if extension == "REPEAT":
        return np.mod(i, n)
    if extension == "EXTEND":
        return np.clip(i, 0, n - 1)
    if extension == "MIRROR":
        m = np.abs(i + (i < 0)) % (2 * n)
        return np.where(m >= n, 2 * n - m - 1, m)
    return i


def _read(pixels, ix, iy, extension: str):
    """Texels at (ix, iy) (inside the image unless CLIP), transparent black outside it
    (read_clip)."""
    h, w = pixels.shape[:2]
    flat = pixels.reshape(h * w, -1)
    if extension != "CLIP":
        return _float(np.take(flat, iy * w + ix, axis=0))
    inside = (ix >= 0) & (ix < w) & (iy >= 0) & (iy < h)
    texels = _float(np.take(flat, np.clip(iy, 0, h - 1) * w + np.clip(ix, 0, w - 1), axis=0))
    return np.where(inside[..., None], texels, 0.0)


def _float(texels) -> np.ndarray:
    """Texels as float64: integer ones k as k / 255 or k / 65535."""
    if texels.dtype.kind == "u":
        return texels * (1.0 / np.iinfo(texels.dtype).max)
    return texels.astype(np.float64)


def _cubic_weights(t):
    """The uniform cubic B-spline's four weights at fraction t (SET_CUBIC_SPLINE_WEIGHTS)."""
    return ((((-1.0 / 6.0) * t + 0.5) * t - 0.5) * t + 1.0 / 6.0, ((0.5 * t - 1.0) * t) * t + 2.0 / 3.0,
            ((-0.5 * t + 0.5) * t + 0.5) * t + 1.0 / 6.0, (1.0 / 6.0) * t * t * t)


def lookup(pixels: np.ndarray, x, y, interpolation: str = "LINEAR", extension: str = "REPEAT") -> np.ndarray:
    """The texels of `pixels` (H, W, C) at texture coordinates x, y (each (N,) or 0-d):
    (N, C) float64. interpolation: CLOSEST, LINEAR, CUBIC or SMART; extension: REPEAT, EXTEND,
    CLIP or MIRROR."""
    h, w = pixels.shape[:2]
    x = np.atleast_1d(np.asarray(x, np.float64)).astype(F32)
    y = np.atleast_1d(np.asarray(y, np.float64)).astype(F32)
    if interpolation == "CLOSEST":
        _, ix = _floor(x * F32(w))
        _, iy = _floor(y * F32(h))
        return _read(pixels, _wrap(ix, w, extension), _wrap(iy, h, extension), extension)
    # Linear and cubic samples are centred on the point: texel centres at half-texel offsets.
    tx, ix = _floor(x * F32(w) - F32(0.5))
    ty, iy = _floor(y * F32(h) - F32(0.5))
    tx, ty = tx.astype(np.float64)[:, None], ty.astype(np.float64)[:, None]
    if interpolation == "LINEAR":
        offsets, wx, wy = (0, 1), (1.0 - tx, tx), (1.0 - ty, ty)
    else:
        offsets, wx, wy = (-1, 0, 1, 2), _cubic_weights(tx), _cubic_weights(ty)
    columns = [_wrap(ix + b, w, extension) for b in offsets]
    out = 0.0
    for a, v in zip(offsets, wy):
        row = _wrap(iy + a, h, extension)
        out = out + v * sum(u * _read(pixels, column, row, extension) for u, column in zip(wx, columns))
    return out


def srgb_to_linear(c):
    """Cycles' color_srgb_to_linear: the sRGB curve, negative values to 0."""
    c = np.asarray(c, np.float64)
    return np.where(c < 0.04045, np.where(c < 0.0, 0.0, c * (1.0 / 12.92)),
                    np.power(np.maximum(c + 0.055, 0.0) * (1.0 / 1.055), 2.4))


@dataclass(frozen=True, eq=False)
class Tiles:
    """A UDIM image: `tiles` ((number, Texels), ...), tile 1001 + u + 10 v covering
    [u, u + 1) x [v, v + 1) of texture space, u in 0..9. Every tile of the image is here; Cycles'
    final renders drop the tiles no UV of the meshes using the material lies in, where the
    Vector is unlinked or the UV map itself (ImageTextureNode::cull_tiles), which shows only
    where a mapping moves those coordinates into another tile: Cycles reads magenta there."""

    name: str
    tiles: tuple

    def first(self) -> Texels | None:
        """Tile 1001, the one a Box projection reads (Cycles culls the others), else None."""
        return dict(self.tiles).get(1001)


def sample(texels: Texels | None, x, y, interpolation: str, extension: str, unassociate: bool = False) -> np.ndarray:
    """svm_image_texture: RGBA (N, 4) of an image at x, y; with `unassociate` (and associated
    texels), the colour divided by alpha where alpha is neither 0 nor 1; sRGB texels converted
    after that (alpha kept); no image: Cycles' magenta."""
    if texels is None:
        return np.broadcast_to(MISSING, (np.size(x), 4)).copy()
    rgba = lookup(texels.pixels, x, y, interpolation, extension)
    if unassociate and texels.associated:
        a = rgba[:, 3:]
        partial = (a != 0.0) & (a != 1.0)
        rgba[:, :3] = np.where(partial, rgba[:, :3] / np.where(partial, a, 1.0), rgba[:, :3])
    if texels.srgb:
        rgba[:, :3] = srgb_to_linear(rgba[:, :3])
    return rgba


def sample_tiles(image, x, y, interpolation: str, extension: str, unassociate: bool = False) -> np.ndarray:
    """svm_node_tex_image's lookup: a plain image (Texels or None) as sample(); for Tiles, each
    point reads the tile its coordinate's integer parts name (truncated toward 0, so
    -1 < u < 0 still reads tile 1001), at the coordinate less those parts; a point in no tile
    of the image, or left of u = -1, below v = -1 or right of u = 10, is magenta."""
    if not isinstance(image, Tiles):
        return sample(image, x, y, interpolation, extension, unassociate)
    x = np.atleast_1d(np.asarray(x, np.float64)).astype(F32)
    y = np.atleast_1d(np.asarray(y, np.float64)).astype(F32)
    tx, ty = np.trunc(x).astype(np.int64), np.trunc(y).astype(np.int64)
    valid = (tx >= 0) & (ty >= 0) & (tx < 10)
    number = np.where(valid, 1001 + 10 * ty + tx, -1)
    out = np.broadcast_to(MISSING, (len(x), 4)).copy()
    for tile, texels in image.tiles:
        at = np.flatnonzero(number == tile)
        if len(at):
            out[at] = sample(texels, x[at] - F32((tile - 1001) % 10), y[at] - F32((tile - 1001) // 10),
                             interpolation, extension, unassociate)
    return out
