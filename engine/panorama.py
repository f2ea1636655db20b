"""Panoramic projections as Cycles 5.0 makes them (kernel/camera/projection.h): the image
point (u, v) in [0, 1]^2 (u left to right, v bottom to top) -> a direction in Cycles'
panorama camera space, and back. Fisheyes, the central cylinder and the cube face look along
+x with +z up and +y to the image's left; the equirectangular map's centre is +x too; the
mirror ball looks along -y with +z up. PANORAMA_TO_CAMERA turns those into Blender's camera
space (x right, y up, looking down -z), as Cycles' Blender sync turns its camera matrix for a
panorama. Points outside the projection's image (beyond a fisheye's circle or field of view,
outside the mirror ball) have no direction: (0, 0, 0), which the camera makes a ray that
carries nothing (Cycles: the sample is not traced; the pixel is black and opaque).

Parameters (Camera fields), in Cycles' units: fisheye_fov (radians), fisheye_lens and sensor
(mm: the sensor after its fit to the image, as Cycles' sync gives it), pano_range (4,):
equirectangular (longitude min, max, latitude min, max) in radians; central cylindrical the
azimuths at u = 0 and u = 1 (Blender's U range negated: +y is the image's left) and the
heights over the radius at v = 0 and v = 1; polynomial (5,) k0..k4.
"""
from __future__ import annotations

import numpy as np

PANORAMAS = ("EQUIRECTANGULAR", "EQUIANGULAR_CUBEMAP_FACE", "MIRRORBALL", "FISHEYE_EQUIDISTANT",
             "FISHEYE_EQUISOLID", "FISHEYE_LENS_POLYNOMIAL", "CENTRAL_CYLINDRICAL")

# Cycles' panorama camera space -> Blender's camera space (columns: where x, y, z go).
_FORWARD_X = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])
_FORWARD_MINUS_Y = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])  # a mirror image


def panorama_to_camera(kind: str) -> np.ndarray:
    """(3,3) from Cycles' panorama camera space of `kind` to Blender's camera space."""
    return _FORWARD_MINUS_Y if kind == "MIRRORBALL" else _FORWARD_X


def _fisheye_direction(theta, x, y, r):
    """Cycles' fisheye_to_direction: polar angle theta from +x, azimuth of the sensor point (x, y)
    at radius r (x toward the image's right is -y)."""
    cos_phi = np.divide(x, r, out=np.zeros_like(x), where=r != 0)
    sin_phi = np.divide(y, r, out=np.ones_like(y), where=r != 0)
    s = np.sin(theta)
    return np.stack([np.cos(theta), -cos_phi * s, sin_phi * s], axis=1)


def _sensor_point(camera, u, v):
    w, h = (float(a) for a in camera.sensor)
    return (u - 0.5) * w, (v - 0.5) * h


