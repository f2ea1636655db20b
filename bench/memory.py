"""Peak memory of a render: render.py in a separate process per measurement.

Two numbers, both read from /proc every POLL seconds while it runs: the render process's
own peak resident set (VmHWM, the kernel's high-water mark, so nothing is missed before the
last poll; not ru_maxrss, which also counts the parent's pages shared before exec), and the
peak of the summed resident sets of its whole process tree (render process plus Ember's
worker processes; a spike shorter than POLL can be missed). A tiny render of the same .blend gives the baseline: Python, bpy, the add-on,
the scene and its export, so what a resolution adds is the difference.
"""
from __future__ import annotations

import os
import pathlib
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
POLL = 0.05


def _status_kib(pid: int, field: str = "VmRSS") -> int:
    try:
        with open(f"/proc/{pid}/status") as fh:
            for line in fh:
                if line.startswith(field + ":"):
                    return int(line.split()[1])
    except OSError:
        pass
    return 0


def _children(pid: int) -> list[int]:
    out = []
    try:
        for task in os.listdir(f"/proc/{pid}/task"):
            with open(f"/proc/{pid}/task/{task}/children") as fh:
                out += [int(c) for c in fh.read().split()]
    except OSError:
        pass
    return out


def tree_rss_kib(pid: int) -> int:
    total, stack = 0, [pid]
    while stack:
        p = stack.pop()
        total += _status_kib(p)
        stack += _children(p)
    return total


def measure(blend, width: int, height: int, samples: int = 1) -> dict:
    """Render blend at width x height with render.py; peaks in MiB, seconds, load average."""
    with tempfile.TemporaryDirectory(prefix="ember_mem_") as tmp:
        env = dict(os.environ, BLENDER_USER_RESOURCES=os.path.join(tmp, "bur"))
        cmd = [sys.executable, str(ROOT / "render.py"), str(blend), "-o", os.path.join(tmp, "m.exr"),
               "--resolution", f"{width}x{height}", "--samples", str(samples), "--no-progress"]
        load = os.getloadavg()[0]
        t0 = time.perf_counter()
        with open(os.path.join(tmp, "stderr.txt"), "w+") as err:
            proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=err)
            peak_tree = peak_main = 0
            while proc.poll() is None:
                peak_tree = max(peak_tree, tree_rss_kib(proc.pid))
                peak_main = max(peak_main, _status_kib(proc.pid, "VmHWM"))
                time.sleep(POLL)
            seconds = time.perf_counter() - t0
            err.seek(0)
            message = err.read()
    if proc.returncode:
        raise RuntimeError(f"render.py exited {proc.returncode}: {message.strip()[-300:]}")
    return {"resolution": f"{width}x{height}", "samples": samples,
            "peak_tree_mib": max(peak_tree, peak_main) / 1024, "peak_main_mib": peak_main / 1024,
            "seconds": seconds, "load": load}
