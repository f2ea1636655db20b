"""Worker processes that run integrator work items, so that every CPU core renders.

Threads do not scale here: a wavefront bounce is hundreds of mid-sized NumPy operations
and the GIL is held between them, so a second thread adds almost nothing. Each
worker is a separate Python process started with the parent's interpreter
(`engine/parallel/worker_main.py`), which loads this package by file path, receives the
Scene as plain arrays (no class references, so it works whatever name Blender imported us
under), builds its own Embree scene and integrator (engine/tracer.py) and then answers
requests over its pipes.

Messages are length-prefixed pickles. Parent -> worker: ("cancel", segment name) once, the
pool's cancel counter (below); ("scene", parts) at the start of every render (part name ->
plain arrays, or None for a part unchanged since the last scene: persistent data; a part of
SHARED_PART bytes or more - a mesh - comes as ("shared", handle, its other fields), its arrays
in a shared-memory segment that the parent unlinks once every worker has built), ("run",
stage as a dict, item, epoch), ("install", version, shared-memory handle), `None` to quit.
Worker -> parent, one answer per scene or run, in order: ("done", result...), ("cancelled",)
or ("error", text); a scene's result is what it built ({"embree": 0 or 1, ...}). Installs
and the counter are not answered: the pipe is ordered, so every run sent after an install
sees the installed arrays.

Cancel without killing (`WorkerPool.cancel`): the parent bumps a counter in a one-word
shared-memory segment; a run whose epoch (the counter when it was sent) is older stops at
its integrator's next stop check (a bounce) or is answered at once if not started, so the
workers are free again within a fraction of a second and keep everything they built.

Persistent data: a pool whose render asked for it (Settings.persistent) is kept after the
render (`keep`) and taken by the next one (`pool_for`) with the same number of workers; its
workers then rebuild only what changed (engine/tracer.py). A cancelled or failed render
kills its pool; one without persistent data closes it and any kept one.

Workers ignore SIGINT and SIGTERM: a terminal's Ctrl-C or a farm's SIGTERM reaches the whole
process group, and the render process alone decides how to stop (it kills the workers). A worker whose parent dies sees
its stdin close and exits.
"""
from __future__ import annotations

import atexit
import io
import dataclasses
import os
import pathlib
import pickle
import signal
import struct
import subprocess
import sys
import threading
from concurrent.futures import Future, wait

import numpy as np

from ..errors import Cancelled, EmberError
from ..integrators.base import Stage
from ..scene import part_digests, scene_from_plain, to_plain
from ..tracer import BUILDS, Tracer
from .shared import Attachment, Publisher, create as create_segment, unlink as unlink_segment

_HEADER = struct.Struct("<Q")
SHARED_PART = 1 << 20  # bytes of arrays from which a scene part reaches the workers through shared memory
ROOT = pathlib.Path(__file__).resolve().parents[2]


def write_message(stream, obj) -> None:
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(_HEADER.pack(len(data)))
    stream.write(data)
    stream.flush()


# This package's name here: `ember` in tests and render.py, Blender's `bl_ext.<repo>.ember`, or
# a worker's private `ember_worker` (worker_main.py).
_PACKAGE = __name__.rsplit(".engine.", 1)[0]


class _Unpickler(pickle.Unpickler):
    """Reads classes of this package (node graphs, image texels in a scene part) under the name
    this process loaded it as, whatever the sender's."""

    def find_class(self, module, name):
        head, sep, tail = module.partition(".engine.")
        if sep and head != _PACKAGE:
            module = f"{_PACKAGE}.engine.{tail}"
        return super().find_class(module, name)


def read_message(stream):
    header = stream.read(_HEADER.size)
    if len(header) < _HEADER.size:
        return None
    (size,) = _HEADER.unpack(header)
    return _Unpickler(io.BytesIO(stream.read(size))).load()


