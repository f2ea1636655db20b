"""Statistics helpers shared by Ember's tests: chi-square goodness of fit, z-tests on images.

Chi-square recipe after Mitsuba 3 (src/python/python/chi2.py and core/math.h `chi2`): histogram
the samples on a grid, integrate the claimed pdf over the same cells, pool cells whose expected
count is below 5, fail outright if a sample falls in a cell of expected count 0, and correct the
significance level for the number of tests with Sidak's formula.
"""
import numpy as np
from scipy import special
from scipy import stats as scipy_stats


def sidak_alpha(alpha, n_tests):
    """Per-test level so that n_tests independent tests together reject with probability alpha."""
    return float(-np.expm1(np.log1p(-alpha) / n_tests))  # 1 - (1 - alpha)^(1/n), no cancellation


# ----------------------------------------------------------------------------------------------
# Chi-square

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


def chi2_test(observed, expected, min_expected=5.0):
    """p-value of Pearson's chi-square test of observed counts against expected counts.

    observed, expected: arrays of the same shape (any rank), e.g. a histogram and the output of
    expected_counts_2d for the same grid. Cells with expected < min_expected are pooled. Returns
    0.0 (reject) if any sample fell in a cell whose expected count is 0. The expected counts are
    not rescaled to the observed total, so a pdf that does not integrate to 1 is caught too.
    """
    observed = np.asarray(observed, dtype=np.float64).ravel()
    expected = np.asarray(expected, dtype=np.float64).ravel()
    if observed.shape != expected.shape:
        raise ValueError(f"shape mismatch: {observed.shape} vs {expected.shape}")
    if np.any(expected < 0.0) or not np.all(np.isfinite(expected)):
        raise ValueError("expected counts must be finite and >= 0")
    if np.any((expected == 0.0) & (observed > 0.0)):
        return 0.0
    live = expected > 0.0
    o, e = _pool_low_cells(observed[live], expected[live], min_expected)
    dof = o.size - 1
    if dof < 1:
        raise ValueError("too few cells for a chi-square test; use more samples or cells")
    statistic = float(np.sum((o - e) ** 2 / e))
    return float(scipy_stats.chi2.sf(statistic, dof))


def _gauss_nodes(edges, order):
    """Gauss-Legendre nodes (cells * order,) and weights (same) for cells between edges."""
    edges = np.asarray(edges, dtype=np.float64)
    t, w = np.polynomial.legendre.leggauss(order)
    width = np.diff(edges)
    nodes = edges[:-1, None] + width[:, None] * (0.5 * (t + 1.0))[None, :]
    weights = width[:, None] * (0.5 * w)[None, :]
    return nodes.ravel(), weights.ravel()


def expected_counts_2d(density, x_edges, y_edges, n_samples, order=4):
    """Expected sample counts (nx, ny) on the grid x_edges x y_edges for n_samples draws.

    density(x, y) takes two broadcast (M, K) arrays and returns the pdf with respect to
    dx dy (include the Jacobian if the grid is in transformed coordinates, e.g. for
    directions over (cos theta, phi) the solid-angle pdf itself, since d omega = dcos dphi).
    Each cell is integrated with order x order Gauss-Legendre nodes; nodes are strictly inside
    cells, so a pdf that jumps on a cell edge is integrated correctly. The layout matches
    np.histogram2d(x, y, bins=[x_edges, y_edges])[0].
    """
    xs, wx = _gauss_nodes(x_edges, order)
    ys, wy = _gauss_nodes(y_edges, order)
    x, y = np.meshgrid(xs, ys, indexing="ij")
    values = np.asarray(density(x, y), dtype=np.float64) * wx[:, None] * wy[None, :]
    nx, ny = len(x_edges) - 1, len(y_edges) - 1
    return n_samples * values.reshape(nx, order, ny, order).sum(axis=(1, 3))


def expected_counts_1d(density, edges, n_samples, order=8):
    """Expected counts (n_cells,) for a 1D pdf density(x) over cells between edges (see 2D)."""
    x, w = _gauss_nodes(edges, order)
    values = np.asarray(density(x), dtype=np.float64) * w
    return n_samples * values.reshape(len(edges) - 1, order).sum(axis=1)


def spherical_coordinates(d):
    """(cos theta, phi in [0, 2 pi)) arrays (N,) of unit directions d (N, 3) around +z."""
    d = np.asarray(d, dtype=np.float64)
    phi = np.arctan2(d[:, 1], d[:, 0])
    return d[:, 2], np.where(phi < 0.0, phi + 2.0 * np.pi, phi)


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
