"""Tests of engine/sampling.py: chi-square fits of every sampler, pdf consistency, normalisation,
edge inputs, and Cycles' pixel-filter definitions.

All statistical tests are seeded. The chi-square tests share one family-wise level of 0.01
(Sidak-corrected over CHI2_CASES); the Monte Carlo normalisation checks use 3 sigma.
"""
import numpy as np
import pytest

from ember.engine import sampling as s
from stats import (Box, ChiSquareTest, Cone, Discrete, Disk, Hemisphere, Interval, Mapped, Sphere, integrate,
                   sidak_alpha, z_test_images)

N_SAMPLES = 400_000
TWO_PI = 2.0 * np.pi


def _u2(seed, n=N_SAMPLES):
    return np.random.default_rng(seed).random((n, 2))


def _reference_one_minus_cos(sin2):
    """1 - sqrt(1 - sin2) by a formula independent of the one under test."""
    with np.errstate(divide="ignore"):  # sin2 = 1: log1p(-1) = -inf, and the result is 1
        return -np.expm1(0.5 * np.log1p(-np.asarray(sin2, dtype=np.float64)))


def _constant(value):
    return lambda p: np.full(len(p), float(value))


# ----------------------------------------------------------------------------------------------
# Chi-square cases: each a ChiSquareTest with a fixed seed; directions on 40 x 80 cells of
# (cos theta, phi), planar samplers on 40 cells per unit axis.

def case_cosine_hemisphere():
    return ChiSquareTest(Hemisphere(), s.sample_cosine_hemisphere, lambda d: s.pdf_cosine_hemisphere(d[:, 2]),
                         (40, 80), N_SAMPLES, seed=1)


def case_uniform_sphere():
    return ChiSquareTest(Sphere(), s.sample_uniform_sphere, _constant(s.pdf_uniform_sphere()), (40, 80),
                         N_SAMPLES, seed=2)


def case_uniform_hemisphere():
    return ChiSquareTest(Hemisphere(), s.sample_uniform_hemisphere, lambda d: s.pdf_uniform_hemisphere(d[:, 2]),
                         (40, 80), N_SAMPLES, seed=3)


def case_triangle():
    # (b0, b1 / (1 - b0)) maps the triangle onto the unit square, db0 db1 = (1 - b0) dx dy: the
    # density 2 (1 - b0) there is smooth, so no cell straddles the hypotenuse.
    def sampler(u):
        b = s.sample_uniform_triangle(u)
        assert np.all(b >= 0.0) and np.allclose(b.sum(axis=1), 1.0, rtol=0, atol=1e-15)
        return b

    def coordinates(b):
        return b[:, 0], np.divide(b[:, 1], 1.0 - b[:, 0], out=np.zeros(len(b)), where=b[:, 0] < 1.0)

    def points(x, y):
        return np.stack([x, (1.0 - x) * y, (1.0 - x) * (1.0 - y)], axis=-1), 1.0 - x

    # The triangle b0, b1 >= 0, b0 + b1 <= 1 has area 1/2: density 2.
    return ChiSquareTest(Mapped(((0, 1), (0, 1)), coordinates, points), sampler, _constant(2.0), 40,
                         N_SAMPLES, seed=4)


def _case_sphere_cone(sin2_theta_max, seed):
    # Cone coordinates (1 - cos theta) / (1 - cos theta_max): even a 1e-12 cone fills the grid.
    reference = _reference_one_minus_cos(sin2_theta_max)

    def sampler(u):
        d, one_minus_cos_max = s.sample_sphere_cone(u, sin2_theta_max)
        np.testing.assert_allclose(one_minus_cos_max, reference, rtol=1e-12)
        return d

    return ChiSquareTest(Cone(reference), sampler, _constant(s.pdf_sphere_cone(reference)), (40, 80), N_SAMPLES,
                         seed=seed)


def case_concentric_disk():
    return ChiSquareTest(Disk((0.0, 0.0), (1.0, 0.0), (0.0, 1.0)), s.sample_concentric_disk,
                         _constant(s.pdf_concentric_disk()), (40, 80), N_SAMPLES, seed=9)


