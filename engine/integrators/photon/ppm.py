"""Stochastic progressive photon mapping (Hachisuka & Jensen 2009), as pbrt-v4's SPPM.

Every pass is one round of two stages:
  photons  a new batch of `photons` photon paths (its own stream per pass), reduced into one
           map of the photons that have bounced at least once (direct light, the first hit
           from a light, is next-event estimation's) and published;
  pixels   one camera sample per pixel (film): the path follows specular surfaces to its
           first diffuse point x, adds emission seen on the way and direct light by light
           sampling (to the film, averaged over passes like the path tracer), and gathers the
           pass's photons within the pixel's radius r: Phi = sum beta f flux, M = count.
After each pass the render process updates every pixel (pbrt-v4 integrators.cpp, SPPM):

    N' = N + alpha M,  r' = r sqrt(N' / (N + M)),  tau' = (tau + Phi) r'^2 / r^2,

and the photon term tau / (N_emitted pi r^2), N_emitted = passes x photons, is added to the
film's mean as its overlay. The radii shrink, so the bias vanishes as passes grow: the
estimate is consistent, not merely converging to a blurred answer. Photons from the wrong
side or with f = 0 are not counted in M (they would shrink the radius for nothing).

The film's noise estimate covers only the averaged part (it assumes independent passes), so
a noise target does not apply; the stats give the mean radius relative to the first.
"""
from __future__ import annotations

import numpy as np

from ... import rng
from ...vec import gatherer
from ..base import Stage
from .integrator import _GROUPS, _LIGHT, PHOTON_BATCH, PHOTON_BYTES, PhotonIntegrator, _accumulate, _no_photons
from .photon_map import PhotonMap
from ...layout import BatchLayout

PPM_RADIUS = 0.01  # x scene radius: the first pass's radius when the setting is 0


