"""A bpy Image -> engine.nodes.image.Texels (Tiles for UDIM images): its pixels as Cycles keeps
them for its kernel (blender/image.cpp BlenderImageLoader, scene/image.cpp ImageManager), so an
image node's graph carries its texels and the renderer hands over nothing more.

Pixels are read once with foreach_get into float32 (image.pixels[:] builds a Python list),
rows bottom-up as Blender stores them and Cycles reads them, made RGBA (one channel is grey
with alpha 1). Float images are taken as they are: Blender has already converted them to scene
linear, whatever their colour space says. Byte images are 8-bit values: with straight alpha
(Blender's byte buffers always are) and a colour space that is not data, Cycles premultiplies
them in 8 bits, (c a) / 255 rounded down; sRGB ones stay sRGB and the kernel converts them
after interpolating (compressed sRGB textures); Linear Rec.709 and Non-Color are read as they
are. A 16-bit sRGB PNG on disk Cycles reads from the file as 16-bit sRGB values (premultiplied
in 16 bits, converted after interpolating), which Blender's linear floats are encoded back to
(a packed one Cycles reads from Blender's floats). Byte images in other colour spaces Cycles
converts with OpenColorIO into half floats, which Ember does not (a warning; the values are
read as linear). Alpha mode None makes alpha 1. Float pixels with a NaN or infinite channel
are cleaned as Cycles cleans them (one in four: _clean). An image Cycles
cannot load (no pixels: a missing file; a channel count other than 1 or 4) is None, rendered
magenta.

Image sources: a UDIM image reads each tile's file (its path with <UDIM> made the tile's
number) into Tiles; a sequence reads the file of the frame its ImageUser shows at the scene's
frame (Blender's BKE_image_user_frame_get, the frame number put in the file name as Blender
numbers sequences); a movie is read as the frame Blender last decoded, with a warning.
"""
from __future__ import annotations

import os
import re

import bpy
import numpy as np

from ..nodes.image import Texels, Tiles

_SRGB = {"sRGB"}
_DATA = {"Non-Color"}
_LINEAR = {"Linear Rec.709", "scene_linear"}


def _quiet(text: str) -> None:
    pass


def image_texels(image, context=None) -> Texels | Tiles | None:
    """PROPS exporter of an image pointer (engine/blender/export_nodes.py)."""
    warn = context.warn if context is not None else _quiet
    node = context.node if context is not None else None
    owner = f"{node.name}: " if node is not None else ""
    if image is None:
        warn(f"{owner}no image: magenta, as in Cycles")
        return None
    if image.source == "TILED":
        return _tiles(image, warn, owner)
    if image.source == "SEQUENCE":
        user = getattr(node, "image_user", None)
        frame = frame_number(user, bpy.context.scene.frame_current) if user is not None else 1
        return _from_file(sequence_path(image.filepath, frame), image, warn, owner)
    if image.source == "MOVIE":
        warn(f"{owner}movie '{image.name}' is read as the frame Blender last decoded, not the scene frame's")
    return texels(image, warn, owner)


def texels(image, warn=_quiet, owner: str = "", name: str | None = None) -> Texels | None:
    """An image's pixels (its buffer as Blender holds it) as the texels Cycles keeps."""
    w, h = (int(v) for v in image.size)
    channels = int(image.channels)
    if w == 0 or h == 0:
        where = f" (file '{bpy.path.abspath(image.filepath, library=image.library)}')" if image.filepath else ""
        warn(f"{owner}image '{image.name}' has no pixels{where}: missing or unreadable, magenta, as in Cycles")
        return None
    if channels not in (1, 4):
        return None
    buf = np.empty(w * h * channels, np.float32)
    image.pixels.foreach_get(buf)
    buf = buf.reshape(h, w, channels)
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :channels if channels == 4 else 3] = buf
    space, alpha_mode = image.colorspace_settings.name, image.alpha_mode
    data = space in _DATA
    associate = channels == 4 and not data and alpha_mode not in ("CHANNEL_PACKED", "NONE")
    srgb = False
    if image.is_float:
        _clean(rgba)
        if space in _SRGB and _read_by_cycles(image) and image.file_format == "PNG":
            rgba, srgb = _ushort_srgb(rgba, associate), True
    else:
        rgba, srgb = _bytes(rgba, associate), space in _SRGB
        if space not in _SRGB | _DATA | _LINEAR:
            warn(f"{owner}image '{image.name}' is in colour space '{space}', which Ember does not convert "
                 "for byte images: its values are read as linear")
    if alpha_mode == "NONE":
        rgba[..., 3] = np.iinfo(rgba.dtype).max if rgba.dtype.kind == "u" else 1.0
    associated = not data and alpha_mode not in ("CHANNEL_PACKED", "NONE")
    return Texels(name or image.name, rgba, srgb=srgb, associated=associated)


def _bytes(rgba, associate: bool) -> np.ndarray:
    """A byte image's 8-bit values (uint8), premultiplied in 8 bits, (c a) / 255 rounded down,
    where Cycles associates alpha (blender/image.cpp: Blender's byte buffers are straight)."""
    values = np.rint(rgba * 255.0).astype(np.int32)
    if associate:
        values[..., :3] = values[..., :3] * values[..., 3:] // 255
    return values.astype(np.uint8)


