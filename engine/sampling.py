"""Warps and tabulated distributions: `sample_*` / `pdf_*` pairs on explicit uniforms.

Every sampler takes its uniform numbers `u` ((N,) or (N, 2) float64 in [0, 1)) as an argument and
returns float64 arrays; nothing here draws random numbers. No Python loop runs over samples.
Each docstring states shapes and the measure of the pdf (solid angle, area, or [0, 1)^d).
Divisions are guarded: a zero pdf or a degenerate size gives 0, never NaN or Inf.

Sources (formulas read, code written here): pbrt-v4 src/pbrt/util/sampling.h (warps,
PiecewiseConstant1D/2D), util/vecmath.h (CoordinateSystem, Duff et al. 2017), shapes.h (sphere
cone); Blender Cycles intern/cycles/scene/film.cpp (pixel filters).
"""
from functools import lru_cache

import numpy as np

ONE_MINUS_EPSILON = float(np.nextafter(1.0, 0.0))  # largest float64 below 1 (1 - 2^-53)
PIXEL_FILTER_KINDS = ("BOX", "GAUSSIAN", "BLACKMAN_HARRIS")

# A continuous sample is kept this far (in units of its bin) from the bin edges, so that
# floor(x * n) in pdf() finds the bin that sample() chose despite the rounding of (i + du) / n.
# Valid for up to 2^24 bins; the shift it causes is 1e-6 of a bin, far below any test's reach.
_BIN_EDGE_MARGIN = 2.0 ** -20
_PIXEL_FILTER_BINS = 4096


# ----------------------------------------------------------------------------------------------
# Small helpers

def _as_u(u, dims, in_unit=False):
    """u as a float64 array of shape (N,) (dims=1) or (N, dims), clamped into [0, 1).
    in_unit: u is known to lie in [0, 1) (a Sampler's numbers), so the clamp, a pass over u
    that changes nothing, is left out."""
    u = np.asarray(u, dtype=np.float64)
    if dims > 1 and (u.ndim != 2 or u.shape[1] != dims):
        raise ValueError(f"u must have shape (N, {dims}), got {u.shape}")
    return u if in_unit else np.clip(u, 0.0, ONE_MINUS_EPSILON)


def _safe_div(a, b):
    """a / b where b > 0, else 0 (broadcast, float64)."""
    a, b = np.broadcast_arrays(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))
    return np.divide(a, b, out=np.zeros(a.shape), where=b > 0)


def _unit_sphere_point(cos_theta, sin_theta, phi):
    """(N, 3) direction from polar angle (cos, sin) and azimuth phi around +z."""
    return np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), cos_theta], axis=-1)


# ----------------------------------------------------------------------------------------------
# Frames

def frame_from_z(n):
    """Tangent frame (t, b) for unit normals n (N, 3): (t, b, n) is orthonormal and right-handed.

    Branchless construction of Duff et al. 2017, "Building an Orthonormal Basis, Revisited"
    (as pbrt-v4 util/vecmath.h CoordinateSystem); stable for n.z = -1. Returns two (N, 3) arrays.
    """
    n = np.asarray(n, dtype=np.float64)
    x, y, z = n[..., 0], n[..., 1], n[..., 2]
    sign = np.copysign(1.0, z)
    a = -1.0 / (sign + z)  # sign + z has |.| >= 1, never 0
    xy_a = x * y * a
    t = np.empty(n.shape)
    b = np.empty(n.shape)
    t[..., 0], t[..., 1], t[..., 2] = 1.0 + sign * x * x * a, sign * xy_a, -sign * x
    b[..., 0], b[..., 1], b[..., 2] = xy_a, sign + y * y * a, -y
    return t, b