class ProgressivePhotonIntegrator(PhotonIntegrator):
    name = "ppm"
    own_passes = ()  # its photon term is one film overlay, caustics not apart
    label = "Progressive Photon Mapping"
    description = "Stochastic progressive photon mapping: photon radii shrink every pass (consistent)"

    noise_target = False  # the film's noise estimate sees only the part averaged over passes
    sample_offset = False  # pass r shrinks the radii of passes < r: no pass stands alone
    adaptive = False  # every pixel's radius shrinks with every pass: each pass covers all pixels

    def __init__(self, scene):
        super().__init__(scene)
        self.layout = BatchLayout(scene)  # one BSDF ray per camera path: the usual batches
        s = scene.settings
        self.n_caustic_items = 0
        self.n_global_items = -(-s.photons // PHOTON_BATCH)
        n = self.layout.n_pixels
        self.r0 = s.ppm_radius or PPM_RADIUS * self.radius
        self.radius_px = np.full(n, self.r0)  # render process: per border pixel
        self.N = np.zeros(n)
        self.tau = np.zeros((n, 3))
        self.passes_done = 0

    # --- render process -------------------------------------------------------------------
    @classmethod
    def memory_estimate(cls, scene) -> int:
        """One pass's map (no caustic map), as PhotonIntegrator.memory_estimate."""
        return 2 * PHOTON_BYTES * 3 * scene.settings.photons

    def work_items(self) -> int:
        return self.scene.settings.samples * (self.n_global_items + -(-self.layout.n_pixels // self.layout.batch_size))

    def stages(self, round: int):
        if round >= self.scene.settings.samples:
            return []
        n = self.layout.n_pixels
        film = self.pixel_stage(round * n, (round + 1) * n)
        # The photon stage carries its pass in `start` (each pass has its own photon stream).
        return [Stage("photons", self.n_global_items, publish=True, start=round, stop=round),
                Stage("pixels", film.items, film=True, publish=True, start=film.start, stop=film.stop)]

    def reduce(self, stage, results):
        s = self.scene.settings
        if stage.name == "photons":
            keep = [{k: r[k][~r["first"]] for k in ("position", "wi", "flux", "normal")} for r in results]
            cat = lambda key: np.concatenate([r[key] for r in keep])  # noqa: E731
            packed = PhotonMap.pack(cat("position"), cat("wi"), cat("flux"), cat("normal"))
            self._counters["photons"] = f"{len(packed['position']) / 1e3:.0f}k photons stored in the last pass"
            if self.passes_done == 0:
                return {**{f"ppm.{k}": v for k, v in packed.items()},
                        "ppm.radius": self.radius_px.astype(np.float32)}
            return {f"ppm.{k}": v for k, v in packed.items()}
        phi = np.concatenate([r["phi"] for r in results])
        M = np.concatenate([r["count"] for r in results]).astype(np.float64)
        alpha = s.ppm_alpha
        N_new = self.N + alpha * M
        shrink = np.sqrt(np.divide(N_new, self.N + M, out=np.ones_like(N_new), where=(self.N + M) > 0))
        self.tau = (self.tau + phi) * (shrink * shrink)[:, None]
        self.radius_px = self.radius_px * shrink
        self.N = N_new
        self.passes_done += 1
        self._counters["radius"] = (f"{self.passes_done} passes, {self.passes_done * s.photons / 1e6:.2f} M photons, "
                                    f"mean radius {np.mean(self.radius_px) / self.r0:.3f} of the first")
        return {"ppm.radius": self.radius_px.astype(np.float32)}

    def overlay(self):
        if not self.passes_done:
            return None
        s = self.scene.settings
        n_emitted = self.passes_done * max(s.photons, 1)
        L = self.tau / (n_emitted * np.pi * (self.radius_px ** 2))[:, None]
        out = np.zeros((s.width * s.height, 3))
        out[self.layout.pixel] = L
        return out

    # --- tracing processes ----------------------------------------------------------------
    def install(self, version, arrays):
        if "ppm.position" in arrays:
            split = {k.split(".", 1)[1]: v for k, v in arrays.items() if k.startswith("ppm.") and k != "ppm.radius"}
            self.pass_map = PhotonMap.from_packed(split, max(self.scene.settings.photons, 1))
        if "ppm.radius" in arrays:
            self.radius_published = arrays["ppm.radius"]

    def run(self, stage, item, stop=None):
        s, layout = self.scene.settings, self.layout
        if stage.name == "photons":
            first = item * PHOTON_BATCH
            paths = np.arange(first, min(first + PHOTON_BATCH, s.photons))
            if self.emitter.empty or len(paths) == 0:
                return _no_photons()
            # Each pass its own photon stream (pixel = pass + 2: 0 and 1 are the photon integrator's).
            sampler = rng.Sampler(s.seed, np.full(len(paths), 2 + stage.start), paths, s.pattern, domain=rng.PHOTONS)
            return self.photon_tracer.trace(sampler, False, stop)
        j, sample = layout.locate(stage, item)
        self._radius_path = np.asarray(self.radius_published, np.float64)[j]
        self._phi = np.zeros((len(j), 3))
        self._count = np.zeros(len(j), np.int64)
        sampler = rng.Sampler(s.seed, layout.pixel[j], sample, s.pattern)
        L = self._render(sampler, layout.pixel[j], sample, layout.px[j], layout.py[j], stop)
        return {"L": L, "phi": self._phi, "count": self._count}

    def _shade_diffuse(self, L, sampler, idx, x, beta, p, ng_f, ns, wo, prim, bsdf, sample, pixel, depth, dist):
        """Direct light (a light sample and a BSDF sample, balance heuristic) and the pass's
        photons within the pixel's radius."""
        s = self.scene.settings
        at = gatherer(x, len(idx))
        rows, bx = idx[x], at(beta)
        self._direct_light(L, sampler.get(1 + _GROUPS * depth + _LIGHT, rows, 3), rows, x, bx, at, p, ng_f, ns, prim,
                           bsdf, 1)
        u = rng.Sampler(s.seed, pixel[rows], sample[rows], s.pattern, domain=rng.GATHER)
        _accumulate(L, rows, bx * self._gather(u, x, p, ng_f, prim, bsdf, 1, emission_only=True))
        phi, count = self.pass_map.gather_radius(at(p), at(ng_f), self._radius_path[rows],
                                                 lambda r, wi: bsdf.eval(wi, x[r])[0],
                                                 accept=self.visible(at(p), at(ng_f), self.pass_map))
        self._phi[rows] += bx * phi
        self._count[rows] += count
