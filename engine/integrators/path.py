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
from ..bsdf.closure import LABEL_DIFFUSE, LABEL_GLOSSY, LABEL_TRANSMIT, LABEL_TRANSPARENT
from ..bsdf.fast_path import make_closure, plain_lambert_albedo
from ..errors import Cancelled
from ..lights.light_set import LightSet
from ..rng import Sampler
from ..scene import LOBE_TRANSPARENT, RAY_CAMERA, RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMIT, Scene
from .. import passes as passes_mod
from ..visibility import RayVisibility
from .base import Integrator, Stage
from .light_passes import LightTally
from .surface import flat_frame_rows, flat_frames, flat_normals, shading_frame, towards
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
# batch: 17 % of the CPU time in the open caustic scene, 3 % in the Cornell box
# (bench/results/tail/notes.md).
ITEM_BATCHES = 4
REFILL_BELOW = 0.5


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
        self.flat_frames = flat_frames(scene.mesh, self.flat_normal, accel.ng)  # or None
        # Barycentrics serve smooth normals and the general closure (textures) only.
        self.needs_bary = self.flat_normal is None or bool(np.isnan(self.lambert_albedo).any())
        self.max_depth = scene.settings.max_depth
        self.rr_depth = scene.settings.rr_depth
        strategy = scene.settings.strategy
        self.use_nee = strategy in ("mis", "light")
        # Weight of emission found by BSDF sampling relative to MIS: "bsdf" alone counts it in
        # full (use_mis False), "light" alone drops it after non-delta bounces.
        self.bsdf_hits = strategy in ("mis", "bsdf")
        self.mis = strategy == "mis"
        st = scene.settings
        self.limits = np.zeros(4, np.int64)  # per LABEL_*
        self.limits[[LABEL_DIFFUSE, LABEL_GLOSSY, LABEL_TRANSMIT, LABEL_TRANSPARENT]] = (
            st.diffuse_bounces, st.glossy_bounces, st.transmission_bounces, st.transparent_bounces)
        self.has_transparent = np.zeros(len(scene.materials.kind), bool)  # may pass a path at its last vertex
        self.has_transparent[scene.materials.lobe_material[scene.materials.lobe_kind == LOBE_TRANSPARENT]] = True
        self.caustics_reflective, self.caustics_refractive = st.caustics_reflective, st.caustics_refractive
        self.filter_glossy = st.filter_glossy
        self.visibility = RayVisibility(accel, scene.mesh)  # objects hidden from some rays
        # Per-path state only where a scene needs it (see _Bounces).
        self.any_transparent = bool(self.has_transparent.any())
        self.counted = bool(np.any(self.limits[[LABEL_DIFFUSE, LABEL_GLOSSY, LABEL_TRANSMIT]] < self.max_depth)
                            or self.any_transparent)
        self.ray_kinds = bool(lights.partial_visibility or not self.visibility.trivial or self.any_transparent
                              or not (st.caustics_reflective and st.caustics_refractive))
        # (direct, indirect) clamping limits on |R|+|G|+|B| (Cycles stores 3 x the UI value), None = off.
        self.clamp = None
        if st.clamp_direct > 0 or st.clamp_indirect > 0:
            self.clamp = tuple(3.0 * v if v > 0 else np.inf for v in (st.clamp_direct, st.clamp_indirect))

    def render(self, sampler, px: np.ndarray, py: np.ndarray, stop=None, tally=None) -> np.ndarray:
        """Radiance estimates (N,3), one path per pixel (px, py). Raises Cancelled if stop is set.
        tally: a LightTally that files the radiance into light passes, or None. Without one,
        the paths run in a pool of one batch, topped up as paths end (path regeneration)."""
        s = self.scene
        o64, d, tmax = camera_mod.camera_rays(s.camera, s.settings, px, py, sampler)
        rays = (o64, o64.astype(np.float32), d, tmax, np.full(len(px), -1, np.int64))
        if tally is not None:  # light passes count per bounce: those items are one batch
            return self.trace(sampler, *rays, stop, tally=tally)
        refill = _Refill(*rays, pool=s.settings.batch_size)
        return self.trace(sampler, *refill.take(min(refill.pool, refill.n)), stop, refill=refill)

    def trace(self, sampler, o64, o32, d, tmax, skip, stop=None, first_emission=True,
              max_depth=None, t_first=None, tally=None, caustic_ends=None, refill=None) -> np.ndarray:
        """Radiance (N,3) arriving along rays from o64 (float64 points; o32 their offset float32
        origins, skip the primitive each leaves or -1) in directions d; tmax (N,) or None.
        Random groups from 1 (group 0 is the caller's). first_emission False leaves out the
        emission the rays themselves find (a gather ray whose direct light is sampled apart);
        max_depth: bounces after the first hit (default: the scene's); t_first (N,), if given,
        receives the first hit's distance (inf where the ray escaped); tally: light passes
        (render, camera rays only); caustic_ends (M,) bool per material, or None: light that a
        path finds before it reaches one of these materials is left out (a gather path from a
        point whose caustics come from a caustic map: that map holds exactly those paths).

        refill: a _Refill (path regeneration) whose first rays are the ones given: the live
        paths are topped up with its next rays whenever fewer than REFILL_BELOW x its pool
        remain, and the result has a row for each of its rays. Paths then sit at different
        bounces (depth per path), yet each path draws the same numbers and sums the same
        terms in the same order, so the result is the same bit for bit."""
        n = len(d)
        L = np.zeros((3, n if refill is None else refill.n))  # channel-major: see _accumulate
        idx = np.arange(n)  # which pixel sample each live path belongs to
        beta = np.ones((n, 3))
        pdf_prev = np.zeros(n)  # q * p_b of the bounce that produced the ray
        no_mis = np.ones(n, bool)  # camera ray: emitters seen with weight 1
        # Paths whose light is left out so far (caustic_ends; else first_emission at depth 0).
        dark = np.full(n, caustic_ends is not None)
        mesh = self.scene.mesh
        max_depth = self.max_depth if max_depth is None else max_depth
        bounces = _Bounces.start(n, max_depth, self.any_transparent, self.counted, self.ray_kinds,
                                 self.filter_glossy > 0)
        limit = max_depth + self.limits[LABEL_TRANSPARENT] + 1  # rays a path traces at most
        # Bounces so far: one int for all paths, or one per path with regeneration.
        depth = 0 if refill is None else np.zeros(len(idx), np.int64)
        if refill is not None:
            bounces = bounces.per_path(len(idx))
        while True:
            if stop is not None and stop.is_set():
                raise Cancelled()
            pending = refill is not None and refill.left > 0
            if pending and len(idx) < REFILL_BELOW * refill.pool:
                k = min(refill.pool - len(idx), refill.left)
                new = _Bounces.start(k, max_depth, self.any_transparent, self.counted, self.ray_kinds,
                                     self.filter_glossy > 0).per_path(k)
                fresh = (np.arange(refill.next, refill.next + k), *refill.take(k))
                idx, o64, o32, d, tmax, skip = (np.concatenate([a, b]) for a, b in zip((idx, o64, o32, d, tmax, skip),
                                                                                          fresh))
                depth, dark = np.concatenate([depth, np.zeros(k, np.int64)]), np.concatenate([dark, np.zeros(k, bool)])
                beta, pdf_prev = np.concatenate([beta, np.ones((k, 3))]), np.concatenate([pdf_prev, np.zeros(k)])
                no_mis, bounces = np.concatenate([no_mis, np.ones(k, bool)]), bounces.join(new)
                pending = refill.left > 0
            if len(idx) == 0:
                break
            base = 1 + _GROUPS * depth  # random groups of this bounce (per path with regeneration)
            kind = bounces.ray  # None when no visibility or caustics toggle needs it
            hit = self.visibility.intersect(o32, d, tmax, skip, kind)
            if t_first is not None and depth == 0:
                t_first[:] = np.where(hit.prim >= 0, hit.t, np.inf)
            camera_ray = kind == RAY_CAMERA if kind is not None else np.broadcast_to(depth == 0, len(idx))
            emission = (first_emission or depth > 0) & ~dark  # (n,) bool
            # Emission found by this ray is "direct" for clamping after at most one bounce.
            direct = bounces.total <= 1 if self.clamp is not None else None
            # Light objects the ray passes on its way (they do not stop it).
            if len(self.lights.hittable) and emission.any():
                c = beta * self.lights.emission_along(o64, d, hit.t, pdf_prev, ~no_mis, camera_ray, kind)
                c[~emission] = 0.0
                c = self._clamp(c, direct)
                _accumulate(L, idx, c)
                if tally:
                    tally.emitted(depth, idx, c)
            # Escaped rays see the suns and the world.
            missed = hit.prim < 0
            if missed.any() and self.lights.sees_escaped and emission.any():
                r = np.flatnonzero(missed & emission)
                c = take(beta, r) * self.lights.escaped(take(d, r), pdf_prev[r], ~no_mis[r], camera_ray[r],
                                                        None if kind is None else kind[r])
                c = self._clamp(c, direct, r)
                _accumulate(L, idx[r], c)
                if tally:
                    tally.emitted(depth, idx[r], c, escaped=True)
            o_prev = o64  # previous vertices, indexed through `keep` where needed
            keep = np.flatnonzero(~missed)
            if len(keep) == 0 and not pending:
                break
            if len(keep) < len(missed):  # drop the escaped rays before their hit points are rebuilt
                idx, pdf_prev, no_mis = idx[keep], pdf_prev[keep], no_mis[keep]
                emission, dark, depth, base = emission[keep], dark[keep], _rows(depth, keep), _rows(base, keep)
                beta, d, hit = take(beta, keep), take(d, keep), hit.take(keep)
                bounces = bounces.take(keep)
            hit_t, prim, hit_p, ng = hit.t, hit.prim, hit.p, hit.ng
            bary = hit.b if self.needs_bary else None
            mat = mesh.material[prim]
            # Emissive triangles hit by the ray.
            emits = self.emissive_material[mat] & emission
            if emits.any():
                r = np.flatnonzero(emits)
                Le = take(self.materials.emission, mat[r])
                cos_l = np.abs(dot(take(d, r), take(ng, r)))
                pdf_light = self.lights.pdf_triangle_hit(prim[r], take(o_prev, keep[r]), hit_t[r], cos_l)
                w = np.where(no_mis[r], 1.0, pdf_prev[r] / np.maximum(pdf_prev[r] + pdf_light, 1e-300))
                c = self._clamp(take(beta, r) * scale(Le, w), bounces.total <= 1, r)
                _accumulate(L, idx[r], c)
                if tally:
                    tally.emitted(depth, idx[r], c)
            # A path past a bounce limit ends at this vertex, except through transparent
            # surfaces when the limit was not the transparent one (Cycles' path_state_next).
            ends = bounces.last & ~self.has_transparent[mat] if self.any_transparent else bounces.last
            if bounces.stop is not None:
                ends |= bounces.stop
            if self.visibility.holdout is not None:  # camera rays end black on holdout objects
                ends |= self.visibility.holdout[prim] & (bounces.ray == RAY_CAMERA)
            if ends.any():
                keep = np.flatnonzero(~ends)
                if len(keep) == 0 and not pending:
                    break
                idx, pdf_prev, no_mis, prim, mat = idx[keep], pdf_prev[keep], no_mis[keep], prim[keep], mat[keep]
                dark, depth, base = dark[keep], _rows(depth, keep), _rows(base, keep)
                beta, hit_p, d, ng = (take(a, keep) for a in (beta, hit_p, d, ng))
                bary = None if bary is None else take(bary, keep)
                bounces = bounces.take(keep)
            # Shading frame, flipped to the side the ray came from (two-sided, like Cycles).
            wo = -d
            frame = None
            if self.flat_frames is not None:
                ng_f, ns, *frame = flat_frame_rows(self.flat_frames, prim, ng, wo)
            else:
                ng_f, ns = shading_frame(mesh, self.flat_normal, prim, bary, ng, wo)
            bsdf = make_closure(self.scene, self.lambert_albedo, mat, ns, ng_f, wo, prim, bary,
                                self._no_caustics(bounces), self._blur(bounces), frame)
            ns = bsdf.ns  # may be perturbed (normal maps)
            # A closure that only reflects puts every lit or sampled direction on ng_f's side.
            reflects = bsdf.reflects_only
            if tally and depth == 0:
                tally.first_hit(idx, bsdf)
            albedo = max3(bsdf.reflectance)
            q = np.where(depth >= self.rr_depth, np.minimum(1.0, albedo), 1.0)
            m = len(idx)
            if caustic_ends is not None:
                dark &= ~caustic_ends[mat]
            # Next-event estimation at points whose BSDF has a non-delta part.
            # A Lambertian closure's black points (emitters) get exact zeros from it: sampling them too
            # spares gathering every array for the others.
            smooth = np.ones(m, bool) if reflects else bsdf.has_smooth
            active = np.flatnonzero((smooth & ~bounces.last if self.any_transparent else smooth) & ~dark)
            if len(active) and self.use_nee and not self.lights.empty:
                at = gatherer(active, m)
                u_light = sampler.get(_rows(base, active) + _LIGHT, at(idx), 3)
                ls = self.lights.sample(at(hit_p), u_light[:, 2], u_light[:, :2], in_unit=True)
                f, pdf_b = bsdf.eval(ls.wi, active, ls.visibility)
                cos_i = np.abs(dot(ls.wi, at(ns)))
                pdf_b_mis = at(q) * pdf_b if self.mis else 0.0
                w = np.where(ls.delta, 1.0, ls.pdf / np.maximum(ls.pdf + pdf_b_mis, 1e-300))
                contrib = at(beta) * f * scale(ls.Le, np.divide(cos_i * w, ls.pdf, out=np.zeros(len(active)),
                                                                 where=ls.valid))
                # Column by column (an axis-1 reduction is several times slower); negative lights subtract.
                test = np.flatnonzero((contrib[:, 0] != 0) | (contrib[:, 1] != 0) | (contrib[:, 2] != 0))
                if len(test):
                    rows = active[test]
                    n_off = take(ng_f, rows) if reflects else towards(take(ng_f, rows), take(ls.wi, test))
                    o_shadow = offset_origin(take(hit_p, rows), n_off)
                    blocked = self.visibility.occluded(o_shadow, take(ls.target, test), prim[rows], ls.target_prim[test])
                    lit = np.flatnonzero(~blocked)
                    c = self._clamp(take(contrib, test[lit]), bounces.total == 0, rows[lit])
                    _accumulate(L, idx[rows[lit]], c)
                    if tally:
                        f_cls = bsdf.eval_by_class(take(ls.wi, test[lit]), rows[lit]) if depth == 0 else None
                        tally.light_sample(depth, idx[rows[lit]], c, f_cls)
            # BSDF sampling continues the path; Russian roulette with survival q.
            if reflects:  # one lobe: no lane 2 to draw; a Sampler's numbers need no clamp
                u_bsdf = sampler.get(base + _BSDF, idx, lanes=(0, 1, 3))
                bs, u_rr = bsdf.sample(u_bsdf[:, :2], None, in_unit=True), u_bsdf[:, 2]
            else:
                u_bsdf = sampler.get(base + _BSDF, idx, 4)
                bs, u_rr = bsdf.sample(u_bsdf[:, :2], u_bsdf[:, 2]), u_bsdf[:, 3]
            if tally and depth == 0:
                tally.first_bounce(idx, bsdf, bs)
            survive = bs.valid & (u_rr < q)
            if self.any_transparent:  # a path at its last vertex goes on only through transparency
                survive &= ~bounces.last | (bs.label == LABEL_TRANSPARENT)
            beta = beta * scale(bs.weight, np.divide(1.0, q, out=np.zeros(m), where=survive))
            survive &= max3(beta) > 0
            keep = np.flatnonzero(survive)
            idx, beta, d, dark = idx[keep], take(beta, keep), take(bs.wi, keep), dark[keep]
            depth = _rows(depth, keep) + 1
            bounces = bounces.take(keep).count(bs, keep, self.limits, max_depth)
            # Strategy switches: pdf_prev 0 makes emission found after a non-delta bounce weigh 0
            # ("light" alone); no_mis makes it weigh 1 (after delta bounces, or "bsdf" alone).
            pdf_prev = (q * bs.pdf)[keep] if self.bsdf_hits else np.zeros(len(keep))
            no_mis = bs.delta[keep] | (not self.use_nee)
            o64 = take(hit_p, keep)
            o32 = offset_origin(o64, take(ng_f, keep) if reflects else towards(take(ng_f, keep), d))
            skip = prim[keep]
            tmax = None if refill is None else np.full(len(keep), np.inf)  # joined with camera rays'
            if np.ndim(depth) == 0:
                if depth >= limit:
                    break
            elif len(depth) and depth.max() >= limit:
                alive = np.flatnonzero(depth < limit)
                idx, beta, d, dark, depth, pdf_prev, no_mis, skip, tmax = (
                    a[alive] for a in (idx, beta, d, dark, depth, pdf_prev, no_mis, skip, tmax))
                o64, o32, bounces = o64[alive], o32[alive], bounces.take(alive)
        return np.ascontiguousarray(L.T)

    def _clamp(self, c: np.ndarray, direct: np.ndarray, rows=None) -> np.ndarray:
        """Contributions c (K,3) clamped as Cycles' film_clamp_light: where |R|+|G|+|B| exceeds
        3 x the limit (clamp_direct where `direct` (K,) (or direct[rows]), else clamp_indirect;
        0 = none), c is scaled to it (hue kept)."""
        if self.clamp is None:
            return c
        limit = np.where(direct if rows is None or np.ndim(direct) == 0 else direct[rows], *self.clamp)
        total = np.abs(c).sum(axis=1)
        over = total > limit
        if not over.any():
            return c
        return scale(c, np.where(over, limit / np.where(over, total, 1.0), 1.0))

    def _blur(self, bounces):
        """Filter Glossy (Cycles' surface_shader.h): GGX alpha at least sqrt(1 - p) / 2 with
        p = min_ray_pdf / filter_glossy where p < 1, or None when off."""
        if not self.filter_glossy > 0:
            return None
        p = bounces.min_pdf / self.filter_glossy
        return np.where(p < 1.0, 0.5 * np.sqrt(np.maximum(1.0 - p, 0.0)), 0.0)

    def _no_caustics(self, bounces):
        """(drop_reflection, drop_refraction) for the closure, or None with both caustics on."""
        if self.caustics_reflective and self.caustics_refractive:
            return None
        after = bounces.ray == RAY_DIFFUSE  # the last non-transparent bounce was diffuse
        return (after & (not self.caustics_reflective), after & (not self.caustics_refractive))