def _read_by_cycles(image) -> bool:
    """Cycles reads the image's file itself (OpenImageIO), not Blender's buffer: a file on disk,
    not packed (blender/shader.cpp image_is_builtin)."""
    return image.packed_file is None and image.source in ("FILE", "SEQUENCE", "TILED")


def _ushort_srgb(rgba, associate: bool) -> np.ndarray:
    """A 16-bit sRGB PNG as Cycles keeps it (uint16): the file's 16-bit sRGB values, converted by the
    kernel after interpolating, premultiplied in 16 bits, (c a) / 65535 rounded down. Blender
    holds them as linear floats (premultiplied where there is alpha): encoded back to sRGB and
    rounded to 16 bits, they are the file's values."""
    a = rgba[..., 3:].astype(np.float64)
    linear = np.where(a > 0.0, rgba[..., :3] / np.where(a > 0.0, a, 1.0), 0.0) if associate else rgba[..., :3]
    linear = np.asarray(linear, np.float64)
    encoded = np.where(linear < 0.0031308, np.maximum(linear, 0.0) * 12.92,
                       1.055 * np.power(np.maximum(linear, 0.0031308), 1.0 / 2.4) - 0.055)
    values = np.rint(np.clip(np.concatenate([encoded, a], axis=-1), 0.0, 1.0) * 65535.0).astype(np.int64)
    if associate:
        values[..., :3] = values[..., :3] * values[..., 3:] // 65535
    return values.astype(np.uint16)


def _clean(rgba) -> None:
    """Cycles' cleaning of float RGBA images (scene/image.cpp file_load_image): a pixel with a
    channel that is not finite becomes transparent black, but the loop steps four pixels at a
    time over a pixel index, so only pixels whose index (row * width + column, from the bottom
    row) is a multiple of 4 are cleaned; the others keep their NaN and infinities, which every
    lookup that touches them spreads (and the film then drops)."""
    flat = rgba.reshape(-1, 4)[::4]
    flat[~np.all(np.isfinite(flat), axis=-1)] = 0.0


def frame_number(user, scene_frame: int) -> int:
    """The image frame an ImageUser shows at `scene_frame` (BKE_image_user_frame_get): frames
    counted from its start, wrapped if cyclic, else held at the ends, then offset."""
    length = int(user.frame_duration)
    if length == 0:
        return 0
    frame = scene_frame - int(user.frame_start) + 1
    if user.use_cyclic:
        frame %= length
        if frame == 0:
            frame = length
    frame = min(max(frame, 0), length)
    return frame + int(user.frame_offset)


def sequence_path(filepath: str, frame: int) -> str:
    """`filepath` with the last run of digits in its file name (before the extension) replaced
    by `frame`, padded to as many digits (Blender's BLI_path_sequence_decode / encode)."""
    head, tail = os.path.split(filepath)
    stem, ext = os.path.splitext(tail)
    found = list(re.finditer(r"\d+", stem))
    if not found:
        return filepath
    digits = found[-1]
    number = f"{frame:0{len(digits.group())}d}"
    return os.path.join(head, stem[:digits.start()] + number + stem[digits.end():] + ext)


def _from_file(path: str, like, warn, owner: str, name: str | None = None) -> Texels | None:
    """The texels of the image file at `path` (a Blender path, // relative to the .blend), read
    with `like`'s colour space and alpha mode; None (magenta) where it cannot be read."""
    full = bpy.path.abspath(path, library=like.library)
    if not os.path.isfile(full):
        warn(f"{owner}image file '{full}' of '{like.name}' is missing: magenta, as in Cycles")
        return None
    loaded = bpy.data.images.load(full, check_existing=False)
    try:
        loaded.colorspace_settings.name = like.colorspace_settings.name
        loaded.alpha_mode = like.alpha_mode
        return texels(loaded, warn, owner, name or like.name)
    finally:
        bpy.data.images.remove(loaded)


def _tiles(image, warn, owner: str) -> Tiles | None:
    """A UDIM image's tiles, each read from its own file (the path's <UDIM> token, or the tile
    number Blender found in the file name, made the tile's number). Tiles that exist only in
    memory (generated, or packed) Ember cannot read one by one: tile 1001 as Blender holds it
    stands for them all, with a warning."""
    numbers = [int(t.number) for t in image.tiles]
    path = image.filepath_raw or image.filepath
    if "<UDIM>" not in path:
        path = re.sub(r"(?<!\d)1\d\d\d(?=\D*$)", "<UDIM>", path, count=1)
    if image.packed_file is not None or "<UDIM>" not in path:
        warn(f"{owner}UDIM image '{image.name}' has tiles Ember cannot read one by one: the first stands for all")
        first = texels(image, warn, owner)
        return Tiles(image.name, tuple((n, first) for n in numbers))
    tiles = tuple((n, _from_file(path.replace("<UDIM>", str(n)), image, warn, owner, f"{image.name}.{n}"))
                  for n in numbers)
    return Tiles(image.name, tiles)
