"""The energy-normalised Phong lobe (seed 000): kd = colour, ks = tint, exponent n; a diffuse
and a glossy branch (formulas: engine/bsdf/phong.py)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...scene import LOBE_PHONG, RAY_DIFFUSE, RAY_GLOSSY
from .. import phong
from . import inputs
from .base import CLASS_GLOSSY, LABEL_DIFFUSE, LABEL_GLOSSY, LobeSample, SurfaceLobe, SurfaceParams, mean_albedo


@dataclass
class PhongParams(SurfaceParams):
    """tint (K,3) ks; exponent (K,) n."""

    tint: np.ndarray
    exponent: np.ndarray


class Phong(SurfaceLobe):
    kind = LOBE_PHONG
    rays = RAY_DIFFUSE | RAY_GLOSSY
    # Its render passes count it glossy whole (kd included).
    reflection_class = transmission_class = CLASS_GLOSSY

    def parameters(self, m, lobe, point, src, inside) -> PhongParams:
        color = inputs.color(m, lobe, point, src)
        return PhongParams(color=color, delta=np.zeros(len(lobe), bool), tint=inputs.tint(m, lobe, color, src),
                           exponent=inputs.exponent(m, lobe, src))

    def albedo(self, p, wo):
        return phong.albedo(p.color, p.tint, p.exponent, wo)

    def eval(self, p, wo, wi):
        args = (p.color, p.tint, p.exponent, wo, wi)
        return phong.eval(*args), phong.pdf(*args)

    def pdf(self, p, wo, wi):
        return phong.pdf(p.color, p.tint, p.exponent, wo, wi)

    def sample(self, p, wo, u, u_branch) -> LobeSample:
        wi, _, pdf = phong.sample(p.color, p.tint, p.exponent, wo, u, u_branch)
        label = np.where(u_branch < phong.diffuse_probability(p.color, p.tint), LABEL_DIFFUSE, LABEL_GLOSSY)
        return LobeSample(wi=wi, pdf=pdf, delta=False, label=label)

    def drop_caustics(self, p, reflection, refraction):
        p.tint[reflection] = 0.0  # Ember's Phong loses ks
        return None

    def stores_photons(self, m, lobe, min_roughness):
        return m.lobe_color[lobe].max(axis=1) > 0  # a diffuse part

    def analysis_albedo(self, m, lobe, color, min_roughness):
        # kd (the colour) is diffuse, ks (the tint) glossy.
        return {"diffuse": np.maximum(mean_albedo(m, lobe, color), 0.0),
                "glossy": (m.lobe_weight[lobe] * m.lobe_tint[lobe]).mean(axis=1)}
