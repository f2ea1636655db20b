"""Regenerate engine/bsdf/sheen_ltc.npz, the microfiber sheen's LTC table (engine/bsdf/sheen.py).

    ./dev python tools/sheen_table.py [--paths 200000] [--seed 0] [--objective likelihood|l3]

The reference is Zeltner, Burley & Chiang's (2022) volumetric sheen: a slab of unit thickness
and density 1 of fibre-like SGGX microflakes (fibres along the normal, cross section
sigma = roughness^2; Heitz et al. 2015, "The SGGX Microflake Distribution") with specular
flakes of albedo 1, light entering from the top and walked for at most 16 scattering events;
a walk that stops while still inside counts as leaving along its last direction, as in the
paper's fitting code. At each node of the 32 x 32 grid over (roughness, mu) (both max(0.01,
k / 31), as the paper's) R is the fraction of walks that come out of the top, and (a, b)
the LTC most likely to have produced their exit directions (maximum likelihood, Nelder-Mead,
warm-started from the next rougher node). --objective l3 fits instead as the paper does (the
L3 distance between R x the LTC density and a histogram of the exit directions on 32 x 32
cells of (theta, phi)), spikes between neighbours smoothed (despike): closer to Cycles' own
table on average but noisier from node to node at these walk counts, and further from
Cycles' renders (bench/results/closures/coat_sheen.md), so the table is the likelihood fit.
"""
from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np
from scipy.optimize import minimize

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import _bootstrap  # noqa: E402

_bootstrap.load_ember()
from ember.engine.bsdf import sheen  # noqa: E402

MAX_BOUNCES = 16


