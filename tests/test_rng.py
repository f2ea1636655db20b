"""The sampler: counter-based, reproducible; "random" i.i.d. uniforms, "sobol" (the default)
Owen-scrambled Sobol nets per pixel and 4D group (Burley 2020), independent across pixels,
groups and seeds."""
import itertools

import numpy as np
import pytest
from scipy.stats import qmc

from ember.engine import rng
from ember.engine.rng import Sampler

from stats import Box, ChiSquareTest, Interval

N = 200_000
PATTERNS = ("random", "sobol")


def _uniform(points, cells, alpha=0.01, n_tests=1, name=""):
    """Chi-square test that points (N,) or (N, 2) are uniform on [0, 1) or [0, 1)^2, on `cells`
    cells per axis (the samples are the sampler's, not drawn by the test)."""
    domain = Interval() if np.ndim(points) == 1 else Box()
    test = ChiSquareTest(domain, None, lambda p: np.ones(len(p)), cells, name=name)
    test.fit(points, alpha=alpha, n_tests=n_tests).check()


def _ints(u):
    """The 32-bit integers x of u = x 2^-32 (exact for both patterns' top 32 bits)."""
    return np.floor(np.asarray(u) * 2.0 ** 32).astype(np.uint64)


@pytest.mark.parametrize("pattern", PATTERNS)
def test_uniform_and_reproducible(pattern):
    s = Sampler(3, np.arange(N), np.zeros(N, np.int64), pattern=pattern)
    u = s.get(5)
    assert np.array_equal(u, Sampler(3, np.arange(N), np.zeros(N, np.int64), pattern=pattern).get(5))
    assert u.min() >= 0 and u.max() < 1
    _uniform(u, 100, alpha=0.001)


def test_default_pattern_is_sobol_and_unknown_patterns_are_refused():
    pix, smp = np.arange(100), np.arange(100) % 9
    assert Sampler(4, pix, smp).pattern == "sobol"
    assert np.array_equal(Sampler(4, pix, smp).get(3, None, 2), Sampler(4, pix, smp, pattern="sobol").get(3, None, 2))
    with pytest.raises(ValueError):
        Sampler(4, pix, smp, pattern="halton")
    with pytest.raises(ValueError):
        Sampler(4, pix, smp).get(0, None, 5)


def test_random_pattern_is_bit_identical_to_the_original_hash():
    """Values of the hash before the sobol pattern existed (engine/rng.py at f2cf822)."""
    s = Sampler(3, np.array([0, 1, 7, 123456, 2 ** 40]), np.array([0, 1, 2, 3, 1000]), pattern="random")
    assert s.get(7, None, 2).tolist() == [
        [0.6771318336778597, 0.17598616405274947], [0.43860937625220275, 0.8874405800833465],
        [0.6356834101725098, 0.7084025612330167], [0.09779700853320838, 0.7785481153772466],
        [0.19836795539512153, 0.4297357425563212]]
    assert s.get(0).tolist() == [0.3109076049360566, 0.6727223789352273, 0.7887110142473744,
                                 0.18651335209015885, 0.08323264925243468]


def test_sobol_pattern_is_bit_identical_to_its_first_version():
    """Values of the sobol pattern at engine/rng.py 135df2f: a faster sampler must give the
    same bits (images stay what they were)."""
    s = Sampler(3, np.array([0, 1, 7, 123456, 2 ** 40]), np.array([0, 1, 2, 3, 1000]))
    assert s.get(7, None, 3).tolist() == [
        [0.007405028911307454, 0.9722435381263494, 0.34444643603637815],
        [0.5396089015994221, 0.6841827356256545, 0.38628662237897515],
        [0.06817276054061949, 0.06660643056966364, 0.06647710036486387],
        [0.78020412591286, 0.6039362289011478, 0.15751063078641891],
        [0.43584780883975327, 0.05474567832425237, 0.06451415992341936]]
    assert s.get(0).tolist() == [0.22639632457867265, 0.10963255539536476, 0.8298620842397213,
                                 0.9109741665888578, 0.26252230000682175]
    assert s.get(2, np.array([4, 0]), 4).tolist() == [
        [0.4718870078213513, 0.5079844375140965, 0.6661957751493901, 0.39693783479742706],
        [0.22128951223567128, 0.8072459315881133, 0.8151762357447296, 0.5873466767370701]]


