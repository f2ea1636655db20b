"""Camera rays: pixel + filter offset -> world-space ray, clipped like Cycles.

Pixel (x, y) counts from the top-left; the image rectangle `Camera.window` maps pixel
edges 0..W, 0..H to left..right, top..bottom. Clipping is planar along the view axis
(Cycles' camera: near/far clip divided by the ray's cosine to the view axis).

Panoramic cameras (engine/panorama.py) map the pixel's point in [0, 1]^2 to a direction
and clip along the ray (Cycles' camera_sample_panorama).

Depth of field follows Cycles' thin lens (kernel/camera/camera.h): a point on the aperture
(a disk, or a regular polygon of `blades` corners, x divided by the anamorphic ratio) times
the aperture radius; the ray leaves it toward the point where the pinhole ray meets the
plane of focus, and is clipped as the pinhole ray would be. The lens has its own random
group (LENS_GROUP), drawn only when the aperture is open, so pinhole images do not change.
"""
from __future__ import annotations

import numpy as np

from . import panorama, sampling
from .scene import Camera, Settings
from .vec import normalize, scale


# rng.Sampler group of the lens sample; far above the groups integrators count per bounce.
LENS_GROUP = 1 << 16


def camera_rays(camera: Camera, settings: Settings, px: np.ndarray, py: np.ndarray, sampler):
    """generate_rays with the pixel filter from group 0 and the lens from LENS_GROUP."""
    u_lens = sampler.get(LENS_GROUP, None, 2) if camera.aperture_radius > 0 else None
    return generate_rays(camera, settings, px, py, sampler.get(0, None, 2), u_lens)


def cycles_frame(camera: Camera) -> np.ndarray:
    """(4,4) Cycles' camera-to-world (no scale): its camera space looks down +z (Blender's
    camera looks down -z), a panorama's is the projection's (engine/panorama.py). What the
    Camera texture coordinates and the Vector Transform's camera space are in."""
    turn = np.eye(4)
    turn[:3, :3] = panorama.panorama_to_camera(camera.panorama) if camera.panorama else np.diag([1.0, 1.0, -1.0])
    m = np.asarray(camera.world_from_camera, np.float64) @ turn
    m[:3, :3] /= np.linalg.norm(m[:3, :3], axis=0)
    return m


def pixel_angle(camera: Camera, settings: Settings) -> float:
    """A pixel's width at the image's centre: radians (perspective: at unit distance; a
    panorama: between the directions of the two middle pixels), metres for orthographic."""
    left, right = (float(v) for v in camera.window[:2])
    if not camera.panorama:
        return abs(right - left) / max(settings.width, 1)
    u = 0.5 + np.array([-0.5, 0.5]) / max(settings.width, 1)
    d = panorama.to_direction(camera, u, np.full(2, 0.5))
    return float(np.arccos(np.clip(np.dot(d[0], d[1]), -1.0, 1.0)))


def sample_aperture(camera: Camera, u: np.ndarray) -> np.ndarray:
    """Points (N,2) on the aperture in camera x, y (metres) from u (N,2): Cycles'
    camera_sample_aperture (uniform disk, or regular_polygon_sample's uniform point in one of
    `blades` triangles around the centre) scaled by the radius, x divided by the ratio."""
    if camera.blades >= 3:
        corners = float(camera.blades)
        c = np.floor(u[:, 0] * corners)
        s = np.sqrt(u[:, 0] * corners - c)  # reused u: uniform in [0, 1) within the corner
        a, b = 1.0 - s, u[:, 1] * s  # uniform barycentrics of the triangle (0, c1, c2)
        half = np.pi / corners
        x, y = (a + b) * np.cos(half), (a - b) * np.sin(half)
        rot = camera.blade_rotation + c * 2.0 * half
        cr, sr = np.cos(rot), np.sin(rot)
        p = np.stack([cr * x - sr * y, sr * x + cr * y], axis=1)
    else:
        p = sampling.sample_concentric_disk(u)
    p = p * camera.aperture_radius
    p[:, 0] /= camera.aperture_ratio
    return p