class _Bounces:
    """Per-path bounce state as Cycles' path_state_next keeps it. Arrays a scene does not need
    are None: total (N,) non-transparent bounces so far; last (N,) bool: the path is over a
    limit, its ray adds the emission it finds and goes on only through transparency
    (TERMINATE_AFTER_TRANSPARENT); stop (N,) bool: the transparent limit is reached, the next
    surface is the last (TERMINATE_ON_NEXT_SURFACE; None without transparent materials);
    counts (N,4) bounces per LABEL_* (None when no per-type limit is below the total); ray (N,)
    RAY_* kind of the path's ray: camera until the first non-transparent bounce, then that
    bounce's kind (None when nothing depends on it); min_pdf (N,) the smallest non-delta BSDF
    pdf so far (Cycles' min_ray_pdf; None without Filter Glossy). When none of these is kept
    and no surface is transparent, every path has made the same number of bounces: total and
    last are then scalars (no per-path arrays to carry)."""

    def __init__(self, **arrays):
        self.__dict__.update(arrays)

    @staticmethod
    def start(n, max_depth, stop, counts, ray, min_pdf) -> "_Bounces":
        uniform = not (stop or counts or ray or min_pdf)
        return _Bounces(total=np.int32(0) if uniform else np.zeros(n, np.int32),
                        last=np.bool_(max_depth <= 0) if uniform else np.full(n, max_depth <= 0),  # 0: emission only
                        stop=np.zeros(n, bool) if stop else None,
                        counts=np.zeros((n, 4), np.int32) if counts else None,
                        ray=np.full(n, RAY_CAMERA, np.uint8) if ray else None,
                        min_pdf=np.full(n, np.inf) if min_pdf else None)

    def take(self, rows) -> "_Bounces":
        return _Bounces(**{k: v if v is None or np.ndim(v) == 0 else v[rows] for k, v in vars(self).items()})

    def per_path(self, n: int) -> "_Bounces":
        """The same state with total and last as (n,) arrays (paths at different bounces)."""
        return _Bounces(**{**vars(self), "total": np.broadcast_to(self.total, n).astype(np.int32),
                           "last": np.broadcast_to(self.last, n).copy()})

    def join(self, other: "_Bounces") -> "_Bounces":
        """These paths followed by other's (both per path)."""
        return _Bounces(**{k: v if v is None else np.concatenate([v, getattr(other, k)]) for k, v in vars(self).items()})

    def count(self, bs, rows, limits: np.ndarray, max_depth: int) -> "_Bounces":
        """The state after the bounce sampled in bs (BSDFSample) at rows (N,); limits (4,)."""
        if self.counts is None and self.ray is None and self.min_pdf is None:  # every bounce counts alike
            self.total = self.total + 1  # scalars or arrays alike
            self.last = self.last | (self.total >= max_depth)
            return self
        label = bs.label[rows]
        see_through = label == LABEL_TRANSPARENT
        self.total += ~see_through
        over = self.total >= max_depth
        if self.counts is not None:
            i = np.arange(len(label))
            self.counts[i, label] += 1
            reached = self.counts[i, label] >= limits[label]
            over |= reached
            if self.stop is not None:  # tracked with counts (transparent materials)
                self.stop |= see_through & reached
        self.last |= ~see_through & over
        if self.ray is not None:
            self.ray = np.where(see_through, self.ray, _RAY_OF_LABEL[label])
        if self.min_pdf is not None:
            self.min_pdf = np.where(bs.delta[rows], self.min_pdf, np.minimum(self.min_pdf, bs.pdf[rows]))
        return self


