"""Where on a textured emitter's triangles light samples go: each triangle whose emission
varies over the surface is cut into k x k congruent sub-triangles (the regular subdivision of
its barycentric domain), the emission program is evaluated at four points of each, and a point
is drawn by choosing a sub-triangle by that luminance, then uniformly inside it. An emissive map
then lights the scene from its bright texels rather than as if it were uniform.

The radiance a sample carries is the program's own at its point, not the table's: the table
only shapes the pdf, which is the table's exactly (pdf_in_triangle). Every sub-triangle keeps at
least FLOOR x its triangle's mean weight, so no point where the surface shines has pdf 0 even
where a centre misses a thin bright feature; MIS with BSDF sampling stays unbiased.

Resolution: k is chosen per scene so that all varying triangles together have about BUDGET
sub-triangles (a single emissive quad gets MAX_K x MAX_K per triangle, a mesh of more than
BUDGET emissive triangles one each: its triangles are then the texels). Cost: four program
evaluations per sub-triangle at build time, 16 bytes of tables per sub-triangle.
"""
from __future__ import annotations

import numpy as np

from .. import sampling
from ..textures import LUMINANCE

BUDGET = 1 << 16  # sub-triangles over all varying triangles
MAX_K = 32
FLOOR = 0.01
# Where each sub-triangle is probed, as weights of its two edges: the centre, and halfway from
# it to each corner.
_PROBES = np.array([[1 / 3, 1 / 3], [1 / 6, 1 / 6], [2 / 3, 1 / 6], [1 / 6, 2 / 3]])


def _subdivision(k: int):
    """The k^2 sub-triangles of the barycentric domain {(u, v): u, v >= 0, u + v <= 1} (u, v the
    weights of corners 1 and 2): origin (S,2), edges (S,2) and (S,2); and the lookup (k, k, 2)
    from a cell (floor(k u), floor(k v)) and whether the point lies past its diagonal to the
    sub-triangle's index; neighbours (S,4) each sub-triangle's own index and its neighbours'."""
    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    up = (i + j <= k - 1).ravel()
    down = (i + j <= k - 2).ravel()
    i, j = i.ravel(), j.ravel()
    origin = np.concatenate([np.stack([i[up], j[up]], 1), np.stack([i[down] + 1, j[down] + 1], 1)]) / k
    e1 = np.concatenate([np.tile([1.0, 0.0], (up.sum(), 1)), np.tile([-1.0, 0.0], (down.sum(), 1))]) / k
    e2 = np.concatenate([np.tile([0.0, 1.0], (up.sum(), 1)), np.tile([0.0, -1.0], (down.sum(), 1))]) / k
    lookup = np.zeros((k, k, 2), np.int64)
    lookup[i[up], j[up], 0] = np.arange(up.sum())
    lookup[i[down], j[down], 1] = up.sum() + np.arange(down.sum())
    # Cells on the diagonal have no second half: rounding past it reads the first.
    lookup[i[up & ~down], j[up & ~down], 1] = lookup[i[up & ~down], j[up & ~down], 0]
    # Each sub-triangle with the ones sharing an edge (itself where it has none there): an
    # upright one's are the inverted ones of its cell and of the cells below in u and in v,
    # an inverted one's the upright ones of its cell and of the cells above.
    iu, ju, idn, jdn = i[up], j[up], i[down], j[down]
    own_u, own_d = lookup[iu, ju, 0], lookup[idn, jdn, 1]

    def at(ii, jj, half, fallback):
        ok = (ii >= 0) & (jj >= 0) & (ii < k) & (jj < k) & (ii + jj <= k - 1 - half)
        return np.where(ok, lookup[np.clip(ii, 0, k - 1), np.clip(jj, 0, k - 1), half], fallback)
    neighbours = np.concatenate([
        np.stack([own_u, at(iu, ju, 1, own_u), at(iu - 1, ju, 1, own_u), at(iu, ju - 1, 1, own_u)], 1),
        np.stack([own_d, at(idn, jdn, 0, own_d), at(idn + 1, jdn, 0, own_d), at(idn, jdn + 1, 0, own_d)], 1)])
    return origin, e1, e2, lookup, neighbours


