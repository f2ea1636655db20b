"""Anisotropic GGX and Beckmann reflection as Cycles evaluates them (bsdf_microfacet.h
bsdf_aniso_D, bsdf_aniso_lambda, bsdf_microfacet_sample): F D G2 / (4 cos_o cos_i) with
alpha_x along the lobe's tangent and alpha_y across it.

The lobe's frame: z the shading normal, x the tangent projected into the surface (Cycles'
make_orthonormals_tangent). Rows arrive in the point's local frame with `a` (K,4) = (alpha_x,
alpha_y, cos phi, sin phi), phi the tangent's azimuth in that frame; directions are turned
into the lobe's frame and samples back.

- GGX: D(h) = 1 / (pi ax ay (x^2/ax^2 + y^2/ay^2 + z^2)^2); Lambda(w) = (sqrt(1 + s) - 1) / 2
  with s = (ax^2 wx^2 + ay^2 wy^2) / wz^2 (Heitz 2014, eq. 72); G2 = 1 / (1 + Lambda(wo) +
  Lambda(wi)); visible normals sampled as microfacet.sample_vndf with both alphas (Heitz 2018).
- Beckmann: D(h) = exp(-(x^2/ax^2 + y^2/ay^2) / z^2) / (pi ax ay z^4), Lambda Cycles' rational
  approximation of the same s (engine/bsdf/beckmann.py). Normals sampled from D(h) cos_h: the
  slopes are Gaussian with standard deviations ax / sqrt 2, ay / sqrt 2; pdf D(h) cos_h /
  (4 wo.h). Cycles samples Beckmann's visible normals; both estimate the same f.
"""
import numpy as np

from . import beckmann
from .microfacet import reflect, sample_vndf
from ..vec import dot, normalize


def _to_lobe(a, w):
    """Directions w (K,3) of the point's frame in the lobe's frame."""
    c, s = a[:, 2], a[:, 3]
    return np.stack([c * w[:, 0] + s * w[:, 1], c * w[:, 1] - s * w[:, 0], w[:, 2]], axis=1)


def _from_lobe(a, w):
    c, s = a[:, 2], a[:, 3]
    return np.stack([c * w[:, 0] - s * w[:, 1], s * w[:, 0] + c * w[:, 1], w[:, 2]], axis=1)


def _s(a, w):
    """(ax^2 wx^2 + ay^2 wy^2) / wz^2 (K,) (a^2 tan^2 along w); Inf on the horizon."""
    z2 = w[:, 2] * w[:, 2]
    num = (a[:, 0] * w[:, 0]) ** 2 + (a[:, 1] * w[:, 1]) ** 2
    return np.divide(num, z2, out=np.full(len(w), np.inf), where=z2 > 0.0)


class _Distribution:
    """The formulas shared by both distributions, in the lobe's frame."""

    def D(self, a, h):
        raise NotImplementedError

    def Lambda(self, a, w):
        raise NotImplementedError

    def sample_normal(self, a, wo, u):
        raise NotImplementedError

    def _pdf(self, a, wo, h, ok):
        raise NotImplementedError

    def eval_reflection(self, a, wo, wi, F):
        """f (K,3) at point-frame wo, wi; 0 unless both are above the surface."""
        wo, wi = _to_lobe(a, wo), _to_lobe(a, wi)
        den = 4.0 * wo[:, 2] * wi[:, 2]
        ok = (wo[:, 2] > 0.0) & (wi[:, 2] > 0.0) & (den > 0.0)
        h = normalize(wo + wi)
        g2 = 1.0 / (1.0 + self.Lambda(a, wo) + self.Lambda(a, wi))
        f = np.divide(self.D(a, h) * g2, den, out=np.zeros(len(wo)), where=ok)
        return np.asarray(F, np.float64) * f[:, None]

    def pdf_reflection(self, a, wo, wi):
        wo, wi = _to_lobe(a, wo), _to_lobe(a, wi)
        ok = (wo[:, 2] > 0.0) & (wi[:, 2] > 0.0)
        return self._pdf(a, wo, normalize(wo + wi), ok)

    def sample_reflection(self, a, wo, u):
        """(wi (K,3), h (K,3), pdf (K,)) in the point's frame; pdf 0 where wi is under the
        surface."""
        wo_l = _to_lobe(a, wo)
        h = self.sample_normal(a, wo_l, u)
        wi = reflect(wo_l, h)
        ok = (wo_l[:, 2] > 0.0) & (wi[:, 2] > 0.0)
        return _from_lobe(a, wi), _from_lobe(a, h), self._pdf(a, wo_l, h, ok)


class GGX(_Distribution):
    def D(self, a, h):
        x, y, z = h[:, 0] / a[:, 0], h[:, 1] / a[:, 1], h[:, 2]
        den = np.pi * a[:, 0] * a[:, 1] * (x * x + y * y + z * z) ** 2
        return np.divide(1.0, den, out=np.zeros(len(h)), where=(z > 0.0) & (den > 0.0))

    def Lambda(self, a, w):
        return 0.5 * (np.sqrt(1.0 + _s(a, w)) - 1.0)

    def sample_normal(self, a, wo, u):
        return sample_vndf(a[:, 0], wo, u, a[:, 1])

    def _pdf(self, a, wo, h, ok):
        # Visible normals: G1(wo) D(h) (wo.h) / wo.z, times 1 / (4 wo.h) for the reflection.
        num = self.D(a, h) / (1.0 + self.Lambda(a, wo))
        return np.divide(num, 4.0 * wo[:, 2], out=np.zeros(len(wo)), where=ok)


class Beckmann(_Distribution):
    def D(self, a, h):
        z2 = h[:, 2] * h[:, 2]
        ok = (h[:, 2] > 0.0) & (z2 > 0.0)
        e = np.divide((h[:, 0] / a[:, 0]) ** 2 + (h[:, 1] / a[:, 1]) ** 2, z2, out=np.full(len(h), np.inf), where=ok)
        return np.divide(np.exp(-e), np.pi * a[:, 0] * a[:, 1] * z2 * z2, out=np.zeros(len(h)), where=ok)

    def Lambda(self, a, w):
        return beckmann.lambda_of(_s(a, w))

    def sample_normal(self, a, wo, u):
        r = np.sqrt(-np.log1p(-np.clip(u[:, 0], 0.0, 1.0 - 1e-16)))
        phi = 2.0 * np.pi * u[:, 1]
        return normalize(np.stack([a[:, 0] * r * np.cos(phi), a[:, 1] * r * np.sin(phi), np.ones(len(u))], axis=1))

    def _pdf(self, a, wo, h, ok):
        cos_oh = dot(wo, h)
        return np.divide(self.D(a, h) * h[:, 2], 4.0 * cos_oh, out=np.zeros(len(h)), where=ok & (cos_oh > 0.0))


GGX_ANISO, BECKMANN_ANISO = GGX(), Beckmann()
