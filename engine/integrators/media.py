"""Homogeneous media in the path tracer: which medium a path is in, distance sampling along
its rays, transmittance of shadow rays, and the scattering vertices (light sample and
phase-function sample, combined by the balance heuristic as at surfaces).

A path's medium is the material of the closed mesh it is inside (-1: none). It changes where
the path is transmitted through the surface of a material that bounds a medium (Cycles'
rule: by the bounce's label, not by the side the new ray leaves on): through the front of a
triangle (its geometric normal points out of a closed mesh) it enters the medium, through
the back it leaves it for vacuum (media do not nest in this version). Camera rays start in the medium around the
camera's eye (one for all of them: an orthographic camera's rays are taken to start there too).

Distance sampling (Cycles' homogeneous case, closure/volume.h volume_sample_channel): a
channel c is picked with probability w_c proportional to |beta_c albedo_c|, the distance
t ~ sigma_t[c] exp(-sigma_t[c] t) from the same number rescaled; the one-sample MIS over
channels gives the densities

    p(t) = sum_c w_c sigma_t[c] exp(-sigma_t[c] t)   (a collision before the surface at t_s)
    P    = sum_c w_c exp(-sigma_t[c] t_s)            (none: the ray reaches the surface)

so a collision weighs T(t) sigma_s / p(t) and a pass T(t_s) / P. A collision continues the
path along a phase sample. Direct light is sampled apart, as Cycles does, at a second point
on every ray segment in a medium, drawn from the exponential truncated to [0, t_s] (density
p_d(t) = sum_c w_c sigma_t[c] exp(-sigma_t[c] t) / (1 - exp(-sigma_t[c] t_s))): one light
sample there, weighted T(t) sigma_s / p_d(t) and by the balance heuristic against the phase
sample of the collision (the two estimate the same single-scattered light, and their weights
sum to 1 at every point and direction). Emission in the medium (radiance per unit length)
is added at that point too, as T(t) E / p_d(t). A path past its volume
bounce limit (Cycles' TERMINATE flags) or in a medium that does not scatter is only
attenuated: beta T(t_s), and the emission integrated in closed form, E (1 - T) / sigma_t.
Russian roulette keeps the path tracer's rule, survival = the largest reflectance of the
vertex's scattering function: a phase function's is 1 (the medium's albedo is in the
collision's weight), so collisions never end a path by roulette.
"""
from __future__ import annotations

import numpy as np

from ..accel import offset_origin
from ..bsdf.lobes.henyey_greenstein import HenyeyGreenstein
from ..nodes import light_path as lp
from ..scene import RAY_CAMERA, RAY_DIFFUSE, RAY_SHADOW
from ..vec import dot, scale, take
from ..volumes import Media
from .path_state import PathState, rows_of
from .surface import towards

# Surfaces a shadow ray crosses at most on its way through media boundaries; past it the
# light is taken as blocked.
MAX_CROSSINGS = 16
_HG = HenyeyGreenstein()


def _exp_neg(sigma: np.ndarray, t: np.ndarray) -> np.ndarray:
    """exp(-sigma t) (K,3) for t (K,) that may be inf (0 there where sigma > 0, 1 where 0)."""
    x = sigma * t[:, None]
    x[sigma == 0] = 0.0
    return np.exp(-x)


def _channel(w: np.ndarray, u: np.ndarray):
    """(c, u') (K,): a channel drawn with probabilities w (K,3) by u (K,), and u rescaled to
    [0, 1) within its cell for reuse (Cycles' volume_sample_channel)."""
    cdf = np.cumsum(w, axis=1)
    c = np.minimum((u[:, None] >= cdf).sum(axis=1), 2)
    ar = np.arange(len(u))
    lo = np.where(c > 0, cdf[ar, np.maximum(c - 1, 0)], 0.0)
    wc = w[ar, c]
    return c, np.clip((u - lo) / np.where(wc > 0, wc, 1.0), 0.0, 1.0 - 1e-16)


