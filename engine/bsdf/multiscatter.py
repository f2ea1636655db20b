"""Cycles' Multiscatter GGX: single-scattering GGX scaled to restore the energy lost to
masking (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks"), as
kernel/closure/bsdf_microfacet.h microfacet_ggx_preserve_energy computes it.

A GGX lobe of roughness r seen from cos_o = mu reflects E(r, mu) of the light when its Fresnel
is 1 (its directional albedo); E_avg(r) = 2 int_0^1 E(r, mu) mu dmu. Cycles multiplies the
whole lobe (its eval and every sample's weight) by

    1 + Fms (1 - E) / E,    Fms = Fss E_avg / (1 - Fss (1 - E_avg))      (per colour channel)

where Fss is the lobe's mean Fresnel (`fss_*` below, Cycles' fits): with Fss = 1 the factor is
1 / E and the lobe reflects all light; a coloured Fresnel saturates the colour the extra
bounces add. The factor depends on wo only, so the lobe is not reciprocal (as in Cycles). The
lobe's albedo estimate (lobe choice, layering, colour passes) is multiplied by
E (1 + Fms (1 - E) / E), Cycles' `darkening` of the closure weight.

Glass (reflection + refraction) uses the same factor with its own E(r, mu, eta) and
E_avg(r, eta): the albedo of Cycles' GGX glass with the exact dielectric Fresnel and no
eta^2 radiance scaling, one table for eta > 1 and one (the "inverse") for 1 / eta, eta the IOR
relative to wo's side; its Fss is the refraction tint. Cycles' inverse tables count refracted
light the lobe drops (it leaves on wo's side: `_glass_albedo`), so glass seen from inside
near grazing gets less compensation than would conserve energy; ours are made the same way,
or Ember's rough glass would be brighter than Cycles'.

Tables: ours, computed with Ember's own GGX (`tabulate`, stratified visible-normal sampling,
the reflect / refract branch taken in expectation), on Cycles' grids and axes
(app/cycles_precompute.cpp; about 3e-4 accurate, as Cycles' own): E on 32 x 32 nodes (roughness, mu), E_avg on 32 roughness nodes,
the glass tables on 16^3 nodes (roughness, mu, z) with eta = ior_from_F0(z^4), nodes clamped
as Cycles (roughness and mu >= 1e-4, z in [1e-4, 0.99]), values clamped to [0, 1], read
with Cycles' lookup_table_read (linear per axis). A smooth lobe (a Dirac) has E = 1.
Regenerate them (a few minutes) with
    ./dev python -c "import _bootstrap; _bootstrap.load_ember(); from ember.engine.bsdf import multiscatter; multiscatter.write_tables()"
"""
from __future__ import annotations

import pathlib
from functools import lru_cache

import numpy as np

from . import fresnel, microfacet
from ..vec import dot

E_SIZE, GLASS_SIZE = 32, 16  # Cycles' grid sizes
TABLE_FILE = pathlib.Path(__file__).with_name("ggx_energy.npz")


# ---------------------------------------------------------------- the tables' integrands

def _strata(n: int, rng) -> np.ndarray:
    """n^2 jittered points (n^2, 2) in [0, 1)^2."""
    g = np.stack(np.meshgrid(np.arange(n), np.arange(n), indexing="ij"), -1).reshape(-1, 2)
    return (g + rng.random(g.shape)) / n


def _reflection_albedo(rough: np.ndarray, mu: np.ndarray, u: np.ndarray) -> np.ndarray:
    """E (C,) of C cells (roughness, mu) from the same points u (S,2): mean of G2 / G1(wo)
    over visible normals whose reflection stays above the surface."""
    C, S = len(rough), len(u)
    alpha = np.repeat(rough * rough, S)
    wo = np.repeat(np.stack([np.sqrt(np.maximum(1.0 - mu * mu, 0.0)), np.zeros(C), mu], -1), S, axis=0)
    h = microfacet.sample_vndf(alpha, wo, np.tile(u, (C, 1)))
    wi = microfacet.reflect(wo, h)
    w = np.where(wi[:, 2] > 0.0, microfacet.G2(alpha, wo, wi) / microfacet.G1(alpha, wo), 0.0)
    E = w.reshape(C, S).mean(axis=1)
    return np.where(microfacet.is_delta(rough * rough), 1.0, np.clip(E, 0.0, 1.0))


