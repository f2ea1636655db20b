"""Two-pass photon mapping with final gathering (seed 001; Jensen 1996, 2001).

Rounds of stages (engine/integrators/base.py):
  0  photons   items of PHOTON_BATCH photon paths: the global stream (every diffuse hit)
               then the caustic stream (L S+ D photons only); reduced into the global and the
               caustic map and published to every worker.
  1  radiance  (radiance photons on) irradiance at every 4th global photon (Christensen
               1999), items of slices, published: a gather ray then needs one lookup.
  2  pixels    camera paths (film stage).

A camera path follows specular surfaces (delta lobes, and lobes too sharp to store photons)
to its first diffuse point x, where the radiance is split as Jensen does:
  direct    one light sample, combined with the G gather rays (BSDF-sampled) by the
            balance heuristic over all G + 1 samples (Veach's multi-sample MIS);
  caustics  the caustic map's radiance estimate at x (L S+ D E), each photon's flux spread
            over its own k-nearest disc (PhotonMap.radiance_scattered: keeps the flux);
  indirect  final gathering: G BSDF-sampled rays from x; a ray's first diffuse hit y gives the
            global map's radiance estimate there (or E(y) of the nearest radiance photon
            times the albedo / pi); specular hits are followed without emission (that light
            is in the caustic map).
Emission seen directly by the camera (or through specular surfaces) is added with weight 1.
"""
from __future__ import annotations

import numpy as np

from ... import camera as camera_mod
from ... import rng
from ...accel import bounding_radius, offset_origin
from ...bsdf.closure import BSDFSample
from ...bsdf.fast_path import make_closure, plain_lambert_albedo
from ...nodes.material import MaterialPrograms
from ...errors import Cancelled
from ...lights.emission import PhotonEmitter
from ...vec import dot, gatherer, max3, scale, take
from ...visibility import RayVisibility
from ..base import Integrator, Stage
from ..path_state import PathState
from ..shadows import ShadowRays
from ..surface import emitted, flat_normals, shading_frame, towards
from .photon_map import PhotonMap, RadiancePhotons
from .tracing import PhotonTracer, diffuse_materials
from ...layout import BatchLayout

PHOTON_BATCH = 1 << 16  # photon paths per work item
RADIANCE_BATCH = 1 << 15  # radiance photons per work item
RADIANCE_STRIDE = 4  # every 4th global photon becomes a radiance photon
GLOBAL_RADIUS, CAUSTIC_RADIUS = 0.05, 0.0125  # x scene radius: Mitsuba 0.6's defaults
VISIBILITY_LIFT = 1e-4  # x scene radius: photon-to-point segments start and end this far off the surfaces
PHOTON_BYTES = 48  # a stored photon: 32 B packed + the k-NN index (tests/test_photon_map.py)
POSITIONS_RADIUS = 0.002  # x scene radius: a photon shows as a dot this size in the "positions" view
_CAUSTIC_COLOUR = np.array([1.0, 0.5, 0.1])
MIN_COUNT = 1  # the seed zeroes estimates below a minimum count, which darkens sparse regions
# Random-number groups of a camera path (rng.Sampler): 0 the pixel filter, then per vertex
# light (0-1 point, 2 choice) and BSDF (0-1 direction, 2 lobe); gather rays use domain GATHER
# with sample index = camera sample x G + ray, per bounce one BSDF group.
_LIGHT, _BSDF, _GROUPS = 0, 1, 2


def _accumulate(L, rows, c):
    """L[:, rows] += c.T for L (3,N); rows may repeat (gather rays of one point)."""
    for k in range(3):
        L[k] += np.bincount(rows, weights=c[:, k], minlength=L.shape[1])


