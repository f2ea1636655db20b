"""Ray queries from inside a shader (Cycles' __SHADER_RAYTRACE__: Ambient Occlusion, Bevel): what
the renderer gives a node program so that it can trace rays from its points into the scene.

ShaderRays holds, for N shading points, the scene's Embree scenes (engine/accel.py Accel: the
one shadow rays see, and the full one, for queries against the point's own object) and the
path's random numbers at each point: numbers of the sampler (engine/rng.py) in groups of their
own, a pure function of (seed, pixel, sample, bounce, stream, sample of the node), so an image
never depends on batches or workers. A node asks
  uniform(stream, k, count)      (N,2) uniforms for its k-th ray of `count` in a stream (AO,
                                 BEVEL, BEVEL_HITS)
  occluded(o, ng, d, tmax, local)
                                 (N,) bool: is the segment o + t d, t in (0, tmax], blocked
                                 (local: only by the point's own object, Cycles'
                                 scene_intersect_local; else by what casts shadows)
  local_hits(o, d, tmax)         every hit of the points' own objects along o + t d, t in
                                 (0, tmax]: (row, prim, t, barycentrics, order along the ray)
                                 per hit, and each ray's count of hits
  normals(prim, bary)            the geometric and interpolated normals of hits
take(rows) gives the queries of some of the points (a batch split by material).
"""
from __future__ import annotations

import numpy as np

from ..accel import offset_origin
from ..vec import dot

AO, BEVEL, BEVEL_HITS = 0, 1, 2
_STREAMS = 3
# Shader rays draw from groups far above the integrator's own (a few per bounce).
_FIRST_GROUP = 1 << 24
# Hits a local query walks through before it gives up on a ray (its later hits are not seen):
# more surfaces of one object along one short ray are rare.
_LOCAL_STEPS = 16


def make_orthonormals(n):
    """Cycles' make_orthonormals: tangents (t, b) (N,3) of unit normals n (N,3), t along
    (1, 1, 1) x n (or (-1, 1, 1) x n where n's components are equal). Shader rays are drawn in
    this frame as Cycles draws them: with few rays per point, the frame's turn about n changes
    the distribution of their estimate (a bevel's probes meet a cube's edges differently)."""
    x, y, z = n[:, 0], n[:, 1], n[:, 2]
    same = (x == y) & (x == z)
    a = np.stack([z - y, np.where(same, x + z, x - z), np.where(same, -y - x, y - x)], axis=1)
    a = a / np.linalg.norm(a, axis=1, keepdims=True)
    return a, np.cross(n, a)


def sample_uniform_disk(u):
    """Cycles' sample_uniform_disk (Shirley's concentric mapping): (N,2) points of the unit
    disk from u (N,2)."""
    a, b = 2.0 * u[:, 0] - 1.0, 2.0 * u[:, 1] - 1.0
    wide = a * a > b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(wide, a, b)
        phi = np.where(wide, 0.25 * np.pi * (b / a), 0.5 * np.pi - 0.25 * np.pi * (a / b))
    r = np.where((a == 0.0) & (b == 0.0), 0.0, r)
    phi = np.where(np.isfinite(phi), phi, 0.0)
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1)


class SceneRays:
    """What shader rays trace against, once per render: `shadow` the Accel shadow rays see,
    `full` the whole scene's, and per object an Accel of its own triangles (Cycles' local
    BVH), made when a query first needs it: a point's own object must be found even where
    another object's surface coincides with it (a box standing on a floor)."""

    def __init__(self, shadow, full, mesh):
        self.shadow, self.full, self.mesh = shadow, full, mesh
        self.triangle_object = None
        if mesh.objects is not None:
            starts = np.asarray(mesh.objects, np.int64)
            self.triangle_object = np.repeat(np.arange(len(starts) - 1), np.diff(starts))
        self._local: dict = {}

    def object_of(self, prim) -> np.ndarray:
        if self.triangle_object is None:
            return np.zeros(len(prim), np.int64)
        return self.triangle_object[prim]

    def local(self, obj: int):
        """The Accel of object `obj`'s triangles (hits report their index in the whole mesh)."""
        if self.triangle_object is None:
            return self.full
        if obj not in self._local:
            a, b = int(self.mesh.objects[obj]), int(self.mesh.objects[obj + 1])
            self._local[obj] = self.full.subset(np.arange(a, b), self.mesh)
        return self._local[obj]


