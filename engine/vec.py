"""Row-wise 3-vector helpers for (N,3) arrays.

NumPy is slow on the short axis of (N,3) arrays: axis=1 reductions, (N,1) broadcasts and
a[idx] row gathers each run several times slower than the
component-wise forms below, and these run on every live ray at every bounce.
"""
import numpy as np


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def max3(a: np.ndarray) -> np.ndarray:
    return np.maximum(np.maximum(a[:, 0], a[:, 1]), a[:, 2])


def length(a: np.ndarray) -> np.ndarray:
    return np.sqrt(dot(a, a))


def normalize(a: np.ndarray) -> np.ndarray:
    n = length(a)
    return scale(a, 1.0 / np.where(n > 0, n, 1.0))


def take(a: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """a[rows] for (N,...) arrays; np.take is several times faster than fancy indexing on (N,3)."""
    return np.take(a, rows, axis=0)


def gatherer(rows: np.ndarray, n: int):
    """A function a -> a[rows] for arrays of n rows; the identity (no copy) when rows are
    0 .. n-1 in order - the common case in a batch (rows may also repeat: gather rays)."""
    everyone = len(rows) == n and (n == 0 or (rows[0] == 0 and rows[-1] == n - 1
                                               and bool(np.all(np.diff(rows) == 1))))
    return (lambda a: a) if everyone else (lambda a: take(a, rows))


def scale(v: np.ndarray, s) -> np.ndarray:
    """v * s[:, None] for v (N,k), s (N,), one contiguous pass per column."""
    if len(v) < 4096:  # small: one broadcast beats three calls
        return v * np.asarray(s)[:, None]
    out = np.empty(v.shape, np.result_type(v, s))
    for k in range(v.shape[1]):
        np.multiply(v[:, k], s, out=out[:, k])
    return out


def interpolate(b: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """sum_j b[:, j] corners[:, j] for barycentrics b (N,3) and corner vectors (N,3,3)."""
    out = np.empty((len(b), 3))
    b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    for k in range(3):
        out[:, k] = b0 * corners[:, 0, k] + b1 * corners[:, 1, k] + b2 * corners[:, 2, k]
    return out


def minus_point(v: np.ndarray, c: np.ndarray) -> np.ndarray:
    """v - c for v (N,3) and one point c (3,), column by column."""
    out = np.empty(v.shape)
    for k in range(3):
        np.subtract(v[:, k], c[k], out=out[:, k])
    return out