@pytest.mark.parametrize("pattern", PATTERNS)
def test_dimensions_samples_and_neighbouring_pixels_are_independent(pattern):
    """Pairs (u_a, u_b) that differ in one counter fill the unit square uniformly (20x20 chi-square).
    Not "next sample" for sobol: a pixel's samples are deliberately stratified against each other."""
    pix = np.arange(N)
    s0 = Sampler(1, pix, np.zeros(N, np.int64), pattern=pattern)
    s1 = Sampler(1, pix, np.ones(N, np.int64), pattern=pattern)
    pairs = [(s0.get(0), s0.get(1)),  # next dimension
             (s0.get(2, None, 2)[:, 0], s0.get(2, None, 2)[:, 1]),  # lanes of one vector
             (s0.get(0)[:-1], s0.get(0)[1:]),  # next pixel
             (s0.get(0), Sampler(2, pix, np.zeros(N, np.int64), pattern=pattern).get(0))]  # next seed
    if pattern == "random":
        pairs.append((s0.get(0), s1.get(0)))  # next sample
    for k, (a, b) in enumerate(pairs):
        _uniform(np.stack([a, b], axis=1), 20, n_tests=len(pairs), name=f"pair {k}")


@pytest.mark.parametrize("pattern", PATTERNS)
def test_rows_batching_and_k_do_not_change_values(pattern):
    """A value depends only on (seed, pixel, sample, dim, lane, pattern): not on which rows are
    asked for, how the paths are batched or ordered, or how many lanes are asked for."""
    gen = np.random.default_rng(0)
    pix, smp = gen.integers(0, 10 ** 6, 1000), gen.integers(0, 5000, 1000)
    s = Sampler(0, pix, smp, pattern=pattern)
    rows = np.array([7, 2, 999, 2])
    mask = gen.random(1000) < 0.5
    perm = gen.permutation(1000)
    for k in (1, 2, 3, 4):
        full = s.get(4, None, k)
        assert full.shape == ((1000,) if k == 1 else (1000, k)) and full.flags.c_contiguous
        for r in (rows, mask, slice(100, 200), np.array([], np.int64)):
            assert np.array_equal(s.get(4, r, k), full[r])
        assert np.array_equal(s.get(4, None, k), full)  # asking for a slice left the state alone
        assert np.array_equal(Sampler(0, pix[perm], smp[perm], pattern=pattern).get(4, None, k), full[perm])
        assert np.array_equal(Sampler(0, pix[300:], smp[300:], pattern=pattern).get(4, None, k), full[300:])
        assert np.array_equal(full if k == 1 else full[:, 0], s.get(4, None, 1))
        if k > 1:
            assert np.array_equal(full[:, :2], s.get(4, None, 2)[:, :k])
    full = s.get(4, None, 4)
    for lanes in ((0, 1, 3), (1,), (2, 3), (0, 2), (3,), (0, 1, 2, 3)):  # only these lanes, the same values
        assert np.array_equal(s.get(4, None, lanes=lanes), full[:, list(lanes)]), lanes
        assert np.array_equal(s.get(4, rows, lanes=lanes), full[rows][:, list(lanes)]), lanes
    with pytest.raises(ValueError):
        s.get(4, None, lanes=(3, 1))


# ----------------------------------------------------------------------------------------------
# The sobol pattern: nets within a pixel

def _t_value(x, m):
    """Smallest t such that the 2^m points x ((2^m, s) 32-bit integers) are a (t, m, s)-net in
    base 2: every elementary interval of volume 2^(t-m) holds exactly 2^t points."""
    s = x.shape[1]
    for t in range(m + 1):
        q = m - t
        ok = True
        for shape in itertools.product(range(q + 1), repeat=s):  # 2^a_1 x ... x 2^a_s cells
            if sum(shape) != q:
                continue
            cell = np.zeros(len(x), np.int64)
            for d, a in enumerate(shape):
                cell = (cell << a) | (x[:, d] >> np.uint64(32 - a)).astype(np.int64) if a else cell
            if not (np.bincount(cell, minlength=1 << q) == 1 << t).all():
                ok = False
                break
        if ok:
            return t
    return None


def _sobol_reference(m):
    """The first 2^m points of Sobol dimensions 1..4 (scipy, Joe-Kuo numbers) as 32-bit integers."""
    return _ints(qmc.Sobol(4, scramble=False, bits=32).random_base2(m))


