"""Camera rays: pixel + filter offset -> world-space ray, clipped like Cycles.

Pixel (x, y) counts from the top-left; the image rectangle `Camera.window` maps pixel
edges 0..W, 0..H to left..right, top..bottom. Clipping is planar along the view axis
(Cycles' camera: near/far clip divided by the ray's cosine to the view axis).
"""
from __future__ import annotations

import numpy as np

from . import sampling
from .scene import Camera, Settings
from .vec import normalize, scale


def generate_rays(camera: Camera, settings: Settings, px: np.ndarray, py: np.ndarray, u_filter: np.ndarray):
    """px, py (N,) integer pixel coordinates; u_filter (N,2).
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
    if camera.ortho:
        d_cam = np.broadcast_to([0.0, 0.0, -1.0], (n, 3))
        o_cam = np.stack([x, y, np.full(n, -camera.clip_start)], axis=1)
        cos_axis = np.ones(n)
    else:
        inv_len = 1.0 / np.sqrt(x * x + y * y + 1.0)
        d_cam = np.stack([x * inv_len, y * inv_len, -inv_len], axis=1)
        cos_axis = inv_len
        o_cam = scale(d_cam, camera.clip_start / cos_axis)
    o = o_cam @ rot.T + eye
    d = normalize(d_cam @ rot.T)  # rot may carry the object's scale
    tmax = (camera.clip_end - camera.clip_start) / cos_axis
    return o, d, tmax
