"""Statistics helpers shared by Ember's tests: a chi-square goodness-of-fit test of samplers
against the densities they claim (ChiSquareTest over a Domain), and z-tests on images.

The chi-square test follows the recipe of Mitsuba 3's ChiSquareTest (src/python/python/chi2.py,
core/math.h `chi2`): histogram the samples on a grid of cells in the domain's coordinates,
integrate the claimed pdf over the same cells, pool cells whose expected count is below 5, fail
outright where a sample lands where the pdf is 0, and correct the significance level for the
number of tests with Sidak's formula. Unlike Mitsuba it also fails a pdf whose integral over
the domain is not the share of samples the sampler keeps (rejected samples form one more cell,
and their number is tested on its own), checks the pdf at every sample, and integrates finely
across the edges of the pdf's support.

    test = ChiSquareTest(Hemisphere(), sampler=sample_cosine_hemisphere,
                         pdf=lambda d: d[:, 2] / np.pi, resolution=(40, 80), n_samples=400_000, seed=1)
    test.check(n_tests=len(CASES))     # AssertionError with a table of the worst cells if rejected
    test.run().p_value                 # or the result, for a test of the test's power
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import special
from scipy import stats as scipy_stats

TWO_PI = 2.0 * np.pi


def sidak_alpha(alpha, n_tests):
    """Per-test level so that n_tests independent tests together reject with probability alpha."""
    return float(-np.expm1(np.log1p(-alpha) / n_tests))  # 1 - (1 - alpha)^(1/n), no cancellation


# ----------------------------------------------------------------------------------------------
# Domains: where samples live, the coordinates they are histogrammed in, and the measure
#
# A domain is a box of coordinates (one or two axes, `bounds`) with two maps:
#   coordinates(points) -> tuple of (N,) arrays, one per axis;
#   points(*coords) -> (points, jacobian): the points at coordinates (M,) each, and
#       d(measure) / d(coords) (M,), the measure being the one the pdf is a density of
#       (length, area, solid angle, counting).
# Points are arrays whose first axis runs over samples.

class Domain:
    bounds: tuple  # ((lo, hi),) or ((x_lo, x_hi), (y_lo, y_hi))
    periodic: tuple = (False, False)  # per axis: the last cell touches the first (an azimuth)
    default_resolution = None

    @property
    def dims(self) -> int:
        return len(self.bounds)


class Interval(Domain):
    """[lo, hi] with the length measure; points (N,) floats."""

    def __init__(self, lo=0.0, hi=1.0):
        self.bounds = ((float(lo), float(hi)),)

    def coordinates(self, x):
        return (np.asarray(x, np.float64),)

    def points(self, x):
        return x, np.ones_like(x)


class Box(Domain):
    """[x_lo, x_hi] x [y_lo, y_hi] with the area measure; points (N,2)."""

    def __init__(self, x=(0.0, 1.0), y=(0.0, 1.0)):
        self.bounds = (tuple(map(float, x)), tuple(map(float, y)))

    def coordinates(self, p):
        p = np.asarray(p, np.float64)
        return p[:, 0], p[:, 1]

    def points(self, x, y):
        return np.stack([x, y], axis=-1), np.ones_like(x)


class Discrete(Domain):
    """The integers 0..n-1 with the counting measure (the pdf is a pmf); points (N,) ints.
    Cell i of the default resolution is [i, i + 1): one cell per value."""

    def __init__(self, n):
        self.bounds = ((0.0, float(n)),)
        self.default_resolution = (int(n),)

    def coordinates(self, k):
        return (np.asarray(k, np.float64),)

    def points(self, x):
        return np.floor(x).astype(np.int64), np.ones_like(x)


def orthonormal_frame(axis):
    """Rows (t, b, n) (3,3) of a right-handed frame around the unit vector n = axis / |axis|."""
    n = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t = np.cross(a, n)
    t /= np.linalg.norm(t)
    return np.stack([t, np.cross(n, t), n])


def _frame_of(axis, frame):
    if frame is not None:
        return np.asarray(frame, np.float64).reshape(3, 3)
    return orthonormal_frame((0.0, 0.0, 1.0) if axis is None else axis)


def _azimuth(local_x, local_y):
    return np.mod(np.arctan2(local_y, local_x), TWO_PI)


class Sphere(Domain):
    """Unit directions (N,3) with the solid-angle measure, in coordinates (cos theta, phi) of
    a frame: `frame` rows (t, b, n) (local = d @ frame.T), or one built around `axis` (default
    +z). d omega = dcos dphi, so the pdf is integrated as it is. cos_range limits the polar
    coordinate (Hemisphere: (0, 1))."""

    periodic = (False, True)

    def __init__(self, axis=None, frame=None, cos_range=(-1.0, 1.0)):
        self.frame = _frame_of(axis, frame)
        self.bounds = (tuple(map(float, cos_range)), (0.0, TWO_PI))

    def coordinates(self, d):
        local = np.asarray(d, np.float64) @ self.frame.T
        return np.clip(local[:, 2], -1.0, 1.0), _azimuth(local[:, 0], local[:, 1])

    def points(self, cos_t, phi):
        sin_t = np.sqrt(np.maximum(0.0, (1.0 - cos_t) * (1.0 + cos_t)))
        local = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)
        return local @ self.frame, np.ones_like(cos_t)


class Hemisphere(Sphere):
    """Sphere restricted to cos theta in [0, 1] about the frame's n."""

    def __init__(self, axis=None, frame=None):
        super().__init__(axis, frame, cos_range=(0.0, 1.0))