def to_world(v_local, t, b, n):
    """Local (N, 3) vectors in the frame (t, b, n) -> world (N, 3)."""
    v_local = np.asarray(v_local, dtype=np.float64)
    x, y, z = v_local[..., 0], v_local[..., 1], v_local[..., 2]
    t, b, n = np.broadcast_arrays(t, b, n)
    out = np.empty(np.broadcast_shapes(v_local.shape, t.shape))
    for k in range(3):  # column by column: NumPy is slow on (N,1) x (N,3) broadcasts
        out[..., k] = x * t[..., k] + y * b[..., k] + z * n[..., k]
    return out


def to_local(v, t, b, n):
    """World (N, 3) vectors -> coordinates (N, 3) in the orthonormal frame (t, b, n)."""
    v = np.asarray(v, dtype=np.float64)

    def dot3(a):
        return v[..., 0] * a[..., 0] + v[..., 1] * a[..., 1] + v[..., 2] * a[..., 2]

    return np.stack([dot3(t), dot3(b), dot3(n)], axis=-1)


# ----------------------------------------------------------------------------------------------
# Spheres and hemispheres (local frame, +z up; pdfs per unit solid angle)

def sample_uniform_sphere(u):
    """Directions (N, 3) uniform on the unit sphere from u (N, 2). pdf: pdf_uniform_sphere()."""
    u = _as_u(u, 2)
    cos_theta = 1.0 - 2.0 * u[:, 0]
    sin_theta = np.sqrt(np.maximum(0.0, 1.0 - cos_theta * cos_theta))
    return _unit_sphere_point(cos_theta, sin_theta, 2.0 * np.pi * u[:, 1])


def pdf_uniform_sphere():
    """Solid-angle pdf of sample_uniform_sphere: 1 / (4 pi)."""
    return 1.0 / (4.0 * np.pi)


def sample_uniform_hemisphere(u):
    """Directions (N, 3) uniform on the hemisphere z > 0 from u (N, 2).

    cos(theta) = 1 - u0 lies in (0, 1], so a sample never lies on the horizon where the pdf is 0.
    """
    u = _as_u(u, 2)
    cos_theta = 1.0 - u[:, 0]
    sin_theta = np.sqrt(np.maximum(0.0, u[:, 0] * (2.0 - u[:, 0])))  # 1 - cos^2 without cancelling
    return _unit_sphere_point(cos_theta, sin_theta, 2.0 * np.pi * u[:, 1])


def pdf_uniform_hemisphere(cos_theta):
    """Solid-angle pdf (N,) of sample_uniform_hemisphere: 1 / (2 pi) where cos_theta > 0, else 0."""
    return np.where(np.asarray(cos_theta, dtype=np.float64) > 0.0, 0.5 / np.pi, 0.0)


def sample_concentric_disk(u):
    """Points (N, 2) uniform in the unit disk from u (N, 2): Shirley-Chiu concentric map.

    Area pdf: pdf_concentric_disk(). Low distortion: strata of u stay compact on the disk.
    """
    r, phi = _concentric_polar(_as_u(u, 2))
    out = np.empty((len(r), 2))
    out[:, 0], out[:, 1] = r * np.cos(phi), r * np.sin(phi)
    return out


def _concentric_polar(u):
    """Radius (signed) and angle of the concentric map: the square ring of the larger
    coordinate becomes a circle ring, the ratio of the two coordinates the angle."""
    a = 2.0 * u[:, 0] - 1.0
    b = 2.0 * u[:, 1] - 1.0
    x_major = np.abs(a) > np.abs(b)
    r = np.where(x_major, a, b)
    ratio = _safe_ratio(np.where(x_major, b, a), r)
    phi = (0.25 * np.pi) * np.where(x_major, ratio, 2.0 - ratio)
    return r, phi


def _safe_ratio(num, den):
    """num / den with 0 where den == 0 (signed denominators allowed)."""
    return np.divide(num, den, out=np.zeros_like(num), where=den != 0.0)


def pdf_concentric_disk():
    """Area pdf of sample_concentric_disk on the unit disk: 1 / pi."""
    return 1.0 / np.pi


