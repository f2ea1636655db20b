"""The atmosphere tables behind the Sky Texture's Single and Multiple Scattering skies: the sky
as a 512 x 256 CIE XYZ texture over azimuth and elevation, and the sun disc's colour at its
lowest and highest point, computed as Blender's intern/sky computes them on the host before
Cycles renders (sky_single_scattering.cpp, sky_multiple_scattering.cpp, read through
Cycles' SkyLoader, scene/image_sky.cpp).

Single Scattering is Nishita et al.'s model ("Display of the Earth Taking into Account
Atmospheric Scattering", SIGGRAPH 1993) as Blender's "Nishita improved" sky has it: 21
wavelengths from 380 to 780 nm, Rayleigh, Mie (Cornette-Shanks phase) and ozone absorption,
32 steps along the view ray, the optical depth toward the sun by 8-point Gauss-Laguerre
quadrature. Multiple Scattering is Fernando García Liñán's spectral model (his thesis; "A
spectral sky in 4 wavelengths", 2024): four wavelengths, a transmittance table, Hillaire's
energy-conserving integration along 64 steps ("Physically Based Sky, Atmosphere and Cloud
Rendering in Frostbite", 2016) and a fitted multiple-scattering term.

Everything is computed in float32 in the order Blender's C++ computes it: heights are
differences of lengths near 6.4e6 m, where float32 steps are half a metre, and the distance
to the ground of a ray grazing it is the root of a float32 difference of squares, so the
texture depends on these roundings; transcendental functions are evaluated in float64 and
rounded, within an ulp of glibc's float functions. Cost, once per distinct setting (cached,
a texture is 1.5 MB): about 1 s of CPU for Multiple Scattering (64 x 16384 transmittance
samples, then 64 in-scattering steps for each of 65536 texels), 0.5 s for Single Scattering
(32 steps of 21 wavelengths for each of 32768 texels), 3 ms for a sun.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

F = np.float32
WIDTH, HEIGHT = 512, 256  # Cycles' SkyLoader texture
PI = F(3.1415926535897932)
PI_2 = F(1.5707963267948966)
TWO_PI = F(6.2831853071795864)
INV_PI = F(0.3183098861837067)
INV_4PI = F(0.0795774715459476)


def _f(x) -> np.ndarray:
    return np.asarray(x, F)


def _exp(x):
    return np.exp(np.asarray(x, np.float64)).astype(F)


def _pow(x, y):
    return np.power(np.asarray(x, np.float64), np.float64(y)).astype(F)


def _cos(x):
    return np.cos(np.asarray(x, np.float64)).astype(F)


def _sin(x):
    return np.sin(np.asarray(x, np.float64)).astype(F)


def _sqrt(x):
    return np.sqrt(_f(x))


def _dot(a, b):
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _length(a):
    return _sqrt(_dot(a, a))


def wrap_sun(elevation: float, rotation: float) -> tuple:
    """Cycles' SkyTextureNode::simplify_settings: the sun's elevation folded into [-pi/2, pi/2]
    (turning it around by pi where it passed the zenith) and its rotation into [0, 2 pi)
    reversed, as the kernel and the tables read them (float32)."""
    e, r = F(elevation), F(rotation)
    e = np.fmod(e, TWO_PI)
    if abs(e) >= PI:
        e = e - F(np.copysign(F(2.0), e)) * PI
    if e >= PI_2 or e <= -PI_2:
        e = F(np.copysign(PI, e)) - e
        r = r + PI
    r = np.fmod(r, TWO_PI)
    if r < 0.0:
        r = r + TWO_PI
    return float(e), float(TWO_PI - r)


def earth_intersection_angle(altitude: float) -> float:
    """How far below the horizon the Earth's edge lies seen from `altitude` metres (Blender's
    SKY_earth_intersection_angle, Earth radius 6371 km)."""
    return float(PI_2 - F(np.arcsin(np.float64(F(6371.0) / (F(6371.0) + F(altitude) / F(1000.0))))))


# ---- Single scattering (sky_single_scattering.cpp) ---------------------------------------------

_S_RAYLEIGH_SCALE = F(8e3)
_S_MIE_SCALE = F(1.2e3)
_S_MIE_COEFF = F(2e-5)
_S_MIE_G = F(0.76)
_S_SQR_G = _S_MIE_G * _S_MIE_G
_S_EARTH_RADIUS = F(6360e3)
_S_ATMOSPHERE_RADIUS = F(6420e3)
_S_STEPS = 32
_S_STEP_LAMBDA = F(20.0)  # (780 - 380) / (21 - 1) nm
# Sun irradiance at the top of the atmosphere (W m^-2 nm^-1), Rayleigh scattering and ozone
# absorption coefficients (m^-1), at 380, 400, ..., 780 nm.
_S_IRRADIANCE = _f([
    1.45756829855592995315, 1.56596305559738380175, 1.65148449067670455293, 1.71496242737209314555,
    1.75797983805020541226, 1.78256407885924539336, 1.79095108475838560302, 1.78541550133410664714,
    1.76815554864306845317, 1.74122069647250410362, 1.70647127164943679389, 1.66556087452739887134,
    1.61993437242451854274, 1.57083597368892080581, 1.51932335059305478886, 1.46628494965214395407,
    1.41245852740172450623, 1.35844961970384092709, 1.30474913844739281998, 1.25174963272610817455,
    1.19975998755420620867])
_S_RAYLEIGH = _f([
    0.00005424820087636473, 0.00004418549866505454, 0.00003635151910165377, 0.00003017929012024763,
    0.00002526320226989157, 0.00002130859310621843, 0.00001809838025320633, 0.00001547057129129042,
    0.00001330284977336850, 0.00001150184784075764, 0.00000999557429990163, 0.00000872799973630707,
    0.00000765513700977967, 0.00000674217203751443, 0.00000596134125832052, 0.00000529034598065810,
    0.00000471115687557433, 0.00000420910481110487, 0.00000377218381260133, 0.00000339051255477280,
    0.00000305591531679811])
_S_OZONE = _f([
    0.00000000325126849861, 0.00000000585395365047, 0.00000001977191155085, 0.00000007309568762914,
    0.00000020084561514287, 0.00000040383958096161, 0.00000063551335912363, 0.00000096707041180970,
    0.00000154797400424410, 0.00000209038647223331, 0.00000246128056164565, 0.00000273551299461512,
    0.00000215125863128643, 0.00000159051840791988, 0.00000112356197979857, 0.00000073527551487574,
    0.00000046450130357806, 0.00000033096079921048, 0.00000022512612292678, 0.00000014879129266490,
    0.00000016828623364192])
# CIE 1931 2-degree colour matching functions at the same wavelengths.
_S_CMF = _f([
    (0.00136800000, 0.00003900000, 0.00645000100), (0.01431000000, 0.00039600000, 0.06785001000),
    (0.13438000000, 0.00400000000, 0.64560000000), (0.34828000000, 0.02300000000, 1.74706000000),
    (0.29080000000, 0.06000000000, 1.66920000000), (0.09564000000, 0.13902000000, 0.81295010000),
    (0.00490000000, 0.32300000000, 0.27200000000), (0.06327000000, 0.71000000000, 0.07824999000),
    (0.29040000000, 0.95400000000, 0.02030000000), (0.59450000000, 0.99500000000, 0.00390000000),
    (0.91630000000, 0.87000000000, 0.00165000100), (1.06220000000, 0.63100000000, 0.00080000000),
    (0.85444990000, 0.38100000000, 0.00019000000), (0.44790000000, 0.17500000000, 0.00002000000),
    (0.16490000000, 0.06100000000, 0.00000000000), (0.04677000000, 0.01700000000, 0.00000000000),
    (0.01135916000, 0.00410200000, 0.00000000000), (0.00289932700, 0.00104700000, 0.00000000000),
    (0.00069007860, 0.00024920000, 0.00000000000), (0.00016615050, 0.00006000000, 0.00000000000),
    (0.00004150994, 0.00001499000, 0.00000000000)])
# Gauss-Laguerre quadrature (8 nodes) along a ray to the top of the atmosphere, scaled so the
# last node stays inside; the weights include the exp(x) factor.
_S_NODES = _f([0.006811185292, 0.03614807107, 0.09004346519, 0.1706680068, 0.2818362161, 0.4303406404,
               0.6296271457, 0.9145252695])
_S_WEIGHTS = _f([0.01750893642, 0.04135477391, 0.06678839063, 0.09507698807, 0.1283416365, 0.1707430204,
                 0.2327233347, 0.3562490486])


def _s_densities(height):
    """Rayleigh, Mie and ozone densities (relative) at heights (m): (..., 3). The ozone layer
    is a tent around 25 km, computed in double as Blender's fmax/fabs on doubles do."""
    ozone = np.maximum(0.0, 1.0 - np.abs(height.astype(np.float64) - 25000.0) / 15000.0).astype(F)
    return np.stack([_exp(-height / _S_RAYLEIGH_SCALE), _exp(-height / _S_MIE_SCALE), ozone], axis=-1)


