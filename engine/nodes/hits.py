"""The shading state of surface hits: each field of engine/nodes/state.py computed from the
Scene's arrays when a program first reads it (a ShadingState's source), as Cycles' ShaderData
has them at a ray hit (kernel/geom/shader_data.h shader_setup_from_ray, geom/triangle.h).

The hit's triangle: Ember stores a negatively scaled instance's triangles with corners 1 and 2
swapped (engine/blender/export_mesh.py: its winding then agrees with its normals), Cycles keeps
Blender's corner order and flips the normal instead. The fields that name corners (barycentric,
triangle, dPdu, dPdv, N_du, the attributes' du, dv) are in Blender's order: the stored corners
(0, 2, 1) on those triangles, so (u, v) = (b2, b1) of Embree's barycentrics there. What is
interpolated (vertex_normal, attribute values) does not depend on the order.

The path's part (path_flag, the bounce counts, dP) comes from a RayState the integrator
gives; without one a hit is a camera ray's first hit, its ray differential the camera's
(camera_differentials), as Cycles' camera rays carry them (kernel/camera/camera.h).

Per-object values (Object Info, Object attributes, the transforms) are looked up per object
and gathered per point; nothing loops over points.

Where this is not Cycles' state exactly:
- smooth: a face whose three corner normals differ (Ember keeps no face flag); a smooth face
  whose corner normals agree reads as flat, which changes nothing but under custom normals;
- vertex_normal, N_du, N_dv: from the export's corner normals, which are Cycles' vertex
  normals (its own for normals per vertex, those of the mesh it splits for normals per corner);
- instancer_generated, instancer_uv: zeros (the export does not carry the instancer's);
- the path: shadow rays evaluate programs only at transparent surfaces they pass (flag
  SHADOW, their counts 0 but transparent_bounce), has no volumes (VOLUME_SCATTER) nor portals
  (portal_bounce 0); a light
  sample's emission reads bounce counts 0 where Cycles reads the path's; the photon
  integrator's hits all read as camera rays' first hits, the irradiance cache's and caustic
  path's gather rays as leaving a diffuse bounce with the camera's footprint there
  (engine/integrators/path.py PathTracer._track).
"""
from __future__ import annotations

import weakref

import numpy as np

from ..scene import ATTRIBUTE_TYPES, Scene
from ..textures import mesh_uv
from ..vec import dot, normalize
from .. import panorama
from ..camera import cycles_frame
from . import light_path
from .state import Attribute, ShadingState

# Cycles' camera space looks down +z; Blender's camera object looks down its -z.
_CYCLES_FROM_BLENDER_CAMERA = np.diag([1.0, 1.0, -1.0, 1.0])
_BLENDER_ORDER = np.array([[0, 1, 2], [0, 2, 1]])  # stored corner of Blender's corner k, unflipped / flipped
_CHANNELS = {"float": 1, "float2": 2, "float3": 3, "float4": 4, "rgba": 4}
_OBJECT_PREFIXES = ("\x01object:", "\x01instancer:")
_COUNTS = ("bounce", "diffuse_bounce", "glossy_bounce", "transmission_bounce", "transparent_bounce")


