"""Radiance caching for moderately glossy surfaces (seed 001, last section; Krivanek, Gautron,
Pattanaik and Bouatouch 2005, "Radiance caching for efficient global illumination
computation", IEEE TVCG; algorithms.md section 1.5).

An irradiance record also holds the *incident radiance* of its gather, projected onto real
spherical harmonics of order n (harmonics.py), with a translational gradient per coefficient,
at no extra rays. At a glossy point the cached incident radiance is interpolated like
irradiance and the reflected indirect light is a dot product:

    L_o(wo) = sum_b lambda_b(p) f_b(wo),   f_b(wo) = int f(wo, w) cos(theta) Y_b(w) dw,

with the BSDF's coefficients f_b projected per query by Q stratified BSDF samples
(f_b ~ 1/Q sum_q weight_q Y_b(w_q), weight = f cos / pdf: no rays, unbiased for the cached
field). Lobes sharper than the basis serves (`harmonics.min_roughness`) are not cached: those
surfaces keep final gathering.

Choices that differ from Krivanek et al. 2005 (stated, measured in bench/results/icache/radiance.md):
- World-space SH instead of hemispherical harmonics in the record's frame: the coefficient
  vector needs no rotation to the query's frame (SH are closed under rotation, so a world-space
  vector is already "rotated" exactly). The record's hemisphere is extended evenly below its
  tangent plane, L(w) = L(mirror(w)), which keeps the function continuous at the horizon (a
  zero lower hemisphere rings); a query whose normal is tilted from the record's reads that
  mirrored radiance in the thin wedge between the two horizons.
- The same record spacing (the same a and radii) as irradiance; Krivanek et al. 2006 shrink
  a for glossier surfaces. The roughness threshold keeps the lobes wide instead.

Coefficients of one record from the cell grid of hemisphere.py (cell (j, k) holds one gather
direction w_jk and its radiance L_jk):

    lambda_b = sum_{j,k} Omega_j Ytilde_b(w_jk) L_jk,   Omega_j = (cos theta_{j-} - cos theta_{j+}) 2 pi / N,
    Ytilde_b(w) = Y_b(w) + Y_b(w - 2 (w . n_i) n_i)      (the even extension),

the cell's solid angle times the basis at its direction (bounded near the horizon, unlike
the unbiased 1 / cos weight). The translational gradient is the improved irradiance gradient
of hemisphere.translational_gradient with the weight of irradiance, cos(theta), replaced by
Ytilde_b (Krivanek et al. 2005, "Improved radiance gradient computation"): a row boundary
(theta_{j-}) sweeps solid angle sin(theta) (2 pi / N) cos(theta) / r per unit of travel, a
column boundary (cos theta_{j-} - cos theta_{j+}) / (r sin theta_j), and the radiance jump
across it is weighted by the basis function there. With Ytilde_b = cos theta it is exactly the
irradiance gradient (tested).
"""
import numpy as np

from ...scene import LOBE_DIFFUSE, LOBE_MICROFACET, LOBE_OREN_NAYAR, LOBE_PHONG
from . import harmonics
from .hemisphere import _inverse_min_distance, _tangent, column_angles, row_angles

BSDF_SAMPLES = 16      # Q: BSDF samples per query projecting f_b (no rays)


def cached_materials(m, order: int) -> np.ndarray:
    """(M,) bool: materials whose whole BSDF is low-frequency for the basis: every lobe diffuse
    (Lambert or Oren-Nayar),
    Phong with n <= max_phong_exponent(order), or microfacet reflection with roughness >=
    min_roughness(order) (any Fresnel, layering allowed); no roughness or opacity texture, no
    transmission."""
    k = m.lobe_kind
    low = (k == LOBE_DIFFUSE) | (k == LOBE_OREN_NAYAR)
    low |= (k == LOBE_PHONG) & (m.lobe_exponent <= harmonics.max_phong_exponent(order))
    low |= (k == LOBE_MICROFACET) & (m.lobe_roughness >= harmonics.min_roughness(order))
    low &= (m.lobe_roughness_tex < 0) & (m.lobe_opacity_tex < 0)
    count = np.bincount(m.lobe_material, minlength=len(m.kind))
    return (count > 0) & (np.bincount(m.lobe_material[low], minlength=len(m.kind)) == count)


def _even(order, w, n):
    """Ytilde_b(w) = Y_b(w) + Y_b(mirror of w in the plane with normal n): (..., B)."""
    mirrored = w - 2.0 * np.sum(w * n, axis=-1, keepdims=True) * n
    return harmonics.evaluate(order, w) + harmonics.evaluate(order, mirrored)


def _local_to_world(local, frame):
    """Local directions (..., 3) (leading axes broadcast against R records) -> world."""
    t, b, n = (np.asarray(a, np.float64) for a in frame)
    return np.einsum("...x,rxy->r...y", local, np.stack([t, b, n], axis=1))