def _glass_albedo(rough: np.ndarray, mu: np.ndarray, eta: np.ndarray, u: np.ndarray) -> np.ndarray:
    """E (C,) of Cycles' GGX glass (F reflects, 1 - F refracts, both of weight G2 / G1(wo),
    no radiance scaling) for C cells (roughness, mu, eta relative to wo's side), counted as
    Cycles' tables count it: a reflection under the surface is lost, a refraction counts on
    whichever side it leaves (which matters only for eta < 1, where one bent away from the
    microfacet normal can leave above the surface; the lobe itself drops it)."""
    C, S = len(rough), len(u)
    alpha = np.repeat(rough * rough, S)
    e = np.repeat(eta, S)
    wo = np.repeat(np.stack([np.sqrt(np.maximum(1.0 - mu * mu, 0.0)), np.zeros(C), mu], -1), S, axis=0)
    h = microfacet.sample_vndf(alpha, wo, np.tile(u, (C, 1)))
    cos_oh = dot(wo, h)
    F, cos_t = fresnel.dielectric_with_cos_t(cos_oh, e)
    g1 = microfacet.G1(alpha, wo)
    wr = microfacet.reflect(wo, h)
    inv = 1.0 / e
    wt = -inv[:, None] * wo + (inv * cos_oh + cos_t)[:, None] * h
    ok = cos_oh > 0.0
    r = np.where(ok & (wr[:, 2] > 0.0), F * microfacet.G2(alpha, wo, wr) / g1, 0.0)
    t = np.where(ok & (F < 1.0), (1.0 - F) * microfacet.G2(alpha, wo, wt) / g1, 0.0)
    E = (r + t).reshape(C, S).mean(axis=1)
    # Cycles samples a smooth or index-matched interface as a Dirac of weight 1.
    delta = microfacet.is_delta(rough * rough) | (np.abs(eta - 1.0) < 1e-4)
    return np.where(delta, 1.0, np.clip(E, 0.0, 1.0))


def nodes(n: int) -> np.ndarray:
    """Cycles' roughness / mu nodes (n,): i / (n - 1) clamped to [1e-4, 1]."""
    return np.clip(np.arange(n) / (n - 1), 1e-4, 1.0)


def eta_nodes() -> np.ndarray:
    """The glass tables' IOR nodes (GLASS_SIZE,): ior_from_F0(z^4), z clamped to [1e-4, 0.99]."""
    z = np.clip(np.arange(GLASS_SIZE) / (GLASS_SIZE - 1), 1e-4, 0.99)
    r = np.sqrt(np.clip(z ** 4, 0.0, 0.99))
    return (1.0 + r) / (1.0 - r)


def _mean_over_mu(albedo, rough: np.ndarray, *rest, strata: int, order: int, rng) -> np.ndarray:
    """E_avg (C,) = 2 int_0^1 E(mu) mu dmu by Gauss-Legendre over mu (order nodes)."""
    x, w = np.polynomial.legendre.leggauss(order)
    mu, w = 0.5 * (x + 1.0), 0.5 * w
    out = np.empty(len(rough))
    for c in range(len(rough)):  # one roughness at a time: the samples of all would not fit in memory
        E = albedo(np.full(order, rough[c]), mu, *(np.full(order, a[c]) for a in rest), _strata(strata, rng))
        out[c] = (E * 2.0 * mu * w).sum()
    return np.clip(out, 0.0, 1.0)


