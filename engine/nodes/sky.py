"""Sky Texture: the sky's radiance in the direction of the Vector, as Cycles' svm/sky.h computes
it, from the host's precomputation (scene/shader_nodes.cpp SkyTextureNode) — for Blender 5.0's
four sky types:

- Preetham: Preetham, Shirley & Smits, "A Practical Analytic Model for Daylight" (SIGGRAPH
  1999): Perez et al.'s distribution for Y, x and y, zenith values fitted over turbidity;
- Hosek / Wilkie: Hosek & Wilkie, "An Analytic Model for Full Spectral Sky-Dome Radiance"
  (SIGGRAPH 2012), the CIE XYZ version (engine/nodes/hosek_data.py), turbidity and ground
  albedo;
- Single Scattering and Multiple Scattering: a precomputed XYZ texture over azimuth and
  elevation (engine/nodes/atmosphere.py: Nishita et al. 1993; García Liñán's spectral
  model), looked up bilinearly, plus the sun disc with limb darkening.

The sun of the first two is the node's Sun Direction (normalised); the others read its
elevation and rotation, folded as Cycles folds them (atmosphere.wrap_sun), and its size,
intensity, the altitude and the air, aerosol and ozone densities. Colours go from XYZ to
scene linear Rec.709 by the matrix Blender's colour configuration gives Cycles, negative
components clamped (kernel xyz_to_rgb_clamped). The Vector is taken as it is, unnormalised;
unlinked it is the Generated coordinate (in a world: the ray direction). Blender 5.0 disables
the Vector of the two scattering skies: a link left from another type is invalid, not
followed. The node's own texture mapping (TexMapping, set from Python only) is not applied.

Evaluated in float64, which differs from Cycles' float32 by about 1e-6, except for the few
values the kernel's roundings move by more: the horizon Preetham and Hosek / Wilkie hold
directions below at, the sun's direction (its disc's rim) and the texture coordinates near
the horizon, which are computed in float32 as the kernel does. Precomputation: the
coefficients in under a millisecond, the scattering tables in atmosphere.py, all cached by
their settings. Per point: 0.2 (Hosek / Wilkie) to 0.6 (Single Scattering) microseconds.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from . import atmosphere, hosek_data, image, texture_mapping
from .base import components, node

# CIE XYZ (D65) -> Linear Rec.709: Blender's OpenColorIO configuration (the Linear Rec.709
# space from CIE-XYZ D65), which Cycles reads through the aces_interchange role.
XYZ_TO_REC709 = np.array([[3.2409699, -1.5373832, -0.4986108],
                          [-0.9692436, 1.8759675, 0.0415551],
                          [0.0556301, -0.2039770, 1.0569715]])
_F32 = np.float32


def xyz_to_rgb(xyz) -> np.ndarray:
    return np.maximum(xyz @ XYZ_TO_REC709.T, 0.0)


def _spherical(d):
    """direction_to_spherical: (theta from +z, phi from +x toward +y); not normalised."""
    x, y, z = components(d)
    return np.arccos(np.clip(z, -1.0, 1.0)), np.arctan2(y, x)


# ---- Preetham and Hosek / Wilkie --------------------------------------------------------------

def _sun_angles(direction) -> tuple:
    """The normalised sun direction's (theta, phi) as the host computes them (float32):
    phi = atan2(x, y), the kernel's azimuth convention."""
    d = np.asarray(direction, np.float64)
    n = np.linalg.norm(d)
    d = (d / n if n > 0.0 else d).astype(_F32)
    return float(np.arccos(np.float64(d[2]))), float(np.arctan2(np.float64(d[0]), np.float64(d[1])))


def _perez(lam, cos_theta, gamma, cos_gamma):
    """Perez et al.'s luminance distribution (sky_perez_function)."""
    return (1.0 + lam[0] * np.exp(lam[1] / cos_theta)) * (1.0 + lam[2] * np.exp(lam[3] * gamma) + lam[4] * cos_gamma ** 2)


