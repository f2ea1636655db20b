"""Import the repository root as the package `ember` (it uses relative imports only, as
Blender imports it as `bl_ext.<repo>.ember`). Used by render.py and the tests."""
import importlib.util
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parent


def load_ember():
    if "ember" not in sys.modules:
        spec = importlib.util.spec_from_file_location(
            "ember", ROOT / "__init__.py", submodule_search_locations=[str(ROOT)])
        module = importlib.util.module_from_spec(spec)
        sys.modules["ember"] = module
        spec.loader.exec_module(module)
    return sys.modules["ember"]
