"""Hard-case scenes with analytic answers, built as arrays (engine.scene; no bpy needed).

The hard-case suite (tests/test_hard_cases.py) renders these and the
Cycles-referenced .blend files of scenes/build_bench.py (tiny light, light touching a wall,
degenerate/duplicated triangles, near-mirror Phong, far origin, grazing floor). Each builder
returns (Scene, expected), where `expected` says what the image must be:

  glossy_enclosure   an orthographic camera looks straight down at a floor of Phong
                     exponent 1e6 or GGX roughness 0.001 (alpha 1e-6) inside a huge room whose
                     walls and ceiling are black emitters of radiance L0: every direction the
                     floor reflects sees L0, so at normal incidence the floor shows
                     albedo x L0 = ks L0 (Phong, exactly) or ~colour x L0 (GGX) in every pixel
  room               a closed diffuse room with a ceiling light and a block, all coordinates
                     multiples of 0.5 m, translated by `offset`: float32 holds it exactly up
                     to 1e6, so a translated render must equal the untranslated one
  grazing_plane      camera 5 cm above a 1 km diffuse plane (albedo a) under a constant sky L:
                     a plane sees only sky, so every path that hits it returns a L exactly
                     and every pixel lies in [a L, L]; pixels wholly below the horizon are a L
  sun_and_sky        a diffuse plane under a sky of radiance 1 and either an environment texel
                     1e5 times brighter or a delta sun of irradiance 1e5 x pi; the plane's
                     radiance is a / pi x (pi + the sun's irradiance): exact
  light_in_box       a closed diffuse box (albedo a) holding a 1 MW point light, under a
                     constant sky L: the box is convex, so its outside shows a L exactly and
                     any light leaking through its faces or edges is visible
  camera_in_box      the camera inside a closed opaque box, a bright sun and sky outside:
                     the image is exactly black
"""
from __future__ import annotations

import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
if "ember" not in sys.modules:  # run from the repository: load it as the package `ember`
    sys.path.insert(0, os.path.dirname(HERE))
    from _bootstrap import load_ember
    load_ember()

from ember.engine.scene import (FRESNEL_NONE, LIGHT_POINT, LIGHT_SUN, LOBE_MICROFACET, MAT_DIFFUSE,  # noqa: E402
                                MAT_EMISSION_ONLY, MAT_NODES, MAT_PHONG, Camera, Lights, Materials, Mesh,
                                Scene, Settings, World)