def sample_cosine_hemisphere(u, in_unit=False):
    """Directions (N, 3) around +z with pdf cos(theta) / pi, from u (N, 2) (Malley's method).

    u = (0, 0) maps to the rim of the disk, i.e. the horizon, where the pdf is 0.
    in_unit: u is known to lie in [0, 1) (see _as_u).
    """
    r, phi = _concentric_polar(_as_u(u, 2, in_unit))
    out = np.empty((len(r), 3))
    out[:, 0], out[:, 1] = r * np.cos(phi), r * np.sin(phi)
    out[:, 2] = np.sqrt(np.maximum(0.0, 1.0 - r * r))  # x^2 + y^2 = r^2
    return out


def pdf_cosine_hemisphere(cos_theta):
    """Solid-angle pdf (N,) of sample_cosine_hemisphere: max(cos_theta, 0) / pi."""
    return np.maximum(np.asarray(cos_theta, dtype=np.float64), 0.0) / np.pi


# ----------------------------------------------------------------------------------------------
# Sphere lights: uniform directions inside the cone a sphere subtends

def one_minus_cos_from_sin2(sin2_theta):
    """1 - cos(theta) = sin^2 / (1 + sqrt(1 - sin^2)) for theta in [0, pi/2]; no cancellation.

    Accurate from sin^2 = 1e-300 up to 1 (where the naive 1 - sqrt(1 - sin^2) is 0 below ~1e-16).
    Input is clipped to [0, 1]; returns float64 of the input's shape.
    """
    s2 = np.clip(np.asarray(sin2_theta, dtype=np.float64), 0.0, 1.0)
    return s2 / (1.0 + np.sqrt(1.0 - s2))


def sample_sphere_cone(u, sin2_theta_max):
    """Directions uniform in solid angle inside the cone of half-angle theta_max around +z.

    u: (N, 2). sin2_theta_max: scalar or (N,) (per-sample cones), clipped to [0, 1]; for a sphere
    of radius r at distance d, sin^2 theta_max = (r / d)^2 (1 = the point is on the sphere or
    inside: the cone becomes the hemisphere).
    Returns (directions (N, 3) local to the cone axis, one_minus_cos_max (N,)); the pdf is
    pdf_sphere_cone(one_minus_cos_max). The sample's 1 - cos(theta) = u0 * (1 - cos theta_max) is
    formed directly (pbrt-v4 shapes.h samples cos linearly the same way), so even a cone of
    sin^2 = 1e-14 gives distinct, correctly spread directions.
    """
    u = _as_u(u, 2)
    one_minus_cos_max = np.broadcast_to(one_minus_cos_from_sin2(sin2_theta_max), u.shape[:1])
    one_minus_cos = u[:, 0] * one_minus_cos_max
    sin_theta = np.sqrt(one_minus_cos * (2.0 - one_minus_cos))  # (1 - c)(1 + c)
    dirs = _unit_sphere_point(1.0 - one_minus_cos, sin_theta, 2.0 * np.pi * u[:, 1])
    return dirs, np.array(one_minus_cos_max)


def pdf_sphere_cone(one_minus_cos_max):
    """Solid-angle pdf (N,) inside the cone: 1 / (2 pi (1 - cos theta_max)); 0 for an empty cone.

    Directions outside the cone have pdf 0; the caller knows which side of the cone it is on.
    """
    return _safe_div(1.0, 2.0 * np.pi * np.asarray(one_minus_cos_max, dtype=np.float64))


# ----------------------------------------------------------------------------------------------
# Planar shapes (pdfs per unit area)

