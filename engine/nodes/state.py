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
  ray_length   (N,) distance from the previous vertex
  world_from_object, object_from_world
               (N,4,4) the point's object transform and its inverse (column vectors: world
               position = M @ (x, y, z, 1)); identity where there is no object (the world)
  world_from_camera, camera_from_world
               (4,4) the render camera's frame and its inverse, one for the batch. Camera space
               is Cycles': x right, y up, z forward into the view (Blender's camera looks down
               its -z), without the camera object's scale
A node names the fields it reads (NodeType.reads); a batch computes only what its program
reads. The state is built from the fields given, and from `source`, an object with a method
per field name, for the others, each asked at most once.
"""
from __future__ import annotations

import numpy as np

FIELDS = ("P", "N", "Ng", "I", "backfacing", "uv", "generated", "object", "camera", "window", "ray_length",
          "instancer_generated", "instancer_uv", "world_from_object", "object_from_world",
          "world_from_camera", "camera_from_world")


class ShadingState:
    def __init__(self, n: int, source=None, **fields):
        self.n = n
        self._source = source
        self._fields = {k: np.asarray(v) for k, v in fields.items()}

    def __getattr__(self, name: str):
        if name.startswith("_") or name not in FIELDS:
            raise AttributeError(name)
        if name not in self._fields:
            make = getattr(self._source, name, None)
            if make is None:
                raise KeyError(f"the shading state has no {name!r} here")
            self._fields[name] = np.asarray(make())
        return self._fields[name]
