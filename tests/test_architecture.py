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


# ---- the import graph ------------------------------------------------------------------------
from tools.import_graph import cycles, module_graph, reaches  # noqa: E402


def test_engine_imports_have_no_circles():
    """Every import counts, inside functions too: a module that needs another at run time
    depends on it as surely as one that imports it at the top."""
    graph = module_graph(ROOT)
    assert len(graph) > 50 and graph["engine.session"]  # the graph was read
    assert cycles(graph) == []


def test_engine_imports_its_own_modules_at_the_top():
    """An import of an engine module inside a function is how a circle hides; none is needed."""
    lazy = sorted(f"{m} -> {t}" for m, edges in module_graph(ROOT).items() for t, inner in edges.items() if inner)
    assert lazy == []


def test_tracing_does_not_depend_on_the_choice_or_the_session():
    graph = module_graph(ROOT)
    for module in ("engine.integrators", "engine.tracer", "engine.runner"):
        assert not {"engine.choice", "engine.session"} & reaches(graph, module), module


def test_the_checks_see_a_circle():
    graph = {"a": {"b": False}, "b": {"c": True}, "c": {"a": False}, "d": {"a": False}}
    assert cycles(graph) == [["a", "b", "c"]] and reaches(graph, "d") == {"a", "b", "c"}