def _rows(x, rows):
    """x[rows], or x itself when it is one value for all paths."""
    return x if np.ndim(x) == 0 else x[rows]


class _Refill:
    """Path regeneration: the camera rays (o64, o32, d, tmax, skip) of an item's n paths,
    handed out in order to a trace whose live paths are kept near `pool`. (Made all at once:
    made per refill, the same rays cost 1.4x the CPU time of the whole item, most of it in
    the kernel, from the heap's new pattern of allocations - bench/results/tail/notes.md.)"""

    def __init__(self, o64, o32, d, tmax, skip, pool: int):
        self.rays = (o64, o32, d, tmax, skip)
        self.n, self.next, self.pool = len(d), 0, max(int(pool), 1)

    @property
    def left(self) -> int:
        return self.n - self.next

    def take(self, k: int) -> tuple:
        """(o64, o32, d, tmax, skip) of the next k paths (k <= left), rows next .. next + k - 1."""
        rows = slice(self.next, self.next + k)
        self.next += k
        return tuple(a[rows] for a in self.rays)


_RAY_OF_LABEL = np.array([RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMIT, RAY_CAMERA], np.uint8)  # per LABEL_*


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
        self.tracer = PathTracer(ctx.scene, ctx.accel, ctx.lights)
        self.tallied = self.light_passes_of(ctx.scene.settings)

    def run(self, stage: Stage, item: int, stop=None) -> np.ndarray:
        layout, s = self.layout, self.scene.settings
        j, sample = layout.locate(stage, item)
        sampler = Sampler(s.seed, layout.pixel[j], sample, s.pattern)
        if not self.tallied:
            return self.tracer.render(sampler, layout.px[j], layout.py[j], stop)
        tally = LightTally(len(j), self.tallied)
        L = self.tracer.render(sampler, layout.px[j], layout.py[j], stop, tally)
        return {"L": L, "passes": tally.passes()}
