"""Ray queries on Embree (embreex): batched closest-hit and occlusion for all live rays.

embreex fixes tnear = 0 and takes float32 rays, so robustness is ours:
- hit points are rebuilt in float64 from barycentrics;
- spawned origins are pushed off the surface along the geometric normal by an integer
  number of float32 ULPs (Waechter & Binder, Ray Tracing Gems ch. 6), which works at any
  coordinate magnitude. Their 256 ULPs (Cycles' old ray_offset) move an origin 25 cm at
  coordinates of 1e4 (more than the gap between a light and the ceiling it hangs under)
  and bias the light there; since the re-trace below handles the triangle a ray leaves,
  4 ULPs (rounded, not truncated) suffice for its coplanar neighbours (tested);
- a ray that still re-hits the primitive it left is re-traced from just past that hit
  (Cycles' self-primitive skip), exact for planar triangles;
- shadow rays stop short of their target (tfar = 1 - 1e-4 of the segment).
"""
from __future__ import annotations

import threading
import time
from functools import cached_property

import numpy as np

from .scene import Mesh
from .vec import scale, take

_ORIGIN = 1.0 / 32.0
_FLOAT_SCALE = 1.0 / 65536.0
_INT_SCALE = 4.0
SHADOW_EPSILON = 1e-4


def offset_origin(p: np.ndarray, ng: np.ndarray) -> np.ndarray:
    """Float32 points just off the surface on the side `ng` points to. p, ng (N,3) -> (N,3) f32."""
    p32 = np.ascontiguousarray(p, dtype=np.float32)
    n32 = np.asarray(ng, dtype=np.float32)
    p_i = p32.view(np.int32)
    of_i = np.rint(np.float32(_INT_SCALE) * n32).astype(np.int32)
    sign = p_i >> 31  # -1 where p < 0: negate the step there (two's complement: (x ^ s) - s)
    out = (p_i + ((of_i ^ sign) - sign)).view(np.float32)
    near = np.abs(p32) < _ORIGIN  # near 0 ULPs are tiny: a fixed float step instead
    np.copyto(out, p32 + np.float32(_FLOAT_SCALE) * n32, where=near)
    return out


class Hit:
    """Closest hits of N rays. prim (N,) int64, -1 on a miss; t (N,) float64 (inf on a miss);
    p (N,3) float64 hit point from barycentrics; b (N,3) barycentrics; ng (N,3) unit geometric
    normal (facing as the triangle's winding). p, b and ng are computed on first use, and
    `take` keeps only some rays before that: a path tracer drops its escaped rays first and
    so never rebuilds (then gathers) their points."""

    def __init__(self, prim, t, b1, b2, rows):
        """b1, b2 (N,) Embree's barycentrics (u, v); rows: Accel.rows (T,12) of the full mesh."""
        self.prim, self.t, self._b1, self._b2, self._rows = prim, t, b1, b2, rows
        self._row = None

    def take(self, keep: np.ndarray) -> "Hit":
        """The hits of rays `keep` (K,)."""
        return Hit(self.prim[keep], self.t[keep], self._b1[keep], self._b2[keep], self._rows)

    def _triangle(self) -> np.ndarray:
        """(N,12) rows v0, e1, e2, ng of the triangles hit (triangle 0 for a miss)."""
        if self._row is None:
            self._row = take(self._rows, np.where(self.prim < 0, 0, self.prim))
        return self._row

    @cached_property
    def p(self) -> np.ndarray:
        rows = self._triangle()
        return rows[:, 0:3] + scale(rows[:, 3:6], self._b1) + scale(rows[:, 6:9], self._b2)

    @cached_property
    def b(self) -> np.ndarray:
        b = np.empty((len(self.prim), 3))
        b[:, 0], b[:, 1], b[:, 2] = 1.0 - self._b1 - self._b2, self._b1, self._b2
        return b

    @cached_property
    def ng(self) -> np.ndarray:
        return np.ascontiguousarray(self._triangle()[:, 9:12])