class RayState:
    """The path's part of the shading state at N points (Cycles' path state, integrator/
    path_state.h): flag, Cycles' PATH_RAY_* bits of the ray that reached them (light_path.py);
    the bounce counts (bounce, diffuse_bounce, glossy_bounce, transmission_bounce,
    transparent_bounce); dP the ray footprint's radius at the points (sd->dP), or None: the
    camera's at a first hit; min_ray_pdf the smallest pdf of the path's non-singular bounces
    so far (Cycles' min_ray_pdf; infinite before any). Each an (N,) array or one value for
    all. rays: the ray queries the path can make from the points (engine/nodes/rays.py
    ShaderRays: the scene and the path's random numbers), or None."""

    __slots__ = ("flag",) + _COUNTS + ("dP", "min_ray_pdf", "rays")

    def __init__(self, flag, bounce=0, diffuse_bounce=0, glossy_bounce=0, transmission_bounce=0,
                 transparent_bounce=0, dP=None, min_ray_pdf=np.inf, rays=None):
        self.flag, self.dP, self.min_ray_pdf, self.rays = flag, dP, min_ray_pdf, rays
        self.bounce, self.diffuse_bounce, self.glossy_bounce = bounce, diffuse_bounce, glossy_bounce
        self.transmission_bounce, self.transparent_bounce = transmission_bounce, transparent_bounce

    def take(self, rows) -> "RayState":
        """The record of points `rows`."""
        pick = lambda v: v if v is None or np.ndim(v) == 0 else v[rows]  # noqa: E731
        rays = None if self.rays is None else self.rays.take(rows)
        return RayState(*(pick(getattr(self, name)) for name in self.__slots__[:-1]), rays=rays)

    def escaped(self) -> "RayState":
        """What the world's shader sees of these paths' rays leaving the scene: their flags with
        Cycles' emission flag added (integrator_eval_background_shader)."""
        return RayState(np.asarray(self.flag, np.uint32) | np.uint32(light_path.EMISSION),
                        *(getattr(self, name) for name in _COUNTS), dP=self.dP)

    def for_emission(self) -> "RayState":
        """What a light's shader sees for a light sample of these paths: Cycles' emission flag,
        the paths' bounce counts, no ray differential (shader_setup_from_sample)."""
        return RayState(light_path.EMISSION, *(getattr(self, name) for name in _COUNTS), dP=0.0)


# The state fields that come from the path (a RayState); portal_bounce is always 0.
PATH_FIELDS = frozenset(("path_flag",) + _COUNTS + ("portal_bounce",))
COUNT_FIELDS = frozenset(_COUNTS)
CAMERA_RAY = RayState(light_path.CAMERA)  # a camera ray's first hit, nothing tracked
EMISSION_RAY = RayState(light_path.EMISSION, dP=0.0)  # a light sample's evaluation, bounce 0

_PER_MESH: dict = {}  # id(mesh) -> (weak reference to it, {name: per-object table})


def _per_object(mesh, name: str, make):
    """A table over the mesh's objects (their transforms' inverses, which are mirrored), made
    once per mesh rather than per batch: a scene of a million instances has a million."""
    key = id(mesh)
    known = _PER_MESH.get(key)
    if known is None or known[0]() is not mesh:
        known = _PER_MESH[key] = (weakref.ref(mesh, lambda _, key=key: _PER_MESH.pop(key, None)), {})
    tables = known[1]
    if name not in tables:
        tables[name] = make()
    return tables[name]


def camera_differentials(scene: Scene, directions: np.ndarray):
    """Cycles' compact ray differentials (dP, dD) (N,) of camera rays along `directions` (N,3)
    (world, unit), dP at the camera (kernel/camera/camera.h): a perspective camera's dP is 0
    and dD the mean length of the change of the normalised direction over one pixel in x and
    in y (dD = 0.5 (|dD.dx| + |dD.dy|), differential_make_compact); an orthographic camera's
    dP is its pixel's mean size and dD 0. The footprint at distance t from the camera is
    dP + t dD (differential_transfer_compact); Cycles moves its rays' start to the near clip
    together with their dP, so t counts from the camera itself."""
    cam, st = scene.camera, scene.settings
    left, right, bottom, top = (float(v) for v in cam.window)
    sx, sy = (right - left) / st.width, (top - bottom) / st.height  # a pixel at unit depth (or in metres)
    n = len(directions)
    if cam.ortho:
        return np.full(n, 0.5 * (abs(sx) + abs(sy))), np.zeros(n)
    rot = np.asarray(cam.world_from_camera, np.float64)[:3, :3]
    rot = rot / np.linalg.norm(rot, axis=0)
    if cam.panorama:  # the change of the projection's direction over one pixel (camera_sample_panorama)
        turn = panorama.panorama_to_camera(cam.panorama)
        d = (np.asarray(directions, np.float64) @ rot) @ turn
        u, v = panorama.from_direction(cam, d)
        centre = panorama.to_direction(cam, u, v)
        dx = panorama.to_direction(cam, u + sx, v) - centre
        dy = panorama.to_direction(cam, u, v + sy) - centre
        return np.zeros(n), 0.5 * (np.linalg.norm(dx, axis=1) + np.linalg.norm(dy, axis=1))
    d = np.asarray(directions, np.float64) @ rot  # camera space: looking down -z
    depth = np.where(d[:, 2] < 0.0, -d[:, 2], 1.0)
    v = d / depth[:, None]  # (x, y, -1): the point on the unit-depth image plane
    centre = normalize(v)
    dx = normalize(v + np.array([sx, 0.0, 0.0])) - centre
    dy = normalize(v + np.array([0.0, sy, 0.0])) - centre
    return np.zeros(n), 0.5 * (np.linalg.norm(dx, axis=1) + np.linalg.norm(dy, axis=1))


