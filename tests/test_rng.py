"""The counter-based sampler: uniform, independent across dimensions and paths, reproducible."""
import numpy as np
from scipy import stats as st

from ember.engine.rng import Sampler

N = 200_000


def test_uniform_and_reproducible():
    s = Sampler(3, np.arange(N), np.zeros(N, np.int64))
    u = s.get(5)
    assert np.array_equal(u, Sampler(3, np.arange(N), np.zeros(N, np.int64)).get(5))
    assert u.min() >= 0 and u.max() < 1
    counts, _ = np.histogram(u, bins=100, range=(0, 1))
    assert st.chisquare(counts).pvalue > 0.001


def test_dimensions_samples_and_neighbouring_pixels_are_independent():
    """Pairs (u_a, u_b) that differ in one counter fill the unit square uniformly (20x20 chi-square)."""
    pix = np.arange(N)
    s0 = Sampler(1, pix, np.zeros(N, np.int64))
    s1 = Sampler(1, pix, np.ones(N, np.int64))
    pairs = [(s0.get(0), s0.get(1)),  # next dimension
             (s0.get(2, None, 2)[:, 0], s0.get(2, None, 2)[:, 1]),  # lanes of one vector
             (s0.get(0), s1.get(0)),  # next sample
             (s0.get(0)[:-1], s0.get(0)[1:]),  # next pixel
             (s0.get(0), Sampler(2, pix, np.zeros(N, np.int64)).get(0))]  # next seed
    alpha = 1 - 0.99 ** (1 / len(pairs))
    for a, b in pairs:
        h, _, _ = np.histogram2d(a, b, bins=20, range=[[0, 1], [0, 1]])
        assert st.chisquare(h.ravel()).pvalue > alpha


def test_rows_select_paths():
    s = Sampler(0, np.arange(10), np.zeros(10, np.int64))
    rows = np.array([7, 2])
    assert np.array_equal(s.get(4, rows, 2), s.get(4, None, 2)[rows])