def sample_uniform_triangle(u, in_unit=False):
    """Barycentrics (N, 3) uniform by area from u (N, 2).

    Heitz 2019, "A Low-Distortion Map Between Triangle and Square" (as pbrt-v4
    SampleUniformTriangle): shift the smaller coordinate by half the larger one. The point is
    b0 * p0 + b1 * p1 + b2 * p2; its area pdf is pdf_uniform_triangle(area).
    in_unit: u is known to lie in [0, 1) (see _as_u).
    """
    u = _as_u(u, 2, in_unit)
    u0, u1 = u[:, 0], u[:, 1]
    first_smaller = u0 < u1
    b0 = np.where(first_smaller, 0.5 * u0, u0 - 0.5 * u1)
    b1 = np.where(first_smaller, u1 - 0.5 * u0, 0.5 * u1)
    return np.stack([b0, b1, 1.0 - b0 - b1], axis=-1)


def pdf_uniform_triangle(area):
    """Area pdf of sample_uniform_triangle on a triangle of the given area: 1 / area (0 if 0)."""
    return _safe_div(1.0, area)


def sample_uniform_rectangle(u, half_x, half_y):
    """Points (N, 2) uniform in [-half_x, half_x] x [-half_y, half_y]; half sizes scalar or (N,)."""
    u = _as_u(u, 2)
    return np.stack([(2.0 * u[:, 0] - 1.0) * half_x, (2.0 * u[:, 1] - 1.0) * half_y], axis=-1)


def pdf_uniform_rectangle(half_x, half_y):
    """Area pdf of sample_uniform_rectangle: 1 / (4 half_x half_y); 0 for a degenerate one."""
    return _safe_div(1.0, 4.0 * np.asarray(half_x, dtype=np.float64) * half_y)


# ----------------------------------------------------------------------------------------------
# Tabulated distributions (pbrt-v4 PiecewiseConstant1D/2D, in float64)

def _checked_function(f, ndim):
    """|f| as a float64 array of the given rank; rejects empty and non-finite tables."""
    func = np.array(f, dtype=np.float64)  # a private copy: it is made read-only later
    if func.ndim != ndim or func.size == 0:
        raise ValueError(f"expected a non-empty {ndim}D table, got shape {func.shape}")
    np.abs(func, out=func)
    if not np.isfinite(func.max()):  # max propagates NaN; one cheap pass over large maps
        raise ValueError("distribution table contains NaN or Inf")
    return func


def _read_only(a):
    a.flags.writeable = False
    return a


class Distribution1D:
    """Piecewise-constant density on [0, 1) over n equal bins, proportional to |f|.

    The CDF is a float64 cumsum with its last entry exactly 1 (it is divided by its own last
    entry, so trailing zero bins end at exactly 1 too). A bin is chosen as the largest i with
    cdf[i] <= u, so zero-probability bins are never chosen. Pdfs and pmfs are read from the
    function table, not from CDF differences, so sample() and pdf() agree bit for bit.
    If f integrates to 0 the distribution is uniform (pdf 1); `integral` still reports 0.

    Attributes: n, func (n,), cdf (n + 1,), integral (of |f| over [0, 1), bins of width 1/n).
    """

    def __init__(self, f):
        func = _checked_function(f, 1)
        cumsum = np.cumsum(func)
        if not np.isfinite(cumsum[-1]):
            raise ValueError("distribution table sums to Inf")
        self.n = func.size
        self.integral = float(cumsum[-1]) / self.n
        if not cumsum[-1] > 0.0:
            func = np.ones_like(func)
            cumsum = np.cumsum(func)
        self.func = _read_only(func)
        self.cdf = _read_only(np.concatenate([[0.0], cumsum / cumsum[-1]]))
        self._func_sum = float(cumsum[-1])
        self._func_mean = self._func_sum / self.n  # normaliser of the sampled density

    def _bin_of_u(self, u):
        return np.clip(np.searchsorted(self.cdf, u, side="right") - 1, 0, self.n - 1)

    def _offset_in_bin(self, u, index):
        """Where u falls inside the CDF span of its bin, in [0, 1) (the reusable uniform)."""
        lo = self.cdf[index]
        return np.clip(_safe_div(u - lo, self.cdf[index + 1] - lo), 0.0, ONE_MINUS_EPSILON)

    def sample_index(self, u):
        """Bin index (N,) int64 from u (N,) in [0, 1) (sample_discrete without the extras)."""
        return self._bin_of_u(np.asarray(u, dtype=np.float64))

    def sample_discrete(self, u):
        """Bin index (N,) int64, its pmf (N,), and u remapped into [0, 1) for reuse, from u (N,)."""
        u = _as_u(u, 1)
        index = self._bin_of_u(u)
        return index, self.pmf(index), self._offset_in_bin(u, index)

    def pmf(self, index):
        """Probability (N,) of choosing bin `index` (N,) int."""
        return self.func[index] / self._func_sum

    def sample_continuous(self, u):
        """x (N,) in [0, 1), its pdf (N,) per unit length on [0, 1), and its bin index (N,)."""
        u = _as_u(u, 1)
        index = self._bin_of_u(u)
        du = np.clip(self._offset_in_bin(u, index), _BIN_EDGE_MARGIN, 1.0 - _BIN_EDGE_MARGIN)
        x = (index + du) / self.n
        return x, self.func[index] / self._func_mean, index

    def pdf(self, x):
        """Density (N,) per unit length at x (N,); x outside [0, 1) is clamped to the end bins."""
        x = np.asarray(x, dtype=np.float64)
        index = np.clip(np.floor(x * self.n).astype(np.int64), 0, self.n - 1)
        return self.func[index] / self._func_mean