def camera_footprint(scene: Scene, p: np.ndarray) -> np.ndarray:
    """(N,) sd->dP of camera rays' first hits at points p (N,3): dP + t dD of the ray from the
    camera through each point (engine/nodes/state.py dP)."""
    eye = np.asarray(scene.camera.world_from_camera, np.float64)[:3, 3]
    if scene.camera.ortho:
        return camera_differentials(scene, np.zeros((len(p), 3)))[0]
    to = np.asarray(p, np.float64) - eye
    t = np.linalg.norm(to, axis=1)
    dP, dD = camera_differentials(scene, to / np.where(t > 0.0, t, 1.0)[:, None])
    return dP + t * dD


class PathFields:
    """The state fields a path gives (Light Path's), read from the RayState `self.ray` of a
    state source of len(self) points."""

    def _per_point(self, value, dtype):
        return np.broadcast_to(np.asarray(value, dtype), (len(self),))

    def path_flag(self):
        return self._per_point(self.ray.flag, np.uint32)

    def bounce(self):
        return self._per_point(self.ray.bounce, np.int64)

    def diffuse_bounce(self):
        return self._per_point(self.ray.diffuse_bounce, np.int64)

    def glossy_bounce(self):
        return self._per_point(self.ray.glossy_bounce, np.int64)

    def transmission_bounce(self):
        return self._per_point(self.ray.transmission_bounce, np.int64)

    def transparent_bounce(self):
        return self._per_point(self.ray.transparent_bounce, np.int64)

    def portal_bounce(self):  # Ember has no Ray Portal BSDF
        return np.zeros(len(self), np.int64)


