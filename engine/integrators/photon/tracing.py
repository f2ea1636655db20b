"""Photon tracing (seed 001, Jensen 2001 ch. 5): wavefront, one Embree call per bounce.

Photons leave the lights with flux chosen so that E[flux] is the lights' power
(engine/lights/emission.py). At every hit the surface's BSDF is sampled in its adjoint form
(the same closure as camera paths; refraction does not scale flux by 1/eta^2), and Russian
roulette keeps max(flux) constant: a photon survives with q = min(1, max(beta f cos / pdf) /
max(beta)) and is divided by q (pbrt-v4 SPPM), so for grey surfaces every photon carries the
same flux and the survival probability is the reflectance, as the seed asks.

Photons are stored at every hit on a *diffuse* surface (`diffuse_materials`: a diffuse or
moderately rough lobe), the first hit from the light included, absorbed ones included.
A photon whose every earlier bounce was specular (delta, or on a surface too sharp to store),
with at least one, is also a caustic photon (L S+ D). Paths whose incoming direction is on
different sides of the geometric and shading normals are dropped, so light does not leak
through smooth-shaded geometry (Veach 1997 p. 158; Mitsuba 0.6 particleproc).
"""
from __future__ import annotations

import numpy as np

from ...bsdf import lobes
from ...bsdf.fast_path import make_closure, plain_lambert_albedo
from ...nodes.material import MaterialPrograms
from ...errors import Cancelled
from ...scene import Materials
from ...vec import dot, max3, scale, take
from ..path_state import PathState
from ..surface import flat_normals, shading_frame

# Smallest GGX roughness (Blender's, alpha = roughness^2) whose lobe stores photons: sharper
# lobes are followed as specular (their radiance estimate from photons would be too blurred).
MIN_STORE_ROUGHNESS = 0.3

# Random-number groups of a photon path: 0 the origin (lanes 0-1) and the light (lane 2),
# 1 the direction (0-1), then per bounce one group: direction (0-1), lobe (2), roulette (3).
EMIT_POS, EMIT_DIR, FIRST_BOUNCE = 0, 1, 2


def diffuse_materials(m: Materials) -> np.ndarray:
    """(M,) bool: materials with a lobe that stores photons (each lobe says: diffuse, Phong
    with a diffuse part, microfacet or rough glass with roughness >= MIN_STORE_ROUGHNESS)."""
    stores = lobes.stores_photons(m, MIN_STORE_ROUGHNESS) & (m.lobe_weight.max(axis=1) > 0)
    return np.bincount(m.lobe_material[stores], minlength=len(m.kind)) > 0


