"""Irradiance caching with gradients (seed 001; Ward, Rubinstein and Clear 1988; Ward and
Heckbert 1992; Krivanek et al. 2005, 2008; Jensen 2001).

Diffuse indirect light changes slowly: it is computed carefully at a few records (E from
M x N stratified gather rays, with rotational and translational gradients) and interpolated
everywhere else. The radiance at a gather hit comes from path tracing (the default) or from
the global photon map (the seed's combination, `icache_gather`). Rounds of stages
(engine/integrators/base.py):

  photons   the global and caustic photon maps, as `photon` (the global map only when gather
            rays read it; the caustic map only with specular surfaces)
  probe     the overture's points: the first diffuse point of every camera sample of the first
            pass (behind mirrors and glass too)
  records   records for a well-spread subset of the points that no record covers, coarse to
            fine (the subset's spacing halves every round), until every point is covered
  refine    one more set of M x N gather rays for every record below the target level; E and
            the gradients become the mean over the sets, so the records' error falls with
            the passes as the pixels' does (a fixed record set leaves a floor of blotches)
  pixels    passes in blocks of 1, 1, 2, 4, ... 16: at the first diffuse point, direct light
            by light sampling, caustics from the caustic map, and albedo / pi times the cached
            irradiance; a point no record covers is final-gathered and becomes a candidate
            for the records round before the next block.

Path-traced gathers are the default: per record they cost less than photon-map gathers (a
k-nearest lookup per gather hit dominates those) and are unbiased, where a starved photon map
(sunlight through a window) darkens the image (measured in bench/results/icache/notes.md).

Records are placed from the points of whole passes, in an order fixed by the points' sample
indices, and each record's gather rays are numbered by the record and its level: the record
set and the image do not depend on the batch size or the number of workers.

Where the cache applies: surfaces with one diffuse lobe (textured or not); with radiance
caching on (icache_radiance, radiance.py), also surfaces whose whole BSDF is low-frequency
(rough glossy), from the incident radiance the records hold in spherical harmonics. Any other
surface is shaded as `photon` does (final gathering) or, with path-traced gathers, by path
tracing.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ... import camera as camera_mod, rng
from ...accel import offset_origin
from ...errors import Cancelled
from ...scene import LOBE_DIFFUSE
from ...sampling import frame_from_z, to_world
from ...vec import dot, gatherer, take
from ..base import Stage
from ..path import PathTracer
from ..path_options import Gather
from ..path_state import PathState
from ..photon.integrator import PHOTON_BYTES, PhotonIntegrator, _accumulate, _sample_rows
from ..surface import towards
from .cache import RecordOctree, Records, neighbour_clamp, spread_subset
from .hemisphere import cell_directions, gradient_to_world, record_terms
from . import radiance
from ...layout import BatchLayout

# The support a R_i of a record, in pixel footprints at the record (Krivanek and Gautron's
# screen-space clamp; Mitsuba 0.6 uses 3 and 20 on R_i with a weight whose support is R_i)...
MIN_PX, MAX_PX = 3.0, 20.0
# ... and in scene radii: behind a curved mirror a footprint can explode (pbrt-v2 issue #36).
MIN_WORLD, MAX_WORLD = 1e-4, 0.1
MIN_COS = 0.2  # a footprint grows as 1 / cos(view angle); grazing views are capped at this cosine
RECORD_RAYS = 1 << 16  # gather rays per work item of the records stage (cancel latency)
MIN_RECORD_ITEMS = 4  # work items a records round is cut into at least (two per core)
# Records per pixel of the frame the memory estimate allows for: above what the pixel-footprint
# clamps let the cache place (bench/results/reliability/memory.md).
RECORDS_PER_PIXEL = 0.125
RECORD_FLOATS = 30  # float64 values of a record without radiance coefficients (cache.Records)
MAX_ROUNDS = 12  # records rounds per placement; points still uncovered are final-gathered
MAX_BLOCK = 16  # passes per pixels stage (records placed between blocks)
# Refinement: before the passes [P, ...) every record holds at least 1 + P // PASSES_PER_LEVEL
# sets of M x N gather rays. Its error then falls with the passes, as the pixels' does; the
# interval balances the records' noise against the pixels' at the records' cost
# (bench/results/icache/notes.md, "Refinement").
PASSES_PER_LEVEL = 16
DIRECT_SAMPLES = 4  # light samples (and as many BSDF samples) per camera sample at a cached point
DOT_PX = 1.5  # the record view: a record shows as a dot this many pixel footprints wide
_FIELDS = ("position", "normal", "footprint", "prim", "key")


def single_diffuse_materials(m) -> np.ndarray:
    """(M,) bool: materials that are one diffuse lobe (any colour texture or normal map), whose
    reflected light is albedo / pi x irradiance - what a record holds."""
    count = np.bincount(m.lobe_material, minlength=len(m.kind))
    diffuse = (m.lobe_kind == LOBE_DIFFUSE) & (m.lobe_layer < 0) & (m.lobe_opacity_tex < 0)
    return (count == 1) & (np.bincount(m.lobe_material[diffuse], minlength=len(m.kind)) == 1)


class IrradianceCacheIntegrator(PhotonIntegrator):
    name = "icache"
    label = "Irradiance Cache"
    description = ("Irradiance caching with gradients: diffuse indirect light from records of photon-map "
                   "final gathering, interpolated (biased, smooth)")
    sample_offset = False  # records placed in passes < K serve pass K: no sample range stands alone

    @staticmethod
    def batch_paths(s) -> int:
        return max(1024, s.batch_size // 2)

    @classmethod
    def batch_rays(cls, scene, paths: int) -> int:
        """Uncached points of a batch each trace gather_rays gather rays; a records item
        traces RECORD_RAYS."""
        return max(super().batch_rays(scene, paths), RECORD_RAYS)

    @classmethod
    def memory_estimate(cls, scene) -> int:
        """The global map where gather rays read it, and the records: their fields and, with
        radiance caching, order^2 coefficients per channel and their gradients, twice (the
        render process's arrays and the published copy)."""
        s = scene.settings
        photons = super().memory_estimate(scene) if s.icache_gather == "photon" else \
            2 * PHOTON_BYTES * (s.caustic_photons // 10)
        coefficients = 4 * 3 * s.icache_radiance_order ** 2 if s.icache_radiance else 0
        records = int(RECORDS_PER_PIXEL * s.width * s.height)
        return photons + 2 * 8 * records * (RECORD_FLOATS + coefficients)

    def __init__(self, scene):
        super().__init__(scene)
        s = scene.settings
        self.layout = BatchLayout(scene, self.batch_paths(s))
        if s.icache_gather == "path":
            self.n_global_items = 0  # gather rays trace paths: no global map
        self.M = max(2, int(round(np.sqrt(s.icache_rays / 2.0))))
        self.N = 2 * self.M  # Mitsuba 0.6's layout: N = 2M cells of about equal shape
        self.records = Records.empty()
        self.record_prim = np.zeros(0, np.int64)  # render process: each record's primitive...
        self.record_level = np.zeros(0, np.int64)  # ... and its sets of gather rays so far
        self.target_level = 0  # the level records are refined to once every point is covered
        self.refining = False  # whether the queue holds records to refine (else new points)
        self.octree = None
        self.candidates = {}  # render process: points still to cover
        self.queue_len = 0
        self.rounds = 0
        self.first_id = 0
        self.interpolated = self.fallback = 0
        self.pixel_angle = camera_mod.pixel_angle(scene.camera, s)  # perspective: at unit distance

    # --- render process -------------------------------------------------------------------
    def stages(self, round: int):
        if round == 0:
            self._plan = self._rounds()
        return next(self._plan, [])

    def _rounds(self):
        s = self.scene.settings
        if self.n_global_items + self.n_caustic_items:
            # No radiance photons: a record's gather rays read the full estimate. The nearest
            # radiance photon's E is biased low where photons are stratified and sparse (it
            # cannot count itself, and its neighbours keep their distance), more than the full
            # estimate (bench/results/icache/code_choices.md), and records need few lookups.
            yield [Stage("photons", self.n_global_items + self.n_caustic_items, publish=True)]
        n = self.layout.n_pixels
        probe = self.pixel_stage(0, n)
        yield [Stage("probe", probe.items, publish=True, start=0, stop=n)]
        yield from self._place()
        start, block = 0, 1
        while start < s.samples:
            stop = min(s.samples, start + block)
            film = self.pixel_stage(start * n, stop * n)
            self.target_level = 1 + stop // PASSES_PER_LEVEL if stop < s.samples else 0
            yield [Stage("pixels", film.items, film=True, publish=True, start=film.start, stop=film.stop)]
            yield from self._place()
            start, block = stop, min(MAX_BLOCK, 2 * block) if start else 1

    def _place(self):
        """Records rounds until every candidate point is covered (or MAX_ROUNDS), then a round
        that refines the records below the target level, if any."""
        while self.queue_len:
            name = "refine" if self.refining else "records"
            yield [Stage(name, -(-self.queue_len // self._records_per_item(self.queue_len)), publish=True)]

    def _records_per_item(self, queued: int) -> int:
        """At most RECORD_RAYS gather rays per item (cancel latency, memory), and a round cut
        into at least MIN_RECORD_ITEMS items, so that a small round does not leave a worker
        idle. Records do not depend on the cut: their rays are numbered by record."""
        return max(1, min(RECORD_RAYS // (self.M * self.N), -(-queued // MIN_RECORD_ITEMS)))

    def reduce(self, stage, results):
        if stage.name in ("photons", "radiance"):
            return super().reduce(stage, results)
        s = self.scene.settings
        if stage.name in ("probe", "pixels"):
            cat = {f: np.concatenate([r[f"miss.{f}"] for r in results]) for f in _FIELDS}
            if stage.name == "pixels":
                self.interpolated += sum(int(r["interpolated"][0]) for r in results)
                self.fallback += sum(int(r["fallback"][0]) for r in results)
            self.candidates, self.rounds = cat, 0
            out = self._queue()
        elif stage.name == "refine":
            self._refine({f: np.concatenate([r[f] for r in results]) for f in results[0]})
            out = {**{f"records.{k}": v for k, v in self.records.pack().items()}, **self._queue()}
        else:  # records
            cat = {f: np.concatenate([r[f] for r in results]) for f in results[0]}
            self.record_prim = np.concatenate([self.record_prim, cat.pop("prim")])
            self.record_level = np.concatenate([self.record_level, np.ones(len(cat["E"]), np.int64)])
            new = Records(**cat)
            self.first_id += len(new)
            self.records = neighbour_clamp(self.records, new)
            self.octree = RecordOctree(self.records, s.icache_a, s.icache_weight)
            self.rounds += 1
            out = {**{f"records.{k}": v for k, v in self.records.pack().items()}, **self._queue()}
        self._count()
        return out

    def _queue(self) -> dict:
        """The next records round's points: a well-spread subset of the candidates no record
        covers, MAX_PX footprints apart in the first round, half as far each round after
        (so smooth regions get few, large records before detailed ones are filled in). Once
        every point is covered: the records below the target level, to refine."""
        c = self.candidates
        if len(c["position"]) and self.octree is not None:
            _, _, count = self.octree.interpolate(c["position"], c["normal"], False)
            c = {f: v[count == 0] for f, v in c.items()}
        self.candidates = c
        n = len(c["position"])
        self.refining = False
        if n == 0 or self.rounds >= MAX_ROUNDS:
            refine = np.flatnonzero(self.record_level < self.target_level)
            self.queue_len, self.refining = len(refine), len(refine) > 0
            r = self.records
            return {"queue.id": refine, "queue.level": self.record_level[refine], "queue.prim": self.record_prim[refine],
                    "queue.position": r.position[refine], "queue.normal": r.normal[refine]}
        # spread_subset keeps points at least spacing / 2 apart: twice the support wanted,
        # down to the smallest support, then that (records a little closer than needed, so
        # that the last gaps close in a round or two, not one record per gap per round).
        px = MAX_PX / 2 ** self.rounds
        keep = spread_subset(c["position"], (2.0 * px if px > MIN_PX else MIN_PX) * c["footprint"], c["key"])
        self.queue_len = len(keep)
        return {"queue.id": self.first_id + np.arange(len(keep)), "queue.level": np.zeros(len(keep), np.int64),
                **{f"queue.{f}": np.ascontiguousarray(v[keep]) for f, v in c.items()}}

    def _refine(self, new: dict) -> None:
        """Records `new["id"]` with one more set of gather rays: E and the gradients become the
        mean over the sets; position, normal and radius stay (so does the octree's layout)."""
        r, i = self.records, new["id"]
        n = self.record_level[i].astype(np.float64)
        kept = n / (n + 1.0)  # the weight of the mean so far

        def mean(old, add):
            w = kept.reshape((-1,) + (1,) * (old.ndim - 1))
            return old[i] * w + add * (1.0 - w)
        E, grad_r, grad_t, coeffs, coeffs_grad = (a.copy() for a in (r.E, r.grad_r, r.grad_t, r.coeffs, r.coeffs_grad))
        # the translational gradient as the first set was kept: scaled down where the footprint
        # minimum raised the radius (_clamp_radius)
        shrink = np.minimum(1.0, np.divide(r.radius_unclamped[i], r.radius[i], out=np.ones(len(i)),
                                           where=r.radius[i] > 0))
        E[i], grad_r[i], grad_t[i] = mean(r.E, new["E"]), mean(r.grad_r, new["grad_r"]), \
            mean(r.grad_t, new["grad_t"] * shrink[:, None, None])
        if "coeffs" in new:  # radiance caching: the coefficients too
            limited = radiance.limit_gradient(new["coeffs"], new["coeffs_grad"], r.radius[i])
            coeffs[i], coeffs_grad[i] = mean(r.coeffs, new["coeffs"]), mean(r.coeffs_grad, limited)
        self.records = replace(r, E=E, grad_r=grad_r, grad_t=grad_t, coeffs=coeffs, coeffs_grad=coeffs_grad)
        self.record_level[i] += 1
        self.octree = RecordOctree(self.records, self.scene.settings.icache_a, self.scene.settings.icache_weight)

    def _count(self):
        s = self.scene.settings
        n = len(self.records)
        mpix = s.width * s.height / 1e6
        rays = self.M * self.N * (self.record_level.mean() if n else 1.0)
        text = f"{n} records ({n / mpix:.0f} per megapixel, {rays:.0f} gather rays each on average)"
        shaded = self.interpolated + self.fallback
        if shaded:
            text += f", {self.interpolated / shaded:.1%} of cached points interpolated"
        self._counters["records"] = text

    # --- tracing processes ----------------------------------------------------------------
    def build(self, ctx) -> None:
        super().build(ctx)
        self.single_diffuse = single_diffuse_materials(self.scene.materials)
        self._build_radiance()
        if self.scene.settings.icache_gather == "path":
            self.path_tracer = PathTracer(self.scene, ctx.accel, ctx.lights)

    def install(self, version, arrays):
        super().install(version, arrays)
        s = self.scene.settings
        if "records.position" in arrays:
            self.records = Records.from_packed({k.split(".", 1)[1]: v for k, v in arrays.items()
                                                if k.startswith("records.")})
            self.octree = RecordOctree(self.records, s.icache_a, s.icache_weight)
        if "queue.id" in arrays:
            self.queue = {k.split(".", 1)[1]: v for k, v in arrays.items() if k.startswith("queue.")}

    def run(self, stage, item, stop=None):
        if stage.name in ("photons", "radiance"):
            return super().run(stage, item, stop)
        if stage.name in ("records", "refine"):
            return self._records(item, stop, refine=stage.name == "refine")
        s, layout = self.scene.settings, self.layout
        j, sample = layout.locate(stage, item)
        self._probing = stage.name == "probe"
        self._misses = []
        self._shaded = [0, 0]
        sampler = rng.Sampler(s.seed, layout.pixel[j], sample, s.pattern)
        L = self._render(sampler, layout.pixel[j], sample, layout.px[j], layout.py[j], stop)
        out = {f"miss.{f}": (np.concatenate([m[f] for m in self._misses]) if self._misses else
                             np.zeros((0, 3) if f in ("position", "normal") else 0,
                                      np.float64 if f in ("position", "normal", "footprint") else np.int64))
               for f in _FIELDS}
        if self._probing:
            return out
        out.update(L=L, interpolated=np.array([self._shaded[0]]), fallback=np.array([self._shaded[1]]))
        if self._caustics is not None:
            out["passes"] = {"Caustics": np.ascontiguousarray(self._caustics.T)}
        return out

    def _shade_diffuse(self, L, sampler, idx, x, beta, p, ng_f, ns, wo, prim, bsdf, sample, pixel, depth, dist):
        """At cached points: direct light, caustics and the cached irradiance; elsewhere (other
        materials, points no record covers) what `photon` does."""
        s, mesh = self.scene.settings, self.scene.mesh
        cached = self.cached_material[mesh.material[prim[x]]]
        c, rest = x[cached], x[~cached]
        if len(c):
            at = gatherer(c, len(idx))
            pc, nc = at(p), at(ns)
            footprint = self._footprint(dist[c], dot(at(wo), nc))
            if self._probing:
                self._miss(c, pc, nc, footprint, prim, sample, pixel, idx)
                return
            E, _, count = (self.octree.interpolate(pc, nc, s.icache_gradients) if self.octree is not None
                           else (np.zeros((len(c), 3)), None, np.zeros(len(c), np.int64)))
            ok = count > 0
            self._shaded[0] += int(ok.sum())
            self._shaded[1] += int((~ok).sum())
            if not ok.all():  # not covered: final-gathered now, a candidate for the next records round
                miss = np.flatnonzero(~ok)
                self._miss(c[miss], take(pc, miss), take(nc, miss), footprint[miss], prim, sample, pixel, idx)
                rest = np.concatenate([rest, c[miss]])
            hit = np.flatnonzero(ok)
            if len(hit):
                self._shade_cached(L, sampler, idx, c[hit], beta, p, ng_f, ns, prim, bsdf, depth, take(E, hit),
                                   footprint[hit], sample, pixel)
        if len(rest) == 0 or self._probing:
            return
        rest = np.sort(rest)
        if s.icache_gather == "photon":
            super()._shade_diffuse(L, sampler, idx, rest, beta, p, ng_f, ns, wo, prim, bsdf, sample, pixel, depth, dist)
            return
        # Path-traced gathering: direct light by light sampling, G gather rays that leave out
        # the emission they find first and the caustic map's light.
        at = gatherer(rest, len(idx))
        rows, bx = idx[rest], at(beta)
        self._direct_emission(L, sampler, rows, rest, bx, at, p, ng_f, ns, prim, bsdf, depth, sample, pixel)
        G = max(s.gather_rays, 1)
        rep = np.repeat(np.arange(len(rest)), G)
        pix, smp = pixel[rows][rep], sample[rows][rep] * G + np.tile(np.arange(G), len(rest))
        bs = _sample_rows(bsdf, rest[rep], rng.Sampler(s.seed, pix, smp, s.pattern, domain=rng.GATHER).get(0, None, 3))
        g = np.flatnonzero(bs.valid)
        d = take(bs.wi, g)
        o64 = take(p, rest[rep][g])
        rays = PathState.rays(o64, offset_origin(o64, towards(take(ng_f, rest[rep][g]), d)), d, None,
                              prim[rest[rep][g]])
        Lg = self.path_tracer.trace(rng.Sampler(s.seed, pix[g], smp[g], s.pattern, domain=rng.GATHER), rays,
                                    Gather(first_emission=False, max_depth=max(s.max_depth - 1, 0),
                                           caustic_ends=self._caustic_ends()))
        _accumulate(L, rows[rep][g], take(bx, rep[g]) * take(bs.weight, g) * Lg / G)

    def _caustic_ends(self):
        """With a caustic map, path-traced gathers leave out the light it holds (L S+ D)."""
        return self.stores if self.n_caustic_items else None

    def _shade_cached(self, L, sampler, idx, c, beta, p, ng_f, ns, prim, bsdf, depth, E, footprint, sample, pixel):
        """Caustics, direct light and the cached irradiance E (K,3) at the points c."""
        s = self.scene.settings
        at = gatherer(c, len(idx))
        rows, bx = idx[c], at(beta)
        albedo = at(bsdf.reflectance)
        if s.icache_view == "records":
            _accumulate(L, rows, self._record_dots(at(p), footprint) + 0.5 * bx * albedo * E / np.pi)
            return
        indirect = albedo * E * (1.0 / np.pi)
        self._glossy_indirect(indirect, c, at, p, ns, prim, bsdf, sample, pixel, rows)
        if s.icache_view == "indirect":  # debug and studies: the cached term alone
            _accumulate(L, rows, bx * indirect)
            return
        self._caustics_at(L, rows, c, bx, at, p, ng_f, bsdf)
        self._direct_emission(L, sampler, rows, c, bx, at, p, ng_f, ns, prim, bsdf, depth, sample, pixel)
        _accumulate(L, rows, bx * indirect)

    # --- radiance caching (radiance.py) ------------------------------------------------------
    def _build_radiance(self):
        """Which materials the records serve (cached_material), and the harmonics order the
        records hold (0: no radiance caching, when it is off or no surface in view of it)."""
        s, m = self.scene.settings, self.scene.materials
        self.glossy_material = np.zeros(len(m.kind), bool)
        if s.icache_radiance:
            used = np.zeros(len(m.kind), bool)
            used[np.unique(self.scene.mesh.material)] = True
            self.glossy_material = radiance.cached_materials(m, s.icache_radiance_order) & ~self.single_diffuse & used
        self.cached_material = self.single_diffuse | self.glossy_material
        self.order = s.icache_radiance_order if self.glossy_material.any() else 0

    def _glossy_indirect(self, indirect, c, at, p, ns, prim, bsdf, sample, pixel, rows):
        """At the glossy cached points among c, replace indirect (K,3) by the dot product of the
        interpolated incident-radiance coefficients with the BSDF's (radiance.py). The BSDF's
        come from BSDF_SAMPLES samples, in the GATHER stream at pixels 2 W H and up (the
        direct light's are at W H and up), sample = camera sample x Q + q."""
        mesh = self.scene.mesh
        g = np.flatnonzero(self.glossy_material[mesh.material[prim[c]]])
        if len(g) == 0:
            return
        s = self.scene.settings
        pg, ng = take(at(p), g), take(at(ns), g)
        coeffs, _ = radiance.interpolate(self.octree, pg, ng, s.icache_gradients)
        Q = radiance.BSDF_SAMPLES
        u = rng.Sampler(s.seed, np.repeat(pixel[rows[g]] + 2 * s.width * s.height, Q),
                        np.repeat(sample[rows[g]] * Q, Q) + np.tile(np.arange(Q), len(g)), s.pattern,
                        domain=rng.GATHER).get(0, None, 3).reshape(len(g), Q, 3)

        def draw(q):
            bs = _sample_rows(bsdf, c[g], u[:, q])
            return bs.wi, bs.weight * bs.valid[:, None]
        indirect[g] = radiance.reflected(coeffs, radiance.bsdf_coefficients(self.order, draw))

    def _indirect_view(self) -> bool:
        return self.scene.settings.icache_view == "indirect"

    def _direct_emission(self, L, sampler, rows, x, bx, at, p, ng_f, ns, prim, bsdf, depth, sample, pixel):
        """Direct light at points x: DIRECT_SAMPLES light samples and as many BSDF samples that
        only look for emission, combined by the balance heuristic (the records leave that
        emission out; light sampling alone gives fireflies next to large emitters). Several
        per camera sample: with the indirect light cached, direct light is most of the noise,
        and its rays cost less than a camera path. Their stream: the GATHER domain at pixels
        W*H and up (no gather ray uses them), sample = camera sample x D + j."""
        s = self.scene.settings
        D = DIRECT_SAMPLES
        rep = np.repeat(np.arange(len(x)), D)
        u = rng.Sampler(s.seed, pixel[rows][rep] + s.width * s.height, sample[rows][rep] * D + np.tile(np.arange(D), len(x)),
                        s.pattern, domain=rng.GATHER)
        xr, bxr = x[rep], take(bx, rep) * (1.0 / D)
        at_r = lambda a: take(a, xr)  # noqa: E731 (rows repeat: not gatherer)
        self._direct_light(L, u.get(1, None, 3), rows[rep], xr, bxr, at_r, p, ng_f, ns, prim, bsdf, 1)
        _accumulate(L, rows[rep], bxr * self._gather(u, xr, p, ng_f, prim, bsdf, 1, emission_only=True))

    def _record_dots(self, pc, footprint):
        """(K,3) white where a record lies within DOT_PX / 2 footprints of the point."""
        from pykdtree.kdtree import KDTree

        if getattr(self, "_dots", (None,))[0] is not self.records:
            self._dots = (self.records, KDTree(np.ascontiguousarray(self.records.position)))
        dist, _ = self._dots[1].query(np.ascontiguousarray(pc), k=1)
        return np.where((dist <= 0.5 * DOT_PX * footprint)[:, None], 1.0, 0.0) * np.ones(3)

    def _footprint(self, dist, cos_view):
        """World size of a pixel at path length dist, seen at cos_view."""
        s = 1.0 if self.scene.camera.ortho else dist
        # Never 0 (a point at the camera, a degenerate window): it sets spacings and radii.
        return np.maximum(s * self.pixel_angle / np.maximum(np.abs(cos_view), MIN_COS), 1e-9 * self.radius + 1e-12)

    def _miss(self, rows, pc, nc, footprint, prim, sample, pixel, idx):
        """Points to cover with records: rows of the batch's live paths idx; their key (the
        order of preference in spread_subset) is a hash of (sample, pixel)."""
        r = idx[rows]
        key = rng._mix((sample[r].astype(np.uint64) << np.uint64(32)) ^ pixel[r].astype(np.uint64))
        self._misses.append({"position": pc, "normal": nc, "footprint": footprint,
                             "prim": prim[rows].astype(np.int64), "key": key.view(np.int64)})

    def _records(self, item, stop, refine=False):
        """Records at queue points [item x per item, ...): M x N gather rays each, numbered by
        the record's id and its level (the sets of rays it had before). refine: only the new
        set's E and gradients, for the render process to average in (_refine)."""
        s = self.scene.settings
        q = self.queue
        per = self._records_per_item(len(q["position"]))
        rows = np.arange(item * per, min((item + 1) * per, len(q["position"])))
        K, M, N = len(rows), self.M, self.N
        MN = M * N
        ids, level = np.asarray(q["id"])[rows], np.asarray(q["level"])[rows]
        sampler = rng.Sampler(s.seed, np.repeat(ids, MN), np.repeat(level * MN, MN) + np.tile(np.arange(MN), K),
                              s.pattern, domain=rng.RECORDS)
        p = np.asarray(q["position"], np.float64)[rows]
        n = np.asarray(q["normal"], np.float64)[rows]
        t, b = frame_from_z(n)
        local = cell_directions(M, N, sampler.get(0, None, 2).reshape(K, M, N, 2)).reshape(-1, 3)
        rep = np.repeat(np.arange(K), MN)
        d = to_world(local, take(t, rep), take(b, rep), take(n, rep))
        o64 = take(p, rep)
        o32 = offset_origin(o64, take(n, rep))
        skip = np.asarray(q["prim"])[rows][rep]
        t_first = np.full(K * MN, np.inf)
        if stop is not None and stop.is_set():
            raise Cancelled()
        if s.icache_gather == "path":
            Lr = self.path_tracer.trace(sampler, PathState.rays(o64, o32, d, None, skip),
                                        Gather(first_emission=False, max_depth=max(s.max_depth - 1, 0),
                                               caustic_ends=self._caustic_ends(), t_first=t_first), stop)
        else:
            Lr = self._trace_gather(sampler, K * MN, PathState.rays(o64, o32, d, None, skip, beta=np.ones((K * MN, 3))),
                                    t_first=t_first)
        E, R, grad_r, grad_t = record_terms(Lr.reshape(K, M, N, 3), t_first.reshape(K, M, N))
        coeffs = {}
        if self.order:  # radiance caching: the same gather in spherical harmonics
            coeffs = dict(zip(("coeffs", "coeffs_grad"), radiance.record_coefficients(
                self.order, Lr.reshape(K, M, N, 3), t_first.reshape(K, M, N), d.reshape(K, M, N, 3), (t, b, n))))
        grad_r = gradient_to_world(grad_r, (t, b, n))
        grad_t = gradient_to_world(grad_t, (t, b, n))
        if refine:
            return {"id": ids, "E": E, "grad_r": grad_r, "grad_t": grad_t, **coeffs}
        out = {"position": p, "normal": n, "E": E, "grad_r": grad_r, "prim": np.asarray(q["prim"])[rows], **coeffs,
               **self._clamp_radius(E, R, grad_t, np.asarray(q["footprint"])[rows])}
        if self.order:
            out["coeffs_grad"] = radiance.limit_gradient(out["coeffs"], out["coeffs_grad"], out["radius"])
        return out

    def _clamp_radius(self, E, R, grad_t, footprint):
        """R_i from the harmonic mean, limited by the gradient (R <= E / |grad_t E|, per channel;
        Krivanek et al. 2008), its support a R_i clamped to MIN_PX..MAX_PX pixel footprints
        and MIN_WORLD..MAX_WORLD scene radii. A record pushed up to the minimum gets its
        translational gradient scaled down by the same factor (Mitsuba 0.6), so it does not
        extrapolate over a range its rays did not see. Returns the Records fields radius,
        radius_unclamped (before the footprint clamps: neighbour clamping works on it),
        radius_min and grad_t."""
        a = self.scene.settings.icache_a
        g = np.sqrt(np.einsum("rcx,rcx->rc", grad_t, grad_t))
        limit = np.where(g > 0, np.divide(E, g, out=np.full(E.shape, np.inf), where=g > 0), np.inf).min(axis=1)
        world_max = MAX_WORLD * self.radius / a
        lo = np.minimum(np.maximum(MIN_PX * footprint, MIN_WORLD * self.radius) / a, world_max)
        hi = np.maximum(np.minimum(MAX_PX * footprint / a, world_max), lo)
        R = np.minimum(np.minimum(R, limit), hi)
        clamped = np.maximum(R, lo)
        shrink = np.divide(R, clamped, out=np.ones_like(R), where=clamped > R)
        return {"radius": clamped, "radius_unclamped": R, "radius_min": lo, "grad_t": grad_t * shrink[:, None, None]}