def case_rectangle():
    return ChiSquareTest(Box((-2.0, 2.0), (-0.5, 0.5)), lambda u: s.sample_uniform_rectangle(u, 2.0, 0.5),
                         _constant(s.pdf_uniform_rectangle(2.0, 0.5)), (40, 20), N_SAMPLES, seed=10)


def _random_table_1d():
    f = np.random.default_rng(11).random(37) ** 2
    f[[0, 5, 6, 36]] = 0.0  # zero bins at both ends and a zero run inside
    return f


def _reference_density_1d(f):
    """f / mean(f) as a density on [0, 1), independent of the code under test (uniform if 0)."""
    f = np.asarray(f, dtype=np.float64)
    table = f / f.mean() if f.sum() > 0.0 else np.ones_like(f)
    return lambda x: table[np.clip((x * f.size).astype(int), 0, f.size - 1)]


def _case_distribution1d(f, seed, subdivide):
    # Cells never straddle a bin edge, so the reference density is constant on each.
    return ChiSquareTest(Interval(0.0, 1.0), lambda u: s.Distribution1D(f).sample_continuous(u[:, 0])[0],
                         _reference_density_1d(f), subdivide * f.size, N_SAMPLES, seed=seed, sample_dim=1)


def case_distribution1d_continuous():
    return _case_distribution1d(_random_table_1d(), 12, 3)


def case_distribution1d_discrete_and_remap():
    # Samples (bin, remapped u) on [0, n) x [0, 1): bins by pmf, the remapped u uniform and
    # independent of the bin; n x 10 cells.
    f = _random_table_1d()
    pmf = f / f.sum()

    def sampler(u):
        index, _, u_remapped = s.Distribution1D(f).sample_discrete(u[:, 0])
        return np.stack([index, u_remapped], axis=1)

    return ChiSquareTest(Box((0, f.size), (0, 1)), sampler, lambda p: pmf[p[:, 0].astype(int)], (f.size, 10),
                         N_SAMPLES, seed=13, sample_dim=1)


def case_distribution1d_single_hot_bin():
    f = np.zeros(64)
    f[17] = 3.0
    return _case_distribution1d(f, 14, 8)


def _case_distribution2d(f, seed, subdivide):
    # Reference density f / mean(f) (uniform if f is 0), read independently of the code under test.
    height, width = f.shape
    table = f / f.mean() if f.sum() > 0.0 else np.ones_like(f)

    def density(uv):
        col = np.clip((uv[:, 0] * width).astype(int), 0, width - 1)
        return table[np.clip((uv[:, 1] * height).astype(int), 0, height - 1), col]

    return ChiSquareTest(Box(), lambda u: s.Distribution2D(f).sample(u)[0], density,
                         (subdivide * width, subdivide * height), N_SAMPLES, seed=seed)


def _random_table_2d():
    f = np.random.default_rng(15).random((23, 31)) ** 3
    f[[0, 7, 22], :] = 0.0
    f[:, [0, 13, 30]] = 0.0
    return f


def case_distribution2d_random_with_zero_rows_and_columns():
    return _case_distribution2d(_random_table_2d(), 16, 2)


def case_distribution2d_hot_cell_on_dim_background():
    f = np.full((16, 32), 1.0)
    f[5, 9] = 1e5  # a sun over a sky: the dim cells still get their share
    return _case_distribution2d(f, 17, 1)


def case_distribution2d_single_hot_cell():
    f = np.zeros((16, 32))
    f[15, 31] = 2.0  # last row and column: the CDF ends must not leak
    return _case_distribution2d(f, 18, 4)


def case_distribution2d_1x1():
    return _case_distribution2d(np.array([[0.7]]), 19, 20)


def case_distribution2d_all_zero():
    return _case_distribution2d(np.zeros((6, 9)), 20, 3)


def _normalised_pixel_filter(kind, width):
    radius = s.pixel_filter_radius(kind, width)
    norm = integrate(Interval(-radius, radius), lambda x: s.pixel_filter_1d(kind, width, x), 2000).sum()
    return lambda x: s.pixel_filter_1d(kind, width, x) / norm


