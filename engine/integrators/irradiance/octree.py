"""Balls in a linear octree, queried for a whole batch of points at once.

The irradiance cache keeps each record's region of influence as a ball (centre c_i, radius
s_i). The seed's octree keeps a record in the node whose size fits its influence, and a lookup
descends the tree from the root, visiting at every depth the one node that holds the point.
This is that tree written flat (a linear, hashed octree) so that NumPy walks all depths for
all points at once:

- The root is the cube [origin, origin + size]^3 around the centres, with size >= 2 max s_i.
  A cell at level l has edge size / 2^l and integer coordinates floor((x - origin) / edge).
- Ball i goes to the finest level whose edge is >= 2 s_i (so its bounding box [c - s, c + s]
  spans at most 2 cells per axis) and is stored in every cell of that level its box meets
  (at most 8). Balls smaller than the finest level (MAX_LEVEL) share its cells.
- A cell is keyed by (level, ix, iy, iz) packed into one int64; the keys of all stored
  entries are sorted once, which is the whole build (cheap enough to redo in every worker).
- A query point's key at every occupied level is one floor per axis; np.searchsorted finds
  each key's run of entries (the node's records), and np.repeat expands the (point, ball)
  candidate pairs. Python loops run only over blocks of points (bounded memory), never over
  points, balls or pairs. A point inside ball i lies in ball i's box, so in one of the cells
  i is stored in: no pair is missed. The candidates are then filtered by the exact distance.

Query points outside the root cube are fine (their cells hold nothing unless a box pokes out
of the root by at most half a cell, which the +1 offset of the stored coordinates keeps).
"""
import numpy as np

MAX_LEVEL = 18              # finest cells are 2^-18 of the root (262144 per axis)
_BITS = 19                  # per axis: stored coordinates + 1 run over [0, 2^18 + 1] < 2^19
_FIT = 1.0 + 1e-6           # a ball's cell edge is >= 2 s _FIT, its box half-width s _BOX:
_BOX = 1.0 + 1e-9           # the box spans <= 2 cells even after rounding, and holds every
                            # point whose computed distance is <= s
BLOCK_POINTS = 1 << 16      # query points per block (the (points, levels, 3) index array)
MAX_PAIRS = 1 << 18         # candidate pairs per chunk handed to the caller

_CORNERS = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)], dtype=np.int64)


def as_points(x, name):
    """x as a float64 (N, 3) array (a view when it already is one), or ValueError."""
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {x.shape}")
    return x


def _pack(level, ix, iy, iz):
    return (((level << _BITS | ix) << _BITS | iy) << _BITS) | iz