def serve(fin, fout) -> None:
    """The worker's loop (runs in the child process)."""
    for sig in (signal.SIGINT, signal.SIGTERM):  # the render process decides (worker_main.py)
        signal.signal(sig, signal.SIG_IGN)
    tracer, plain = None, {}
    epoch = None  # the pool's cancel counter (a one-element view of shared memory)
    held = {}  # scene part name -> the Attachment its arrays live in (big parts)
    current = {}  # array name -> the Attachment holding its latest version
    deferred = None  # an install's failure, reported as the next request's answer
    try:
        while True:
            msg = read_message(fin)
            if msg is None:
                return
            try:
                if msg[0] == "scene":
                    changed = {name for name, part in msg[1].items() if part is not None}
                    replaced = [held.pop(name) for name in changed if name in held]
                    for name in changed:
                        part = msg[1][name]
                        if isinstance(part, tuple):  # ("shared", handle, fields not in it)
                            held[name] = Attachment(part[1])
                            part = {**part[2], **held[name].arrays}
                        plain[name] = part
                    for attachment in set(current.values()):  # the last render's published arrays
                        attachment.close()
                    current = {}
                    before = dict(BUILDS)
                    tracer = Tracer(scene_from_plain(plain), tracer, changed)
                    for attachment in replaced:  # the parts they held are gone with the old tracer
                        attachment.close()
                    write_message(fout, ("done", {k: BUILDS[k] - before[k] for k in BUILDS}))
                    continue
                if msg[0] == "cancel":
                    counter = Attachment((msg[1], {"epoch": (0, (1,), "<i8")}))
                    epoch = counter.arrays["epoch"]
                    continue
                if msg[0] == "install":
                    _, version, handle = msg
                    try:
                        new = Attachment(handle)
                    except FileNotFoundError:
                        # Published again before this worker got here: a segment is unlinked
                        # once every array in it has a newer version, whose install follows.
                        continue
                    tracer.install(version, new.arrays)
                    replaced = {current[name] for name in new.arrays if name in current}
                    current.update(dict.fromkeys(new.arrays, new))
                    for old in replaced - set(current.values()):
                        old.close()  # every array it held has a newer version
                    continue
                if deferred is not None:
                    write_message(fout, ("error", deferred))
                    deferred = None
                    continue
                _, stage, item, sent = msg
                stop = None if epoch is None else _Stale(epoch, sent)
                if stop is not None and stop.is_set():
                    write_message(fout, ("cancelled",))
                    continue
                try:
                    result = tracer.run(Stage(**stage), item, stop)
                except Cancelled:
                    write_message(fout, ("cancelled",))
                    continue
                write_message(fout, ("done",) + result)
            except Exception:  # reported to the parent, which raises it on its side
                import traceback

                # Every request gets exactly one answer; an install gets none (the parent's
                # reader pairs answers with requests in order), so its failure waits.
                if msg[0] == "install":
                    deferred = traceback.format_exc()
                else:
                    write_message(fout, ("error", traceback.format_exc()))
    finally:
        for attachment in set(current.values()):
            attachment.close()


class _Stale:
    """A work item's stop event: set once the pool's cancel counter has moved past the epoch
    the item was sent in (what integrators poll every bounce)."""

    def __init__(self, counter, sent: int):
        self.counter, self.sent = counter, sent

    def is_set(self) -> bool:
        return int(self.counter[0]) != self.sent


def available_cores() -> int:
    """CPUs this process may run on: its affinity mask (taskset, a farm's cgroup pinning)."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except (AttributeError, OSError):  # not Linux
        return os.cpu_count() or 1


STARTED = [0]  # worker processes this process has started (persistent-data tests)


def can_spawn() -> bool:
    """A plain Python interpreter is needed; Blender's own binary cannot run the worker."""
    exe = pathlib.Path(sys.executable or "")
    return exe.is_file() and not exe.name.lower().startswith("blender")


class _Worker:
    def __init__(self):
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join([p for p in sys.path if p])
        self.proc = subprocess.Popen([sys.executable, "-u", str(ROOT / "engine" / "parallel" / "worker_main.py"),
                                      str(ROOT)],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env)
        STARTED[0] += 1
        self.pending: list[Future] = []
        self.lock = threading.Lock()
        self.dead = False
        self.reader = threading.Thread(target=self._read, daemon=True, name="ember-worker-reader")
        self.reader.start()

    def _read(self):
        while True:
            try:
                msg = read_message(self.proc.stdout)
            except (OSError, EOFError, pickle.UnpicklingError):
                msg = None
            if msg is None:
                self._fail(EmberError("An Ember worker process ended unexpectedly (see the console)."))
                return
            with self.lock:
                fut = self.pending.pop(0) if self.pending else None
            if fut is None:  # an answer nobody asked for: the pipe is out of step
                self._fail(EmberError("An Ember worker process answered out of turn (see the console)."))
                return
            if msg[0] == "done":
                fut.set_result(msg[1:])
            elif msg[0] == "cancelled":
                fut.set_exception(Cancelled())
            else:
                fut.set_exception(RuntimeError("Ember worker failed:\n" + msg[1]))

    def _fail(self, exc):
        with self.lock:
            self.dead = True
            pending, self.pending = self.pending, []
        for fut in pending:
            if not fut.done():
                fut.set_exception(exc)

    def request(self, msg) -> Future:
        fut = Future()
        with self.lock:
            if self.dead:
                fut.set_exception(EmberError("An Ember worker process ended unexpectedly (see the console)."))
                return fut
            self.pending.append(fut)
            write_message(self.proc.stdin, msg)
        return fut

    def submit(self, stage: dict, item: int, epoch: int) -> Future:
        return self.request(("run", stage, item, epoch))

    def send(self, msg) -> None:
        """A message that gets no answer (install, the cancel counter)."""
        with self.lock:
            write_message(self.proc.stdin, msg)

    def load(self) -> int:
        with self.lock:
            return len(self.pending)

    def close(self, kill: bool):
        try:
            if kill:
                self.proc.kill()
            else:
                write_message(self.proc.stdin, None)
                self.proc.stdin.close()
            self.proc.wait(timeout=10)
        except (OSError, ValueError, subprocess.TimeoutExpired):
            self.proc.kill()


