"""Only engine/blender/, ui/, __init__.py and render.py may import Blender modules."""
import ast
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[1]
BLENDER_MODULES = {"bpy", "mathutils", "gpu", "gpu_extras", "bl_ui", "bpy_extras", "bl_operators"}


def _imports(path):
    tree = ast.parse(path.read_text(), filename=str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.module.split(".")[0]


def test_core_does_not_import_blender():
    offenders = []
    for path in (ROOT / "engine").rglob("*.py"):
        rel = path.relative_to(ROOT)
        if rel.parts[:2] == ("engine", "blender"):
            continue
        bad = BLENDER_MODULES.intersection(_imports(path))
        if bad:
            offenders.append(f"{rel}: {sorted(bad)}")
    assert offenders == []
    # The check itself works: the Blender layer does import bpy.
    assert any("bpy" in set(_imports(p)) for p in (ROOT / "engine" / "blender").rglob("*.py")) or not list((ROOT / "engine" / "blender").rglob("export*.py"))