class Accel:
    """One Embree scene per render over the flattened mesh.

    Thread-safe: queries from several threads run in parallel (embreex releases the GIL).
    Counts rays traced and time spent inside Embree.
    """

    def __init__(self, mesh: Mesh, previous: "Accel | None" = None, split: bool = False):
        """split: big objects get Embree scenes of their own (`blocks`; persistent data: the
        viewport, animations); previous: the Accel of an earlier version of the scene, whose
        Embree scenes and per-triangle rows are reused for blocks that are byte for byte the
        same."""
        self.mesh = mesh
        # v0, e1, e2 and ng side by side in one (T,12) row: a hit reads one 96-byte row, not
        # four scattered ones (on a million triangles the gathers are cache and TLB misses).
        self.rows = np.empty((mesh.n_triangles, 12))
        self.area = np.empty(mesh.n_triangles)
        self.v0, self.e1, self.e2, self.ng = (self.rows[:, k:k + 3] for k in (0, 3, 6, 9))
        self.n_triangles = mesh.n_triangles
        self.scene_radius = bounding_radius(mesh.vertices)
        self._lock = threading.Lock()
        self.rays = 0
        self.embree_seconds = 0.0
        self._global_prim = None  # subset views: Embree's primID -> triangle index
        self._stats = self  # where rays and Embree time are counted (subset views: the full Accel)
        # One Embree scene per block (engine/accel.py's BLOCK_MIN): [(scene, first triangle,
        # first vertex, triangles, vertices)]; queries take the closest hit over all of them.
        self._blocks = []
        for a, b in (blocks(mesh) if split else [(0, mesh.n_triangles)] if mesh.n_triangles else []):
            tris = mesh.triangles[a:b]
            va, vb = int(tris.min()), int(tris.max()) + 1
            old = previous._same_block(mesh, a, b, va, vb) if previous is not None else None
            if old is not None:
                embree, pa = old
                self.rows[a:b], self.area[a:b] = previous.rows[pa:pa + b - a], previous.area[pa:pa + b - a]
            else:
                embree = self._build(mesh.vertices[va:vb], tris - va)
                BUILT[0] += 1
                self._fill_rows(a, b)
            self._blocks.append((embree, a, va, b - a, vb - va))
        self._embree = self._blocks[0][0] if self._blocks else None

    def _fill_rows(self, a: int, b: int) -> None:
        tri = self.mesh.vertices.astype(np.float64)[self.mesh.triangles[a:b]]  # (T,3,3)
        self.v0[a:b] = tri[:, 0]
        np.subtract(tri[:, 1], tri[:, 0], out=self.e1[a:b])
        np.subtract(tri[:, 2], tri[:, 0], out=self.e2[a:b])
        cross = np.cross(self.e1[a:b], self.e2[a:b])
        norm = np.linalg.norm(cross, axis=1)
        self.area[a:b] = 0.5 * norm
        ng = self.ng[a:b]
        np.divide(cross, norm[:, None], out=ng, where=norm[:, None] > 0)
        ng[norm == 0] = 0.0

    def _same_block(self, mesh: Mesh, a: int, b: int, va: int, vb: int):
        """(Embree scene, first triangle) of this Accel's block holding the same triangles over
        the same vertex positions as mesh's block [a, b) on vertices [va, vb), or None."""
        for embree, pa, pva, n, nv in self._blocks:
            if n != b - a or nv != vb - va or \
                    not np.array_equal(self.mesh.vertices[pva:pva + nv], mesh.vertices[va:vb]):
                continue
            mine, theirs = self.mesh.triangles[pa:pa + n], mesh.triangles[a:b]
            if np.array_equal(mine, theirs) if pva == va else np.array_equal(mine - pva, theirs - va):
                return embree, pa
        return None

    def _build(self, vertices, triangles):
        from embreex import rtcore as rtc
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh

        self._device = rtc.EmbreeDevice()
        scene = rtcs.EmbreeScene(self._device)
        TriangleMesh(scene, np.ascontiguousarray(vertices, np.float32), np.ascontiguousarray(triangles, np.int32))
        # Commit now (the first run() would), so threads never race on it.
        scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32), query="OCCLUDED")
        return scene

    def subset(self, triangles: np.ndarray, mesh: Mesh) -> "Accel":
        """The same queries over only the triangles `triangles` (K,) of `mesh` (hits report
        their index in the full mesh): what one kind of ray sees when objects are hidden from
        it (Cycles' ray visibility). Shares this one's per-triangle arrays."""
        view = object.__new__(Accel)
        view.__dict__.update({k: v for k, v in self.__dict__.items() if k not in ("_device", "_embree", "_blocks")})
        view._global_prim = np.asarray(triangles, np.int64)
        view._embree = view._build(mesh.vertices, mesh.triangles[triangles]) if len(triangles) else None
        view._blocks = [(view._embree, 0, 0, len(triangles), len(mesh.vertices))] if len(triangles) else []
        return view

    def _prims(self, prim_id) -> np.ndarray:
        """Triangle indices (int64, -1 for a miss) of Embree's primIDs."""
        prim = prim_id.astype(np.int64)
        if self._global_prim is not None:
            prim = np.where(prim >= 0, self._global_prim[np.maximum(prim, 0)], -1)
        return prim

    def _run(self, o32, d32, tfar32, query):
        """Embree's answer over every block: the closest hit (primID counted over the whole
        mesh) or, for OCCLUDED, >= 0 where any block blocks the segment."""
        t0 = time.perf_counter()
        if query == "INTERSECT":
            out = self._embree.run(o32, d32, dists=tfar32, output=1)
            for embree, a, _, _, _ in self._blocks[1:]:  # later blocks: only hits closer than the best so far
                more = embree.run(o32, d32, dists=out["tfar"].copy(), output=1)
                closer = more["primID"] >= 0
                for key in ("tfar", "u", "v"):
                    out[key] = np.where(closer, more[key], out[key])
                out["primID"] = np.where(closer, more["primID"] + a, out["primID"])
        else:
            out = self._embree.run(o32, d32, dists=tfar32, query="OCCLUDED")
            for embree, _, _, _, _ in self._blocks[1:]:
                out = np.maximum(out, embree.run(o32, d32, dists=tfar32.copy(), query="OCCLUDED"))
        dt = time.perf_counter() - t0
        stats = self._stats
        with stats._lock:
            stats.embree_seconds += dt
            stats.rays += len(o32)
        return out

    def intersect(self, o: np.ndarray, d: np.ndarray, tmax=None, skip_prim=None) -> Hit:
        """Closest hit along o + t d, t in (0, tmax]. o (N,3) float32 (already offset),
        d (N,3) unit float64; skip_prim (N,) primitive each ray leaves (-1 none)."""
        n = len(o)
        if self._embree is None or n == 0:
            return Hit(np.full(n, -1, np.int64), np.full(n, np.inf), np.zeros(n), np.zeros(n), np.zeros((1, 12)))
        o32 = np.ascontiguousarray(o, np.float32)
        d32 = np.ascontiguousarray(d, np.float32)
        tfar = np.full(n, 1e30, np.float32) if tmax is None else np.minimum(tmax, 1e30).astype(np.float32)
        r = self._run(o32, d32, tfar.copy(), "INTERSECT")  # Embree writes hit distances into it
        prim = self._prims(r["primID"])
        t = r["tfar"].astype(np.float64)
        b1, b2 = r["u"].astype(np.float64), r["v"].astype(np.float64)
        if skip_prim is not None:
            self._retrace_self_hits(o32, d32, tfar, skip_prim, prim, t, b1, b2)
        t[prim < 0] = np.inf
        return Hit(prim, t, b1, b2, self.rows)

    def _retrace_self_hits(self, o32, d32, tfar, skip_prim, prim, t, b1, b2):
        """Rays that re-hit the triangle they leave are traced again from just through its
        plane (in place; rare: the origin offset already avoids most)."""
        active = np.flatnonzero((prim >= 0) & (prim == skip_prim))
        t_base = np.zeros(len(active))
        for _ in range(2):
            if len(active) == 0:
                return
            hp = prim[active]
            step = t[active] - t_base
            through = self.ng[hp] * np.sign(np.einsum("ij,ij->i", d32[active], self.ng[hp]))[:, None]
            o_new = offset_origin(o32[active] + step[:, None] * d32[active], through)
            t_base = t[active]
            r = self._run(o_new, d32[active], np.maximum(tfar[active] - step, 0).astype(np.float32), "INTERSECT")
            again_prim = self._prims(r["primID"])
            prim[active] = again_prim
            t[active] = t_base + r["tfar"]
            b1[active], b2[active] = r["u"], r["v"]
            keep = (again_prim >= 0) & (again_prim == skip_prim[active])
            active, t_base, o32 = active[keep], t_base[keep], o32
            o32[active] = o_new[keep]
        prim[active] = -1  # still on its own triangle after two steps through: degenerate, a miss
        t[active] = np.inf

    def occluded(self, o: np.ndarray, target: np.ndarray, skip_prim: np.ndarray = None,
                 target_prim: np.ndarray = None) -> np.ndarray:
        """(N,) bool: is the segment from o (N,3) to target (N,3) blocked (it stops 1e-4 of the
        way short of the target). Embree's occlusion query cannot skip primitives, so the
        segments it reports blocked are confirmed by a closest-hit query that skips the
        triangle the ray leaves (skip_prim) and ignores the emitter it aims at (target_prim,
        -1 none): at coordinates of 1e4 float32 rounding otherwise lets a few percent of shadow
        rays hit one of those two."""
        n = len(o)
        if self._embree is None or n == 0:
            return np.zeros(n, bool)
        o32 = np.ascontiguousarray(o, np.float32)
        d32 = (np.asarray(target, np.float64) - o32).astype(np.float32)
        tfar = np.full(n, 1.0 - SHADOW_EPSILON, np.float32)
        blocked = self._run(o32, d32, tfar, "OCCLUDED") >= 0
        rows = np.flatnonzero(blocked)
        if len(rows) and (skip_prim is not None or target_prim is not None):
            seg = d32[rows].astype(np.float64)
            length = np.sqrt(seg[:, 0] ** 2 + seg[:, 1] ** 2 + seg[:, 2] ** 2)
            unit = seg / np.where(length > 0, length, 1.0)[:, None]
            hit = self.intersect(o32[rows], unit, length * (1.0 - SHADOW_EPSILON),
                                 None if skip_prim is None else skip_prim[rows])
            real = hit.prim >= 0
            if target_prim is not None:
                real &= hit.prim != target_prim[rows]
            blocked[rows] = real
        return blocked


