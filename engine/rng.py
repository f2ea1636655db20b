"""The only source of random numbers: a pure function of (seed, pixel, sample, dimension).

Every random number a path uses is a pure function of where it is used, so a render with
the same seed and settings gives the same image whatever the batch size, the number of
threads, or the render border (a border render equals the crop of the full frame).

Two patterns:

"random"  independent uniforms. The hash is SplitMix64's finaliser (Steele, Lea & Flood 2014)
          over a Weyl-sequence combination of the counters; the top 53 bits become a double.

"sobol"   (default) Owen-scrambled, shuffled Sobol points padded per 4D group, after
          B. Burley, "Practical Hash-based Owen Scrambling", JCGT 9(4), 2020 (what Cycles calls
          Sobol-Burley). For group `dim` of a pixel, the same SplitMix64 hash of (seed, pixel,
          dim) gives a 64-bit key h; the sample index (mod 2^32) is shuffled by a nested-uniform
          (Owen) scramble keyed by h's top 32 bits; lane j is Sobol dimension j of the shuffled
          index (j = 0 the van der Corput sequence, j = 1..3 Joe & Kuo's direction numbers),
          Owen-scrambled with a 32-bit hash of (h's low 32 bits, j). Within one pixel and
          group, samples c 2^m .. (c+1) 2^m - 1 are a scrambled (t, m, 4)-net (lanes 0 and 1 a
          (0, m, 2)-net); different pixels, groups and seeds are independent. Samples of one
          pixel are deliberately NOT independent: their sample variance overstates the
          variance of their mean.

Owen scrambling is done as in Burley's paper: in the bit-reversed domain, a hash whose output
bit i is input bit i XOR a function of the lower bits (Laine & Karras 2011, "Stratified sampling
for stochastic transparency"; constants of Burley's improved hash) is exactly a nested-uniform
permutation of the digits. The Sobol generator-matrix product is four byte-table gathers per
32-bit index (two lanes per 64-bit table entry). Bit reversal swaps bits, pairs and nibbles
with masks and then the bytes: in NumPy that is faster than four byte-table gathers
(bench/results/tail/report.md).
"""
import numpy as np

from .settings import DECLARED

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_K_SAMPLE = np.uint64(0xD1B54A32D192ED03)
_K_DIM = np.uint64(0xAEF17502108EF2D9)
_K_GROUP = np.uint64(0xDB4F0B9175AE2165)  # sobol: Weyl step per group (differs from _K_DIM)
_K_DOMAIN = np.uint64(0x8CB92BA72F3D8DD7)  # separates the streams of different domains

# Domains: independent streams for different kinds of paths. A camera path's numbers are those
# of domain 0 (unchanged since before domains existed); photon paths use pixel = photon path
# index within its pass and sample = pass; gather rays their own stream per camera sample;
# irradiance-cache records pixel = record index and sample = gather ray.
CAMERA, PHOTONS, GATHER, RECORDS = 0, 1, 2, 3

PATTERNS = DECLARED["pattern"].values


def _mix(x: np.ndarray) -> np.ndarray:
    x = (x ^ (x >> np.uint64(30))) * _M1
    x = (x ^ (x >> np.uint64(27))) * _M2
    return x ^ (x >> np.uint64(31))


# ----------------------------------------------------------------------------------------------
# Sobol generator matrices and byte tables

# Joe & Kuo, "Constructing Sobol sequences with better two-dimensional projections", SIAM J. Sci.
# Comput. 30 (2008), file new-joe-kuo-6.21201, dimensions 2..4 as (degree s, coefficients a,
# initial m_1..m_s). Dimension 1 (our lane 0) is the van der Corput sequence (all m_k = 1).
_JOE_KUO = ((1, 0, (1,)),        # x + 1
            (2, 1, (1, 3)),      # x^2 + x + 1
            (3, 1, (1, 3, 1)))   # x^3 + x + 1


def _direction_numbers(s: int, a: int, m_init) -> list:
    """32 direction numbers V_k = m_k 2^(32-k), k = 1..32 (Bratley & Fox 1988 recurrence):
    m_k = 2 a_1 m_(k-1) ^ 4 a_2 m_(k-2) ^ ... ^ 2^(s-1) a_(s-1) m_(k-s+1) ^ 2^s m_(k-s) ^ m_(k-s),
    for the primitive polynomial x^s + a_1 x^(s-1) + ... + a_(s-1) x + 1, a = a_1..a_(s-1) in binary."""
    m = list(m_init)
    for k in range(s, 32):
        v = m[k - s] ^ (m[k - s] << s)
        for i in range(1, s):
            if (a >> (s - 1 - i)) & 1:
                v ^= m[k - i] << i
        m.append(v)
    return [m[k] << (31 - k) for k in range(32)]


