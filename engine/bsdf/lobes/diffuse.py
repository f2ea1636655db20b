"""The Lambertian lobe (Diffuse BSDF, Principled base): f = colour / pi, cosine-weighted
(formulas: engine/bsdf/diffuse.py)."""
from __future__ import annotations

import numpy as np

from ...scene import LOBE_DIFFUSE, RAY_DIFFUSE
from .. import diffuse
from . import inputs
from .base import CLASS_DIFFUSE, LABEL_DIFFUSE, LobeSample, SurfaceLobe, SurfaceParams, mean_albedo


class Diffuse(SurfaceLobe):
    kind = LOBE_DIFFUSE
    rays = RAY_DIFFUSE
    reflection_class = transmission_class = CLASS_DIFFUSE

    def parameters(self, m, lobe, point, src, inside) -> SurfaceParams:
        return SurfaceParams(color=inputs.color(m, lobe, point, src), delta=np.zeros(len(lobe), bool))

    def albedo(self, p, wo):
        return p.color

    def eval(self, p, wo, wi):
        return diffuse.eval(p.color, wi[:, 2]), diffuse.pdf(wi[:, 2])

    def pdf(self, p, wo, wi):
        return diffuse.pdf(wi[:, 2])

    def sample(self, p, wo, u, u_branch) -> LobeSample:
        wi = diffuse.sample(u)
        return LobeSample(wi=wi, pdf=diffuse.pdf(wi[:, 2]), delta=False, label=LABEL_DIFFUSE)

    def stores_photons(self, m, lobe, min_roughness):
        return np.ones(len(lobe), bool)

    def analysis_albedo(self, m, lobe, color, min_roughness):
        return {"diffuse": np.maximum(mean_albedo(m, lobe, color), 0.0)}
