"""How much a Principled BSDF's dielectric specular layer reflects: Cycles' layering estimate.

Cycles weighs everything under the specular layer (the diffuse base) by
1 - max_rgb(mix(f0, 1, s)) (svm/closure.h Principled, bsdf_util.h closure_layering_weight,
bsdf_microfacet.h bsdf_microfacet_estimate_albedo), where s(roughness, cos_o, eta) is the
mean over visible normals h ~ D_wo of the remapped Fresnel factor
(F(wo.h, eta) - F0(eta)) / (1 - F0(eta)), a reflection under the surface counting as 0
(app/cycles_precompute.cpp precompute_ggx_gen_schlick_s, table ggx_gen_schlick_ior_s).

Like Cycles we tabulate s on its 16^3 grid of (roughness, cos_o, z), z = sqrt(|eta - 1| /
(eta + 1)) (eta = ior_from_F0(z^4) at the nodes), and interpolate linearly as
kernel/util/lookup_table.h does. The table (ggx_layer_s.npy, computed by `tabulate` with
256 x 256 jittered strata per cell; about 1e-4 accurate) is ours, not copied from Cycles.
Regenerate it with
    ./dev python -c "import _bootstrap; _bootstrap.load_ember(); from ember.engine.bsdf import layering; layering.write_table()"
"""
from __future__ import annotations

import pathlib
from functools import lru_cache

import numpy as np

from . import fresnel, microfacet

GRID = 16  # Cycles' table resolution per axis
TABLE_FILE = pathlib.Path(__file__).with_name("ggx_layer_s.npy")


def eta_of_z(z) -> np.ndarray:
    """Cycles' IOR parametrisation of the table's third axis: ior_from_F0(z^4), z clipped."""
    r = np.clip(np.asarray(z, np.float64), 1e-4, 0.99) ** 2  # sqrt(F0) with F0 = z^4
    return (1.0 + r) / (1.0 - r)


def nodes() -> np.ndarray:
    """Grid nodes (GRID,) of the roughness and cosine axes (Cycles clamps them to >= 1e-4)."""
    return np.clip(np.arange(GRID) / (GRID - 1), 1e-4, 1.0)


def remapped_fresnel_mean(roughness: float, mu: float, eta: float, u: np.ndarray) -> float:
    """Mean of the remapped Fresnel over visible normals h(u) (u (K,2) in [0,1)^2) seen from
    wo = (sqrt(1 - mu^2), 0, mu); reflections under the surface count 0."""
    n = len(u)
    alpha = np.full(n, roughness * roughness)
    wo = np.tile([np.sqrt(max(1.0 - mu * mu, 0.0)), 0.0, mu], (n, 1))
    # Cycles samples a smooth lobe as its normal itself.
    h = np.tile([0.0, 0.0, 1.0], (n, 1)) if microfacet.is_delta(alpha[:1])[0] else microfacet.sample_vndf(alpha, wo, u)
    wi = microfacet.reflect(wo, h)
    F0 = fresnel.f0_from_ior(eta)
    s = np.clip((fresnel.dielectric(np.einsum("ij,ij->i", wo, h), eta) - F0) / (1.0 - F0), 0.0, 1.0)
    return float(np.where(wi[:, 2] > 0.0, s, 0.0).mean())


def tabulate(strata: int = 256, seed: int = 0) -> np.ndarray:
    """s on the (z, cos_o, roughness) grid (GRID, GRID, GRID), strata^2 jittered samples per cell."""
    rng = np.random.default_rng(seed)
    grid = (np.stack(np.meshgrid(np.arange(strata), np.arange(strata), indexing="ij"), -1).reshape(-1, 2))
    table = np.zeros((GRID, GRID, GRID))
    for k, eta in enumerate(eta_of_z(np.arange(GRID) / (GRID - 1))):
        for j, mu in enumerate(nodes()):
            for i, rough in enumerate(nodes()):
                u = (grid + rng.random(grid.shape)) / strata
                table[k, j, i] = remapped_fresnel_mean(rough, mu, eta, u)
    return table


def write_table(strata: int = 256) -> None:
    np.save(TABLE_FILE, tabulate(strata).astype(np.float32))


@lru_cache(maxsize=1)
def _table() -> np.ndarray:
    return np.load(TABLE_FILE).astype(np.float64)


def _lerp_index(x: np.ndarray):
    """Cycles' lookup_table_read indexing: (index, next index, fraction) for x in [0, 1]."""
    x = np.clip(x, 0.0, 1.0) * (GRID - 1)
    i = np.minimum(np.floor(x).astype(np.int64), GRID - 1)
    return i, np.minimum(i + 1, GRID - 1), x - i


def schlick_factor(roughness: np.ndarray, cos_o: np.ndarray, eta: np.ndarray) -> np.ndarray:
    """s (K,) for Blender roughness (K,), cos_o = wo.n (K,) and relative IOR eta (K,) > 0,
    trilinear in the table as Cycles' lookup_table_read_3D."""
    roughness, cos_o, eta = np.broadcast_arrays(*(np.asarray(a, np.float64) for a in (roughness, cos_o, eta)))
    t = _table()
    zi, zn, tz = _lerp_index(np.sqrt(np.abs(eta - 1.0) / (eta + 1.0)))
    mi, mn, tm = _lerp_index(cos_o)
    ri, rn, tr = _lerp_index(roughness)

    def plane(z):
        return (1 - tm) * ((1 - tr) * t[z, mi, ri] + tr * t[z, mi, rn]) + tm * ((1 - tr) * t[z, mn, ri] + tr * t[z, mn, rn])

    return (1 - tz) * plane(zi) + tz * plane(zn)


def base_weight(f0: np.ndarray, roughness: np.ndarray, cos_o: np.ndarray, eta: np.ndarray,
                scale: np.ndarray | None = None) -> np.ndarray:
    """Weight (K,) left for the layers under a specular layer with F0 colour f0 (K,3):
    clamp(1 - max_rgb(f0 + (1 - f0) s), 0, 1) (Cycles' closure_layering_weight); the albedo
    times `scale` (K,3) where given (what the closure's weight carries besides, e.g. Multiscatter
    GGX's energy factor)."""
    s = schlick_factor(roughness, cos_o, eta)[:, None]
    albedo = np.asarray(f0, np.float64) * (1.0 - s) + s
    if scale is not None:
        albedo = albedo * scale
    return np.clip(1.0 - albedo.max(axis=1), 0.0, 1.0)
