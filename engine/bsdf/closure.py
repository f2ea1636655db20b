"""The BSDF at N shading points, dispatched once per material kind present.

Frames: `ns` and `ng` arrive already flipped to the side of `wo` (two-sided shading, as
Cycles). `prim` and `bary` locate the hits on the mesh (for textures / UVs); a closure may
replace `ns` (normal maps), and the integrator then uses `closure.ns`. A direction wi is valid only on that side of the *geometric* normal (pbrt-v3's
rule: no light leaks through low-poly geometry); cosines use the shading normal.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..vec import dot, max3

from .. import sampling
from ..scene import MAT_DIFFUSE, Scene
from . import diffuse



@dataclass
class BSDFSample:
    """wi (N,3); weight (N,3) = f |cos| / pdf (the throughput factor); pdf (N,) solid-angle
    pdf of the whole closure (for delta lobes the lobe's selection probability, never used in
    MIS); delta (N,) bool: chosen from a delta lobe; valid (N,) bool."""

    wi: np.ndarray
    weight: np.ndarray
    pdf: np.ndarray
    delta: np.ndarray
    valid: np.ndarray


class Closure:
    def __init__(self, scene: Scene, mat: np.ndarray, ns: np.ndarray, ng: np.ndarray, wo: np.ndarray,
                 prim: np.ndarray, bary: np.ndarray):
        materials = scene.materials
        self.ns, self.ng, self.wo = ns, ng, wo
        self.kind = materials.kind[mat]
        self.albedo = materials.base_color[mat]
        self.diffuse_rows = np.flatnonzero(self.kind == MAT_DIFFUSE)
        is_diffuse = self.kind == MAT_DIFFUSE
        # Reflectance drives Russian roulette (seed 000: survival from the material).
        self.reflectance = np.where(is_diffuse[:, None], self.albedo, 0.0)
        self.t, self.b = sampling.frame_from_z(ns)
        # Points with a non-delta component take part in next-event estimation.
        self.has_smooth = is_diffuse & (max3(self.albedo) > 0)

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

    def sample(self, u: np.ndarray, u_lobe: np.ndarray) -> BSDFSample:
        """Sample wi at every point; u (N,2) for the direction, u_lobe (N,) to choose a lobe."""
        wi = np.zeros((self.n, 3))
        weight = np.zeros((self.n, 3))
        pdf = np.zeros(self.n)
        rows = self.diffuse_rows
        if len(rows):
            local = diffuse.sample(u[rows])
            wi[rows] = sampling.to_world(local, self.t[rows], self.b[rows], self.ns[rows])
            ok = dot(wi[rows], self.ng[rows]) > 0
            # f cos / pdf = albedo for cosine-weighted sampling of a Lambertian lobe.
            weight[rows] = np.where(ok[:, None], self.albedo[rows], 0.0)
            pdf[rows] = np.where(ok, diffuse.pdf(local[:, 2]), 0.0)
        valid = pdf > 0
        return BSDFSample(wi=wi, weight=weight, pdf=pdf, delta=np.zeros(self.n, bool), valid=valid)

    def cos_i(self, wi: np.ndarray) -> np.ndarray:
        return np.abs(dot(wi, self.ns))