def _quad(a, b, s2):
    """a^T S b for S = diag(1, 1, s2) (fibres along z), rows of a, b (N,3)."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + s2 * a[:, 2] * b[:, 2]


def _basis(n):
    """Two unit vectors (N,3) completing n (N,3) to an orthonormal frame (Duff et al. 2017)."""
    sign = np.where(n[:, 2] >= 0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = np.stack([1 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], axis=1)
    s = np.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], axis=1)
    return t, s


def projected_area(w, s2):
    """SGGX sigma(w) = sqrt(w^T S w) (N,)."""
    return np.sqrt(np.maximum(_quad(w, w, s2), 0.0))


def sample_specular_phase(wi, s2, u):
    """Outgoing directions (N,3) of the specular SGGX phase function at wi (N,3) (pointing away
    from the scattering point toward where the light came from): a visible normal (Heitz et al.
    2015, sec. 5: a uniform disk point mapped by the projected ellipsoid) and the mirror of wi."""
    k, j = _basis(wi)
    Skk, Sjj, Sii = _quad(k, k, s2), _quad(j, j, s2), _quad(wi, wi, s2)
    Skj, Ski, Sji = _quad(k, j, s2), _quad(k, wi, s2), _quad(j, wi, s2)
    det = np.sqrt(np.abs(Skk * Sjj * Sii - Skj ** 2 * Sii - Ski ** 2 * Sjj - Sji ** 2 * Skk + 2 * Skj * Ski * Sji))
    inv_sqrt_ii = 1.0 / np.sqrt(Sii)
    tmp = np.sqrt(np.maximum(Sjj * Sii - Sji ** 2, 1e-300))
    r, phi = np.sqrt(u[:, 0]), 2.0 * np.pi * u[:, 1]
    x, y = r * np.sin(phi), r * np.cos(phi)
    z = np.sqrt(np.maximum(1.0 - x * x - y * y, 0.0))
    mk = x * det / tmp - y * inv_sqrt_ii * (Ski * Sji - Skj * Sii) / tmp + z * inv_sqrt_ii * Ski
    mj = y * inv_sqrt_ii * tmp + z * inv_sqrt_ii * Sji
    mi = z * inv_sqrt_ii * Sii
    m = mk[:, None] * k + mj[:, None] * j + mi[:, None] * wi
    m /= np.linalg.norm(m, axis=1, keepdims=True)
    out = 2.0 * np.einsum("ij,ij->i", m, wi)[:, None] * m - wi
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def walk(mu: float, roughness: float, n: int, rng) -> np.ndarray:
    """Directions (M,3) of the walks that leave through the top (M <= n), light arriving
    from wo = (sqrt(1 - mu^2), 0, mu)."""
    s2 = (roughness * roughness) ** 2
    d = np.tile([-np.sqrt(1.0 - mu * mu), 0.0, -mu], (n, 1))  # propagation direction
    depth = np.zeros(n)  # 0 at the top, 1 at the bottom
    out = []
    for bounce in range(MAX_BOUNCES + 1):
        sigma_t = projected_area(d, s2)
        dist = -np.log1p(-rng.random(len(d))) / np.maximum(sigma_t, 1e-300)
        depth = depth - dist * d[:, 2]
        up, inside = depth < 0.0, (depth >= 0.0) & (depth <= 1.0)
        out.append(d[up])
        if bounce == MAX_BOUNCES:
            break
        d, depth = d[inside], depth[inside]
        d = sample_specular_phase(-d, s2, rng.random((len(d), 2)))
        if bounce == MAX_BOUNCES - 1:  # the walk stops here: its last direction counts
            out.append(d[d[:, 2] > 0])
            break
    return np.concatenate(out)


def fit_likelihood(w: np.ndarray, x0) -> np.ndarray:
    """(a, b) maximising the LTC log-likelihood of directions w (M,3) in the view frame: the
    starting point of fit()."""
    logz = np.log(np.maximum(w[:, 2], 1e-300)).sum()

    def nll(p):
        a, b = p
        if a <= 1e-4:
            return 1e30
        len2 = (a * w[:, 0] + b * w[:, 2]) ** 2 + (a * w[:, 1]) ** 2 + w[:, 2] ** 2
        return -(logz + len(w) * np.log(a * a / np.pi) - 2.0 * np.log(len2).sum())

    return minimize(nll, x0, method="Nelder-Mead", options=dict(xatol=1e-5, fatol=1e-6, maxiter=2000)).x


BINS = 32  # theta (0, pi/2) x phi (0, pi) cells of the fit, as the paper's
_theta = (np.arange(BINS) + 0.5) / BINS * 0.5 * np.pi
_phi = (np.arange(BINS) + 0.5) / BINS * np.pi
_PHI, _THETA = np.meshgrid(_phi, _theta)
CELLS = np.stack([np.sin(_THETA) * np.cos(_PHI), np.sin(_THETA) * np.sin(_PHI), np.cos(_THETA)], -1).reshape(-1, 3)


def fit(w: np.ndarray, R: float, n: int, x0) -> np.ndarray:
    """(a, b) of the paper's objective: the L3 distance between R D and the reference's f cos
    at the cell centres, the reference's values a histogram of the n walks' exit directions w
    (M,3) (folded to phi in [0, pi] by symmetry), per unit solid angle."""
    theta = np.arccos(np.clip(w[:, 2], -1.0, 1.0))
    phi = np.abs(np.arctan2(w[:, 1], w[:, 0]))
    h, _, _ = np.histogram2d(theta, phi, bins=[BINS, BINS], range=[[0, 0.5 * np.pi], [0, np.pi]],
                             weights=1.0 / np.sin(theta))
    ref = (h * BINS * BINS / (np.pi ** 2 * n)).ravel()
    x, z = CELLS[:, 0], CELLS[:, 2]

    def l3(p):
        a, b = p
        if a <= 1e-4:
            return 1e30
        len2 = (a * x + b * z) ** 2 + (a * CELLS[:, 1]) ** 2 + z * z
        return np.sum(np.abs(R * z * a * a / (np.pi * len2 * len2) - ref) ** 3)

    start = fit_likelihood(w, x0)
    return minimize(l3, start, method="Nelder-Mead", options=dict(xatol=1e-6, fatol=1e-14, maxiter=4000)).x


def despike(a: np.ndarray, b: np.ndarray, rounds: int = 3, tol_a: float = 0.1, tol_b: float = 0.02):
    """(a, b) with spikes smoothed: an interior fit that strays from the mean of its two
    neighbours along mu or along roughness (a by more than tol_a of that mean, b by more than
    tol_b) takes that mean. Where the lobe is broad the L3 objective is flat and the
    histogram's noise moves its minimum far; the table's edges (grazing mu, where a changes
    fast) are left as fitted."""
    a, b = a.astype(np.float64).copy(), b.astype(np.float64).copy()
    fitted = a > 0
    for _ in range(rounds):
        for axis in (1, 0):
            A, B, F = (np.moveaxis(x, axis, 0) for x in (a, b, fitted))  # views into a, b
            ma, mb = 0.5 * (A[:-2] + A[2:]), 0.5 * (B[:-2] + B[2:])
            out = F[:-2] & F[2:] & F[1:-1] & ((np.abs(A[1:-1] - ma) > tol_a * ma) | (np.abs(B[1:-1] - mb) > tol_b))
            A[1:-1][out], B[1:-1][out] = ma[out], mb[out]
    return a, b


def tabulate(paths: int, seed: int, objective: str = "likelihood") -> dict:
    nodes = np.maximum(0.01, np.linspace(0.0, 1.0, sheen.GRID))
    a, b, R = (np.zeros((sheen.GRID, sheen.GRID)) for _ in range(3))
    rng = np.random.default_rng(seed)
    for i, mu in enumerate(nodes):
        x0 = (1.0, 0.0)
        for j in range(sheen.GRID - 1, -1, -1):  # rough to smooth, warm-started
            w = walk(mu, nodes[j], paths, rng)
            R[j, i] = len(w) / paths
            if len(w) >= 50:
                x0 = fit_likelihood(w, x0) if objective == "likelihood" else fit(w, R[j, i], paths, x0)
                a[j, i], b[j, i] = x0
        print(f"mu {mu:.3f}: R at r=1 {R[-1, i]:.4f}, a {a[-1, i]:.4f}, b {b[-1, i]:.4f}", flush=True)
    if objective == "l3":
        a, b = despike(a, b)
    return dict(a=a, b=b, R=R)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--paths", type=int, default=200_000)
    ap.add_argument("--objective", choices=("likelihood", "l3"), default="likelihood")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=str(sheen.TABLE_FILE))
    args = ap.parse_args()
    t = tabulate(args.paths, args.seed, args.objective)
    np.savez_compressed(args.out, **{k: v.astype(np.float32) for k, v in t.items()})
    print("wrote", args.out)


if __name__ == "__main__":
    main()