class Cone(Domain):
    """Unit directions (N,3) within a cone about n, solid-angle measure, in coordinates
    x = (1 - cos theta) / one_minus_cos_max in [0, extent] and phi: a narrow cone (a sun, a
    small light seen from afar) fills the grid. d omega = one_minus_cos_max dx dphi. 1 - cos
    is taken as |d - n|^2 / 2 (no cancellation near the axis)."""

    periodic = (False, True)

    def __init__(self, one_minus_cos_max, axis=None, frame=None, extent=1.0):
        self.frame = _frame_of(axis, frame)
        self.scale = float(one_minus_cos_max)
        self.bounds = ((0.0, float(extent)), (0.0, TWO_PI))

    def coordinates(self, d):
        d = np.asarray(d, np.float64)
        local = d @ self.frame.T
        chord = d - self.frame[2]
        return 0.5 * np.sum(chord * chord, axis=1) / self.scale, _azimuth(local[:, 0], local[:, 1])

    def points(self, x, phi):
        omc = x * self.scale
        sin_t = np.sqrt(np.maximum(0.0, omc * (2.0 - omc)))
        local = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), 1.0 - omc], axis=-1)
        return local @ self.frame, np.full_like(x, self.scale)


class Disk(Domain):
    """Points (N,dim) of the ellipse center + u a + v b, u^2 + v^2 <= 1, with the area measure,
    in coordinates (rho^2 = u^2 + v^2, phi = atan2(v, u)): uniform points are uniform in both.
    a, b: orthogonal semi-axis vectors (dim,). dA = |a| |b| / 2 drho^2 dphi."""

    periodic = (False, True)

    def __init__(self, center, a, b):
        self.center = np.asarray(center, np.float64)
        self.a = np.asarray(a, np.float64)
        self.b = np.asarray(b, np.float64)
        self.bounds = ((0.0, 1.0), (0.0, TWO_PI))

    def coordinates(self, p):
        q = np.asarray(p, np.float64) - self.center
        u, v = q @ self.a / (self.a @ self.a), q @ self.b / (self.b @ self.b)
        return u * u + v * v, _azimuth(u, v)

    def points(self, rho2, phi):
        r = np.sqrt(rho2)
        p = self.center + np.multiply.outer(r * np.cos(phi), self.a) + np.multiply.outer(r * np.sin(phi), self.b)
        return p, np.full_like(rho2, 0.5 * np.linalg.norm(self.a) * np.linalg.norm(self.b))