def _case_pixel_filter(kind, width, seed):
    # Joint 2D fit against g(x) g(y): checks each axis and their independence.
    radius = s.pixel_filter_radius(kind, width)
    g = _normalised_pixel_filter(kind, width)
    return ChiSquareTest(Box((-radius, radius), (-radius, radius)), lambda u: s.sample_pixel_filter(kind, width, u),
                         lambda p: g(p[:, 0]) * g(p[:, 1]), 31, 300_000, seed=seed)


CONE_SIN2 = (1e-12, 0.01, 0.5, 1.0)
FILTER_WIDTHS = (1.0, 1.5, 3.0)

CHI2_CASES = {
    "cosine_hemisphere": case_cosine_hemisphere,
    "uniform_sphere": case_uniform_sphere,
    "uniform_hemisphere": case_uniform_hemisphere,
    "triangle": case_triangle,
    **{f"sphere_cone_{sin2:g}": (lambda sin2=sin2, i=i: _case_sphere_cone(sin2, 5 + i))
       for i, sin2 in enumerate(CONE_SIN2)},
    "concentric_disk": case_concentric_disk,
    "rectangle": case_rectangle,
    "distribution1d_continuous": case_distribution1d_continuous,
    "distribution1d_discrete_and_remap": case_distribution1d_discrete_and_remap,
    "distribution1d_single_hot_bin": case_distribution1d_single_hot_bin,
    "distribution2d_random_zero_rows_cols": case_distribution2d_random_with_zero_rows_and_columns,
    "distribution2d_hot_cell_on_dim": case_distribution2d_hot_cell_on_dim_background,
    "distribution2d_single_hot_cell": case_distribution2d_single_hot_cell,
    "distribution2d_1x1": case_distribution2d_1x1,
    "distribution2d_all_zero": case_distribution2d_all_zero,
    **{f"pixel_filter_{kind}_{width:g}":
       (lambda kind=kind, width=width, i=i: _case_pixel_filter(kind, width, 30 + i))
       for i, (kind, width) in enumerate((k, w) for k in s.PIXEL_FILTER_KINDS
                                         for w in FILTER_WIDTHS)},
}


@pytest.mark.parametrize("name", list(CHI2_CASES))
def test_chi2_goodness_of_fit(name):
    CHI2_CASES[name]().check(n_tests=len(CHI2_CASES))


# ----------------------------------------------------------------------------------------------
# Frames

def test_frame_from_z_is_orthonormal_and_right_handed():
    rng = np.random.default_rng(40)
    poles = np.array([[0, 0, 1], [0, 0, -1], [1e-9, 0, -1], [0, -1e-12, 1], [1, 0, 0]], float)
    n = np.concatenate([rng.normal(size=(10_000, 3)), poles])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    t, b = s.frame_from_z(n)
    for a, c in ((t, b), (t, n), (b, n)):
        assert np.max(np.abs(np.sum(a * c, axis=1))) < 1e-12
    for a in (t, b):
        assert np.max(np.abs(np.linalg.norm(a, axis=1) - 1.0)) < 1e-12
    assert np.max(np.abs(np.cross(t, b) - n)) < 1e-12
    v = rng.normal(size=n.shape)
    assert np.max(np.abs(s.to_world(s.to_local(v, t, b, n), t, b, n) - v)) < 1e-12
    assert np.max(np.abs(s.to_local(n, t, b, n) - [0.0, 0.0, 1.0])) < 1e-12


# ----------------------------------------------------------------------------------------------
# Support: samples never land where the pdf is 0

def test_direction_samplers_are_unit_and_inside_their_support():
    u = _u2(41, 100_000)
    for sampler, pdf in ((s.sample_cosine_hemisphere, s.pdf_cosine_hemisphere),
                         (s.sample_uniform_hemisphere, s.pdf_uniform_hemisphere)):
        d = sampler(u)
        assert np.max(np.abs(np.linalg.norm(d, axis=1) - 1.0)) < 1e-12
        assert np.all(pdf(d[:, 2]) > 0.0)
    d = s.sample_uniform_sphere(u)
    assert np.max(np.abs(np.linalg.norm(d, axis=1) - 1.0)) < 1e-12
    assert np.all(np.linalg.norm(s.sample_concentric_disk(u), axis=1) <= 1.0 + 1e-15)
    rect = s.sample_uniform_rectangle(u, 3.0, 0.25)
    assert np.all(np.abs(rect) <= [3.0, 0.25])


