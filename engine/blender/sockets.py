"""Following shader-node links to the node that feeds a socket (through reroutes)."""
from __future__ import annotations


def follow_socket(socket):
    """(node, output socket) feeding `socket` through reroutes, or (None, None) if
    unconnected or muted."""
    seen = 0
    while socket is not None and socket.is_linked and seen < 64:
        link = socket.links[0]
        if getattr(link, "is_muted", False) or not getattr(link, "is_valid", True):
            return None, None
        node = link.from_node
        if node.bl_idname == "NodeReroute":
            socket = node.inputs[0] if node.inputs else None
            seen += 1
            continue
        return node, link.from_socket
    return None, None


def follow_link(socket):
    """The node feeding `socket` (through reroutes), or None if unconnected or muted."""
    return follow_socket(socket)[0]