class Mapped(Domain):
    """Any parameterisation: bounds as Domain; coordinates(points) -> tuple of (N,) arrays;
    points(*coords) -> (points, jacobian (M,) = d measure / d coords)."""

    def __init__(self, bounds, coordinates, points, periodic=(False, False)):
        self.bounds = tuple(tuple(map(float, b)) for b in bounds)
        self._coordinates, self._points, self.periodic = coordinates, points, tuple(periodic)

    def coordinates(self, p):
        return tuple(self._coordinates(p))

    def points(self, *coords):
        return self._points(*coords)


# ----------------------------------------------------------------------------------------------
# Integrating a density over the cells of a grid

def _edges(domain, resolution):
    """Cell edges per axis. resolution: None (the domain's default), an int (cells on every
    axis), or a tuple with, per axis, a number of cells or the edges (an array; on a line the
    array may stand alone)."""
    if resolution is None:
        resolution = domain.default_resolution
    if isinstance(resolution, (int, np.integer)):
        resolution = (resolution,) * domain.dims
    elif isinstance(resolution, np.ndarray):
        resolution = (resolution,)
    if len(resolution) != domain.dims:
        raise ValueError(f"{len(resolution)} resolutions for a domain of {domain.dims} axes")
    edges = []
    for r, (lo, hi) in zip(resolution, domain.bounds):
        e = np.linspace(lo, hi, int(r) + 1) if np.ndim(r) == 0 else np.asarray(r, np.float64)
        if e[0] != lo or e[-1] != hi or np.any(np.diff(e) <= 0):
            raise ValueError(f"edges must rise from {lo} to {hi}")
        edges.append(e)
    return edges


def _nodes(lo, hi, sub, order):
    """Composite Gauss-Legendre nodes (cells, sub * order) and weights (same) for cells lo..hi:
    sub equal parts, order nodes each, all strictly inside the cell (a pdf that jumps on a
    cell edge is integrated as if it did not)."""
    t, w = np.polynomial.legendre.leggauss(order)
    s = ((np.arange(sub)[:, None] + 0.5 * (t[None, :] + 1.0)) / sub).ravel()
    ws = np.tile(w, sub) / (2.0 * sub)
    width = hi - lo
    return lo[:, None] + width[:, None] * s[None, :], width[:, None] * ws[None, :]


def _cell_integrals(domain, f, lo, hi, sub, order):
    """Integrals (K,) of f(points) x jacobian over K boxes lo, hi (K, dims), and the values at
    the nodes (K, nodes)."""
    per_axis = [_nodes(lo[:, k], hi[:, k], sub, order) for k in range(domain.dims)]
    if domain.dims == 1:
        (x, w), = per_axis
        coords, weights = (x,), w
    else:
        (x, wx), (y, wy) = per_axis
        m = x.shape[1]
        coords = (np.repeat(x, m, axis=1), np.tile(y, (1, m)))
        weights = np.repeat(wx, m, axis=1) * np.tile(wy, (1, m))
    shape = coords[0].shape
    points, jacobian = domain.points(*(c.ravel() for c in coords))
    values = (np.asarray(f(points), np.float64).reshape(-1) * jacobian).reshape(shape)
    return np.sum(values * weights, axis=1), values


def _boxes(edges, index):
    """lo, hi (K, dims) of the cells with multi-indices index (K, dims)."""
    lo = np.stack([e[i] for e, i in zip(edges, index.T)], axis=1)
    hi = np.stack([e[i + 1] for e, i in zip(edges, index.T)], axis=1)
    return lo, hi


