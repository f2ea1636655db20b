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

Safe output (`write_atomically`): a file is written to a temporary file in its own
directory, checked (EXR read back, PNG parsed to its last chunk), flushed to disk and only
then renamed over the destination with `os.replace`. A failure (full disk, permission,
a writer that reports success after a short write) raises `OutputError` and leaves any
previous file at the destination untouched and no temporary file; a killed process leaves
at most one hidden `.<name>.ember-tmp-<pid>-*` file, which `remove_stale_temporaries`
deletes once its process is gone.
"""
from __future__ import annotations

import errno
import io
import json
import os
import pathlib
import struct
import tempfile
import zlib
from typing import Callable, Iterable

import numpy as np

__all__ = ["write_exr", "read_exr", "write_rgba_exr", "read_rgb", "OutputError", "write_atomically",
           "check_png", "check_exr", "remove_stale_temporaries", "save_rgba_exr", "load_exr_binding",
           "check_writable"]

# Attributes that write_exr sets itself or the format derives from the pixels.
_RESERVED = {"channels", "compression", "dataWindow", "displayWindow", "lineOrder",
             "pixelAspectRatio", "screenWindowCenter", "screenWindowWidth", "type",
             "tiles", "name", "version", "chunkCount"}

_INT32 = (-(2 ** 31), 2 ** 31 - 1)


def _openexr():
    import OpenEXR  # imported lazily: only I/O needs it
    return OpenEXR


def load_exr_binding() -> None:
    """Import OpenEXR now: an import that a KeyboardInterrupt cuts short leaves the binding
    unusable in this process (its initialisation fails for good). Its writer imports
    `fractions` on first use."""
    import importlib
    importlib.import_module("fractions")
    _openexr()


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
        if _utf8(path):
            f.write(str(path))
        else:  # the binding takes UTF-8 names only: the bytes go through Python's file
            buffer = io.BytesIO()
            f.write(buffer)
            with open(path, "wb") as fh:
                fh.write(buffer.getvalue())


def _utf8(path) -> bool:
    """Whether the path's name is valid UTF-8 (a byte that is not was decoded by the file
    system encoding's surrogateescape, which OpenEXR's binding cannot encode)."""
    try:
        str(path).encode("utf-8")
        return True
    except UnicodeEncodeError:
        return False


def read_exr(path: str | os.PathLike) -> tuple[dict[str, np.ndarray], dict]:
    """Read the first part of an EXR.

    Returns (channels, header): channels maps each channel name to an (H, W) array,
    top-down rows, dtype float32 for FLOAT channels and float16 for HALF (uint32 for
    UINT); header is the attribute dict as the OpenEXR binding returns it (strings,
    ints, floats, plus the format's own entries such as 'dataWindow').
    """
    exr = _openexr()
    source = str(path)
    if not _utf8(path):
        with open(path, "rb") as fh:
            source = io.BytesIO(fh.read())
    with exr.File(source, separate_channels=True) as f:
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


# ---- safe output ------------------------------------------------------------------------------

class OutputError(Exception):
    """An output file could not be written; the message is one line for the user."""


_TMP_TAG = ".ember-tmp-"


def _reason(e: BaseException) -> str:
    """One line saying why a write failed (writers word a full disk in several ways)."""
    text = str(e).strip().splitlines()
    text = text[-1] if text else type(e).__name__
    if (isinstance(e, OSError) and e.errno == errno.ENOSPC) or "no space left" in text.lower():
        return "no space left on the device"
    if isinstance(e, OSError) and e.strerror:
        return e.strerror[0].lower() + e.strerror[1:]
    return text


def _file_mode() -> int:
    """Permissions a plainly created file would get (0666 minus the umask)."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def write_atomically(path: str | os.PathLike, write: Callable[[str], None],
                     check: Callable[[str], None] | None = None) -> None:
    """Create `path` through a temporary file in the same directory.

    write(tmp) writes the whole file at the path it is given (it keeps the destination's
    extension, for writers that choose the format by it); check(tmp) raises if the result is
    not a complete file (a writer may report success after a short write). Then the data
    is fsync'ed and the temporary renamed over `path` in one step. Raises OutputError with
    a one-line reason; the destination is unchanged and the temporary removed on any
    failure, also on KeyboardInterrupt.
    """
    path = pathlib.Path(path)
    directory = path.parent if str(path.parent) else pathlib.Path(".")
    tmp = _temporary(path)
    try:
        try:
            write(tmp)
            size = os.path.getsize(tmp)
            if size == 0:
                raise OSError(errno.EIO, "the writer produced an empty file")
            if check is not None:
                check(tmp)
            os.chmod(tmp, _file_mode())
            fd = os.open(tmp, os.O_RDONLY)
            try:
                os.fsync(fd)  # the data is on disk before the name points at it
            finally:
                os.close(fd)
            os.replace(tmp, path)
        except (OSError, RuntimeError, ValueError, KeyError, zlib.error, struct.error) as e:
            reason = _reason(e).replace(tmp, str(path))
            if not isinstance(e, OSError) and _disk_full(directory):  # a silent short write
                reason = f"no space left on the device ({reason})"
            raise OutputError(f"could not write {path}: {reason}") from e
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def _temporary(path: pathlib.Path) -> str:
    """A new empty temporary file for `path` in its directory (OutputError if none can be made)."""
    directory = path.parent if str(path.parent) else pathlib.Path(".")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}{_TMP_TAG}{os.getpid()}-", suffix=path.suffix,
                                   dir=directory)
        os.close(fd)
    except OSError as e:
        if e.errno == errno.ENAMETOOLONG:
            extra = len(os.fsencode(f".{_TMP_TAG}{os.getpid()}-xxxxxxxx{path.suffix}"))
            most = _name_max(directory)
            raise OutputError(f"could not write {path}: its name is {len(os.fsencode(path.name))} bytes, too long "
                              f"for the temporary file written first, which adds {extra} to it (names of at "
                              f"most {most} bytes here): use at most {most - extra}") from e
        raise OutputError(f"could not write {path}: {_reason(e)}") from e
    return tmp


