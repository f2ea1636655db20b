"""A bpy Image -> engine.nodes.image.Texels: its pixels as Cycles keeps them for its kernel
(blender/image.cpp BlenderImageLoader, scene/image.cpp), so an image node's graph carries its
texels and the renderer hands over nothing more.

Pixels are read once with foreach_get into float32 (image.pixels[:] builds a Python list),
rows bottom-up as Blender stores them and Cycles reads them, made RGBA (one channel is grey
with alpha 1). Float images are taken as they are: Blender has already converted them to scene
linear, whatever their colour space says. Byte images are 8-bit values: with straight alpha
(Blender's byte buffers always are) and a colour space that is not data, Cycles premultiplies
them in 8 bits, (c a) / 255 rounded down; sRGB ones stay sRGB and the kernel converts them
after interpolating (compressed sRGB textures); other colour spaces are read as linear, which
is exact for Linear Rec.709 and Non-Color. Alpha mode None makes alpha 1. NaN and infinite
values become 0. An image Cycles cannot load (no pixels: a missing file; a channel count other
than 1 or 4) is None, rendered magenta.
"""
from __future__ import annotations

import numpy as np

from ..nodes.image import Texels

_SRGB = {"sRGB"}
_DATA = {"Non-Color"}


def image_texels(image, context=None) -> Texels | None:
    """PROPS exporter of an image pointer (engine/blender/export_nodes.py)."""
    if image is None:
        return None
    w, h = (int(v) for v in image.size)
    channels = int(image.channels)
    if w == 0 or h == 0 or channels not in (1, 4):
        return None
    buf = np.empty(w * h * channels, np.float32)
    image.pixels.foreach_get(buf)
    buf = buf.reshape(h, w, channels)
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :channels if channels == 4 else 3] = buf
    rgba[~np.isfinite(rgba)] = 0.0
    space, alpha_mode = image.colorspace_settings.name, image.alpha_mode
    if not image.is_float:
        values = np.rint(rgba * 255.0).astype(np.int32)
        if channels == 4 and space not in _DATA and alpha_mode not in ("CHANNEL_PACKED", "NONE"):
            values[..., :3] = values[..., :3] * values[..., 3:] // 255
        rgba = (values / 255.0).astype(np.float32)
    if alpha_mode == "NONE":
        rgba[..., 3] = 1.0
    return Texels(image.name, rgba, srgb=not image.is_float and space in _SRGB)