class ShaderRays:
    """Ray queries for N points on triangles `prim` (N,) of the scene `scene` (SceneRays);
    `sampler`, `idx` (N,) the paths' rows in it and `depth` (N,) or one value their bounces:
    where the numbers come from."""

    def __init__(self, scene: SceneRays, prim, sampler, idx, depth):
        self.scene, self.prim, self.sampler, self.idx, self.depth = scene, prim, sampler, idx, depth

    def __len__(self) -> int:
        return len(self.prim)

    def take(self, rows) -> "ShaderRays":
        depth = self.depth if np.ndim(self.depth) == 0 else self.depth[rows]
        return ShaderRays(self.scene, self.prim[rows], self.sampler, self.idx[rows], depth)

    def uniform(self, stream: int, k: int, count: int) -> np.ndarray:
        """(N,2) uniforms in [0, 1) for ray k of the `count` a point traces in `stream`: Cycles'
        path_branched_rng_2D, the rays of one sample stratified together."""
        group = _FIRST_GROUP + np.asarray(self.depth, np.int64) * _STREAMS + stream
        return self.sampler.branched(k, count).get(group, self.idx, 2)

    def _by_object(self, rows):
        """(object, rows of `rows` on it) per object of the points `rows`."""
        own = self.scene.object_of(self.prim[rows])
        for obj in np.unique(own):
            yield int(obj), rows[own == obj]

    def occluded(self, o, ng, d, tmax, local: bool = False) -> np.ndarray:
        """(N,) bool for segments from points o (N,3) (on their triangles, geometric normals ng)
        along unit d (N,3) to t = tmax (N,); the point's own triangle never blocks."""
        out = np.zeros(len(o), bool)
        live = np.flatnonzero(np.asarray(tmax) > 0.0)
        if len(live) == 0:
            return out
        o, ng, d, tmax = o[live], ng[live], d[live], np.asarray(tmax, np.float64)[live]
        start = offset_origin(o, ng * np.where(dot(ng, d) >= 0.0, 1.0, -1.0)[:, None])
        target = o + d * tmax[:, None]
        prim = self.prim[live]
        if not local:
            out[live] = self.scene.shadow.occluded(start, target, prim)
            return out
        blocked = np.zeros(len(live), bool)
        for obj, rows in self._by_object(np.arange(len(live))):
            blocked[rows] = self.scene.local(obj).occluded(start[rows], target[rows], prim[rows])
        out[live] = blocked
        return out

    def local_hits(self, o, d, tmax):
        """The hits of each point's own object along rays from o (N,3) (the ray starts there,
        nothing skipped) along unit d (N,3) up to tmax (N,): ((rows (H,), prim (H,), t (H,),
        barycentrics (H,3) over the stored corners, order (H,) 0 for a ray's nearest hit, 1
        for the next, ...), count (N,) of each ray's hits, up to _LOCAL_STEPS)."""
        o32 = np.ascontiguousarray(o, np.float32)
        tmax = np.asarray(tmax, np.float64)
        found, count = [], np.zeros(len(o), np.int64)
        for obj, rows in self._by_object(np.flatnonzero(tmax > 0.0)):
            accel = self.scene.local(obj)
            start, skip, t0 = o32[rows], np.full(len(rows), -1, np.int64), np.zeros(len(rows))
            for _ in range(_LOCAL_STEPS):
                h = accel.intersect(start, d[rows], tmax[rows] - t0, skip)
                go = np.flatnonzero(h.prim >= 0)
                if len(go) == 0:
                    break
                found.append((rows[go], h.prim[go], t0[go] + h.t[go], h.b[go], count[rows[go]]))
                count[rows[go]] += 1
                # On from just through the hit triangle's plane, skipping it.
                through = h.ng[go] * np.where(dot(h.ng[go], d[rows[go]]) >= 0.0, 1.0, -1.0)[:, None]
                start, skip = offset_origin(h.p[go], through), h.prim[go]
                t0, rows = t0[go] + h.t[go], rows[go]
        if not found:
            empty = np.zeros(0, np.int64)
            return (empty, empty, np.zeros(0), np.zeros((0, 3)), empty), count
        return tuple(np.concatenate(x) for x in zip(*found)), count

    def normals(self, prim, bary):
        """(ng, n) (H,3) of hits on triangles prim (H,) at barycentrics bary (H,3) over the
        stored corners: the triangle's winding normal (Cycles' hit Ng, flipped for a mirrored
        object as Ember's stored winding already is) and its corner normals interpolated and
        normalised (Cycles' triangle_smooth_normal; a flat face's are its normal), or ng where
        they cancel."""
        ng = np.asarray(self.scene.full.ng[prim], np.float64)
        n = np.einsum("hk,hkc->hc", bary, self.scene.mesh.normals[prim].astype(np.float64))
        length = np.linalg.norm(n, axis=1, keepdims=True)
        return ng, np.where(length > 0.0, n / np.where(length > 0.0, length, 1.0), ng)