@pytest.mark.parametrize("sin2", [1e-14, 1e-12, 1e-6, 0.01, 0.5, 0.999999, 1.0])
def test_sphere_cone_stays_inside_cone(sin2):
    d, one_minus_cos_max = s.sample_sphere_cone(_u2(42, 100_000), sin2)
    reference = _reference_one_minus_cos(sin2)
    np.testing.assert_allclose(one_minus_cos_max, reference, rtol=1e-12)
    assert np.max(np.abs(np.linalg.norm(d, axis=1) - 1.0)) < 1e-12
    one_minus_cos = (d[:, 0] ** 2 + d[:, 1] ** 2) / (1.0 + d[:, 2])
    assert np.all(one_minus_cos <= reference * (1.0 + 1e-12))
    # The samples resolve the cone: their spread matches the uniform law's mean r = 1/2.
    assert abs(np.mean(one_minus_cos / reference) - 0.5) < 0.01
    np.testing.assert_allclose(s.pdf_sphere_cone(one_minus_cos_max),
                               1.0 / (TWO_PI * reference), rtol=1e-12)


def test_sphere_cone_accepts_per_sample_cones():
    sin2 = np.array([1e-14, 0.25, 1.0, 0.0])
    d, one_minus_cos_max = s.sample_sphere_cone(np.full((4, 2), 0.999), sin2)
    np.testing.assert_allclose(one_minus_cos_max, _reference_one_minus_cos(sin2), rtol=1e-12)
    one_minus_cos = (d[:, 0] ** 2 + d[:, 1] ** 2) / (1.0 + d[:, 2])
    np.testing.assert_allclose(one_minus_cos, 0.999 * one_minus_cos_max, rtol=1e-12)
    assert s.pdf_sphere_cone(one_minus_cos_max)[3] == 0.0  # an empty cone has pdf 0, not Inf


# ----------------------------------------------------------------------------------------------
# Tabulated distributions: sample and pdf agree bit for bit; zero cells never chosen

def test_distribution1d_sample_pdf_pmf_round_trip():
    f = _random_table_1d()
    dist = s.Distribution1D(f)
    u = np.random.default_rng(43).random(200_000)
    x, pdf, index = dist.sample_continuous(u)
    assert np.all((x >= 0.0) & (x < 1.0))
    np.testing.assert_array_equal(dist.pdf(x), pdf)
    assert np.all(f[index] > 0.0)
    np.testing.assert_array_equal(np.floor(x * dist.n).astype(int), index)
    i, pmf, u_remapped = dist.sample_discrete(u)
    np.testing.assert_array_equal(i, index)
    np.testing.assert_array_equal(dist.pmf(i), pmf)
    np.testing.assert_allclose(pmf * dist.n, pdf, rtol=1e-12)
    assert np.all((u_remapped >= 0.0) & (u_remapped < 1.0))
    assert abs(dist.pmf(np.arange(dist.n)).sum() - 1.0) < 1e-12
    assert dist.cdf[0] == 0.0 and dist.cdf[-1] == 1.0
    assert dist.integral == pytest.approx(f.mean(), rel=1e-12)


def test_distribution1d_trailing_zero_bins_are_never_chosen():
    f = np.array([0.3, 0.1, 1e-300, 0.0, 0.0])
    dist = s.Distribution1D(f)
    u = np.array([0.0, 0.5, 0.99999999, s.ONE_MINUS_EPSILON, 1.0])
    index, pmf, _ = dist.sample_discrete(u)
    assert np.all(index <= 2) and np.all(pmf > 0.0)
    x, pdf, _ = dist.sample_continuous(u)
    assert np.all(x < 0.6) and np.all(pdf > 0.0)