def record_coefficients(order, L, r, w, frame):
    """Coefficients (R, B, C) and their translational gradients (R, B, C, 3), world space, of R
    records from one gather each: L (R, M, N, C) radiance, r (R, M, N) hit distances (inf:
    escaped), w (R, M, N, 3) the gather directions in world space, frame (t, b, n) each (R, 3)
    the records' frames (n the normal)."""
    L, r, w = (np.asarray(a, np.float64) for a in (L, r, w))
    R, M, N = r.shape
    t, b, n = (np.asarray(a, np.float64) for a in frame)
    sin_lo, cos_lo, sin_c, cos_c = row_angles(M)
    phi_lo, phi_c = column_angles(N)
    omega = (cos_lo[:-1] - cos_lo[1:]) * (2.0 * np.pi / N)                        # (M,)
    Y = _even(order, w, n[:, None, None, :])                                         # (R, M, N, B)
    coeffs = np.einsum("j,rjkb,rjkc->rbc", omega, Y, L)

    def at(sin_t, cos_t, phi):   # the basis at local (theta, phi) grid points: (R, J, K, B)
        local = np.stack(np.broadcast_arrays(sin_t[:, None] * np.cos(phi)[None], sin_t[:, None] * np.sin(phi)[None],
                                             cos_t[:, None] + 0 * phi[None]), axis=-1)
        return _even(order, _local_to_world(local, (t, b, n)), n[:, None, None, :])

    # Row boundaries theta_{j-}, j = 1..M-1, at the column centres, moved along u_k.
    w_rows = (2.0 * np.pi / N) * sin_lo[1:M] * cos_lo[1:M]                            # (M-1,)
    Y_rows = at(sin_lo[1:M], cos_lo[1:M], phi_c)                                      # (R, M-1, N, B)
    inv_rows = _inverse_min_distance(r[:, 1:], r[:, :-1])
    d_rows = L[:, 1:] - L[:, :-1]
    rows = np.einsum("j,rjkb,rjk,rjkc->rkbc", w_rows, Y_rows, inv_rows, d_rows)
    # Column boundaries phi_{k-} at the row centres, moved along v_k-.
    w_cols = (1.0 / M) / (cos_lo[:-1] + cos_lo[1:]) / sin_c                          # (M,)
    Y_cols = at(sin_c, cos_c, phi_lo)                                                 # (R, M, N, B)
    inv_cols = _inverse_min_distance(r, np.roll(r, 1, axis=2))
    d_cols = L - np.roll(L, 1, axis=2)
    cols = np.einsum("j,rjkb,rjk,rjkc->rkbc", w_cols, Y_cols, inv_cols, d_cols)
    u_world = _local_to_world(_tangent(phi_c), (t, b, n))                             # (R, N, 3)
    v_world = _local_to_world(_tangent(phi_lo + 0.5 * np.pi), (t, b, n))
    grad = np.einsum("rkbc,rkx->rbcx", rows, u_world) + np.einsum("rkbc,rkx->rbcx", cols, v_world)
    return coeffs, grad


def limit_gradient(coeffs, grad, radius):
    """grad (R, B, C, 3) scaled down per record and channel so that over its radius R_i it
    changes the coefficient vector by at most its norm: |grad_c| R_i <= |lambda_c| (Frobenius
    norms over b and the axes). The analogue of the irradiance limit R_i <= E / |grad E|
    (Krivanek et al. 2008), applied to the gradient because the radius is irradiance's: the
    boundary terms weigh the jump in radiance by the basis at the horizon, where irradiance's
    cos(theta) vanishes, so a noisy gather near a wall (small r) gives large, noisy gradients."""
    g = np.sqrt(np.einsum("rbcx,rbcx->rc", grad, grad)) * np.asarray(radius)[:, None]
    norm = np.sqrt(np.einsum("rbc,rbc->rc", coeffs, coeffs))
    scale = np.divide(norm, g, out=np.ones_like(g), where=g > norm)
    return grad * scale[:, None, :, None]


def interpolate(octree, p, n, gradients=True):
    """Cached incident-radiance coefficients (K, B, C) at points p (K,3) with normals n: the
    weighted average of the records' coefficients (moved by their translational gradients),
    over the records that pass the octree's weight test (the same as irradiance's), and the
    number of those records (K,) (0: not covered, coefficients 0)."""
    rec = octree.records
    K = len(p)
    B, C = rec.coeffs.shape[1:]
    rows, recs, w = octree.weights(p, n)
    value = np.take(rec.coeffs, recs, axis=0)
    if gradients and len(recs):
        diff = np.take(p, rows, axis=0) - np.take(rec.position, recs, axis=0)
        value = value + np.einsum("pbcx,px->pbc", np.take(rec.coeffs_grad, recs, axis=0), diff)
    out = np.zeros((K, B * C))
    flat = (w[:, None] * value.reshape(len(recs), B * C))
    for i in range(B * C):
        out[:, i] = np.bincount(rows, weights=flat[:, i], minlength=K)
    wsum = np.bincount(rows, weights=w, minlength=K)
    np.divide(out, wsum[:, None], out=out, where=wsum[:, None] > 0)
    return out.reshape(K, B, C), np.bincount(rows, minlength=K)


def bsdf_coefficients(order, sample, samples=BSDF_SAMPLES):
    """f_b (K, B, C) from Q = samples BSDF samples per point: sample(q) -> (wi (K,3), weight
    (K,C) = f cos / pdf, 0 where invalid) for q = 0..Q-1. f_b = 1/Q sum_q weight_q Y_b(wi_q)."""
    out = None
    Q = samples
    for q in range(Q):
        wi, weight = sample(q)
        term = np.einsum("kb,kc->kbc", harmonics.evaluate(order, wi), weight)
        out = term if out is None else out + term
    return out / Q


def reflected(coeffs, f):
    """L_o (K, C) = sum_b lambda_b f_b per channel, clamped >= 0 (a truncated expansion can
    ring below 0)."""
    return np.maximum(np.einsum("kbc,kbc->kc", coeffs, f), 0.0)


def reconstruct(coeffs, w, order):
    """The cached incident radiance (K, C) along directions w (K, 3): sum_b lambda_b Y_b(w)."""
    return np.einsum("kbc,kb->kc", coeffs, harmonics.evaluate(order, w))