def _split(lo, hi, parts):
    """Boxes lo, hi (K, dims) cut into parts^dims equal children each, box by box."""
    dims = lo.shape[1]
    corner = np.stack(np.meshgrid(*[np.arange(parts)] * dims, indexing="ij"), axis=-1).reshape(-1, dims)
    size = (hi - lo) / parts
    child_lo = (lo[:, None, :] + corner[None] * size[:, None, :]).reshape(-1, dims)
    return child_lo, child_lo + np.repeat(size, len(corner), axis=0)


def _is_cut(domain, f, lo, hi, values):
    """Boxes lo, hi (K, dims) where f is 0 at some of the node values (K, nodes) or at the
    box's corners and not at others: a support edge passes. The corners, moved inside by 1e-7
    of the box (off a singular domain edge), catch an edge that runs between nodes: a straight
    edge through a box always separates corners."""
    dims = lo.shape[1]
    corner = np.stack(np.meshgrid(*[[1e-7, 1.0 - 1e-7]] * dims, indexing="ij"), axis=-1).reshape(-1, dims)
    at = (lo[:, None, :] + corner[None] * (hi - lo)[:, None, :]).reshape(-1, dims)
    points, jacobian = domain.points(*at.T)
    corners = (np.asarray(f(points), np.float64).reshape(-1) * jacobian).reshape(len(lo), -1)
    values = np.concatenate([values, corners], axis=1)
    return (values.min(axis=1) == 0.0) & (values.max(axis=1) > 0.0)


