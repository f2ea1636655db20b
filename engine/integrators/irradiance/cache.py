"""Irradiance-cache records: storage, interpolation, neighbour clamping, spreading new records.

Pure NumPy, vectorised over whole batches of query points (records come from
`hemisphere.record_terms`; the octree is `octree.BallOctree`).

Weights (algorithms.md section 1.4). Both give a record the same support a R_i along the
surface, so that a (the user's 0.1-0.35) means the same for both:

- Ward et al. 1988: eps_i = |p - p_i| / R_i + sqrt(1 - n . n_i), the record is used iff
  eps_i < a, with weight w_i = 1 / max(eps_i, WARD_EPS_MIN). The floor on eps keeps the
  weight finite at the record itself; classic Radiance does the same (ambient.c `sumambient`
  caps the weight at 1e3 for eps <= 1e-3).
- Tabellion & Lamorlette 2004 (as in Mitsuba 0.6 irrcache.h `Record::getWeight`):
  w_i = 1 - kappa max(|p - p_i| / (R_i / 2), sqrt(1 - n . n_i) / sqrt(1 - cos 10 deg)), used
  iff w_i > 0, with kappa = 1 / (2 a): then w_i > 0 iff |p - p_i| < a R_i (for equal
  normals), Ward's support. Its normal support, sqrt(1 - n . n_i) < 2 a sqrt(1 - cos 10 deg)
  = 0.247 a, is about 4x tighter than Ward's (< a). Its weight falls to 0 at the edge of the
  support, so records fade in and out smoothly; Ward's jumps from 1/a to 0 there.

Both reject records "in front of" the point, (p - p_i) . (n + n_i) / 2 < -FRONT_TOLERANCE a R_i
(Ward et al. 1988; Radiance `sumambient`; Mitsuba 0.6 uses an absolute -0.05, which depends on
the scene's units): such a record sits above p's surface and sees light p may not (a step, a
ledge). The quantity is exactly 0 for p and p_i on one plane or one sphere (the chord is
perpendicular to the mean normal), so the tolerance only has to absorb tessellation and
rounding; as a fraction of the support it is scale-free: 0.05 allows facets about 6 degrees
apart (a chord across two facets at angle t leaves the mean plane by up to sin(t)/2 of its
length).

Extrapolation to (p, n) is hemisphere.extrapolate: E_i + (n_i x n) . grad_r + (p - p_i) . grad_t,
clamped >= 0 per channel (Ward & Heckbert 1992; the clamp as Mitsuba 0.6).

Neighbour clamping (Krivanek et al. 2006, "Making radiance and irradiance caching practical:
adaptive caching and neighbor clamping"; Mitsuba 0.6 irrcache.cpp `clamp_self_functor`,
`clamp_neighbors_functor`): R_i <= R_j + |p_i - p_j| for every pair, on the radius before the
pixel-footprint clamps (`radius_unclamped`), which is kept for later clamping; the final radius
is that value clamped again from below by `radius_min` (the footprint minimum; the maximum
clamps were applied before and can only have got tighter).
"""
from dataclasses import dataclass, fields, replace

import numpy as np

from ...settings import DECLARED
from .hemisphere import extrapolate
from .octree import BallOctree, as_points

WEIGHTS = DECLARED["icache_weight"].values
WARD_EPS_MIN = 1e-3                                   # Ward weight <= 1e3 (Radiance)
FRONT_TOLERANCE = 0.05                                # of the support a R_i; see above
SQRT_1_MINUS_COS_10 = float(np.sqrt(1.0 - np.cos(np.radians(10.0))))   # 0.12326


# ----------------------------------------------------------------------------------------------
# Records