def _s_atmosphere_exit(pos, direction):
    """Where rays from `pos` along `direction` leave the atmosphere (the far root)."""
    b = F(-2.0) * _dot(direction, -pos)
    c = _dot(pos, pos) - _S_ATMOSPHERE_RADIUS * _S_ATMOSPHERE_RADIUS
    t = (-b + _sqrt(b * b - F(4.0) * c)) / F(2.0)
    return pos + direction * t[..., None]


def _s_optical_depth(origin, direction):
    """Rayleigh, Mie and ozone optical depth (relative, m) from `origin` out of the atmosphere."""
    length = _length(origin - _s_atmosphere_exit(origin, direction))
    segment = length[..., None] * direction
    depth = np.zeros(origin.shape, F)
    for node_t, weight in zip(_S_NODES, _S_WEIGHTS):
        height = _length(origin + node_t * segment) - _S_EARTH_RADIUS
        depth = depth + _s_densities(height) * weight
    return depth * length[..., None]


def _s_spectrum_to_xyz(spectrum):
    xyz = np.zeros(spectrum.shape[:-1] + (3,), F)
    for i in range(spectrum.shape[-1]):
        xyz = xyz + _S_CMF[i] * spectrum[..., i:i + 1]
    return xyz * _S_STEP_LAMBDA


