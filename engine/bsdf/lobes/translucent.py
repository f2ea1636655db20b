"""The Translucent BSDF: Lambertian transmission, f = colour / pi for wi on the far side of the
shading normal, sampled cosine-weighted around -n (Cycles' closure/bsdf_diffuse.h, translucent):
the Diffuse lobe mirrored through the shading plane. Cycles counts it as a diffuse closure
(CLOSURE_IS_BSDF_DIFFUSE: diffuse passes, lit by lights with diffuse visibility) whose bounce
is a transmission (LABEL_TRANSMIT | LABEL_DIFFUSE)."""
from __future__ import annotations

from ...scene import LOBE_TRANSLUCENT
from .base import LABEL_TRANSMIT, LobeSample
from .diffuse import Diffuse


def _mirrored(w):
    """Local directions w (K,3) mirrored through the shading plane (a copy)."""
    out = w.copy()
    out[:, 2] = -out[:, 2]
    return out


class Translucent(Diffuse):
    kind = LOBE_TRANSLUCENT

    def eval(self, p, wo, wi):
        return super().eval(p, wo, _mirrored(wi))

    def pdf(self, p, wo, wi):
        return super().pdf(p, wo, _mirrored(wi))

    def sample(self, p, wo, u, u_branch) -> LobeSample:
        s = super().sample(p, wo, u, u_branch)
        return LobeSample(wi=_mirrored(s.wi), pdf=s.pdf, delta=False, label=LABEL_TRANSMIT)