def to_direction(camera, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Directions (N,3) (unit, or (0, 0, 0) where there is none) of image points u, v (N,)."""
    kind = camera.panorama
    u, v = np.asarray(u, np.float64), np.asarray(v, np.float64)
    if kind == "EQUIRECTANGULAR":
        lon_min, lon_max, lat_min, lat_max = (float(a) for a in camera.pano_range)
        phi = -lon_min - (lon_max - lon_min) * u
        theta = 0.5 * np.pi - lat_min - (lat_max - lat_min) * v
        return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=1)
    if kind == "EQUIANGULAR_CUBEMAP_FACE":
        d = np.stack([np.ones_like(u), np.tan((0.5 - u) * 0.5 * np.pi), np.tan((v - 0.5) * 0.5 * np.pi)], axis=1)
        return d / np.linalg.norm(d, axis=1, keepdims=True)
    if kind == "MIRRORBALL":
        x, z = 2.0 * u - 1.0, 2.0 * v - 1.0
        inside = x * x + z * z <= 1.0
        n = np.stack([x, -np.sqrt(np.maximum(1.0 - x * x - z * z, 0.0)), z], axis=1)  # the ball's normal
        d = 2.0 * (-n[:, 1:2]) * n - np.array([0.0, -1.0, 0.0])  # the view ray -y mirrored about it
        return np.where(inside[:, None], d, 0.0)
    if kind == "FISHEYE_EQUIDISTANT":
        x, y = 2.0 * (u - 0.5), 2.0 * (v - 0.5)
        r = np.hypot(x, y)
        d = _fisheye_direction(0.5 * r * float(camera.fisheye_fov), x, y, r)
        return np.where((r <= 1.0)[:, None], d, 0.0)
    if kind == "FISHEYE_EQUISOLID":
        x, y = _sensor_point(camera, u, v)
        r = np.hypot(x, y)
        lens = float(camera.fisheye_lens)
        inside = r <= 2.0 * lens * np.sin(0.25 * float(camera.fisheye_fov))
        theta = 2.0 * np.arcsin(np.minimum(r / (2.0 * lens), 1.0))
        return np.where(inside[:, None], _fisheye_direction(theta, x, y, r), 0.0)
    if kind == "FISHEYE_LENS_POLYNOMIAL":
        x, y = _sensor_point(camera, u, v)
        r = np.hypot(x, y)
        k = [float(a) for a in camera.polynomial]
        theta = -(k[0] + r * (k[1] + r * (k[2] + r * (k[3] + r * k[4]))))
        inside = np.abs(theta) <= 0.5 * float(camera.fisheye_fov)
        return np.where(inside[:, None], _fisheye_direction(theta, x, y, r), 0.0)
    if kind == "CENTRAL_CYLINDRICAL":
        a_min, a_max, h_min, h_max = (float(a) for a in camera.pano_range)
        azimuth, height = a_min + (a_max - a_min) * u, h_min + (h_max - h_min) * v
        d = np.stack([np.cos(azimuth), np.sin(azimuth), height], axis=1)
        return d / np.linalg.norm(d, axis=1, keepdims=True)
    raise ValueError(f"unknown panorama {kind!r}")


def from_direction(camera, d: np.ndarray):
    """(u, v) (N,) of directions d (N,3) in Cycles' panorama camera space (Cycles'
    direction_to_panorama): where the projection shows them."""
    kind = camera.panorama
    d = np.asarray(d, np.float64)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    if kind == "EQUIRECTANGULAR":
        lon_min, lon_max, lat_min, lat_max = (float(a) for a in camera.pano_range)
        u = (np.arctan2(d[:, 1], d[:, 0]) + lon_min) / (lon_min - lon_max)
        v = (np.arccos(np.clip(d[:, 2], -1.0, 1.0)) - 0.5 * np.pi + lat_min) / (lat_min - lat_max)
        return u, v
    if kind == "EQUIANGULAR_CUBEMAP_FACE":
        return 0.5 - np.arctan2(d[:, 1], d[:, 0]) * 2.0 / np.pi, np.arctan2(d[:, 2], d[:, 0]) * 2.0 / np.pi + 0.5
    if kind == "MIRRORBALL":
        h = d - np.array([0.0, 1.0, 0.0])  # along the ball's normal
        h = h / np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-300)
        return 0.5 * (h[:, 0] + 1.0), 0.5 * (h[:, 2] + 1.0)
    theta = np.arccos(np.clip(d[:, 0], -1.0, 1.0))
    side = np.hypot(d[:, 1], d[:, 2])
    ey = np.divide(d[:, 1], side, out=np.zeros_like(side), where=side > 0)
    ez = np.divide(d[:, 2], side, out=np.zeros_like(side), where=side > 0)
    if kind == "FISHEYE_EQUIDISTANT":
        r = theta / float(camera.fisheye_fov)
        return 0.5 - r * ey, 0.5 + r * ez
    w, h = (float(a) for a in camera.sensor)
    if kind == "FISHEYE_EQUISOLID":
        r = 2.0 * float(camera.fisheye_lens) * np.sin(0.5 * theta)
    elif kind == "FISHEYE_LENS_POLYNOMIAL":
        r = _polynomial_radius(camera, -theta)
    elif kind == "CENTRAL_CYLINDRICAL":
        a_min, a_max, h_min, h_max = (float(a) for a in camera.pano_range)
        height = d[:, 2] / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-300)
        return (np.arctan2(d[:, 1], d[:, 0]) - a_min) / (a_max - a_min), (height - h_min) / (h_max - h_min)
    else:
        raise ValueError(f"unknown panorama {kind!r}")
    return 0.5 - r * ey / w, 0.5 + r * ez / h


def _polynomial_radius(camera, theta):
    """The sensor radius r (mm) whose polynomial angle is theta (Newton's method from the
    linear term's root, as Cycles' direction_to_fisheye_lens_polynomial)."""
    k = [float(a) for a in camera.polynomial]
    r = (theta - k[0]) / k[1]
    for _ in range(20):
        f = theta - (k[0] + r * (k[1] + r * (k[2] + r * (k[3] + r * k[4]))))
        df = k[1] + r * (2.0 * k[2] + r * (3.0 * k[3] + r * 4.0 * k[4]))
        r = r + f / df
    return r


def defocus(camera, d: np.ndarray, lens: np.ndarray):
    """Cycles' panorama depth of field: rays from the aperture points lens (N,2) (metres, in the
    plane across each pinhole direction d (N,3) unit) toward the point focus_distance along d.
    Returns (origins (N,3), directions (N,3)) in the panorama camera space."""
    focus = d * float(camera.focus_distance)
    a = np.array([1.0, 0.0, 0.0]) - d[:, :1] * d
    along_x = np.linalg.norm(a, axis=1) < 1e-9  # d along +-x: any axis across it
    a[along_x] = [0.0, 1.0, 0.0]
    a = a / np.linalg.norm(a, axis=1, keepdims=True)
    b = np.cross(d, a)
    p = a * lens[:, :1] + b * lens[:, 1:2]
    out = focus - p
    return p, out / np.linalg.norm(out, axis=1, keepdims=True)