BLOCK_MIN = 1 << 17  # triangles of an object that gets an Embree scene of its own
MAX_BLOCKS = 4  # Embree calls per query at most (the biggest objects get their own)
BUILT = [0]  # Embree scenes built by this process (tests)


def blocks(mesh: Mesh) -> list[tuple[int, int]]:
    """Triangle ranges [a, b) that get an Embree scene each: every object (Mesh.objects) of at
    least BLOCK_MIN triangles alone, the rest together between them. A scene without such
    objects is one block. A big object's scene then survives edits elsewhere (an object
    moved, added or deleted), at the price of one more Embree call per query and block:
    embreex offers neither instances nor refits, which would do the same inside Embree."""
    n = mesh.n_triangles
    if n == 0:
        return []
    bounds = getattr(mesh, "objects", None)
    if bounds is None:
        return [(0, n)]
    cuts = {0, n}
    size = np.diff(bounds)
    for i in np.argsort(-size, kind="stable")[:MAX_BLOCKS - 1]:
        if size[i] >= BLOCK_MIN:
            cuts |= {int(bounds[i]), int(bounds[i + 1])}
    cuts = sorted(cuts)
    return list(zip(cuts[:-1], cuts[1:]))


def bounding_radius(v: np.ndarray) -> float:
    if len(v) == 0:
        return 1.0
    lo, hi = v.min(axis=0).astype(np.float64), v.max(axis=0).astype(np.float64)
    return max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)
