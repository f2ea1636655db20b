"""Entry point of an Ember worker process: `python worker_main.py <package root>`.

Loads the package by file path under a private name (the parent may know it as `ember` or
as Blender's `bl_ext.<repo>.ember`) and serves batch requests on stdin/stdout.
"""
import importlib.util
import pathlib
import sys


def main() -> None:
    root = pathlib.Path(sys.argv[1])
    spec = importlib.util.spec_from_file_location("ember_worker", root / "__init__.py",
                                                  submodule_search_locations=[str(root)])
    package = importlib.util.module_from_spec(spec)
    sys.modules["ember_worker"] = package
    spec.loader.exec_module(package)
    from ember_worker.engine.parallel.workers import serve

    serve(sys.stdin.buffer, sys.stdout.buffer)


if __name__ == "__main__":
    main()