def test_distribution2d_sample_pdf_round_trip():
    f = _random_table_2d()
    dist = s.Distribution2D(f)
    uv, pdf, (row, col) = dist.sample(_u2(44, 200_000))
    assert np.all((uv >= 0.0) & (uv < 1.0))
    np.testing.assert_array_equal(dist.pdf(uv), pdf)
    cell_row, cell_col = dist.cell_of(uv)
    np.testing.assert_array_equal(cell_row, row)
    np.testing.assert_array_equal(cell_col, col)
    assert np.all(f[row, col] > 0.0)
    np.testing.assert_allclose(pdf, f[row, col] / f.mean(), rtol=1e-12)
    assert dist.integral == pytest.approx(f.mean(), rel=1e-12)
    cells = np.stack(np.meshgrid((np.arange(31) + 0.5) / 31, (np.arange(23) + 0.5) / 23),
                     axis=-1).reshape(-1, 2)
    assert abs(dist.pdf(cells).sum() / f.size - 1.0) < 1e-12  # cell pmfs sum to 1


def test_distribution2d_edge_rows_and_uniform_fallback():
    hot = np.zeros((4, 5))
    hot[3, 4] = 1.0
    dist = s.Distribution2D(hot)
    u = np.array([[0.0, 0.0], [s.ONE_MINUS_EPSILON] * 2, [1.0, 1.0], [0.5, 0.5]])
    uv, pdf, (row, col) = dist.sample(u)
    assert np.all(row == 3) and np.all(col == 4) and np.all(pdf == 20.0)
    assert np.all((uv[:, 0] >= 0.8) & (uv[:, 0] < 1.0) & (uv[:, 1] >= 0.75) & (uv[:, 1] < 1.0))
    zero = s.Distribution2D(np.zeros((3, 2)))
    uv, pdf, _ = zero.sample(u)
    assert zero.integral == 0.0 and np.all(pdf == 1.0) and np.all(zero.pdf(uv) == 1.0)
    assert s.Distribution1D(np.zeros(4)).integral == 0.0


def test_distribution2d_large_map_with_sun():
    rng = np.random.default_rng(45)
    f = rng.random((512, 1024), dtype=np.float32) * 1e-3
    f[100:103, 700:703] = 1e5
    dist = s.Distribution2D(f)
    uv, pdf, (row, col) = dist.sample(_u2(46, 100_000))
    np.testing.assert_array_equal(dist.pdf(uv), pdf)
    expected_sun = f[100:103, 700:703].sum(dtype=np.float64) / f.sum(dtype=np.float64)
    assert abs(np.mean((row >= 100) & (row < 103) & (col >= 700) & (col < 703)) - expected_sun) \
        < 4 * np.sqrt(expected_sun * (1 - expected_sun) / 100_000) + 1e-9


@pytest.mark.parametrize("bad", [np.array([1.0, np.nan]), np.array([np.inf, 1.0]), np.zeros(0)])
def test_distribution_rejects_bad_tables(bad):
    with pytest.raises(ValueError):
        s.Distribution1D(bad)
    with pytest.raises(ValueError):
        s.Distribution2D(bad.reshape(1, -1))


# ----------------------------------------------------------------------------------------------
# Normalisation: the MC integral of each pdf over a domain covering its support is 1 (3 sigma)

def _uniform_directions(seed, n):
    return s.sample_uniform_sphere(_u2(seed, n))


def _integral_cosine_hemisphere(n):
    d = _uniform_directions(50, n)
    return s.pdf_cosine_hemisphere(d[:, 2]) / s.pdf_uniform_sphere()


def _integral_uniform_hemisphere(n):
    d = _uniform_directions(51, n)
    return s.pdf_uniform_hemisphere(d[:, 2]) / s.pdf_uniform_sphere()


def _integral_sphere_cone(sin2, n):
    # Directions uniform on a cap twice the cone's size (clipped to the sphere).
    one_minus_cos_max = s.one_minus_cos_from_sin2(sin2)
    cap = min(2.0 * one_minus_cos_max, 2.0)
    one_minus_cos = np.random.default_rng(52).random(n) * cap
    inside = one_minus_cos <= one_minus_cos_max
    return np.where(inside, s.pdf_sphere_cone(one_minus_cos_max), 0.0) * (TWO_PI * cap)


def _integral_disk(n):
    p = 2.0 * _u2(53, n) - 1.0  # the square [-1, 1]^2, area 4
    return np.where(np.sum(p * p, axis=1) <= 1.0, s.pdf_concentric_disk(), 0.0) * 4.0


