"""Sheen: Cycles' two models of the Sheen BSDF (and the Principled BSDF's sheen layer).

Microfiber (Cycles' default; Zeltner, Burley & Chiang 2022, "Practical Multiple-Scattering
Sheen Using Linearly Transformed Cosines"): the cosine-weighted BRDF is a linearly transformed
cosine lobe scaled by the directional albedo R of a layer of fibres,

    f cos_i = R(mu_o, r) D(wi),   D(w) = z a^2 / (pi ((a x + b z)^2 + (a y)^2 + z^2)^2),

with w in the frame whose x axis is wo's projection on the surface (Cycles'
make_orthonormals_safe_tangent), the inverse transform [[a, 0, b], [0, a, 0], [0, 0, 1]] and
(a, b, R) read from a 32 x 32 table over (mu_o = cos of wo, roughness r in [1e-3, 1]) with
Cycles' bilinear lookup (kernel/util/lookup_table.h). D is a normalised density over wi that
sampling draws exactly (a cosine sample mapped by the inverse transform), so the lobe's pdf
is D itself and its albedo is R. The table (sheen_ltc.npz) is ours: R and the lobe's shape
come from a random walk in the paper's reference model (a unit slab of fibre-like SGGX
microflakes, sigma = r^2), (a, b) the LTC most likely to have produced the walks' exit
directions; tools/sheen_table.py regenerates it.

Ashikhmin velvet (Cycles' closure/bsdf_ashikhmin_velvet.h, from OSL): an inverted-Gaussian
microfacet distribution D(h) = exp(-cot^2 / s^2) / (pi s^2 sin^4), G = min(1, 2 cos_h
cos_o / (h.wo), 2 cos_h cos_i / (h.wo)), f = D G / (4 cos_o cos_i), s = max(sigma, 0.01),
sampled uniformly over the hemisphere.
"""
from __future__ import annotations

import pathlib
from functools import lru_cache

import numpy as np

from .. import sampling

TABLE_FILE = pathlib.Path(__file__).with_name("sheen_ltc.npz")
GRID = 32  # the table's nodes per axis, as Cycles'
MIN_ROUGHNESS = 1e-3  # Cycles' bsdf_sheen_setup clamp
# Cycles drops a microfiber closure whose transform or albedo falls below this.
MIN_LTC = 1e-5


@lru_cache(maxsize=1)
def table() -> dict:
    """{"a", "b", "R"}: (GRID, GRID) float64 arrays indexed [roughness node, mu node]."""
    with np.load(TABLE_FILE) as z:
        return {k: z[k].astype(np.float64) for k in ("a", "b", "R")}


def _lerp(x: np.ndarray):
    """Cycles' lookup_table_read indexing: (index, next, fraction) of x in [0, 1]."""
    x = np.clip(x, 0.0, 1.0) * (GRID - 1)
    i = np.minimum(x.astype(np.int64), GRID - 1)
    return i, np.minimum(i + 1, GRID - 1), x - i


def lookup(mu: np.ndarray, roughness: np.ndarray):
    """(a, b, R) (K,) each at cosines mu (K,) of wo and roughness (K,) (clamped as Cycles)."""
    t = table()
    i, i1, fx = _lerp(mu)
    j, j1, fy = _lerp(np.clip(roughness, MIN_ROUGHNESS, 1.0))

    def read(v):
        lo = (1.0 - fx) * v[j, i] + fx * v[j, i1]
        hi = (1.0 - fx) * v[j1, i] + fx * v[j1, i1]
        return (1.0 - fy) * lo + fy * hi

    return read(t["a"]), read(t["b"]), read(t["R"])


def mean_albedo(roughness: np.ndarray) -> np.ndarray:
    """(K,) cosine-weighted mean of R over the hemisphere of wo, 2 int R(mu) mu dmu."""
    roughness = np.asarray(roughness, np.float64)
    mu = (np.arange(64) + 0.5) / 64
    R = lookup(np.tile(mu, len(roughness)), np.repeat(roughness, len(mu)))[2].reshape(len(roughness), len(mu))
    return 2.0 * (R * mu).mean(axis=1)


def valid(a: np.ndarray, R: np.ndarray) -> np.ndarray:
    """(K,) bool: rows Cycles keeps (an invertible transform and a non-zero albedo)."""
    return (np.abs(a) >= MIN_LTC) & (R >= MIN_LTC)