def _largest_index_at_or_below(cdf, rows, u):
    """Per sample, the largest j in [0, W - 1] with cdf[rows, j] <= u; cdf is (H, W + 1).

    A vectorised binary search (np.searchsorted needs one sorted array; here each sample has
    its own row). Invariant cdf[lo] <= u < cdf[hi] holds from lo = 0, hi = W because every row
    starts at 0 and ends at 1 > u; same rule as searchsorted(side='right') - 1.
    """
    width = cdf.shape[1] - 1
    flat = cdf.ravel()
    base = rows * (width + 1)
    lo = np.zeros(u.shape, dtype=np.int64)
    hi = np.full(u.shape, width, dtype=np.int64)
    for _ in range(int(width).bit_length()):  # enough halvings to shrink hi - lo to 1
        mid = (lo + hi) >> 1
        go_right = flat[base + mid] <= u
        lo = np.where(go_right, mid, lo)
        hi = np.where(go_right, hi, mid)
    return lo


class Distribution2D:
    """Piecewise-constant density on [0, 1)^2 proportional to |f| for a table f of shape (H, W).

    Rows (v, second coordinate) are chosen from the marginal over row sums, then a column (u,
    first coordinate) from that row's conditional CDF (pbrt-v4 PiecewiseConstant2D). Zero rows
    and zero columns are never chosen; an all-zero table is sampled uniformly (pdf 1) and
    reports `integral` 0. The pdf is func[row, col] / mean(func) from the table, identical in
    sample() and pdf().

    Attributes: shape (H, W), func (H, W), cdf (H, W + 1) conditional CDFs, marginal
    (Distribution1D over the H row sums), integral (of |f| over [0, 1)^2).
    Memory: 16 bytes per cell (func + cdf, float64); an 8192 x 4096 map needs ~540 MB.
    """

    def __init__(self, f):
        func = _checked_function(f, 2)
        height, width = func.shape
        self.shape = (height, width)
        cdf = np.empty((height, width + 1))
        cdf[:, 0] = 0.0
        np.cumsum(func, axis=1, out=cdf[:, 1:])
        row_sum = cdf[:, -1].copy()
        self.marginal = Distribution1D(row_sum)
        self.integral = self.marginal.integral / width
        if not self.integral > 0.0:
            func = np.ones_like(func)
            row_sum[:] = width
            np.cumsum(func, axis=1, out=cdf[:, 1:])
        # Normalise rows in place; zero rows (never chosen) get a uniform CDF so every row is valid.
        nonzero = row_sum > 0.0
        np.divide(cdf[:, 1:], np.where(nonzero, row_sum, 1.0)[:, None], out=cdf[:, 1:])
        cdf[~nonzero, 1:] = np.arange(1, width + 1) / width
        self.func = _read_only(func)
        self.cdf = _read_only(cdf)
        self._func_mean = float(np.sum(row_sum)) / (height * width)

    def sample(self, u2):
        """Sample from u2 (N, 2): u2[:, 1] picks the row, u2[:, 0] the column.

        Returns uv (N, 2) in [0, 1)^2 (uv[:, 0] column coordinate, uv[:, 1] row coordinate),
        pdf_uv (N,) per unit area of [0, 1)^2, and (row, col) int64 index arrays (N,).
        """
        u2 = _as_u(u2, 2)
        v, _, row = self.marginal.sample_continuous(u2[:, 1])
        col = _largest_index_at_or_below(self.cdf, row, u2[:, 0])
        lo = self.cdf[row, col]
        du = np.clip(_safe_div(u2[:, 0] - lo, self.cdf[row, col + 1] - lo),
                     _BIN_EDGE_MARGIN, 1.0 - _BIN_EDGE_MARGIN)
        uv = np.stack([(col + du) / self.shape[1], v], axis=-1)
        return uv, self.func[row, col] / self._func_mean, (row, col)

    def cell_of(self, uv):
        """(row, col) int64 indices (N,) of the cells holding uv (N, 2), clamped into range."""
        uv = np.asarray(uv, dtype=np.float64)
        height, width = self.shape
        col = np.clip(np.floor(uv[:, 0] * width).astype(np.int64), 0, width - 1)
        row = np.clip(np.floor(uv[:, 1] * height).astype(np.int64), 0, height - 1)
        return row, col

    def pdf(self, uv):
        """Density (N,) per unit area of [0, 1)^2 at uv (N, 2)."""
        row, col = self.cell_of(uv)
        return self.func[row, col] / self._func_mean


