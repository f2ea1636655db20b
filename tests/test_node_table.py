"""The shader-node coverage in README.md and docs/nodes.md is what the node registry gives
(tools/node_table.py), and every node not built says why."""
import pytest

pytest.importorskip("bpy")

from tools import node_table  # noqa: E402

pytestmark = pytest.mark.blender


def test_readme_and_docs_list_what_the_registry_builds():
    assert node_table.README.read_text() == node_table.updated(node_table.README.read_text())
    assert node_table.DOC.read_text() == node_table.doc()


def test_every_node_not_built_has_its_reason():
    missing = [kind for _, _, kind, status, note in node_table.rows() if status == "not built" and
               kind not in node_table.NOT_BUILT]
    assert missing == []
