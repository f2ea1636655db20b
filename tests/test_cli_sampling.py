"""render.py's sampling controls as a user sees them: the progress bar on a terminal, the
adaptive-sampling and animated-seed options, their validation."""
from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest

from test_cli import RENDER, _env, _one_clear_line, run, scenes  # noqa: F401 (scenes: the fixture)

pytestmark = pytest.mark.blender


def _run_on_terminal(scenes, *args) -> tuple[int, str]:
    """render.py with stdout and stderr on one 100x24 pseudo-terminal, as in a shell."""
    import fcntl
    import pty
    import struct
    import termios

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # tqdm draws nothing on 0x0
    proc = subprocess.Popen([sys.executable, str(RENDER), *map(str, args)], cwd=scenes, env=_env(scenes),
                            stdin=slave, stdout=slave, stderr=slave)
    os.close(slave)
    out = b""
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:  # the child closed the terminal
            break
        if not chunk:
            break
        out += chunk
    os.close(master)
    return proc.wait(timeout=180), out.decode(errors="replace")


def test_progress_bar_follows_the_time_limit_and_ends_before_the_summary(scenes):
    code, text = _run_on_terminal(scenes, "ok.blend", "-o", "bar.png", "--time-limit", "1.5", "--samples", "100000",
                                  "--resolution", "16x16")
    assert code == 0, text
    assert re.search(r"\d+%\|.*\| \d+\.\d/1\.5 s, \d+/100000 spp", text), text  # a bar of the time limit
    for line in ("Ember stopped at the time limit", "Ember: ok.blend -> bar.png"):
        at = text.index(line)
        assert text[at - 1] == "\n", text[max(0, at - 200):at + 40]  # on a line of its own
    bar_end = text[:text.index("Ember stopped at the time limit")]
    last_bar = bar_end.replace("\r\n", "\n").split("\r")[-1]
    assert "100%" in last_bar and "1.5/1.5 s" in last_bar, last_bar


@pytest.mark.parametrize("args, words", [
    (["--adaptive", "maybe"], ["--adaptive", "on or off"]),
    (["--adaptive-threshold", "1.5"], ["--adaptive-threshold", "at most 1"]),
    (["--adaptive-threshold", "-0.1"], ["--adaptive-threshold"]),
    (["--adaptive-min-samples", "5000"], ["--adaptive-min-samples", "at most 4096"]),
    (["--animated-seed", "yes"], ["--animated-seed", "on or off"]),
    (["--preset", "draft"], ["--preset", "preview", "final"]),
])
def test_bad_sampling_options_one_line_exit_2(scenes, args, words):
    code, out, err = run(scenes, "ok.blend", "-o", "x.png", *args)
    assert code == 2
    _one_clear_line(err, *words)


def test_adaptive_options_render(scenes):
    """--preset preview, then single values over it: the summary names adaptive sampling and
    the pixels still active."""
    code, out, err = run(scenes, "ok.blend", "-o", "adaptive.png", "--resolution", "16x16", "--preset", "preview",
                         "--samples", "48", "--adaptive-min-samples", "16", "--adaptive-threshold", "0.05",
                         "--animated-seed", "on", "--no-progress")
    assert code == 0, err
    assert re.search(r"adaptive: \d+ of 256 pixels active at the end", out), out
