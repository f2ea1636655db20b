"""The BSDF at N shading points, dispatched once per material kind present.

Frames: `ns` and `ng` arrive already flipped to the side of `wo` (two-sided shading, as
Cycles). A direction wi is valid only on that side of the *geometric* normal (pbrt-v3's
rule: no light leaks through low-poly geometry); cosines use the shading normal.
"""
from __future__ import annotations

import numpy as np

from ..vec import dot, max3

from .. import sampling
from ..scene import MAT_DIFFUSE, Materials
from . import diffuse



class Closure:
    def __init__(self, materials: Materials, mat: np.ndarray, ns: np.ndarray, ng: np.ndarray, wo: np.ndarray):
        self.ns, self.ng, self.wo = ns, ng, wo
        self.kind = materials.kind[mat]
        self.albedo = materials.base_color[mat]
        self.diffuse_rows = np.flatnonzero(self.kind == MAT_DIFFUSE)
        is_diffuse = self.kind == MAT_DIFFUSE
        # Reflectance drives Russian roulette (seed 000: survival from the material).
        self.reflectance = np.where(is_diffuse[:, None], self.albedo, 0.0)
        self.t, self.b = sampling.frame_from_z(ns)

    @property
    def n(self) -> int:
        return len(self.kind)

    def eval(self, wi: np.ndarray, rows: np.ndarray):
        """f (K,3) and solid-angle pdf (K,) at the points `rows` (K,) for directions wi (K,3)."""
        f = np.zeros((len(rows), 3))
        pdf = np.zeros(len(rows))
        ok = dot(wi, self.ng[rows]) > 0
        sel = np.flatnonzero(self.kind[rows] == MAT_DIFFUSE)
        if len(sel):
            r = rows[sel]
            cos_i = np.where(ok[sel], dot(wi[sel], self.ns[r]), 0.0)
            f[sel] = diffuse.eval(self.albedo[r], cos_i)
            pdf[sel] = diffuse.pdf(cos_i)
        return f, pdf

    def sample(self, u: np.ndarray):
        """Sample wi for every point. Returns wi (N,3), f (N,3), pdf (N,), valid (N,)."""
        wi = np.zeros((self.n, 3))
        f = np.zeros((self.n, 3))
        pdf = np.zeros(self.n)
        rows = self.diffuse_rows
        if len(rows):
            local = diffuse.sample(u[rows])
            wi[rows] = sampling.to_world(local, self.t[rows], self.b[rows], self.ns[rows])
            cos_i = np.where(dot(wi[rows], self.ng[rows]) > 0, local[:, 2], 0.0)
            f[rows] = diffuse.eval(self.albedo[rows], cos_i)
            pdf[rows] = diffuse.pdf(cos_i)
        valid = pdf > 0
        return wi, f, pdf, valid

    def cos_i(self, wi: np.ndarray) -> np.ndarray:
        return np.abs(dot(wi, self.ns))
