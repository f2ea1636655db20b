"""Distributed rendering on Dask (`dask.distributed`): frames and sample ranges as tasks.

The caller (render.py --scheduler) cuts the job into tasks - one per frame, or per sample
range [K, K + S) of a frame when --chunk-samples S is less than the frame's samples - and
submits them to a Dask scheduler. A task runs on a Dask worker as `render.py` in a subprocess
(a fresh interpreter with the bpy module: bpy is one scene per process and not thread-safe,
and Dask runs tasks on threads) on the same .blend - a path every node sees, or its bytes
sent with the task - and returns the partial EXR's bytes. The caller merges the parts of a
frame (engine/merge.py) and writes it as soon as all of them are in.

Dask reschedules a task whose worker dies on another worker (the scheduler's
allowed-failures); since a part is a pure function of (scene, seed, frame, sample range), a
retried task returns the same bytes and the merged image is unchanged. A task that fails
(render.py exits non-zero) raises RenderTaskError with render.py's one-line message, which
ends the job: a render error would fail again anywhere.

`render_task` is pickled by value (cloudpickle: Dask does so for functions of `__main__`,
hence its __module__), so workers need no Ember package on their import path - only the bpy
module in their Python and render.py at the path given. It uses nothing but the standard
library and raises a plain RuntimeError (prefixed TASK_ERROR) that the caller turns back
into RenderTaskError.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass


class RenderTaskError(RuntimeError):
    """render.py failed on a worker; the message is its one line."""


TASK_ERROR = "ember render task failed: "  # render_task's errors start so (it cannot name the class)


@dataclass(frozen=True)
class Task:
    frame: int
    offset: int  # first sample index
    samples: int

    @property
    def key(self) -> str:
        return f"ember-frame{self.frame}-samples{self.offset}-{self.offset + self.samples}"

    def describe(self) -> str:
        return f"frame {self.frame} samples [{self.offset}, {self.offset + self.samples})"


def plan(frames, samples: int, offset: int = 0, chunk: int = 0) -> list[Task]:
    """Tasks for `frames`, each frame's samples [offset, offset + samples) cut into ranges of
    at most `chunk` samples (0: whole frames)."""
    step = chunk if chunk > 0 else samples
    return [Task(f, k, min(step, offset + samples - k)) for f in frames for k in range(offset, offset + samples, step)]


def render_task(task: dict, render_py: str, blend: str | None, blend_bytes: bytes | None,
                options: list, python: str | None = None) -> dict:
    """On a Dask worker: render one Task with render.py; {"exr": bytes, "line": summary,
    "warnings": its Warning lines, for the caller to show}."""
    import ctypes
    import glob
    import os
    import signal
    import subprocess
    import sys
    import tempfile

    failed = "ember render task failed: "  # TASK_ERROR (no module globals: pickled by value)

    def die_with_parent():  # a killed worker takes its render with it (Linux)
        if sys.platform.startswith("linux"):
            try:
                ctypes.CDLL(None).prctl(1, signal.SIGKILL)
            except (OSError, AttributeError):
                pass

    with tempfile.TemporaryDirectory(prefix="ember-task-") as tmp:
        if blend_bytes is not None:
            blend = os.path.join(tmp, "scene.blend")
            with open(blend, "wb") as fh:
                fh.write(blend_bytes)
        cmd = [python or sys.executable, render_py, blend, *options, "--frames", str(task["frame"]),
               "--samples", str(task["samples"]), "--sample-offset", str(task["offset"]),
               "--output", os.path.join(tmp, "part#.exr"), "--no-progress"]
        proc = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp, preexec_fn=die_with_parent,
                              stdin=subprocess.DEVNULL)
        if proc.returncode != 0:
            lines = [l for l in proc.stderr.splitlines() if l.startswith("render.py: error:")]
            message = lines[-1][len("render.py: error: "):] if lines else (proc.stderr.strip().splitlines() or
                                                                          [f"exit code {proc.returncode}"])[-1]
            raise RuntimeError(failed + message)
        parts = glob.glob(os.path.join(tmp, "part*.exr"))
        if len(parts) != 1:
            raise RuntimeError(f"{failed}render.py wrote {len(parts)} files, expected one")
        with open(parts[0], "rb") as fh:
            data = fh.read()
    summary = [l for l in proc.stdout.splitlines() if l.startswith("Ember: ") and " -> " in l]
    warnings = list(dict.fromkeys(l for l in proc.stdout.splitlines() if l.startswith("Warning: ")))
    return {"exr": data, "line": summary[-1] if summary else "", "warnings": warnings}


render_task.__module__ = "__main__"  # Dask then pickles it by value (see the module docstring)


def connect(scheduler: str):
    """A dask.distributed Client for 'tcp://host:port' or 'local:N' (a LocalCluster of N
    single-threaded worker processes on loopback). Returns (client, cluster or None)."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise RenderTaskError("--scheduler needs dask.distributed: pip install 'distributed' in this Python")
    if scheduler.startswith("local:"):
        n = int(scheduler.split(":", 1)[1])
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                               dashboard_address=None)
        return Client(cluster), cluster
    return Client(scheduler, timeout="30s"), None


def submit(client, tasks: list[Task], render_py: str, blend: str | None, blend_bytes: bytes | None,
           options: list, python: str | None = None) -> dict:
    """Submit every task; {future: Task}. The .blend's bytes go once to every worker."""
    payload = client.scatter(blend_bytes, broadcast=True) if blend_bytes is not None else None
    return {client.submit(render_task, dataclasses.asdict(t), render_py, blend, payload, list(options), python,
                          key=t.key, pure=False): t for t in tasks}


def gather(futures: dict, on_task=None):
    """Yield (Task, result) as tasks finish (any order); on_task(done, total, task, result)
    after each. Raises RenderTaskError (a failed render) or Dask's KilledWorker (a task
    whose workers kept dying)."""
    from distributed import as_completed

    total = len(futures)
    for done, fut in enumerate(as_completed(list(futures)), 1):
        task = futures[fut]
        try:
            result = fut.result()
        except RuntimeError as e:
            if not str(e).startswith(TASK_ERROR):
                raise
            for other in futures:
                other.cancel()
            raise RenderTaskError(f"{task.describe()}: {str(e)[len(TASK_ERROR):]}")
        if on_task is not None:
            on_task(done, total, task, result)
        yield task, result
