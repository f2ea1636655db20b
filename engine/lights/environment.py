"""Environment map light: radiance from an image on the sphere at infinity, importance sampled.

L(d) = scale * image[cell(A d / |A d|)] for world directions d, where A = World.env_from_world is
the linear map Cycles applies to the lookup vector (Mapping node) and cell() is Cycles'
projection followed by a nearest-pixel lookup (intern/cycles/kernel/camera/projection.h):

  equirectangular  u = 0.5 - atan2(e_y, e_x) / 2 pi,  v = 1 - theta / pi  (theta from +z)
  mirror ball      the ball seen from -y: u = (X + 1) / 2, v = (Z + 1) / 2 with
                   (X, Z) = (e_x, e_z) / (2 sqrt((1 - e_y) / 2))

Image rows are top-down (row 0 = v = 1), so the row coordinate is y = 1 - v.

Sampling (seed 000, section 3): a piecewise-constant 2D distribution over the pixels
(`sampling.Distribution2D`, float64 CDFs: marginal over rows, conditional within a row) with
weight luminance(|scale * pixel|) x the pixel's solid angle. Inside the chosen pixel the
direction is drawn uniformly in solid angle, so the solid-angle pdf is constant over a pixel
and L / pdf is the same for every direction of a pixel (no specks next to a hot pixel).

  equirectangular: a pixel of row r spans theta in [r, r + 1] pi / H and has solid angle
      dw_r = (2 pi / W) dz_r, dz_r = cos theta_r - cos theta_r+1 = 2 sin(theta_c) sin(pi / 2H),
      exactly proportional to sin(theta_c) at the row centre; cos theta is drawn linearly inside
      the row. pdf = p_uv / (W H dw_r) = p_uv / (2 pi H dz_r), which is pbrt's
      p_uv / (2 pi^2 sin theta) with sin theta replaced by the row's exact mean
      (H dz_r / pi -> sin theta_c as H grows); it stays finite in the pole rows.
  mirror ball: equal-area (dw = 16 du dv), pdf = p_uv / 16; a pixel is weighted by the part of
      it inside the ball, and a sample drawn in a pixel's corner outside the ball is invalid
      (pdf 0 there, so the density of valid samples is still exactly pdf).

A non-orthonormal A (non-uniform scale) changes solid angles: pdf_world(d) =
pdf_env(e) |det A| / |A d|^3.

MIS compensation (Karlik et al. 2019, "MIS compensation: optimizing sampling techniques in
multiple importance sampling"; pbrt-v4 ImageInfiniteLight's compensatedDistribution): when the
environment is combined with BSDF sampling by MIS, the table is built from
max(luminance - its solid-angle mean, 0) instead: BSDF sampling already covers the smooth part
well, so light samples go to what stands out (a sun). Directions with weight 0 are left to
BSDF sampling (their MIS weight becomes 1), so this is only valid under MIS; it is skipped when
the map is nearly flat (its maximum within 1 % of the mean).

Sources read (formulas only): blender/blender intern/cycles/kernel/camera/projection.h,
kernel/svm/mapping_util.h, kernel/light/background.h; pbrt-v3 src/lights/infinite.cpp;
Mitsuba 0.6 src/emitters/envmap.cpp.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import sampling
from ..errors import EmberError
from ..scene import ENV_PROJECTIONS
from ..textures import LUMINANCE  # Cycles' rgb_to_y weights (Rec. 709)

_BALL_SUBSAMPLES = 8  # per axis, to estimate how much of a mirror-ball pixel lies in the ball
_BALL_MIN_FRACTION = 1e-3  # a pixel that touches the ball is never given weight 0


@dataclass(frozen=True, slots=True)
class EnvironmentSample:
    """N directions drawn from an environment map.

    wi (N,3) unit world direction towards the environment; Le (N,3) radiance arriving along
    -wi (W/(m^2 sr)), 0 where not valid; pdf (N,) solid-angle pdf of wi (1/sr), 0 where not
    valid; valid (N,) bool, False where the pdf is 0 or not finite: mirror-ball samples drawn
    in a pixel's corner outside the ball.
    """

    wi: np.ndarray
    Le: np.ndarray
    pdf: np.ndarray
    valid: np.ndarray


def _as_image(image) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3 or img.shape[0] < 1 or img.shape[1] < 1:
        raise EmberError(f"Environment image must be (H, W, 3), got shape {img.shape}.")
    if img.dtype != np.float32:
        img = img.astype(np.float32)
    return img


class EnvironmentMap:
    """The world's image light. Build once per render; all methods are wavefront.

    image (H, W, 3) float32 linear RGB, rows top-down (kept by reference, not copied);
    scale (3,) radiance factor (Background colour x strength); projection in ENV_PROJECTIONS;
    env_from_world (3, 3) invertible; compensate: build the MIS-compensated table (only for
    use with MIS, see the module docstring). Attributes: power_integral (3,) = integral of L
    over the sphere (W/m^2 per channel), used for light selection; compensated (bool).
    """

    def __init__(self, image, scale=(1.0, 1.0, 1.0), projection="EQUIRECTANGULAR", env_from_world=None,
                 compensate=False):
        if projection not in ENV_PROJECTIONS:
            raise EmberError(f"Unknown environment projection {projection!r} "
                             f"(use one of {', '.join(ENV_PROJECTIONS)}).")
        self.image = _as_image(image)
        self.scale = np.asarray(scale, np.float64).reshape(3)
        self.projection = projection
        A = np.eye(3) if env_from_world is None else np.asarray(env_from_world, np.float64).reshape(3, 3)
        det = float(np.linalg.det(A))
        if not (np.isfinite(det) and abs(det) > 1e-12):
            raise EmberError("The environment's mapping is singular (a scale of 0?); it cannot be inverted.")
        self.env_from_world = A
        self.world_from_env = np.linalg.inv(A)
        self._abs_det = abs(det)
        self._rigid = bool(np.allclose(A @ A.T, np.eye(3), rtol=0, atol=1e-12))
        H, W = self.image.shape[:2]
        self.shape = (H, W)
        if projection == "EQUIRECTANGULAR":
            half = 0.5 * np.pi / H
            theta_c = (np.arange(H) + 0.5) * (np.pi / H)
            self._dz = 2.0 * np.sin(theta_c) * np.sin(half)  # cos theta_r - cos theta_r+1, no cancellation
            edges = np.arange(H + 1) * (np.pi / H)
            self._one_minus_z_top = 2.0 * np.sin(0.5 * edges[:-1]) ** 2  # 1 - cos theta_r
            self._one_plus_z_bottom = 2.0 * np.cos(0.5 * edges[1:]) ** 2  # 1 + cos theta_r+1
            self._pdf_from_uv = np.divide(1.0, 2.0 * np.pi * H * self._dz, out=np.zeros(H), where=self._dz > 0)
            solid_angle = (2.0 * np.pi / W) * self._dz[:, None]  # (H, 1): the same for a whole row
        else:
            solid_angle = 16.0 / (H * W) * _ball_fraction(H, W)  # (H, W)
        weight = self._luminance_table()
        self.compensated = compensate and _compensate(weight, solid_angle)
        weight *= solid_angle.astype(np.float32)
        self.table = sampling.Distribution2D(weight)
        del weight
        # Integral of L over the sphere, sum of L x pixel solid angle, for light selection only
        # (float32 BLAS products: any positive power keeps the estimator unbiased).
        if solid_angle.shape[1] == 1:
            per_column = solid_angle[:, 0].astype(np.float32) @ self.image.reshape(H, W * 3)
            integral = per_column.reshape(W, 3).sum(axis=0, dtype=np.float64)
        else:
            integral = solid_angle.astype(np.float32).reshape(H * W) @ self.image.reshape(H * W, 3)
        self.power_integral = self.scale * integral.astype(np.float64)

    def _luminance_table(self) -> np.ndarray:
        """(H, W) float32 luminance of |scale * image| (a BLAS matrix-vector product: fast)."""
        k = (LUMINANCE * np.abs(self.scale)).astype(np.float32)
        img = self.image
        if img.min() < 0:  # HDRs may hold small negative values; the table takes |.|
            img = np.abs(img)
        H, W = self.shape
        return (img.reshape(H * W, 3) @ k).reshape(H, W)

    # ---- projections (env space) -------------------------------------------------------------
    def _cell(self, e):
        """(row, col) of unit env-space directions e (N, 3)."""
        H, W = self.shape
        if self.projection == "EQUIRECTANGULAR":
            u = 0.5 - np.arctan2(e[:, 1], e[:, 0]) / (2.0 * np.pi)
            y = np.arctan2(np.hypot(e[:, 0], e[:, 1]), e[:, 2]) / np.pi
        else:
            div = 2.0 * np.sqrt(np.maximum(0.5 * (1.0 - e[:, 1]), 0.0))
            inv = np.divide(1.0, div, out=np.zeros_like(div), where=div > 0)
            u = 0.5 * (e[:, 0] * inv + 1.0)
            y = 0.5 * (1.0 - e[:, 2] * inv)
        col = np.clip(np.floor(u * W).astype(np.int64), 0, W - 1)
        row = np.clip(np.floor(y * H).astype(np.int64), 0, H - 1)
        return row, col

    def _to_env(self, d):
        """Unit env directions e (N, 3) and the solid-angle Jacobian factor (N,) or None."""
        d = np.asarray(d, np.float64)
        if self._rigid:
            return d @ self.env_from_world.T, None
        e = d @ self.env_from_world.T
        n = np.sqrt(np.einsum("ij,ij->i", e, e))
        e = e / np.where(n > 0, n, 1.0)[:, None]
        return e, np.divide(self._abs_det, n**3, out=np.zeros_like(n), where=n > 0)

    # ---- queries -------------------------------------------------------------------------------
    def eval(self, d) -> np.ndarray:
        """Radiance (N, 3) float64 arriving from unit world directions d (N, 3) (W/(m^2 sr))."""
        e, _ = self._to_env(d)
        row, col = self._cell(e)
        return self.image[row, col].astype(np.float64) * self.scale

    def pdf(self, d) -> np.ndarray:
        """Solid-angle pdf (N,) with which `sample` produces the unit world directions d (N, 3)."""
        e, jac = self._to_env(d)
        row, col = self._cell(e)
        pdf = self._pdf_cell(row, col)
        return pdf if jac is None else pdf * jac

    def _pdf_cell(self, row, col):
        """Solid-angle pdf (N,) in env space of the cells (row, col)."""
        H, W = self.shape
        p_uv = self.table.pdf(np.stack([(col + 0.5) / W, (row + 0.5) / H], axis=-1))
        return self._pdf_from_p_uv(p_uv, row)

    def _pdf_from_p_uv(self, p_uv, row):
        if self.projection == "EQUIRECTANGULAR":
            return p_uv * self._pdf_from_uv[row]
        return p_uv / 16.0

    def sample(self, u) -> EnvironmentSample:
        """Directions from u (N, 2) in [0, 1)^2."""
        H, W = self.shape
        uv, p_uv, (row, col) = self.table.sample(u)
        x = uv[:, 0]
        dy = np.clip(uv[:, 1] * H - row, 0.0, 1.0)  # position inside the row, margins kept by the table
        if self.projection == "EQUIRECTANGULAR":
            phi = np.pi * (1.0 - 2.0 * x)
            # cos theta linear inside the row (uniform in solid angle); 1 - z and 1 + z kept apart
            # so sin theta is accurate in the pole rows.
            one_minus_z = self._one_minus_z_top[row] + dy * self._dz[row]
            one_plus_z = self._one_plus_z_bottom[row] + (1.0 - dy) * self._dz[row]
            sin_theta = np.sqrt(np.maximum(one_minus_z * one_plus_z, 0.0))
            e = np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), 0.5 * (one_plus_z - one_minus_z)], axis=-1)
            valid = np.ones(len(x), bool)
        else:
            X = 2.0 * x - 1.0
            Z = 1.0 - 2.0 * uv[:, 1]
            r2 = X * X + Z * Z
            valid = r2 < 1.0
            r2 = np.minimum(r2, 1.0)  # corner samples become the back direction +y (still unit)
            c = np.sqrt(1.0 - r2)
            e = np.stack([2.0 * c * X, 2.0 * r2 - 1.0, 2.0 * c * Z], axis=-1)
        pdf = self._pdf_from_p_uv(p_uv, row)
        if self._rigid:
            wi = e @ self.world_from_env.T
        else:
            d = e @ self.world_from_env.T
            n = np.sqrt(np.einsum("ij,ij->i", d, d))
            wi = d / np.where(n > 0, n, 1.0)[:, None]
            pdf = pdf * self._abs_det * n**3  # |A d| = 1 / |A^-1 e| for d = A^-1 e / |A^-1 e|
        Le = self.image[row, col].astype(np.float64) * self.scale
        valid &= (pdf > 0) & np.isfinite(pdf)
        return EnvironmentSample(wi, np.where(valid[:, None], Le, 0.0), np.where(valid, pdf, 0.0), valid)

    def uncompensated(self) -> "EnvironmentMap":
        """The same light with the uncompensated table (photon emission)."""
        if not self.compensated:
            return self
        return EnvironmentMap(self.image, self.scale, self.projection, self.env_from_world, compensate=False)

    @property
    def nbytes(self) -> int:
        """Bytes held by the sampling table (the image is the scene's)."""
        t = self.table
        return t.func.nbytes + t.cdf.nbytes + t.marginal.func.nbytes + t.marginal.cdf.nbytes


def _compensate(lum: np.ndarray, solid_angle: np.ndarray) -> bool:
    """Replace lum (H, W) in place by max(lum - mean, 0), the mean weighted by solid_angle
    ((H, 1) per row, or (H, W)); False (lum untouched) if the map is nearly flat."""
    if solid_angle.shape[1] == 1:
        total = float(solid_angle[:, 0] @ lum.sum(axis=1, dtype=np.float64))
        sphere = float(solid_angle.sum()) * lum.shape[1]
    else:
        total = float(np.sum(lum * solid_angle, dtype=np.float64))
        sphere = float(solid_angle.sum())
    mean = total / sphere
    if not float(lum.max()) - mean > 0.01 * mean:
        return False
    lum -= np.float32(mean)
    np.maximum(lum, 0.0, out=lum)
    return True


def _ball_fraction(H: int, W: int) -> np.ndarray:
    """(H, W) fraction of each mirror-ball pixel inside the ball (the unit disk of X = 2u - 1,
    Z = 1 - 2y): 1 or 0 for pixels wholly inside or outside, a sub-pixel grid estimate for the
    O(H + W) pixels the rim crosses, at least _BALL_MIN_FRACTION for any pixel touching the disk
    (so every direction keeps a positive pdf)."""
    x0, x1 = 2.0 * np.arange(W) / W - 1.0, 2.0 * np.arange(1, W + 1) / W - 1.0
    z1, z0 = 1.0 - 2.0 * np.arange(H) / H, 1.0 - 2.0 * np.arange(1, H + 1) / H
    near = np.clip(0.0, z0, z1)[:, None] ** 2 + np.clip(0.0, x0, x1)[None, :] ** 2
    far = np.maximum(z0**2, z1**2)[:, None] + np.maximum(x0**2, x1**2)[None, :]
    fraction = (far <= 1.0).astype(np.float64)
    rim_r, rim_c = np.nonzero((near < 1.0) & (far > 1.0))
    k = _BALL_SUBSAMPLES
    s = (np.arange(k) + 0.5) / k
    X = 2.0 * (rim_c[:, None] + s[None, :]) / W - 1.0  # (K, k)
    Z = 1.0 - 2.0 * (rim_r[:, None] + s[None, :]) / H
    inside = (X[:, None, :] ** 2 + Z[:, :, None] ** 2 < 1.0).mean(axis=(1, 2))
    fraction[rim_r, rim_c] = np.maximum(inside, _BALL_MIN_FRACTION)
    return fraction


def world_light(world, compensate=False):
    """What a World needs to be lit with: (constant radiance (3,) float64, EnvironmentMap or None).

    Only what the scene needs: a black world (zero colour or an all-zero image) is no light at
    all; a constant world or a constant image (e.g. 1 x 1) is a constant radiance that BSDF
    sampling covers, with no table; only a varying image builds an EnvironmentMap (with the
    MIS-compensated table if `compensate`).
    """
    scale = np.asarray(world.color, np.float64).reshape(3)
    image = world.image
    if image is None:
        return scale.copy(), None
    image = _as_image(image)
    lo, hi = image.min(), image.max()  # flat reductions: fast, and they propagate NaN
    if not (np.isfinite(lo) and np.isfinite(hi)):
        raise EmberError("The environment image contains NaN or infinite pixels.")
    if not np.any(scale != 0) or lo == hi == 0:
        return np.zeros(3), None
    first = image[0, 0]
    if np.array_equal(image[-1, -1], first) and np.all(image == first):  # cheap reject first
        return scale * first.astype(np.float64), None
    return np.zeros(3), EnvironmentMap(image, scale, world.projection, world.env_from_world, compensate)