def view_frame(wo: np.ndarray):
    """(x, y) (K,3) each: the tangent frame with x along wo's projection on the surface
    (z the normal); any frame where wo is the normal."""
    t = np.stack([wo[:, 0], wo[:, 1], np.zeros(len(wo))], axis=1)
    n = np.sqrt(t[:, 0] ** 2 + t[:, 1] ** 2)
    ok = n > 1e-7
    x = np.where(ok[:, None], t / np.where(ok, n, 1.0)[:, None], np.array([1.0, 0.0, 0.0]))
    y = np.stack([-x[:, 1], x[:, 0], np.zeros(len(wo))], axis=1)  # z x x
    return x, y


def ltc_density(a: np.ndarray, b: np.ndarray, w: np.ndarray) -> np.ndarray:
    """D (K,) of directions w (K,3) in the view frame (solid angle); 0 under the surface."""
    x, y, z = w[:, 0], w[:, 1], w[:, 2]
    len2 = (a * x + b * z) ** 2 + (a * y) ** 2 + z * z
    return np.where(z > 0, z * np.divide(a * a, len2 * len2, out=np.zeros(len(w)), where=len2 > 0) / np.pi, 0.0)


def ltc_sample(a: np.ndarray, b: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Directions (K,3) in the view frame drawn from D: a cosine sample mapped by the
    transform (x - b z, y, a z), normalised."""
    d = sampling.sample_concentric_disk(u)
    z = np.sqrt(np.maximum(1.0 - d[:, 0] ** 2 - d[:, 1] ** 2, 0.0))
    w = np.stack([d[:, 0] - b * z, d[:, 1], a * z], axis=1)
    return w / np.linalg.norm(w, axis=1, keepdims=True)


def microfiber_eval(a, b, wo: np.ndarray, wi: np.ndarray):
    """(D cos-free factor D / cos_i (K,), pdf D (K,)) at local wo, wi (K,3) (z the normal)."""
    x, y = view_frame(wo)
    w = np.stack([np.einsum("ij,ij->i", wi, x), np.einsum("ij,ij->i", wi, y), wi[:, 2]], axis=1)
    D = ltc_density(a, b, w)
    return np.divide(D, wi[:, 2], out=np.zeros(len(wi)), where=wi[:, 2] > 0), D


def microfiber_sample(a, b, wo: np.ndarray, u: np.ndarray):
    """(wi (K,3) local, pdf (K,))."""
    x, y = view_frame(wo)
    w = ltc_sample(a, b, u)
    wi = w[:, :1] * x + w[:, 1:2] * y
    wi[:, 2] = w[:, 2]
    return wi, ltc_density(a, b, w)


def velvet_sigma(roughness: np.ndarray) -> np.ndarray:
    return np.maximum(roughness, 0.01)


def velvet_eval(sigma: np.ndarray, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
    """f (K,) (no cosine) of the Ashikhmin velvet at local wo, wi (K,3); 0 where Cycles
    rejects the pair (either side under the surface, h along the normal or grazing wo)."""
    cos_o, cos_i = wo[:, 2], wi[:, 2]
    h = wo + wi
    h = h / np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-300)
    cos_h = h[:, 2]
    cos_hv = np.abs(np.einsum("ij,ij->i", wo, h))
    ok = (cos_o > 0) & (cos_i > 0) & (np.abs(cos_h) < 1.0 - 1e-5) & (cos_hv > 1e-5)
    ratio = np.maximum(np.divide(cos_h, cos_hv, out=np.zeros(len(wo)), where=ok), 1e-5)
    G = np.minimum(1.0, np.minimum(2.0 * ratio * cos_o, 2.0 * ratio * cos_i))
    sin2 = np.where(ok, 1.0 - cos_h * cos_h, 1.0)
    inv_s2 = 1.0 / (sigma * sigma)
    D = np.exp(-cos_h * cos_h / sin2 * inv_s2) * inv_s2 / (np.pi * sin2 * sin2)
    den = 4.0 * cos_o * cos_i
    return np.where(ok, D * G / np.where(ok, den, 1.0), 0.0)


def velvet_sample(u: np.ndarray):
    """(wi (K,3) local, pdf (K,)): uniform over the hemisphere, as Cycles."""
    wi = sampling.sample_uniform_hemisphere(u)
    return wi, sampling.pdf_uniform_hemisphere(wi[:, 2])
