"""A surface lobe's inputs from the material table (Scene.Materials): the constant or, where a
texture slot feeds it, the texture's value at the shading point's UV. Shared by the lobes'
`parameters`; rows are lobes `lobe` (K,) at shading points `point` (K,), uv (N,2) per point
(None when no texture is in the batch)."""
from __future__ import annotations

import numpy as np

from ... import textures


def weight(m, lobe: np.ndarray, point: np.ndarray, uv) -> np.ndarray:
    """(K,3) mixture weight: lobe_weight x the opacity texture (1 - its value where inverted)."""
    w = m.lobe_weight[lobe]
    rows = np.flatnonzero(m.lobe_opacity_tex[lobe] >= 0)
    if len(rows):
        a = textures.scalar(m, m.lobe_opacity_tex[lobe[rows]], uv[point[rows]])
        w[rows] *= np.where(m.lobe_opacity_invert[lobe[rows]], 1.0 - a, a)[:, None]
    return w


def color(m, lobe: np.ndarray, point: np.ndarray, uv) -> np.ndarray:
    """(K,3) colour input; sqrt(clamp(colour)) where lobe_color_sqrt (Principled transmission)."""
    c = m.lobe_color[lobe]
    rows = np.flatnonzero(m.lobe_color_tex[lobe] >= 0)
    if len(rows):
        c[rows] = textures.color(m, m.lobe_color_tex[lobe[rows]], uv[point[rows]])
    rows = np.flatnonzero(m.lobe_color_sqrt[lobe])
    if len(rows):
        c[rows] = np.sqrt(np.clip(c[rows], 0.0, 1.0))
    return c


def tint(m, lobe: np.ndarray, color: np.ndarray) -> np.ndarray:
    """(K,3) tint: lobe_tint, or the colour itself where lobe_tint_is_color."""
    return np.where(m.lobe_tint_is_color[lobe][:, None], color, m.lobe_tint[lobe])


def roughness(m, lobe: np.ndarray, point: np.ndarray, uv) -> np.ndarray:
    """(K,) Blender roughness in [0, 1]."""
    r = m.lobe_roughness[lobe]
    rows = np.flatnonzero(m.lobe_roughness_tex[lobe] >= 0)
    if len(rows):
        r[rows] = textures.scalar(m, m.lobe_roughness_tex[lobe[rows]], uv[point[rows]])
    return np.clip(r, 0.0, 1.0)