# ----------------------------------------------------------------------------------------------
# Pixel filters, as Blender Cycles defines them
#
# Source: blender/blender intern/cycles/scene/film.cpp (filter_func_box, filter_func_gaussian,
# filter_func_blackman_harris, filter_table) with util/math_cdf.{h,cpp} and the kernel lookup in
# kernel/camera/camera.h. Cycles evaluates each filter f(v, W) on [0, W / 2] with a scaled W:
#   BOX:             W = width,    f = 1                        -> support |x| <= width / 2
#   GAUSSIAN:        W = 3 width,  f = exp(-2 (6 v / W)^2) = exp(-8 v^2 / width^2),
#                                  i.e. sigma = width / 4       -> support |x| <= 1.5 width
#   BLACKMAN_HARRIS: W = 2 width,  p = 2 pi (v / W + 1/2),
#                    f = 0.35875 - 0.48829 cos p + 0.14128 cos 2p - 0.01168 cos 3p
#                                                               -> support |x| <= width
# and importance-samples it separably in x and y around the pixel centre (weight 1 per sample).
# Blender's Cycles sync (intern/cycles/blender/sync.cpp) forces width = 1 for BOX; that rule
# belongs to the exporter, the functions here honour `width` as Cycles' Film does.
#
# Cycles tabulates the inverse CDF in 1024 float32 entries read with linear interpolation. That
# table has artefacts we do not copy: its last entry is never written (stays 0), so u in
# (1022/1023, 1) is interpolated toward the pixel's corner (-0.5 from the centre); the
# inversion takes the next bin's slope (upper_bound without -1) and scales by 1/1023 where
# 1/1022 is meant. We sample the same filter on the same support from float64 bin integrals
# (4096 bins over the half support, uniform inside a bin), keeping Cycles' symmetric layout:
# u in [0, 1) maps monotonically onto [-support, support], u = 1/2 to the centre.

