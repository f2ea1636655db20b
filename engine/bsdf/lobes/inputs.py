"""A surface lobe's inputs: from the material table (Scene.Materials), the constant or, where a
texture slot feeds it, the texture's value at the shading point's UV; where a material's node
program computes an input per point (engine/nodes/material.py), that value. Shared by the
lobes' `parameters`; rows are lobes `lobe` (K,) at shading points `point` (K,) of the pairs
that `src` (Sources, restricted to the same K pairs) describes."""
from __future__ import annotations

import numpy as np

from ... import textures


class Sources:
    """Where K pairs' inputs come from besides the table: uv (N,2) per point (None when no
    texture is in the batch), `values` {input name: (values (K,...), has (K,) bool)} that
    node programs computed for some of the pairs, and frame (t, b) (N,3 each): the points'
    shading frames' tangents (where a lobe orients itself by a world direction)."""

    def __init__(self, uv, values=None, frame=None):
        self.uv, self.values, self.frame = uv, values or {}, frame

    def take(self, rows: np.ndarray) -> "Sources":
        if not self.values:
            return self
        return Sources(self.uv, {k: (v[rows], has[rows]) for k, (v, has) in self.values.items()}, self.frame)

    def apply(self, name: str, a: np.ndarray) -> np.ndarray:
        """a (K,...) with the programs' values of input `name` where they have one."""
        if name in self.values:
            v, has = self.values[name]
            a[has] = v[has]
        return a


def weight(m, lobe: np.ndarray, point: np.ndarray, src: Sources) -> np.ndarray:
    """(K,3) mixture weight: lobe_weight x the opacity texture (1 - its value where inverted)."""
    w = m.lobe_weight[lobe]
    rows = np.flatnonzero(m.lobe_opacity_tex[lobe] >= 0)
    if len(rows):
        a = textures.scalar(m, m.lobe_opacity_tex[lobe[rows]], src.uv[point[rows]])
        w[rows] *= np.where(m.lobe_opacity_invert[lobe[rows]], 1.0 - a, a)[:, None]
    return src.apply("weight", w)


def color(m, lobe: np.ndarray, point: np.ndarray, src: Sources) -> np.ndarray:
    """(K,3) colour input; sqrt(clamp(colour)) where lobe_color_sqrt (Principled transmission)."""
    c = m.lobe_color[lobe]
    rows = np.flatnonzero(m.lobe_color_tex[lobe] >= 0)
    if len(rows):
        c[rows] = textures.color(m, m.lobe_color_tex[lobe[rows]], src.uv[point[rows]])
    rows = np.flatnonzero(m.lobe_color_sqrt[lobe])
    if len(rows):
        c[rows] = np.sqrt(np.clip(c[rows], 0.0, 1.0))
    return src.apply("color", c)


def tint(m, lobe: np.ndarray, color: np.ndarray, src: Sources) -> np.ndarray:
    """(K,3) tint: lobe_tint, or the colour itself where lobe_tint_is_color."""
    return src.apply("tint", np.where(m.lobe_tint_is_color[lobe][:, None], color, m.lobe_tint[lobe]))


def roughness(m, lobe: np.ndarray, point: np.ndarray, src: Sources) -> np.ndarray:
    """(K,) Blender roughness in [0, 1]."""
    r = m.lobe_roughness[lobe]
    rows = np.flatnonzero(m.lobe_roughness_tex[lobe] >= 0)
    if len(rows):
        r[rows] = textures.scalar(m, m.lobe_roughness_tex[lobe[rows]], src.uv[point[rows]])
    return np.clip(src.apply("roughness", r), 0.0, 1.0)


def ior(m, lobe: np.ndarray, src: Sources) -> np.ndarray:
    """(K,) index of refraction (inside over outside)."""
    return src.apply("ior", m.lobe_ior[lobe]) if "ior" in src.values else m.lobe_ior[lobe]


def exponent(m, lobe: np.ndarray, src: Sources) -> np.ndarray:
    """(K,) Phong exponent."""
    return src.apply("exponent", m.lobe_exponent[lobe]) if "exponent" in src.values else m.lobe_exponent[lobe]


def film(m, lobe: np.ndarray, src: Sources):
    """(thickness (K,) nm, index (K,)) of a thin film on the lobe's Fresnel."""
    d, n = m.lobe_film_thickness[lobe], m.lobe_film_ior[lobe]
    if "film_thickness" in src.values or "film_ior" in src.values:
        d, n = src.apply("film_thickness", d.copy()), src.apply("film_ior", n.copy())
    return d, n


def anisotropy(point: np.ndarray, src: Sources):
    """(aspect (K,), tangent azimuth (K,2) = (cos, sin) in the points' shading frames) of the
    pairs whose programs give an anisotropy, alpha_x = alpha / aspect, alpha_y = alpha aspect
    (Cycles' alpha_x along the tangent); None where no pair has one. A tangent along the
    normal keeps azimuth 0."""
    if "aspect" not in src.values or src.frame is None:
        return None
    aspect = src.apply("aspect", np.ones(len(point)))
    tangent = src.apply("tangent", np.zeros((len(point), 3)))
    t, b = src.frame
    x = np.einsum("ij,ij->i", tangent, t[point])
    y = np.einsum("ij,ij->i", tangent, b[point])
    r = np.hypot(x, y)
    ok = r > 0.0
    aspect = np.where(ok, aspect, 1.0)
    azimuth = np.stack([np.divide(x, r, out=np.ones_like(r), where=ok), np.divide(y, r, out=np.zeros_like(r), where=ok)],
                       axis=1)
    return aspect, azimuth