def _s_inscattering(directions, sun, origin, densities):
    """Single-scattered sun light (21 wavelengths) along view rays `directions` (N,3) from
    `origin`, 32 steps evaluated at their middles."""
    n = len(directions)
    length = _length(origin - _s_atmosphere_exit(np.broadcast_to(origin, directions.shape), directions))
    step = length / F(_S_STEPS)
    segment = step[:, None] * directions
    mu = _dot(directions, sun)
    rayleigh_phase = (F(0.1875) * INV_PI) * (F(1.0) + mu * mu)
    mie_phase = ((F(3.0) * (F(1.0) - _S_SQR_G)) * (F(1.0) + mu * mu)) / (
        ((F(8.0) * PI) * (F(2.0) + _S_SQR_G)) * _pow((F(1.0) + _S_SQR_G) - (F(2.0) * _S_MIE_G) * mu, 1.5))
    scale = _f(densities)
    depth = np.zeros((n, 3), F)
    spectrum = np.zeros((n, len(_S_IRRADIANCE)), F)
    p = origin + F(0.5) * segment
    mie_extinction = F(1.11) * _S_MIE_COEFF
    for _ in range(_S_STEPS):
        height = _length(p) - _S_EARTH_RADIUS
        density = scale * _s_densities(height)
        depth = depth + step[:, None] * density
        lit = ~_s_earth_blocks(p, sun)
        if lit.any():
            total = depth[lit] + scale * _s_optical_depth(p[lit], np.broadcast_to(sun, p[lit].shape))
            extinction = (total[:, 0:1] * _S_RAYLEIGH + total[:, 1:2] * mie_extinction) + total[:, 2:3] * _S_OZONE
            attenuation = _exp(-extinction)
            d = density[lit]
            scattered = (rayleigh_phase[lit, None] * (d[:, 0:1] * _S_RAYLEIGH)
                         + mie_phase[lit, None] * (d[:, 1:2] * _S_MIE_COEFF)) + F(0.0)
            spectrum[lit] = spectrum[lit] + ((attenuation * scattered) * _S_IRRADIANCE) * step[lit, None]
        p = p + segment
    return spectrum


