"""Camera rays: pixel + filter offset -> world-space ray, clipped like Cycles.

Pixel (x, y) counts from the top-left; the image rectangle `Camera.window` maps pixel
edges 0..W, 0..H to left..right, top..bottom. Clipping is planar along the view axis
(Cycles' camera: near/far clip divided by the ray's cosine to the view axis).
"""
from __future__ import annotations

import numpy as np

from . import sampling
from .scene import Camera, Settings


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
        d_cam = np.stack([x, y, -np.ones(n)], axis=1)
        d_cam = d_cam / np.linalg.norm(d_cam, axis=1, keepdims=True)
        cos_axis = -d_cam[:, 2]
        o_cam = d_cam * (camera.clip_start / cos_axis)[:, None]
    o = o_cam @ rot.T + eye
    d = d_cam @ rot.T
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    tmax = (camera.clip_end - camera.clip_start) / cos_axis
    return o, d, tmax
