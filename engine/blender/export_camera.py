"""Scene camera -> Camera (world_from_camera without scale, image window).

The window follows Blender's BKE_camera_params_compute_viewplane (which Cycles'
blender/camera.cpp reproduces): the sensor (perspective) or ortho_scale (orthographic)
spans the fitted image dimension; AUTO fits the larger of width*pixel_aspect_x and
height*pixel_aspect_y (horizontal on ties); the other dimension follows the image aspect
including pixel aspect; shift moves the window by shift * (fitted extent).
Tests check it against Object.calc_matrix_camera.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import EmberError
from ..panorama import PANORAMAS
from ..scene import Camera


def camera_window(*, ortho: bool, lens: float, sensor_width: float, sensor_height: float,
                  sensor_fit: str, ortho_scale: float, shift_x: float, shift_y: float,
                  width: int, height: int, pixel_aspect_x: float = 1.0,
                  pixel_aspect_y: float = 1.0) -> np.ndarray:
    """(left, right, bottom, top): at z = -1 for perspective, in metres for orthographic."""
    ycor = pixel_aspect_y / pixel_aspect_x
    if sensor_fit == "AUTO":
        horizontal = pixel_aspect_x * width >= pixel_aspect_y * height
        sensor = sensor_width
    elif sensor_fit == "HORIZONTAL":
        horizontal, sensor = True, sensor_width
    elif sensor_fit == "VERTICAL":
        horizontal, sensor = False, sensor_height
    else:
        raise EmberError(f"Unknown camera sensor fit '{sensor_fit}'.")
    extent = ortho_scale if ortho else sensor / lens  # of the fitted dimension
    viewfac = width if horizontal else ycor * height  # fitted dimension in 'pixels'
    pix = extent / viewfac
    dx = shift_x * viewfac
    dy = shift_y * viewfac
    return np.array([(-0.5 * width + dx) * pix, (0.5 * width + dx) * pix,
                     (-0.5 * ycor * height + dy) * pix, (0.5 * ycor * height + dy) * pix],
                    np.float64)


def world_from_camera_matrix(matrix_world) -> np.ndarray:
    """4x4 float64 with the scale removed (unit axis columns), like Cycles'
    transform_clear_scale."""
    m = np.array(matrix_world, np.float64).reshape(4, 4)
    norms = np.linalg.norm(m[:3, :3], axis=0)
    if not np.all(norms > 0) or not np.all(np.isfinite(m)):
        raise EmberError("The camera has a zero or invalid scale; reset its scale to 1.")
    m[:3, :3] /= norms
    return m


def export_camera(depsgraph, scene, settings, warn) -> Camera:
    """The scene camera (evaluated). Raises EmberError if missing or of an unsupported type."""
    cam_ob = scene.camera
    if cam_ob is None:
        raise EmberError("The scene has no camera; add one and make it the active camera "
                         "(Scene Properties > Camera).")
    cam_ob = cam_ob.evaluated_get(depsgraph) if not cam_ob.is_evaluated else cam_ob
    if cam_ob.type != "CAMERA":
        raise EmberError(f"The scene camera '{cam_ob.name}' is not a camera object.")
    cam = cam_ob.data
    if cam.type == "PANO":
        return _panoramic(cam_ob, scene, settings, warn)
    if cam.type not in ("PERSP", "ORTHO"):
        raise EmberError(f"Camera '{cam_ob.name}' has type {cam.type}; Ember supports "
                         "perspective, orthographic and panoramic cameras.")
    ortho = cam.type == "ORTHO"
    if not ortho and not cam.lens > 0:
        raise EmberError(f"Camera '{cam_ob.name}' has a focal length of {cam.lens} mm; it must be positive.")
    if ortho and not cam.ortho_scale > 0:
        raise EmberError(f"Camera '{cam_ob.name}' has an orthographic scale of {cam.ortho_scale}; it must be positive.")

    render = scene.render
    window = camera_window(
        ortho=ortho, lens=cam.lens, sensor_width=cam.sensor_width, sensor_height=cam.sensor_height,
        sensor_fit=cam.sensor_fit, ortho_scale=cam.ortho_scale, shift_x=cam.shift_x,
        shift_y=cam.shift_y, width=settings.width, height=settings.height,
        pixel_aspect_x=render.pixel_aspect_x, pixel_aspect_y=render.pixel_aspect_y)

    if render.use_motion_blur:
        warn("Motion blur is not supported yet: the image is rendered without it.")

    clip_start, clip_end = float(cam.clip_start), float(cam.clip_end)
    if not (math.isfinite(clip_start) and math.isfinite(clip_end) and clip_end > clip_start):
        raise EmberError(f"Camera '{cam_ob.name}' has invalid clipping ({clip_start}, {clip_end}).")
    world_from_camera = world_from_camera_matrix(cam_ob.matrix_world)
    return Camera(world_from_camera=world_from_camera, window=window, ortho=ortho, clip_start=clip_start,
                  clip_end=clip_end, **lens_settings(cam_ob, world_from_camera))


def fitted_sensor(cam, aspect_x: float, aspect_y: float) -> tuple:
    """(width, height) mm of the camera's sensor fitted to an image of aspect_x : aspect_y as
    Cycles' sync fits a panorama's: the fitted side the sensor's size, the other by the aspect."""
    fit = cam.sensor_fit
    horizontal = aspect_x >= aspect_y if fit == "AUTO" else fit == "HORIZONTAL"
    size = float(cam.sensor_height if fit == "VERTICAL" else cam.sensor_width)
    return (size, size * aspect_y / aspect_x) if horizontal else (size * aspect_x / aspect_y, size)


