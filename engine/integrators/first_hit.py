"""What the camera ray of a sample first hits, for every integrator: alpha (film
transparency) and the "hit" render passes (engine/passes.py).

The ray is the integrators' own camera ray (the same pixel-filter numbers, group 0 of the
camera stream), traced once more: one Embree call per batch, and only when the render asks
for a hit pass or a transparent film.
"""
from __future__ import annotations

import numpy as np

from .. import camera as camera_mod
from .. import passes as passes_mod
from ..bsdf.fast_path import make_closure, plain_lambert_albedo
from ..nodes.material import MaterialPrograms
from ..scene import HOLDOUT, RAY_CAMERA, Scene
from ..vec import take
from ..visibility import RayVisibility
from .surface import flat_normals, shading_frame


def computes_alpha(scene: Scene) -> bool:
    """Whether the film keeps an alpha: a transparent film, or holdouts (Holdout objects and
    materials cut holes in the alpha whatever the film: Cycles' holdout writes to it)."""
    vis = scene.mesh.visibility
    return bool(scene.settings.film_transparent or np.any(scene.materials.holdout > 0)
                or (vis is not None and np.any(vis & HOLDOUT)))


class FirstHit:
    def __init__(self, scene: Scene, accel):
        s = scene.settings
        self.scene, self.accel = scene, accel
        self.wanted = tuple(n for n in s.passes if n in passes_mod.HIT)
        self.alpha = computes_alpha(scene)
        self.background_alpha = 0.0 if s.film_transparent else 1.0  # of camera rays that find nothing
        self.holdout = scene.materials.holdout if np.any(scene.materials.holdout > 0) else None
        # Objects hidden from camera rays, holdouts (Cycles: alpha 0 there): only when the scene has them.
        self.visibility = RayVisibility(accel, scene.mesh) if scene.mesh.visibility is not None else None
        self.lambert_albedo = plain_lambert_albedo(scene.materials)
        self.programs = MaterialPrograms.of(scene.materials)
        self.flat_normal = flat_normals(scene.mesh)
        m = np.asarray(scene.camera.world_from_camera, np.float64)
        self.eye = m[:3, 3]
        rot = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)  # without the camera object's scale
        self.forward = -rot[:, 2]
        # Cycles' camera space: x right, y up, z forward (Blender's camera looks down -z).
        self.camera_from_world = rot.T * np.array([1.0, 1.0, -1.0])[:, None]

    def passes(self, sampler, px: np.ndarray, py: np.ndarray) -> dict:
        """name -> (N, channels) for the paths of one batch (pixels px, py)."""
        s, n = self.scene.settings, len(px)
        o64, d, tmax = camera_mod.camera_rays(self.scene.camera, s, px, py, sampler)  # the lens too
        if self.visibility is None:
            hit = self.accel.intersect(o64.astype(np.float32), d, tmax, np.full(n, -1, np.int64))
        else:
            hit = self.visibility.intersect(o64.astype(np.float32), d, tmax, np.full(n, -1, np.int64),
                                            np.full(n, RAY_CAMERA, np.uint8))
        found = hit.prim >= 0
        out = {}
        if self.alpha:
            # Outside a panorama's image: black and opaque (Cycles traces nothing there).
            alpha = np.where(found, 1.0, np.where(tmax <= 0.0, 1.0, self.background_alpha))
            if self.visibility is not None and self.visibility.holdout is not None:
                alpha = np.where(found & self.visibility.holdout[np.maximum(hit.prim, 0)], 0.0, alpha)
            if self.holdout is not None:  # Cycles: transparency += the holdout closures' mean weight
                alpha = alpha - np.where(found, self.holdout[self.scene.mesh.material[np.maximum(hit.prim, 0)]], 0.0)
            out["alpha"] = np.clip(alpha, 0.0, 1.0)[:, None]
        if not self.wanted:
            return out
        rows = np.flatnonzero(found)
        prim, p, d_hit = hit.prim[rows], take(hit.p, rows), take(d, rows)

        def at_hits(values, channels):
            full = np.zeros((n, channels))
            full[rows] = values.reshape(len(rows), channels)
            return full

        if "Depth" in self.wanted:
            out["Depth"] = at_hits((p - self.eye) @ self.forward, 1)
        if "Position" in self.wanted:
            out["Position"] = at_hits(p + np.asarray(s.origin), 3)
        ng_f, ns = shading_frame(self.scene.mesh, self.flat_normal, prim, take(hit.b, rows), take(hit.ng, rows), -d_hit)
        if "Normal" in self.wanted:
            out["Normal"] = at_hits(ns, 3)
        if "Denoising Albedo" in self.wanted or "Denoising Normal" in self.wanted:
            mat = self.scene.mesh.material[prim]
            bsdf = make_closure(self.scene, self.lambert_albedo, mat, ns, ng_f, -d_hit, prim, take(hit.b, rows),
                                programs=self.programs, p=p)
            if "Denoising Albedo" in self.wanted:
                out["Denoising Albedo"] = at_hits(np.clip(bsdf.reflectance, 0.0, 1.0), 3)
            if "Denoising Normal" in self.wanted:
                # In camera space, as Cycles writes it for the denoiser.
                out["Denoising Normal"] = at_hits(bsdf.ns @ self.camera_from_world.T, 3)
        return out