def _integral_triangle(n):
    # Barycentric (b0, b1) uniform on the unit square; the triangle's area is 2 * area * (1/2).
    area = 0.37
    b = _u2(54, n)
    return np.where(b.sum(axis=1) <= 1.0, s.pdf_uniform_triangle(area), 0.0) * (2.0 * area)


def _integral_rectangle(n):
    hx, hy = 1.5, 0.2
    return np.full(n, s.pdf_uniform_rectangle(hx, hy) * 4.0 * hx * hy)


def _integral_distribution1d(n):
    return s.Distribution1D(_random_table_1d()).pdf(np.random.default_rng(55).random(n))


def _integral_distribution2d(n):
    return s.Distribution2D(_random_table_2d()).pdf(_u2(56, n))


NORMALISATION_CASES = {
    "cosine_hemisphere": _integral_cosine_hemisphere,
    "uniform_hemisphere": _integral_uniform_hemisphere,
    **{f"sphere_cone_{sin2:g}": (lambda n, sin2=sin2: _integral_sphere_cone(sin2, n))
       for sin2 in (1e-14, 0.01, 0.5, 1.0)},
    "disk": _integral_disk,
    "triangle": _integral_triangle,
    "rectangle": _integral_rectangle,
    "distribution1d": _integral_distribution1d,
    "distribution2d": _integral_distribution2d,
}


@pytest.mark.parametrize("name", list(NORMALISATION_CASES))
def test_pdf_integrates_to_one(name):
    n = 200_000
    estimates = NORMALISATION_CASES[name](n)
    sigma = np.std(estimates) / np.sqrt(n)
    assert abs(np.mean(estimates) - 1.0) <= 3.0 * sigma + 1e-12


# ----------------------------------------------------------------------------------------------
# Edge inputs: no NaN or Inf

EDGE_U = np.array([[0.0, 0.0], [0.0, s.ONE_MINUS_EPSILON], [s.ONE_MINUS_EPSILON, 0.0],
                   [s.ONE_MINUS_EPSILON, s.ONE_MINUS_EPSILON], [0.5, 0.5], [1.0, 1.0],
                   [0.25, 0.75]])


def test_edge_inputs_give_finite_results():
    outputs = [
        s.sample_cosine_hemisphere(EDGE_U), s.sample_uniform_sphere(EDGE_U),
        s.sample_uniform_hemisphere(EDGE_U), s.sample_concentric_disk(EDGE_U),
        s.sample_uniform_triangle(EDGE_U), s.sample_uniform_rectangle(EDGE_U, 1.0, 2.0),
        s.pdf_cosine_hemisphere(s.sample_cosine_hemisphere(EDGE_U)[:, 2]),
        s.pdf_uniform_rectangle(0.0, 1.0), s.pdf_uniform_triangle(np.array([0.0, 1e-300])),
    ]
    for sin2 in (0.0, 1e-300, 1e-14, 1.0, 1.5):
        d, one_minus_cos_max = s.sample_sphere_cone(EDGE_U, sin2)
        outputs += [d, one_minus_cos_max, s.pdf_sphere_cone(one_minus_cos_max)]
    for f in (np.array([0.0, 1.0, 0.0]), np.zeros(3), np.array([5.0])):
        dist = s.Distribution1D(f)
        outputs += list(dist.sample_continuous(EDGE_U[:, 0])[:2])
        outputs += list(dist.sample_discrete(EDGE_U[:, 1])[1:])
        outputs.append(dist.pdf(np.array([-1.0, 0.0, 1.0, 2.0])))
    for f in (np.array([[0.0, 2.0], [0.0, 0.0]]), np.zeros((2, 3)), np.ones((1, 1))):
        dist = s.Distribution2D(f)
        uv, pdf, _ = dist.sample(EDGE_U)
        outputs += [uv, pdf, dist.pdf(np.array([[-1.0, 2.0], [1.0, 1.0]]))]
    for kind in s.PIXEL_FILTER_KINDS:
        outputs.append(s.sample_pixel_filter(kind, 1.5, EDGE_U))
    for out in outputs:
        assert np.all(np.isfinite(out))
    d, _ = s.sample_sphere_cone(EDGE_U, 0.0)
    assert np.all(d == [0.0, 0.0, 1.0])  # an empty cone collapses onto its axis