def _s_earth_blocks(pos, direction):
    """Whether rays from `pos` toward `direction` (one, (3,)) hit the Earth."""
    if direction[2] >= 0.0:
        return np.zeros(len(pos), bool)
    b = F(-2.0) * _dot(np.broadcast_to(direction, pos.shape), -pos)
    c = _dot(pos, pos) - _S_EARTH_RADIUS * _S_EARTH_RADIUS
    return b * b - F(4.0) * c >= 0.0


def _geographic(latitude, longitude):
    latitude, longitude = _f(latitude), _f(longitude)
    return np.stack(np.broadcast_arrays(_cos(latitude) * _cos(longitude), _cos(latitude) * _sin(longitude),
                                        _sin(latitude)), axis=-1)


@lru_cache(maxsize=8)
def single_scattering_texture(sun_elevation: float, altitude: float, air: float, aerosol: float,
                              ozone: float) -> np.ndarray:
    """SKY_single_scattering_precompute_texture: (256, 512, 3) float32 XYZ, row 0 looking
    straight down. Row y >= 128 looks up at elevation pi/2 (y / 128 - 1)^2 and column x at
    azimuth 2 pi x / 512 - pi (both without the half-texel offset the kernel's lookup assumes,
    as Blender builds it), the sun at azimuth 0; the columns mirror about the sun's. The rows
    below the horizon are the horizon's, faded by (1 - 2.5 sin(pi/2 (y / 128 - 1)^2))^3 down
    to black."""
    altitude = np.clip(F(altitude), F(1.0), F(59999.0))
    origin = _f([0.0, 0.0, _S_EARTH_RADIUS + altitude])
    sun = _geographic(F(sun_elevation), F(0.0))
    half_w, half_h = WIDTH // 2, HEIGHT // 2
    latitude = PI_2 * np.square(np.arange(HEIGHT).astype(F) / F(half_h) - F(1.0))
    longitude = (TWO_PI / F(WIDTH)) * np.arange(half_w).astype(F) - PI
    directions = _geographic(latitude[half_h:, None], longitude[None, :]).reshape(-1, 3)
    xyz = _s_spectrum_to_xyz(_s_inscattering(directions, sun, origin, (air, aerosol, ozone)))
    table = np.zeros((HEIGHT, WIDTH, 3), F)
    table[half_h:, :half_w] = xyz.reshape(HEIGHT - half_h, half_w, 3)
    table[half_h:, half_w:] = table[half_h:, :half_w][:, ::-1]
    z = _sin(latitude[:half_h])
    fade = np.where(z < F(0.4), F(1.0) - z * F(2.5), F(0.0)).astype(F)
    table[:half_h] = table[half_h] * (fade * fade * fade)[:, None, None]
    table.flags.writeable = False
    return table