@lru_cache(maxsize=32)
def preetham_coefficients(direction: tuple, turbidity: float) -> tuple:
    """sky_texture_precompute_preetham: (theta, phi, zenith (Y, x, y), Perez coefficients for
    Y, x, y), the zenith values divided by the distribution at the zenith."""
    theta, phi = _sun_angles(direction)
    t = float(turbidity)
    chi = (4.0 / 9.0 - t / 120.0) * (np.pi - 2.0 * theta)
    zenith_y = ((4.0453 * t - 4.9710) * np.tan(chi) - 0.2155 * t + 2.4192) * 0.06
    # Zenith chromaticity: cubic in the sun's zenith angle, quadratic in turbidity.
    powers, turbidities = np.array([theta ** 3, theta ** 2, theta, 1.0]), np.array([t * t, t, 1.0])
    zenith_x = turbidities @ np.array([[0.00166, -0.00375, 0.00209, 0.0], [-0.02903, 0.06377, -0.03202, 0.00394],
                                       [0.11693, -0.21196, 0.06052, 0.25886]]) @ powers
    zenith_yy = turbidities @ np.array([[0.00275, -0.00610, 0.00317, 0.0], [-0.04214, 0.08970, -0.04153, 0.00516],
                                        [0.15346, -0.26756, 0.06670, 0.26688]]) @ powers
    perez = np.array([[0.1787, -1.4630], [-0.3554, 0.4275], [-0.0227, 5.3251], [0.1206, -2.5771], [-0.0670, 0.3703],
                      [-0.0193, -0.2592], [-0.0665, 0.0008], [-0.0004, 0.2125], [-0.0641, -0.8989], [-0.0033, 0.0452],
                      [-0.0167, -0.2608], [-0.0950, 0.0092], [-0.0079, 0.2102], [-0.0441, -1.6537], [-0.0109, 0.0529]])
    lam = (perez @ [t, 1.0]).reshape(3, 5)
    zenith = np.array([zenith_y, zenith_x, zenith_yy]) / [_perez(row, 1.0, theta, np.cos(theta)) for row in lam]
    return theta, phi, zenith, lam


def _bezier5(points, s):
    """The quintic Bezier of six control points (last axis -2) at s."""
    weights = np.array([(1 - s) ** 5, 5 * (1 - s) ** 4 * s, 10 * (1 - s) ** 3 * s ** 2, 10 * (1 - s) ** 2 * s ** 3,
                        5 * (1 - s) * s ** 4, s ** 5])
    return np.tensordot(weights, points, axes=([0], [-2])) if points.ndim > 1 else weights @ points


def _hosek_cook(table, turbidity: float, albedo: float, s: float):
    """ArHosekSkyModel_CookConfiguration: the table (albedo, turbidity, 6 control points, ...)
    blended over the elevation parameter s, linearly over turbidity and albedo."""
    t = int(turbidity)
    rem = turbidity - t
    out = (1.0 - albedo) * (1.0 - rem) * _bezier5(table[0, t - 1], s) + albedo * (1.0 - rem) * _bezier5(table[1, t - 1], s)
    if t == 10:
        return out
    return out + (1.0 - albedo) * rem * _bezier5(table[0, t], s) + albedo * rem * _bezier5(table[1, t], s)


@lru_cache(maxsize=32)
def hosek_coefficients(direction: tuple, turbidity: float, albedo: float) -> tuple:
    """sky_texture_precompute_hosek: (theta, phi, radiances (3,), configurations (3, 9)) for
    X, Y, Z; the sun clamped to the horizon, turbidity to [0, 10] (its property: [1, 10])."""
    theta, phi = _sun_angles(direction)
    theta = min(max(theta, 0.0), float(_F32(np.pi / 2)))
    turbidity = min(max(float(turbidity), 0.0), 10.0)
    elevation = float(_F32(np.pi / 2) - _F32(theta))
    s = (elevation / (np.pi / 2.0)) ** (1.0 / 3.0)
    config, radiance = np.asarray(hosek_data.CONFIG), np.asarray(hosek_data.RADIANCE)
    configs = np.array([_hosek_cook(config[c], turbidity, albedo, s) for c in range(3)])
    radiances = np.array([_hosek_cook(radiance[c], turbidity, albedo, s) for c in range(3)])
    return theta, phi, radiances, configs