# ----------------------------------------------------------------------------------------------
# Pixel filters: Cycles' definitions

def _cycles_filter_table(kind, width, size=1024):
    """Transcription of Cycles' inverse-CDF filter table (intern/cycles/scene/film.cpp
    filter_table + util/math_cdf util_cdf_inverted, symmetric branch), in float64. Entries are
    offsets from the pixel corner; entry 511 + k holds the quantile k / 511 of |offset|."""
    scaled_width = width * {"BOX": 1.0, "GAUSSIAN": 3.0, "BLACKMAN_HARRIS": 2.0}[kind]
    half_range = 0.5 * scaled_width
    x = half_range * np.arange(size - 1) / (size - 2)
    cdf = np.concatenate([[0.0], np.cumsum(s.pixel_filter_1d(kind, width, x))])
    cdf /= cdf[-1]
    half = (size - 1) // 2
    target = np.arange(half + 1) / half
    index = np.searchsorted(cdf, target, side="right")  # std::upper_bound, as in Cycles
    inside = index < cdf.size - 1
    i = np.minimum(index, cdf.size - 2)
    t = np.where(inside, (target - cdf[i]) / (cdf[i + 1] - cdf[i]), 0.0)
    y = (np.where(inside, index, cdf.size - 1) + t) / (size - 1) * 2.0 * half_range
    table = np.zeros(size)
    table[half + np.arange(half + 1)] = 0.5 * (1.0 + y)
    table[half - np.arange(half + 1)] = 0.5 * (1.0 - y)
    return table


@pytest.mark.parametrize("kind", s.PIXEL_FILTER_KINDS)
@pytest.mark.parametrize("width", FILTER_WIDTHS)
def test_pixel_filter_quantiles_match_cycles_table(kind, width):
    k = np.arange(511)  # entry 1022 (k = 511) is the support end; 1023 is never written in Cycles
    table = _cycles_filter_table(kind, width)[511 + k] - 0.5
    u = 0.5 * (1.0 + k / 511.0)
    ours = s.sample_pixel_filter(kind, width, np.stack([u, u], axis=-1))[:, 0]
    assert np.max(np.abs(ours - table)) < 1e-3 * width  # Cycles' table error is <= 4e-4 width


def test_pixel_filter_definitions():
    # Gaussian: sigma = width / 4, cut at 1.5 width; Blackman-Harris: peak 1 at 0, zero outside
    # +-width; box: 1 on +-width / 2.
    w = 2.0
    g = s.pixel_filter_1d("GAUSSIAN", w, np.array([0.0, w / 4, 1.5 * w, 1.5 * w + 1e-9]))
    np.testing.assert_allclose(g, [1.0, np.exp(-0.5), np.exp(-18.0), 0.0], rtol=1e-14)
    bh = s.pixel_filter_1d("BLACKMAN_HARRIS", w, np.array([0.0, -w, w, w + 1e-9]))
    np.testing.assert_allclose(bh, [1.0, 6e-5, 6e-5, 0.0], rtol=1e-12, atol=1e-15)
    box = s.pixel_filter_1d("BOX", w, np.array([0.0, -1.0, 1.0, 1.0 + 1e-9]))
    np.testing.assert_array_equal(box, [1.0, 1.0, 1.0, 0.0])
    assert [s.pixel_filter_radius(k, w) for k in s.PIXEL_FILTER_KINDS] == [1.0, 3.0, 2.0]
    with pytest.raises(ValueError):
        s.pixel_filter_radius("MITCHELL", 1.0)


@pytest.mark.parametrize("kind", s.PIXEL_FILTER_KINDS)
def test_pixel_filter_is_monotone_in_u_and_inside_support(kind):
    u = np.linspace(0.0, 1.0, 100_001)
    offsets = s.sample_pixel_filter(kind, 1.5, np.stack([u, u[::-1]], axis=-1))
    radius = s.pixel_filter_radius(kind, 1.5)
    assert np.all(np.abs(offsets) <= radius)
    assert np.all(np.diff(offsets[:, 0]) >= 0.0) and np.all(np.diff(offsets[:, 1]) <= 0.0)
    np.testing.assert_allclose(offsets[:, 0], -offsets[::-1, 0], atol=1e-8)  # odd about 1/2