class PhotonIntegrator(Integrator):
    name = "photon"
    label = "Photon Mapping"
    description = ("Two-pass photon mapping: caustic map, final gathering on the global map "
                   "(biased, consistent as photons grow)")
    own_passes = ("Caustics",)
    adaptive = True  # its camera pass: the maps are built once, before it
    view_independent = ("photons", "radiance")  # ppm's photons carry their pass; icache's records see the camera

    def __init__(self, scene):
        super().__init__(scene)
        s = scene.settings
        # Every camera path may spawn G gather rays: fewer paths per item keep an item's rays
        # (memory) and its duration (cancel latency) near the path tracer's.
        self.layout = BatchLayout(scene, self.batch_paths(s))
        v = scene.mesh.vertices
        self.center = (0.5 * (v.min(axis=0) + v.max(axis=0))).astype(np.float64) if len(v) else np.zeros(3)
        self.radius = bounding_radius(v)
        self.r_global = s.global_radius or GLOBAL_RADIUS * self.radius
        self.r_caustic = s.caustic_radius or CAUSTIC_RADIUS * self.radius
        # Caustics need a specular surface: without one the caustic stream is skipped.
        m = scene.materials
        specular = ~diffuse_materials(m) & (np.bincount(m.lobe_material, minlength=len(m.kind)) > 0)
        used = np.unique(scene.mesh.material) if scene.mesh.n_triangles else np.zeros(0, np.int64)
        self.has_specular = bool(np.any(specular[used]))
        self.n_global_items = -(-s.photons // PHOTON_BATCH)
        self.n_caustic_items = -(-s.caustic_photons // PHOTON_BATCH) if self.has_specular else 0
        self._counters: dict = {}
        self.global_map = self.caustic_map = self.radiance_photons = None
        self.n_global_photons = 0

    # --- render process -------------------------------------------------------------------
    @classmethod
    def memory_estimate(cls, scene) -> int:
        """About 3 stored photons per global path (a closed room; open scenes store fewer) and
        1 per 10 caustic paths, 48 B each with the index, twice (the reduced arrays and the
        published copy)."""
        s = scene.settings
        return 2 * PHOTON_BYTES * (3 * s.photons + s.caustic_photons // 10)

    @staticmethod
    def batch_paths(s) -> int:
        """Camera paths per batch: every one may spawn gather_rays gather rays."""
        return max(1024, s.batch_size // max(1, s.gather_rays))

    @classmethod
    def batch_rays(cls, scene, paths: int) -> int:
        s = scene.settings
        return min(cls.batch_paths(s), paths) * max(1, s.gather_rays)

    def work_items(self) -> int:
        return self.layout.n_batches + self.n_global_items + self.n_caustic_items

    def stages(self, round: int):
        s = self.scene.settings
        if round == 0:
            return [Stage("photons", self.n_global_items + self.n_caustic_items, publish=True)]
        if round == 1:  # the photons are reduced: their count decides whether radiance photons pay
            self._after_photons = [[self.samples_stage()]]
            if s.radiance_photons and s.photon_view == "full" and self.n_global_photons:
                items = -(-(-(-self.n_global_photons // RADIANCE_STRIDE)) // RADIANCE_BATCH)
                self._after_photons.insert(0, [Stage("radiance", items, publish=True)])
        rest = self._after_photons
        return rest[round - 1] if round - 1 < len(rest) else []

    def reduce(self, stage, results):
        if stage.name == "photons":
            g, c = results[:self.n_global_items], results[self.n_global_items:]
            cat = lambda parts, key: np.concatenate([r[key] for r in parts]) if parts else np.zeros((0, 3), np.float32)  # noqa: E731
            out = {}
            for prefix, parts in (("global", g), ("caustic", c)):
                packed = PhotonMap.pack(cat(parts, "position"), cat(parts, "wi"), cat(parts, "flux"),
                                        cat(parts, "normal"))
                out.update({f"{prefix}.{k}": v for k, v in packed.items()})
            self.n_global_photons = len(out["global.position"])
            n_caustic = len(out["caustic.position"])
            bounces = sum(int(r["bounces"][0]) for r in results)
            nbytes = sum(v.nbytes for v in out.values())
            self._counters["photons"] = (f"{self.n_global_photons / 1e3:.0f}k global + {n_caustic / 1e3:.0f}k caustic "
                                         f"photons stored ({bounces / 1e6:.2f} M photon hits, {nbytes / 2**20:.0f} MiB)")
            if not self.n_caustic_items:
                self._counters["caustic"] = "no caustic map: no specular surface"
            return out
        # radiance photons: the slices in order
        cat = lambda key: np.concatenate([r[key] for r in results])  # noqa: E731
        return {f"radiance.{k}": v for k, v in RadiancePhotons.pack(cat("position"), cat("normal"), cat("E")).items()}

    def counters(self) -> dict:
        return dict(self._counters)

    # --- tracing processes ----------------------------------------------------------------
    def build(self, ctx) -> None:
        super().build(ctx)
        s = self.scene.settings
        self.emitter = PhotonEmitter(ctx.lights, self.center, self.radius)
        self.photon_tracer = PhotonTracer(ctx, self.emitter, s.max_depth)
        self.lambert_albedo = plain_lambert_albedo(self.scene.materials)
        self.programs = MaterialPrograms.of(self.scene.materials)
        self.flat_normal = flat_normals(self.scene.mesh)
        self.shadows = ShadowRays(self.scene, RayVisibility(ctx.accel, self.scene.mesh), self.programs, ctx.lights.links)
        self._bary = None  # the barycentrics of the camera pass's points being shaded
        self.stores = diffuse_materials(self.scene.materials)
        self.emissive_material = self.scene.materials.emission.mean(axis=1) > 0
        # per triangle; a miss (-1) reads the last entry, False
        self.emissive_prim = np.append(self.emissive_material[self.scene.mesh.material], False)

    def install(self, version, arrays):
        split = lambda prefix: {k.split(".", 1)[1]: v for k, v in arrays.items() if k.startswith(prefix + ".")}  # noqa: E731
        if "global.position" in arrays:
            s = self.scene.settings
            self.global_map = PhotonMap.from_packed(split("global"), max(s.photons, 1))
            self.caustic_map = PhotonMap.from_packed(split("caustic"), max(s.caustic_photons, 1))
            self.caustic_map.set_photon_radii(s.photon_k, self.r_caustic)
        if "radiance.position" in arrays:
            self.radiance_photons = RadiancePhotons.from_packed(split("radiance"))

    def run(self, stage, item, stop=None):
        s = self.scene.settings
        if stage.name == "photons":
            caustic = item >= self.n_global_items
            first = (item - self.n_global_items if caustic else item) * PHOTON_BATCH
            total = s.caustic_photons if caustic else s.photons
            paths = np.arange(first, min(first + PHOTON_BATCH, total))
            if self.emitter.empty or len(paths) == 0:
                return _no_photons()
            # One Sobol sequence per stream: photon j is sample j (stratified emission).
            sampler = rng.Sampler(s.seed, np.full(len(paths), int(caustic)), paths, s.pattern, domain=rng.PHOTONS)
            return self.photon_tracer.trace(sampler, caustic, stop)
        if stage.name == "radiance":
            rows = np.arange(item * RADIANCE_BATCH, min((item + 1) * RADIANCE_BATCH,
                                                        -(-len(self.global_map) // RADIANCE_STRIDE)))
            rows = rows * RADIANCE_STRIDE
            position = take(self.global_map.position, rows)
            normal = self.global_map.normal(rows)
            visible = self.visible(position, normal, self.global_map)

            def others(r, j):
                # The estimate at a photon must not count that photon: it was not drawn
                # independently of the point, and where photons are sparse (a few per disk)
                # counting it overstated E several-fold, enough to brighten a whole interior
                # (bench/results/photon/code_choices.md).
                keep = j != rows[r]
                keep[keep] = visible(r[keep], j[keep])
                return keep
            E, _ = self.global_map.irradiance(position, normal, s.photon_k, self.r_global, kernel=s.photon_kernel,
                                              min_count=MIN_COUNT, accept=others)
            return {"position": position, "normal": normal, "E": E}
        layout = self.layout
        j, sample = layout.locate(stage, item)
        sampler = rng.Sampler(s.seed, layout.pixel[j], sample, s.pattern)
        L = self._render(sampler, layout.pixel[j], sample, layout.px[j], layout.py[j], stop)
        if self._caustics is None:
            return L
        return {"L": L, "passes": {"Caustics": np.ascontiguousarray(self._caustics.T)}}

    # --- the camera pass --------------------------------------------------------------------
    def _render(self, sampler, pixel, sample, px, py, stop):
        scene, s, accel, lights = self.scene, self.scene.settings, self.ctx.accel, self.ctx.lights
        o64, d, tmax = camera_mod.camera_rays(scene.camera, s, px, py, sampler)
        n = len(px)
        L = np.zeros((3, n))
        # The Caustics render pass: the caustic map's term alone (same layout as L).
        self._caustics = np.zeros((3, n)) if "Caustics" in s.passes else None
        idx = np.arange(n)
        o32 = o64.astype(np.float32)
        beta = np.ones((n, 3))
        beta[tmax <= 0.0] = 0.0  # a panoramic camera's rays outside its image carry nothing
        skip = np.full(n, -1, np.int64)
        dist = np.zeros(n)  # length of the camera path so far (pixel footprints)
        mesh = scene.mesh
        for depth in range(s.max_depth + 1):
            if stop is not None and stop.is_set():
                raise Cancelled()
            if len(idx) == 0:
                break
            hit = accel.intersect(o32, d, tmax, skip)
            camera_ray = np.full(len(idx), depth == 0)
            no_weight = np.zeros(len(idx))
            everyone = np.zeros(len(idx), bool)  # use_mis False: emission with weight 1
            if len(lights.hittable):
                _accumulate(L, idx, beta * lights.emission_along(o64, d, hit.t, no_weight, everyone, camera_ray))
            missed = hit.prim < 0
            if missed.any() and lights.sees_escaped:
                r = np.flatnonzero(missed)
                _accumulate(L, idx[r], take(beta, r) * lights.escaped(take(d, r), no_weight[r], everyone[r],
                                                                      camera_ray[r]))
            keep = np.flatnonzero(~missed)
            if len(keep) == 0:
                break
            idx, prim, dist = idx[keep], hit.prim[keep], dist[keep] + hit.t[keep]
            beta, p, d, bary, ng = (take(a, keep) for a in (beta, hit.p, d, hit.b, hit.ng))
            mat = mesh.material[prim]
            emits = self.emissive_material[mat]
            if emits.any():
                r = np.flatnonzero(emits)
                Le = emitted(scene, self.programs, self.flat_normal, take(scene.materials.emission, mat[r]),
                             hit.take(keep[r]), take(d, r))
                _accumulate(L, idx[r], take(beta, r) * Le)
            wo = -d
            ng_f, ns = shading_frame(mesh, self.flat_normal, prim, bary, ng, wo)
            bsdf = make_closure(scene, self.lambert_albedo, mat, ns, ng_f, wo, prim, bary, programs=self.programs, p=p)
            ns = bsdf.ns
            diffuse = self.stores[mat] & bsdf.has_smooth
            x = np.flatnonzero(diffuse)
            if len(x):
                self._bary = bary  # the terminator offsets' (_direct_light)
                self._shade_diffuse(L, sampler, idx, x, beta, p, ng_f, ns, wo, prim, bsdf, sample, pixel, depth, dist)
            spec = np.flatnonzero(~diffuse)
            if depth == s.max_depth or len(spec) == 0:
                break
            # Specular vertices: follow the BSDF (no light sampling: the camera path only
            # looks for its first diffuse point).
            u = sampler.get(1 + _GROUPS * depth + _BSDF, idx[spec], 3)
            bs = bsdf.sample(*_full(u, spec, len(idx)))
            ok = spec[bs.valid[spec]]
            beta = take(beta, ok) * take(bs.weight, ok)
            live = np.flatnonzero(max3(beta) > 0)
            ok = ok[live]
            beta = take(beta, live)
            idx, d, dist = idx[ok], take(bs.wi, ok), dist[ok]
            o64 = take(p, ok)
            o32 = offset_origin(o64, towards(take(ng_f, ok), d))
            skip, tmax = prim[ok], None
        return np.ascontiguousarray(L.T)

    def _shade_diffuse(self, L, sampler, idx, x, beta, p, ng_f, ns, wo, prim, bsdf, sample, pixel, depth, dist):
        """Direct light, caustics and final gathering at the diffuse points x (rows of idx);
        dist: the camera paths' lengths."""
        s = self.scene.settings
        at = gatherer(x, len(idx))
        rows, bx = idx[x], at(beta)
        G = max(s.gather_rays, 0)
        view = s.photon_view
        f_at = lambda pts: (lambda r, wi: bsdf.eval(wi, pts[r])[0])  # noqa: E731
        if view == "positions":  # debug: where photons landed, caustic ones in orange
            r = np.full(len(x), POSITIONS_RADIUS * self.radius)
            near = lambda m: m.gather_radius(at(p), at(ng_f), r)[1] > 0 if len(m) else np.zeros(len(x), bool)  # noqa: E731
            caustic, seen = near(self.caustic_map), near(self.global_map)
            colour = np.where(caustic[:, None], _CAUSTIC_COLOUR, np.where(seen[:, None], 1.0, 0.0))
            _accumulate(L, rows, colour)
            return
        if view == "global":
            Lg, _ = self.global_map.radiance(at(p), at(ng_f), f_at(x), s.photon_k, self.r_global, kernel=s.photon_kernel, min_count=MIN_COUNT,
                                             accept=self.visible(at(p), at(ng_f), self.global_map))
            _accumulate(L, rows, bx * Lg)
            return
        indirect = self._indirect_view()
        if not indirect:
            self._caustics_at(L, rows, x, bx, at, p, ng_f, bsdf)
        if view == "caustic":
            return
        if not indirect:
            self._direct_light(L, sampler.get(1 + _GROUPS * depth + _LIGHT, rows, 3), rows, x, bx, at, p, ng_f, ns,
                               prim, bsdf, G)
        if G == 0:
            return
        # Final gathering: G rays per point, stratified over the pixel's camera samples.
        rep = np.repeat(np.arange(len(x)), G)
        gsampler = rng.Sampler(s.seed, pixel[rows][rep], sample[rows][rep] * G + np.tile(np.arange(G), len(x)), s.pattern,
                               domain=rng.GATHER)
        Lg = self._gather(gsampler, x[rep], p, ng_f, prim, bsdf, G, emission=not indirect)
        _accumulate(L, rows[rep], take(bx, rep) * Lg / G)

    def _indirect_view(self) -> bool:
        """The debug view of the final-gathered indirect light alone (no direct, no caustics)."""
        return self.scene.settings.photon_view == "indirect"

    def _caustics_at(self, L, rows, x, bx, at, p, ng_f, bsdf):
        """The caustic map's radiance estimate at the diffuse points x, into L (and the
        Caustics render pass when it is on)."""
        if self.caustic_map is None or not len(self.caustic_map):
            return
        s = self.scene.settings
        # Each caustic photon spreads its flux over its own k-nearest disc: a sharp caustic keeps
        # its energy (the k-nearest disc of a dark point beside it would reach in and add light).
        Lc = self.caustic_map.radiance_scattered(at(p), at(ng_f), lambda r, wi: bsdf.eval(wi, x[r])[0],
                                                 kernel=s.photon_kernel,
                                                 accept=self.visible(at(p), at(ng_f), self.caustic_map))
        _accumulate(L, rows, bx * Lc)
        if self._caustics is not None:
            _accumulate(self._caustics, rows, bx * Lc)

    def visible(self, p, n, photons):
        """accept(rows, j) for the photon estimates: photon j and query point p[rows] see each
        other. Photons a thin wall away pass the search and the normal test (the floor on both
        sides of a wall faces up); a segment between the two, lifted off their surfaces along
        their normals, crosses the wall. Costs one shadow ray per candidate photon."""
        lift = VISIBILITY_LIFT * self.radius

        def accept(rows, j):
            o = take(p, rows) + take(n, rows) * lift
            t = take(photons.position, j).astype(np.float64) + photons.normal(j).astype(np.float64) * lift
            return ~self.ctx.accel.occluded(o, t)
        return accept

    def _direct_light(self, L, u_light, rows, x, bx, at, p, ng_f, ns, prim, bsdf, G):
        """One light sample (uniforms u_light (K,3)) at each diffuse point x (K,) (rows of L),
        weighted by the balance heuristic against G BSDF samples (Veach's multi-sample MIS;
        G = 0: light sampling alone); the shadow terminator's offsets as the path tracer's (the
        barycentrics of the batch's points: self._bary)."""
        lights = self.ctx.lights
        if lights.empty:
            return
        ls = lights.sample(at(p), u_light[:, 2], u_light[:, :2],
                           receiver=lights.receivers(prim[x]) if lights.light_linked else None)
        f, pdf_b = bsdf.eval(ls.wi, x, None, self.shadows.lifted(prim[x]))
        if self.shadows.shading_offset is not None:  # the terminator's Shading Offset
            f = scale(f, self.shadows.shading_factor(prim[x], at(bsdf.ns), ls.wi))
        cos_i = np.abs(dot(ls.wi, at(ns)))
        w = np.where(ls.delta, 1.0, ls.pdf / np.maximum(ls.pdf + G * pdf_b, 1e-300))
        contrib = bx * f * scale(ls.Le, np.divide(cos_i * w, ls.pdf, out=np.zeros(len(x)), where=ls.valid))
        test = np.flatnonzero(max3(contrib) > 0)
        if len(test):
            t = x[test]
            o_shadow, skip = self.shadows.origin(take(at(p), test), towards(take(at(ng_f), test), take(ls.wi, test)),
                                                 prim[t], None if self._bary is None else take(self._bary, t),
                                                 take(getattr(bsdf, "n_smooth", bsdf.ns), t), take(at(ng_f), test),
                                                 take(ls.wi, test))
            lit, T = self.shadows.trace(o_shadow, take(ls.target, test), skip, ls.target_prim[test],
                                        light=None if ls.light is None else ls.light[test])
            lit = test[lit]
            _accumulate(L, rows[lit], take(contrib, lit) if T is None else take(contrib, lit) * T)

    def _gather(self, sampler, pts, p, ng_f, prim, bsdf, G, emission_only=False, emission=True):
        """Radiance (K,3) x BSDF weight of one gather ray from each diffuse point pts (K,);
        emission_only: only the emission the ray finds (the BSDF strategy of direct light);
        emission False: none of the emission the ray finds first (its light is sampled apart)."""
        u = sampler.get(0, None, 3)
        bs = _sample_rows(bsdf, pts, u)
        if self.shadows.shading_offset is not None:  # the terminator's Shading Offset
            bs.weight = scale(bs.weight, self.shadows.shading_factor(prim[pts], take(bsdf.ns, pts), bs.wi))
        g = np.flatnonzero(bs.valid)
        d = take(bs.wi, g)
        o64 = take(p, pts[g])
        o32 = offset_origin(o64, towards(take(ng_f, pts[g]), d))
        rays = PathState.rays(o64, o32, d, None, prim[pts[g]], idx=g, beta=take(bs.weight, g))
        if emission:  # the rays are also the BSDF strategy of direct light (G samples of it)
            rays.pdf_prev, rays.no_mis = G * bs.pdf[g], bs.delta[g]
        return self._trace_gather(sampler, len(pts), rays, emission_only=emission_only)

    def _trace_gather(self, sampler, K, rays: PathState, t_first=None, emission_only=False):
        """Radiance (K,3) x beta found by gather rays (PathState.rays: rows idx of the K
        outputs, throughput beta). With their MIS state (pdf_prev, no_mis: delta) the rays
        are also the BSDF strategy of direct light, and the emission they find is weighted
        against light sampling (balance heuristic); without it, that emission is left out
        (its light is sampled apart). t_first (K,), if given, receives the first hit's
        distance (inf where the ray escaped). Random groups from 1."""
        scene, s = self.scene, self.scene.settings
        out = np.zeros((3, K))
        paths = rays
        for depth in range(s.max_depth):
            if len(paths) == 0:
                break
            hit = paths.intersect(self.ctx.accel, t_first=t_first if depth == 0 else None)
            if paths.pdf_prev is not None:
                self._emission_found(out, paths, hit)
            if emission_only:
                break
            paths = paths.arrive(hit, np.flatnonzero(hit.prim >= 0), scene.mesh.material)
            wo = -paths.d
            paths.ng, paths.ns = shading_frame(scene.mesh, self.flat_normal, paths.prim, paths.bary, paths.ng, wo)
            stores = self.stores[paths.mat]
            self._photon_radiance(out, paths, wo, stores)
            # Specular gather hits: follow them (no emission: that light is the caustic map's).
            c = np.flatnonzero(~stores)
            if len(c) == 0:
                break
            paths = paths.take(c) if len(c) < len(paths) else paths
            bsdf = make_closure(scene, self.lambert_albedo, paths.mat, paths.ns, paths.ng, -paths.d, paths.prim,
                                paths.bary, programs=self.programs, p=paths.p)
            u = sampler.get(1 + paths.depth, paths.idx, 3)
            bs = bsdf.sample(u[:, :2], u[:, 2])
            ok = np.flatnonzero(bs.valid)
            paths = paths.leave(ok, take(bs.wi, ok), take(paths.beta, ok) * take(bs.weight, ok))
        return np.ascontiguousarray(out.T)

    def _emission_found(self, out, rays: PathState, hit) -> None:
        """Emission the gather rays find (light objects they pass, suns and the world where
        they escape, emissive triangles they hit), weighted by the balance heuristic against
        light sampling (pdf_prev / (pdf_prev + p_L); 1 where no_mis)."""
        lights, idx = self.ctx.lights, rays.idx
        not_camera = np.zeros(len(rays), bool)
        use_mis = ~rays.no_mis
        receiver = lights.receivers(rays.skip)  # light linking: the lights linked to the points they leave
        if len(lights.hittable):
            _accumulate(out, idx, rays.beta * lights.emission_along(rays.o64, rays.d, hit.t, rays.pdf_prev, use_mis,
                                                                    not_camera, receiver=receiver))
        missed = hit.prim < 0
        if missed.any() and lights.sees_escaped:
            r = np.flatnonzero(missed)
            _accumulate(out, idx[r], take(rays.beta, r) * lights.escaped(take(rays.d, r), rays.pdf_prev[r], use_mis[r],
                                                                          not_camera[r], receiver=None if receiver is None
                                                                          else receiver[r]))
        emits = self.emissive_prim[hit.prim]
        if receiver is not None and emits.any():
            emits &= lights.links.lights(lights.light_of_prim[np.maximum(hit.prim, 0)], receiver)
        if emits.any():
            r = np.flatnonzero(emits)
            prim, pm = hit.prim[r], rays.pdf_prev[r]
            at = hit.take(r)
            cos_l = np.abs(dot(take(rays.d, r), at.ng))
            pdf_light = lights.pdf_triangle_hit(prim, take(rays.o64, r), hit.t[r], cos_l, at.b,
                                                None if receiver is None else receiver[r])
            w = np.where(rays.no_mis[r], 1.0, pm / np.maximum(pm + pdf_light, 1e-300))
            Le = emitted(self.scene, self.programs, self.flat_normal, take(self.scene.materials.emission,
                         self.scene.mesh.material[prim]), at, take(rays.d, r))
            _accumulate(out, idx[r], take(rays.beta, r) * scale(Le, w))

    def _photon_radiance(self, out, paths: PathState, wo, stores) -> None:
        """The global map's radiance estimate at the gather hits on diffuse surfaces (stores
        (N,) bool), x beta, into out."""
        s = self.scene.settings
        # Radiance photons hold irradiance, so they serve surfaces that reflect it as
        # Lambert's law says (albedo / pi E); any other BSDF is evaluated per photon.
        lambert = stores & ~np.isnan(self.lambert_albedo[paths.mat, 0]) if self.radiance_photons is not None else None
        for y, fast in ((np.flatnonzero(lambert), True), (np.flatnonzero(stores & ~lambert), False)) \
                if lambert is not None else ((np.flatnonzero(stores), False),):
            if len(y) == 0:
                continue
            py, ny = take(paths.p, y), take(paths.ng, y)
            if fast:
                E, found = self.radiance_photons.lookup(py, ny, self.r_global, return_found=True,
                                                        accept=self.visible(py, ny, self.radiance_photons))
                # Where photons are sparse no radiance photon may lie within the radius:
                # the full estimate there, not 0 (which visibly darkened a sunlit interior).
                miss = np.flatnonzero(~found)
                if len(miss):
                    pm, nm = take(py, miss), take(ny, miss)
                    E[miss], _ = self.global_map.irradiance(pm, nm, s.photon_k, self.r_global,
                                                            kernel=s.photon_kernel, min_count=MIN_COUNT,
                                                            accept=self.visible(pm, nm, self.global_map))
                Ly = E * take(self.lambert_albedo, paths.mat[y]) * (1.0 / np.pi)
            else:
                bsdf_y = make_closure(self.scene, self.lambert_albedo, paths.mat[y], take(paths.ns, y), ny, take(wo, y),
                                      paths.prim[y], take(paths.bary, y), programs=self.programs, p=py)
                Ly, _ = self.global_map.radiance(py, ny, lambda r, wi: bsdf_y.eval(wi, r)[0],
                                                 s.photon_k, self.r_global, kernel=s.photon_kernel, min_count=MIN_COUNT,
                                                 accept=self.visible(py, ny, self.global_map))
            _accumulate(out, paths.idx[y], take(paths.beta, y) * Ly)


def _sample_rows(bsdf, pts, u):
    """BSDF samples at points pts (K,) (repeats allowed) of a closure built for N points."""
    if hasattr(bsdf, "sample_at"):  # sampled at any rows directly
        return bsdf.sample_at(pts, u[:, :2])
    n = bsdf.n if hasattr(bsdf, "n") else len(bsdf.ns)
    # Sample all repeats by sampling the closure once per repeat round: rows of the same point
    # within one round are distinct, so each round is one call over unique points.
    order = np.argsort(pts, kind="stable")
    rank = np.empty(len(pts), np.int64)
    first = np.searchsorted(pts[order], pts[order])
    rank[order] = np.arange(len(pts)) - first
    K = len(pts)
    wi, weight, pdf = np.zeros((K, 3)), np.zeros((K, 3)), np.zeros(K)
    delta, valid = np.zeros(K, bool), np.zeros(K, bool)
    for r in range(int(rank.max()) + 1 if K else 0):
        sel = np.flatnonzero(rank == r)
        uu = np.zeros((n, 3))
        uu[pts[sel]] = u[sel]
        bs = bsdf.sample(uu[:, :2], uu[:, 2])
        src = pts[sel]
        wi[sel], weight[sel], pdf[sel] = bs.wi[src], bs.weight[src], bs.pdf[src]
        delta[sel], valid[sel] = bs.delta[src], bs.valid[src]
    return BSDFSample(wi=wi, weight=weight, pdf=pdf, delta=delta, valid=valid)


def _full(u, rows, n):
    """u (K,3) for rows (K,) of n points as full (n,2) and (n,) arrays (zeros elsewhere)."""
    uu = np.zeros((n, 3))
    uu[rows] = u
    return uu[:, :2], uu[:, 2]


def _no_photons() -> dict:
    z3 = np.zeros((0, 3), np.float32)
    return {"position": z3, "wi": z3, "normal": z3, "flux": z3, "caustic": np.zeros(0, bool),
            "first": np.zeros(0, bool), "bounces": np.array([0])}
