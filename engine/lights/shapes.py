"""Per-kind geometry of analytic lights: sampling from a shading point, ray hits, power.

Conventions (Scene.Lights): spheres (point/spot of radius r) emit uniformly outward;
with `soft` (Blender's Soft Falloff, its default) a point/spot is instead a disk of radius r
centred on the light and facing the shading point (ray origin), emitting the same radiance
(intern/cycles/kernel/light/point.h, the branch without is_sphere);
rect and disk emit one-sided along the light's -z; the sun's light travels along -z from a
cone of half-angle `sun_half_angle` around +z. Spot cones attenuate with Cycles'
smoothstep((cos - cos_half) / smooth) of the direction from the light to the lit point
(intern/cycles/kernel/light/spot.h). All solid-angle pdfs exclude the selection pmf.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..vec import dot, minus_point, scale, take

from .. import sampling
from ..scene import LIGHT_DISK, LIGHT_POINT, LIGHT_RECT, LIGHT_SPOT, LIGHT_SUN, Lights


@dataclass(frozen=True, slots=True)
class ShapeSample:
    """Points sampled on lights as seen from N shading points p.

    wi (N,3) unit direction from p towards the point; Le (N,3) radiance arriving at p along -wi
    (W/(m^2 sr)), spots' attenuation included; for delta lights the irradiance at normal
    incidence instead (W/m^2: intensity / d^2 for points and spots, Le for a sun of angle 0); pdf (N,) solid-angle pdf of wi (1/sr),
    without the selection pmf: 1 for delta lights, 0 where nothing can be sampled (p inside a
    sphere); target (N,3) the sampled point (m), p + wi 1e30 for suns; finite (N,) bool, False
    for suns (their target stands for infinity).
    """

    wi: np.ndarray
    Le: np.ndarray
    pdf: np.ndarray
    target: np.ndarray
    finite: np.ndarray


@dataclass(frozen=True, slots=True)
class LightHit:
    """N rays tested against one light.

    hit (N,) bool; gain (N,) radiance factor: the radiance is gain x Le of the light (the spot
    attenuation, else 1); pdf (N,) solid-angle pdf (1/sr) with which next-event estimation
    from the ray's origin samples that direction, without the selection pmf; t (N,) the
    distance along the ray to the light where hit (inf for suns; a light's shader reads it).
    """

    hit: np.ndarray
    gain: np.ndarray
    pdf: np.ndarray
    t: np.ndarray = None


def _avg(c):
    return np.asarray(c, np.float64).mean(axis=-1)


def one_minus_cos(half_angle):
    """1 - cos(x) without cancellation."""
    return 2.0 * np.sin(0.5 * np.asarray(half_angle, np.float64)) ** 2


def is_delta(lights: Lights) -> np.ndarray:
    k = lights.kind
    return (((k == LIGHT_POINT) | (k == LIGHT_SPOT)) & (lights.radius <= 0)) | ((k == LIGHT_SUN) & (lights.sun_half_angle <= 0))


def area(lights: Lights) -> np.ndarray:
    hx, hy = lights.size[:, 0], lights.size[:, 1]
    return np.where(lights.kind == LIGHT_RECT, 4.0 * hx * hy, np.where(lights.kind == LIGHT_DISK, np.pi * hx * hy, 0.0))


def analytic_power(lights: Lights, scene_radius: float) -> np.ndarray:
    """Emitted power (W, mean over RGB) used only to choose lights (pbrt-v4 lights.cpp)."""
    k, r, Le = lights.kind, lights.radius, _avg(lights.Le)
    sphere = 4.0 * np.pi * np.where(r > 0, np.pi * r * r * Le, Le)  # 4 pi I, I = pi r^2 L
    cos_end = lights.spot_cos_half
    cos_start = np.minimum(cos_end + lights.spot_smooth, 1.0)
    cone = ((1.0 - cos_start) + 0.5 * (cos_start - cos_end)) / 2.0  # fraction of the sphere lit
    sun_E = np.where(lights.sun_half_angle > 0, Le * np.pi * np.sin(lights.sun_half_angle) ** 2, Le)
    power = np.select(
        [k == LIGHT_POINT, k == LIGHT_SPOT, k == LIGHT_SUN, (k == LIGHT_RECT) | (k == LIGHT_DISK)],
        [sphere, sphere * cone, sun_E * np.pi * scene_radius**2, np.pi * area(lights) * Le], 0.0)
    return power


def spot_attenuation(lights: Lights, i, w_from_light):
    """Cycles' spot cone factor for directions from the light (N,3); i (N,) or scalar."""
    axis = -lights.frame[i, 2]
    cos = dot(w_from_light, np.broadcast_to(axis, w_from_light.shape))
    cos_half = np.broadcast_to(lights.spot_cos_half[i], cos.shape)
    smooth = np.broadcast_to(lights.spot_smooth[i], cos.shape)
    x = np.divide(cos - cos_half, smooth, out=np.where(cos > cos_half, 1.0, 0.0), where=smooth > 0)
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def area_to_solid_angle(p, y, n_light, area_light, two_sided):
    """(wi, pdf): unit directions p -> y (N,3) and the solid-angle pdf (N,) (1/sr) of points y
    drawn uniformly over a light of area area_light (m^2) with normals n_light (N,3); 0 where
    y is seen edge-on or from behind a one-sided light."""
    v = y - p
    d2 = dot(v, v)
    d = np.sqrt(d2)
    wi = scale(v, np.divide(1.0, d, out=np.zeros_like(d), where=d > 0))
    cos_l = -dot(wi, n_light)
    if two_sided:
        cos_l = np.abs(cos_l)
    denom = area_light * cos_l
    pdf = np.divide(d2, denom, out=np.zeros_like(d2), where=denom > 0)
    return wi, np.where(np.isfinite(pdf), pdf, 0.0)


def sample_analytic(kind, lights: Lights, idx, p, u) -> ShapeSample:
    """Sample lights idx (N,) (all of `kind`) from points p (N,3) with uniforms u (N,2)."""
    n = len(p)
    c = take(lights.position, idx)
    frame = take(lights.frame, idx)
    finite = np.ones(n, bool)
    if kind in (LIGHT_POINT, LIGHT_SPOT):
        r = lights.radius[idx]
        v = c - p
        d2 = dot(v, v)
        dist = np.sqrt(d2)
        to_c = scale(v, 1.0 / np.maximum(dist, 1e-300))
        t_axis, b_axis = sampling.frame_from_z(to_c)
        soft = lights.soft[idx] & (r > 0)

        def disk(rows):  # soft: uniform by area on the disk through c facing p; (wi, pdf, point)
            xy = sampling.sample_concentric_disk(u[rows])
            rr = r[rows]
            y = c[rows] + scale(t_axis[rows], xy[:, 0] * rr) + scale(b_axis[rows], xy[:, 1] * rr)
            wi, pdf = area_to_solid_angle(p[rows], y, -to_c[rows], np.pi * rr * rr, two_sided=False)
            return wi, pdf, y

        if soft.all():
            wi, pdf_dir, target = disk(slice(None))
        else:  # spheres (and delta points): uniform in the subtended cone, to the near side
            sin2 = np.minimum(np.divide(r * r, d2, out=np.ones_like(d2), where=d2 > 0), 1.0)
            local, omc_max = sampling.sample_sphere_cone(u, sin2)
            wi = np.where((r > 0)[:, None], sampling.to_world(local, t_axis, b_axis, to_c), to_c)
            cos_t = local[:, 2]
            t_hit = dist * cos_t - np.sqrt(np.maximum(r * r - d2 * (1.0 - cos_t * cos_t), 0.0))
            target = p + scale(wi, np.where(r > 0, t_hit, dist))
            pdf_dir = np.where(r > 0, np.divide(1.0, 2.0 * np.pi * omc_max, out=np.zeros(n), where=omc_max > 0), 1.0)
            pdf_dir = np.where(d2 <= r * r, 0.0, pdf_dir)  # inside the sphere: nothing to sample
            if soft.any():
                rows = np.flatnonzero(soft)
                wi[rows], pdf_dir[rows], target[rows] = disk(rows)
        Le = scale(take(lights.Le, idx), np.where(r > 0, 1.0, 1.0 / np.maximum(d2, 1e-300)))
        if kind == LIGHT_SPOT:
            Le = scale(Le, spot_attenuation(lights, idx, -wi))
        return ShapeSample(wi, Le, pdf_dir, target, finite)
    if kind == LIGHT_SUN:
        z = frame[:, 2]
        half = lights.sun_half_angle[idx]
        local, omc_max = sampling.sample_sphere_cone(u, np.sin(np.minimum(half, np.pi / 2)) ** 2)
        t_axis, b_axis = sampling.frame_from_z(z)
        wi = np.where((half > 0)[:, None], sampling.to_world(local, t_axis, b_axis, z), z)
        pdf_dir = np.where(half > 0, np.divide(1.0, 2.0 * np.pi * omc_max, out=np.zeros(n), where=omc_max > 0), 1.0)
        finite[:] = False
        return ShapeSample(wi, lights.Le[idx].copy(), pdf_dir, p + wi * 1e30, finite)
    # Rect and disk: uniform by area, one-sided along -z.
    hx, hy = lights.size[idx, 0], lights.size[idx, 1]
    if kind == LIGHT_RECT:
        xy = sampling.sample_uniform_rectangle(u, hx, hy)
    else:
        xy = sampling.sample_concentric_disk(u) * np.stack([hx, hy], axis=1)
    y = c + xy[:, :1] * frame[:, 0] + xy[:, 1:2] * frame[:, 1]
    a = np.where(kind == LIGHT_RECT, 4.0 * hx * hy, np.pi * hx * hy)
    wi, pdf_dir = area_to_solid_angle(p, y, -frame[:, 2], a, two_sided=False)
    return ShapeSample(wi, lights.Le[idx].copy(), pdf_dir, y, finite)


def hit_analytic(kind, lights: Lights, i: int, o, d, tmax) -> LightHit:
    """Rays o + t d (o, d (N,3), d unit) against analytic light i (of `kind`), 0 < t < tmax (N,)."""
    n = len(o)
    c = lights.position[i]
    frame = lights.frame[i]
    f = minus_point(o, c)  # light centre -> origin
    gain = np.ones(n)
    if kind in (LIGHT_POINT, LIGHT_SPOT):
        r = lights.radius[i]
        f2 = dot(f, f)
        if lights.soft[i]:  # disk through c facing o
            dist = np.sqrt(f2)
            cos_l = -dot(d, f) / np.maximum(dist, 1e-300)
            t = np.divide(dist, cos_l, out=np.full(n, -1.0), where=cos_l > 0)
            # |f + t d|^2 = f2 + 2 t f.d + t^2 (d unit) without forming the point
            q2 = f2 - 2.0 * t * cos_l * dist + t * t
            hit = (cos_l > 0) & (q2 <= r * r) & (t > 0) & (t < tmax)
            pdf_dir = np.divide(t * t, np.pi * r * r * cos_l, out=np.zeros(n), where=hit)
        else:
            b = dot(f, d)
            disc = r * r - (f2 - b * b)  # r^2 - |perpendicular part of f|^2
            t = -b - np.sqrt(np.maximum(disc, 0.0))
            hit = (f2 > r * r) & (disc >= 0) & (t > 0) & (t < tmax)
            sin2 = np.minimum(r * r / np.maximum(f2, 1e-300), 1.0)
            omc = sin2 / (1.0 + np.sqrt(1.0 - sin2))
            pdf_dir = np.divide(1.0, 2.0 * np.pi * omc, out=np.zeros(n), where=omc > 0)
        if kind == LIGHT_SPOT:
            gain = spot_attenuation(lights, i, -d)  # from the light towards o
        return LightHit(hit, gain, pdf_dir, t)
    z = frame[2]
    dz = d @ z
    t = np.divide(-(f @ z), dz, out=np.full(n, -1.0), where=dz != 0)
    q = f + scale(d, t)
    x, y = q @ frame[0], q @ frame[1]
    hx, hy = lights.size[i]
    if kind == LIGHT_RECT:
        inside = (np.abs(x) <= hx) & (np.abs(y) <= hy)
        a = 4.0 * hx * hy
    else:
        inside = (x / max(hx, 1e-300)) ** 2 + (y / max(hy, 1e-300)) ** 2 <= 1.0
        a = np.pi * hx * hy
    # The emitting face looks along -z: a ray meets it travelling towards +z.
    hit = inside & (dz > 0) & (t > 0) & (t < tmax)
    pdf_dir = np.divide(t * t, a * dz, out=np.zeros(n), where=(dz > 0) & (a > 0))
    return LightHit(hit, gain, pdf_dir, t)


def sun_hit(lights: Lights, i: int, d) -> LightHit:
    """Escaped directions d (N,3) against sun i's cone (gain 1; a sun of angle 0 is never hit)."""
    half = lights.sun_half_angle[i]
    n = len(d)
    if half <= 0:
        return LightHit(np.zeros(n, bool), np.ones(n), np.zeros(n), np.full(n, np.inf))
    omc = one_minus_cos(half)
    # 1 - cos(angle to the axis) compared without cancellation via the chord length.
    chord2 = dot(d - lights.frame[i, 2], d - lights.frame[i, 2])
    hit = 0.5 * chord2 <= omc
    return LightHit(hit, np.ones(n), np.full(n, 1.0 / (2.0 * np.pi * omc)), np.full(n, np.inf))
