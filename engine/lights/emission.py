"""Photon emission: choose an emitter by flux, sample a ray leaving it, give the photon its flux.

For N photon paths: emitter l with probability P(l) proportional to its flux (mean RGB), an
origin o and a direction of travel d from the emitter, and the photon flux

    flux = Le(o, d) |cos| / (P(l) pdf_pos pdf_dir)        (W; delta lights: the analogous ratio)

so that E[flux] = total power of the emitters (W per channel) and the photon estimator
(1 / N_emitted) sum(flux ...) is unbiased (seed 001; Jensen 2001 ch. 5; pbrt-v3 Light::Sample_Le,
pbrt-v4 SPPM). Every kind is sampled proportionally to Le |cos| where that is possible, so the
flux of one photon is the same for all photons of a light (exactly: total_power, for grey
lights whose selection weight equals their flux).

Emitters (the order of LightSet: analytic 0..L-1, emissive triangles L..L+E-1, the environment
map last; plus one extra index after them for a constant world, see below), with the
conventions of `shapes` and `light_set` (Cycles'), so that the photons' irradiance equals what
next-event estimation gives:

  rect, disk/ellipse  origin uniform on the area (pdf_pos 1/A), direction cosine-weighted around
                      the emitting normal -z (pdf_dir cos/pi); one-sided; flux pi A Le.
  emissive triangle   origin uniform (1/A), side chosen with probability 1/2 (two-sided, as NEE),
                      cosine-weighted about that side's normal (pdf_dir |cos| / 2 pi); 2 pi A Le.
  point / spot        direction first: uniform on the sphere (point) or proportional to the spot
                      attenuation (`shapes.spot_attenuation`: Cycles' smoothstep of the cosine
                      to the axis, inverted exactly: flat cap + quartic CDF of the ramp).
                      radius 0: origin the centre (pdf_pos 1), Le is the intensity I (W/sr).
                      radius r, Soft Falloff: origin uniform on the disk of radius r through the
                      centre perpendicular to d (pdf_pos 1/(pi r^2), cos 1): intensity pi r^2 Le
                      in every direction as Cycles' facing disk. (Near the light the two differ:
                      the disk faces each receiver, which no light field can do; a photon sees
                      a sphere's silhouette. Relative difference about (r/dist)^2.)
                      radius r, sphere: the same disk point lifted onto the hemisphere facing d.
                      For a point light this is exactly 'uniform on the sphere, cosine-weighted
                      outward'; pdf_pos = cos(n, d) / (pi r^2) is the area density on the sphere
                      given d. Flux I x att(d) / pdf_dir (constant: I 4 pi, or I 2 pi M for a
                      spot whose attenuation integrates to 2 pi M over the sphere).
  sun                 direction of travel -wi, wi uniform in the sun's cone (or the sun's axis
                      for angle 0), origin uniform on a disk of radius R (the scene's bounding
                      radius) perpendicular to wi, centred R from the scene centre towards the
                      sun (pdf_pos 1/(pi R^2)). One disk per direction rather than one
                      perpendicular to the axis: every direction's beam covers the whole
                      bounding sphere, and each direction carries radiance Le over pi R^2, so
                      the power is pi R^2 Le 2 pi (1 - cos half) (angle 0: pi R^2 E). A receiver
                      still gets Cycles' irradiance (integral of Le cos over the cone, pi sin^2
                      (half) Le when it faces the sun); only the bookkeeping power differs from
                      pi R^2 x that irradiance, by 2 / (1 + cos half) (1.0002 for a 2-degree sun).
  environment map     wi from the importance table (never the MIS-compensated one: that table
                      is zero where the map is below its mean, which only MIS can afford; an
                      uncompensated copy is built then), d = -wi, origin on the disk as the sun
                      (pbrt-v3 InfiniteAreaLight::Sample_Le); flux pi R^2 L(wi) / pdf(wi).
  constant world      LightSet does not sample it (BSDF sampling covers it); photons need it as
                      light all the same: one extra emitter index (lights.count, `world_index`),
                      wi uniform on the sphere, origin on the disk; power 4 pi^2 R^2 L.

Power accuracy: exact in closed form for every kind but the environment, whose power is
pi R^2 EnvironmentMap.power_integral (float32 sums; for a mirror ball its rim pixels' estimated
coverage; for a non-rigid mapping (a Mapping node with non-uniform scale) the integral in env
space, not over world directions). The photons' mean flux is exact in all cases; only the
reported power is approximate there.

Emitters whose mean-RGB flux is <= 0 (black, or negative lights) are never chosen; `emitted`
says which are. Sampling uses u_select for the emitter (its remainder chooses a triangle's
side), u_pos (N,2) for the origin and u_dir (N,2) for the direction.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import sampling
from ..scene import LIGHT_DISK, LIGHT_POINT, LIGHT_RECT, LIGHT_SPOT, LIGHT_SUN
from ..vec import dot, scale, take
from . import shapes
from .light_set import LightSet, avg

# Emitter groups beyond the analytic kinds (LIGHT_POINT .. LIGHT_DISK are 0..4).
TRIANGLE = 5
ENVIRONMENT = 6
WORLD = 7


@dataclass(frozen=True, slots=True)
class PhotonEmission:
    """N photons leaving the emitters.

    o (N,3) float64 origin (m); d (N,3) float64 unit direction of travel; flux (N,3) float64 W
    (0 where not valid); light (N,) int64 emitter index; prim (N,) int64 emissive triangle the
    origin lies on (-1 for other emitters: the tracer skips it on the first ray); valid (N,) bool.
    """

    o: np.ndarray
    d: np.ndarray
    flux: np.ndarray
    light: np.ndarray
    prim: np.ndarray
    valid: np.ndarray


@dataclass(frozen=True, slots=True)
class PhotonRays:
    """N photons of one group of emitters, before the selection pmf.

    o (N,3) origin (m); d (N,3) unit direction of travel; flux (N,3) Le |cos| / (pdf_pos
    pdf_dir) (W; 0 where not valid); prim (N,) int64 emissive triangle of the origin, or None
    for groups that are not triangles.
    """

    o: np.ndarray
    d: np.ndarray
    flux: np.ndarray
    prim: np.ndarray | None = None


@dataclass(frozen=True, slots=True)
class PhotonPdf:
    """Densities of N photons (o, d), without the selection pmf.

    pos (N,): area density of o on the emitting surface (1/m^2; 1 for a delta position); for
    directions-first emitters (point/spot of radius r, sun, environment, world) the density of
    o given d. dir (N,): solid-angle density of d (1/sr; given o for area lights and triangles;
    1 for a delta sun).
    """

    pos: np.ndarray
    dir: np.ndarray


# ----------------------------------------------------------------------------------------------
# Spot cones: directions proportional to Cycles' smoothstep attenuation

def spot_mass(cos_half, smooth):
    """Integral M (shape of cos_half) of the spot attenuation over mu = cos(angle to the axis)
    in [-1, 1]; its integral over the sphere is 2 pi M. The attenuation is 1 on
    [cos_start, 1] and smoothstep(x), x = (mu - cos_half) / smooth, on the ramp below;
    the integral of 3x^2 - 2x^3 from 0 to X is X^3 - X^4 / 2 (X = 1 unless the ramp is clipped
    at mu = 1). Returns (cos_start, x_max, M)."""
    cos_half = np.asarray(cos_half, np.float64)
    smooth = np.asarray(smooth, np.float64)
    cos_start = np.minimum(cos_half + smooth, 1.0)
    x_max = np.divide(cos_start - cos_half, smooth, out=np.zeros(np.shape(smooth)), where=smooth > 0)
    ramp = smooth * x_max**3 * (1.0 - 0.5 * x_max)
    return cos_start, x_max, (1.0 - cos_start) + ramp


def _ramp_inverse(target):
    """x in [0, 1] with x^3 - x^4 / 2 = target (N,), target in [0, 1/2] (the ramp's CDF).

    x^3 (1 - x/2) = target: the fixed point x = cbrt(target / (1 - x/2)) contracts by at most 1/3
    on [0, 1] and starts below the root from x = cbrt(target); three steps of it, then Newton on a
    convex increasing function, converge to rounding (checked against the forward map in tests).
    """
    x = np.cbrt(target)
    for _ in range(3):
        x = np.cbrt(target / (1.0 - 0.5 * x))
    for _ in range(3):
        slope = x * x * (3.0 - 2.0 * x)
        x = x - np.divide(x**3 * (1.0 - 0.5 * x) - target, slope, out=np.zeros_like(x), where=slope > 0)
        x = np.clip(x, 0.0, 1.0)
    return x


def sample_spot_cos(u, cos_half, smooth):
    """mu = cos(angle to the axis) (N,) with density att(mu) / M on [-1, 1], from u (N,).

    cos_half, smooth (N,). The flat cap [cos_start, 1] is chosen with probability
    (1 - cos_start) / M and is uniform in mu; the ramp inverts its CDF (`_ramp_inverse`). mu
    decreases monotonically with u."""
    cos_start, x_max, mass = spot_mass(cos_half, smooth)
    p_flat = np.divide(1.0 - cos_start, mass, out=np.ones_like(mass), where=mass > 0)
    in_flat = u < p_flat
    # flat: 1 - mu uniform on [0, 1 - cos_start]
    v_flat = np.divide(u, p_flat, out=np.zeros_like(u), where=p_flat > 0)
    mu_flat = 1.0 - v_flat * (1.0 - cos_start)
    # ramp: F(x) / F(x_max) = 1 - v with F(x) = x^3 - x^4 / 2 (mu falls as u grows: one monotone
    # map from u to mu, so stratified u stay stratified)
    v_ramp = np.clip(np.divide(u - p_flat, 1.0 - p_flat, out=np.zeros_like(u), where=p_flat < 1.0), 0.0, 1.0)
    x = np.minimum(_ramp_inverse((1.0 - v_ramp) * x_max**3 * (1.0 - 0.5 * x_max)), x_max)
    mu_ramp = cos_half + smooth * x
    return np.where(in_flat, mu_flat, mu_ramp)


def _direction_about(mu, u_phi, axis):
    """Unit directions (N,3) at cos mu to axis (N,3), azimuth 2 pi u_phi."""
    sin_t = np.sqrt(np.maximum(0.0, (1.0 - mu) * (1.0 + mu)))
    phi = 2.0 * np.pi * u_phi
    local = np.empty((len(mu), 3))
    local[:, 0], local[:, 1], local[:, 2] = sin_t * np.cos(phi), sin_t * np.sin(phi), mu
    t, b = sampling.frame_from_z(axis)
    return sampling.to_world(local, t, b, axis)


def _one_or_all(light):
    """light[0] (an int) when every entry is the same emitter, else light (N,): gathers of
    per-emitter rows then broadcast one row instead of copying it N times."""
    first = int(light[0])
    return first if bool(np.all(light == first)) else light


def _affine(base, *terms):
    """base + sum of s * v over terms (s, v), (N,3), column by column (see vec.py);
    base and each v (3,) or (N,3), each s (N,) (at least one s is (N,))."""
    n = max(np.size(s) for s, _ in terms)
    out = np.empty((n, 3))
    for k in range(3):
        col = base[..., k]
        for s, v in terms:
            col = col + s * v[..., k]
        out[:, k] = col
    return out


def _colour(c, s):
    """c * s[:, None] (N,3) for a colour or vector c (3,) or (N,3) and s (N,)."""
    return np.multiply.outer(s, c) if np.ndim(c) == 1 else scale(c, s)


# ----------------------------------------------------------------------------------------------

class PhotonEmitter:
    """Photon emission from every emitter of a LightSet (see the module docstring).

    lights: the scene's LightSet; scene_center (3,), scene_radius R (m): a sphere holding the
    scene, where parallel beams (sun, environment, constant world) start.
    Attributes:
      power (C,3) float64 RGB flux (W) of each emitter, C = count (LightSet's order; C =
          lights.count + 1 when a constant world emits, its index `world_index`, else -1);
          exact, signed (a negative light has negative power and is not emitted).
      emitted (C,) bool: chosen with positive probability (mean-RGB power > 0).
      total_power (3,) sum of power over emitted emitters = E[flux] of one photon.
      empty: nothing emits (the caller shoots no photons).
    """

    def __init__(self, lights: LightSet, scene_center, scene_radius: float):
        self.lights = lights
        self.center = np.asarray(scene_center, np.float64).reshape(3)
        self.radius = float(scene_radius)
        L, n_tri = lights.n_analytic, len(lights.tri_prim)
        an = lights.lights
        R2 = self.radius**2
        # Environment: the uncompensated table (see the module docstring).
        env = lights.env
        if env is not None:
            env = env.uncompensated()
        self.env = env
        group = [an.kind.astype(np.int64), np.full(n_tri, TRIANGLE)]
        power = [self._analytic_power(), 2.0 * np.pi * lights.tri_area[:, None] * lights.tri_Le]
        if env is not None:
            group.append(np.array([ENVIRONMENT]))
            power.append(np.pi * R2 * env.power_integral[None, :])
        self.world_index = -1
        if env is None and avg(lights.world) > 0:
            self.world_L = np.asarray(lights.world, np.float64).reshape(3)
            self.world_index = L + n_tri
            group.append(np.array([WORLD]))
            power.append(4.0 * np.pi**2 * R2 * self.world_L[None, :])
        self.group = np.concatenate(group)
        self.power = np.concatenate(power, axis=0).reshape(-1, 3)
        self.count = len(self.power)
        weight = avg(self.power)
        self.emitted = weight > 0
        self.total_power = self.power[self.emitted].sum(axis=0) if self.emitted.any() else np.zeros(3)
        self.empty = not self.emitted.any()
        self.select = None if self.empty else sampling.Distribution1D(np.where(self.emitted, weight, 0.0))
        self.groups_present = sorted(set(self.group[self.emitted].tolist()))

    def _analytic_power(self):
        """(L,3) exact RGB flux of the analytic lights (W)."""
        an = self.lights.lights
        k, r = an.kind, an.radius
        _, _, mass = spot_mass(an.spot_cos_half, an.spot_smooth)
        half = np.minimum(an.sun_half_angle, 0.5 * np.pi)  # NEE's cone stops at the hemisphere too
        sun = np.pi * self.radius**2 * np.where(half > 0, 2.0 * np.pi * shapes.one_minus_cos(half), 1.0)
        factor = np.select([k == LIGHT_POINT, k == LIGHT_SPOT, k == LIGHT_SUN, (k == LIGHT_RECT) | (k == LIGHT_DISK)],
                           [4.0 * np.pi, 2.0 * np.pi * mass, sun, np.pi * shapes.area(an)], 0.0)
        # point/spot of radius r: Le is a radiance, the intensity pi r^2 Le (projected area pi r^2)
        to_intensity = np.where(((k == LIGHT_POINT) | (k == LIGHT_SPOT)) & (r > 0), np.pi * r * r, 1.0)
        return an.Le * (to_intensity * factor)[:, None]

    def pmf(self, light):
        """Selection probability (N,) of emitters `light` (N,) int."""
        if self.empty:
            return np.zeros(len(light))
        return self.select.pmf(light)

    # ---- sampling ----------------------------------------------------------------------------
    def sample(self, u_select, u_pos, u_dir) -> PhotonEmission:
        """N photons from u_select (N,), u_pos (N,2), u_dir (N,2), all in [0, 1)."""
        u_select = np.asarray(u_select, np.float64)
        u_pos = np.asarray(u_pos, np.float64)
        u_dir = np.asarray(u_dir, np.float64)
        n = len(u_select)
        if self.empty or n == 0:
            d = np.zeros((n, 3))
            d[:, 2] = 1.0
            return PhotonEmission(np.zeros((n, 3)), d, np.zeros((n, 3)), np.zeros(n, np.int64),
                                  np.full(n, -1, np.int64), np.zeros(n, bool))
        light, pmf, u_side = self.select.sample_discrete(u_select)
        prim = np.full(n, -1, np.int64)
        if len(self.groups_present) == 1:  # one kind of emitter (the common case): no scatter
            rays = self._sample_group(self.groups_present[0], light, u_pos, u_dir, u_side)
            o, d, flux = rays.o, rays.d, rays.flux
            if rays.prim is not None:
                prim = rays.prim
        else:
            o, d, flux = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
            g = self.group[light]
            for code in self.groups_present:
                rows = np.flatnonzero(g == code)
                if not len(rows):
                    continue
                rays = self._sample_group(code, light[rows], u_pos[rows], u_dir[rows], u_side[rows])
                o[rows], d[rows], flux[rows] = rays.o, rays.d, rays.flux
                if rays.prim is not None:
                    prim[rows] = rays.prim
        inv_pmf = np.divide(1.0, pmf, out=np.zeros(n), where=pmf > 0)
        for k in range(3):
            flux[:, k] *= inv_pmf
        valid = ((flux[:, 0] != 0) | (flux[:, 1] != 0) | (flux[:, 2] != 0)) \
            & np.isfinite(flux[:, 0] + flux[:, 1] + flux[:, 2])
        if not valid.all():
            flux[~valid] = 0.0
        return PhotonEmission(o, d, flux, light, prim, valid)

    def _sample_group(self, code, light, u_pos, u_dir, u_side) -> PhotonRays:
        """Photons of emitters `light` (N,), all of group `code`."""
        ls, an = self.lights, self.lights.lights
        n = len(light)
        i = _one_or_all(light)  # an int when one emitter makes all of them: its rows broadcast
        if code in (LIGHT_RECT, LIGHT_DISK):
            fx, fy, fz = (take(an.frame[:, k], i) for k in range(3))
            hx, hy = an.size[i, 0], an.size[i, 1]
            if code == LIGHT_RECT:
                xy = sampling.sample_uniform_rectangle(u_pos, hx, hy)
            else:
                xy = sampling.sample_concentric_disk(u_pos)
                xy[:, 0] *= hx
                xy[:, 1] *= hy
            o = _affine(take(an.position, i), (xy[:, 0], fx), (xy[:, 1], fy))
            local = sampling.sample_cosine_hemisphere(u_dir)
            d = sampling.to_world(local, fx, fy, -fz)
            a = shapes.area(an)[i]
            ok = (local[:, 2] > 0) & (a > 0)
            return PhotonRays(o, d, _colour(take(an.Le, i), np.where(ok, np.pi * a, 0.0)))
        if code == TRIANGLE:
            t = i - ls.n_analytic
            b = sampling.sample_uniform_triangle(u_pos)
            density = np.ones(n)  # relative to uniform over the triangle
            r = np.flatnonzero(ls.tri_varying[t]) if ls.tri_varying is not None else ()
            if len(r):  # textured emitters: photons leave where they shine
                b[r], density[r] = ls.maps.sample(ls.map_row[t[r]], u_pos[r])
            o = _affine(take(ls.tri_v0, t), (b[:, 1], take(ls.tri_e1, t)), (b[:, 2], take(ls.tri_e2, t)))
            nrm = _colour(take(ls.tri_ng, t), np.where(u_side < 0.5, 1.0, -1.0))  # two-sided: either face
            local = sampling.sample_cosine_hemisphere(u_dir)
            tb = sampling.frame_from_z(nrm)
            d = sampling.to_world(local, tb[0], tb[1], nrm)
            a = ls.tri_area[t]
            Le = take(ls.tri_Le, t)
            if len(r):
                Le[r] = ls.triangle_emission(t[r], b[r], o[r], d[r])
            flux = _colour(Le, np.where(local[:, 2] > 0, 2.0 * np.pi * a / density, 0.0))
            return PhotonRays(o, d, flux, np.broadcast_to(ls.tri_prim[t], (n,)).copy())
        if code in (LIGHT_POINT, LIGHT_SPOT):
            c = take(an.position, i)
            if code == LIGHT_POINT:
                d = sampling.sample_uniform_sphere(u_dir)
                att_over_pdf = np.full(n, 4.0 * np.pi)
            else:
                axis = -take(an.frame[:, 2], i)
                mu = sample_spot_cos(u_dir[:, 0], np.broadcast_to(an.spot_cos_half[i], (n,)),
                                     np.broadcast_to(an.spot_smooth[i], (n,)))
                d = _direction_about(mu, u_dir[:, 1], np.broadcast_to(axis, (n, 3)))
                pdf_dir = self._pdf_spot(i, d)
                att = shapes.spot_attenuation(an, i, d)
                att_over_pdf = np.divide(att, pdf_dir, out=np.zeros_like(att), where=pdf_dir > 0)
            r = an.radius[i]
            if np.any(r > 0):
                t, b = sampling.frame_from_z(d)
                xy = sampling.sample_concentric_disk(u_pos)
                # sphere: lift the disk point onto the hemisphere facing d (projected-area sampling)
                lift = np.where(an.soft[i], 0.0, r * np.sqrt(np.maximum(0.0, 1.0 - xy[:, 0]**2 - xy[:, 1]**2)))
                o = _affine(c, (r * xy[:, 0], t), (r * xy[:, 1], b), (lift, d))
            else:
                o = np.empty((n, 3))
                o[:] = c
            intensity = _colour(take(an.Le, i), np.where(r > 0, np.pi * r * r, 1.0) * att_over_pdf)
            return PhotonRays(o, d, intensity)
        # Parallel beams: wi towards the emitter, origin on the disk of radius R behind the scene.
        beam = np.pi * self.radius**2
        if code == LIGHT_SUN:
            z = np.broadcast_to(take(an.frame[:, 2], i), (n, 3))
            half = np.broadcast_to(np.minimum(an.sun_half_angle[i], 0.5 * np.pi), (n,))
            local, omc = sampling.sample_sphere_cone(u_dir, np.sin(half) ** 2)
            t, b = sampling.frame_from_z(z)
            wi = np.where((half > 0)[:, None], sampling.to_world(local, t, b, z), z)
            solid_angle = np.where(half > 0, 2.0 * np.pi * omc, 1.0)  # 1 / pdf_dir (delta: 1)
            flux = _colour(take(an.Le, i), beam * solid_angle)
        elif code == ENVIRONMENT:
            e = self.env.sample(u_dir)
            wi = e.wi
            flux = scale(e.Le, np.divide(beam, e.pdf, out=np.zeros_like(e.pdf), where=e.pdf > 0))
        else:  # WORLD
            wi = sampling.sample_uniform_sphere(u_dir)
            flux = _colour(self.world_L, np.full(n, beam * 4.0 * np.pi))
        return PhotonRays(self._disk_origin(wi, u_pos), -wi, flux)

    def _disk_origin(self, wi, u_pos):
        """Points (N,3) uniform on the disk of radius R perpendicular to wi, centred R from the
        scene centre along wi (tangent to the bounding sphere, on the emitter's side)."""
        t, b = sampling.frame_from_z(wi)
        xy = sampling.sample_concentric_disk(u_pos) * self.radius
        return _affine(self.center, (np.full(len(wi), self.radius), wi), (xy[:, 0], t), (xy[:, 1], b))

    def _pdf_spot(self, light, d):
        """Solid-angle pdf (N,) of spot directions d (N,3): att / (2 pi M)."""
        an = self.lights.lights
        _, _, mass = spot_mass(an.spot_cos_half[light], an.spot_smooth[light])
        att = shapes.spot_attenuation(an, light, d)
        return np.divide(att, 2.0 * np.pi * mass, out=np.zeros_like(att), where=mass > 0)

    # ---- densities ---------------------------------------------------------------------------
    def pdf(self, light, o, d) -> PhotonPdf:
        """Densities of photons (o, d) (N,3) from emitters `light` (N,). o is assumed to lie on
        the emitter's support (as `sample` puts it); only the direction is checked against the
        emitter."""
        light = np.asarray(light, np.int64)
        o = np.asarray(o, np.float64)
        d = np.asarray(d, np.float64)
        n = len(light)
        pdf_pos, pdf_dir = np.zeros(n), np.zeros(n)
        if self.empty:
            return PhotonPdf(pdf_pos, pdf_dir)
        ls, an = self.lights, self.lights.lights
        g = self.group[light]
        disk = 1.0 / (np.pi * self.radius**2)
        for code in set(g.tolist()):
            rows = np.flatnonzero(g == code)
            i = light[rows]
            dr = d[rows]
            if code in (LIGHT_RECT, LIGHT_DISK):
                a = shapes.area(an)[i]
                pdf_pos[rows] = np.divide(1.0, a, out=np.zeros_like(a), where=a > 0)
                pdf_dir[rows] = np.maximum(-dot(dr, take(an.frame[:, 2], i)), 0.0) / np.pi
            elif code == TRIANGLE:
                t = i - ls.n_analytic
                pdf_pos[rows] = 1.0 / ls.tri_area[t]
                v = np.flatnonzero(ls.tri_varying[t]) if ls.tri_varying is not None else ()
                if len(v):
                    b = ls.barycentrics(t[v], o[rows[v]])
                    pdf_pos[rows[v]] *= ls.maps.pdf_in_triangle(ls.map_row[t[v]], b)
                pdf_dir[rows] = np.abs(dot(dr, take(ls.tri_ng, t))) / (2.0 * np.pi)
            elif code in (LIGHT_POINT, LIGHT_SPOT):
                pdf_dir[rows] = np.full(len(rows), 0.25 / np.pi) if code == LIGHT_POINT else self._pdf_spot(i, dr)
                r = an.radius[i]
                q = o[rows] - take(an.position, i)
                cos_n = np.divide(dot(q, dr), r, out=np.zeros_like(r), where=r > 0)  # sphere: cos(n, d)
                area_term = np.where(an.soft[i], 1.0, np.maximum(cos_n, 0.0))
                pdf_pos[rows] = np.where(r > 0, np.divide(area_term, np.pi * r * r, out=np.zeros_like(r), where=r > 0), 1.0)
            elif code == LIGHT_SUN:
                half = np.minimum(an.sun_half_angle[i], 0.5 * np.pi)
                omc = shapes.one_minus_cos(half)
                z = take(an.frame[:, 2], i)
                inside = 0.5 * dot(dr + z, dr + z) <= omc  # -d within the cone (chord form)
                pdf_dir[rows] = np.where(half > 0, np.where(inside, 1.0 / np.maximum(2.0 * np.pi * omc, 1e-300), 0.0), 1.0)
                pdf_pos[rows] = disk
            elif code == ENVIRONMENT:
                pdf_dir[rows] = self.env.pdf(-dr)
                pdf_pos[rows] = disk
            else:
                pdf_dir[rows] = 0.25 / np.pi
                pdf_pos[rows] = disk
        return PhotonPdf(pdf_pos, pdf_dir)
