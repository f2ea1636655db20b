"""The shading state: what nodes may read about the points of a batch.

Fields, each per point (N rows), in world space unless said otherwise, as Cycles' ShaderData:
  P            (N,3) position
  N            (N,3) shading normal (interpolated, facing the incoming ray, as Cycles flips it)
  Ng           (N,3) geometric normal (facing the incoming ray)
  I            (N,3) unit direction toward where the ray came from
  backfacing   (N,) bool: the ray hit the back of the triangle (its winding normal faced away)
  uv           (N,3) the active render UV map at the point, (u, v, 0)
  generated    (N,3) position in the object's texture space (its bounds mapped to [0, 1]^3)
  instancer_generated, instancer_uv
               (N,3) for an instance, the generated and UV coordinates of the instancer at
               its origin (Texture Coordinate's From Instancer); zero for other objects
  object       (N,3) position in object space
  camera       (N,3) position in camera space
  window       (N,3) position in normalised window coordinates (x, y in [0, 1], z 0)
  ray_length   (N,) distance from the previous vertex (Cycles' isect.t; FLT_MAX for a ray
               that left the scene, as in a world shader)
  world_from_object, object_from_world
               (N,4,4) the point's object transform and its inverse (column vectors: world
               position = M @ (x, y, z, 1)); identity where there is no object (the world)
  world_from_camera, camera_from_world
               (4,4) the render camera's frame and its inverse, one for the batch. Camera space
               is Cycles': x right, y up, z forward into the view (Blender's camera looks down
               its -z), without the camera object's scale

The hit on its triangle (engine/nodes/geometry.py, wireframe.py, normal_map.py and Bump read
these; a point that is not on a mesh triangle, as in a world shader, gives zeros):
  barycentric  (N,2) Cycles' (u, v) of the hit: P = (1 - u - v) P0 + u P1 + v P2 over the
               triangle's vertices in Blender's corner order (Mesh.loop_triangles). A bake's
               (u, v) from Blender's pixel (u_b, v_b) is (v_b, 1 - u_b - v_b)
  triangle     (N,3,3) the triangle's vertices P0, P1, P2 in world space
  dPdu, dPdv   (N,3) P1 - P0 and P2 - P0 in world space, negated on backfacing hits (sd->dPdu,
               sd->dPdv)
  smooth       (N,) bool: the face is smooth shaded (SHADER_SMOOTH_NORMAL: N interpolated
               from vertex normals; flat faces have N = Ng)
  vertex_normal
               (N,3) object space: the vertex normals interpolated at the point and not
               renormalised, (1 - u - v) n0 + u n1 + v n2 (triangle_smooth_normal_unnormalized;
               Normal Map's tangent frame). Vertex normals are Blender's (Mesh.vertex_normals)
  N_du, N_dv   (N,3) how N moves with u and v: (n1 - n0) and (n2 - n0) of the world-space
               vertex normals (each M^-T n renormalised, as Cycles stores them once the
               object's transform is applied), divided by the length of their interpolation
               at the point, negated on backfacing hits; zero on flat faces. N moved by
               (du, dv) is normalize(N + du N_du + dv N_dv), exactly the renormalised
               re-interpolation Cycles' texco_normal_from_uv computes
  uv_du, uv_dv, generated_du, generated_dv
               (N,3) how uv and generated move with u and v: their values at the triangle's
               corners, f1 - f0 and f2 - f0 (zero third component for uv)

Ray differentials (Cycles keeps them compact: a radius, no direction):
  dP           (N,) sd->dP: the ray footprint's radius at the point, ray.dP + t ray.dD from
               the ray's own compact differentials (a camera ray: the pixel's spread; Cycles'
               bake: 0.5 (|dP/dx| + |dP/dy|) of the texel's footprint). Bump and Wireframe
               expand it to two axes, dP times make_orthonormals(Ng) (differentials.py)
  ndc_from_world
               (4,4) Cycles' worldtondc projection of a perspective or orthographic camera
               (window = (M @ (P, 1)).xyz / w): read only for the Window coordinate of a Bump
               node's offset evaluations, which project the moved point

What the object and material give (Object Info); zeros where there is no object:
  object_color (N,3) the object's Color property (Object.color, RGB as stored)
  object_alpha (N,) its alpha (Object.color[3])
  object_index (N,) its Pass Index (Object.pass_index)
  object_random
               (N,) Cycles' per-object random number: hash_uint2(hash_string(name), 0) of the
               object's name, or Blender's instance random id for an instance, times 2^-32 in
               float32 (engine/nodes/object_info.py object_random computes it from a name)
  material_index
               (N,) the Pass Index of the material shading the point (Material.pass_index)

The path that reached the point (Light Path; Cycles' path state):
  path_flag    (N,) uint32 with Cycles' PATH_RAY_* bits of the ray (engine/nodes/light_path.py
               has them): CAMERA, REFLECT, TRANSMIT, DIFFUSE, GLOSSY, SINGULAR, TRANSPARENT,
               VOLUME_SCATTER, SHADOW_OPAQUE, SHADOW_TRANSPARENT, EMISSION (a light's or the
               world's shader seen by this ray). A camera ray's first hit has CAMERA alone
  bounce, diffuse_bounce, glossy_bounce, transmission_bounce, transparent_bounce, portal_bounce
               (N,) int: the path's bounces so far, in total and by kind (for a shadow ray, the
               counts of the path that cast it); portal_bounce is 0 unless the scene has a Ray
               Portal BSDF (KERNEL_FEATURE_NODE_PORTAL)
  min_ray_pdf  (N,) the smallest BSDF pdf of the path's non-singular bounces so far (Cycles'
               min_ray_pdf; infinite for a camera ray's first hit): Bevel works only above 8

Ray queries (Ambient Occlusion, Bevel: Cycles' shader ray tracing), not an array:
  ray_queries  an engine/nodes/rays.py ShaderRays of the points: the scene's Embree scenes and
               the path's random numbers; None where the renderer gives none (a bake, a
               light's or the world's shader, the photon integrators): Cycles' answer where it
               cannot trace (no BVH yet) is then what the nodes give

Named attributes, by ShadingState.attribute(name) (not fields): the mesh's own attributes by
their names (UV maps, colour attributes, generic attributes on points, faces, corners or
edges), and Cycles' standard names: "uv" (the active render UV map), "generated",
"vertex_color" (the active render colour attribute), "tangent" and "tangent_sign" (MikkTSpace
tangents of the active render UV map, per corner; "<map>.tangent", "<map>.tangent_sign" for a
named map; "undisplaced_tangent", "<map>.undisplaced_tangent", ... the same for meshes that are
not displaced), "pointiness" and "random_per_island" (engine/nodes/mesh_attributes.py computes
both from the mesh), and with the prefixes "\\x01object:", "\\x01instancer:" the Object and
Instancer attributes (custom properties, looked up as Cycles' blender/object.cpp does). Each is
an Attribute (below) or None where the point's geometry has no such attribute.

A node names the fields it reads (NodeType.reads; "attribute:<name>" for a named attribute); a
batch computes only what its program reads. The state is built from the fields given, and from
`source`, an object with a method per field name (and `attribute(name)`), for the others, each
asked at most once. texcoord_normal (the normal Texture Coordinate's Normal output transforms)
is N itself unless given: a Bump node's offset evaluations move it (differentials.py).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FIELDS = ("P", "N", "Ng", "I", "backfacing", "uv", "generated", "object", "camera", "window", "ray_length",
          "instancer_generated", "instancer_uv", "world_from_object", "object_from_world",
          "world_from_camera", "camera_from_world",
          "barycentric", "triangle", "dPdu", "dPdv", "smooth", "vertex_normal", "N_du", "N_dv",
          "uv_du", "uv_dv", "generated_du", "generated_dv", "dP", "ndc_from_world",
          "object_color", "object_alpha", "object_index", "object_random", "material_index",
          "path_flag", "bounce", "diffuse_bounce", "glossy_bounce", "transmission_bounce", "transparent_bounce",
          "portal_bounce", "texcoord_normal", "min_ray_pdf", "ray_queries")

# Fields that default to another where the source does not give them.
_DEFAULTS = {"texcoord_normal": "N"}
# Fields that are objects rather than arrays, None where the source does not give them.
_OBJECTS = ("ray_queries",)


@dataclass(frozen=True)
class Attribute:
    """A named attribute at the points: `type` as Cycles stores it ("float", "float2", "float3",
    "float4" or "rgba"), `value` (N,c) or (c,) for one value over the batch (an object's or a
    mesh's single value), c = 1, 2, 3 or 4 channels; `du`, `dv` how it moves with the hit's
    barycentric u and v (the corner values f1 - f0, f2 - f0; None for per-face and constant
    attributes): what a Bump node's offset evaluations add."""

    type: str
    value: np.ndarray
    du: np.ndarray | None = None
    dv: np.ndarray | None = None


class ShadingState:
    def __init__(self, n: int, source=None, **fields):
        self.n = n
        self._source = source
        self._fields = {k: v if k in _OBJECTS else np.asarray(v) for k, v in fields.items()}
        self._attributes: dict = {}

    def __getattr__(self, name: str):
        if name.startswith("_") or name not in FIELDS:
            raise AttributeError(name)
        if name in _OBJECTS:
            if name not in self._fields:
                make = getattr(self._source, name, None)
                self._fields[name] = make() if make is not None else None
            return self._fields[name]
        if name not in self._fields:
            make = getattr(self._source, name, None)
            if make is None and name in _DEFAULTS:
                return getattr(self, _DEFAULTS[name])
            if make is None:
                raise KeyError(f"the shading state has no {name!r} here")
            self._fields[name] = np.asarray(make())
        return self._fields[name]

    @property
    def unshifted(self) -> "ShadingState":
        """The state itself: what a node reads where Cycles reads it at the point even inside a
        Bump node's offset evaluations (differentials.OffsetState overrides this)."""
        return self

    def attribute(self, name: str) -> Attribute | None:
        """The named attribute at the points (see the module's docstring), or None."""
        if name not in self._attributes:
            make = getattr(self._source, "attribute", None)
            self._attributes[name] = make(name) if make is not None else None
        return self._attributes[name]