def tabulate(strata: int = 384, glass_strata: int = 128, order: int = 32, seed: int = 0) -> dict:
    """The tables: E (32 mu, 32 roughness), E_avg (32,), glass_E (2 [eta, 1 / eta], 16 z,
    16 mu, 16 roughness), glass_E_avg (2, 16 z, 16 roughness)."""
    rng = np.random.default_rng(seed)
    r, m = np.meshgrid(nodes(E_SIZE), nodes(E_SIZE))  # [mu, roughness]
    E = np.stack([np.concatenate([_reflection_albedo(r[j, i:i + 4], m[j, i:i + 4], _strata(strata, rng))
                                  for i in range(0, E_SIZE, 4)]) for j in range(E_SIZE)])
    E_avg = _mean_over_mu(_reflection_albedo, nodes(E_SIZE), strata=strata // 2, order=order, rng=rng)
    glass_E = np.zeros((2, GLASS_SIZE, GLASS_SIZE, GLASS_SIZE))
    glass_avg = np.zeros((2, GLASS_SIZE, GLASS_SIZE))
    rg = nodes(GLASS_SIZE)
    for side in range(2):
        for k, eta in enumerate(eta_nodes()):
            eta = eta if side == 0 else 1.0 / eta
            for j, mu in enumerate(nodes(GLASS_SIZE)):
                glass_E[side, k, j] = _glass_albedo(rg, np.full(GLASS_SIZE, mu), np.full(GLASS_SIZE, eta),
                                                    _strata(glass_strata, rng))
            glass_avg[side, k] = _mean_over_mu(_glass_albedo, rg, np.full(GLASS_SIZE, eta), strata=glass_strata // 2,
                                               order=order, rng=rng)
    return dict(E=E, E_avg=E_avg, glass_E=glass_E, glass_E_avg=glass_avg)


def write_tables(**kw) -> None:
    np.savez_compressed(TABLE_FILE, **{k: v.astype(np.float32) for k, v in tabulate(**kw).items()})


@lru_cache(maxsize=1)
def tables() -> dict:
    with np.load(TABLE_FILE) as f:
        return {k: f[k].astype(np.float64) for k in f.files}


# ---------------------------------------------------------------- lookups (Cycles' lookup_table.h)

def _axis(x: np.ndarray, n: int):
    """(index, next index, fraction) of x (clamped to [0, 1]) on n nodes."""
    x = np.clip(x, 0.0, 1.0) * (n - 1)
    i = np.minimum(x.astype(np.int64), n - 1)
    return i, np.minimum(i + 1, n - 1), x - i


def _read2(t: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear t[..., y, x] of K points: t (K or 1, ny, nx) gathered per row."""
    i, i1, tx = _axis(x, t.shape[-1])
    j, j1, ty = _axis(y, t.shape[-2])
    k = np.arange(len(x)) if t.shape[0] > 1 else np.zeros(len(x), np.int64)
    return ((1 - ty) * ((1 - tx) * t[k, j, i] + tx * t[k, j, i1])
            + ty * ((1 - tx) * t[k, j1, i] + tx * t[k, j1, i1]))


def E(roughness: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """Directional albedo (K,) of GGX reflection with F = 1 at Blender roughness and cos_o."""
    return _read2(tables()["E"][None], np.asarray(roughness, np.float64), np.asarray(mu, np.float64))


def E_avg(roughness: np.ndarray) -> np.ndarray:
    """Hemispherical mean (K,) of E over cosine-weighted directions."""
    i, i1, t = _axis(np.asarray(roughness, np.float64), E_SIZE)
    a = tables()["E_avg"]
    return (1 - t) * a[i] + t * a[i1]


def _glass_axes(eta: np.ndarray):
    """(table side (K,) 0 / 1, z (K,)) for eta relative to wo's side."""
    eta = np.asarray(eta, np.float64)
    inv = eta < 1.0
    ior = np.where(inv, 1.0 / np.maximum(eta, 1e-12), eta)
    return inv.astype(np.int64), np.sqrt(np.abs((ior - 1.0) / (ior + 1.0)))


def glass_E(roughness, mu, eta) -> np.ndarray:
    """Directional albedo (K,) of GGX glass at relative IOR eta (wi side over wo side)."""
    side, z = _glass_axes(eta)
    k, k1, tz = _axis(z, GLASS_SIZE)
    t = tables()["glass_E"]
    r, m = np.asarray(roughness, np.float64), np.asarray(mu, np.float64)
    return (1 - tz) * _read2(t[side, k], r, m) + tz * _read2(t[side, k1], r, m)


def glass_E_avg(roughness, eta) -> np.ndarray:
    side, z = _glass_axes(eta)
    return _read2(tables()["glass_E_avg"][side], np.asarray(roughness, np.float64), z)


# ---------------------------------------------------------------- the compensation

def fss_dielectric(eta) -> np.ndarray:
    """Mean Fresnel 2 int F(mu, eta) mu dmu of a dielectric: Kulla & Conty's fit (bsdf_util.h
    fresnel_dielectric_Fss)."""
    eta = np.asarray(eta, np.float64)
    return np.where(eta < 1.0, 0.997118 + eta * (0.1014 - eta * (0.965241 + eta * 0.130607)),
                    (eta - 1.0) / (4.08567 + 1.00071 * eta))


def fss_f82(f0: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Mean Fresnel (K,3) of the F82-tint model (bsdf_util.h fresnel_f82_Fss)."""
    return f0 + (1.0 - f0) / 21.0 - b / 126.0


def fss_remapped(f0: np.ndarray, eta: np.ndarray) -> np.ndarray:
    """Mean Fresnel (K,3) of the exact dielectric Fresnel remapped onto [f0, 1] (Principled
    specular; Cycles' generalised Schlick with a negative exponent)."""
    F0 = fresnel.f0_from_ior(eta)
    span = 1.0 - F0
    s = np.clip(np.divide(fss_dielectric(eta) - F0, span, out=np.ones_like(F0), where=span > 0.0), 0.0, 1.0)
    f0 = np.clip(f0, 0.0, 1.0)
    return f0 + (1.0 - f0) * s[:, None]


def factor(E_: np.ndarray, E_avg_: np.ndarray, Fss: np.ndarray):
    """(scale (K,3) of the lobe, darkening (K,3) of its albedo estimate) for albedo E (K,),
    mean albedo E_avg (K,) and mean Fresnel Fss (K,3)."""
    E_ = np.maximum(E_, 1e-6)[:, None]
    A = E_avg_[:, None]
    Fms = Fss * A / (1.0 - Fss * (1.0 - A))
    scale = 1.0 + Fms * (1.0 - E_) / E_
    return scale, scale * E_
