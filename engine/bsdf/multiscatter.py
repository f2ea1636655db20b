"""Multiscatter GGX as Cycles renders it: single-scattering GGX scaled by an energy factor.

Cycles' "Multiscatter GGX" (the Principled BSDF's default distribution, so that of every
material Blender's glTF importer makes) is no random walk on the microsurface: it is the
single-scattering lobe times a per-point factor (bsdf_microfacet.h
microfacet_ggx_preserve_energy, after Kulla and Conty 2017):

    c = 1 + Fms (1 - E) / E,    Fms = Fss E_avg / (1 - Fss (1 - E_avg))

E(roughness, mu) is the directional albedo of the lobe with F = 1 seen at mu = wo.n, E_avg
its cosine-weighted mean over mu, Fss the Fresnel colour's hemispherical average for the
lobe's model (`fresnel_average`). The factor multiplies the BSDF value of every direction;
whatever Cycles estimates from the closure (the layering of a Principled BSDF's diffuse base
under its specular layer, the closure's selection weight) sees its albedo times c E.

Like Cycles we tabulate E on a 32 x 32 grid of (roughness = sqrt(alpha), mu) and E_avg on 32
roughnesses (app/cycles_precompute.cpp precompute_ggx_E, ggx_Eavg) and interpolate linearly
as kernel/util/lookup_table.h does. The tables (ggx_E.npy, computed by `tabulate`: the mean of
G2 / G1 over 128 x 128 jittered strata of visible normals per node, a reflection under the
surface counting 0) are ours, not copied from Cycles. Regenerate them with
    ./dev python -c "import _bootstrap; _bootstrap.load_ember(); from ember.engine.bsdf import multiscatter; multiscatter.write_table()"
"""
from __future__ import annotations

import pathlib
from functools import lru_cache

import numpy as np

from . import fresnel, microfacet

GRID = 32  # Cycles' table resolution per axis
TABLE_FILE = pathlib.Path(__file__).with_name("ggx_E.npy")
_F82_COS = 1.0 / 7.0


def nodes() -> np.ndarray:
    """Grid nodes (GRID,) of the roughness and cosine axes (clamped away from 0 as Cycles')."""
    return np.clip(np.arange(GRID) / (GRID - 1), 1e-4, 1.0)


def directional_albedo(roughness: float, mu: float, u: np.ndarray) -> float:
    """E: mean of G2 / G1(wo) over visible normals h(u) (u (K,2)) seen from wo = (sqrt(1 -
    mu^2), 0, mu): the reflected energy of the F = 1 lobe, what Cycles' sampler returns as
    eval / pdf."""
    n = len(u)
    alpha = np.full(n, roughness * roughness)
    wo = np.tile([np.sqrt(max(1.0 - mu * mu, 0.0)), 0.0, mu], (n, 1))
    if microfacet.is_delta(alpha[:1])[0]:
        return 1.0
    wi = microfacet.reflect(wo, microfacet.sample_vndf(alpha, wo, u))
    ratio = microfacet.G2(alpha, wo, wi) / microfacet.G1(alpha, wo)
    return float(np.where(wi[:, 2] > 0.0, ratio, 0.0).mean())


def tabulate(strata: int = 128, seed: int = 0) -> np.ndarray:
    """(GRID + 1, GRID): rows j < GRID hold E at (mu_j, roughness_i); the last row E_avg(roughness_i)
    = 2 int E(mu) mu dmu, by the trapezoid rule on a fine grid of mu."""
    rng = np.random.default_rng(seed)
    grid = np.stack(np.meshgrid(np.arange(strata), np.arange(strata), indexing="ij"), -1).reshape(-1, 2)
    table = np.zeros((GRID + 1, GRID))
    fine = np.linspace(0.0, 1.0, 65)
    for i, rough in enumerate(nodes()):
        for j, mu in enumerate(nodes()):
            table[j, i] = directional_albedo(rough, mu, (grid + rng.random(grid.shape)) / strata)
        e = np.array([directional_albedo(rough, max(mu, 1e-4), (grid + rng.random(grid.shape)) / strata)
                      for mu in fine])
        table[GRID, i] = np.trapz(2.0 * e * fine, fine)
    return table


def write_table(strata: int = 128) -> None:
    np.save(TABLE_FILE, tabulate(strata).astype(np.float32))


@lru_cache(maxsize=1)
def _table() -> np.ndarray:
    return np.load(TABLE_FILE).astype(np.float64)


def _lerp_index(x: np.ndarray):
    """Cycles' lookup_table_read indexing: (index, next index, fraction) for x in [0, 1]."""
    x = np.clip(x, 0.0, 1.0) * (GRID - 1)
    i = np.minimum(np.floor(x).astype(np.int64), GRID - 1)
    return i, np.minimum(i + 1, GRID - 1), x - i


def energy(roughness: np.ndarray, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(E, E_avg), each (K,), for Blender roughness (K,) and mu = wo.n (K,)."""
    t = _table()
    ri, rn, tr = _lerp_index(np.asarray(roughness, np.float64))
    mi, mn, tm = _lerp_index(np.asarray(mu, np.float64))
    row = lambda j: (1 - tr) * t[j, ri] + tr * t[j, rn]  # noqa: E731
    return (1 - tm) * row(mi) + tm * row(mn), row(GRID)


def dielectric_average(eta: np.ndarray) -> np.ndarray:
    """Cycles' fresnel_dielectric_Fss: Kulla and Conty's fit of 2 int F(mu, eta) mu dmu."""
    eta = np.asarray(eta, np.float64)
    below = 0.997118 + eta * (0.1014 - eta * (0.965241 + eta * 0.130607))
    above = (eta - 1.0) / (4.08567 + 1.00071 * eta)
    return np.where(eta < 1.0, below, above)


def f82_average(f0: np.ndarray, tint: np.ndarray) -> np.ndarray:
    """Cycles' fresnel_f82_Fss for the F82-tint model: mix(f0, 1, 1/21) - b / 126 (K,3)."""
    f0, tint = np.asarray(f0, np.float64), np.asarray(tint, np.float64)
    s = 1.0 - _F82_COS
    s5 = s ** 5
    b = (f0 + (1.0 - f0) * s5) * (1.0 - tint) / (_F82_COS * s5 * s)  # fresnel_f82tint_B
    return f0 + (1.0 - f0) / 21.0 - b / 126.0


def remapped_dielectric_average(f0: np.ndarray, eta: np.ndarray) -> np.ndarray:
    """Fss of the dielectric Fresnel of eta remapped onto [f0, 1] (K,3) (the Principled
    specular layer, Cycles' generalised Schlick with a negative exponent)."""
    F0 = fresnel.f0_from_ior(eta)
    span = 1.0 - F0
    s = np.clip(np.divide(dielectric_average(eta) - F0, span, out=np.ones_like(F0), where=span > 0.0), 0.0, 1.0)
    f0 = np.asarray(f0, np.float64)
    return f0 + (1.0 - f0) * s[:, None]


def compensation(fss: np.ndarray, roughness: np.ndarray, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(c (K,3), E (K,)): the factor on the single-scattering lobe and the F = 1 albedo at mu."""
    E, E_avg = energy(roughness, mu)
    E = np.maximum(E, 1e-6)
    fss = np.asarray(fss, np.float64)
    fms = fss * E_avg[:, None] / np.maximum(1.0 - fss * (1.0 - E_avg[:, None]), 1e-6)
    return 1.0 + fms * ((1.0 - E) / E)[:, None], E
