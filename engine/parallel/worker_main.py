"""Entry point of an Ember worker process: `python worker_main.py <package root>`.

Loads the package by file path under a private name (the parent may know it as `ember` or
as Blender's `bl_ext.<repo>.ember`) and serves batch requests on stdin/stdout.

Workers ignore SIGINT and SIGTERM from the start (a terminal's Ctrl-C, `timeout`, `docker
stop` and farm managers signal the whole process group; the render process alone decides how
to stop, and a worker dying first would be reported as a failure) and, on Linux, are killed
with their parent.
"""
import signal

for _sig in (signal.SIGINT, signal.SIGTERM):  # before any import: no KeyboardInterrupt tracebacks
    signal.signal(_sig, signal.SIG_IGN)

import importlib.util  # noqa: E402
import pathlib  # noqa: E402
import sys  # noqa: E402


def _die_with_parent() -> None:
    """PR_SET_PDEATHSIG: the kernel sends SIGKILL when the render process ends, however it ends."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # 1 = PR_SET_PDEATHSIG
        except (OSError, AttributeError):  # pragma: no cover - not glibc
            pass


def main() -> None:
    _die_with_parent()
    root = pathlib.Path(sys.argv[1])
    spec = importlib.util.spec_from_file_location("ember_worker", root / "__init__.py",
                                                  submodule_search_locations=[str(root)])
    package = importlib.util.module_from_spec(spec)
    sys.modules["ember_worker"] = package
    spec.loader.exec_module(package)
    from ember_worker.engine.parallel.workers import serve

    try:
        serve(sys.stdin.buffer, sys.stdout.buffer)
    except (BrokenPipeError, EOFError, ConnectionResetError):  # the render process is gone
        import os

        os._exit(0)


if __name__ == "__main__":
    main()
