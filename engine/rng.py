"""The only source of random numbers: counter-based streams keyed by (seed, pass, batch).

Each (dimension) of a batch draws from its own Philox stream, so a render with the same
seed and settings is reproducible whatever the thread scheduling or batch completion order.
"""
import numpy as np

_MASK32 = (1 << 32) - 1


class Sampler:
    """Uniform numbers for one batch of one pass.

    `get(dim, shape)` returns float64 in [0, 1); the same (seed, pass, batch, dim) always
    gives the same numbers. Dimensions are small integers chosen by the integrator
    (e.g. 16 * bounce + purpose).
    """

    def __init__(self, seed: int, pass_index: int, batch_index: int):
        self.key = np.array([seed & ((1 << 64) - 1), ((pass_index & _MASK32) << 32) | (batch_index & _MASK32)],
                            dtype=np.uint64)

    def get(self, dim: int, shape) -> np.ndarray:
        # The counter's top word is the dimension: streams never overlap (2^192 draws apart).
        bitgen = np.random.Philox(key=self.key, counter=np.array([0, 0, 0, dim], dtype=np.uint64))
        u = np.random.Generator(bitgen).random(shape)
        return np.minimum(u, 1.0 - 2.0**-53)