def single_scattering_sun(sun_elevation: float, angular_diameter: float, altitude: float, air: float,
                          aerosol: float) -> tuple:
    """SKY_single_scattering_precompute_sun: XYZ radiance of the sun disc's lowest and highest
    points (the sun through the atmosphere over its solid angle; no ozone), black when the
    whole disc is below the horizon."""
    altitude = np.clip(F(altitude), F(1.0), F(59999.0))
    half = F(angular_diameter) / F(2.0)
    solid_angle = TWO_PI * (F(1.0) - _cos(half))
    bottom, top = F(sun_elevation) - half, F(sun_elevation) + half
    if not top > 0.0:
        return np.zeros(3), np.zeros(3)
    elevations = _f([max(bottom, F(0.0)), top])
    origin = np.broadcast_to(_f([0.0, 0.0, _S_EARTH_RADIUS + altitude]), (2, 3))
    depth = _s_optical_depth(origin, _geographic(elevations, F(0.0)))
    mie_extinction = F(1.11) * _S_MIE_COEFF
    extinction = (_S_RAYLEIGH * depth[:, 0:1]) * F(air) + (mie_extinction * depth[:, 1:2]) * F(aerosol)
    spectrum = (_S_IRRADIANCE * _exp(-extinction)) / solid_angle
    xyz = _s_spectrum_to_xyz(spectrum).astype(np.float64)
    return xyz[0], xyz[1]


# ---- Multiple scattering (sky_multiple_scattering.cpp) ----------------------------------------

_M_GROUND_ALBEDO = F(0.3)
_M_RAYLEIGH_PHASE_SCALE = (F(3.0) / F(16.0)) * INV_PI
_M_G = F(0.8)  # aerosol anisotropy
_M_SQR_G = _M_G * _M_G
_M_EARTH_RADIUS = F(6371.0)  # km
_M_ATMOSPHERE_THICKNESS = F(100.0)
_M_ATMOSPHERE_RADIUS = _M_EARTH_RADIUS + _M_ATMOSPHERE_THICKNESS
_M_TRANSMITTANCE_STEPS = 64
_M_INSCATTERING_STEPS = 64
_M_LUT_W, _M_LUT_H = 256, 64
# Four wavelengths, 630, 560, 490 and 430 nm (an urban-area sun spectrum).
_M_SUN_IRRADIANCE = _f([1.679, 1.828, 1.986, 1.307])
_M_MOLECULAR_SCATTERING = _f([6.605e-3, 1.067e-2, 1.842e-2, 3.156e-2])
_M_OZONE_CROSS_SECTION = _f([3.472e-25, 3.914e-25, 1.349e-25, 11.03e-27])
_M_OZONE_MEAN_DOBSON = F(334.5)
_M_AEROSOL_ABSORPTION = _f([2.8722e-24, 4.6168e-24, 7.9706e-24, 1.3578e-23])
_M_AEROSOL_SCATTERING = _f([1.5908e-22, 1.7711e-22, 2.0942e-22, 2.4033e-22])
_M_AEROSOL_BASE_DENSITY = F(1.3681e20)
_M_AEROSOL_BACKGROUND_DENSITY = F(2e6)
_M_AEROSOL_HEIGHT_SCALE = F(0.73)
# The four wavelengths' radiances to CIE XYZ (rows: wavelengths).
_M_SPECTRAL_XYZ = _f([(53.386917738564668023, 22.981337506691024754, 0.0),
                      (43.904844466369358263, 71.347795700053393866, 0.102506867965741307),
                      (1.6137278251608962005, 18.422960591455485011, 31.742921188390805758),
                      (20.762668673810577145, 2.3614213523314368527, 110.48009643252140334)])
_M_MS_FIT = F(0.02) * _f([0.217, 0.347, 0.594, 1.0])


def _m_sun_direction(cos_theta):
    cos_theta = _f(cos_theta)
    return np.stack(np.broadcast_arrays(-_sqrt(F(1.0) - cos_theta * cos_theta), F(0.0), cos_theta), axis=-1)


def _m_sphere_distance(pos, direction, radius):
    """ray_sphere_intersection: the distance to the sphere of `radius` about the Earth's
    centre, -1 where the ray misses it or starts outside it going away."""
    b = _dot(pos, direction)
    c = _dot(pos, pos) - radius * radius
    d = b * b - c
    root = _sqrt(np.maximum(d, F(0.0)))
    t = np.where(d >= b * b, -b + root, -b - root)
    return np.where(((c > 0.0) & (b > 0.0)) | (d < 0.0), F(-1.0), t).astype(F)