def _reverse32(v: int) -> int:
    return int(f"{v:032b}"[::-1], 2)


# Column c of lane j's matrix in the reversed domain: reverse(V_(c+1)), the contribution of
# index bit c to the bit-reversed Sobol coordinate. Lane 0: reverse(2^(31-c)) = 2^c.
_COLUMNS = [[1 << c for c in range(32)]] + [[_reverse32(v) for v in _direction_numbers(*jk)] for jk in _JOE_KUO]


def _byte_tables(columns_of_bit) -> np.ndarray:
    """(4, 256) uint32: table[p][b] = XOR of columns_of_bit(8p + t) over the set bits t of b."""
    t = np.zeros((4, 256), np.uint32)
    for p in range(4):
        for b in range(256):
            v = 0
            for bit in range(8):
                if (b >> bit) & 1:
                    v ^= columns_of_bit(8 * p + bit)
            t[p, b] = v
    return t


# The product is taken over the bit-reversed shuffled index r = reverse(index'): bit i of r is
# index bit 31 - i. _SOBOL_T[p, b, j] is lane j's reversed-domain contribution of r's byte p = b,
# so reverse(sobol_j(index')) = XOR_p _SOBOL_T[p, byte_p(r), j] with no reversal of the index.
_SOBOL_T = np.ascontiguousarray(np.stack([_byte_tables(lambda i, j=j: _COLUMNS[j][31 - i]) for j in range(4)], axis=-1))
# Lanes (0, 1) and (2, 3) packed in one 64-bit word, lane 2i in the low half: one gather, two lanes.
_SOBOL_T64 = [_SOBOL_T[:, :, 2 * i].astype(np.uint64) | (_SOBOL_T[:, :, 2 * i + 1].astype(np.uint64) << np.uint64(32))
              for i in range(2)]
_LANES = np.array([0x9E3779B9 * (j + 1) & 0xFFFFFFFF for j in range(4)], np.uint32)  # lane-key offsets

# The helpers below work in place with one scratch array `t` of x's dtype and shape: NumPy
# temporaries of this size are fresh pages from the allocator, and faulting them in costs as
# much as the arithmetic.