def _name_max(directory) -> int:
    try:
        return os.pathconf(directory, "PC_NAME_MAX")
    except (OSError, ValueError):
        return 255


def check_writable(path: str | os.PathLike) -> None:
    """Raise OutputError unless write_atomically could create its temporary file for `path`
    (a name too long for it, a directory without write permission): checked before rendering."""
    os.unlink(_temporary(pathlib.Path(path)))


def _disk_full(directory, margin: int = 1 << 16) -> bool:
    try:
        st = os.statvfs(directory)
    except (OSError, AttributeError):
        return False
    return st.f_bavail * st.f_frsize < margin


def remove_stale_temporaries(path: str | os.PathLike, include_own: bool = False) -> int:
    """Delete temporaries of `path` left by processes that no longer run (killed during a
    write), and this process's own with include_own (before it ends abruptly). Returns how
    many were removed."""
    path = pathlib.Path(path)
    directory = path.parent if str(path.parent) else pathlib.Path(".")
    prefix = f".{path.name}{_TMP_TAG}"
    removed = 0
    try:
        names = [n for n in os.listdir(directory) if n.startswith(prefix)]
    except OSError:
        return 0
    for name in names:
        pid_text = name[len(prefix):].split("-", 1)[0]
        if not pid_text.isdigit():
            continue
        pid = int(pid_text)
        if _process_alive(pid) and not (include_own and pid == os.getpid()):
            continue
        try:
            os.unlink(directory / name)
            removed += 1
        except OSError:
            pass
    return removed


def _process_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


_PNG_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}


def check_png(path: str | os.PathLike, size: tuple[int, int] | None = None) -> None:
    """Raise ValueError unless `path` is a complete PNG: every chunk whole with a correct CRC,
    IHDR first, IEND last, the image data inflating to exactly the rows IHDR promises and,
    if given, size == (width, height)."""
    data = pathlib.Path(path).read_bytes()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("not a PNG file")
    pos, ihdr, idat, ended = 8, None, [], False
    while pos + 12 <= len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if len(body) < n or pos + 12 + n > len(data):
            break
        (crc,) = struct.unpack(">I", data[pos + 8 + n:pos + 12 + n])
        if zlib.crc32(kind + body) != crc:
            raise ValueError(f"PNG chunk {kind!r} is corrupt")
        if ihdr is None and kind != b"IHDR":
            raise ValueError("PNG does not start with IHDR")
        if kind == b"IHDR":
            ihdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            ended = True
            break
        pos += 12 + n
    if not ended or ihdr is None:
        raise ValueError("the PNG file is truncated")
    w, h, depth, ctype, _, _, interlace = ihdr
    if size is not None and (w, h) != tuple(size):
        raise ValueError(f"the PNG is {w}x{h}, expected {size[0]}x{size[1]}")
    if interlace == 0 and ctype in _PNG_CHANNELS:
        row = (w * _PNG_CHANNELS[ctype] * depth + 7) // 8 + 1  # filter byte + samples
        inflater = zlib.decompressobj()
        got = sum(len(inflater.decompress(b)) for b in idat) + len(inflater.flush())
        if got != row * h or not inflater.eof:
            raise ValueError("the PNG image data is incomplete")


def check_exr(path: str | os.PathLike, shape: tuple[int, int] | None = None) -> None:
    """Raise unless `path` reads back as an EXR whose channels all have shape (H, W)."""
    channels, _ = read_exr(path)
    if not channels:
        raise ValueError("the EXR file has no channels")
    for name, ch in channels.items():
        if shape is not None and ch.shape != tuple(shape):
            raise ValueError(f"EXR channel {name!r} is {ch.shape}, expected {tuple(shape)}")


def save_rgba_exr(path: str | os.PathLike, image: np.ndarray, header: dict | None = None) -> None:
    """write_rgba_exr through write_atomically, checked by reading the file back."""
    img = np.asarray(image)
    write_atomically(path, lambda tmp: write_rgba_exr(tmp, img, header),
                     lambda tmp: check_exr(tmp, img.shape[:2]))
