"""The Henyey-Greenstein phase function (Cycles' Volume Scatter, Principled Volume):

    p(cos) = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos)^(3/2)),

cos the cosine between the propagation directions before and after scattering (-wo and wi:
g > 0 scatters forward), g the mean cosine in (-1, 1). Sampled exactly (f = pdf, weight 1).
Cycles (kernel/closure/volume_util.h, volume_henyey_greenstein.h) clamps |g| <= 1 - 1e-3
and inverts the CDF as cos = (1 + g^2 - k^2) / (2 g), k = (1 - g^2) / (1 - g x),
x = 1 - 2 u, switching to a uniform sphere below |g| = 1e-3. We invert the same CDF in a
form without the division by g (exact at g = 0) nor cancellation near either pole:

    1 - cos = (1 - g) (1 - u) (k + 1 - g) / (1 - g x),    1 + g^2 - 2 g cos = k^2,

and evaluate with 1 - cos = |wo + wi|^2 / 2 (the chord, accurate for the narrow forward
lobe of g near 1). No normal: the result is the same in any frame."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ... import sampling
from ...vec import dot
from .base import LABEL_SCATTER, Lobe, LobeSample, Params

MAX_G = 1.0 - 1e-3  # Cycles' clamp: keeps the phase function from a Dirac


@dataclass
class HenyeyGreensteinParams(Params):
    """g (K,) mean cosine, |g| <= MAX_G."""

    g: np.ndarray


def phase(g: np.ndarray, one_minus_cos: np.ndarray) -> np.ndarray:
    """p (K,) per unit solid angle at 1 - cos (K,) in [0, 2]."""
    # 1 + g^2 - 2 g cos, as (1 - g)^2 + 2 g (1 - cos): no cancellation near the forward peak.
    t = (1.0 - g) ** 2 + 2.0 * g * one_minus_cos
    return (1.0 - g * g) / (4.0 * np.pi * t * np.sqrt(t))


class HenyeyGreenstein(Lobe):
    def parameters(self, g) -> HenyeyGreensteinParams:
        """g (K,) from the volume's data, clamped to |g| <= MAX_G as Cycles' setup does."""
        g = np.asarray(g, np.float64)
        return HenyeyGreensteinParams(g=np.sign(g) * np.minimum(np.abs(g), MAX_G))

    def albedo(self, p, wo):
        # A phase function scatters all it receives; a medium's colour is its mixture weight.
        return np.ones((len(p), 3))

    def eval(self, p, wo, wi):
        pdf = self.pdf(p, wo, wi)
        return np.repeat(pdf[:, None], 3, axis=1), pdf

    def pdf(self, p, wo, wi):
        d = wo + wi  # |wo + wi|^2 / 2 = 1 + wo.wi = 1 - cos(-wo, wi)
        return phase(p.g, 0.5 * dot(d, d))

    def sample(self, p, wo, u, u_branch) -> LobeSample:
        g = p.g
        u = np.clip(np.asarray(u, np.float64), 0.0, sampling.ONE_MINUS_EPSILON)
        s = 1.0 - g * (1.0 - 2.0 * u[:, 0])
        k = (1.0 - g * g) / s
        one_minus_cos = np.clip((1.0 - g) * (1.0 - u[:, 0]) * (k + 1.0 - g) / s, 0.0, 2.0)
        sin = np.sqrt(one_minus_cos * (2.0 - one_minus_cos))
        phi = 2.0 * np.pi * u[:, 1]
        local = np.stack([sin * np.cos(phi), sin * np.sin(phi), 1.0 - one_minus_cos], axis=1)
        forward = -wo
        t, b = sampling.frame_from_z(forward)
        wi = sampling.to_world(local, t, b, forward)
        return LobeSample(wi=wi, pdf=phase(g, one_minus_cos), delta=False, label=LABEL_SCATTER)