def _hosek_radiance(c, theta, gamma):
    """The Hosek-Wilkie distribution (sky_radiance_internal) for one channel's configuration."""
    cos_gamma, cos_theta = np.cos(gamma), np.cos(theta)
    mie = (1.0 + cos_gamma ** 2) / np.power(1.0 + c[8] * c[8] - 2.0 * c[8] * cos_gamma, 1.5)
    return (1.0 + c[0] * np.exp(c[1] / (cos_theta + 0.01))) * \
        (c[2] + c[3] * np.exp(c[4] * gamma) + c[5] * cos_gamma ** 2 + c[6] * mie + c[7] * np.sqrt(cos_theta))


# Below the horizon the models hold the direction 0.001 above it, at this float32 angle: cos
# there is 1e-3, and Preetham's exp(B / cos theta) magnifies the angle's rounding (1e-4).
_HORIZON = float(_F32(np.pi / 2) - _F32(0.001))


def _view_angles(d, sun_theta, sun_phi):
    """(theta, gamma): the direction's angle from the zenith, clamped just above the horizon
    (the models do not extend below it), and its angle to the sun."""
    theta, phi = _spherical(d)
    phi = -phi + np.pi / 2.0
    cos_psi = np.sin(theta) * np.sin(sun_theta) * np.cos(sun_phi - phi) + np.cos(theta) * np.cos(sun_theta)
    gamma = np.arccos(np.clip(cos_psi, -1.0, 1.0))
    return np.minimum(theta, _HORIZON), gamma


def preetham(d, direction, turbidity) -> np.ndarray:
    sun_theta, sun_phi, zenith, lam = preetham_coefficients(tuple(direction), float(turbidity))
    theta, gamma = _view_angles(d, sun_theta, sun_phi)
    cos_theta, cos_gamma = np.cos(theta), np.cos(gamma)
    big_y, x, y = (z * _perez(row, cos_theta, gamma, cos_gamma) for z, row in zip(zenith, lam))
    safe_y = np.where(y != 0.0, y, 1.0)
    big_x = np.where(y != 0.0, x / safe_y * big_y, 0.0)
    big_z = np.where((y != 0.0) & (big_y != 0.0), (1.0 - x - y) / safe_y * big_y, 0.0)
    return xyz_to_rgb(np.stack([big_x, big_y, big_z], axis=-1))


def hosek_wilkie(d, direction, turbidity, albedo) -> np.ndarray:
    sun_theta, sun_phi, radiances, configs = hosek_coefficients(tuple(direction), float(turbidity), float(albedo))
    theta, gamma = _view_angles(d, sun_theta, sun_phi)
    xyz = np.stack([_hosek_radiance(configs[c], theta, gamma) * radiances[c] for c in range(3)], axis=-1)
    return xyz_to_rgb(xyz) * (2.0 * np.pi / 683.0)


# ---- Single and Multiple Scattering ------------------------------------------------------------

@lru_cache(maxsize=32)
def scattering_sun(multiple: bool, elevation: float, size: float, altitude: float, air: float, aerosol: float,
                   ozone: float) -> tuple:
    """The sun disc's XYZ at its bottom and top (atmosphere.*_sun)."""
    if multiple:
        return atmosphere.multiple_scattering_sun(elevation, size, altitude, air, aerosol, ozone)
    return atmosphere.single_scattering_sun(elevation, size, altitude, air, aerosol)


def scattering_sun_direction(elevation: float, rotation: float) -> np.ndarray:
    """The sun's direction as the kernel computes it, in float32: the disc's rim is where the
    angle to it is half the sun's size, and a float32 rounding of a 1e-7 there moves the limb
    darkening's steep edge by 1e-4."""
    theta, phi = _F32(elevation) - _F32(np.pi / 2), _F32(rotation) - _F32(np.pi / 2)
    sin_t, cos_t = (_F32(f(np.float64(theta))) for f in (np.sin, np.cos))
    sin_p, cos_p = (_F32(f(np.float64(phi))) for f in (np.sin, np.cos))
    return np.array([sin_t * cos_p, sin_t * sin_p, cos_t], _F32).astype(np.float64)