def _integrate_across_edges(domain, f, lo, hi, levels=3):
    """Integrals (K,) over boxes that a support edge of f may cross: 8 parts per axis of order 3,
    and parts the edge crosses halved again, levels times (down to 1/64 of the box)."""
    owner = np.repeat(np.arange(len(lo)), 8 ** domain.dims)
    lo, hi = _split(lo, hi, 8)
    total = np.zeros(len(owner) // 8 ** domain.dims)
    for level in range(levels + 1):
        integral, values = _cell_integrals(domain, f, lo, hi, 1, 3)
        cut = _is_cut(domain, f, lo, hi, values) if level < levels else np.zeros(len(lo), bool)
        np.add.at(total, owner[~cut], integral[~cut])
        if not cut.any():
            break
        owner = np.repeat(owner[cut], 2 ** domain.dims)
        lo, hi = _split(lo[cut], hi[cut], 2)
    return total


def _grow(mask, periodic):
    """mask or'ed with its 8 (2 on a line) neighbours; periodic axes wrap around."""
    for axis in range(mask.ndim):
        grown = mask.copy()
        for step in (1, -1):
            shifted = np.roll(mask, step, axis=axis)
            if not periodic[axis]:  # clear the row rolled in from the other end
                edge = [slice(None)] * mask.ndim
                edge[axis] = 0 if step == 1 else -1
                shifted[tuple(edge)] = False
            grown |= shifted
        mask = grown
    return mask


def integrate(domain, f, resolution=None, order=None, refine=False):
    """Integrals of f over the cells of the grid, shaped like the grid (np.histogram2d's layout).

    f(points) -> (M,) a density with respect to the domain's measure. Each cell gets order
    Gauss-Legendre nodes per axis (default 8 on a line, 4 on a plane). refine: cells a support
    edge of f crosses (f is 0 at some probe points or corners and not at others: a lobe clipped
    by the horizon, a light's silhouette) and their neighbours are integrated again, finely
    where the edge passes (_integrate_across_edges).
    """
    edges = _edges(domain, resolution)
    shape = tuple(len(e) - 1 for e in edges)
    order = order or (8 if domain.dims == 1 else 4)
    index = np.stack(np.unravel_index(np.arange(np.prod(shape)), shape), axis=1)
    lo, hi = _boxes(edges, index)
    total, _ = _cell_integrals(domain, f, lo, hi, 1, order)
    if refine:
        # Cells an edge crosses, and their neighbours: a curved edge (a rect's corner seen in
        # polar coordinates) may poke into a cell between its probe points and corners.
        _, probe = _cell_integrals(domain, f, lo, hi, 3, 2)
        k = np.flatnonzero(_grow(_is_cut(domain, f, lo, hi, probe).reshape(shape), domain.periodic).ravel())
        if len(k):
            total[k] = _integrate_across_edges(domain, f, lo[k], hi[k])
    return total.reshape(shape)


# ----------------------------------------------------------------------------------------------
# Pearson's chi-square with pooling

def _pool_low_cells(observed, expected, min_expected):
    """Cells as (observed, expected) arrays after pooling those with expected < min_expected.

    Low cells are merged in increasing order of expected count into groups of at least
    min_expected (Mitsuba's rule); a remainder too small to stand alone joins the smallest
    regular cell, or the last group if there is none.
    """
    order = np.argsort(expected, kind="stable")
    observed, expected = observed[order], expected[order]
    n_low = int(np.searchsorted(expected, min_expected, side="left"))
    groups_o, groups_e = [], []
    pool_o = pool_e = 0.0
    for o, e in zip(observed[:n_low], expected[:n_low]):
        pool_o += o
        pool_e += e
        if pool_e >= min_expected:
            groups_o.append(pool_o)
            groups_e.append(pool_e)
            pool_o = pool_e = 0.0
    observed, expected = list(observed[n_low:]), list(expected[n_low:])
    if pool_e > 0.0:
        if observed:
            observed[0] += pool_o
            expected[0] += pool_e
        elif groups_o:
            groups_o[-1] += pool_o
            groups_e[-1] += pool_e
        else:
            groups_o.append(pool_o)
            groups_e.append(pool_e)
    return np.array(groups_o + observed), np.array(groups_e + expected)


def _pearson(observed, expected, min_expected):
    """(statistic, dof, p-value, number of cells after pooling) over cells of expected > 0."""
    live = expected > 0.0
    o, e = _pool_low_cells(observed[live], expected[live], min_expected)
    dof = o.size - 1
    if dof < 1:
        raise ValueError("too few cells for a chi-square test; use more samples or cells")
    statistic = float(np.sum((o - e) ** 2 / e))
    return statistic, dof, float(scipy_stats.chi2.sf(statistic, dof)), o.size


# ----------------------------------------------------------------------------------------------
# The test

@dataclass
class ChiSquareResult:
    """Outcome of ChiSquareTest.run.

    p_value: of Pearson's statistic (0.0 after an outright failure); p_kept: of the number of
    samples rejected, binomial with the probability 1 - integral the pdf leaves for rejections
    (1.0 for a sampler that rejects none); alpha: the per-test level (Sidak-corrected for the
    family), each of the two p-values judged at Sidak's level for 2 tests within it when the
    sampler can reject; passed: both p-values above their level and no outright failure;
    failure: why the test failed outright ('' if it did not); observed, expected: counts per
    cell, grid-shaped (expected = n_samples x integral of the pdf over the cell); rejected,
    rejected_expected: samples the sampler rejected and how many the pdf leaves room for
    (n_samples x (1 - integral)); integral: of the pdf over the domain; edges: per axis;
    statistic, dof: Pearson's, after pooling; notes: what was done to the data.
    """

    name: str
    p_value: float
    alpha: float
    passed: bool
    failure: str
    observed: np.ndarray
    expected: np.ndarray
    rejected: int
    rejected_expected: float
    integral: float
    n_samples: int
    edges: list
    statistic: float = float("nan")
    dof: int = 0
    notes: tuple = ()
    p_kept: float = 1.0

    def __repr__(self):
        return self.report(rows=0).splitlines()[0]

    def check(self):
        """self, or an AssertionError carrying the report if the test did not pass."""
        assert self.passed, "\n" + self.report()
        return self

    def table(self, rows=12):
        """The worst cells first by |observed - expected| / sqrt(expected), one line each."""
        o = np.append(self.observed.ravel(), self.rejected)
        e = np.append(self.expected.ravel(), self.rejected_expected)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(e > 0, (o - e) / np.sqrt(e), np.where(o > 0, np.inf, 0.0))
        worst = np.argsort(-np.abs(z), kind="stable")[:rows]
        shape = self.observed.shape
        lines = [f"  {'cell':<44} {'observed':>10} {'expected':>12} {'(o-e)/sqrt(e)':>14}"]
        for k in worst:
            if k == o.size - 1:
                label = "rejected by the sampler"
            else:
                idx = np.unravel_index(k, shape)
                label = " x ".join(f"[{e_[i]:.4g}, {e_[i + 1]:.4g})" for e_, i in zip(self.edges, idx))
            lines.append(f"  {label:<44} {o[k]:>10.0f} {e[k]:>12.2f} {z[k]:>14.2f}")
        return "\n".join(lines)

    def report(self, rows=12):
        head = f"chi-square test {self.name!r}: " if self.name else "chi-square test: "
        if self.failure:
            head += f"failed outright: {self.failure}"
        else:
            verdict = "accepted" if self.passed else "REJECTED"
            head += (f"{verdict}, p = {self.p_value:.3g} (level {self.alpha:.3g}), "
                     f"chi2 = {self.statistic:.1f}, dof = {self.dof}; p of the share kept = {self.p_kept:.3g}")
        lines = [head, f"  {self.n_samples} samples, {self.rejected} rejected by the sampler "
                       f"(pdf leaves room for {self.rejected_expected:.1f}); integral of the pdf "
                       f"over the domain {self.integral:.6f}"]
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines + ([self.table(rows)] if rows else []))