def test_unscrambled_sobol_matches_scipy():
    """Direction numbers computed from Joe & Kuo's polynomials and initial m: the same points as
    scipy's Sobol (which enumerates in Gray-code order: point i is our point i ^ (i >> 1))."""
    i = np.arange(1 << 14)
    ours = rng.sobol_reversed(i ^ (i >> 1), 4)
    ours = np.stack([rng._reverse_bits(ours[:, j]) for j in range(4)], axis=1).astype(np.uint64)
    assert np.array_equal(ours, _sobol_reference(14))


def test_owen_scramble_is_a_nested_uniform_permutation():
    """In the reversed domain, output bit i is input bit i XOR a function of input bits 0..i-1:
    low bits map through a bijection of themselves, and flipping bit i flips output bit i only
    at and above i."""
    gen = np.random.default_rng(5)
    x = gen.integers(0, 2 ** 32, 50_000, dtype=np.uint64).astype(np.uint32)
    key = gen.integers(0, 2 ** 32, 50_000, dtype=np.uint64).astype(np.uint32)
    scr = lambda v: rng._owen_reversed_(v.copy(), key, np.empty_like(v))
    y = scr(x)
    with np.errstate(over="ignore"):
        for i in range(32):
            low = np.uint32((1 << i) - 1)
            bit = np.uint32(1 << i)
            y2 = scr(x ^ bit)
            assert np.array_equal(y2 & low, y & low)  # lower bits do not see bit i
            assert np.array_equal((y2 ^ y) & bit, np.full_like(y, bit))  # bit i flips
            assert np.array_equal(scr(x & low) & low, y & low)  # nor any higher bit


# t-values of the first 2^m points of Sobol dimensions (1, 2, 3, 4), m = 4..10, for the lane
# pairs and all four lanes; scrambling keeps them exactly (any aligned block of 2^m points of a
# digital sequence is a digitally shifted copy of the first, and Owen scrambling maps
# elementary intervals onto elementary intervals). The upper bounds are the sequence's t-value
# sum(degree - 1) over the lanes' primitive polynomials (degrees 1, 1, 2, 3).
NET_LANES = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3), (0, 1, 2, 3)]
T_BOUND = {(0, 1): 0, (0, 2): 1, (0, 3): 2, (1, 2): 1, (1, 3): 2, (2, 3): 3, (0, 1, 2, 3): 3}


def test_reference_t_values_are_within_the_sequence_bounds():
    for m in range(4, 11):
        x = _sobol_reference(m)
        for lanes in NET_LANES:
            assert _t_value(x[:, lanes], m) <= T_BOUND[lanes], (m, lanes)
        assert _t_value(x[:, [0, 1]], m) == 0


@pytest.mark.parametrize("seed, pixel, dim", [(0, 0, 0), (7, 123457, 3), (2 ** 40 + 1, 5, 29)])
def test_sobol_samples_of_a_pixel_are_scrambled_nets(seed, pixel, dim):
    """Samples 0..2^m-1 and 3*2^m..4*2^m-1 of one pixel and group, m = 4..10: each lane alone is
    exactly stratified into 2^m intervals, lanes (0, 1) are a (0, m, 2)-net (every elementary
    interval of area 2^-m, all shapes, holds exactly one point), and the other lane pairs and
    all four lanes have exactly the unscrambled Sobol net's t-value."""
    for m in range(4, 11):
        ref = _sobol_reference(m)
        for start in (0, 3 << m):
            smp = np.arange(start, start + (1 << m))
            x = _ints(Sampler(seed, np.full(1 << m, pixel), smp).get(dim, None, 4))
            for j in range(4):
                assert np.array_equal(np.sort(x[:, j] >> np.uint64(32 - m)), np.arange(1 << m)), (m, j)
            assert _t_value(x[:, [0, 1]], m) == 0, m
            for lanes in NET_LANES:
                assert _t_value(x[:, lanes], m) == _t_value(ref[:, lanes], m), (m, lanes)


