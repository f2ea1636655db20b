"""The only source of random numbers: a counter-based hash of (seed, pixel, sample, dimension).

Every random number a path uses is a pure function of where it is used, so a render with
the same seed and settings gives the same image whatever the batch size, the number of
threads, or the render border (a border render equals the crop of the full frame).
The hash is SplitMix64's finaliser (Steele, Lea & Flood 2014) over a Weyl-sequence
combination of the counters; the top 53 bits become a double in [0, 1).
"""
import numpy as np

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_K_SAMPLE = np.uint64(0xD1B54A32D192ED03)
_K_DIM = np.uint64(0xAEF17502108EF2D9)


def _mix(x: np.ndarray) -> np.ndarray:
    x = (x ^ (x >> np.uint64(30))) * _M1
    x = (x ^ (x >> np.uint64(27))) * _M2
    return x ^ (x >> np.uint64(31))


class Sampler:
    """Uniform numbers for a batch of N paths, path i belonging to (pixel[i], sample[i]).

    `get(dim, rows=None, k=1)` returns float64 in [0, 1), shape (len(rows),) for k = 1 or
    (len(rows), k), for the paths `rows` (all when None). Dimensions are small integers the
    integrator assigns (e.g. 8 * bounce + purpose); a k-vector uses dims dim*4 .. dim*4+k-1.
    """

    def __init__(self, seed: int, pixel: np.ndarray, sample: np.ndarray):
        with np.errstate(over="ignore"):
            key = _mix(np.uint64(seed & 0xFFFFFFFFFFFFFFFF) * _GOLDEN + _GOLDEN)
            self.key = _mix(key ^ (np.asarray(pixel, np.uint64) * _GOLDEN)) ^ (np.asarray(sample, np.uint64) * _K_SAMPLE)

    def get(self, dim: int, rows=None, k: int = 1) -> np.ndarray:
        key = self.key if rows is None else self.key[rows]
        u = np.empty((len(key), k))
        with np.errstate(over="ignore"):
            for lane in range(k):  # k <= 4 columns, each a contiguous pass over the keys
                x = _mix(key + np.uint64(4 * dim + lane) * _K_DIM)
                u[:, lane] = (x >> np.uint64(11)).astype(np.float64)
        u *= 1.0 / 9007199254740992.0
        return u[:, 0] if k == 1 else u
