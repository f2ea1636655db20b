"""Path tracing with a caustic photon map (issue 11: what `auto` picks for caustics of small lights).

A path tracer finds the light that glass and mirrors focus onto a diffuse surface (L S+ D)
only when a path leaving that surface through the specular chain happens to hit the light:
rarely for a small light, never for a point light. The caustic map (Jensen 2001) estimates
exactly that light. Here the two split the light at a camera path's first diffuse point x
(reached through specular surfaces, as `photon`'s camera pass does) without overlap:

  caustics   the caustic map's estimate at x (light that arrived through specular surfaces
             only: the photon tracer's caustic photons);
  direct     one light sample at x, combined by the balance heuristic with the BSDF sample
             below when it hits an emitter directly;
  the rest   the BSDF sample at x is followed through specular surfaces collecting nothing
             (that light is the caustic map's) to the first diffuse point y, from which the
             path tracer takes over, leaving out y's own emission (a photon that left y and
             crossed the chain is a caustic photon too).

Everything beyond y, and every diffuse surface the camera does not see through specular
surfaces first, is path traced: no global map, no final gathering. Biased only by the
caustic map's blur; consistent as caustic photons grow.
"""
from __future__ import annotations

import numpy as np

from ... import rng
from ...accel import offset_origin
from ...vec import gatherer, max3, take
from .integrator import _GROUPS, _LIGHT, PhotonIntegrator, _accumulate, _sample_rows
from ..path import PathTracer
from ..surface import shading_frame, towards
from ...bsdf.closure import make_closure




class CausticPathIntegrator(PhotonIntegrator):
    name = "path_caustic"
    label = "Path Tracing + Caustic Map"
    description = ("Path tracing, with the light focused by glass and mirrors onto diffuse surfaces "
                   "(caustics) from a caustic photon map (biased by the map's blur only)")

    def __init__(self, scene):
        super().__init__(scene)
        from ...tracer import BatchLayout

        self.layout = BatchLayout(scene)  # one continuation per camera path: the path tracer's batches
        self.n_global_items = 0  # no global map: the path tracer finds the rest
        self._counters["global"] = "no global map: path tracing beyond the first diffuse point"

    @classmethod
    def memory_estimate(cls, scene) -> int:
        from .integrator import PHOTON_BYTES

        return 2 * PHOTON_BYTES * (scene.settings.caustic_photons // 10)

    def build(self, ctx) -> None:
        super().build(ctx)
        self.path_tracer = PathTracer(self.scene, ctx.accel, ctx.lights)

    def _shade_diffuse(self, L, sampler, idx, x, beta, p, ng_f, ns, wo, prim, bsdf, sample, pixel, depth, dist):
        s = self.scene.settings
        at = gatherer(x, len(idx))
        rows, bx = idx[x], at(beta)
        self._caustics_at(L, rows, x, bx, at, p, ng_f, bsdf)
        self._direct_light(L, sampler.get(1 + _GROUPS * depth + _LIGHT, rows, 3), rows, x, bx, at, p, ng_f, ns,
                           prim, bsdf, 1)
        # One BSDF sample at x: the other strategy of direct light, then the rest of the path.
        gs = rng.Sampler(s.seed, pixel[rows], sample[rows], s.pattern, domain=rng.GATHER)
        bs = _sample_rows(bsdf, x, gs.get(0, None, 3))
        g = np.flatnonzero(bs.valid)
        d = take(bs.wi, g)
        o64 = take(p, x[g])
        o32 = offset_origin(o64, towards(take(ng_f, x[g]), d))
        beta_g = take(bx, g) * take(bs.weight, g)
        _accumulate(L, rows, self._trace_gather(gs, len(x), g, beta_g, d, o64, o32, prim[x[g]],
                                                (bs.pdf[g], bs.delta[g]), emission_only=True))
        # The path tracer's numbers: the GATHER stream at pixels W*H and up (nothing else uses them).
        ps = lambda r: rng.Sampler(s.seed, pixel[rows][r] + s.width * s.height, sample[rows][r], s.pattern,  # noqa: E731
                                   domain=rng.GATHER)
        _accumulate(L, rows, self._beyond(gs, ps, len(x), g, beta_g, d, o64, o32, prim[x[g]],
                                          max(s.max_depth - depth - 1, 0)))

    def _beyond(self, gs, ps, K, g, beta, d, o64, o32, skip, budget):
        """Radiance (K,3) x beta that the first diffuse surface y along each ray (rows g of K)
        reflects back, following specular surfaces on the way without collecting light; from
        y on the path tracer (ps(rows of K): its sampler), without y's emission. gs: the
        chain's BSDF groups (from 1); budget: bounces left."""
        scene, mesh = self.scene, self.scene.mesh
        out = np.zeros((K, 3))
        for k in range(budget + 1):
            if len(g) == 0:
                break
            hit = self.ctx.accel.intersect(o32, d, None, skip)
            keep = np.flatnonzero(hit.prim >= 0)
            mat = mesh.material[hit.prim[keep]]
            y = keep[self.stores[mat]]
            if len(y):  # the path tracer re-traces the ray to y (first_emission False: not y's light)
                Ly = self.path_tracer.trace(ps(g[y]), take(o64, y), take(o32, y), take(d, y), None, skip[y],
                                            first_emission=False, max_depth=max(budget - k - 1, 0))
                np.add.at(out, g[y], take(beta, y) * Ly)
            c = keep[~self.stores[mat]]
            if len(c) == 0 or k == budget:
                break
            wo = -take(d, c)
            prim_c = hit.prim[c]
            ng_c, ns_c = shading_frame(mesh, self.flat_normal, prim_c, take(hit.b, c), take(hit.ng, c), wo)
            bsdf_c = make_closure(scene, self.lambert_albedo, mesh.material[prim_c], ns_c, ng_c, wo, prim_c,
                                  take(hit.b, c))
            u = gs.get(1 + k, g[c], 3)
            bc = bsdf_c.sample(u[:, :2], u[:, 2])
            ok = np.flatnonzero(bc.valid & (max3(bc.weight) > 0))
            g, beta = g[c[ok]], take(beta, c[ok]) * take(bc.weight, ok)
            d = take(bc.wi, ok)
            o64 = take(hit.p, c[ok])
            o32 = offset_origin(o64, towards(take(ng_c, ok), d))
            skip = prim_c[ok]
        return out

