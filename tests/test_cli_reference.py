"""render.py --reference (relMSE while rendering and at the end) and --noise-target, as users
run them: `python render.py scene.blend ...` in a subprocess, on test_cli's tiny scenes."""
from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest

from test_cli import BUILD, RENDER, _env, _one_clear_line

pytestmark = pytest.mark.blender
SIZE = ("--resolution", "256x256")


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    pytest.importorskip("bpy")
    d = tmp_path_factory.mktemp("cli_ref")
    proc = subprocess.run([sys.executable, "-c", BUILD, str(d)], env=_env(d), capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return d


def run(scenes, *args):
    proc = subprocess.run([sys.executable, str(RENDER), *map(str, args), "--no-progress"], cwd=scenes,
                          env=_env(scenes), capture_output=True, text=True, timeout=180)
    return proc.returncode, proc.stdout, proc.stderr


@pytest.fixture(scope="module")
def reference(scenes):
    """A 16-sample render of ok.blend (seed 3, independent samples) as the reference, 256x256:
    a path-tracer item of 4 batches of 131072 paths is 8 passes, so progress lines come every
    8 passes or more (a render of 8 passes is one unit per worker: a single line)."""
    code, out, err = run(scenes, "ok.blend", "-o", "ref.exr", "--samples", "16", "--seed", "3",
                         "--pattern", "random", *SIZE)
    assert code == 0, err
    return scenes / "ref.exr"


def _progress_lines(out):
    return [(int(n), float(e)) for e, n in
            re.findall(r"^relMSE (\S+) \(eps 0\.01\) at (\d+) samples", out, re.MULTILINE)]


def _final_relmse(out):
    return float(re.search(r"relMSE (\S+) \(eps 0\.01\)$", out.strip().splitlines()[-1]).group(1))


def test_relmse_falls_as_samples_grow(scenes, reference):
    code, out, err = run(scenes, "ok.blend", "-o", "x.exr", "--samples", "32", "--seed", "4",
                         "--pattern", "random", "--reference", reference, *SIZE)
    assert code == 0, err
    lines = _progress_lines(out)
    counts = [n for n, _ in lines]
    assert len(lines) >= 2 and counts == sorted(set(counts)) and counts[-1] == 32, out
    # Independent samples (--pattern random) and seeds, so E[relMSE] = v (1/n + 1/16) with v
    # the per-sample relative variance: each line must follow that curve (fitted on the last
    # one) to 25 %.
    v = lines[-1][1] / (1 / 32 + 1 / 16)
    for n, e in lines:
        assert e == pytest.approx(v * (1 / n + 1 / 16), rel=0.25), (n, e, lines)
    assert _final_relmse(out) == pytest.approx(lines[-1][1], rel=1e-3)


def test_same_seed_matches_reference_exactly(scenes, reference):
    """Same seed and samples reproduce the reference: relMSE ~ 0 shows that rows, channels
    and pixels line up (float32 storage is the only difference)."""
    code, out, err = run(scenes, "ok.blend", "-o", "y.exr", "--samples", "16", "--seed", "3",
                         "--pattern", "random", "--reference", reference, *SIZE)
    assert code == 0, err
    assert _final_relmse(out) < 1e-12
    assert re.search(r", noise \d+\.\d+", out.strip().splitlines()[-1])


def test_noise_target_stops_the_render(scenes):
    code, out, err = run(scenes, "ok.blend", "-o", "z.exr", "--samples", "4096", "--noise-target", "0.5")
    assert code == 0, err
    last = out.strip().splitlines()[-1]
    assert "stopped at the noise target" in last, last
    samples = int(re.search(r"(\d+) samples", last).group(1))
    assert 4 <= samples < 4096
    noise = float(re.search(r"noise (\d+\.\d+)", last).group(1))
    assert noise <= 0.5


def test_reference_of_the_wrong_size(scenes, reference):
    code, out, err = run(scenes, "ok.blend", "-o", "w.exr", "--samples", "1", "--resolution", "20x12",
                         "--reference", reference)
    assert code == 2
    _one_clear_line(err, "256x256", "20x12")


@pytest.mark.parametrize("name, words", [
    ("missing.exr", ["reference not found"]),
    ("ok.blend", ["reference must be", ".exr"]),
    ("luma.exr", ["no R, G, B channels"]),
])
def test_bad_reference(scenes, name, words):
    from ember.engine import imageio
    imageio.write_exr(scenes / "luma.exr", {"Y": np.zeros((16, 24), np.float32)})
    code, out, err = run(scenes, "ok.blend", "-o", "v.exr", "--reference", name)
    assert code == 2
    _one_clear_line(err, *words)


@pytest.mark.parametrize("value", ["-0.1", "lots", "inf"])
def test_bad_noise_target(scenes, value):
    code, out, err = run(scenes, "ok.blend", "--noise-target", value)
    assert code == 2
    _one_clear_line(err, "--noise-target")
