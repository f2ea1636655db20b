"""The shading state of surface hits: each field of engine/nodes/state.py computed from the
Scene's arrays when a program first reads it (a ShadingState's source), as Cycles' ShaderData
has them at a ray hit.
"""
from __future__ import annotations

import numpy as np

from ..scene import Scene
from ..textures import mesh_uv
from ..vec import dot, normalize
from .state import ShadingState

# Cycles' camera space looks down +z; Blender's camera object looks down its -z.
_CYCLES_FROM_BLENDER_CAMERA = np.diag([1.0, 1.0, -1.0, 1.0])


class SurfaceHits:
    """Fields of N hits: prim (N,) triangles, bary (N,3) barycentrics, p (N,3) positions, ns and
    ng (N,3) shading and geometric normals facing the incoming ray, wo (N,3) toward it; t (N,)
    the ray's length to the hit, or None (Light Falloff's ray length then reads 0)."""

    def __init__(self, scene: Scene, prim, bary, p, ns, ng, wo, t=None):
        self.scene, self.prim, self.bary = scene, prim, bary
        self._p, self._ns, self._ng, self._wo, self._t = p, ns, ng, wo, t

    def state(self) -> ShadingState:
        return ShadingState(len(self.prim), source=self)

    def take(self, rows: np.ndarray) -> "SurfaceHits":
        """The hits `rows` (K,) of these."""
        return SurfaceHits(self.scene, self.prim[rows], self.bary[rows], self._p[rows], self._ns[rows], self._ng[rows],
                           self._wo[rows], None if self._t is None else self._t[rows])

    def P(self):
        return self._p

    def N(self):
        return self._ns

    def Ng(self):
        return self._ng

    def I(self):  # noqa: E743 (Cycles' name)
        return self._wo

    def ray_length(self):
        return np.zeros(len(self.prim)) if self._t is None else self._t

    def backfacing(self):
        mesh = self.scene.mesh
        v = mesh.vertices[mesh.triangles[self.prim]].astype(np.float64)
        return dot(self._wo, normalize(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]))) < 0

    def uv(self):
        uv = mesh_uv(self.scene.mesh.uvs, self.prim, self.bary)
        return np.concatenate([uv, np.zeros((len(uv), 1))], axis=1)

    def _objects(self) -> np.ndarray | None:
        mesh = self.scene.mesh
        if mesh.objects is None or mesh.object_matrix is None:
            return None
        return np.searchsorted(mesh.objects, self.prim, side="right") - 1

    def world_from_object(self):
        obj = self._objects()
        if obj is None:
            return np.broadcast_to(np.eye(4), (len(self.prim), 4, 4))
        return self.scene.mesh.object_matrix[obj]

    def object_from_world(self):
        obj = self._objects()
        if obj is None:
            return np.broadcast_to(np.eye(4), (len(self.prim), 4, 4))
        inverse = np.linalg.inv(self.scene.mesh.object_matrix)  # one per object, not per point
        return inverse[obj]

    def object(self):
        m = self.object_from_world()
        return np.einsum("nij,nj->ni", m[:, :3, :3], self._p) + m[:, :3, 3]

    def generated(self):
        obj = self._objects()
        if obj is None:
            return self.object()
        loc, size = self.scene.mesh.object_texspace[obj, 0], self.scene.mesh.object_texspace[obj, 1]
        return (self.object() - loc + size) / (2.0 * size)

    def world_from_camera(self):
        m = np.asarray(self.scene.camera.world_from_camera, np.float64) @ _CYCLES_FROM_BLENDER_CAMERA
        m[:3, :3] /= np.linalg.norm(m[:3, :3], axis=0)
        return m

    def camera_from_world(self):
        return np.linalg.inv(self.world_from_camera())

    def camera(self):
        m = self.camera_from_world()
        return self._p @ m[:3, :3].T + m[:3, 3]

    def window(self):
        """The point in the camera's window: (0, 0) bottom left, (1, 1) top right, z 0."""
        cam = self.scene.camera
        c = self.camera()  # z forward
        left, right, bottom, top = (float(v) for v in cam.window)
        depth = np.ones(len(c)) if cam.ortho else np.where(c[:, 2] != 0, c[:, 2], 1.0)
        x = (c[:, 0] / depth - left) / (right - left)
        y = (c[:, 1] / depth - bottom) / (top - bottom)
        return np.stack([x, y, np.zeros(len(c))], axis=1)

    def instancer_generated(self):
        return np.zeros((len(self.prim), 3))

    def instancer_uv(self):
        return np.zeros((len(self.prim), 3))


def provides(field: str) -> bool:
    """Whether SurfaceHits gives a state field (or, for "attribute:<name>", named attributes):
    a program reading anything else cannot run at surface hits yet."""
    return hasattr(SurfaceHits, "attribute" if field.startswith("attribute:") else field)