@dataclass(frozen=True)
class Records:
    """R irradiance records, float64 arrays (read-only views are fine: nothing is written).

    position (R,3); normal (R,3) unit; E (R,C) irradiance, W m^-2 per channel; radius (R,)
    validity radius R_i after all clamps (world units); grad_r, grad_t (R,C,3) world-space
    rotational (W m^-2 per radian) and translational (W m^-3) gradients;
    radius_unclamped (R,) the radius before the pixel-footprint clamps (after the gradient
    limit and neighbour clamping; default: radius); radius_min (R,) the footprint minimum
    (default 0). All radii finite and >= 0: cap them at the world-space maximum.
    coeffs (R,B,C), coeffs_grad (R,B,C,3): the incident radiance in B world-space spherical
    harmonics and its translational gradient (radiance caching, radiance.py); B = 0 without.
    """

    position: np.ndarray
    normal: np.ndarray
    E: np.ndarray
    radius: np.ndarray
    grad_r: np.ndarray
    grad_t: np.ndarray
    radius_unclamped: np.ndarray = None
    radius_min: np.ndarray = None
    coeffs: np.ndarray = None
    coeffs_grad: np.ndarray = None

    def __post_init__(self):
        def set_(name, value):                                  # the dataclass is frozen
            object.__setattr__(self, name, value)
        for f in fields(self):
            value = getattr(self, f.name)
            if value is not None:
                set_(f.name, np.asarray(value, dtype=np.float64))
        if self.radius_unclamped is None:
            set_("radius_unclamped", self.radius)
        if self.radius_min is None:
            set_("radius_min", np.zeros_like(self.radius))
        R = len(self.position)
        C = self.E.shape[1] if self.E.ndim == 2 else -1
        if self.coeffs is None:
            set_("coeffs", np.zeros((R, 0, max(C, 0))))
        if self.coeffs_grad is None:
            set_("coeffs_grad", np.zeros(self.coeffs.shape + (3,)))
        B = self.coeffs.shape[1] if self.coeffs.ndim == 3 else -1
        shapes = dict(position=(R, 3), normal=(R, 3), E=(R, C), radius=(R,), grad_r=(R, C, 3),
                      grad_t=(R, C, 3), radius_unclamped=(R,), radius_min=(R,), coeffs=(R, B, C),
                      coeffs_grad=(R, B, C, 3))
        for name, shape in shapes.items():
            if getattr(self, name).shape != shape:
                raise ValueError(f"Records.{name} must have shape {shape}, got "
                                 f"{getattr(self, name).shape}")
        for f in fields(self):
            if not np.all(np.isfinite(getattr(self, f.name))):
                raise ValueError(f"Records.{f.name} has non-finite values")
        if min(self.radius.min(initial=0), self.radius_unclamped.min(initial=0),
               self.radius_min.min(initial=0)) < 0:
            raise ValueError("record radii must be >= 0")

    @classmethod
    def empty(cls, channels=3):
        z = np.zeros
        return cls(z((0, 3)), z((0, 3)), z((0, channels)), z(0), z((0, channels, 3)),
                   z((0, channels, 3)))

    def __len__(self):
        return len(self.position)

    def concat(self, other):
        """These records followed by other's (an empty set takes the other's coefficient count)."""
        if len(self) == 0 or len(other) == 0:
            return other if len(self) == 0 else self
        return Records(**{f.name: np.concatenate([getattr(self, f.name), getattr(other, f.name)])
                          for f in fields(self)})

    def take(self, index):
        """The records at index (integer array or boolean mask), in that order."""
        return Records(**{f.name: getattr(self, f.name)[index] for f in fields(self)})

    def pack(self):
        """{field name: C-contiguous float64 array}, e.g. to copy into shared memory."""
        return {f.name: np.ascontiguousarray(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def from_packed(cls, arrays):
        """Records over the arrays of `pack` (no copy; read-only views are fine)."""
        return cls(**{f.name: arrays[f.name] for f in fields(cls)})


# ----------------------------------------------------------------------------------------------
# Weights (all broadcast over leading axes)

def _normal_term(n, n_i):
    """sqrt(1 - n . n_i), with the cosine clipped into [-1, 1] against rounding."""
    return np.sqrt(1.0 - np.clip(np.sum(n * n_i, axis=-1), -1.0, 1.0))


def ward_error(p, n, p_i, n_i, R_i):
    """Ward's eps = |p - p_i| / R_i + sqrt(1 - n . n_i); inf where R_i = 0."""
    p, n, p_i, n_i, R_i = (np.asarray(x, dtype=np.float64) for x in (p, n, p_i, n_i, R_i))
    dist = np.linalg.norm(p - p_i, axis=-1)
    dist, R_i = np.broadcast_arrays(dist, R_i)
    scaled = np.divide(dist, R_i, out=np.full(dist.shape, np.inf), where=R_i > 0)
    return scaled + _normal_term(n, n_i)


def tabellion_weight(p, n, p_i, n_i, R_i, a):
    """Tabellion-Lamorlette weight with kappa = 1 / (2 a) (may be <= 0: record not used)."""
    p, n, p_i, n_i, R_i = (np.asarray(x, dtype=np.float64) for x in (p, n, p_i, n_i, R_i))
    dist = np.linalg.norm(p - p_i, axis=-1)
    dist, R_i = np.broadcast_arrays(dist, R_i)
    scaled = np.divide(dist, 0.5 * R_i, out=np.full(dist.shape, np.inf), where=R_i > 0)
    return 1.0 - np.maximum(scaled, _normal_term(n, n_i) / SQRT_1_MINUS_COS_10) / (2.0 * a)


def front_offset(p, n, p_i, n_i):
    """(p - p_i) . (n + n_i) / 2: negative when the record lies in front of (above) p."""
    return 0.5 * np.sum((np.asarray(p) - p_i) * (np.asarray(n) + n_i), axis=-1)


def _check_a(a):
    a = float(a)
    if not (np.isfinite(a) and a > 0.0):
        raise ValueError(f"the irradiance-cache accuracy a must be > 0, got {a}")
    return a


# ----------------------------------------------------------------------------------------------
# The cache

class RecordOctree:
    """Records in a `BallOctree` of their supports (balls of radius a R_i), for batched lookups.

    Cheap to build (the sort of at most 8 keys per record), so every worker rebuilds it when a
    new record set is published.
    """

    def __init__(self, records, a, weight="ward"):
        if weight not in WEIGHTS:
            raise ValueError(f"unknown irradiance-cache weight {weight!r}; one of {WEIGHTS}")
        self.records, self.a, self.weight = records, _check_a(a), weight
        self.tree = BallOctree(records.position, self.a * records.radius)

    def __len__(self):
        return len(self.records)

    def _weights(self, p, n):
        """Yield (lo, hi, rows, recs, w, diff, nr) for the records that pass the weight test at
        p[lo:hi]: diff = p - p_i and nr = n of each pair."""
        rec, a = self.records, self.a
        for lo, hi, rows, recs, diff, _ in self.tree.chunks(p):
            nr = np.take(n[lo:hi], rows, axis=0)        # np.take: faster than fancy indexing
            ni, R = np.take(rec.normal, recs, axis=0), np.take(rec.radius, recs)
            if self.weight == "ward":                  # p - p_i given as diff - 0
                eps = ward_error(diff, nr, 0.0, ni, R)
                use = eps < a
                w = 1.0 / np.maximum(eps, WARD_EPS_MIN)
            else:
                w = tabellion_weight(diff, nr, 0.0, ni, R, a)
                use = w > 0.0
            use &= front_offset(diff, nr, 0.0, ni) >= -FRONT_TOLERANCE * a * R
            use = np.flatnonzero(use)
            yield (lo, hi, rows[use], recs[use], w[use], np.take(diff, use, axis=0),
                   np.take(nr, use, axis=0))

    def weights(self, p, n):
        """(rows, recs, w): every (point, record) pair that passes the weight test, its weight."""
        p, n = as_points(p, "p"), as_points(n, "n")
        parts = [(lo + r, i, w) for lo, _, r, i, w, _, _ in self._weights(p, n)]
        if not parts:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        return tuple(np.concatenate(x) for x in zip(*parts))

    def interpolate(self, p, n, gradients=True):
        """Irradiance at points p (N,3) with unit normals n (N,3) from the cache.

        Returns (E (N,C), wsum (N,), count (N,) int64): the weighted average of the records'
        values extrapolated to (p, n) with both gradients (without: plain E_i), over the
        records that pass the weight test; wsum the sum of their weights, count their number.
        E = 0 where count == 0 (not covered).
        """
        p, n = as_points(p, "p"), as_points(n, "n")
        if n.shape != p.shape:
            raise ValueError(f"p and n must have the same shape, got {p.shape} and {n.shape}")
        rec = self.records
        C = rec.E.shape[1]
        E, wsum, count = np.zeros((len(p), C)), np.zeros(len(p)), np.zeros(len(p), np.int64)
        for lo, hi, rows, recs, w, diff, nr in self._weights(p, n):
            if gradients:                      # p - p_i given as diff - 0
                E_i, grad_r, grad_t, n_i = (np.take(x, recs, axis=0) for x in
                                            (rec.E, rec.grad_r, rec.grad_t, rec.normal))
                value = extrapolate(E_i, grad_r, grad_t, 0.0, n_i, diff, nr)
            else:
                value = np.take(rec.E, recs, axis=0)
            m = hi - lo
            for c in range(C):
                E[lo:hi, c] = np.bincount(rows, weights=w * value[:, c], minlength=m)
            wsum[lo:hi] = np.bincount(rows, weights=w, minlength=m)
            count[lo:hi] = np.bincount(rows, minlength=m)
        np.divide(E, wsum[:, None], out=E, where=wsum[:, None] > 0)
        return E, wsum, count

    def overlapping(self, p, radius):
        """(rows, recs): pairs where the ball (p_row, radius_row) meets record recs' support."""
        return self.tree.overlapping(p, radius)


# ----------------------------------------------------------------------------------------------
# Neighbour clamping

def neighbour_clamp(records, new):
    """The whole record set, `records` then `new`, with R_i <= R_j + |p_i - p_j| for all pairs.

    The constraint is applied to radius_unclamped, both ways between new and existing records
    and among the new ones; every record's radius becomes min(radius, max(radius_unclamped,
    radius_min)). `records` must already satisfy it (it does if it came from here). The result
    is the largest radius field below the given one that satisfies the constraint (for each
    record min_j (R_j + |p_i - p_j|) over all records), so it does not depend on the order of
    the records, nor on how they were split into batches, and clamping again changes nothing.
    Only pairs with |p_i - p_j| < max(R_i, R_j) can clamp; they are found as the new centres
    inside the balls of all records plus all centres inside the new records' balls. (So the
    interpolation settings a and weight, which define overlapping supports, do not enter.)
    """
    union = records.concat(new)
    m = len(records)
    if len(new) == 0:
        return union
    R = union.radius_unclamped
    clamped = R.copy()

    def clamp(i, j, d):
        np.minimum.at(clamped, i, R[j] + d)
        np.minimum.at(clamped, j, R[i] + d)

    for lo, _, new_in, any_ball, _, d in BallOctree(union.position, R).chunks(new.position):
        clamp(m + lo + new_in, any_ball, d)
    for lo, _, any_in, new_ball, _, d in BallOctree(new.position, R[m:]).chunks(union.position):
        clamp(m + new_ball, lo + any_in, d)
    radius = np.minimum(union.radius, np.maximum(clamped, union.radius_min))
    return replace(union, radius=radius, radius_unclamped=clamped)


# ----------------------------------------------------------------------------------------------
# Spreading new records

def spread_subset(p, spacing, key):
    """Indices (sorted) of a well-spread subset of points p (N,3): kept points lie at least
    max(spacing_i, spacing_j) / 2 apart, and every point within about 2 spacing of a kept one.

    spacing: (N,) or a scalar, > 0; key (N,) integers (e.g. a hash of the pixel index), the
    priority: smaller keys win. The subset depends only on the points, spacings and keys, not
    on their order (ties in key are broken by position).
    1. One candidate per grid cell: the point with the smallest key. The grid is anchored at the
       origin (so a cell does not depend on the other points in the batch), with edge
       h = 2^(floor(4 log2 spacing) / 4) in (0.84 spacing, spacing]; points whose spacings
       round to different h use different grids.
    2. Among the candidates, the greedy set by key: walking the candidates in key order, keep
       one unless it lies closer than max(spacing_i, spacing_j) / 2 to a kept one. Computed in
       rounds (Luby's parallel form with fixed priorities): a candidate whose key is the
       smallest among its undecided conflicting neighbours is kept and those neighbours are
       dropped; the rounds are few when keys are hash-like.
    A point is within sqrt(3) h of its cell's candidate, which is kept or within spacing / 2
    of a kept point: within (sqrt(3) + 1/2) spacing of a kept point.
    """
    p = as_points(p, "p")
    N = len(p)
    s = np.broadcast_to(np.asarray(spacing, dtype=np.float64), (N,))
    key = np.asarray(key)
    if key.shape != (N,) or not np.issubdtype(key.dtype, np.integer):
        raise ValueError(f"key must be (N,) integers, got {key.dtype} {key.shape}")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(s)) and np.all(s > 0)):
        raise ValueError("spread_subset needs finite points and finite spacings > 0")
    if N == 0:
        return np.zeros(0, np.int64)
    # 1. the candidate of each cell: first in (bucket, cell, key, position) order
    bucket = np.floor(4.0 * np.log2(s)).astype(np.int64)
    x = p / np.exp2(bucket / 4.0)[:, None]
    if np.abs(x).max() >= 2.0 ** 52:                   # cells exact in float64
        raise ValueError("spread_subset: spacing too small for the points' coordinates")
    cell = np.floor(x).astype(np.int64)
    by_cell = np.lexsort((p[:, 2], p[:, 1], p[:, 0], key, cell[:, 2], cell[:, 1], cell[:, 0],
                          bucket))
    group = np.column_stack([bucket[by_cell], cell[by_cell]])
    first = np.ones(N, bool)
    first[1:] = np.any(group[1:] != group[:-1], axis=1)
    cand = by_cell[first]
    # 2. greedy by key among the candidates
    cp, cs = p[cand], s[cand]
    rank = np.empty(len(cand), np.int64)
    rank[np.lexsort((cp[:, 2], cp[:, 1], cp[:, 0], key[cand]))] = np.arange(len(cand))
    i, j, d = BallOctree(cp, 0.5 * cs).candidates(cp)          # cp[i] within s_j / 2 of cp[j]
    conflict = (i != j) & (d < 0.5 * np.maximum(cs[i], cs[j]))
    i, j = np.concatenate([i[conflict], j[conflict]]), np.concatenate([j[conflict], i[conflict]])
    UNDECIDED, KEPT, DROPPED = 0, 1, 2
    state = np.zeros(len(cand), np.int8)
    while np.any(state == UNDECIDED):
        live = (state[i] == UNDECIDED) & (state[j] == UNDECIDED)
        smallest = np.full(len(cand), np.iinfo(np.int64).max)
        np.minimum.at(smallest, i[live], rank[j[live]])
        new = (state == UNDECIDED) & (rank < smallest)
        state[new] = KEPT
        state[j[new[i] & (state[j] == UNDECIDED)]] = DROPPED
    return np.sort(cand[state == KEPT])
