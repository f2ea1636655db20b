"""Read-only arrays published by the render process to its worker processes.

One POSIX shared-memory segment per published version holds all of its arrays, each at an
aligned offset; a worker maps it and sees read-only views (a 10-million-photon map is
shared, not pickled to every worker). Arrays are named: a later version of a name replaces
the earlier one, other names stay current (photon maps, then radiance photons beside them).
The render process owns the segments and unlinks them on every exit path
(`Publisher.release`, also run by the session's `finally`; `unlink_all` where a signal ends
the process at once); workers only attach and close. A process killed outright (SIGKILL, to
its whole process group: its resource tracker dies with it) cannot clean up, so segments are
named `ember_<owner pid>_<random>` and the next process that creates one first removes those
whose owner is gone (`remove_orphans`).

Python 3.11's resource tracker registers every SharedMemory it sees, also in processes that
merely attach, and would unlink the segment when such a process exits (cpython issue 82300):
attaching processes unregister it again.
"""
from __future__ import annotations

import os
import secrets
from multiprocessing import resource_tracker, shared_memory

import numpy as np

_ALIGN = 64
_OWNED: dict = {}  # name -> SharedMemory this process created and has not unlinked yet
PREFIX = "ember_"
SHM_DIR = "/dev/shm"  # where Linux keeps POSIX shared memory (elsewhere orphans are not looked for)
_SWEPT = [False]  # remove_orphans ran in this process


def create(size: int) -> shared_memory.SharedMemory:
    """A new segment this process owns: unlink() it, or unlink_all() on an abrupt exit."""
    if not _SWEPT[0]:
        _SWEPT[0] = True
        remove_orphans()
    while True:
        try:
            shm = shared_memory.SharedMemory(create=True, size=size,
                                             name=f"{PREFIX}{os.getpid()}_{secrets.token_hex(6)}")
            break
        except FileExistsError:  # pragma: no cover - 48 random bits
            continue
    _OWNED[shm.name] = shm
    return shm


def owner(name: str) -> int | None:
    """The pid in a segment name this module made, else None."""
    if not name.startswith(PREFIX):
        return None
    pid = name[len(PREFIX):].split("_", 1)[0]
    return int(pid) if pid.isdigit() else None


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def remove_orphans(directory: str = SHM_DIR) -> list[str]:
    """Unlink the segments of processes that no longer run (killed outright); their names."""
    try:
        names = os.listdir(directory)
    except OSError:
        return []
    removed = []
    for name in names:
        pid = owner(name)
        if pid is None or pid == os.getpid() or _alive(pid):
            continue
        try:
            os.unlink(os.path.join(directory, name))
            removed.append(name)
        except OSError:  # gone meanwhile, or not ours to remove
            pass
    return removed


def unlink(shm) -> None:
    """Unlink first (the name goes; mappings stay valid), then unmap: a view still alive in
    this process makes close() fail, which must not keep the segment from being unlinked."""
    _OWNED.pop(shm.name, None)
    try:
        shm.unlink()
    except FileNotFoundError:  # pragma: no cover - already gone
        pass
    try:
        shm.close()
    except BufferError:  # pragma: no cover - a view is alive: unmapped at exit
        pass


def unlink_all() -> None:
    """Unlink every segment this process still owns: for an exit that skips the owners'
    cleanup (os._exit after a signal), so that none outlives the process."""
    for shm in list(_OWNED.values()):
        try:
            unlink(shm)
        except Exception:  # pragma: no cover - best effort on the way out
            pass


def _layout(arrays: dict[str, np.ndarray]):
    """{name: (offset, shape, dtype str)} and the total size in bytes."""
    spec, offset = {}, 0
    for name, a in arrays.items():
        spec[name] = (offset, a.shape, a.dtype.str)
        offset += -(-a.nbytes // _ALIGN) * _ALIGN
    return spec, max(offset, 1)


def views(buffer, spec: dict) -> dict[str, np.ndarray]:
    """Read-only arrays over `buffer` laid out by `spec`."""
    out = {}
    for name, (offset, shape, dtype) in spec.items():
        a = np.ndarray(shape, np.dtype(dtype), buffer=buffer, offset=offset)
        a.flags.writeable = False
        out[name] = a
    return out


class Publisher:
    """Render-process side: `publish` copies arrays into a new segment and returns the handle
    ((segment name, spec)) that workers pass to `attach`."""

    def __init__(self):
        self.segments: list[shared_memory.SharedMemory] = []
        self.names: dict[str, shared_memory.SharedMemory] = {}  # array name -> latest segment

    def publish(self, arrays: dict[str, np.ndarray]):
        """A new version of the named arrays (others published before stay current). A segment
        is unlinked once every array in it has a newer version: workers that still map it
        keep their mapping until they move on (POSIX), new ones never see it."""
        spec, size = _layout(arrays)
        shm = create(size)
        self.segments.append(shm)  # at once: release() unlinks it whatever interrupts below
        replaced = {self.names[name].name for name in arrays if name in self.names}
        self.names.update(dict.fromkeys(arrays, shm))
        live = {seg.name for seg in self.names.values()}
        for seg in [seg for seg in self.segments if seg.name in replaced and seg.name not in live]:
            self.segments.remove(seg)
            unlink(seg)
        for name, a in arrays.items():
            offset, shape, dtype = spec[name]
            np.ndarray(shape, np.dtype(dtype), buffer=shm.buf, offset=offset)[...] = a
        return shm.name, spec

    def release(self) -> None:
        self.names.clear()
        while self.segments:
            unlink(self.segments.pop())


class Attachment:
    """Worker side: the arrays of one published version; `close` when a newer one arrives."""

    def __init__(self, handle):
        name, spec = handle
        self.shm = shared_memory.SharedMemory(name=name)
        try:
            resource_tracker.unregister(self.shm._name, "shared_memory")
        except Exception:  # pragma: no cover - tracker details differ across versions
            pass
        self.arrays = views(self.shm.buf, spec)

    def close(self) -> None:
        self.arrays = {}
        try:
            self.shm.close()
        except BufferError:  # a view is still referenced somewhere: the OS frees it at exit
            pass