def pixel_filter_radius(kind, width):
    """Half-width (pixels) of the support of Cycles' pixel filter `kind` of the given width."""
    scale = {"BOX": 0.5, "GAUSSIAN": 1.5, "BLACKMAN_HARRIS": 1.0}
    if kind not in scale:
        raise ValueError(f"unknown pixel filter {kind!r}; expected one of {PIXEL_FILTER_KINDS}")
    if not width > 0.0:
        raise ValueError(f"pixel filter width must be > 0, got {width}")
    return scale[kind] * float(width)


def pixel_filter_1d(kind, width, x):
    """Unnormalised 1D filter value at offsets x (pixels from the pixel centre); 0 off support."""
    radius = pixel_filter_radius(kind, width)
    x = np.asarray(x, dtype=np.float64)
    if kind == "BOX":
        value = np.ones_like(x)
    elif kind == "GAUSSIAN":
        scaled_width = 3.0 * width
        v = x * (6.0 / scaled_width)
        value = np.exp(-2.0 * v * v)
    else:
        scaled_width = 2.0 * width
        p = 2.0 * np.pi * (x / scaled_width + 0.5)
        value = (0.35875 - 0.48829 * np.cos(p) + 0.14128 * np.cos(2.0 * p)
                 - 0.01168 * np.cos(3.0 * p))
    return np.where(np.abs(x) <= radius, value, 0.0)


@lru_cache(maxsize=16)
def _pixel_filter_half_distribution(kind, width):
    """Distribution1D over [0, radius] (rescaled to [0, 1)) of the filter's exact bin integrals."""
    radius = pixel_filter_radius(kind, width)
    edges = np.linspace(0.0, radius, _PIXEL_FILTER_BINS + 1)
    nodes, weights = np.polynomial.legendre.leggauss(8)
    x = edges[:-1, None] + (edges[1:] - edges[:-1])[:, None] * (0.5 * (nodes + 1.0))[None, :]
    bin_integrals = pixel_filter_1d(kind, width, x) @ (0.5 * weights)
    return Distribution1D(bin_integrals)


def sample_pixel_filter(kind, width, u):
    """Filter-importance-sampled offsets (N, 2) in pixels from the pixel centre, from u (N, 2).

    Separable: x and y are independent draws from Cycles' 1D filter (see pixel_filter_1d), each
    with density proportional to it on [-radius, radius]; the sample weight is 1. The map from
    u to offset is monotone and odd about u = 1/2 (like Cycles' table), so stratified u stay
    stratified. The table is built once per (kind, width).
    """
    u = _as_u(u, 2)
    radius = pixel_filter_radius(kind, width)
    inverse = _pixel_filter_inverse_table(kind, float(width))
    s = 2.0 * u - 1.0
    # The inverse CDF tabulated at uniform steps of u: an O(1) lookup with linear
    # interpolation instead of a binary search per sample.
    x = np.minimum(np.abs(s), ONE_MINUS_EPSILON) * (len(inverse) - 1)
    i = x.astype(np.intp)
    magnitude = inverse[i] + (x - i) * (inverse[i + 1] - inverse[i])
    return np.copysign(magnitude * radius, s)


_INVERSE_STEPS = 1 << 16


@lru_cache(maxsize=16)
def _pixel_filter_inverse_table(kind, width):
    """Offsets (fraction of the radius) at u = 0, 1/M, ..., 1 of the half filter's inverse CDF
    (the piecewise-linear CDF of Distribution1D, inverted by interpolation; the filters are
    positive inside their support, so the CDF is strictly increasing)."""
    half = _pixel_filter_half_distribution(kind, width)
    return np.interp(np.linspace(0.0, 1.0, _INVERSE_STEPS + 1), half.cdf, np.linspace(0.0, 1.0, half.n + 1))