# ----------------------------------------------------------------------------------------------
# The statistics helpers themselves (tests/stats.py)

def _draw_from(p, seed, pmf=None, n=20_000):
    """ChiSquareTest of n indices drawn from the table p against the pmf `pmf` (default p)."""
    cdf = np.cumsum(p) / np.sum(p)
    claimed = p / p.sum() if pmf is None else pmf
    return ChiSquareTest(Discrete(len(p)), lambda u: np.minimum(np.searchsorted(cdf, u[:, 0], side="right"), len(p) - 1),
                         lambda k: claimed[k], n_samples=n, seed=seed, sample_dim=1)


def test_chi2_test_is_calibrated_and_has_power():
    rng = np.random.default_rng(60)
    p = rng.random(300)
    p[:40] *= 1e-3  # low-expectation cells that must be pooled
    p /= p.sum()
    p_null = np.array([_draw_from(p, seed).run().p_value for seed in range(300)])
    assert 0.02 <= np.mean(p_null < 0.05) <= 0.09  # binomial(300, 0.05): +-3.3 sigma
    q = p * (1.0 + 0.1 * np.sin(np.arange(p.size)))
    assert _draw_from(q, 300, pmf=p, n=100_000).run().p_value < 1e-6
    assert sidak_alpha(0.01, 1) == pytest.approx(0.01, rel=1e-12)
    assert (1.0 - sidak_alpha(0.01, 28)) ** 28 == pytest.approx(0.99, rel=1e-12)


def test_chi2_test_fails_outright_where_it_must():
    p = np.array([0.2, 0.3, 0.5])
    samples_where_pdf_is_0 = _draw_from(p, 1, pmf=np.array([0.4, 0.0, 0.6])).run()
    assert not samples_where_pdf_is_0.passed and "pdf is 0" in samples_where_pdf_is_0.failure
    for scale in (1.03, 0.97):  # a pdf that does not integrate to 1 while nothing is rejected
        r = _draw_from(p, 2, pmf=scale * p).run()
        assert not r.passed and "integrates to" in r.failure, r.report()
    outside = ChiSquareTest(Interval(0.0, 1.0), lambda u: 1.01 * u[:, 0], _constant(1.0), 10, 1000, sample_dim=1)
    assert "outside the domain" in outside.run().failure
    # Rejected samples form one more cell, expected n (1 - integral), and their number is tested
    # on its own: the upper half of uniform directions on the sphere against 1 / (4 pi) on the
    # hemisphere passes, 4 % more fails.
    upper = lambda u: (s.sample_uniform_sphere(u), s.sample_uniform_sphere(u)[:, 2] > 0.0)  # noqa: E731
    ok = ChiSquareTest(Hemisphere(), upper, _constant(0.25 / np.pi), (10, 20), 100_000, seed=3).check()
    assert ok.rejected_expected == pytest.approx(50_000) and 49_000 < ok.rejected < 51_000
    too_much = ChiSquareTest(Hemisphere(), upper, _constant(1.04 * 0.25 / np.pi), (10, 20), 100_000, seed=3).run()
    assert not too_much.passed and too_much.p_kept < 1e-9
    with pytest.raises(AssertionError, match="rejected by the sampler"):  # the worst cell, in the report
        too_much.check()


def test_z_test_images_accepts_equal_and_rejects_shifted_means():
    rng = np.random.default_rng(61)
    truth = rng.random((64, 64, 3))
    var_mean = np.full(truth.shape, 1e-3)
    a = truth + rng.normal(size=truth.shape) * np.sqrt(var_mean)
    b = truth + rng.normal(size=truth.shape) * np.sqrt(var_mean)
    assert z_test_images(a, var_mean, b, var_mean) == 1.0
    assert z_test_images(a + 0.2, var_mean, b, var_mean) < 0.9
    exact = np.zeros((8, 8))  # deterministic pixels: zero variance on both sides
    assert z_test_images(exact + 1e-7, exact, exact, exact) == 1.0
    assert z_test_images(exact + 1e-2, exact, exact, exact) == 0.0
    assert z_test_images(exact + np.nan, exact, exact, exact) == 0.0