def _span(sigma: np.ndarray, t: np.ndarray) -> np.ndarray:
    """1 - exp(-sigma t) (K,3): the exponential's mass on [0, t]; t itself where sigma = 0
    (a uniform density there), 1 for t = inf."""
    x = sigma * np.where(np.isfinite(t), t, 1.0)[:, None]
    out = np.where(np.isfinite(t)[:, None], -np.expm1(-x), 1.0)
    return np.where(sigma > 0, out, t[:, None])


def after_crossing(media: Media, medium: np.ndarray, mat: np.ndarray, ng: np.ndarray, d: np.ndarray,
                   transmit: np.ndarray) -> np.ndarray:
    """The medium (K,) of paths in `medium` going on from a vertex on material mat (K,) that
    they reached along d (K,3), ng (K,3) the triangle's own (outward) normal: as Cycles'
    volume_stack_enter_exit, a transmission (transmit (K,) bool: a refraction or a
    transparent pass) through the surface of a medium's mesh enters that medium from the
    front and leaves it for vacuum from the back; a reflection keeps the medium."""
    crosses = media.has[mat] & transmit
    if not crosses.any():
        return medium
    return np.where(crosses, np.where(dot(d, ng) > 0, -1, mat), medium)


class MediumSteps:
    """The path tracer's media (a Media table) and what their steps need of it."""

    def __init__(self, tracer, media: Media, light_group, bsdf_group):
        """light_group, bsdf_group: depth -> the tracer's random-number groups of that bounce
        (distance sampling takes the light group's lane 3, which surfaces leave unused)."""
        self.tracer, self.media = tracer, media
        self.light_group, self.bsdf_group = light_group, bsdf_group
        self.ng_raw = np.asarray(tracer.accel.ng, np.float64)
        self.shadow_accel = tracer.visibility.views.get(RAY_SHADOW, tracer.accel)
        self.limit = tracer.scene.settings.volume_bounces
        eye = np.asarray(tracer.scene.camera.world_from_camera, np.float64)[:3, 3]
        self.camera_medium = self.medium_at(eye)

    def medium_at(self, p: np.ndarray) -> int:
        """The medium around the point p (3,): the first medium whose boundary a ray from p
        crosses outward before crossing it inward (Cycles finds the camera's volume stack by
        a ray the same way), -1 for none."""
        d = np.array([[0.48, 0.6, 0.64]])  # any direction; off the axes, where box edges lie
        o32, skip, seen = p[None].astype(np.float32), np.array([-1]), set()
        mat_of = self.tracer.mesh.material
        for _ in range(MAX_CROSSINGS * 4):
            hit = self.tracer.accel.intersect(o32, d, None, skip)
            prim = int(hit.prim[0])
            if prim < 0:
                return -1
            mat = int(mat_of[prim])
            if self.media.has[mat] and mat not in seen:
                if float(dot(d, self.ng_raw[prim][None])[0]) > 0:
                    return mat
                seen.add(mat)
            o32, skip = offset_origin(hit.p, towards(self.ng_raw[prim][None], d)), hit.prim
        return -1

    def start(self, paths) -> None:
        """Camera paths begin in the medium around the camera's eye."""
        paths.medium = np.full(len(paths), self.camera_medium, np.int64)
        paths.volume_bounces = np.zeros(len(paths), np.int32)

    # -- distance sampling ---------------------------------------------------------------
    def propagate(self, L, sampler, paths, hit):
        """Distance sampling along the rays of paths (before arrive). Returns (paths, hit)
        of those that reach their surface (or escape), their throughput updated, and the
        PathState of those that collided, on the rays their phase samples continue along
        (or None)."""
        paths.mis_pdf, paths.mis_off = paths.pdf_prev, paths.no_mis  # for passes through boundaries
        rows = np.flatnonzero(paths.medium >= 0)
        if len(rows) == 0:
            return paths, hit, None
        med, md = self.media, paths.medium[rows]
        sigma_t, sigma_s, emission = take(med.sigma_t, md), take(med.sigma_s, md), take(med.emission, md)
        t_s = np.where(hit.prim[rows] >= 0, hit.t[rows], np.inf)
        beta = take(paths.beta, rows)
        attenuate = paths.bounces.last[rows] | ~np.any(sigma_s > 0, axis=1)
        if paths.bounces.stop is not None:
            attenuate |= paths.bounces.stop[rows]
        new_beta = beta.copy()
        collide = np.zeros(len(rows), bool)
        t_sample = np.full(len(rows), np.inf)  # the collision distance drawn (inf: only attenuated)
        w_all = np.zeros((len(rows), 3))  # the channel probabilities of the rows that sample
        s = np.flatnonzero(~attenuate)
        a = np.flatnonzero(attenuate)
        if len(a):
            T = _exp_neg(sigma_t[a], t_s[a])
            glow = np.any(emission[a] != 0, axis=1)
            if glow.any():
                g = a[glow]
                s_t = sigma_t[g]
                seg = np.where(s_t > 0, (1.0 - T[glow]) / np.where(s_t > 0, s_t, 1.0), t_s[g][:, None])
                self.tracer._add(L, paths.idx[rows[g]], beta[g] * emission[g] * seg, None, paths.depth)
            new_beta[a] = beta[a] * T
        if len(s):
            ar, r, st_s, ts = np.arange(len(s)), rows[s], sigma_t[s], t_s[s]
            albedo = np.divide(sigma_s[s], st_s, out=np.zeros((len(s), 3)), where=st_s > 0)
            w = np.abs(beta[s] * albedo)
            total = w.sum(axis=1)
            w = np.where(total[:, None] > 0, w / np.where(total > 0, total, 1.0)[:, None], 1.0 / 3.0)
            w_all[s] = w
            depth = rows_of(paths.depth, r)
            # The collision that continues the path: light group lane 3 (surfaces leave it unused).
            c, u = _channel(w, sampler.get(self.light_group(depth), paths.idx[r], lanes=(3,))[:, 0])
            st_c = st_s[ar, c]
            t = np.where(st_c > 0, -np.log1p(-u) / np.where(st_c > 0, st_c, 1.0), np.inf)
            hits = t < ts
            t_sample[s] = t
            tt = np.where(hits, t, ts)
            T = _exp_neg(st_s, tt)
            pdf_t = np.where(hits, (w * st_s * T).sum(axis=1), (w * T).sum(axis=1))
            inv = np.divide(1.0, pdf_t, out=np.zeros(len(s)), where=pdf_t > 0)
            new_beta[s] = beta[s] * T * np.where(hits[:, None], sigma_s[s], 1.0) * inv[:, None]
            collide[s] = hits
            t_coll = np.zeros(len(rows))
            t_coll[s] = tt
            # Direct light and emission at a point drawn on the whole segment (Cycles' direct
            # scatter): the exponential truncated to [0, t_s], with the same channel MIS; BSDF
            # group lane 2 (a surface's lobe choice: the two never meet on one vertex).
            c, u = _channel(w, sampler.get(self.bsdf_group(depth), paths.idx[r], lanes=(2,))[:, 0])
            span = _span(st_s, ts)
            st_c, span_c = st_s[ar, c], span[ar, c]
            t = np.where(st_c > 0, -np.log1p(-u * span_c) / np.where(st_c > 0, st_c, 1.0), u * ts)
            T = _exp_neg(st_s, t)
            pdf_d = (w * np.where(st_s > 0, st_s, 1.0) * T / np.maximum(span, 1e-300)).sum(axis=1)
            ok = np.isfinite(t) & (pdf_d > 0)
            weight = beta[s] * T * np.divide(1.0, pdf_d, out=np.zeros(len(s)), where=ok)[:, None]
            glow = ok & np.any(emission[s] != 0, axis=1)
            if glow.any():
                g = np.flatnonzero(glow)
                self.tracer._add(L, paths.idx[r[g]], weight[g] * emission[s[g]], None, paths.depth)
            if self.tracer.strategy.nee and not self.tracer.lights.empty:
                k = np.flatnonzero(ok)
                self._direct(L, sampler, paths, r[k], t[k], weight[k] * sigma_s[s[k]])
        if len(self.tracer.lights.hittable):
            self._lights_passed(L, paths, rows, t_s, t_sample, sigma_t, attenuate, w_all)
        paths.beta = paths.beta.copy()
        paths.beta[rows] = new_beta
        coll = rows[collide]
        if len(coll) == 0:
            return paths, hit, None
        scattered = self._scatter_vertices(sampler, paths.take(coll), t_coll[collide])
        keep = np.ones(len(paths), bool)
        keep[coll] = False
        rest = np.flatnonzero(keep)
        return paths.take(rest), hit.take(rest), scattered

    def _lights_passed(self, L, paths, rows, t_s, t_sample, sigma_t, attenuate, w) -> None:
        """Emission of the lights (area, sphere) that the rays `rows` in a medium pass before
        their surface at t_s, at distance t each: beta T(t) where the ray is only attenuated,
        beta T(t) / P(t) where the ray did not collide before t (P(t) its chance not to, from
        the channel probabilities w), else nothing. (The path tracer's emission step leaves
        these rays' lights out.)"""
        tr, b = self.tracer, paths.bounces
        beta = take(paths.beta, rows)

        def through(t):
            T = _exp_neg(sigma_t, t)
            P = (w * T).sum(axis=1)
            passed = np.where(attenuate, 1.0, np.divide(1.0, P, out=np.zeros(len(t)), where=(P > 0) & (t_sample > t)))
            return beta * T * passed[:, None]

        kind = None if b.ray is None else b.ray[rows]
        camera = kind == RAY_CAMERA if kind is not None else rows_of(paths.depth, rows) == 0
        c = tr.lights.emission_along(take(paths.o64, rows), take(paths.d, rows), t_s, paths.pdf_prev[rows],
                                     ~paths.no_mis[rows], np.broadcast_to(camera, len(rows)), kind, through=through)
        tr._add(L, paths.idx[rows], tr._clamp(c, b.total[rows] <= 1, None), None, paths.depth)

    # -- scattering ------------------------------------------------------------------------
    def _direct(self, L, sampler, paths, rows, t, beta):
        """One light sample at the points t (K,) along the rays of paths `rows` (K,), with
        throughput beta (K,3) there, weighted against phase sampling (balance heuristic)."""
        tr = self.tracer
        p = take(paths.o64, rows) + take(paths.d, rows) * t[:, None]
        wo = -take(paths.d, rows)
        medium = paths.medium[rows]
        g = _HG.parameters(self.media.g[medium])
        depth, b = rows_of(paths.depth, rows), paths.bounces
        u = sampler.get(self.light_group(depth), paths.idx[rows], 3)
        ls = tr.lights.sample(p, u[:, 2], u[:, :2], in_unit=True,
                              ray=b.record(rows) if tr.lights.world_reads else None)
        f, pdf_ph = _HG.eval(g, wo, ls.wi)
        pdf_mis = pdf_ph if tr.strategy.mis else 0.0
        w = np.where(ls.delta, 1.0, ls.pdf / np.maximum(ls.pdf + pdf_mis, 1e-300))
        contrib = beta * f * scale(ls.Le, np.divide(w, ls.pdf, out=np.zeros(len(rows)), where=ls.valid))
        test = np.flatnonzero(np.any(contrib != 0, axis=1))
        if len(test) == 0:
            return
        T = self.transmittance(take(p, test), None, take(ls.target, test), np.full(len(test), -1),
                               ls.target_prim[test], medium[test])
        c = tr._clamp(take(contrib, test) * T, b.total[rows[test]] == 0, None)
        tr._add(L, paths.idx[rows[test]], c, None, depth)

    def _scatter_vertices(self, sampler, paths, t):
        """Paths (on their rays) that collide at distance t (K,): a phase sample at
        p = o + t d continues them; returns the paths on those rays."""
        tr = self.tracer
        p = paths.o64 + paths.d * t[:, None]
        wo = -paths.d
        g = _HG.parameters(self.media.g[paths.medium])
        depth = paths.depth
        # The phase sample continues the path (weight 1: HG is sampled exactly).
        u = sampler.get(self.bsdf_group(depth), paths.idx, lanes=(0, 1))
        smp = _HG.sample(g, wo, u, None)
        out = PathState(paths.idx, depth + 1, d=smp.wi, beta=paths.beta, skip=np.full(len(paths), -1, np.int64),
                        o64=p, o32=p.astype(np.float32), tmax=None)
        out.pdf_prev = smp.pdf if tr.strategy.bsdf_hits else np.zeros(len(paths))
        out.no_mis = np.full(len(paths), not tr.strategy.nee)
        out.medium = paths.medium
        out.volume_bounces = paths.volume_bounces + 1
        out.specular = None if paths.specular is None else np.zeros(len(paths), bool)
        if paths.t_mis is not None:  # the MIS state is this vertex's
            out.t_mis = np.zeros(len(paths))
        out.receiver = paths.receiver  # light linking: the receiver sets of the ray's origin
        out.bounces = self._count(paths.bounces, out.volume_bounces)
        return out

    def _count(self, b, volume_bounces):
        """Cycles' path_state_next for a volume scatter: one more bounce; past the total or
        the volume limit the path is only attenuated and adds the emission it finds."""
        b.total = b.total + 1
        b.last = b.last | (b.total >= b.max_depth) | (volume_bounces >= self.limit)
        if b.ray is not None:  # no longer a camera ray; ray visibility has no volume kind: diffuse's
            b.ray = np.full(len(b.ray), RAY_DIFFUSE, np.uint8)
        if b.flag is not None:
            cleared = np.uint32(~((1 << 11) - 1 | lp.MIS_SKIP) & 0xFFFFFFFF)
            b.flag = ((b.flag & cleared) | np.uint32(lp.VOLUME_SCATTER)).astype(np.uint32)
        return b

    # -- shadow rays -----------------------------------------------------------------------
    def transmittance(self, p, n_off, target, skip, target_prim, medium) -> np.ndarray:
        """(K,3) transmittance of the segments from p (K,3) (offset along n_off (K,3) when
        on a surface, else None) to target (K,3): 0 where an opaque surface blocks them,
        else exp(-sum sigma_t d) over the media they cross; they pass the boundaries of
        volume-only materials, entering and leaving those media."""
        k = len(p)
        T = np.ones((k, 3))
        d = target - p
        dist = np.sqrt(dot(d, d))
        d = d / np.maximum(dist, 1e-300)[:, None]
        tmax = dist * (1.0 - 1e-4)
        o32 = p.astype(np.float32) if n_off is None else offset_origin(p, n_off)
        alive = np.arange(k)
        medium, skip, target_prim = medium.copy(), skip.copy(), np.asarray(target_prim)
        mat_of = self.tracer.mesh.material
        for _ in range(MAX_CROSSINGS):
            hit = self.shadow_accel.intersect(o32, d, tmax, skip)
            reach = (hit.prim < 0) | (hit.prim == target_prim)
            seg = np.where(reach, tmax, hit.t)
            T[alive] *= _exp_neg(take(self.media.sigma_t, medium), seg)
            mat = mat_of[np.maximum(hit.prim, 0)]
            cross = ~reach & self.media.passable[mat]
            T[alive[~reach & ~cross]] = 0.0
            r = np.flatnonzero(cross)
            if len(r) == 0:
                return T
            h = hit.take(r)
            ng = take(self.ng_raw, h.prim)
            dr = take(d, r)
            medium = np.where(dot(dr, ng) < 0, mat[r], -1)
            alive, d, skip, target_prim = alive[r], dr, h.prim, target_prim[r]
            tmax = tmax[r] - h.t
            o32 = offset_origin(h.p, towards(ng, dr))
        T[alive] = 0.0
        return T

