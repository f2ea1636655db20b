"""Layout of Veach's multiple-importance test scene (no bpy: shared by the .blend builder and
the core-array test). After Veach 1997 fig. 9.2 and Bitterli's port (algorithms.md sec. 3;
jgarciapueyo/mitsuba2-transient-scenes veach-mis): four glossy plates of increasing roughness,
four sphere lights of very different radii and equal power, direct light only.

Blender space, Z up. The camera looks along +Y at the plates; plate i (0 = nearest) is
tilted about X so that its normal bisects the directions to the camera and to the middle of
the light row, so every plate mirrors the whole row of lights toward the camera.
"""
import numpy as np

ALPHAS = (0.01, 0.05, 0.1, 0.25)  # Beckmann roughness of the plates, nearest first
PHONG_EXPONENTS = tuple(2.0 / a**2 - 2.0 for a in ALPHAS)  # 19998, 798, 198, 30
PLATE_REFLECTANCE = 0.3  # specular reflectance of the plates
BACKDROP_ALBEDO = 0.5
RADII = (0.03, 0.1, 0.3, 0.9)  # sphere lights, left to right
LIGHT_X = (-2.7, -0.9, 0.9, 2.7)
LIGHT_YZ = (3.5, 3.8)
POWER = 40.0  # W per light (Blender point-light power; radiance P / (pi 4 pi r^2))
CAMERA = dict(position=(0.0, -8.0, 3.6), target=(0.0, 0.4, 1.1), lens_mm=42.0, sensor_mm=36.0)
PLATE_WIDTH, PLATE_DEPTH, PLATE_STEP = 5.0, 0.9, (1.05, 0.45)  # step in (y, z) per plate
BACKDROP = [(-9.0, 6.0, -1.0), (9.0, 6.0, -1.0), (9.0, 6.0, 9.0), (-9.0, 6.0, 9.0)]


def lights() -> np.ndarray:
    """Light centres (4,3)."""
    y, z = LIGHT_YZ
    return np.array([(x, y, z) for x in LIGHT_X])


def plates() -> np.ndarray:
    """Plate quads (4,4,3), corners counter-clockwise seen from the side they face."""
    cam = np.array(CAMERA["position"])
    mid = lights().mean(axis=0)
    quads = []
    for i in range(4):
        c = np.array([0.0, -0.8 + i * PLATE_STEP[0], 0.4 + i * PLATE_STEP[1]])
        n = (cam - c) / np.linalg.norm(cam - c) + (mid - c) / np.linalg.norm(mid - c)
        n[0] = 0.0
        n /= np.linalg.norm(n)
        along = np.cross(n, [1.0, 0.0, 0.0])  # in the Y-Z plane, up the slope
        hx, hd = np.array([PLATE_WIDTH / 2, 0.0, 0.0]), along * PLATE_DEPTH / 2
        q = [c - hx - hd, c + hx - hd, c + hx + hd, c - hx + hd]
        if np.dot(np.cross(q[1] - q[0], q[2] - q[0]), n) < 0:
            q = q[::-1]
        quads.append(q)
    return np.array(quads)
