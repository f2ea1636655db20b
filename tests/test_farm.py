"""Distributed rendering on Dask: a LocalCluster of two worker processes on
loopback renders a short animation and split frames; the images equal the local renders
(split frames to float32 rounding, whole frames bit for bit), also when one worker is killed
in the middle of the job. About 40 s on two busy cores (bpy starts once per task)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from test_pipeline import BUILD, F32_ULP, ROOT, RENDER, _env, read

pytestmark = pytest.mark.blender
distributed = pytest.importorskip("distributed")

OPTIONS = ("--seed", "3", "--threads", "1")


@pytest.fixture(scope="module")
def farm_dir(tmp_path_factory):
    pytest.importorskip("bpy")
    d = tmp_path_factory.mktemp("farm")
    proc = subprocess.run([sys.executable, "-c", BUILD, str(ROOT), str(d)], env=_env(d), capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    # The local renders every farm result is compared with.
    proc = subprocess.run([sys.executable, str(RENDER), "anim.blend", "--frames", "1-2", "--samples", "16", *OPTIONS,
                           "-o", "local_#.exr"], cwd=d, env=_env(d), capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0, proc.stderr
    return d


def test_animation_and_split_frames_on_a_local_cluster(farm_dir):
    """render.py --scheduler local:2: frame 1 whole, frame 2 in two sample ranges."""
    d = farm_dir
    for frames, chunk, out in (("1", "16", "farm_whole_#.exr"), ("2", "8", "farm_split_#.exr")):
        proc = subprocess.run([sys.executable, str(RENDER), "anim.blend", "--frames", frames, "--samples", "16",
                               "--chunk-samples", chunk, *OPTIONS, "--scheduler", "local:2", "-o", out],
                              cwd=d, env=_env(d), capture_output=True, text=True, timeout=180)
        assert proc.returncode == 0, proc.stderr[-3000:]
        assert f"frame {frames} -> " in proc.stdout
        # auto (the default) chooses once for the parts of a split frame, not per part
        assert ("auto chose" in proc.stdout and "(once, for every part)" in proc.stdout) == (chunk == "8")
    whole, _ = read(d / "farm_whole_1.exr")
    np.testing.assert_array_equal(whole, read(d / "local_1.exr")[0])
    split, header = read(d / "farm_split_2.exr")
    assert header["ember/mergedParts"] == 2 and header["ember/sampleRange"] == "[0, 16)"
    np.testing.assert_allclose(split, read(d / "local_2.exr")[0], rtol=2 * F32_ULP, atol=0)


def test_a_killed_worker_changes_nothing(farm_dir, monkeypatch):
    """SIGKILL one of two workers while it renders: Dask reruns its task elsewhere and every
    frame equals the local render."""
    from ember.engine.imageio import read_exr
    from ember.engine.merge import Part, merge
    from ember.engine.parallel import farm

    d = farm_dir
    monkeypatch.chdir(d)
    tasks = farm.plan([1, 2], 16, 0, 8)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        pids = client.run(os.getpid)
        futures = farm.submit(client, tasks, str(RENDER), str(d / "anim.blend"), None, list(OPTIONS))
        deadline = time.monotonic() + 60
        while not any(client.processing().values()):
            assert time.monotonic() < deadline
            time.sleep(0.05)
        time.sleep(1.0)  # render.py is running by now
        victim = next(w for w, keys in client.processing().items() if keys)
        os.kill(pids[victim], signal.SIGKILL)
        results = list(farm.gather(futures))
        assert pids[victim] not in client.run(os.getpid).values()  # it died (the nanny started another)
    assert sorted(t.key for t, _ in results) == sorted(t.key for t in tasks)
    for frame in (1, 2):
        parts = []
        for i, (task, result) in enumerate(r for r in results if r[0].frame == frame):
            path = d / f"killed_{frame}_{i}.exr"
            path.write_bytes(result["exr"])
            parts.append(Part.from_exr(path.name, *read_exr(path)))
        image, _ = merge(parts)
        np.testing.assert_allclose(image, read(d / f"local_{frame}.exr")[0], rtol=2 * F32_ULP, atol=0)


def test_task_plan_and_options():
    from ember.engine.parallel import farm
    from test_pipeline import _render_py

    assert [(t.frame, t.offset, t.samples) for t in farm.plan([1, 2], 10, 4, 4)] == \
        [(1, 4, 4), (1, 8, 4), (1, 12, 2), (2, 4, 4), (2, 8, 4), (2, 12, 2)]
    assert [(t.frame, t.offset, t.samples) for t in farm.plan([7], 10)] == [(7, 0, 10)]
    rp = _render_py()
    argv = ["x.blend", "--frames", "1-3", "--seed", "4", "--no-progress", "--output=o_#.exr", "--send-blend",
            "--scheduler", "local:2", "--radiance-photons", "off", "--chunk-samples", "8", "--samples", "16"]
    assert rp.task_options(argv) == ["--seed", "4", "--radiance-photons", "off"]


def test_a_failing_task_reports_its_one_line(tmp_path):
    """What render.py says on the worker reaches the caller (RenderTaskError)."""
    from ember.engine.parallel import farm

    with pytest.raises(RuntimeError) as e:
        farm.render_task({"frame": 1, "offset": 0, "samples": 1}, str(RENDER), str(tmp_path / "gone.blend"), None, [])
    assert str(e.value).startswith(farm.TASK_ERROR) and "file not found" in str(e.value)
