"""The Oren-Nayar lobe (Diffuse BSDF and Principled base with a roughness): Cycles'
energy-preserving Oren-Nayar of sigma = roughness, cosine-weighted (formulas:
engine/bsdf/oren_nayar.py)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...scene import LOBE_OREN_NAYAR, RAY_DIFFUSE
from .. import diffuse, oren_nayar
from . import inputs
from .base import CLASS_DIFFUSE, LABEL_DIFFUSE, LobeSample, SurfaceLobe, SurfaceParams, mean_albedo


@dataclass
class OrenNayarParams(SurfaceParams):
    """roughness (K,) sigma in [0, 1]."""

    roughness: np.ndarray


class OrenNayar(SurfaceLobe):
    kind = LOBE_OREN_NAYAR
    rays = RAY_DIFFUSE
    reflection_class = transmission_class = CLASS_DIFFUSE

    def parameters(self, m, lobe, point, src, inside) -> OrenNayarParams:
        return OrenNayarParams(color=inputs.color(m, lobe, point, src), delta=np.zeros(len(lobe), bool),
                               roughness=inputs.roughness(m, lobe, point, src))

    def albedo(self, p, wo):
        return p.color  # Cycles' estimate: the closure's weight

    def eval(self, p, wo, wi):
        return oren_nayar.eval(p.color, p.roughness, wo, wi), diffuse.pdf(wi[:, 2])

    def pdf(self, p, wo, wi):
        return diffuse.pdf(wi[:, 2])

    def sample(self, p, wo, u, u_branch) -> LobeSample:
        wi = diffuse.sample(u)
        return LobeSample(wi=wi, pdf=diffuse.pdf(wi[:, 2]), delta=False, label=LABEL_DIFFUSE)

    def stores_photons(self, m, lobe, min_roughness):
        return np.ones(len(lobe), bool)

    def analysis_albedo(self, m, lobe, color, min_roughness):
        return {"diffuse": np.maximum(mean_albedo(m, lobe, color), 0.0)}
