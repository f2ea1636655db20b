"""The Translucent BSDF: Lambertian transmission, f = colour / pi for wi on the far side of the
shading normal, sampled cosine-weighted around -n (Cycles' closure/bsdf_diffuse.h, translucent).
Cycles counts it as a diffuse closure (CLOSURE_IS_BSDF_DIFFUSE: diffuse passes, lit by lights
with diffuse visibility) whose bounce is a transmission (LABEL_TRANSMIT | LABEL_DIFFUSE)."""
from __future__ import annotations

import numpy as np

from ...scene import LOBE_TRANSLUCENT, RAY_DIFFUSE
from .. import diffuse
from . import inputs
from .base import CLASS_DIFFUSE, LABEL_TRANSMIT, LobeSample, SurfaceLobe, SurfaceParams, mean_albedo


class Translucent(SurfaceLobe):
    kind = LOBE_TRANSLUCENT
    rays = RAY_DIFFUSE
    reflection_class = transmission_class = CLASS_DIFFUSE

    def parameters(self, m, lobe, point, src, inside) -> SurfaceParams:
        return SurfaceParams(color=inputs.color(m, lobe, point, src), delta=np.zeros(len(lobe), bool))

    def albedo(self, p, wo):
        return p.color

    def eval(self, p, wo, wi):
        cos_t = -wi[:, 2]  # the cosine on the far side
        return diffuse.eval(p.color, cos_t), diffuse.pdf(cos_t)

    def pdf(self, p, wo, wi):
        return diffuse.pdf(-wi[:, 2])

    def sample(self, p, wo, u, u_branch) -> LobeSample:
        wi = diffuse.sample(u)
        wi[:, 2] = -wi[:, 2]
        return LobeSample(wi=wi, pdf=diffuse.pdf(-wi[:, 2]), delta=False, label=LABEL_TRANSMIT)

    def stores_photons(self, m, lobe, min_roughness):
        return np.ones(len(lobe), bool)

    def analysis_albedo(self, m, lobe, color, min_roughness):
        return {"diffuse": np.maximum(mean_albedo(m, lobe, color), 0.0)}
