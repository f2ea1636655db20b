"""Path tracing with a caustic photon map (`auto` prefers `photon`, see engine/choice/rule.py).

A path tracer finds the light that glass and mirrors focus onto a diffuse surface (L S+ D)
only when a path leaving that surface through the specular chain happens to hit the light:
rarely for a small light, never for a point light. The caustic map (Jensen 2001) estimates
exactly that light. Here the two split the light at a camera path's first diffuse point x
(reached through specular surfaces, as `photon`'s camera pass does) without overlap:

  caustics   the caustic map's estimate at x (light that arrived through specular surfaces
             only: the photon tracer's caustic photons);
  direct     one light sample at x, combined by the balance heuristic with the BSDF sample
             below when it hits an emitter directly;
  the rest   the path tracer from x along the same BSDF sample, collecting nothing until it
             reaches a diffuse point y (Gather.caustic_ends of PathTracer.trace: that light is the
             caustic map's, y's own emission too - a photon that left y and crossed the
             specular chain is a caustic photon).

Everything from y on is path traced: no global map, no final gathering. Biased only by the
caustic map's blur; consistent as caustic photons grow.
"""
from __future__ import annotations

import numpy as np

from ... import rng
from ...accel import offset_origin
from ...vec import gatherer, scale, take
from .integrator import _GROUPS, _LIGHT, PHOTON_BYTES, PhotonIntegrator, _accumulate, _sample_rows
from ..path import PathTracer
from ..path_options import Gather
from ..path_state import PathState
from ..surface import towards
from ...layout import BatchLayout


class CausticPathIntegrator(PhotonIntegrator):
    name = "path_caustic"
    label = "Path Tracing + Caustic Map"
    description = ("Path tracing, with the light focused by glass and mirrors onto diffuse surfaces "
                   "(caustics) from a caustic photon map (biased by the map's blur only)")

    def __init__(self, scene):
        super().__init__(scene)
        self.layout = BatchLayout(scene)  # one continuation per camera path: the path tracer's batches
        self.n_global_items = 0  # no global map: the path tracer finds the rest
        self._counters["global"] = "no global map: path tracing beyond the first diffuse point"

    @classmethod
    def batch_rays(cls, scene, paths: int) -> int:  # one continuation per camera path
        return min(int(scene.settings.batch_size), paths)

    @classmethod
    def memory_estimate(cls, scene) -> int:
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
        if self.shadows.shading_offset is not None:  # the terminator's Shading Offset
            bs.weight = scale(bs.weight, self.shadows.shading_factor(prim[x], take(bsdf.ns, x), bs.wi))
        g = np.flatnonzero(bs.valid)
        d = take(bs.wi, g)
        o64 = take(p, x[g])
        o32 = offset_origin(o64, towards(take(ng_f, x[g]), d))
        beta_g, skip = take(bx, g) * take(bs.weight, g), prim[x[g]]
        rays = PathState.rays(o64, o32, d, None, skip, idx=g, beta=beta_g, pdf_prev=bs.pdf[g], no_mis=bs.delta[g])
        _accumulate(L, rows, self._trace_gather(gs, len(x), rays, emission_only=True))
        # The rest of the path: the path tracer from x along the same sample, leaving out the
        # light it finds before its first diffuse point (caustic_ends: the caustic map's, and
        # what the BSDF sample above found directly). Its numbers: the GATHER stream at pixels
        # W*H and up (nothing else uses them).
        ps = rng.Sampler(s.seed, pixel[rows][g] + s.width * s.height, sample[rows][g], s.pattern, domain=rng.GATHER)
        Lp = self.path_tracer.trace(ps, PathState.rays(o64, o32, d, None, skip),
                                    Gather(max_depth=max(s.max_depth - depth - 1, 0), caustic_ends=self.stores))
        _accumulate(L, rows[g], beta_g * Lp)