class SurfaceHits(PathFields):
    """Fields of N hits: prim (N,) triangles, bary (N,3) barycentrics over the stored corners, p
    (N,3) positions, ns and ng (N,3) shading and geometric normals facing the incoming ray, wo
    (N,3) toward it; t (N,) the ray's length to the hit, or None (Light Falloff's ray length
    then reads 0); ray: the path's RayState of the hits, or None (a camera ray's first hit)."""

    def __init__(self, scene: Scene, prim, bary, p, ns, ng, wo, t=None, ray: RayState | None = None):
        self.scene, self.prim, self.bary = scene, prim, bary
        self._p, self._ns, self._ng, self._wo, self._t = p, ns, ng, wo, t
        self.ray = CAMERA_RAY if ray is None else ray
        self._memo: dict = {}

    def __len__(self):
        return len(self.prim)

    def state(self) -> ShadingState:
        return ShadingState(len(self.prim), source=self)

    def take(self, rows: np.ndarray) -> "SurfaceHits":
        """The hits `rows` (K,) of these."""
        return SurfaceHits(self.scene, self.prim[rows], self.bary[rows], self._p[rows], self._ns[rows], self._ng[rows],
                           self._wo[rows], None if self._t is None else self._t[rows], self.ray.take(rows))

    def _once(self, key, make):
        if key not in self._memo:
            self._memo[key] = make()
        return self._memo[key]

    # --- the hit -----------------------------------------------------------------------------
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

    def _stored(self) -> np.ndarray:
        """(N,3,3) float64 world vertices of the hit triangles, in the stored corner order."""
        mesh = self.scene.mesh
        return self._once("stored", lambda: mesh.vertices[mesh.triangles[self.prim]].astype(np.float64))

    def backfacing(self):
        v = self._stored()
        return dot(self._wo, normalize(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]))) < 0

    def _flipped(self) -> np.ndarray:
        """(N,) bool: the triangle's corners 1 and 2 are stored swapped (a negatively scaled
        instance, export_mesh): per object, from the sign of its transform's determinant."""
        def make():
            obj = self._objects()
            if obj is None:
                return np.zeros(len(self.prim), bool)
            mesh = self.scene.mesh
            negative = _per_object(mesh, "negative", lambda: np.linalg.det(mesh.object_matrix[:, :3, :3]) < 0.0)
            return negative[obj]
        return self._once("flipped", make)

    def _blender(self, corners: np.ndarray) -> np.ndarray:
        """Per-corner values (N,3,...) in the stored order, reordered to Blender's."""
        flipped = self._flipped()
        if not flipped.any():
            return corners
        out = corners.copy()
        out[flipped, 1], out[flipped, 2] = corners[flipped, 2], corners[flipped, 1]
        return out

    def _differences(self, corners: np.ndarray):
        """(f1 - f0, f2 - f0) of stored per-corner values (N,3,...) in Blender's corner order."""
        f = self._blender(corners)
        return f[:, 1] - f[:, 0], f[:, 2] - f[:, 0]

    def barycentric(self):
        b = self.bary[:, 1:3]
        flipped = self._flipped()
        return np.where(flipped[:, None], b[:, ::-1], b) if flipped.any() else b.copy()

    def triangle(self):
        return self._blender(self._stored())

    def _side(self) -> np.ndarray:
        """(N,1): -1 on backfacing hits, where Cycles has negated dPdu, dPdv, N and Ng."""
        return self._once("side", lambda: np.where(self.backfacing(), -1.0, 1.0)[:, None])

    def dPdu(self):
        return self._differences(self._stored())[0] * self._side()

    def dPdv(self):
        return self._differences(self._stored())[1] * self._side()

    def _corner_normals(self) -> np.ndarray:
        """(N,3,3) float64 world-space corner normals (unit: export_mesh stores M^-T n
        renormalised), stored order: Cycles' world vertex normals (its own for meshes whose
        normals are per vertex, the split mesh's where they are per corner)."""
        return self._once("normals", lambda: self.scene.mesh.normals[self.prim].astype(np.float64))

    def smooth(self):
        """Smooth faces: their corner normals differ (a flat face's are its normal, three times).
        A smooth face whose three normals agree reads as flat: its normal is the same either way
        but for custom normals, and N_du, N_dv are zero on it as on a flat face."""
        n = self._corner_normals()
        return np.any(n != n[:, :1], axis=(1, 2))

    def vertex_normal(self):
        """Object space: each corner's world normal taken back by M^T (the export's M^-T n,
        renormalised, returns to the unit object normal) and renormalised, interpolated."""
        n = self._corner_normals()
        m = self.world_from_object()[:, :3, :3]
        local = normalize(np.einsum("nji,nkj->nki", m, n).reshape(-1, 3)).reshape(n.shape)
        return np.einsum("nk,nkc->nc", self.bary, local)

    def _normal_derivatives(self):
        def make():
            n = self._corner_normals()
            raw = np.einsum("nk,nkc->nc", self.bary, n)
            length = np.linalg.norm(raw, axis=1, keepdims=True)
            scale = np.where(self.smooth()[:, None] & (length > 0.0), self._side() / np.where(length > 0.0, length, 1.0),
                             0.0)
            du, dv = self._differences(n)
            return du * scale, dv * scale
        return self._once("N_d", make)

    def N_du(self):
        return self._normal_derivatives()[0]

    def N_dv(self):
        return self._normal_derivatives()[1]

    # --- coordinates -------------------------------------------------------------------------
    def uv(self):
        uv = mesh_uv(self.scene.mesh.uvs, self.prim, self.bary)
        return np.concatenate([uv, np.zeros((len(uv), 1))], axis=1)

    def _uv_differences(self):
        def make():
            du, dv = self._differences(self.scene.mesh.uvs[self.prim].astype(np.float64))
            zero = np.zeros((len(du), 1))
            return np.concatenate([du, zero], axis=1), np.concatenate([dv, zero], axis=1)
        return self._once("uv_d", make)

    def uv_du(self):
        return self._uv_differences()[0]

    def uv_dv(self):
        return self._uv_differences()[1]

    def _objects(self) -> np.ndarray | None:
        def make():
            mesh = self.scene.mesh
            if mesh.objects is None or mesh.object_matrix is None:
                return None
            return np.searchsorted(mesh.objects, self.prim, side="right") - 1
        return self._once("objects", make)

    def world_from_object(self):
        obj = self._objects()
        if obj is None:
            return np.broadcast_to(np.eye(4), (len(self.prim), 4, 4))
        return self.scene.mesh.object_matrix[obj]

    def object_from_world(self):
        def make():
            obj = self._objects()
            if obj is None:
                return np.broadcast_to(np.eye(4), (len(self.prim), 4, 4))
            mesh = self.scene.mesh
            return _per_object(mesh, "inverse", lambda: np.linalg.inv(mesh.object_matrix))[obj]
        return self._once("object_from_world", make)

    def object(self):
        m = self.object_from_world()
        return np.einsum("nij,nj->ni", m[:, :3, :3], self._p) + m[:, :3, 3]

    def _texspace(self):
        """(location, size) (N,3) each of the points' texture spaces, or None (generated =
        object space)."""
        obj = self._objects()
        if obj is None:
            return None
        return self.scene.mesh.object_texspace[obj, 0], self.scene.mesh.object_texspace[obj, 1]

    def generated(self):
        space = self._texspace()
        if space is None:
            return self.object()
        loc, size = space
        return (self.object() - loc + size) / (2.0 * size)

    def _generated_differences(self):
        def make():
            m = self.object_from_world()
            local = np.einsum("nij,nkj->nki", m[:, :3, :3], self._stored())  # corners, object space (no shift)
            du, dv = self._differences(local)
            space = self._texspace()
            if space is not None:
                du, dv = du / (2.0 * space[1]), dv / (2.0 * space[1])
            return du, dv
        return self._once("generated_d", make)

    def generated_du(self):
        return self._generated_differences()[0]

    def generated_dv(self):
        return self._generated_differences()[1]

    def world_from_camera(self):
        return cycles_frame(self.scene.camera)

    def camera_from_world(self):
        return np.linalg.inv(self.world_from_camera())

    def camera(self):
        m = self.camera_from_world()
        return self._p @ m[:3, :3].T + m[:3, 3]

    def window(self):
        """The point in the camera's window: (0, 0) bottom left, (1, 1) top right, z 0."""
        cam = self.scene.camera
        if cam.panorama:  # where the projection shows the point (Cycles' camera_world_to_ndc)
            u, v = panorama.from_direction(cam, self.camera())
            return np.stack([u, v, np.zeros(len(u))], axis=1)
        c = self.camera()  # z forward
        left, right, bottom, top = (float(v) for v in cam.window)
        depth = np.ones(len(c)) if cam.ortho else np.where(c[:, 2] != 0, c[:, 2], 1.0)
        x = (c[:, 0] / depth - left) / (right - left)
        y = (c[:, 1] / depth - bottom) / (top - bottom)
        return np.stack([x, y, np.zeros(len(c))], axis=1)

    def ndc_from_world(self):
        """Cycles' worldtondc: window = (M @ (P, 1)).xyz / w, the projection `window` computes,
        as one matrix (a Bump node's offset evaluations project their moved points with it)."""
        cam = self.scene.camera
        left, right, bottom, top = (float(v) for v in cam.window)
        sx, sy = 1.0 / (right - left), 1.0 / (top - bottom)
        if cam.ortho:
            ndc = np.array([[sx, 0, 0, -left * sx], [0, sy, 0, -bottom * sy], [0, 0, 0, 0], [0, 0, 0, 1.0]])
        else:
            ndc = np.array([[sx, 0, -left * sx, 0], [0, sy, -bottom * sy, 0], [0, 0, 0, 0], [0, 0, 1.0, 0]])
        return ndc @ self.camera_from_world()

    def instancer_generated(self):
        return np.zeros((len(self.prim), 3))

    def instancer_uv(self):
        return np.zeros((len(self.prim), 3))

    # --- the ray -----------------------------------------------------------------------------
    def dP(self):
        dp = self.ray.dP
        if dp is None:  # a camera ray's first hit
            return camera_footprint(self.scene, self._p)
        return np.broadcast_to(np.asarray(dp, np.float64), (len(self.prim),))

    def ray_queries(self):
        return self.ray.rays

    def min_ray_pdf(self):
        return np.broadcast_to(np.asarray(self.ray.min_ray_pdf, np.float64), (len(self.prim),))

    # --- object and material -----------------------------------------------------------------
    def _object_info(self, columns):
        info, obj = self.scene.mesh.object_info, self._objects()
        if info is None or obj is None:
            return np.zeros((len(self.prim),) + np.shape(np.zeros(6)[columns]))
        return info[obj][:, columns]

    def object_color(self):
        return self._object_info(slice(0, 3))

    def object_alpha(self):
        return self._object_info(3)

    def object_index(self):
        return self._object_info(4)

    def object_random(self):
        return self._object_info(5)

    def material_index(self):
        table = self.scene.mesh.material_pass_index
        if table is None:
            return np.zeros(len(self.prim))
        return table[self.scene.mesh.material[self.prim]]

    # --- named attributes --------------------------------------------------------------------
    def _types(self, name: str):
        """(N,) int8 the Cycles type (ATTRIBUTE_TYPES index) of attribute `name` at each point,
        -1 where the point's mesh has none; None where no mesh has it."""
        attributes = self.scene.mesh.attributes
        if not attributes or name not in attributes:
            return None
        types = attributes[name][1]
        obj = self._objects()
        return types[obj] if obj is not None else np.broadcast_to(types[:1], (len(self.prim),))

    def split(self, rows: np.ndarray, names) -> list:
        """`rows` (K,) of these hits in groups whose meshes all have, or all lack, each named
        attribute of `names` (with the same type): a ShadingState's attribute is one for the
        batch. One group (rows itself) where they agree, the common case."""
        codes = [t[rows] for t in (self._types(name) for name in names) if t is not None]
        if not codes or all(np.all(c == c[:1]) for c in codes):
            return [rows]
        key = np.zeros(len(rows), np.int64)
        for c in codes:
            key = key * (len(ATTRIBUTE_TYPES) + 1) + (c.astype(np.int64) + 1)
        _, group = np.unique(key, return_inverse=True)
        order = np.argsort(group, kind="stable")
        return np.split(rows[order], np.flatnonzero(np.diff(group[order])) + 1)

    def attribute(self, name: str):
        """The named attribute at the points (engine/nodes/state.py), or None. The points' meshes
        agree on having it (MaterialPrograms batches them by split)."""
        if name.startswith(_OBJECT_PREFIXES):
            table, obj = self.scene.mesh.object_attributes, self._objects()
            if table is None or name not in table or obj is None:
                return Attribute("float4", np.zeros((len(self.prim), 4)))
            return Attribute("float4", table[name][obj])
        if name == "generated":
            return Attribute("float3", self.generated(), self.generated_du(), self.generated_dv())
        if name == "uv":
            return Attribute("float2", self.uv()[:, :2], self.uv_du()[:, :2], self.uv_dv()[:, :2])
        types = self._types(name)
        if types is None or len(types) == 0 or types[0] < 0:
            return None
        kind = ATTRIBUTE_TYPES[int(types[0])]
        values = self.scene.mesh.attributes[name][0]
        f = values[self.prim, ..., :_CHANNELS[kind]].astype(np.float64)
        if f.ndim == 2:  # one value per triangle
            return Attribute(kind, f)
        du, dv = self._differences(f)
        return Attribute(kind, np.einsum("nk,nkc->nc", self.bary, f), du, dv)


def provides(field: str) -> bool:
    """Whether SurfaceHits gives a state field (or, for "attribute:<name>", named attributes):
    a program reading anything else cannot run at surface hits yet."""
    return hasattr(SurfaceHits, "attribute" if field.startswith("attribute:") else field)