class WorkerPool:
    """n worker processes running the work items of one scene's integrator (`load`); `submit`
    returns a Future of (result, rays, embree_seconds, seconds). Requests go to the least-loaded worker."""

    def __init__(self, n: int):
        self.n = n
        self.counter = create_segment(8)  # the cancel epoch
        self.workers = []
        self.digests = {}  # part name -> digest of the scene part the workers hold
        try:  # interrupted while the workers start (a signal): nothing may outlive the pool
            self.epoch = np.ndarray((1,), np.int64, buffer=self.counter.buf)
            self.epoch[0] = 0
            for _ in range(n):
                self.workers.append(_Worker())
            for w in self.workers:
                w.send(("cancel", self.counter.name))
        except BaseException:
            self.close(kill=True)
            raise

    def load(self, scene) -> dict:
        """Send `scene`, only the parts that changed since the last load; wait until every
        worker has built it. Returns what one worker built ({"embree": 0 or 1, ...})."""
        now = part_digests(scene)
        parts = {name: (to_plain(getattr(scene, name)) if now[name] != self.digests.get(name) else None)
                 for name in now}
        # A big part (a mesh) goes through shared memory: written once, not pickled down every
        # pipe. The segment is unlinked once every worker has mapped it.
        shared = Publisher()
        try:
            for name, part in parts.items():
                arrays = {k: v for k, v in (part or {}).items() if isinstance(v, np.ndarray) and v.dtype != object}
                if sum(a.nbytes for a in arrays.values()) >= SHARED_PART:
                    rest = {k: v for k, v in part.items() if k not in arrays}
                    parts[name] = ("shared", shared.publish(arrays), rest)
            futures = [w.request(("scene", parts)) for w in self.workers]
            self.digests = {}  # unknown until every worker has it
            built = [f.result()[0] for f in futures]
        finally:
            shared.release()
        self.digests = now
        return {k: max(b[k] for b in built) for k in built[0]}

    def alive(self) -> bool:
        return all(w.proc.poll() is None and not w.dead for w in self.workers)

    def submit(self, stage, item: int) -> Future:
        plain = dataclasses.asdict(stage)  # no class references across the pipe
        return min(self.workers, key=_Worker.load).submit(plain, item, int(self.epoch[0]))

    def install(self, version: int, handle) -> None:
        """Every worker installs the published arrays before its next item."""
        for w in self.workers:
            w.send(("install", version, handle))

    def cancel(self, timeout: float = 10.0) -> bool:
        """Stop every item sent so far (running ones at their next stop check) and wait until
        all are answered; the workers stay up with what they built. False if they did not
        answer in time (the caller then closes the pool)."""
        self.epoch[0] += 1
        pending = []
        for w in self.workers:
            with w.lock:
                pending += w.pending
        not_done = wait(pending, timeout=timeout).not_done
        return not not_done and self.alive()

    def close(self, kill: bool = False) -> None:
        for w in self.workers:
            w.close(kill)
        self.epoch = None
        unlink_segment(self.counter)


_kept: list = []  # the pool a persistent render left for the next one (at most one)


def pool_for(n: int) -> WorkerPool:
    """The kept pool if it has n live workers, else a new one (the kept one closed)."""
    pool = _kept.pop() if _kept else None
    if pool is not None and pool.n == n and pool.alive():
        return pool
    if pool is not None:
        pool.close(kill=True)
    return WorkerPool(n)


def keep(pool: WorkerPool) -> None:
    """Keep `pool` for the next render (closing any other kept one)."""
    release_kept()
    _kept.append(pool)


def release_kept() -> None:
    """Close the kept pool (a render without persistent data; process exit)."""
    while _kept:
        _kept.pop().close(kill=False)


atexit.register(release_kept)