class _Atmosphere:
    """The collision coefficients of air, aerosols and ozone scaled by the node's densities,
    and the transmittance table (toward the sun, over its zenith cosine and the altitude)."""

    def __init__(self, air: float, aerosol: float, ozone: float):
        self.air, self.aerosol, self.ozone = F(air), F(aerosol), F(ozone)
        cos_theta = (np.arange(_M_LUT_W).astype(F) / F(_M_LUT_W - 1)) * F(2.0) - F(1.0)
        altitude = np.arange(_M_LUT_H).astype(F) / F(_M_LUT_H - 1)
        c, a = np.meshgrid(cos_theta, altitude)
        self.lut = self.transmittance(c.ravel(), a.ravel()).reshape(_M_LUT_H, _M_LUT_W, 4)
        self.flat = self.lut.reshape(-1, 4)
        self.at_sea_level = self.toward_zenith(F(0.0))

    def coefficients(self, altitude):
        """(aerosol absorption, aerosol scattering, molecular absorption, molecular scattering)
        at altitudes (km), each (..., 4)."""
        aerosol = (_M_AEROSOL_BASE_DENSITY * (_exp(-altitude / _M_AEROSOL_HEIGHT_SCALE)
                                              + _M_AEROSOL_BACKGROUND_DENSITY / _M_AEROSOL_BASE_DENSITY)) * self.aerosol
        log_h = np.log(np.maximum(altitude, F(1e-4)).astype(np.float64)).astype(F)
        ozone = F(3.78547397e20) * _exp(-np.square(log_h - F(3.22261)) * F(5.55555555) - log_h)
        return (_M_AEROSOL_ABSORPTION * aerosol[..., None], _M_AEROSOL_SCATTERING * aerosol[..., None],
                ((_M_OZONE_CROSS_SECTION * _M_OZONE_MEAN_DOBSON) * ozone[..., None]) * self.ozone,
                (_M_MOLECULAR_SCATTERING * _exp(F(-0.07771971) * _pow(altitude, F(1.16364243)))[..., None]) * self.air)

    def extinction(self, altitude):
        aa, a_s, ma, ms = self.coefficients(altitude)
        return ((aa + a_s) + ma) + ms

    def transmittance(self, cos_theta, normalized_altitude):
        """Transmittance to the sun (marched, 64 steps) from the normalised altitude."""
        sun = _m_sun_direction(cos_theta)
        radius = _M_EARTH_RADIUS + _f(normalized_altitude) * (_M_ATMOSPHERE_RADIUS - _M_EARTH_RADIUS)
        origin = np.stack(np.broadcast_arrays(F(0.0), F(0.0), radius), axis=-1)
        step = _m_sphere_distance(origin, sun, _M_ATMOSPHERE_RADIUS) / F(_M_TRANSMITTANCE_STEPS)
        depth = np.zeros(np.shape(radius) + (4,), F)
        for i in range(_M_TRANSMITTANCE_STEPS):
            x = origin + sun * ((F(i) + F(0.5)) * step)[..., None]
            altitude = np.maximum(_length(x) - _M_EARTH_RADIUS, F(0.0))
            depth = depth + self.extinction(altitude) * step[..., None]
        return _exp(-depth)

    def lookup(self, cos_theta, normalized_altitude):
        """The transmittance table, bilinear (lookup_transmittance)."""
        x = F(_M_LUT_W - 1) * np.clip(cos_theta * F(0.5) + F(0.5), F(0.0), F(1.0))
        y = F(_M_LUT_H - 1) * np.clip(normalized_altitude, F(0.0), F(1.0))
        x1, y1 = x.astype(np.int64), y.astype(np.int64)
        dx = np.where(x1 < _M_LUT_W - 1, 1, 0)
        dy = np.where(y1 < _M_LUT_H - 1, _M_LUT_W, 0)
        fx, fy = (x - x1.astype(F))[:, None], (y - y1.astype(F))[:, None]
        i = y1 * _M_LUT_W + x1
        flat = self.flat
        a, b = np.take(flat, i, axis=0), np.take(flat, i + dx, axis=0)
        c, d = np.take(flat, i + dy, axis=0), np.take(flat, i + dy + dx, axis=0)
        bottom = a + fx * (b - a)
        top = c + fx * (d - c)
        return bottom + fy * (top - bottom)

    def at_ground(self, cos_theta):
        """The table's bottom row (the ground), linear (lookup_transmittance_at_ground)."""
        x = F(_M_LUT_W - 1) * np.clip(cos_theta * F(0.5) + F(0.5), F(0.0), F(1.0))
        x1 = x.astype(np.int64)
        x2 = np.minimum(x1 + 1, _M_LUT_W - 1)
        fx = (x - x1.astype(F))[:, None]
        row = self.lut[0]
        a = np.take(row, x1, axis=0)
        return a + fx * (np.take(row, x2, axis=0) - a)

    def toward_zenith(self, normalized_altitude):
        """The table's last column (straight up), linear (lookup_transmittance_to_sun)."""
        y = F(_M_LUT_H - 1) * np.clip(_f(normalized_altitude), F(0.0), F(1.0))
        y1 = y.astype(np.int64)
        y2 = np.minimum(y1 + 1, _M_LUT_H - 1)
        fy = (y - y1.astype(F))[..., None]
        column = self.lut[:, _M_LUT_W - 1]
        a = np.take(column, y1, axis=0)
        return a + fy * (np.take(column, y2, axis=0) - a)

    def multiple_scattering(self, cos_theta, normalized_altitude, distance):
        """Light scattered more than once: the ground's second bounce (albedo 0.3) and the fit
        of the atmosphere's own higher orders (lookup_multiscattering)."""
        ratio = _M_EARTH_RADIUS / distance
        omega = TWO_PI * (F(1.0) - _sqrt(F(1.0) - ratio * ratio))
        to_ground = self.at_ground(cos_theta)
        ground_to_sample = self.at_sea_level / self.toward_zenith(normalized_altitude)
        ground = (((((INV_4PI * omega)[..., None] * (_M_GROUND_ALBEDO * INV_PI)) * to_ground) * ground_to_sample)
                  * cos_theta[..., None])
        fit = _M_MS_FIT * (F(1.0) / (F(1.0) + F(5.0) * _exp(F(-17.92) * cos_theta)))[..., None]
        return fit + ground

    def inscattering(self, sun, origin, directions, distance):
        """Radiance (4 wavelengths) scattered toward `origin` along `directions` over
        `distance` (km), 64 steps of Hillaire's integration."""
        cos_theta = _dot(-directions, sun)
        molecular_phase = _M_RAYLEIGH_PHASE_SCALE * (F(1.0) + cos_theta * cos_theta)
        den = F(1.0) + _M_SQR_G + F(2.0) * _M_G * cos_theta
        aerosol_phase = INV_4PI * (F(1.0) - _M_SQR_G) / (den * _sqrt(den))
        dt = distance / F(_M_INSCATTERING_STEPS)
        radiance = np.zeros((len(directions), 4), F)
        transmittance = np.ones((len(directions), 4), F)
        for i in range(_M_INSCATTERING_STEPS):
            x = origin + directions * ((F(i) + F(0.5)) * dt)[:, None]
            d = _length(x)
            zenith = x / d[:, None]
            altitude = np.maximum(d - _M_EARTH_RADIUS, F(0.0))
            normalized = altitude / _M_ATMOSPHERE_THICKNESS
            sample_cos = _dot(zenith, sun)
            aa, a_s, ma, ms = self.coefficients(altitude)
            extinction = ((aa + a_s) + ma) + ms
            to_sun = self.lookup(sample_cos, normalized)
            multiple = self.multiple_scattering(sample_cos, normalized, d)
            source = _M_SUN_IRRADIANCE * (ms * (molecular_phase[:, None] * to_sun + multiple)
                                          + a_s * (aerosol_phase[:, None] * to_sun + multiple))
            step = _exp(-dt[:, None] * extinction)
            integrated = (source - source * step) / np.maximum(extinction, F(1e-7))
            radiance = radiance + transmittance * integrated
            transmittance = transmittance * step
        return radiance