def _texture_coordinates(theta, phi, rotation: float):
    """Where the sky texture is read: u the azimuth from the sun's, v the elevation with the
    texture's square spacing undone. In float32 from the float32 angles, as the kernel: near
    the horizon v changes as the square root of the elevation, and next to the rows of rays
    that graze the Earth a float32 step of acosf moves the lookup by 1e-4 of a texel there."""
    theta, phi = np.asarray(theta, np.float64).astype(_F32), np.asarray(phi, np.float64).astype(_F32)
    u = (-phi - _F32(np.pi / 2) + _F32(rotation)) * _F32(1.0 / (2.0 * np.pi))
    u = u - np.floor(u)
    elevation = _F32(np.pi / 2) - theta
    v = np.copysign(np.sqrt(np.abs(elevation) * _F32(2.0 / np.pi)), elevation) * _F32(0.5) + _F32(0.5)
    return u, v


def scattering(d, props: dict) -> np.ndarray:
    """sky_radiance_nishita: the sun disc where the direction is within half the sun's
    angular diameter of it and above the Earth's edge, plus the sky texture, to RGB."""
    multiple = props["sky_type"] == "MULTIPLE_SCATTERING"
    elevation, rotation = atmosphere.wrap_sun(props["sun_elevation"], props["sun_rotation"])
    size = max(float(props["sun_size"]), float(_F32(0.0005)))  # Cycles' get_sun_size
    dens = (float(props["altitude"]), float(props["air_density"]), float(props["aerosol_density"]),
            float(props["ozone_density"]))
    texture = (atmosphere.multiple_scattering_texture if multiple else atmosphere.single_scattering_texture)(
        elevation, *dens)
    theta, phi = _spherical(d)
    dir_elevation = np.pi / 2.0 - theta
    xyz = np.zeros(np.shape(theta) + (3,))
    if props["sun_disc"]:
        bottom, top = scattering_sun(multiple, elevation, size, *dens)
        sun = scattering_sun_direction(elevation, rotation)
        angle = 2.0 * np.arctan2(np.linalg.norm(d - sun, axis=-1), np.linalg.norm(d + sun, axis=-1))
        half = size * 0.5
        inside = (angle < half) & (dir_elevation > -atmosphere.earth_intersection_angle(dens[0]))
        y = ((dir_elevation - elevation) / size + 0.5)[..., None]
        limb = 1.0 - 0.6 * (1.0 - np.sqrt(np.maximum(1.0 - (angle / half) ** 2, 0.0)))
        disc = (bottom + y * (top - bottom)) * (float(props["sun_intensity"]) * limb)[..., None]
        xyz = np.where(inside[..., None], disc, 0.0)
    u, v = _texture_coordinates(theta, phi, rotation)
    xyz = xyz + image.lookup(texture, np.ravel(u), np.ravel(v), "LINEAR", "EXTEND").reshape(xyz.shape)
    return xyz_to_rgb(xyz)


_SETTINGS = ("sky_type", "sun_disc", "sun_size", "sun_intensity", "sun_elevation", "sun_rotation", "altitude",
             "air_density", "aerosol_density", "ozone_density", "sun_direction", "turbidity", "ground_albedo")
_DEFAULTS = {"sky_type": "MULTIPLE_SCATTERING", "sun_disc": True, "sun_size": 0.009512044489383698,
             "sun_intensity": 1.0, "sun_elevation": 0.2617993950843811, "sun_rotation": 0.0, "altitude": 100.0,
             "air_density": 1.0, "aerosol_density": 1.0, "ozone_density": 1.0, "sun_direction": (0.0, 0.0, 1.0),
             "turbidity": 2.2, "ground_albedo": 0.3}


def sky(kind: str, d, props: dict) -> np.ndarray:
    """RGB (..., 3) of sky `kind` in directions d (..., 3)."""
    if kind == "PREETHAM":
        return preetham(d, props["sun_direction"], props["turbidity"])
    if kind == "HOSEK_WILKIE":
        return hosek_wilkie(d, props["sun_direction"], props["turbidity"], props["ground_albedo"])
    return scattering(d, props)


@node("ShaderNodeTexSky", "Texture", reads=texture_mapping.unlinked_reads("generated"))
def sky_texture(node, inputs, state):
    d = texture_mapping.coordinate(node, inputs, state)
    props = {key: node.prop(key, _DEFAULTS[key]) for key in _SETTINGS}
    return {"Color": sky(props["sky_type"], d, props)}


NODES = (sky_texture,)
