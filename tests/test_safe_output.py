"""Safe output: an image is written to a temporary file beside the
destination, checked, and renamed into place. A failed write (full disk, a writer that stops
short without saying so, an interrupt, a killed process) leaves a previous file untouched and
no temporary behind, and the CLI exits 1 with one line."""
from __future__ import annotations

import errno
import os
import pathlib
import signal
import struct
import subprocess
import sys
import textwrap
import zlib

import numpy as np
import pytest

from ember.engine import imageio

ROOT = pathlib.Path(__file__).resolve().parents[1]
PREVIOUS = b"previous good render"


def _png_bytes(w=5, h=3):
    """A valid 8-bit RGBA PNG (what Blender writes, minus its text chunks)."""
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
    rows = b"".join(b"\x00" + bytes(range(y, y + 4 * w)) for y in range(h))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def _leftovers(d):
    return sorted(p.name for p in pathlib.Path(d).iterdir() if p.name.startswith("."))


# ---- the helpers ----------------------------------------------------------------------------
def test_check_png_accepts_whole_file_and_rejects_every_truncation(tmp_path):
    data = _png_bytes()
    p = tmp_path / "x.png"
    p.write_bytes(data)
    imageio.check_png(p, (5, 3))
    with pytest.raises(ValueError, match="5x3"):
        imageio.check_png(p, (6, 3))
    for cut in range(len(data)):  # every short write, including a lost IEND
        p.write_bytes(data[:cut])
        with pytest.raises(ValueError):
            imageio.check_png(p)
    flipped = bytearray(data)
    flipped[len(data) // 2] ^= 0x40  # a corrupt byte inside the image data
    p.write_bytes(bytes(flipped))
    with pytest.raises(ValueError):
        imageio.check_png(p)


def test_enospc_mid_write_keeps_previous_file_and_leaves_no_temporary(tmp_path):
    out = tmp_path / "out.exr"
    out.write_bytes(PREVIOUS)

    def write(tmp):
        with open(tmp, "wb") as fh:
            fh.write(b"half of an image")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with pytest.raises(imageio.OutputError, match="no space left on the device") as info:
        imageio.write_atomically(out, write)
    assert str(info.value).startswith(f"could not write {out}")
    assert "\n" not in str(info.value)
    assert out.read_bytes() == PREVIOUS
    assert _leftovers(tmp_path) == []


def test_silent_short_write_is_caught_by_the_check(tmp_path):
    """Blender's save_render reports success after a short PNG write on a full disk."""
    out = tmp_path / "out.png"
    out.write_bytes(PREVIOUS)
    data = _png_bytes()
    with pytest.raises(imageio.OutputError, match="truncated"):
        imageio.write_atomically(out, lambda tmp: pathlib.Path(tmp).write_bytes(data[:-20]),
                                 lambda tmp: imageio.check_png(tmp))
    assert out.read_bytes() == PREVIOUS
    assert _leftovers(tmp_path) == []
    imageio.write_atomically(out, lambda tmp: pathlib.Path(tmp).write_bytes(data), imageio.check_png)
    assert out.read_bytes() == data and _leftovers(tmp_path) == []


def test_interrupt_during_write_removes_the_temporary(tmp_path):
    out = tmp_path / "out.png"
    out.write_bytes(PREVIOUS)

    def write(tmp):
        pathlib.Path(tmp).write_bytes(b"partial")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        imageio.write_atomically(out, write)
    assert out.read_bytes() == PREVIOUS and _leftovers(tmp_path) == []


def test_exr_written_whole_with_normal_permissions(tmp_path):
    img = np.random.default_rng(3).random((6, 9, 4)).astype(np.float32)
    out = tmp_path / "img.exr"
    out.write_bytes(PREVIOUS)
    imageio.save_rgba_exr(out, img)
    ch, _ = imageio.read_exr(out)
    assert np.array_equal(np.stack([ch[c] for c in "RGBA"], -1), img)
    mask = os.umask(0)
    os.umask(mask)
    assert out.stat().st_mode & 0o777 == 0o666 & ~mask
    assert _leftovers(tmp_path) == []


def test_stale_temporaries_of_dead_processes_are_removed(tmp_path):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f".out.png.ember-tmp-{dead.pid}-abc.png"
    live = tmp_path / f".out.png.ember-tmp-{os.getpid()}-def.png"
    other = tmp_path / f".other.png.ember-tmp-{dead.pid}-ghi.png"
    for p in (stale, live, other):
        p.write_bytes(b"x")
    assert imageio.remove_stale_temporaries(tmp_path / "out.png") == 1
    assert not stale.exists() and live.exists() and other.exists()


# ---- through render.py ----------------------------------------------------------------------
@pytest.fixture
def full_disk(tmp_path):
    """A 96 KiB tmpfs with a previous render in it (needs root; skipped elsewhere)."""
    d = tmp_path / "small"
    d.mkdir()
    if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", "size=96k", "tmpfs", str(d)],
                                           capture_output=True).returncode != 0:
        pytest.skip("cannot mount a small tmpfs here")
    try:
        yield d
    finally:
        subprocess.run(["umount", str(d)], capture_output=True)


