"""Unidirectional path tracer with next-event estimation and MIS (seed 000).

At every vertex with a non-black BSDF: one light sample (light chosen by power) and one
BSDF sample that also continues the path. Direct light from the two strategies is combined
by the balance heuristic; indirect light is added in full. Russian roulette with survival
q (from the material's reflectance, fixed before sampling) is folded into the weights, as
the seed prescribes and as SmallVCM does: the BSDF strategy's effective density is q p_b,

    w_light = p_L / (p_L + q p_b),   w_bsdf = q p_b / (q p_b + p_L),

with p_L = P(light) p_light(w) for the light actually sampled or hit. Delta lights and
camera rays get weight 1.

Wavefront: one batch of paths advances one bounce at a time; each bounce is one Embree
call for all live rays (plus one occlusion call for the shadow rays) and the shading runs
per material kind over index groups.
"""
from __future__ import annotations

import numpy as np

from ..vec import dot, gatherer, max3, scale, take

from .. import camera as camera_mod
from ..accel import Accel, offset_origin
from ..bsdf.closure import make_closure, plain_lambert_albedo
from ..errors import Cancelled
from ..lights.light_set import LightSet
from ..rng import Sampler
from ..scene import Scene
from .. import passes as passes_mod
from .base import Integrator, Stage
from .light_passes import LightTally
from .surface import flat_normals, shading_frame, towards

# Random-number groups (rng.Sampler): 0 the pixel filter, then per bounce _GROUPS groups:
# light (lanes 0-1 the point on the light, 2 its choice) and BSDF (0-1 the direction, 2 the
# lobe, 3 Russian roulette). A group's lanes are stratified jointly under "sobol", so each
# 2D sample gets the best-distributed pair of lanes (0, 1).
_GROUPS = 2
_LIGHT, _BSDF = 0, 1



def _accumulate(L: np.ndarray, rows: np.ndarray, c: np.ndarray) -> None:
    """L[:, rows] += c.T for L (3,N) (rows unique): three 1-D scatters, not one slow (N,3) one."""
    for k in range(3):
        L[k][rows] += c[:, k]