class PhotonTracer:
    def __init__(self, ctx, emitter, max_depth: int):
        self.scene, self.accel, self.emitter = ctx.scene, ctx.accel, emitter
        self.lambert_albedo = plain_lambert_albedo(ctx.scene.materials)
        self.programs = MaterialPrograms.of(ctx.scene.materials)
        self.flat_normal = flat_normals(ctx.scene.mesh)
        self.stores = diffuse_materials(ctx.scene.materials)
        self.max_depth = max_depth
        self.lights = ctx.lights

    def trace(self, sampler, caustic_only: bool, stop=None) -> dict:
        """Trace one photon path per row of `sampler` (domain PHOTONS).

        Returns position, wi (toward where the photon came from), normal (the geometric normal
        on the arrival side), flux (M,3) float32, caustic (M,) bool and first (M,) bool (the
        photon's first hit: direct light) of the stored photons,
        and `bounces` (the photon-surface interactions traced, for statistics). caustic_only:
        only caustic photons are stored and paths end at their first diffuse hit."""
        u0 = sampler.get(EMIT_POS, None, 3)
        em = self.emitter.sample(u0[:, 2], u0[:, :2], sampler.get(EMIT_DIR, None, 2))
        live = np.flatnonzero(em.valid)
        # specular: every bounce so far specular (none yet)
        photons = PathState.rays(None, take(em.o, live).astype(np.float32), take(em.d, live), None, em.prim[live],
                                 idx=live, beta=take(em.flux, live), specular=np.ones(len(live), bool))
        out = {key: [] for key in ("position", "wi", "normal", "flux", "caustic", "first")}
        mesh, bounces = self.scene.mesh, 0
        while True:
            if stop is not None and stop.is_set():
                raise Cancelled()
            if len(photons) == 0:
                break
            hit = photons.intersect(self.accel)
            photons = photons.arrive(hit, np.flatnonzero(hit.prim >= 0), mesh.material)
            if photons.depth == 0 and self.lights.light_linked and len(photons):
                photons = self._linked(photons, em.light)
            if len(photons) == 0:
                break
            bounces += len(photons)
            wo = -photons.d  # toward where the photon came from
            photons.ng, photons.ns = shading_frame(mesh, self.flat_normal, photons.prim, photons.bary, photons.ng, wo)
            diffuse = self.stores[photons.mat]
            self._store(out, photons, wo, diffuse, caustic_only)
            go = ~diffuse if caustic_only else np.ones(len(photons), bool)
            go &= dot(wo, photons.ns) > 0  # shading and geometric normals disagree: a leak, drop
            if photons.depth == self.max_depth or not go.any():
                break
            if not go.all():
                g = np.flatnonzero(go)
                photons, diffuse = photons.take(g), diffuse[g]
            photons = self._scatter(sampler, photons, diffuse)
        arrays = {key: (np.concatenate(v) if v else np.zeros((0, 3), np.float32)) for key, v in out.items()
                  if key not in ("caustic", "first")}
        for key in ("caustic", "first"):
            arrays[key] = np.concatenate(out[key]) if out[key] else np.zeros(0, bool)
        arrays["bounces"] = np.array([bounces])
        return arrays

    def _linked(self, photons: PathState, light: np.ndarray) -> PathState:
        """The photons at their first hits that their emitters (light (N,) by photon row) light:
        light linking keeps a linked emitter's light off the other objects (a constant world's
        photons, index past the LightSet's emitters, reach everything)."""
        emitter = light[photons.idx]
        links = self.lights.links
        known = emitter < len(links.receive)
        ok = ~known
        r = np.flatnonzero(known)
        ok[r] = links.lights(emitter[r], links.receiver(photons.prim[r]))
        return photons if ok.all() else photons.take(np.flatnonzero(ok))

    @staticmethod
    def _store(out: dict, photons: PathState, wo: np.ndarray, diffuse: np.ndarray, caustic_only: bool) -> None:
        """Files the photons that hit a diffuse surface (caustic_only: the caustic ones) into out."""
        caustic = photons.specular & (photons.depth > 0) & diffuse
        store = caustic if caustic_only else diffuse
        if not store.any():
            return
        r = np.flatnonzero(store)
        out["position"].append(take(photons.p, r).astype(np.float32))
        out["wi"].append(take(wo, r).astype(np.float32))
        out["normal"].append(take(photons.ng, r).astype(np.float32))
        out["flux"].append(take(photons.beta, r).astype(np.float32))
        out["caustic"].append(caustic[r])
        out["first"].append(np.full(len(r), photons.depth == 0))

    def _scatter(self, sampler, photons: PathState, diffuse: np.ndarray) -> PathState:
        """The photons' next bounce: the BSDF sampled in its adjoint form, Russian roulette
        with survival q = max(beta') / max(beta) (so max(flux) stays constant)."""
        bsdf = make_closure(self.scene, self.lambert_albedo, photons.mat, photons.ns, photons.ng, -photons.d,
                            photons.prim, photons.bary, programs=self.programs, p=photons.p, adjoint=True)
        u = sampler.get(FIRST_BOUNCE + photons.depth, photons.idx, 4)
        bs = bsdf.sample(u[:, :2], u[:, 2])
        w = bs.weight if bs.refraction_eta2 is None else scale(bs.weight, bs.refraction_eta2)
        beta, beta_new = photons.beta, photons.beta * w
        q = np.minimum(1.0, np.divide(max3(beta_new), max3(beta), out=np.zeros(len(photons)), where=max3(beta) > 0))
        survive = bs.valid & (u[:, 3] < q) & (max3(beta_new) > 0)
        keep = np.flatnonzero(survive)
        photons = photons.leave(keep, take(bs.wi, keep), scale(take(beta_new, keep), 1.0 / q[keep]))
        photons.specular &= ~diffuse[keep]
        return photons