def _mix_(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """_mix(x) in place (uint64)."""
    x ^= np.right_shift(x, np.uint64(30), out=t)
    x *= _M1
    x ^= np.right_shift(x, np.uint64(27), out=t)
    x *= _M2
    x ^= np.right_shift(x, np.uint64(31), out=t)
    return x


def _hash32_(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """A 32-bit integer hash in place ("lowbias32", C. Wellons 2018, hash-prospector)."""
    x ^= np.right_shift(x, np.uint32(16), out=t)
    x *= np.uint32(0x7FEB352D)
    x ^= np.right_shift(x, np.uint32(15), out=t)
    x *= np.uint32(0x846CA68B)
    x ^= np.right_shift(x, np.uint32(16), out=t)
    return x


def _reverse_bits_(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Bit reversal of uint32 x in place: swap bits, pairs and nibbles with masks and shifts,
    then the bytes (in NumPy this beats four byte-table gathers: bench/results/tail/report.md)."""
    for shift, mask in ((1, 0x55555555), (2, 0x33333333), (4, 0x0F0F0F0F)):
        np.right_shift(x, np.uint32(shift), out=t)
        t &= np.uint32(mask)
        x &= np.uint32(mask)
        x <<= np.uint32(shift)
        x |= t
    return x.byteswap(inplace=True)


def _owen_reversed_(x: np.ndarray, key: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Nested-uniform (Owen) scramble, keyed by key, of bit-reversed uint32 values x, in place.

    Burley 2020, section 3 (his improved Laine-Karras hash): each step (x ^= x * even,
    x += key, x *= odd) leaves bit i equal to itself XOR a function of bits 0..i-1 only, which
    in the reversed domain flips each digit by a function of the more significant digits: a
    nested-uniform permutation. Uses t as scratch (and clobbers it)."""
    x ^= np.multiply(x, np.uint32(0x3D20ADEA), out=t)
    x += key
    np.right_shift(key, np.uint32(16), out=t)
    t |= np.uint32(1)
    x *= t
    x ^= np.multiply(x, np.uint32(0x05526C56), out=t)
    x ^= np.multiply(x, np.uint32(0x53A22864), out=t)
    return x


def _sobol_of_reversed_index(r: np.ndarray, k: int, work=None) -> np.ndarray:
    """(N, k) uint32: lanes 0..k-1 of the bit-reversed Sobol point whose bit-reversed index is r:
    per pair of lanes, four byte-table gathers XORed (a GF(2) matrix-vector product).
    work(name, dtype, size) supplies scratch arrays (default: new ones)."""
    work = work or (lambda name, dtype, size: np.empty(size, dtype))
    n, pairs = len(r), (k + 1) // 2
    r_bytes = r.astype("<u4", copy=False).view(np.uint8).reshape(n, 4)  # byte p = bits 8p..8p+7
    b = work("byte", np.intp, n)
    y = work("sobol", "<u8", n * pairs).reshape(n, pairs)
    acc, t = work("acc", np.uint64, n), work("t64", np.uint64, n)
    for i in range(pairs):
        for p in range(4):
            b[:] = r_bytes[:, p]
            if p == 0:
                np.take(_SOBOL_T64[i][0], b, out=acc, mode="clip")
            else:
                acc ^= np.take(_SOBOL_T64[i][p], b, out=t, mode="clip")
        y[:, i] = acc
    return y.view("<u4")[:, :k]  # lane 2i is the low half of pair i


def _reverse_bits(x) -> np.ndarray:
    x = np.array(x, np.uint32)
    return _reverse_bits_(x, np.empty_like(x))


def sobol_reversed(index, k: int = 4) -> np.ndarray:
    """Unscrambled Sobol points, bit-reversed: (N, k) uint32, reverse of the 32-bit coordinate.

    Exposed for tests (compare with scipy.stats.qmc.Sobol(scramble=False))."""
    return _sobol_of_reversed_index(_reverse_bits(index), k)


class Sampler:
    """Uniform numbers for a batch of N paths, path i belonging to (pixel[i], sample[i]) of
    stream `domain` (CAMERA, PHOTONS, GATHER, RECORDS: independent of each other).

    `get(dim, rows=None, k=1)` returns float64 in [0, 1), shape (len(rows),) for k = 1 or
    (len(rows), k), for the paths `rows` (all when None). Dimensions are small integers the
    integrator assigns (e.g. 8 * bounce + purpose); a k-vector (k <= 4) is group `dim`, lanes
    dim*4 .. dim*4+k-1; `get(dim, rows, lanes=(0, 1, 3))` computes and returns only those
    lanes (a caller that does not use lane 2), with the same values. With pattern "sobol" the
    lanes of one group are jointly stratified over a pixel's samples (put quantities sampled
    together in one group); "random" is i.i.d.
    """

    def __init__(self, seed: int, pixel: np.ndarray, sample: np.ndarray, pattern: str = "sobol",
                 domain: int = CAMERA):
        if pattern not in PATTERNS:
            raise ValueError(f"unknown sampling pattern {pattern!r} (expected one of {PATTERNS})")
        self.pattern = pattern
        with np.errstate(over="ignore"):
            key = _mix(np.uint64(seed & 0xFFFFFFFFFFFFFFFF) * _GOLDEN + _GOLDEN)
            if domain != CAMERA:
                key = _mix(key ^ (np.uint64(domain) * _K_DOMAIN))
            pixel_key = _mix(key ^ (np.asarray(pixel, np.uint64) * _GOLDEN))
            if pattern == "random":
                self.key = pixel_key ^ (np.asarray(sample, np.uint64) * _K_SAMPLE)
            else:
                index = (np.asarray(sample, np.uint64) & np.uint64(0xFFFFFFFF)).astype(np.uint32)
                pixel_key, index = np.broadcast_arrays(np.atleast_1d(pixel_key), np.atleast_1d(index))
                self.key = pixel_key.copy()
                self.index_r = _reverse_bits(index)  # bit-reversed sample index (a copy)
                self._scratch = {}  # see _work: one Sampler serves one thread

    def branched(self, branch: int, branches: int) -> "Sampler":
        """The sampler of branch `branch` of `branches` taken at each path's sample (Cycles'
        path_branched_rng: several rays from one shading point): its sample index becomes
        sample * branches + branch, so under "sobol" the branches of one sample are
        stratified together with the pixel's other samples; under "random" each branch is an
        independent stream."""
        out = object.__new__(Sampler)
        out.pattern = self.pattern
        with np.errstate(over="ignore"):
            if self.pattern == "random":
                out.key = _mix(self.key ^ (np.uint64(branch + 1) * _K_GROUP))
                return out
            out.key = self.key
            index = _reverse_bits(self.index_r) * np.uint32(branches) + np.uint32(branch)
            out.index_r = _reverse_bits(index)
        out._scratch = {}
        return out

    def get(self, dim: int, rows=None, k: int = 1, lanes=None) -> np.ndarray:
        """lanes: the lanes of the group to return, increasing (e.g. (0, 1, 3)), instead of
        the first k; the result is then (len(rows), len(lanes)). Only those are computed."""
        if not 1 <= k <= 4:
            raise ValueError(f"k must be 1..4 (got {k})")
        one = lanes is None and k == 1
        lanes = tuple(range(k)) if lanes is None else tuple(lanes)
        if not lanes or list(lanes) != sorted(set(lanes)) or not 0 <= lanes[0] <= lanes[-1] <= 3:
            raise ValueError(f"lanes must be increasing lane numbers 0..3 (got {lanes})")
        if self.pattern == "sobol":
            u = self._get_sobol(dim, rows, lanes)
            return u[:, 0] if one else u
        key = self.key if rows is None else self.key[rows]
        u = np.empty((len(key), len(lanes)))
        with np.errstate(over="ignore"):
            for j, lane in enumerate(lanes):  # at most 4 columns, each a contiguous pass over the keys
                x = _mix(key + np.uint64(4 * dim + lane) * _K_DIM)
                u[:, j] = (x >> np.uint64(11)).astype(np.float64)
        u *= 1.0 / 9007199254740992.0
        return u[:, 0] if one else u

    def _work(self, name: str, dtype, size: int) -> np.ndarray:
        """Scratch array `name` of at least `size` elements, kept between calls: NumPy's large
        temporaries otherwise come back from the allocator as fresh pages on every call, and
        faulting them in costs more than the arithmetic."""
        a = self._scratch.get(name)
        if a is None or len(a) < size:
            a = self._scratch[name] = np.empty(size, dtype)
        return a[:size]

    def _get_sobol(self, dim: int, rows, lanes: tuple) -> np.ndarray:
        """(N, len(lanes)) uniforms of lanes `lanes` of group dim."""
        key = self.key if rows is None else self.key[rows]
        n = len(key)
        kk = len(lanes)
        work = self._work
        r = work("index", np.uint32, n)
        r[:] = self.index_r if rows is None else self.index_r[rows]
        with np.errstate(over="ignore"):
            h = np.add(key, np.uint64(dim + 1) * _K_GROUP, out=work("h", np.uint64, n))
            t64 = work("t64", np.uint64, n)
            _mix_(h, t64)  # the group's 64-bit hash of (seed, pixel, dim)
            shuffle_key, lane_key = work("shuffle_key", np.uint32, n), work("lane_key", np.uint32, n * kk)
            shuffle_key[:] = h  # the low 32 bits
            t = work("t32", np.uint32, n * kk)
            # Lane keys: a 32-bit hash of (low half of h, lane), laid out (n, kk) like the
            # output, so that the scramble runs over one flat array.
            for j, lane in enumerate(lanes):  # one strided pass per lane (a broadcast (n, kk) op is slower)
                np.bitwise_xor(shuffle_key, _LANES[lane], out=lane_key.reshape(n, kk)[:, j])
            _hash32_(lane_key, t)
            shuffle_key[:] = np.right_shift(h, np.uint64(32), out=t64[:n])  # the high 32 bits
            _owen_reversed_(r, shuffle_key, t[:n])  # shuffled sample index, bit-reversed
            if lanes == (0,):  # van der Corput: its reversed coordinate is the shuffled index itself
                y = _reverse_bits_(r, t[:n])
            else:
                points = _sobol_of_reversed_index(r, lanes[-1] + 1, work)
                if points.flags.c_contiguous and lanes == tuple(range(points.shape[1])):
                    y = points.ravel()  # all lanes of whole pairs: already one flat array
                else:  # the lanes asked for, side by side (the scrambles below run on these only)
                    y = work("lanes", np.uint32, n * kk)
                    for j, lane in enumerate(lanes):
                        y.reshape(n, kk)[:, j] = points[:, lane]
            _owen_reversed_(y, lane_key, t)
            _reverse_bits_(y, t)
        u = y.astype(np.float64)
        u *= 2.0 ** -32  # y <= 2^32 - 1, so u < 1 exactly
        return u.reshape(n, kk)


def animated_seed(seed: int, frame: int, subframe: float = 0.0) -> int:
    """The seed of frame `frame` when the noise pattern is animated (Cycles' use_animated_seed:
    a hash of the frame and the seed, plus one of the subframe; intern/cycles/blender/sync.cpp).
    Our own hash (SplitMix64), so the values differ from Cycles'; a seed in 0 .. 2^31 - 1."""
    mask = (1 << 64) - 1

    def mix(a: int, b: int) -> int:
        return int(_mix(np.array([(a * int(_GOLDEN) ^ b * int(_K_SAMPLE)) & mask], np.uint64))[0])

    h = mix(seed, frame & 0xFFFFFFFF)
    if subframe:
        h ^= mix(seed + 1, int(subframe * 0x7FFFFFFF) & 0xFFFFFFFF)
    return h >> 33