def _panoramic(cam_ob, scene, settings, warn) -> Camera:
    """A panoramic camera as Cycles' Blender sync sets it up (engine/panorama.py): the window
    is the image's (u, v) square; a fisheye of sensor and lens has its sensor fitted to the
    image as a perspective camera's is (the fitted side the sensor's size, the other one by
    the image's aspect)."""
    cam = cam_ob.data
    kind = cam.panorama_type
    if kind not in PANORAMAS:
        raise EmberError(f"Camera '{cam_ob.name}' has the panorama type {kind}, which Ember does not support.")
    render = scene.render
    if cam.shift_x or cam.shift_y:
        warn(f"Camera '{cam_ob.name}': lens shift is ignored on panoramic cameras.")
    if render.use_motion_blur:
        warn("Motion blur is not supported yet: the image is rendered without it.")
    sensor = fitted_sensor(cam, settings.width * render.pixel_aspect_x, settings.height * render.pixel_aspect_y)
    if kind == "EQUIRECTANGULAR":
        pano_range = (cam.longitude_min, cam.longitude_max, cam.latitude_min, cam.latitude_max)
    elif kind == "CENTRAL_CYLINDRICAL":
        radius = max(float(cam.central_cylindrical_radius), 1e-6)
        pano_range = (-cam.central_cylindrical_range_u_min, -cam.central_cylindrical_range_u_max,
                      cam.central_cylindrical_range_v_min / radius, cam.central_cylindrical_range_v_max / radius)
    else:
        pano_range = Camera.pano_range
    pano_range = tuple(float(a) for a in pano_range)
    if not (all(math.isfinite(a) for a in pano_range) and pano_range[0] != pano_range[1]
            and pano_range[2] != pano_range[3]):
        raise EmberError(f"Camera '{cam_ob.name}' has an empty panorama range {pano_range}.")
    polynomial = tuple(float(getattr(cam, f"fisheye_polynomial_k{i}")) for i in range(5))
    if kind == "FISHEYE_LENS_POLYNOMIAL" and polynomial[1] == 0.0:
        raise EmberError(f"Camera '{cam_ob.name}': its fisheye polynomial has no linear term (k1 = 0).")
    if kind == "FISHEYE_EQUISOLID" and not cam.fisheye_lens > 0:
        raise EmberError(f"Camera '{cam_ob.name}' has a fisheye lens of {cam.fisheye_lens} mm; it must be positive.")
    clip_start, clip_end = float(cam.clip_start), float(cam.clip_end)
    if not (math.isfinite(clip_start) and math.isfinite(clip_end) and clip_end > clip_start):
        raise EmberError(f"Camera '{cam_ob.name}' has invalid clipping ({clip_start}, {clip_end}).")
    world_from_camera = world_from_camera_matrix(cam_ob.matrix_world)
    return Camera(world_from_camera=world_from_camera, window=np.array([0.0, 1.0, 0.0, 1.0]), clip_start=clip_start,
                  clip_end=clip_end, panorama=kind, fisheye_fov=float(cam.fisheye_fov),
                  fisheye_lens=float(cam.fisheye_lens), sensor=tuple(float(a) for a in sensor), pano_range=pano_range,
                  polynomial=polynomial, **lens_settings(cam_ob, world_from_camera))


def lens_settings(cam_ob, world_from_camera) -> dict:
    """Camera thin-lens fields from Blender's depth of field, as Cycles' blender/camera.cpp
    reads them: radius = lens / (2 f-stop) in metres (1 / (2 f-stop) for orthographic), the
    focus distance from the focus object's distance along the view axis when there is one,
    blades < 3 = a round aperture."""
    cam = cam_ob.data
    dof = getattr(cam, "dof", None)
    if dof is None or not dof.use_dof:
        return {}
    fstop = max(float(dof.aperture_fstop), 1e-5)
    radius = 1.0 / (2.0 * fstop) if cam.type == "ORTHO" else cam.lens * 1e-3 / (2.0 * fstop)
    focus = float(dof.focus_distance)
    target = dof.focus_object
    if target is not None:
        to_camera = world_from_camera[:3, 3] - np.array(target.matrix_world.translation, np.float64)
        focus = abs(float(np.dot(world_from_camera[:3, 2], to_camera)))
    ratio = float(dof.aperture_ratio)
    if not (math.isfinite(radius) and ratio > 0 and math.isfinite(ratio)):
        raise EmberError(f"Camera '{cam_ob.name}' has an invalid aperture (f-stop {dof.aperture_fstop}, "
                         f"ratio {dof.aperture_ratio}).")
    blades = int(dof.aperture_blades)
    return dict(aperture_radius=radius, focus_distance=max(focus, 1e-5), blades=blades if blades >= 3 else 0,
                blade_rotation=float(dof.aperture_rotation), aperture_ratio=ratio)
