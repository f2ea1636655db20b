"""Transparency (Transparent BSDF, alpha): light passes straight through, tinted by the
colour - a delta lobe, wi = -wo."""
from __future__ import annotations

import numpy as np

from ...scene import LOBE_TRANSPARENT
from . import inputs
from .base import CLASS_TRANSMISSION, LABEL_TRANSPARENT, LobeSample, SurfaceLobe, SurfaceParams


class Transparent(SurfaceLobe):
    kind = LOBE_TRANSPARENT
    rays = 0  # a delta lobe: no light sampling lights it
    reflection_class = transmission_class = CLASS_TRANSMISSION
    straight = True

    def parameters(self, m, lobe, point, src, inside) -> SurfaceParams:
        return SurfaceParams(color=inputs.color(m, lobe, point, src), delta=np.ones(len(lobe), bool))

    def is_delta(self, p):
        return np.ones(len(p), bool)

    def albedo(self, p, wo):
        return p.color

    def eval(self, p, wo, wi):
        return np.zeros((len(p), 3)), np.zeros(len(p))  # a direction has probability 0 of being its

    def sample(self, p, wo, u, u_branch) -> LobeSample:
        return LobeSample(wi=-wo, pdf=np.ones(len(p)), delta=True, label=LABEL_TRANSPARENT, weight=p.color)

    def stores_photons(self, m, lobe, min_roughness):
        return np.zeros(len(lobe), bool)

    def analysis_albedo(self, m, lobe, color, min_roughness):
        return {"transparent": np.maximum(m.lobe_weight[lobe].mean(axis=1), 0.0)}
