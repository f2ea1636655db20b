"""The sheen lobe (Sheen BSDF, Principled sheen layer): Cycles' microfiber sheen (an LTC lobe
scaled by its tabulated albedo) or, where the node asks for it, the Ashikhmin velvet
(formulas: engine/bsdf/sheen.py).

Microfiber is not reciprocal (its shape and albedo are read at the viewing direction): light
particles (Params.adjoint) evaluate f with the roles of wo and wi swapped; sampling stays the
lobe of wo (a proposal whose pdf eval reports). Cycles counts both models' samples as diffuse
bounces; microfiber is a diffuse closure for render passes and light visibility, the velvet a
glossy one (its albedo goes to the glossy passes)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...scene import DIST_VELVET, LOBE_SHEEN, RAY_DIFFUSE
from ... import sampling
from .. import sheen
from . import inputs
from .base import CLASS_DIFFUSE, CLASS_GLOSSY, LABEL_DIFFUSE, LobeSample, SurfaceLobe, SurfaceParams, mean_albedo


@dataclass
class SheenParams(SurfaceParams):
    """roughness (K,) in [0, 1]; velvet (K,) bool: the Ashikhmin velvet model."""

    roughness: np.ndarray
    velvet: np.ndarray


def _ltc(p, view: np.ndarray):
    """(a, b, R) (K,) of microfiber rows at viewing directions view (K,3); R = 0 where Cycles
    drops the closure."""
    a, b, R = sheen.lookup(np.clip(view[:, 2], 0.0, 1.0), p.roughness)
    return a, b, np.where(sheen.valid(a, R), R, 0.0)


def _split(p):
    """(microfiber rows, velvet rows), None for all rows."""
    v = p.velvet
    if not v.any():
        return None, np.zeros(0, np.int64)
    if v.all():
        return np.zeros(0, np.int64), None
    return np.flatnonzero(~v), np.flatnonzero(v)


def _microfiber_eval(p, wo, wi):
    a, b, R = _ltc(p, wo)
    g, pdf = sheen.microfiber_eval(a, b, wo, wi)
    if p.adjoint:  # f(wi, wo): the lobe of wi at wo
        a2, b2, R = _ltc(p, wi)
        g = sheen.microfiber_eval(a2, b2, wi, wo)[0]
    return p.color * (R * g)[:, None], pdf


def _velvet_eval(p, wo, wi):
    f = sheen.velvet_eval(sheen.velvet_sigma(p.roughness), wo, wi)
    pdf = np.where(wo[:, 2] > 0, sampling.pdf_uniform_hemisphere(wi[:, 2]), 0.0)
    return p.color * f[:, None], pdf


class Sheen(SurfaceLobe):
    kind = LOBE_SHEEN
    rays = RAY_DIFFUSE
    reflection_class = transmission_class = CLASS_DIFFUSE

    def parameters(self, m, lobe, point, src, inside) -> SheenParams:
        return SheenParams(color=inputs.color(m, lobe, point, src), delta=np.zeros(len(lobe), bool),
                           roughness=inputs.roughness(m, lobe, point, src),
                           velvet=m.lobe_distribution[lobe] == DIST_VELVET)

    def albedo(self, p, wo):
        mf, _ = _split(p)
        a = p.color.copy()  # the velvet's estimate: its weight, as Cycles'
        if mf is None:
            return a * _ltc(p, wo)[2][:, None]
        if len(mf):
            a[mf] *= _ltc(p.take(mf), wo[mf])[2][:, None]
        return a

    def eval(self, p, wo, wi):
        mf, v = _split(p)
        if mf is None:
            return _microfiber_eval(p, wo, wi)
        if v is None:
            return _velvet_eval(p, wo, wi)
        f, pdf = np.empty((len(p), 3)), np.empty(len(p))
        f[mf], pdf[mf] = _microfiber_eval(p.take(mf), wo[mf], wi[mf])
        f[v], pdf[v] = _velvet_eval(p.take(v), wo[v], wi[v])
        return f, pdf

    def _sample_microfiber(self, p, wo, u):
        a, b, _ = _ltc(p, wo)
        return sheen.microfiber_sample(a, b, wo, u)

    def sample(self, p, wo, u, u_branch) -> LobeSample:
        mf, v = _split(p)
        if mf is None:
            wi, pdf = self._sample_microfiber(p, wo, u)
        elif v is None:
            wi, pdf = sheen.velvet_sample(u)
        else:
            wi, pdf = np.empty((len(p), 3)), np.empty(len(p))
            wi[mf], pdf[mf] = self._sample_microfiber(p.take(mf), wo[mf], u[mf])
            wi[v], pdf[v] = sheen.velvet_sample(u[v])
        return LobeSample(wi=wi, pdf=np.where(wo[:, 2] > 0, pdf, 0.0), delta=False, label=LABEL_DIFFUSE)

    def albedo_parts(self, p, wo, weight, estimate):
        velvet = p.velvet[:, None]
        return [(CLASS_DIFFUSE, np.where(velvet, 0.0, estimate)), (CLASS_GLOSSY, np.where(velvet, estimate, 0.0))]

    def stores_photons(self, m, lobe, min_roughness):
        # Both models spread light over a wide solid angle at any roughness (the smoothest
        # microfiber lobe still covers tens of degrees near grazing; the velvet is sampled
        # uniformly): no sheen path is specular, so photons are stored as on diffuse surfaces.
        return np.ones(len(lobe), bool)

    def analysis_albedo(self, m, lobe, color, min_roughness):
        a = np.maximum(mean_albedo(m, lobe, color), 0.0)
        velvet = m.lobe_distribution[lobe] == DIST_VELVET
        # Microfiber: its mean albedo over the hemisphere at the row's roughness.
        return {"diffuse": np.where(velvet, a, a * sheen.mean_albedo(m.lobe_roughness[lobe]))}