def test_sobol_lanes_are_uniform_over_pixels():
    """Any sample index, across pixels: each of the 4 lanes is uniform (100-bin chi-square) and
    each pair of lanes fills the square (20x20), with sample indices drawn over 0..2^20."""
    gen = np.random.default_rng(1)
    u = Sampler(9, np.arange(N), gen.integers(0, 1 << 20, N)).get(6, None, 4)
    assert u.min() >= 0 and u.max() < 1
    pairs = list(itertools.combinations(range(4), 2))
    for j in range(4):
        _uniform(u[:, j], 100, n_tests=4 + len(pairs), name=f"lane {j}")
    for i, j in pairs:
        _uniform(u[:, [i, j]], 20, n_tests=4 + len(pairs), name=f"lanes {i}, {j}")


def test_sobol_groups_and_seeds_are_padded_independently():
    """Within each pixel, over its samples, different groups (and different seeds) are
    scrambled independently: pairs of them fill the square (20x20 chi-square; each coordinate
    alone is stratified, which only makes the test conservative). Equal keys would put the
    pairs on a line."""
    pixels, n = 64, 4096
    pix, smp = np.repeat(np.arange(pixels), n), np.tile(np.arange(n), pixels)
    s = Sampler(5, pix, smp)
    a, b = s.get(1, None, 2), s.get(2, None, 2)
    pairs = [(a[:, 0], b[:, 0]), (a[:, 1], b[:, 1]), (a[:, 0], b[:, 1]), (a[:, 0], s.get(9)),
             (a[:, 0], Sampler(6, pix, smp).get(1))]
    for k, (x, y) in enumerate(pairs):
        _uniform(np.stack([x, y], axis=1), 20, n_tests=len(pairs), name=f"pair {k}")


# ----------------------------------------------------------------------------------------------
# Convergence of per-pixel estimates (bench/rng_study.py prints the full tables)

def _rms_errors(pattern, f, exact, n_max, pixels, seed=11, dim=2):
    """RMS over pixels of the error of the mean of each pixel's first N samples, N = 1, 2 .. n_max."""
    pix, smp = np.repeat(np.arange(pixels), n_max), np.tile(np.arange(n_max), pixels)
    u = Sampler(seed, pix, smp, pattern=pattern).get(dim, None, 2)
    v = f(u[:, 0], u[:, 1]).reshape(pixels, n_max)
    ns = 2 ** np.arange(int(np.log2(n_max)) + 1)
    return ns, np.array([np.sqrt(np.mean((v[:, :n].mean(axis=1) - exact) ** 2)) for n in ns])


def _slope(ns, e, lo, hi):
    m = (ns >= lo) & (ns <= hi)
    return np.polyfit(np.log(ns[m]), np.log(e[m]), 1)[0]


def test_sobol_integrates_a_smooth_function_much_better():
    """f = exp(-x) sin(3y) + xy, 256 samples per pixel, 2000 pixels: the sobol error is a small
    fraction of random's, and over N = 16..1024 it falls close to Owen's N^-1.5 for smooth
    integrands, random's as N^-1/2 (the measured errors and slopes:
    bench/results/full/code_choices.md)."""
    exact = (1 - np.exp(-1)) * (1 - np.cos(3)) / 3 + 0.25
    f = lambda x, y: np.exp(-x) * np.sin(3 * y) + x * y
    ns, e_sobol = _rms_errors("sobol", f, exact, 1024, 2000)
    _, e_random = _rms_errors("random", f, exact, 1024, 2000)
    at = list(ns).index(256)
    assert e_sobol[at] < 0.05 * e_random[at]
    assert _slope(ns, e_sobol, 16, 1024) < -1.2
    assert -0.6 < _slope(ns, e_random, 16, 1024) < -0.4


def test_sobol_error_on_a_discontinuous_function_falls_faster_than_monte_carlo():
    """Indicator of the disk of radius 0.4 at (0.5, 0.5), 2000 pixels: the RMS error over
    N = 16..1024 falls about as Owen's N^-3/4 for discontinuities under sobol, as N^-1/2 under
    random (the measured slopes: bench/results/full/code_choices.md)."""
    exact = np.pi * 0.16
    f = lambda x, y: ((x - 0.5) ** 2 + (y - 0.5) ** 2 < 0.16).astype(np.float64)
    ns, e_sobol = _rms_errors("sobol", f, exact, 1024, 2000)
    _, e_random = _rms_errors("random", f, exact, 1024, 2000)
    assert _slope(ns, e_sobol, 16, 1024) < -0.65
    assert -0.6 < _slope(ns, e_random, 16, 1024) < -0.4
    assert e_sobol[-1] < 0.3 * e_random[-1]
