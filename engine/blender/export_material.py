"""Materials -> one global table (Materials), first approximation.

The active Material Output (target ALL or CYCLES) Surface link decides the kind:
Diffuse BSDF -> MAT_DIFFUSE(Color); Emission -> MAT_EMISSION_ONLY(Color * Strength);
Principled BSDF -> MAT_DIFFUSE(Base Color) + Emission Color * Emission Strength;
nothing connected -> black (like Cycles); anything else, or a linked colour input
(textures), -> grey diffuse 0.8 plus one warning per material. A material without a node
tree uses diffuse_color (as Cycles does). Socket values are scene-linear already.
"""
from __future__ import annotations

import numpy as np

from ..scene import MAT_DIFFUSE, MAT_EMISSION_ONLY, Materials

GREY = (0.8, 0.8, 0.8)
DEFAULT_NAME = "default"


# --- node helpers (shared with lights and world) ------------------------------------------
def find_output(tree, bl_idname: str):
    """The output node Cycles uses: the active one among targets ALL/CYCLES, else the
    first such node, else None."""
    outs = [n for n in tree.nodes if n.bl_idname == bl_idname
            and getattr(n, "target", "ALL") in ("ALL", "CYCLES")]
    for n in outs:
        if getattr(n, "is_active_output", False):
            return n
    return outs[0] if outs else None


def follow_link(socket):
    """The node feeding `socket` (through reroutes), or None if unconnected or muted."""
    seen = 0
    while socket is not None and socket.is_linked and seen < 64:
        link = socket.links[0]
        if getattr(link, "is_muted", False) or not getattr(link, "is_valid", True):
            return None
        node = link.from_node
        if node.bl_idname == "NodeReroute":
            socket = node.inputs[0] if node.inputs else None
            seen += 1
            continue
        return node
    return None


def rgb(socket) -> tuple:
    return tuple(float(c) for c in socket.default_value[:3])


# --- material conversion ----------------------------------------------------------------
def _grey(name, reason, warn):
    warn(f"Material '{name}': {reason}; rendered as grey diffuse.")
    return dict(kind=MAT_DIFFUSE, base_color=GREY, emission=(0.0, 0.0, 0.0), name=name)


def material_row(mat, warn) -> dict:
    """One Materials row for a bpy Material (evaluated or original). Warns at most once."""
    name = mat.name
    tree = mat.node_tree
    if tree is None:
        return dict(kind=MAT_DIFFUSE, base_color=tuple(mat.diffuse_color[:3]), emission=(0, 0, 0), name=name)
    out = find_output(tree, "ShaderNodeOutputMaterial")
    if out is None:
        return _grey(name, "it has no Material Output node", warn)
    node = follow_link(out.inputs["Surface"])
    if node is None:  # Cycles: no surface shader -> black
        return dict(kind=MAT_EMISSION_ONLY, base_color=(0, 0, 0), emission=(0, 0, 0), name=name)
    kind = node.bl_idname
    if node.mute:
        return _grey(name, f"node '{node.name}' is muted", warn)

    def linked_names(*sockets):
        linked = [s.name for s in sockets if s.is_linked]
        return linked

    if kind == "ShaderNodeBsdfDiffuse":
        linked = linked_names(node.inputs["Color"])
        if linked:
            return _grey(name, f"node '{node.name}' has a linked {', '.join(linked)} input (textures are not supported yet)", warn)
        return dict(kind=MAT_DIFFUSE, base_color=rgb(node.inputs["Color"]), emission=(0, 0, 0), name=name)
    if kind == "ShaderNodeEmission":
        col, stre = node.inputs["Color"], node.inputs["Strength"]
        linked = linked_names(col, stre)
        if linked:
            return _grey(name, f"node '{node.name}' has a linked {', '.join(linked)} input (textures are not supported yet)", warn)
        e = np.array(rgb(col)) * float(stre.default_value)
        return dict(kind=MAT_EMISSION_ONLY, base_color=(0, 0, 0), emission=tuple(e), name=name)
    if kind == "ShaderNodeBsdfPrincipled":
        inp = node.inputs
        col, ecol, estr = inp["Base Color"], inp["Emission Color"], inp["Emission Strength"]
        linked = linked_names(col, ecol, estr)
        if linked:
            return _grey(name, f"node '{node.name}' has a linked {', '.join(linked)} input (textures are not supported yet)", warn)
        e = np.array(rgb(ecol)) * float(estr.default_value)
        approx = [label for label, key, default in (
            ("metallic", "Metallic", 0.0), ("transmission", "Transmission Weight", 0.0),
            ("coat", "Coat Weight", 0.0), ("sheen", "Sheen Weight", 0.0),
            ("subsurface", "Subsurface Weight", 0.0), ("alpha", "Alpha", 1.0))
            if key in inp and (inp[key].is_linked or float(inp[key].default_value) != default)]
        if approx:
            warn(f"Material '{name}': Principled BSDF {', '.join(approx)} not supported yet; "
                 "rendered as diffuse with its base colour.")
        return dict(kind=MAT_DIFFUSE, base_color=rgb(col), emission=tuple(e), name=name)
    return _grey(name, f"node '{node.name}' ({node.bl_label}) is not supported yet", warn)


class MaterialTable:
    """Global material table; index(None) is the default grey material."""

    def __init__(self, warn):
        self._warn = warn
        self._rows: list[dict] = []
        self._index: dict[int, int] = {}
        self._default = None

    def index(self, mat) -> int:
        if mat is None:
            if self._default is None:
                self._default = len(self._rows)
                self._rows.append(dict(kind=MAT_DIFFUSE, base_color=GREY, emission=(0, 0, 0), name=DEFAULT_NAME))
            return self._default
        key = (getattr(mat, "original", None) or mat).as_pointer()
        i = self._index.get(key)
        if i is None:
            i = self._index[key] = len(self._rows)
            self._rows.append(material_row(mat, self._warn))
        return i

    def __len__(self):
        return len(self._rows)

    def materials(self) -> Materials:
        return Materials.make(self._rows)