def _m_to_xyz(spectrum):
    xyz = np.zeros(spectrum.shape[:-1] + (3,), F)
    for i in range(4):
        xyz = xyz + _M_SPECTRAL_XYZ[i] * spectrum[..., i:i + 1]
    return xyz


@lru_cache(maxsize=4)
def _atmosphere(air: float, aerosol: float, ozone: float) -> _Atmosphere:
    return _Atmosphere(air, aerosol, ozone)


@lru_cache(maxsize=8)
def multiple_scattering_texture(sun_elevation: float, altitude: float, air: float, aerosol: float,
                                ozone: float) -> np.ndarray:
    """SKY_multiple_scattering_precompute_texture: (256, 512, 3) float32 XYZ at texel centres,
    row y at elevation sign(l) l^2 pi/2 with l = 2 (y + 0.5) / 256 - 1 (more rows near the
    horizon), column x at azimuth 2 pi (x + 0.5) / 512, the sun at azimuth pi; the columns
    mirror about the sun's. Rays that meet the ground end there."""
    atmosphere = _atmosphere(air, aerosol, ozone)
    altitude = np.clip(F(altitude), F(1.0), F(99999.0)) / F(1000.0)
    sun = _m_sun_direction(_cos(PI_2 - F(sun_elevation)))
    half_w = WIDTH // 2
    u = (np.arange(half_w).astype(F) + F(0.5)) / F(WIDTH)
    v = (np.arange(HEIGHT).astype(F) + F(0.5)) / F(HEIGHT)
    azimuth = TWO_PI * u
    l = v * F(2.0) - F(1.0)
    elevation = np.copysign(l * l, l).astype(F) * PI_2
    el, az = np.meshgrid(elevation, azimuth, indexing="ij")
    directions = np.stack([_cos(el) * _cos(az), _cos(el) * _sin(az), _sin(el)], axis=-1).reshape(-1, 3)
    origin = np.broadcast_to(_f([0.0, 0.0, _M_EARTH_RADIUS + altitude]), directions.shape)
    to_space = _m_sphere_distance(origin, directions, _M_ATMOSPHERE_RADIUS)
    to_ground = _m_sphere_distance(origin, directions, _M_EARTH_RADIUS)
    distance = np.where(to_ground < 0.0, to_space, to_ground).astype(F)
    xyz = _m_to_xyz(atmosphere.inscattering(sun, origin, directions, distance))
    table = np.zeros((HEIGHT, WIDTH, 3), F)
    table[:, :half_w] = xyz.reshape(HEIGHT, half_w, 3)
    table[:, half_w:] = table[:, :half_w][:, ::-1]
    table.flags.writeable = False
    return table


def multiple_scattering_sun(sun_elevation: float, angular_diameter: float, altitude: float, air: float,
                            aerosol: float, ozone: float) -> tuple:
    """SKY_multiple_scattering_precompute_sun: XYZ radiance of the sun disc's lowest and
    highest points, the sun's spectrum through the marched transmittance over its solid angle."""
    atmosphere = _atmosphere(air, aerosol, ozone)
    altitude = np.clip(F(altitude), F(1.0), F(99999.0)) / F(1000.0)
    half = F(angular_diameter) / F(2.0)
    solid_angle = TWO_PI * (F(1.0) - _cos(half))
    elevations = _f([F(sun_elevation) - half, F(sun_elevation) + half])
    transmittance = atmosphere.transmittance(_cos(PI_2 - elevations), np.full(2, altitude / _M_ATMOSPHERE_THICKNESS, F))
    xyz = _m_to_xyz(_M_SUN_IRRADIANCE * transmittance / solid_angle).astype(np.float64)
    return xyz[0], xyz[1]