def look_at(eye, target, up=(0, 0, 1)) -> np.ndarray:
    """world_from_camera (4,4) for a camera at eye looking at target (it looks down -z)."""
    eye, target, up = (np.asarray(v, np.float64) for v in (eye, target, up))
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross(up, back)
    if np.linalg.norm(right) < 1e-9:
        right = np.cross((0, 1, 0), back)
    right /= np.linalg.norm(right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, np.cross(back, right), back, eye
    return m


def perspective(eye, target, fov_deg=40.0, **kw) -> Camera:
    h = np.tan(np.radians(fov_deg) / 2)
    return Camera(world_from_camera=look_at(eye, target, kw.pop("up", (0, 0, 1))),
                  window=np.array([-h, h, -h, h]), **kw)


def quads_mesh(quads, material_ids) -> Mesh:
    """quads (Q,4,3) corners in order -> two triangles each, flat normals from the winding."""
    v = np.asarray(quads, np.float64).reshape(-1, 3)
    b = 4 * np.arange(len(quads))[:, None]
    tris = np.concatenate([b + [0, 1, 2], b + [0, 2, 3]], axis=1).reshape(-1, 3).astype(np.int32)
    p = v[tris]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return Mesh(v.astype(np.float32), tris, np.repeat(n[:, None], 3, axis=1).astype(np.float32),
                np.repeat(np.asarray(material_ids, np.int32), 2))


def box_quads(lo, hi, inward=False) -> np.ndarray:
    """The six faces of an axis-aligned box, normals outward (inward for a room)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    q = np.array([
        [[x0, y0, z0], [x0, y1, z0], [x1, y1, z0], [x1, y0, z0]],  # -z
        [[x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]],  # +z
        [[x0, y0, z0], [x1, y0, z0], [x1, y0, z1], [x0, y0, z1]],  # -y
        [[x0, y1, z0], [x0, y1, z1], [x1, y1, z1], [x1, y1, z0]],  # +y
        [[x0, y0, z0], [x0, y0, z1], [x0, y1, z1], [x0, y1, z0]],  # -x
        [[x1, y0, z0], [x1, y1, z0], [x1, y1, z1], [x1, y0, z1]],  # +x
    ], np.float64)
    return q[:, ::-1] if inward else q


def settings(**kw) -> Settings:
    """Small, independent samples (honest per-pixel variances for the z-tests)."""
    base = dict(width=32, height=32, samples=16, seed=1, filter="BOX", filter_width=1.0, batch_size=1 << 15,
                pattern="random", threads=1, integrator="path")  # the core's default is auto
    base.update(kw)
    return Settings(**base)


# ---- scenes -------------------------------------------------------------------------------
L0 = 1.0


def glossy_enclosure(lobe: str, **kw):
    """lobe 'phong' (kd 0, ks 0.7, n 1e6) or 'ggx' (Glossy colour 0.7, roughness 0.001)."""
    albedo = 0.7
    walls = box_quads((-50, -50, 0), (50, 50, 100), inward=True)
    if lobe == "phong":
        floor = dict(kind=MAT_PHONG, phong=((0.0,) * 3, (albedo,) * 3, 1e6), name="phong_1e6")
    else:
        floor = dict(kind=MAT_NODES, name="ggx_0.001", base_color=(albedo,) * 3,
                     lobes=[dict(kind=LOBE_MICROFACET, color=(albedo,) * 3, roughness=0.001, fresnel=FRESNEL_NONE)])
    mats = Materials.make([floor, dict(kind=MAT_EMISSION_ONLY, emission=(L0,) * 3, name="emitter")])
    mesh = quads_mesh(walls, [0, 1, 1, 1, 1, 1])
    cam = Camera(world_from_camera=look_at((0.3, 0.2, 5.0), (0.3, 0.2, 0.0), up=(0, 1, 0)),
                 window=np.array([-1.0, 1.0, -1.0, 1.0]), ortho=True)
    return Scene(mesh, mats, Lights.make([]), World(), cam, settings(**kw)), albedo * L0


ROOM_LIGHT = 20.0


def room(offset=0.0, **kw):
    """A 4 x 4 x 3 m closed room with a 1 x 1 m ceiling light and a 1 x 1 x 1.5 m block;
    every coordinate is a multiple of 0.5 m (exact in float32 up to |x| ~ 4e6)."""
    o = np.float64(offset)
    quads = np.concatenate([box_quads((-2, -2, 0), (2, 2, 3), inward=True),
                            box_quads((0.0, 0.0, 0.0), (1.0, 1.0, 1.5)),
                            [[[-0.5, -0.5, 2.5], [0.5, -0.5, 2.5], [0.5, 0.5, 2.5], [-0.5, 0.5, 2.5]]]])
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(0.7, 0.6, 0.5), name="wall"),
                           dict(kind=MAT_DIFFUSE, base_color=(0.2, 0.5, 0.8), name="block"),
                           dict(kind=MAT_EMISSION_ONLY, emission=(ROOM_LIGHT,) * 3, name="light")])
    mesh = quads_mesh(quads + o, [0] * 6 + [1] * 6 + [2])
    cam = perspective(np.array([-1.5, -1.5, 1.5]) + o, np.array([0.5, 0.5, 0.5]) + o, 70.0)
    return Scene(mesh, mats, Lights.make([]), World(), cam, settings(**kw))


SKY = 0.8


def grazing_plane(**kw):
    """1 km x 1 km plane (albedo 0.5) under a constant sky; the camera 5 cm above it looks
    0.5 degrees down. Returns (scene, (a L, L))."""
    a = 0.5
    h = 500.0
    mesh = quads_mesh([[[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]]], [0])
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(a,) * 3, name="ground")])
    eye = np.array([3.0, -400.0, 0.05])
    target = eye + np.array([0.0, np.cos(np.radians(0.5)), -np.sin(np.radians(0.5))])
    cam = perspective(eye, target, 10.0)
    return Scene(mesh, mats, Lights.make([]), World(color=np.full(3, SKY)), cam, settings(**kw)), (a * SKY, SKY)


SUN_RATIO = 1e5


def sun_and_sky(kind: str, **kw):
    """kind 'texel': an equirectangular sky of radiance 1 with one texel of 1e5;
    kind 'delta': a sky of 1 and a delta sun of irradiance 1e5 x pi at 30 degrees from the
    zenith. A diffuse plane (albedo 0.5) seen from above; returns (scene, exact radiance)."""
    a = 0.5
    mesh = quads_mesh([[[-50, -50, 0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]]], [0])
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(a,) * 3, name="ground")])
    cam = perspective((0.0, -1.0, 2.0), (0.0, 0.0, 0.0), 30.0)
    lights = Lights.make([])
    if kind == "texel":
        H, W, row = 32, 64, 5
        image = np.ones((H, W, 3), np.float32)
        image[row, 17] = SUN_RATIO  # rows from the top: row 5 spans theta in [5, 6] pi / 32
        world = World(color=np.ones(3), image=image)
        t0, t1 = row * np.pi / H, (row + 1) * np.pi / H
        # Irradiance on +z: pi from the unit sky's upper half, plus the texel's excess,
        # integral of cos over the texel = (2 pi / W) (sin^2 t1 - sin^2 t0) / 2.
        E = np.pi + (SUN_RATIO - 1.0) * (2 * np.pi / W) * 0.5 * (np.sin(t1) ** 2 - np.sin(t0) ** 2)
    else:
        zen = np.radians(30.0)
        z = np.array([0.0, np.sin(zen), np.cos(zen)])  # the sun's +z points at the sun
        x = np.array([1.0, 0.0, 0.0])
        frame = np.stack([x, np.cross(z, x), z])
        E_sun = SUN_RATIO * np.pi
        lights = Lights.make([dict(kind=LIGHT_SUN, Le=(E_sun,) * 3, sun_half_angle=0.0, frame=frame, name="sun")])
        world = World(color=np.ones(3))
        E = np.pi + E_sun * np.cos(zen)
    return Scene(mesh, mats, lights, world, cam, settings(**kw)), a / np.pi * E


def light_in_box(**kw):
    """A closed 1 m box (albedo 0.5) with a 1 MW point light inside, floating in a constant
    sky. Returns (scene, (a L, L))."""
    a = 0.5
    mesh = quads_mesh(box_quads((-0.5, -0.5, -0.5), (0.5, 0.5, 0.5)), [0] * 6)
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(a,) * 3, name="box")])
    lights = Lights.make([dict(kind=LIGHT_POINT, position=(0.1, -0.2, 0.05), Le=(1e6 / (4 * np.pi),) * 3,
                               name="caged")])
    cam = perspective((2.0, -2.5, 1.5), (0.0, 0.0, 0.0), 35.0)
    return Scene(mesh, mats, lights, World(color=np.full(3, SKY)), cam, settings(**kw)), (a * SKY, SKY)


def camera_in_box(**kw):
    """The camera inside a closed diffuse box; a sun and a sky outside. The image is black."""
    mesh = quads_mesh(box_quads((-1, -1, -1), (1, 1, 1)), [0] * 6)
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(0.8,) * 3, name="box")])
    lights = Lights.make([dict(kind=LIGHT_SUN, Le=(1e4,) * 3, sun_half_angle=0.01, frame=np.eye(3), name="sun")])
    cam = perspective((0.2, -0.3, 0.1), (0.0, 1.0, -0.2), 90.0)
    return Scene(mesh, mats, lights, World(color=np.full(3, 2.0)), cam, settings(**kw))