@pytest.mark.blender
@pytest.mark.parametrize("name", ["out.png", "out.exr"])
def test_cli_full_disk_exits_1_keeps_previous_file(scenes, full_disk, name):
    from test_cli import run
    out = full_disk / name
    out.write_bytes(PREVIOUS)
    (full_disk / "filler").write_bytes(os.urandom(80 * 1024))  # ~16 KiB left: the PNG needs 22
    code, stdout, stderr = run(scenes, "ok.blend", "-o", out, "--samples", "2", "--resolution", "200x200",
                               "--no-progress")
    assert code == 1, (stdout, stderr)
    lines = [l for l in stderr.splitlines() if l.startswith("render.py")]
    assert len(lines) == 1 and lines[0].startswith(f"render.py: error: could not write {out}: "), stderr
    assert "no space left on the device" in lines[0], stderr
    assert "Traceback" not in stderr and f"-> {out}" not in stdout  # no success line
    assert out.read_bytes() == PREVIOUS
    assert _leftovers(full_disk) == []


KILL_DURING_WRITE = textwrap.dedent('''
    import os, signal, sys
    sys.argv = [sys.argv[0]] + sys.argv[1:]
    sys.path.insert(0, {root!r})
    from _bootstrap import load_ember
    load_ember()
    from ember.engine import imageio
    real = imageio.write_rgba_exr

    def write_then_die(path, *args, **kwargs):
        with open(path, "wb") as fh:
            fh.write(b"half an image")
            fh.flush()
        os.kill(os.getpid(), signal.SIGKILL)

    imageio.write_rgba_exr = write_then_die
    import runpy
    runpy.run_path({render!r}, run_name="__main__")
''')


@pytest.mark.blender
def test_cli_killed_during_write_keeps_previous_file(scenes, tmp_path):
    from test_cli import _env, run
    out = tmp_path / "out.exr"
    out.write_bytes(PREVIOUS)
    script = KILL_DURING_WRITE.format(root=str(ROOT), render=str(ROOT / "render.py"))
    proc = subprocess.run([sys.executable, "-c", script, "ok.blend", "-o", str(out), "--samples", "1",
                           "--no-progress"], cwd=scenes, env=_env(scenes), capture_output=True, text=True,
                          timeout=180)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    assert out.read_bytes() == PREVIOUS  # never truncated
    assert len(_leftovers(tmp_path)) == 1  # SIGKILL cannot clean up: one hidden temporary
    code, stdout, stderr = run(scenes, "ok.blend", "-o", out, "--samples", "1", "--no-progress")
    assert code == 0, stderr
    assert out.read_bytes()[:4] == b"v/1\x01"  # an EXR now
    assert _leftovers(tmp_path) == []  # the next render removed the dead one's temporary


from test_cli import scenes  # noqa: E402,F401  (module fixture: the small .blend files)