class BallOctree:
    """Balls (centre (R,3), radius (R,) finite, >= 0) for batched point-in-ball queries."""

    def __init__(self, centre, radius):
        centre = as_points(centre, "centre")
        radius = np.asarray(radius, dtype=np.float64)
        if radius.shape != (len(centre),):
            raise ValueError(f"radius must have shape ({len(centre)},), got {radius.shape}")
        if not (np.all(np.isfinite(centre)) and np.all(np.isfinite(radius))
                and np.all(radius >= 0.0)):
            raise ValueError("ball centres must be finite and radii finite and >= 0")
        self.centre, self.radius = centre, radius
        if len(centre) == 0:
            self.keys = np.zeros(0, np.int64)
            self.ball = np.zeros(0, np.int64)
            self.levels = np.zeros(0, np.int64)
            return
        self.origin = centre.min(axis=0)
        half = radius * _BOX
        need = 2.0 * _FIT * half                                     # smallest usable edge
        size = max(float((centre.max(axis=0) - self.origin).max()), float(need.max()))
        self.size = size if size > 0.0 else 1.0
        with np.errstate(divide="ignore"):
            level = np.floor(np.log2(self.size / need))              # inf where s = 0
        level = np.clip(np.nan_to_num(level, posinf=MAX_LEVEL), 0, MAX_LEVEL).astype(np.int64)
        level -= (self.size * np.exp2(-level) < need)                # log2 rounded up: one finer
        edge = self.size * np.exp2(-level)

        lo = np.floor((centre - half[:, None] - self.origin) / edge[:, None]).astype(np.int64) + 1
        hi = np.floor((centre + half[:, None] - self.origin) / edge[:, None]).astype(np.int64) + 1
        cells = lo[:, None, :] + _CORNERS[None]                      # (R, 8, 3)
        inside = np.all(cells <= hi[:, None, :], axis=2)
        ball = np.broadcast_to(np.arange(len(centre))[:, None], inside.shape)[inside]
        cells = cells[inside]
        keys = _pack(level[ball], cells[:, 0], cells[:, 1], cells[:, 2])
        order = np.argsort(keys, kind="stable")                      # runs list balls ascending
        self.keys, self.ball = keys[order], ball[order]
        self.levels = np.unique(level)
        self._edge = self.size * np.exp2(-self.levels)
        self._last = (1 << self.levels) + 1                          # largest stored coordinate

    def __len__(self):
        return len(self.centre)

    def _runs(self, q):
        """Start and length (n, L) of the run of stored entries in q's cell at each level."""
        finite = np.all(np.isfinite(q), axis=1)
        x = np.where(finite[:, None], q, self.origin) - self.origin
        x = np.floor(x[:, None, :] / self._edge[None, :, None]) + 1.0         # (n, L, 3)
        last = self._last[None, :, None]
        valid = finite[:, None] & np.all((x >= 0) & (x <= last), axis=2)
        x = np.clip(x, 0, last).astype(np.int64)
        key = _pack(self.levels[None, :], x[..., 0], x[..., 1], x[..., 2])
        start = np.searchsorted(self.keys, key, side="left")
        stop = np.searchsorted(self.keys, key, side="right")
        return start, np.where(valid, stop - start, 0)

    def chunks(self, q, max_pairs=None):
        """Yield (lo, hi, rows, balls, diff, dist): every pair of a point q[lo:hi] and a ball
        holding it.

        rows index q[lo:hi] (0-based within the chunk), diff = q - c, dist = |diff| <= radius.
        A chunk holds at most max_pairs candidates unless one point alone has more. Pairs come
        sorted by row, and within a row by level, then ball index.
        """
        q = as_points(q, "points")
        max_pairs = MAX_PAIRS if max_pairs is None else max_pairs
        if len(self.keys) == 0:
            if len(q):
                z = np.zeros(0, np.int64)
                yield 0, len(q), z, z, np.zeros((0, 3)), np.zeros(0)
            return
        for b0 in range(0, len(q), BLOCK_POINTS):
            qb = q[b0:b0 + BLOCK_POINTS]
            start, count = self._runs(qb)
            per_point = np.cumsum(count.sum(axis=1))
            lo = 0
            while lo < len(qb):
                before = per_point[lo - 1] if lo else 0
                hi = max(int(np.searchsorted(per_point, before + max_pairs, side="right")), lo + 1)
                rows, balls = self._expand(start[lo:hi], count[lo:hi])
                diff = np.take(qb[lo:hi], rows, axis=0) - np.take(self.centre, balls, axis=0)
                d2 = np.einsum("ij,ij->i", diff, diff)
                keep = np.flatnonzero(d2 <= np.take(self.radius, balls) ** 2)
                yield (b0 + lo, b0 + hi, rows[keep], balls[keep], np.take(diff, keep, axis=0),
                       np.sqrt(d2[keep]))
                lo = hi

    def _expand(self, start, count):
        """(rows, balls) of all stored entries in the runs (start, count), each (n, L)."""
        s, c = start.ravel(), count.ravel()
        total = int(c.sum())
        rows = np.repeat(np.arange(len(s)) // start.shape[1], c)
        entry = np.arange(total) + np.repeat(s - (np.cumsum(c) - c), c)
        return rows, self.ball[entry]

    def candidates(self, q):
        """(rows, balls, dist): all pairs with point q[row] inside ball `ball` (|q - c| <= s)."""
        parts = [(lo + r, b, d) for lo, _, r, b, _, d in self.chunks(q)]
        if not parts:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        return tuple(np.concatenate(a) for a in zip(*parts))

    def overlapping(self, q, radius):
        """(rows, balls): all pairs whose balls meet, |q_row - c_ball| <= radius_row + s_ball.

        Such a pair has distance <= 2 max(radius_row, s_ball), so it is found by two point
        queries with doubled radii (q in the doubled stored balls, and the stored centres in
        the doubled query balls) and then filtered exactly.
        """
        q = as_points(q, "points")
        radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), (len(q),))
        r1, b1, _ = BallOctree(self.centre, 2.0 * self.radius).candidates(q)
        b2, r2, _ = BallOctree(q, 2.0 * radius).candidates(self.centre)
        pair = np.unique(np.concatenate([r1, r2]) * max(len(self), 1) + np.concatenate([b1, b2]))
        rows, balls = pair // max(len(self), 1), pair % max(len(self), 1)
        dist = np.linalg.norm(q[rows] - self.centre[balls], axis=1)
        keep = dist <= radius[rows] + self.radius[balls]
        return rows[keep], balls[keep]
