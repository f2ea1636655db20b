"""Squeeze Value (Legacy), as Cycles renders it: Cycles builds no node for it (its Blender
sync knows no such node), so a link leaving it is dropped and the socket it feeds keeps its own
value. EEVEE's 1 / (1 + exp(-(value - center) * width)) is not what a Cycles render shows, so
Ember follows Cycles: engine/nodes/program.py drops links from a node kind marked `inert`."""
from __future__ import annotations

from .base import node


@node("ShaderNodeSqueeze", "Utilities", inert=True)
def squeeze(node, inputs, state):
    return {}


NODES = (squeeze,)