class ChiSquareTest:
    """Pearson's chi-square test of a sampler against the pdf it claims.

    domain: a Domain (the grid's coordinates and the measure the pdf is a density of).
    sampler(u) -> points, or (points, valid): u (n_samples, sample_dim) uniforms in [0, 1)
        from numpy's default_rng(seed) (None for a test only given samples, see `fit`);
        valid (N,) bool marks the samples the sampler keeps:
        the others (zero weight, below the horizon...) are counted in one extra cell, whose
        expected count is n_samples (1 - integral of the pdf over the domain), and their number
        is tested on its own too (binomial; a wrong normalisation is a 1-degree effect that
        Pearson's statistic over many cells dilutes). A sampler that returns no mask claims to
        keep all: the pdf must then integrate to 1 (within integral_tolerance).
    pdf(points) -> (M,): the density the sampler claims, w.r.t. the domain's measure.
    resolution: cells per axis (an int for all, a tuple per axis) or explicit edges per axis.
    n_samples, seed (an int or a sequence of ints), sample_dim.
    order, refine: how the pdf is integrated over cells (see `integrate`); min_expected: cells
        expected to hold fewer samples are pooled (Mitsuba: 5).
    check_support: evaluate the pdf at every kept sample; one where it is 0 fails outright.
        A cell of expected count 0 that holds samples then only shows a sliver of support the
        quadrature missed (the pdf is positive at them): it is pooled, and the report says so.
    name: shown in the report.

    Outright failures (p = 0): samples outside the domain's bounds, samples where the pdf is 0
    (without check_support: samples in a cell of expected count 0), a pdf that is negative or
    not finite at a quadrature node, a pdf whose integral exceeds 1, or differs from 1 although
    the sampler rejects nothing. The expected counts are never rescaled to the observed total.
    """

    def __init__(self, domain, sampler, pdf, resolution=None, n_samples=100_000, seed=0, sample_dim=2,
                 order=None, refine=False, min_expected=5.0, check_support=True, integral_tolerance=1e-3,
                 name=""):
        self.domain, self.sampler, self.pdf = domain, sampler, pdf
        self.resolution, self.n_samples, self.seed, self.sample_dim = resolution, int(n_samples), seed, sample_dim
        self.order, self.refine, self.min_expected = order, refine, min_expected
        self.check_support, self.integral_tolerance, self.name = check_support, integral_tolerance, name

    def draw(self):
        """(points, valid (N,) bool or None when the sampler returns no mask) from the sampler."""
        u = np.random.default_rng(self.seed).random((self.n_samples, self.sample_dim))
        out = self.sampler(u)
        points, valid = out if isinstance(out, tuple) else (out, None)
        if len(points) != self.n_samples or (valid is not None and np.shape(valid) != (self.n_samples,)):
            raise ValueError(f"the sampler returned {len(points)} points and {np.shape(valid)} flags "
                             f"for {self.n_samples} samples")
        return points, valid

    def run(self, alpha=0.01, n_tests=1) -> ChiSquareResult:
        """Draw n_samples and test them at the family-wise level alpha over n_tests tests."""
        return self.fit(*self.draw(), alpha, n_tests)

    def check(self, alpha=0.01, n_tests=1) -> ChiSquareResult:
        """run(), and an AssertionError carrying the report unless the test passed."""
        return self.run(alpha, n_tests).check()

    def fit(self, points, valid=None, alpha=0.01, n_tests=1) -> ChiSquareResult:
        """Test given samples (points, and valid as a sampler returns it) instead of drawing them."""
        n = len(points)
        rejections_possible = valid is not None
        valid = np.ones(n, bool) if valid is None else np.asarray(valid, bool)
        domain, edges = self.domain, _edges(self.domain, self.resolution)
        kept = points[valid]
        coords = domain.coordinates(kept)
        level = sidak_alpha(alpha, n_tests)
        notes = []

        expected = n * integrate(domain, self.pdf, edges, self.order, self.refine)
        integral = float(expected.sum() / n) if n else 0.0
        rejected = int(n - valid.sum())
        rejected_expected = max(n - float(expected.sum()), 0.0)

        def outcome(failure="", statistic=float("nan"), dof=0, p=0.0, observed=None, p_kept=1.0):
            if observed is None:
                observed = np.zeros(expected.shape)
            each = sidak_alpha(level, 2) if rejections_possible else level
            passed = not failure and p >= each and p_kept >= each
            return ChiSquareResult(self.name, p, level, passed, failure, observed, expected, rejected,
                                   rejected_expected, integral, n, edges, statistic, dof, tuple(notes), p_kept)

        if not np.all(np.isfinite(expected)) or np.any(expected < 0.0):
            return outcome("the pdf is negative or not finite at quadrature nodes")

        # Histogram. Coordinates within rounding of the bounds are clamped; others fail.
        inside = np.ones(len(coords[0]), bool)
        clamped = []
        for c, (lo, hi) in zip(coords, domain.bounds):
            tol = 1e-9 * (hi - lo)
            inside &= (c >= lo - tol) & (c <= hi + tol)  # NaN is outside
            clamped.append(np.clip(c, lo, hi))
        if not inside.all():
            bad = np.flatnonzero(~inside)
            where = ", ".join(str(tuple(float(c[i]) for c in coords)) for i in bad[:3])
            return outcome(f"{len(bad)} kept samples outside the domain {domain.bounds}, e.g. {where}")
        if domain.dims == 1:
            observed = np.histogram(clamped[0], edges[0])[0].astype(np.float64)
        else:
            observed = np.histogram2d(clamped[0], clamped[1], bins=edges)[0]

        if self.check_support and len(kept):
            at_samples = np.asarray(self.pdf(kept), np.float64).reshape(-1)
            zero = np.flatnonzero(~(at_samples > 0.0))
            if len(zero):
                where = ", ".join(str(tuple(float(c[i]) for c in coords)) for i in zero[:3])
                return outcome(f"{len(zero)} kept samples where the pdf is 0 (or not finite), at "
                               f"coordinates {where}", observed=observed)
        empty = (expected == 0.0) & (observed > 0.0)
        if empty.any():
            if not self.check_support:
                return outcome(f"{int(observed[empty].sum())} samples in {int(empty.sum())} cells of "
                               f"expected count 0", observed=observed)
            # The pdf is positive at those samples: the quadrature missed a sliver of support.
            notes.append(f"{int(empty.sum())} cells hold samples where the pdf is positive but "
                         "integrates to 0 by quadrature; they are pooled")
            expected = np.where(empty, 1e-12, expected)

        if integral > 1.0 + self.integral_tolerance:
            return outcome(f"the pdf integrates to {integral:.6f} > 1 over the domain", observed=observed)
        if not rejections_possible and abs(integral - 1.0) > self.integral_tolerance:
            return outcome(f"the pdf integrates to {integral:.6f} over the domain, not 1 (the sampler "
                           "rejects no sample)", observed=observed)
        o = np.append(observed.ravel(), rejected)
        e = np.append(expected.ravel(), rejected_expected if rejections_possible else 0.0)
        if rejected and e[-1] == 0.0:
            return outcome(f"{rejected} samples rejected, but the pdf integrates to {integral:.6f}: no "
                           "room for rejections", observed=observed)
        statistic, dof, p, cells = _pearson(o, e, self.min_expected)
        if cells < np.count_nonzero(e):
            notes.append(f"{np.count_nonzero(e)} cells pooled into {cells} (expected counts >= "
                         f"{self.min_expected:g})")
        p_kept = 1.0
        if rejections_possible and 0.0 < e[-1] < n:
            p_kept = float(scipy_stats.binomtest(rejected, n, e[-1] / n).pvalue)
        return outcome("", statistic, dof, p, observed, p_kept)


