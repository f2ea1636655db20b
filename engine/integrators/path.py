"""Unidirectional path tracer with next-event estimation and MIS (seed 000).

At every vertex with a non-black BSDF: one light sample (light chosen by power) and one
BSDF sample that also continues the path. Direct light from the two strategies is combined
by the balance heuristic; indirect light is added in full. Russian roulette with survival
q (from the material's reflectance, fixed before sampling) is folded into the weights, as
the seed prescribes and as SmallVCM does: the BSDF strategy's effective density is q p_b,

    w_light = p_L / (p_L + q p_b),   w_bsdf = q p_b / (q p_b + p_L),

with p_L = P(light) p_light(w) for the light actually sampled or hit. Delta lights and
camera rays get weight 1.

Wavefront: one batch of paths (a PathState) advances one bounce at a time; each bounce is
one Embree call for all live rays (plus one occlusion call for the shadow rays) and the
shading runs per material kind over index groups. A bounce is a few steps (PathTracer.trace),
each with its options in a record (path_options.py).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..vec import dot, gatherer, max3, normalize, scale, take

from .. import camera as camera_mod
from ..accel import Accel, offset_origin
from ..bsdf.closure import LABEL_TRANSMIT, LABEL_TRANSPARENT
from ..bsdf.fast_path import make_closure, plain_lambert_albedo
from ..nodes import light_path as lp
from ..nodes.hits import COUNT_FIELDS, RayState, camera_differentials, camera_footprint
from ..nodes.material import MaterialPrograms
from ..nodes.rays import SceneRays, ShaderRays
from ..errors import Cancelled
from ..lights.light_set import LightSet
from ..rng import Sampler
from ..scene import RAY_CAMERA, RAY_SHADOW, Scene
from .. import passes as passes_mod
from ..visibility import RayVisibility
from ..volumes import Media
from .base import Integrator, Stage
from .light_passes import LightTally
from .media import MediumSteps, after_crossing
from .path_options import CAMERA_PATHS, Clamp, ClosureOptions, Gather, LightPaths, Strategy
from .path_state import PathState, rows_of
from .shadows import ShadowRays
from .surface import emitted, flat_frame_rows, flat_frames, flat_normals, shading_frame, towards
from ..layout import BatchLayout

# Random-number groups (rng.Sampler): 0 the pixel filter, then per bounce _GROUPS groups:
# light (lanes 0-1 the point on the light, 2 its choice) and BSDF (0-1 the direction, 2 the
# lobe, 3 Russian roulette). A group's lanes are stratified jointly under "sobol", so each
# 2D sample gets the best-distributed pair of lanes (0, 1).
_GROUPS = 2
_LIGHT, _BSDF = 0, 1

# Path regeneration (PathTracer.render): an item holds ITEM_BATCHES batches of camera paths,
# which run in a pool of one batch (Settings.batch_size) of live paths, topped up with the
# item's next camera paths whenever fewer than REFILL_BELOW x the pool remain. The narrow
# bounces of the pool's last paths (the tail) then come once per item instead of once per
# batch (bench/results/tail/notes.md).
ITEM_BATCHES = 4
REFILL_BELOW = 0.5


def _accumulate(L: np.ndarray, rows: np.ndarray, c: np.ndarray) -> None:
    """L[:, rows] += c.T for L (3,N) (rows unique): three 1-D scatters, not one slow (N,3) one."""
    for k in range(3):
        L[k][rows] += c[:, k]


def _light_group(depth):
    return 1 + _GROUPS * depth + _LIGHT


def _bsdf_group(depth):
    return 1 + _GROUPS * depth + _BSDF


class PathTracer:
    def __init__(self, scene: Scene, accel: Accel, lights: LightSet, media: bool = False):
        """media: render the materials' volumes (the path integrator's camera paths; other
        integrators leave them out, with a warning from validation)."""
        self.scene, self.accel, self.lights = scene, accel, lights
        self.mesh, self.materials = scene.mesh, scene.materials
        emissive = np.any(scene.materials.emission != 0, axis=1)  # per material; negative emission too
        self.emissive_prim = np.append(emissive[scene.mesh.material], False)  # per triangle; a miss (-1): False
        self.lambert_albedo = plain_lambert_albedo(scene.materials)
        self.programs = MaterialPrograms.of(scene.materials)
        self.flat_normal = flat_normals(scene.mesh)  # None unless every triangle is flat-shaded
        self.flat_frames = flat_frames(scene.mesh, self.flat_normal, accel.ng)  # or None
        # Barycentrics serve smooth normals and the general closure (textures) only.
        self.needs_bary = self.flat_normal is None or bool(np.isnan(self.lambert_albedo).any())
        self.visibility = RayVisibility(accel, scene.mesh)  # objects hidden from some rays
        self.shadows = ShadowRays(scene, self.visibility, self.programs, lights.links)  # transparency, linking
        st = scene.settings
        self.strategy = Strategy.of(st.strategy)
        self.clamp = Clamp.of(st)  # None: off
        self.light_paths = LightPaths.of(scene, lights, self.visibility)
        self.closure_options = ClosureOptions.of(st)
        # What node programs read of the path: its flags, its counts by kind, its differentials.
        reads = self.programs.reads | lights.world_reads
        self.track_flag = "path_flag" in reads
        self.track_dP = "dP" in reads
        self.track = self.track_flag or self.track_dP or bool(reads & COUNT_FIELDS) or "min_ray_pdf" in reads
        if reads & COUNT_FIELDS - {"bounce"} and not self.light_paths.counts:
            self.light_paths = dataclasses.replace(self.light_paths, counts=True)
        if "min_ray_pdf" in reads and not self.light_paths.min_pdf:
            self.light_paths = dataclasses.replace(self.light_paths, min_pdf=True)
        # Programs that trace rays (Ambient Occlusion, Bevel): what they trace against.
        self.shader_rays = None
        if "ray_queries" in reads:
            self.shader_rays = SceneRays(self.visibility.views.get(RAY_SHADOW, accel), accel, scene.mesh)
        table = Media.of(scene.materials) if media else None
        self.media = None if table is None else MediumSteps(self, table, _light_group, _bsdf_group)

    def render(self, sampler, px: np.ndarray, py: np.ndarray, stop=None, tally=None) -> np.ndarray:
        """Radiance estimates (N,3), one path per pixel (px, py). Raises Cancelled if stop is set.
        tally: a LightTally that files the radiance into light passes, or None. Without one,
        the paths run in a pool of one batch, topped up as paths end (path regeneration)."""
        s = self.scene
        o64, d, tmax = camera_mod.camera_rays(s.camera, s.settings, px, py, sampler)
        paths = PathState.rays(o64, o64.astype(np.float32), d, tmax, np.full(len(px), -1, np.int64))
        if tally is not None:  # light passes count per bounce: those items are one batch
            return self.trace(sampler, paths, stop=stop, tally=tally)
        refill = _Refill(paths, pool=s.settings.batch_size)
        return self.trace(sampler, refill.take(min(refill.pool, refill.n)), stop=stop, refill=refill)

    def trace(self, sampler, paths: PathState, gather: Gather = CAMERA_PATHS, stop=None, tally=None,
              refill=None) -> np.ndarray:
        """Radiance (N,3) arriving along the rays of `paths` (PathState.rays: its rows idx are
        the result's; the trace takes the state over). Random groups from 1 (group 0 is the
        caller's). gather: what the trace collects (camera paths by default); tally: light
        passes (render, camera rays only); raises Cancelled if stop is set.

        refill: a _Refill (path regeneration) whose first paths are the ones given: the live
        paths are topped up with its next ones whenever fewer than REFILL_BELOW x its pool
        remain, and the result has a row for each of its paths. Paths then sit at different
        bounces (depth per path), yet each path draws the same numbers and sums the same
        terms in the same order, so the result is the same bit for bit."""
        L = np.zeros((3, len(paths) if refill is None else refill.n))  # channel-major: see _accumulate
        max_depth = self.light_paths.max_depth if gather.max_depth is None else gather.max_depth
        rays = self.light_paths.rays_at_most(max_depth)
        paths = self._start(paths, gather, max_depth, per_path=refill is not None or self.media is not None)
        t_first = gather.t_first  # the first rays' only
        while True:
            if stop is not None and stop.is_set():
                raise Cancelled()
            paths = self._top_up(paths, refill, gather, max_depth)  # path regeneration
            if len(paths) == 0:
                break
            hit = paths.intersect(self.visibility, paths.bounces.ray, t_first)  # one Embree call
            t_first = None
            scattered = None  # paths that collide in a medium, on their next rays
            if self.media is not None:
                paths, hit, scattered = self.media.propagate(L, sampler, paths, hit)
            self._emission(L, paths, hit, gather, tally, sampler)  # found by the rays, weighted by MIS
            paths = paths.arrive(hit, np.flatnonzero(hit.prim >= 0), self.mesh.material, self.needs_bary)
            paths = self._terminate(paths)  # bounce limits, holdouts
            if len(paths) == 0 and not (refill is not None and refill.left > 0) and scattered is None:
                break
            bsdf = self._closure(paths, tally, sampler)
            q = self._survival(paths, bsdf)  # Russian roulette's, fixed before sampling
            if paths.specular is not None:  # light found from a caustic end on is not the caustic map's
                paths.specular &= ~gather.caustic_ends[paths.mat]
            self._next_event(L, sampler, paths, bsdf, q, tally)  # one light sample
            paths = self._scatter(sampler, paths, bsdf, q, tally)  # one BSDF sample goes on
            if scattered is not None:
                paths = paths.join(scattered)
            if np.ndim(paths.depth) == 0:  # a path traces at most `rays` rays
                if paths.depth >= rays:
                    break
            elif len(paths) and paths.depth.max() >= rays:
                paths = paths.take(np.flatnonzero(paths.depth < rays))
        return np.ascontiguousarray(L.T)

    def _start(self, paths: PathState, gather: Gather, max_depth: int, per_path: bool) -> PathState:
        """paths on their first rays as this tracer's: throughput 1, emission found by the
        rays with weight 1 (camera rays), no bounce yet; per_path: depth and bounce counts per
        path (regeneration). The arrays are set in place."""
        n = len(paths)
        paths.beta, paths.pdf_prev, paths.no_mis = np.ones((n, 3)), np.zeros(n), np.ones(n, bool)
        if paths.tmax is not None:  # a panoramic camera's rays outside its image carry nothing
            paths.beta[paths.tmax <= 0.0] = 0.0
        paths.specular = np.ones(n, bool) if gather.caustic_ends is not None else None
        paths.depth = np.zeros(n, np.int64) if per_path else 0
        paths.t_mis = np.zeros(n) if self.light_paths.any_transparent else None
        paths.receiver = np.full(n, -1, np.int64) if self.lights.light_linked else None
        paths.bounces = self.light_paths.start(n, max_depth, per_path)
        if self.track:
            self._track(paths, gather)
        if self.media is not None:
            self.media.start(paths)
        return paths

    def _track(self, paths: PathState, gather: Gather) -> None:
        """The path flags and ray differentials of the first rays, for node programs. Camera
        paths (the render's: they keep their first emission and have no caustic ends) start
        as Cycles' camera rays: CAMERA, the camera's differentials with dP moved to the ray's
        start (its near clip: Cycles moves dP with it). Other traces start from a surface
        point (the irradiance cache's and the caustic path's gather rays): their rays are
        counted as leaving a diffuse bounce there (REFLECT | DIFFUSE, one bounce), their
        differentials the camera's at that point, as if it were a camera ray's first hit."""
        n, s = len(paths), self.scene
        camera = gather.first_emission and gather.caustic_ends is None
        dP = dD = None
        if self.track_dP:
            eye = np.asarray(s.camera.world_from_camera, np.float64)[:3, 3]
            if camera:
                dP, dD = camera_differentials(s, paths.d)
                dP = dP + np.linalg.norm(paths.o64 - eye, axis=1) * dD
            else:
                dP = camera_footprint(s, paths.o64)
                dD = camera_differentials(s, normalize(paths.o64 - eye))[1]
        flag = None
        if self.track_flag:
            flag = np.full(n, lp.CAMERA if camera else lp.REFLECT | lp.DIFFUSE, np.uint32)
        paths.bounces.track(flag, dP, dD, base=0 if camera else 1)

    def _top_up(self, paths: PathState, refill, gather: Gather, max_depth: int) -> PathState:
        """Path regeneration: fewer than REFILL_BELOW x the pool live, the pool is topped up
        with the item's next paths (appended, at bounce 0)."""
        if refill is None or refill.left == 0 or len(paths) >= REFILL_BELOW * refill.pool:
            return paths
        k = min(refill.pool - len(paths), refill.left)
        return paths.join(self._start(refill.take(k), gather, max_depth, per_path=True))

    def _emission(self, L, paths: PathState, hit, gather: Gather, tally, sampler) -> None:
        """Emission the rays find, weighted by the balance heuristic against light sampling
        (pdf_prev / (pdf_prev + p_L); 1 where no_mis): light objects they pass on their way
        (those do not stop them), suns and the world where they escape, emissive triangles
        they hit. Emission is "direct" for clamping after at most one bounce."""
        lit = self._lit(paths, gather)
        if lit is False:
            return
        lights, b, depth, idx = self.lights, paths.bounces, paths.depth, paths.idx
        kind = b.ray  # None when no visibility or caustics toggle needs it
        camera_ray = kind == RAY_CAMERA if kind is not None else np.broadcast_to(depth == 0, len(paths))
        direct = b.total <= 1 if self.clamp is not None else None
        use_mis = ~paths.no_mis
        # After transparent passes the MIS state is the last vertex's, o_mis, t_mis behind the origin.
        o_mis, t_mis = paths.o64, None
        if paths.t_mis is not None and paths.t_mis.any():
            t_mis = paths.t_mis
            o_mis = paths.o64 - scale(paths.d, t_mis)
        if len(lights.hittable):
            c = paths.beta * lights.emission_along(o_mis, paths.d, hit.t if t_mis is None else hit.t + t_mis,
                                                   paths.pdf_prev, use_mis, camera_ray, kind, tmin=t_mis,
                                                   receiver=paths.receiver)
            if lit is not None:
                c[~lit] = 0.0
            if paths.medium is not None:  # found in media: MediumSteps.propagate weighed those
                c[paths.medium >= 0] = 0.0
            self._add(L, idx, self._clamp(c, direct), tally, depth)
        missed = hit.prim < 0
        if lights.sees_escaped and missed.any():
            r = np.flatnonzero(missed if lit is None else missed & lit)
            c = take(paths.beta, r) * lights.escaped(take(paths.d, r), paths.pdf_prev[r], use_mis[r], camera_ray[r],
                                                     None if kind is None else kind[r],
                                                     b.record(r) if lights.world_reads else None,
                                                     None if paths.receiver is None else paths.receiver[r])
            self._add(L, idx[r], self._clamp(c, direct, r), tally, depth, escaped=True)
        emits = self.emissive_prim[hit.prim]
        if lit is not None:
            emits &= lit
        if paths.receiver is not None and emits.any():  # light linking: lights linked to the ray's origin
            emits &= lights.links.lights(lights.light_of_prim[np.maximum(hit.prim, 0)], paths.receiver)
        if emits.any():
            r = np.flatnonzero(emits)
            prim, pdf_prev = hit.prim[r], paths.pdf_prev[r]
            Le = take(self.materials.emission, self.mesh.material[prim])
            ray = self._ray_state(b.record(r, hit.t[r]) if self.track else None, prim, sampler, idx[r],
                                  rows_of(depth, r))
            at = hit.take(r)
            Le = emitted(self.scene, self.programs, self.flat_normal, Le, at, take(paths.d, r), ray)
            cos_l = np.abs(dot(take(paths.d, r), at.ng))
            pdf_light = lights.pdf_triangle_hit(prim, take(o_mis, r), hit.t[r] if t_mis is None else hit.t[r] + t_mis[r],
                                                cos_l, at.b, None if paths.receiver is None else paths.receiver[r])
            w = np.where(paths.no_mis[r], 1.0, pdf_prev / np.maximum(pdf_prev + pdf_light, 1e-300))
            self._add(L, idx[r], self._clamp(take(paths.beta, r) * scale(Le, w), b.total <= 1, r), tally, depth)

    @staticmethod
    def _lit(paths: PathState, gather: Gather):
        """Whose found light counts: None (every path's), False (none's) or (N,) bool."""
        lit = gather.first_emission or paths.depth > 0
        if paths.specular is not None:
            lit = lit & ~paths.specular
        if np.ndim(lit) == 0:
            return None if lit else False
        return lit if lit.any() else False

    def _terminate(self, paths: PathState) -> PathState:
        """The paths that go on from their vertices. A path past a bounce limit ends there,
        except through transparent surfaces when the limit was not the transparent one
        (Cycles' path_state_next); camera rays end black on holdout objects."""
        b, lp = paths.bounces, self.light_paths
        ends = b.last & ~lp.transparent[paths.mat] if lp.any_transparent else b.last
        if b.stop is not None:
            ends = ends | b.stop
        if self.visibility.holdout is not None:
            ends = ends | (self.visibility.holdout[paths.prim] & (b.ray == RAY_CAMERA))
        return paths.take(np.flatnonzero(~ends)) if ends.any() else paths

    def _closure(self, paths: PathState, tally, sampler):
        """The BSDF at the paths' vertices, in the shading frame flipped to the side the ray
        came from (two-sided, like Cycles); paths.ng becomes the flipped geometric normal.
        Programs that trace rays get the scene and the paths' numbers of `sampler`."""
        wo = -paths.d
        frame = None
        if self.flat_frames is not None:
            ng_f, ns, *frame = flat_frame_rows(self.flat_frames, paths.prim, paths.ng, wo)
        else:
            ng_f, ns = shading_frame(self.mesh, self.flat_normal, paths.prim, paths.bary, paths.ng, wo)
        paths.ng = ng_f
        b, options = paths.bounces, self.closure_options
        ray = self._ray_state(b.record() if self.track else None, paths.prim, sampler, paths.idx, paths.depth)
        bsdf = make_closure(self.scene, self.lambert_albedo, paths.mat, ns, ng_f, wo, paths.prim, paths.bary,
                            options.no_caustics(b), options.blur(b), frame, self.programs, paths.p, ray)
        if tally and paths.depth == 0:
            tally.first_hit(paths.idx, bsdf)
        return bsdf

    def _ray_state(self, ray, prim, sampler, idx, depth):
        """The record `ray` (a RayState, or None) of paths idx (N,) at their vertices on
        triangles prim (N,), at bounce depth, with the ray queries their programs may make
        (Ambient Occlusion, Bevel) where some program traces rays. One vertex draws the same
        numbers for its emission and its closure, so both see the same occlusion."""
        if self.shader_rays is None:
            return ray
        ray = ray if ray is not None else RayState(lp.CAMERA)
        ray.rays = ShaderRays(self.shader_rays, prim, sampler, idx, depth)
        return ray

    def _survival(self, paths: PathState, bsdf) -> np.ndarray:
        """Russian roulette's survival probability q (N,): the BSDF's largest reflectance
        (at most 1), fixed before sampling; 1 for the first rr_depth bounces."""
        return np.where(paths.depth >= self.light_paths.rr_depth, np.minimum(1.0, max3(bsdf.reflectance)), 1.0)

    def _next_event(self, L, sampler, paths: PathState, bsdf, q: np.ndarray, tally) -> None:
        """One light sample at every vertex whose BSDF has a non-delta part, weighted against
        the BSDF strategy (q p_b: roulette folded in); shadow rays for non-zero terms only."""
        if not self.strategy.nee or self.lights.empty:
            return
        m, b, reflects = len(paths), paths.bounces, bsdf.reflects_only  # reflects: every wi on ng's side
        # A Lambertian closure's black points (emitters) get exact zeros from it: sampling them too
        # spares gathering every array for the others.
        smooth = np.ones(m, bool) if reflects else bsdf.has_smooth
        if self.light_paths.any_transparent:  # a path at its last vertex only passes transparency
            smooth = smooth & ~b.last
        if paths.specular is not None:
            smooth = smooth & ~paths.specular
        active = np.flatnonzero(smooth)
        if len(active) == 0:
            return
        at = gatherer(active, m)
        u = sampler.get(1 + _GROUPS * rows_of(paths.depth, active) + _LIGHT, at(paths.idx), 3)
        ls = self.lights.sample(at(paths.p), u[:, 2], u[:, :2], in_unit=True,
                                ray=b.record(active) if self.lights.world_reads else None,
                                receiver=self.lights.receivers(at(paths.prim)) if self.lights.light_linked else None)
        shadows = self.shadows
        f, pdf_b = bsdf.eval(ls.wi, active, ls.visibility,
                             None if shadows.geometry_offset is None else shadows.lifted(at(paths.prim)))
        if shadows.shading_offset is not None:  # the terminator's Shading Offset
            f = scale(f, shadows.shading_factor(at(paths.prim), at(bsdf.ns), ls.wi))
        cos_i = np.abs(dot(ls.wi, at(bsdf.ns)))  # ns: may be perturbed (normal maps)
        pdf_b_mis = at(q) * pdf_b if self.strategy.mis else 0.0
        w = np.where(ls.delta, 1.0, ls.pdf / np.maximum(ls.pdf + pdf_b_mis, 1e-300))
        contrib = at(paths.beta) * f * scale(ls.Le, np.divide(cos_i * w, ls.pdf, out=np.zeros(len(active)),
                                                               where=ls.valid))
        # Column by column (an axis-1 reduction is several times slower); negative lights subtract.
        test = np.flatnonzero((contrib[:, 0] != 0) | (contrib[:, 1] != 0) | (contrib[:, 2] != 0))
        if len(test) == 0:
            return
        rows = active[test]
        n_off = take(paths.ng, rows) if reflects and self.shadows.geometry_offset is None else \
            towards(take(paths.ng, rows), take(ls.wi, test))
        if self.media is None:
            passed = None if b.counts is None or not self.shadows.any_transparent else b.counts[rows, LABEL_TRANSPARENT]
            if self.shadows.geometry_offset is None:
                o, skip = offset_origin(take(paths.p, rows), n_off), paths.prim[rows]
            else:  # the terminator's Geometry Offset
                o, skip = self.shadows.origin(take(paths.p, rows), n_off, paths.prim[rows],
                                              None if paths.bary is None else take(paths.bary, rows),
                                              take(getattr(bsdf, "n_smooth", bsdf.ns), rows), take(paths.ng, rows),
                                              take(ls.wi, test))
            lit, T = self.shadows.trace(o, take(ls.target, test), skip, ls.target_prim[test], passed,
                                        None if ls.light is None else ls.light[test])
            c = take(contrib, test[lit])
            c = c if T is None else c * T
        else:  # through media: transmittance, and the medium on the light's side of the surface
            medium = after_crossing(self.media.media, paths.medium[rows], paths.mat[rows],
                                    take(self.media.ng_raw, paths.prim[rows]), take(paths.d, rows),
                                    dot(take(ls.wi, test), take(bsdf.ns, rows)) < 0)
            T = self.media.transmittance(take(paths.p, rows), n_off, take(ls.target, test), paths.prim[rows],
                                         ls.target_prim[test], medium)
            lit = np.flatnonzero(np.any(T != 0, axis=1))
            c = take(contrib, test[lit]) * T[lit]
        rows = rows[lit]
        c = self._clamp(c, b.total == 0, rows)
        _accumulate(L, paths.idx[rows], c)
        if tally:
            f_cls = bsdf.eval_by_class(take(ls.wi, test[lit]), rows) if paths.depth == 0 else None
            tally.light_sample(paths.depth, paths.idx[rows], c, f_cls)

    def _scatter(self, sampler, paths: PathState, bsdf, q: np.ndarray, tally) -> PathState:
        """One BSDF sample continues each path, Russian roulette (survival q) ends some: the
        survivors on their next rays, with the MIS state of this bounce (pdf_prev = q p_b)."""
        m, b, reflects = len(paths), paths.bounces, bsdf.reflects_only
        base = 1 + _GROUPS * paths.depth  # random groups of this bounce
        if reflects:  # one lobe: no lane 2 to draw; a Sampler's numbers need no clamp
            u = sampler.get(base + _BSDF, paths.idx, lanes=(0, 1, 3))
            bs, u_rr = bsdf.sample(u[:, :2], None, in_unit=True), u[:, 2]
        else:
            u = sampler.get(base + _BSDF, paths.idx, 4)
            bs, u_rr = bsdf.sample(u[:, :2], u[:, 2]), u[:, 3]
        if self.shadows.shading_offset is not None:  # the terminator's Shading Offset
            bs.weight = scale(bs.weight, self.shadows.shading_factor(paths.prim, bsdf.ns, bs.wi))
        if tally and paths.depth == 0:
            tally.first_bounce(paths.idx, bsdf, bs)
        survive = bs.valid & (u_rr < q)
        if self.light_paths.any_transparent:  # a path at its last vertex goes on only through transparency
            survive &= ~b.last | (bs.label == LABEL_TRANSPARENT)
        beta = paths.beta * scale(bs.weight, np.divide(1.0, q, out=np.zeros(m), where=survive))
        survive &= max3(beta) > 0
        keep = np.flatnonzero(survive)
        vertex = paths
        if self.media is not None:
            label, mat = bs.label[keep], paths.mat[keep]
            mis_pdf, mis_off = paths.mis_pdf[keep], paths.mis_off[keep]
            medium = after_crossing(self.media.media, paths.medium[keep], mat,
                                    take(self.media.ng_raw, paths.prim[keep]), take(paths.d, keep),
                                    (label == LABEL_TRANSMIT) | (label == LABEL_TRANSPARENT))
        paths = vertex.leave(keep, take(bs.wi, keep), take(beta, keep), reflects)
        if self.media is not None:
            paths.medium = medium
        paths.bounces = paths.bounces.count(bs, keep, self.light_paths.per_label)
        # Strategy switches: pdf_prev 0 makes emission found after a non-delta bounce weigh 0
        # ("light" alone); no_mis makes it weigh 1 (after delta bounces, or "bsdf" alone).
        paths.pdf_prev = (q * bs.pdf)[keep] if self.strategy.bsdf_hits else np.zeros(len(keep))
        paths.no_mis = bs.delta[keep] | (not self.strategy.nee)
        if vertex.t_mis is not None:  # a transparent pass keeps the MIS state of the vertex before (Cycles)
            through = bs.label[keep] == LABEL_TRANSPARENT
            paths.t_mis = np.where(through, vertex.t_mis[keep], 0.0)
            paths.pdf_prev = np.where(through, vertex.pdf_prev[keep], paths.pdf_prev)
            paths.no_mis = np.where(through, vertex.no_mis[keep], paths.no_mis)
        if self.lights.light_linked:  # light linking: what the ray may find is its origin's
            receiver = self.lights.receivers(vertex.prim[keep])
            paths.receiver = receiver if vertex.t_mis is None else np.where(through, vertex.receiver[keep], receiver)
        if self.media is not None and vertex.t_mis is None:  # passing a volume-only boundary keeps the MIS state
            passes = (label == LABEL_TRANSPARENT) & self.media.media.passable[mat]
            if passes.any():
                paths.pdf_prev = np.where(passes, mis_pdf, paths.pdf_prev)
                paths.no_mis = np.where(passes, mis_off, paths.no_mis)
        return paths

    def _clamp(self, c: np.ndarray, direct, rows=None) -> np.ndarray:
        """c clamped (Clamp), or c itself with clamping off."""
        return c if self.clamp is None else self.clamp(c, direct, rows)

    @staticmethod
    def _add(L, idx, c, tally, depth, escaped=False) -> None:
        """Emission c (K,3) found by paths idx (K,) into L and the light passes."""
        _accumulate(L, idx, c)
        if tally:
            tally.emitted(depth, idx, c, escaped)


class _Refill:
    """Path regeneration: the camera rays (a PathState on its first rays) of an item's n
    paths, handed out in order to a trace whose live paths are kept near `pool`. (Made all at
    once: made per refill, the same rays cost more than the whole item, most of it in the
    kernel, from the heap's new pattern of allocations - bench/results/tail/notes.md.)"""

    def __init__(self, rays: PathState, pool: int):
        self.rays = rays
        self.n, self.next, self.pool = len(rays), 0, max(int(pool), 1)

    @property
    def left(self) -> int:
        return self.n - self.next

    def take(self, k: int) -> PathState:
        """The next k paths (k <= left) on their first rays, rows next .. next + k - 1."""
        rows, r = slice(self.next, self.next + k), self.rays
        paths = PathState.rays(r.o64[rows], r.o32[rows], r.d[rows], None if r.tmax is None else r.tmax[rows],
                               r.skip[rows], idx=np.arange(self.next, self.next + k))
        self.next += k
        return paths


class PathIntegrator(Integrator):
    """The path tracer as one film stage over all samples."""

    name = "path"
    label = "Path Tracing"
    description = "Unidirectional path tracing with next-event estimation and MIS (unbiased)"
    light_passes = True
    adaptive = True

    def __init__(self, scene):
        super().__init__(scene)
        if not self.light_passes_of(scene.settings):  # regeneration: items of ITEM_BATCHES pools
            self.layout = BatchLayout(scene, ITEM_BATCHES * scene.settings.batch_size)

    @staticmethod
    def light_passes_of(settings) -> tuple:
        """The light passes a render keeps (the Color passes Direct/Indirect need included)."""
        return tuple(n for n in passes_mod.needed(settings.passes) if n in passes_mod.LIGHT)

    def stages(self, round: int):
        return [self.samples_stage()] if round == 0 else []

    def work_items(self) -> int:
        return -(-self.layout.total_paths // self.scene.settings.batch_size)  # batches: the runner splits items

    def build(self, ctx) -> None:
        super().build(ctx)
        self.tallied = self.light_passes_of(ctx.scene.settings)
        # Light passes count per bounce of a batch at one depth: volumes are left out there
        # (validation.volume_warnings says so).
        self.tracer = PathTracer(ctx.scene, ctx.accel, ctx.lights, media=not self.tallied)

    def run(self, stage: Stage, item: int, stop=None) -> np.ndarray:
        layout, s = self.layout, self.scene.settings
        j, sample = layout.locate(stage, item)
        sampler = Sampler(s.seed, layout.pixel[j], sample, s.pattern)
        if not self.tallied:
            return self.tracer.render(sampler, layout.px[j], layout.py[j], stop)
        tally = LightTally(len(j), self.tallied)
        L = self.tracer.render(sampler, layout.px[j], layout.py[j], stop, tally)
        return {"L": L, "passes": tally.passes()}
