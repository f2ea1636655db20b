"""Scene analysis: what a scene needs, measured cheaply before rendering.

From the Scene arrays and short pilots through the same Embree scene, light set, path tracer
and photon tracer the integrators use:

- lights: every emitter by kind and size relative to the scene's bounding radius R: "delta"
  (points and spots of radius 0, suns of angle 0), "tiny" (size < TINY R), "small", "large"
  (size > LARGE R), "distant" (suns with an angle) and the world ("environment" for an image,
  "constant" for a uniform colour); size is the diameter of a sphere light, the square root
  of an area light's area, and of the total area of an emissive material's triangles (one
  material = one emitter object: many small lights of one material count as one large one).
  Power shares by class from the LightSet's selection powers.
- materials by surface area, each material's area split over its lobes by their albedo:
  diffuse (Lambert, Phong's kd), glossy (Phong's ks, microfacet and rough glass of roughness
  >= the photon tracer's MIN_STORE_ROUGHNESS), specular (sharper microfacet and glass: what
  caustic paths pass through), transparent (straight pass-through); emitters apart.
- enclosure: the share of probe rays that escape, cosine-distributed about the normals at the
  camera's first hits (camera rays that miss are counted apart).
- indirect / direct: at the camera's first diffuse hits, the path tracer's radiance with one
  bounce (direct light: NEE and BSDF hits, MIS) and with up to PILOT_DEPTH bounces; their
  difference is the indirect light (what path tracing finds: caustics of delta lights are
  counted by the caustic pilot, not here). Its noise: the second moment of one path's
  indirect light over the squared mean radiance, E[I^2] / E[L]^2, the relative variance the
  indirect light adds to a path-traced sample (a light next to a wall: a hot spot that few
  bounce rays find, 45; the Cornell box, 1.2).
- caustics (L S+ D): possible when specular surfaces and lights exist; a pilot of photons
  (the photon map's own tracer) measures the share of the flux arriving at diffuse surfaces
  that came through specular bounces only.
- sizes: triangles, surface area, texture images and texels, environment texels, and a
  pixel's width at the camera's first hits (median; what search radii compare with).

Nothing here chooses an integrator: `auto` reads the figures. Every pilot is seeded (the
figures are reproducible) and skipped when it cannot find anything (no geometry, no light,
no specular surface), which the summary says.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .. import camera as camera_mod
from .. import rng, sampling
from ..accel import Accel, offset_origin
from ..bsdf import lobes
from ..integrators.base import TraceContext
from ..integrators.path import PathTracer
from ..integrators.path_options import Gather
from ..integrators.path_state import PathState
from ..integrators.photon.tracing import MIN_STORE_ROUGHNESS, PhotonTracer
from ..lights import shapes
from ..lights.emission import PhotonEmitter
from ..lights.light_set import LightSet
from ..scene import LIGHT_DISK, LIGHT_POINT, LIGHT_RECT, LIGHT_SPOT, LIGHT_SUN, Scene
from ..vec import dot, max3, scale, take

TINY, LARGE = 0.02, 0.25  # light size classes, relative to the scene's bounding radius
ENCLOSED = 0.05  # escape share below which a scene counts as enclosed
PILOT_DEPTH = 6  # bounces of the indirect-light pilot
LIGHT_CLASSES = ("delta", "tiny", "small", "large", "distant", "environment", "constant")
_KIND_NAMES = {LIGHT_POINT: "point", LIGHT_SPOT: "spot", LIGHT_SUN: "sun", LIGHT_RECT: "rect", LIGHT_DISK: "disk"}


@dataclass(frozen=True)
class SceneAnalysis:
    """Figures of one scene (see the module docstring); shares in [0, 1], NaN where a pilot
    did not run (its reason in `skipped`)."""

    n_triangles: int
    scene_radius: float  # m
    surface_area: float  # m^2
    n_images: int
    texture_texels: int
    environment_texels: int
    n_analytic_lights: int
    n_emissive_triangles: int
    light_kinds: tuple  # sorted names: point, spot, sun, rect, disk, emissive, environment, constant
    light_counts: tuple  # ((class, emitters), ...) over LIGHT_CLASSES, classes present only
    light_power: tuple  # ((class, share of the selection power), ...)
    diffuse_share: float  # of the non-emitting surface area, weighted by lobe albedo
    glossy_share: float
    specular_share: float
    transparent_share: float
    caustics_possible: bool  # specular surfaces and a light
    caustic_share: float  # pilot: flux at diffuse surfaces that came via specular bounces only
    camera_escape_share: float  # camera rays that hit nothing
    pixel_footprint: float  # m: median width of a pixel at the camera's first hits
    escape_share: float  # probe rays from the first hits that hit nothing
    indirect_ratio: float  # indirect / direct radiance at the first diffuse hits
    indirect_noise: float  # E[I^2] / E[L]^2 of one path sample there (I indirect, L all light)
    pilot_rays: int  # every ray the pilots traced (camera, probes, paths, shadows, photons)
    pilot_photons: int
    seconds: float
    skipped: tuple  # (reason, ...) for pilots not run
    summary: str

    @property
    def has_light(self) -> bool:
        return bool(self.light_counts)

    @property
    def enclosed(self) -> bool:
        return bool(self.escape_share < ENCLOSED)

    def count(self, light_class: str) -> int:
        return dict(self.light_counts).get(light_class, 0)


# ----------------------------------------------------------------------------------------------
# Lights

def _size_class(rel_size):
    return np.where(rel_size < TINY, "tiny", np.where(rel_size > LARGE, "large", "small"))


def _light_classes(scene: Scene, lights: LightSet, R: float):
    """(class (C,) str per emitter in LightSet order, counts {class: emitters}, kind names
    present); emissive triangles count once per material."""
    L = scene.lights
    kinds = set()
    cls = []
    if len(L):
        delta = shapes.is_delta(L)
        area = shapes.area(L)
        size = np.where((L.kind == LIGHT_POINT) | (L.kind == LIGHT_SPOT), 2.0 * L.radius, np.sqrt(area))
        c = np.where(delta, "delta", _size_class(size / R))
        cls += np.where(L.kind == LIGHT_SUN, np.where(delta, "delta", "distant"), c).tolist()
        kinds |= {_KIND_NAMES[int(k)] for k in L.kind}
    counts = {c: cls.count(c) for c in set(cls)}
    if len(lights.tri_prim):
        kinds.add("emissive")
        mat = scene.mesh.material[lights.tri_prim]
        total = np.bincount(mat, weights=lights.tri_area, minlength=len(scene.materials.kind))
        tri_cls = _size_class(np.sqrt(total[mat]) / R)
        cls += tri_cls.tolist()
        for c in set(tri_cls.tolist()):
            counts[c] = counts.get(c, 0) + len(np.unique(mat[tri_cls == c]))
    if lights.env is not None:
        kinds.add("environment")
        cls.append("environment")
        counts["environment"] = 1
    return np.array(cls, dtype=object), counts, kinds


# ----------------------------------------------------------------------------------------------
# Materials

def _lobe_albedo(m) -> np.ndarray:
    """(K, 4) mean albedo of each lobe by class (lobes.ANALYSIS_CLASSES: diffuse, glossy,
    specular, transparent; textured colours: the image's mean texel), as each lobe counts it."""
    color = m.lobe_color.copy()
    tex = np.flatnonzero(m.lobe_color_tex >= 0)
    for k in tex.tolist():
        img = int(m.tex_image[m.lobe_color_tex[k]])
        w, h = m.image_size[img]
        o = int(m.image_offset[img])
        color[k] = m.image_texels[o:o + w * h, :3].mean(axis=0)
    return lobes.analysis_albedo(m, color, MIN_STORE_ROUGHNESS)


def _material_shares(scene: Scene, tri_area: np.ndarray):
    """Area shares (diffuse, glossy, specular, transparent) of the non-emitting surface."""
    m = scene.materials
    albedo = _lobe_albedo(m)
    n_mat = len(m.kind)
    per = {name: np.bincount(m.lobe_material, weights=albedo[:, j], minlength=n_mat)
           for j, name in enumerate(lobes.ANALYSIS_CLASSES)}
    total = sum(per.values())
    area = np.bincount(scene.mesh.material, weights=tri_area, minlength=n_mat) if len(tri_area) else np.zeros(n_mat)
    emits = np.any(m.emission != 0, axis=1)
    weight = np.where(emits | (total <= 0), 0.0, area)  # black and emitting surfaces apart
    if weight.sum() <= 0:
        return {name: 0.0 for name in per}
    return {name: float(np.sum(weight * np.divide(v, total, out=np.zeros(n_mat), where=total > 0)) / weight.sum())
            for name, v in per.items()}


# ----------------------------------------------------------------------------------------------
# Pilots

def _camera_rays(scene: Scene, n: int, seed: int):
    """About n camera rays on a regular pixel grid (jittered by the pixel filter)."""
    s = scene.settings
    side = max(1, int(np.sqrt(n)))
    xs = np.minimum((np.arange(side) + 0.5) * s.width / side, s.width - 1).astype(np.int64)
    ys = np.minimum((np.arange(side) + 0.5) * s.height / side, s.height - 1).astype(np.int64)
    py, px = (a.ravel() for a in np.meshgrid(ys, xs, indexing="ij"))
    sampler = rng.Sampler(seed, py * s.width + px, np.zeros(len(px), np.int64), "random", domain=rng.RECORDS)
    o, d, tmax = camera_mod.generate_rays(scene.camera, s, px, py, sampler.get(0, None, 2))
    return sampler, o, d, tmax


def _footprint(scene, hit) -> float:
    """Median width (m) of a pixel where camera rays first hit (perspective and panoramic:
    distance x the pixel's angle; orthographic: the window's width over the pixels)."""
    pixel = camera_mod.pixel_angle(scene.camera, scene.settings)
    t = hit.t[hit.prim >= 0]
    if len(t) == 0:
        return float("nan")
    return float(pixel if scene.camera.ortho else np.median(t) * pixel)


def _escape_pilot(scene, accel, hit, d, seed, probes=4):
    """Share of cosine-distributed probe rays from the first hits that escape."""
    rows = np.flatnonzero(hit.prim >= 0)
    if len(rows) == 0:
        return float("nan")
    rows = np.repeat(rows, probes)
    ng = take(hit.ng, rows)
    ng = scale(ng, np.where(dot(ng, take(d, rows)) > 0, -1.0, 1.0))  # the side the camera sees
    u = rng.Sampler(seed + 1, rows, np.arange(len(rows)), "random", domain=rng.RECORDS).get(0, None, 2)
    t, b = sampling.frame_from_z(ng)
    w = sampling.to_world(sampling.sample_cosine_hemisphere(u), t, b, ng)
    probe = accel.intersect(offset_origin(take(hit.p, rows), ng), w, None, hit.prim[rows])
    return float(np.mean(probe.prim < 0))


def _indirect_pilot(scene, accel, lights, sampler, o, d, tmax, diffuse_first):
    """(indirect / direct, E[I^2] / E[L]^2): radiance (mean RGB) over rays whose first hit is
    diffuse, I its indirect part and L all of it."""
    tracer = PathTracer(scene, accel, lights)
    o32 = o.astype(np.float32)
    skip = np.full(len(d), -1, np.int64)
    direct = tracer.trace(sampler, PathState.rays(o, o32, d, tmax, skip), Gather(first_emission=False, max_depth=1))
    total = tracer.trace(sampler, PathState.rays(o, o32, d, tmax, skip),
                         Gather(first_emission=False, max_depth=PILOT_DEPTH))
    indirect = (total - direct)[diffuse_first].mean(axis=1)
    direct, total = direct[diffuse_first].mean(axis=1), total[diffuse_first].mean(axis=1)
    d_sum, i_sum, mean = float(direct.sum()), float(indirect.sum()), float(total.mean())
    ratio = i_sum / d_sum if d_sum > 0 else (float("inf") if i_sum > 0 else float("nan"))
    return ratio, float(np.mean(indirect ** 2) / mean ** 2) if mean > 0 else float("nan")


def _caustic_pilot(scene, accel, lights, n, seed):
    """Share of the photon flux stored on diffuse surfaces that arrived through specular
    bounces only (L S+ D), from n photon paths."""
    v = scene.mesh.vertices
    center = (0.5 * (v.min(axis=0) + v.max(axis=0))).astype(np.float64)
    emitter = PhotonEmitter(lights, center, accel.scene_radius)
    if emitter.empty:
        return float("nan")
    tracer = PhotonTracer(TraceContext(scene, accel, lights, None), emitter, PILOT_DEPTH)
    sampler = rng.Sampler(seed, np.full(n, 3), np.arange(n), "random", domain=rng.PHOTONS)
    photons = tracer.trace(sampler, caustic_only=False)
    flux = max3(photons["flux"].astype(np.float64)) if len(photons["flux"]) else np.zeros(0)
    return float(flux[photons["caustic"]].sum() / flux.sum()) if flux.sum() > 0 else 0.0


# ----------------------------------------------------------------------------------------------

def analyse(scene: Scene, pilot_rays: int = 4096, pilot_photons: int = 16384, seed: int = 0) -> SceneAnalysis:
    """The figures of `scene` (module docstring) from pilots of about pilot_rays camera rays
    (4 escape probes each) and pilot_photons photon paths."""
    t0 = time.perf_counter()
    mesh, m = scene.mesh, scene.materials
    accel = Accel(mesh)
    R = accel.scene_radius
    lights = LightSet(scene.lights, mesh, m, scene.world, accel, R, scene.settings.strategy)
    cls, per_class, kinds = _light_classes(scene, lights, R)
    if lights.env is None and bool(np.abs(lights.world).max() > 0):
        kinds.add("constant")
        per_class["constant"] = 1
    power = lights.power if lights.count else np.zeros(0)
    counts = tuple((c, per_class[c]) for c in LIGHT_CLASSES if per_class.get(c, 0))
    total_power = power.sum()
    light_power = tuple((c, float(power[cls == c].sum() / total_power)) for c, _ in counts
                        if c != "constant" and total_power > 0)
    shares = _material_shares(scene, accel.area if mesh.n_triangles else np.zeros(0))
    has_light = bool(counts)
    caustics_possible = shares["specular"] > 0 and has_light
    skipped = []
    nan = float("nan")
    camera_escape = escape = indirect = noise = caustic = footprint = nan
    n_rays = n_photons = 0
    if mesh.n_triangles == 0:
        skipped.append("no pilots: the scene has no geometry")
    else:
        sampler, o, d, tmax = _camera_rays(scene, pilot_rays, seed)
        hit = accel.intersect(o.astype(np.float32), d, tmax, None)
        camera_escape = float(np.mean(hit.prim < 0))
        footprint = _footprint(scene, hit)
        escape = _escape_pilot(scene, accel, hit, d, seed)
        if not has_light:
            skipped.append("no indirect-light pilot: the scene has no light")
        elif not np.any(hit.prim >= 0):
            skipped.append("no indirect-light pilot: the camera sees no surface")
        else:
            mat = mesh.material[np.maximum(hit.prim, 0)]
            diffuse_mat = _material_shares_per_material(scene) >= 0.5
            first_diffuse = (hit.prim >= 0) & diffuse_mat[mat]
            if first_diffuse.any():
                indirect, noise = _indirect_pilot(scene, accel, lights, sampler, o, d, tmax, first_diffuse)
            else:
                skipped.append("no indirect-light pilot: the camera sees no diffuse surface")
        if not caustics_possible:
            skipped.append("no caustic pilot: " + ("no light" if not has_light else "no specular surface"))
        else:
            caustic = _caustic_pilot(scene, accel, lights, pilot_photons, seed)
            n_photons = pilot_photons
        n_rays = accel.rays
    figures = dict(
        n_triangles=int(mesh.n_triangles), scene_radius=float(R),
        surface_area=float(accel.area.sum()) if mesh.n_triangles else 0.0,
        n_images=int(len(m.image_size)), texture_texels=int(np.prod(m.image_size, axis=1).sum()) if len(m.image_size) else 0,
        environment_texels=int(np.prod(scene.world.image.shape[:2])) if scene.world.image is not None else 0,
        n_analytic_lights=int(len(scene.lights)), n_emissive_triangles=int(len(lights.tri_prim)),
        light_kinds=tuple(sorted(kinds)), light_counts=counts, light_power=light_power,
        diffuse_share=shares["diffuse"], glossy_share=shares["glossy"], specular_share=shares["specular"],
        transparent_share=shares["transparent"], caustics_possible=bool(caustics_possible), caustic_share=caustic,
        camera_escape_share=camera_escape, pixel_footprint=footprint, escape_share=escape, indirect_ratio=indirect,
        indirect_noise=noise,
        pilot_rays=n_rays, pilot_photons=n_photons, skipped=tuple(skipped))
    figures["seconds"] = time.perf_counter() - t0
    return SceneAnalysis(summary=_summary(figures), **figures)


def _material_shares_per_material(scene: Scene) -> np.ndarray:
    """(M,) the diffuse share of each material's lobe albedo (Phong: kd over kd + ks)."""
    m = scene.materials
    albedo = _lobe_albedo(m)
    n_mat = len(m.kind)
    diffuse = np.bincount(m.lobe_material, weights=albedo[:, 0], minlength=n_mat)
    total = np.bincount(m.lobe_material, weights=albedo.sum(axis=1), minlength=n_mat)
    return np.divide(diffuse, total, out=np.zeros(n_mat), where=total > 0)


def _pct(x):
    return "n/a" if not np.isfinite(x) else f"{100 * x:.0f} %"


def _summary(f: dict) -> str:
    """A few lines for the stats and the CLI."""
    lights = ", ".join(f"{k} {c}" for c, k in f["light_counts"]) or "none"
    power = ", ".join(f"{c} {_pct(p)}" for c, p in f["light_power"] if p > 0)
    lines = [f"lights: {lights}" + (f" (power: {power})" if power else "") + f"; kinds: {', '.join(f['light_kinds']) or 'none'}",
             f"materials by area: diffuse {_pct(f['diffuse_share'])}, glossy {_pct(f['glossy_share'])}, "
             f"specular {_pct(f['specular_share'])}, transparent {_pct(f['transparent_share'])}"]
    if f["caustics_possible"]:
        lines.append(f"caustics possible (L S+ D): {_pct(f['caustic_share'])} of the light at diffuse surfaces "
                     "comes through specular surfaces")
    else:
        lines.append("no caustics: " + ("no light" if not f["light_counts"] else "no specular surface"))
    if np.isfinite(f["escape_share"]):
        enclosure = "enclosed" if f["escape_share"] < ENCLOSED else "open"
        lines.append(f"{enclosure}: {_pct(f['escape_share'])} of probe rays escape "
                     f"({_pct(f['camera_escape_share'])} of camera rays see the background)")
    if np.isfinite(f["indirect_ratio"]):
        lines.append(f"indirect / direct light at the first diffuse hits: {f['indirect_ratio']:.2f}; "
                     f"its noise in a path sample, E[I^2] / E[L]^2: {f['indirect_noise']:.2f}")
    lines.append(f"geometry: {f['n_triangles']} triangles, radius {f['scene_radius']:.3g} m, a pixel {f['pixel_footprint']:.2g} m "
                 f"wide at the first hits; textures: {f['n_images']} images, {f['texture_texels']} texels; "
                 f"environment {f['environment_texels']} texels")
    lines += list(f["skipped"])
    lines.append(f"analysis: {f['pilot_rays']} pilot rays, {f['pilot_photons']} photons, {f['seconds']:.2f} s")
    return "\n".join(lines)