class PathTracer:
    def __init__(self, scene: Scene, accel: Accel, lights: LightSet):
        self.scene = scene
        self.accel = accel
        self.lights = lights
        self.materials = scene.materials
        self.emissive_material = np.any(scene.materials.emission != 0, axis=1)  # negative emission too
        self.lambert_albedo = plain_lambert_albedo(scene.materials)
        self.flat_normal = flat_normals(scene.mesh)  # None unless every triangle is flat-shaded
        self.max_depth = scene.settings.max_depth
        self.rr_depth = scene.settings.rr_depth
        strategy = scene.settings.strategy
        self.use_nee = strategy in ("mis", "light")
        # Weight of emission found by BSDF sampling relative to MIS: "bsdf" alone counts it in
        # full (use_mis False), "light" alone drops it after non-delta bounces.
        self.bsdf_hits = strategy in ("mis", "bsdf")
        self.mis = strategy == "mis"

    def render(self, sampler, px: np.ndarray, py: np.ndarray, stop=None, tally=None) -> np.ndarray:
        """Radiance estimates (N,3), one path per pixel (px, py). Raises Cancelled if stop is set.
        tally: a LightTally that files the radiance into light passes, or None."""
        s = self.scene
        o64, d, tmax = camera_mod.generate_rays(s.camera, s.settings, px, py, sampler.get(0, None, 2))
        return self.trace(sampler, o64, o64.astype(np.float32), d, tmax, np.full(len(px), -1, np.int64), stop,
                          tally=tally)

    def trace(self, sampler, o64, o32, d, tmax, skip, stop=None, first_emission=True,
              max_depth=None, t_first=None, tally=None) -> np.ndarray:
        """Radiance (N,3) arriving along rays from o64 (float64 points; o32 their offset float32
        origins, skip the primitive each leaves or -1) in directions d; tmax (N,) or None.
        Random groups from 1 (group 0 is the caller's). first_emission False leaves out the
        emission the rays themselves find (a gather ray whose direct light is sampled apart);
        max_depth: bounces after the first hit (default: the scene's); t_first (N,), if given,
        receives the first hit's distance (inf where the ray escaped); tally: light passes
        (render, camera rays only)."""
        n = len(d)
        L = np.zeros((3, n))  # channel-major: see _accumulate
        idx = np.arange(n)  # which pixel sample each live path belongs to
        beta = np.ones((n, 3))
        pdf_prev = np.zeros(n)  # q * p_b of the bounce that produced the ray
        no_mis = np.ones(n, bool)  # camera ray: emitters seen with weight 1
        mesh = self.scene.mesh
        max_depth = self.max_depth if max_depth is None else max_depth
        for depth in range(max_depth + 1):
            if stop is not None and stop.is_set():
                raise Cancelled()
            if len(idx) == 0:
                break
            base = 1 + _GROUPS * depth
            hit = self.accel.intersect(o32, d, tmax, skip)
            if depth == 0 and t_first is not None:
                t_first[:] = np.where(hit.prim >= 0, hit.t, np.inf)
            camera_ray = np.full(len(idx), depth == 0)
            emission = first_emission or depth > 0
            # Light objects the ray passes on its way (they do not stop it).
            if len(self.lights.hittable) and emission:
                c = beta * self.lights.emission_along(o64, d, hit.t, pdf_prev, ~no_mis, camera_ray)
                _accumulate(L, idx, c)
                if tally:
                    tally.emitted(depth, idx, c)
            # Escaped rays see the suns and the world.
            missed = hit.prim < 0
            if missed.any() and self.lights.sees_escaped and emission:
                r = np.flatnonzero(missed)
                c = take(beta, r) * self.lights.escaped(take(d, r), pdf_prev[r], ~no_mis[r], camera_ray[r])
                _accumulate(L, idx[r], c)
                if tally:
                    tally.emitted(depth, idx[r], c, escaped=True)
            keep = np.flatnonzero(~missed)
            if len(keep) == 0:
                break
            o_prev = o64  # previous vertices, indexed through `keep` where needed
            idx, pdf_prev, no_mis, hit_t, prim = idx[keep], pdf_prev[keep], no_mis[keep], hit.t[keep], hit.prim[keep]
            beta, hit_p, d, bary, ng = (take(a, keep) for a in (beta, hit.p, d, hit.b, hit.ng))
            mat = mesh.material[prim]
            # Emissive triangles hit by the ray.
            emits = self.emissive_material[mat]
            if emits.any() and emission:
                r = np.flatnonzero(emits)
                Le = take(self.materials.emission, mat[r])
                cos_l = np.abs(dot(take(d, r), take(ng, r)))
                pdf_light = self.lights.pdf_triangle_hit(prim[r], take(o_prev, keep[r]), hit_t[r], cos_l)
                w = np.where(no_mis[r], 1.0, pdf_prev[r] / np.maximum(pdf_prev[r] + pdf_light, 1e-300))
                c = take(beta, r) * scale(Le, w)
                _accumulate(L, idx[r], c)
                if tally:
                    tally.emitted(depth, idx[r], c)
            if depth == max_depth:
                break
            # Shading frame, flipped to the side the ray came from (two-sided, like Cycles).
            wo = -d
            ng_f, ns = shading_frame(mesh, self.flat_normal, prim, bary, ng, wo)
            bsdf = make_closure(self.scene, self.lambert_albedo, mat, ns, ng_f, wo, prim, bary)
            ns = bsdf.ns  # may be perturbed (normal maps)
            if tally and depth == 0:
                tally.first_hit(idx, bsdf)
            albedo = max3(bsdf.reflectance)
            q = np.minimum(1.0, albedo) if depth >= self.rr_depth else np.ones(len(idx))
            m = len(idx)
            # Next-event estimation at points whose BSDF has a non-delta part.
            active = np.flatnonzero(bsdf.has_smooth)
            if len(active) and self.use_nee and not self.lights.empty:
                at = gatherer(active, m)
                u_light = sampler.get(base + _LIGHT, idx[active], 3)
                ls = self.lights.sample(at(hit_p), u_light[:, 2], u_light[:, :2])
                f, pdf_b = bsdf.eval(ls.wi, active)
                cos_i = np.abs(dot(ls.wi, at(ns)))
                pdf_b_mis = q[active] * pdf_b if self.mis else 0.0
                w = np.where(ls.delta, 1.0, ls.pdf / np.maximum(ls.pdf + pdf_b_mis, 1e-300))
                contrib = at(beta) * f * scale(ls.Le, np.divide(cos_i * w, ls.pdf, out=np.zeros(len(active)),
                                                                 where=ls.valid))
                test = np.flatnonzero(np.any(contrib != 0, axis=1))  # negative lights subtract
                if len(test):
                    rows = active[test]
                    o_shadow = offset_origin(take(hit_p, rows), towards(take(ng_f, rows), take(ls.wi, test)))
                    blocked = self.accel.occluded(o_shadow, take(ls.target, test), prim[rows], ls.target_prim[test])
                    lit = np.flatnonzero(~blocked)
                    _accumulate(L, idx[rows[lit]], take(contrib, test[lit]))
                    if tally:
                        f_cls = bsdf.eval_by_class(take(ls.wi, test[lit]), rows[lit]) if depth == 0 else None
                        tally.light_sample(depth, idx[rows[lit]], take(contrib, test[lit]), f_cls)
            # BSDF sampling continues the path; Russian roulette with survival q.
            u_bsdf = sampler.get(base + _BSDF, idx, 4)
            bs = bsdf.sample(u_bsdf[:, :2], u_bsdf[:, 2])
            if tally and depth == 0:
                tally.first_bounce(idx, bsdf, bs)
            survive = bs.valid & (u_bsdf[:, 3] < q)
            beta = beta * scale(bs.weight, np.divide(1.0, q, out=np.zeros(m), where=survive))
            survive &= max3(beta) > 0
            keep = np.flatnonzero(survive)
            idx, beta, d = idx[keep], take(beta, keep), take(bs.wi, keep)
            # Strategy switches: pdf_prev 0 makes emission found after a non-delta bounce weigh 0
            # ("light" alone); no_mis makes it weigh 1 (after delta bounces, or "bsdf" alone).
            pdf_prev = (q * bs.pdf)[keep] if self.bsdf_hits else np.zeros(len(keep))
            no_mis = bs.delta[keep] | (not self.use_nee)
            o64 = take(hit_p, keep)
            o32 = offset_origin(o64, towards(take(ng_f, keep), d))
            skip = prim[keep]
            tmax = None
        return np.ascontiguousarray(L.T)


class PathIntegrator(Integrator):
    """The path tracer as one film stage over all samples."""

    name = "path"
    label = "Path Tracing"
    description = "Unidirectional path tracing with next-event estimation and MIS (unbiased)"
    light_passes = True

    def stages(self, round: int):
        return [self.samples_stage()] if round == 0 else []

    def build(self, ctx) -> None:
        super().build(ctx)
        self.tracer = PathTracer(ctx.scene, ctx.accel, ctx.lights)
        # The light passes this render keeps (the Color passes Direct/Indirect need included).
        self.tallied = tuple(n for n in passes_mod.needed(ctx.scene.settings.passes) if n in passes_mod.LIGHT)

    def run(self, stage: Stage, item: int, stop=None) -> np.ndarray:
        layout, s = self.layout, self.scene.settings
        k = layout.paths(stage, item)
        j = k % layout.n_pixels
        sampler = Sampler(s.seed, layout.pixel[j], k // layout.n_pixels, s.pattern)
        if not self.tallied:
            return self.tracer.render(sampler, layout.px[j], layout.py[j], stop)
        tally = LightTally(len(k), self.tallied)
        L = self.tracer.render(sampler, layout.px[j], layout.py[j], stop, tally)
        return {"L": L, "passes": tally.passes()}