def generate_rays(camera: Camera, settings: Settings, px: np.ndarray, py: np.ndarray, u_filter: np.ndarray,
                  u_lens: np.ndarray = None):
    """px, py (N,) integer pixel coordinates; u_filter (N,2); u_lens (N,2) or None (pinhole).
    Returns origins (N,3), unit directions (N,3), tmax (N,) (distance to the far clip)."""
    offset = sampling.sample_pixel_filter(settings.filter, settings.filter_width, u_filter)
    fx = (px + 0.5 + offset[:, 0]) / settings.width
    fy = (py + 0.5 + offset[:, 1]) / settings.height
    left, right, bottom, top = camera.window
    x = left + (right - left) * fx
    y = top + (bottom - top) * fy
    m = np.asarray(camera.world_from_camera, np.float64)
    rot, eye = m[:3, :3], m[:3, 3]
    n = len(px)
    if camera.panorama:
        return _panorama_rays(camera, x, y, u_lens, rot, eye)
    if camera.ortho:
        d_cam = np.broadcast_to([0.0, 0.0, -1.0], (n, 3))
        o_cam = np.stack([x, y, np.full(n, -camera.clip_start)], axis=1)
        cos_axis = np.ones(n)
    else:
        inv_len = 1.0 / np.sqrt(x * x + y * y + 1.0)
        d_cam = np.stack([x * inv_len, y * inv_len, -inv_len], axis=1)
        cos_axis = inv_len
        o_cam = scale(d_cam, camera.clip_start / cos_axis)
    if u_lens is not None and camera.aperture_radius > 0:
        lens = np.zeros((n, 3))
        lens[:, :2] = sample_aperture(camera, u_lens)
        # The pinhole ray meets the plane of focus (z = -focus_distance) at `focus`.
        focus = (np.stack([x, y, np.full(n, -1.0)], axis=1) * camera.focus_distance if not camera.ortho
                 else o_cam + d_cam * (camera.focus_distance - camera.clip_start))
        if camera.ortho:
            lens[:, :2] += o_cam[:, :2]
        d_cam = normalize(focus - lens)
        # Clipped where the pinhole ray would be: clip_start / cos along the new direction
        # (Cycles: nearclip * z_inv of the pinhole ray; orthographic: at the near plane).
        start = camera.clip_start / cos_axis if not camera.ortho else camera.clip_start / -d_cam[:, 2]
        o_cam = lens + scale(d_cam, start)
    o = o_cam @ rot.T + eye
    d = normalize(d_cam @ rot.T)  # rot may carry the object's scale
    tmax = (camera.clip_end - camera.clip_start) / cos_axis
    return o, d, tmax


def _panorama_rays(camera: Camera, u, v, u_lens, rot, eye):
    """Cycles' camera_sample_panorama: the projection's direction of image point (u, v) (N,),
    depth of field about it, the origin moved to the near clip along the ray and the far clip
    at clip_end - clip_start along it. A point without a direction (outside a fisheye's
    circle) gets a ray of length 0 along the view axis: it finds nothing and its path carries
    nothing (tmax 0 marks it)."""
    d = panorama.to_direction(camera, u, v)
    valid = np.any(d != 0.0, axis=1)
    o = np.zeros_like(d)
    if u_lens is not None and camera.aperture_radius > 0 and valid.any():
        o[valid], d[valid] = panorama.defocus(camera, d[valid], sample_aperture(camera, u_lens[valid]))
    turn = panorama.panorama_to_camera(camera.panorama)
    d[~valid] = turn.T @ np.array([0.0, 0.0, -1.0])
    d = normalize((d @ turn.T) @ rot.T)
    o = (o @ turn.T) @ rot.T + eye + d * camera.clip_start
    tmax = np.where(valid, camera.clip_end - camera.clip_start, 0.0)
    return o, d, tmax
