"""Environment Texture: an image wrapped around the sphere of directions, read in the direction
of the Vector (svm/image.h svm_node_tex_environment; kernel/camera/projection.h
direction_to_equirectangular and direction_to_mirrorball).

The Vector is normalised (a zero vector stays zero). Equirectangular puts azimuth along u
(u = 1/2 - atan2(y, x) / 2 pi: -x at the image's edges, +x in its middle) and the angle
from +z along v (v = 1 - theta / pi); Mirror Ball is the image of a mirrored sphere seen from
-y. The image repeats beyond its edges and is interpolated as the node says
(engine/nodes/image.py). An unlinked Vector reads the position (in a world: the ray
direction); an image Cycles cannot read is magenta. The image comes with the node, as the
texels Cycles keeps (image.Texels, exported by engine/blender/export_image.py).
"""
from __future__ import annotations

import numpy as np

from . import image, texture_mapping
from .base import components, node

# Blender's interpolation identifiers are capitalised words ("Linear"); Cycles' are the same.
_INTERPOLATION = {"Closest": "CLOSEST", "Linear": "LINEAR", "Cubic": "CUBIC", "Smart": "SMART"}


def equirectangular(d):
    """(u, v) of unit directions; the zero vector maps to (0, 0)."""
    x, y, z = components(d)
    zero = (x == 0.0) & (y == 0.0) & (z == 0.0)
    u = (np.arctan2(y, x) - np.pi) / (-2.0 * np.pi)
    v = (np.arccos(np.clip(z, -1.0, 1.0)) - np.pi) / -np.pi
    return np.where(zero, 0.0, u), np.where(zero, 0.0, v)


def mirror_ball(d):
    """(u, v) of unit directions on the image of a mirror ball seen along +y."""
    x, y, z = components(d)
    y = y - 1.0
    div = 2.0 * np.sqrt(np.maximum(-0.5 * y, 0.0))
    scale = np.where(div > 0.0, 1.0 / np.where(div > 0.0, div, 1.0), 1.0)
    return 0.5 * (x * scale + 1.0), 0.5 * (z * scale + 1.0)


def environment(d, texels, projection: str, interpolation: str) -> np.ndarray:
    """RGBA (..., 4) of the image in directions d (..., 3)."""
    n = np.linalg.norm(d, axis=-1, keepdims=True)
    d = np.where(n != 0.0, d / np.where(n != 0.0, n, 1.0), d)
    u, v = (mirror_ball if projection == "MIRROR_BALL" else equirectangular)(d)
    if isinstance(texels, image.Tiles):  # one image to Cycles: tile 1001 stands for a UDIM image
        texels = texels.first()
    rgba = image.sample(texels, np.ravel(u), np.ravel(v), _INTERPOLATION.get(interpolation, "LINEAR"), "REPEAT")
    return rgba.reshape(np.shape(u) + (4,))


@node("ShaderNodeTexEnvironment", "Texture", reads=texture_mapping.unlinked_reads("P"))
def environment_texture(node, inputs, state):
    d = texture_mapping.coordinate(node, inputs, state, "P")
    rgba = environment(d, node.prop("image"), node.prop("projection", "EQUIRECTANGULAR"),
                       node.prop("interpolation", "Linear"))
    return {"Color": rgba[..., :3], "Alpha": rgba[..., 3]}


NODES = (environment_texture,)