# ----------------------------------------------------------------------------------------------
# Images: per-pixel z-test of two Monte Carlo estimates

DEFAULT_VAR_FLOOR = 1e-8


def z_test_p_values(mean_a, var_mean_a, mean_b, var_mean_b, var_floor=DEFAULT_VAR_FLOOR):
    """Two-sided p-values, per element, that two independent estimates share the same mean.

    var_mean_*: variance of each *mean* (per-sample variance / sample count; 0 for an exact
    reference). The combined variance is floored at var_floor (default 1e-8, i.e. a standard
    deviation of 1e-4 in image units) so that deterministic pixels, whose variances are both 0
    (background, directly seen emitters), pass when they agree up to float32 rounding instead
    of dividing by 0. Mitsuba 3's render tests instead floor the reference's per-sample
    variance at 1e-4; pass var_floor=1e-4 / spp to reproduce that. NaN inputs give p = NaN.
    """
    diff = np.asarray(mean_a, dtype=np.float64) - np.asarray(mean_b, dtype=np.float64)
    var = np.maximum(np.asarray(var_mean_a, dtype=np.float64) + var_mean_b, var_floor)
    z = np.abs(diff) / np.sqrt(var)
    return special.erfc(z / np.sqrt(2.0))


def z_test_images(mean_a, var_mean_a, mean_b, var_mean_b, alpha=0.01,
                  var_floor=DEFAULT_VAR_FLOOR):
    """Fraction of pixels (array elements, so channels count separately) that pass a z-test.

    Each element is tested two-sided at the Sidak-corrected level sidak_alpha(alpha, size), so
    when the images agree in distribution all pass with probability 1 - alpha. NaN fails.
    Callers assert a minimum fraction (Mitsuba uses 99.75%). See z_test_p_values for the floor.
    """
    p = z_test_p_values(mean_a, var_mean_a, mean_b, var_mean_b, var_floor)
    alpha_per_pixel = sidak_alpha(alpha, p.size)
    return float(np.mean(p >= alpha_per_pixel))