class EmissionMaps:
    """Sub-triangle tables of the varying triangles. radiance(t, b) (K,3) evaluates the
    emission at barycentrics b (K,3) of varying triangle t (K,) (indices into the table's
    triangles); count: how many triangles."""

    def __init__(self, count: int, radiance, budget: int = BUDGET):
        self.k = int(np.clip(np.sqrt(budget / max(count, 1)), 1, MAX_K))
        self.origin, self.e1, self.e2, self.lookup, self.neighbours = _subdivision(self.k)
        s = len(self.origin)
        # Per sub-triangle: its centre and three points halfway from it to the corners.
        points = self.origin[:, None] + _PROBES[None, :, :1] * self.e1[:, None] + _PROBES[None, :, 1:] * self.e2[:, None]
        uv = np.tile(points.reshape(-1, 2), (count, 1))
        b = np.column_stack([1.0 - uv.sum(axis=1), uv])
        Le = radiance(np.repeat(np.arange(count), s * len(_PROBES)), b).reshape(count, s, len(_PROBES), 3)
        self.mean = Le.mean(axis=(1, 2))  # (count, 3): the triangle's mean radiance
        lum = np.maximum(Le @ LUMINANCE, 0.0)
        # Halfway between the probes' mean and the largest probe of it and its neighbours: a
        # sub-triangle with a bright sliver its own probes miss (a texture's edge crossing it)
        # is not starved.
        w = 0.5 * (lum.mean(axis=2) + lum.max(axis=2)[:, self.neighbours].max(axis=2))
        w = np.maximum(w, FLOOR * w.mean(axis=1, keepdims=True))
        w = np.where(w.sum(axis=1, keepdims=True) > 0, w, 1.0)  # all dark: uniform
        self.pmf = w / w.sum(axis=1, keepdims=True)  # (count, S)
        cdf = np.cumsum(self.pmf, axis=1)
        cdf[:, -1] = 1.0
        # Rows offset by their index: one searchsorted over all of them.
        self._cdf = (cdf + np.arange(count)[:, None]).ravel()
        self.nbytes = self.pmf.nbytes + self._cdf.nbytes

    def sample(self, t: np.ndarray, u: np.ndarray):
        """Barycentrics (N,3) on varying triangles t (N,) from u (N,2), and the pdf (N,) with
        respect to the triangle's area times its area (pdf_in_triangle)."""
        s = len(self.origin)
        u = np.asarray(u, np.float64)
        u0 = np.clip(u[:, 0], 0.0, sampling.ONE_MINUS_EPSILON)
        flat = np.searchsorted(self._cdf, t + u0, side="right")
        flat = np.minimum(flat, (t + 1) * s - 1)
        j = flat - t * s
        pmf = self.pmf[t, j]
        lo = self._cdf[flat] - t - pmf  # the cdf below sub-triangle j
        v = np.column_stack([(u0 - lo) / pmf, u[:, 1]]).clip(0.0, sampling.ONE_MINUS_EPSILON)
        a = sampling.sample_uniform_triangle(v, in_unit=True)
        uv = self.origin[j] + a[:, 1:2] * self.e1[j] + a[:, 2:3] * self.e2[j]
        b = np.column_stack([1.0 - uv.sum(axis=1), uv])
        return b, pmf * s

    def sub_triangle(self, b: np.ndarray) -> np.ndarray:
        """(N,) the sub-triangle holding barycentrics b (N,3)."""
        k = self.k
        uv = np.asarray(b, np.float64)[:, 1:3] * k
        cell = np.clip(np.floor(uv).astype(np.int64), 0, k - 1)
        past = ((uv - cell).sum(axis=1) > 1.0).astype(np.int64)
        return self.lookup[cell[:, 0], cell[:, 1], past]

    def pdf_in_triangle(self, t: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(N,) the density of sample()'s points at barycentrics b (N,3) of triangles t, relative
        to uniform over the triangle (1 everywhere for a uniform table)."""
        return self.pmf[t, self.sub_triangle(b)] * len(self.origin)
