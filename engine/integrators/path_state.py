"""A wavefront's paths: the per-path arrays of a batch that advances one bounce at a time.

Every tracer here moves a batch of paths bounce by bounce - camera and gather paths
(path.py), photons (photon/tracing.py), final-gathering rays (photon/integrator.py) - with
one Embree call for all live rays, then shading over the hits; after each step the paths
that ended are dropped, and path regeneration appends fresh ones. A PathState holds those
arrays, one row per path, and compacts (`take`) and extends (`join`) all of them at once.

A path is either on a ray (o64, o32, d, tmax, skip) or, after `arrive`, at a vertex (prim,
mat, p, ng, ns, bary; d is then the direction it arrived along); `leave` puts it on its
next ray. Arrays that a phase or a tracer does not use are None, and None costs nothing:
compaction copies only the arrays that exist. Where every path is at the same bounce,
`depth` (and the counts in Bounces) are scalars rather than per-path arrays.
"""
from __future__ import annotations

import numpy as np

from ..accel import Hit, offset_origin
from ..bsdf.closure import LABEL_DIFFUSE, LABEL_GLOSSY, LABEL_TRANSMIT, LABEL_TRANSPARENT
from ..nodes import light_path as lp
from ..nodes.hits import RayState
from ..scene import RAY_CAMERA, RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMIT
from ..visibility import RayVisibility
from .surface import towards

_RAY_OF_LABEL = np.array([RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMIT, RAY_CAMERA], np.uint8)  # per LABEL_*
# Cycles' path flag bits a bounce of each LABEL_* sets (integrator/path_state.h path_state_next;
# a transparent bounce adds TRANSPARENT to the flags it keeps), SINGULAR besides where delta.
_FLAG_OF_LABEL = np.array([lp.REFLECT | lp.DIFFUSE, lp.REFLECT | lp.GLOSSY, lp.TRANSMIT | lp.GLOSSY, 0], np.uint32)
_CLEARED = np.uint32(~((1 << 11) - 1 | lp.MIS_SKIP) & 0xFFFFFFFF)  # ~(PATH_RAY_ALL_VISIBILITY | MIS_SKIP)


def rows_of(x, rows):
    """x[rows], or x itself when it is one value for all paths."""
    return x if np.ndim(x) == 0 else x[rows]


def _gather(a: np.ndarray, rows) -> np.ndarray:
    """a[rows] for an (N,...) array: ndarray.take for rows of several columns (several times
    faster than fancy indexing on (N,3)), fancy indexing for 1-D (no call overhead)."""
    return a[rows] if a.ndim == 1 else a.take(rows, axis=0)


class PathState:
    """The live paths of a wavefront, row i being path i. Arrays (N,...) or None:

    idx      (N,) int64: the path's row in the tracer's output (its pixel sample, gather ray...)
    o64      (N,3) float64 ray origins (the previous vertex); o32 (N,3) float32 the same
             offset off their surface; d (N,3) unit directions; tmax (N,) or None: no limit;
             skip (N,) int64: the primitive each ray leaves (-1 none)
    prim, mat  (N,) int64: the triangle hit and its material
    p, ng    (N,3): the vertex (float64) and the geometric normal (once shaded: flipped to
             the side the ray came from); ns (N,3) the shading normal; bary (N,3) or None
    beta     (N,3): throughput (photons: flux)
    pdf_prev (N,): q p_b of the bounce that produced the ray (MIS weights of the emission
             it finds); no_mis (N,) bool: that emission counts with weight 1
    t_mis    (N,) or None (no transparent surface): how far the ray's origin lies along it
             from the last vertex that was not a transparent pass, where its MIS state was
             made (Cycles' transparent passes go on with the same ray); at a vertex, from
             there to the vertex. With it pdf_prev and no_mis stay with the path at its vertex.
    receiver (N,) int64 or None (no light linking): the receiver set of that vertex (light
             linking: the lights the ray may find; -1 for camera rays: all)
    specular (N,) bool: every vertex so far was specular (caustic paths; None: not kept)
    medium   (N,) int64: the material whose medium the path is in (-1 none), volume_bounces
             (N,) its scattering events in media (both None without media: integrators/media.py);
             mis_pdf, mis_off (N,): the ray's pdf_prev and no_mis kept to the vertex, where a
             pass through a volume-only boundary hands them on (None without media)
    depth    bounces so far (rays traced - 1): an int, or (N,) int64 with regeneration
    bounces  Bounces (the light-path limits' counts) or None
    """

    __slots__ = ("idx", "o64", "o32", "d", "tmax", "skip", "prim", "mat", "p", "ng", "ns", "bary",
                 "beta", "pdf_prev", "no_mis", "t_mis", "receiver", "specular", "medium", "volume_bounces",
                 "mis_pdf", "mis_off", "depth", "bounces")
    # Per-path arrays, compacted and joined alike (depth and bounces are handled apart), and
    # those a path carries from its ray to the vertex it arrives at.
    _ARRAYS = __slots__[:-2]
    _CARRIED = ("idx", "d", "beta", "specular", "medium", "volume_bounces", "mis_pdf", "mis_off")
    _SPENT = ("o64", "o32", "tmax", "skip", "prim", "mat", "p", "ng", "ns", "bary", "pdf_prev", "no_mis", "t_mis",
              "receiver")
    _MIS = ("pdf_prev", "no_mis", "t_mis", "receiver")  # carried to the vertex with t_mis, else spent

    def __init__(self, idx: np.ndarray, depth=0, **fields):
        for name in self.__slots__:
            setattr(self, name, None)
        self.idx, self.depth = idx, depth
        for name, value in fields.items():
            setattr(self, name, value)

    @classmethod
    def rays(cls, o64, o32, d, tmax=None, skip=None, **fields) -> "PathState":
        """Paths on the rays o64/o32 (N,3) along d (N,3), rows 0 .. N-1 unless idx is given."""
        idx = fields.pop("idx", None)
        return cls(np.arange(len(d)) if idx is None else idx, o64=o64, o32=o32, d=d, tmax=tmax, skip=skip,
                   **fields)

    def __len__(self) -> int:
        return len(self.idx)

    def take(self, rows: np.ndarray) -> "PathState":
        """The paths `rows` (K,) int, in that order."""
        return self._take(rows, self._ARRAYS)

    def _take(self, rows, names, dropped=()) -> "PathState":
        """The paths `rows` (None: all, sharing the arrays) with the arrays `names`, those
        `dropped` None."""
        out = PathState.__new__(PathState)
        for name in names:
            a = getattr(self, name)
            setattr(out, name, a if a is None or rows is None else _gather(a, rows))
        for name in dropped:
            setattr(out, name, None)
        if rows is None:
            out.depth, out.bounces = self.depth, self.bounces
        else:
            out.depth = rows_of(self.depth, rows)
            out.bounces = None if self.bounces is None else self.bounces.take(rows)
        return out

    def join(self, other: "PathState") -> "PathState":
        """These paths followed by other's (both with per-path depth). A ray without a limit
        (tmax None) joins rays with one as tmax = inf."""
        out = PathState.__new__(PathState)
        for name in self._ARRAYS:
            a, b = getattr(self, name), getattr(other, name)
            if a is None and b is None:
                setattr(out, name, None)
            elif name == "tmax":
                setattr(out, name, np.concatenate([np.full(len(x), np.inf) if t is None else t
                                                   for x, t in ((self, a), (other, b))]))
            else:
                setattr(out, name, np.concatenate([a, b]))
        out.depth = np.concatenate([self.depth, other.depth])
        out.bounces = None if self.bounces is None else self.bounces.join(other.bounces)
        return out

    def intersect(self, accel, kind=None, t_first=None) -> Hit:
        """Closest hits of the paths' rays in accel (an Accel, or a RayVisibility given the
        rays' kinds (N,) RAY_* or None). t_first, if given, receives each ray's distance to its
        hit at rows idx (inf where it escaped)."""
        if isinstance(accel, RayVisibility):
            hit = accel.intersect(self.o32, self.d, self.tmax, self.skip, kind)
        else:
            hit = accel.intersect(self.o32, self.d, self.tmax, self.skip)
        if t_first is not None:
            t_first[self.idx] = np.where(hit.prim >= 0, hit.t, np.inf)
        return hit

    def arrive(self, hit: Hit, rows: np.ndarray, material: np.ndarray, bary: bool = True) -> "PathState":
        """The paths `rows` (K,) (those whose rays hit) at their hits: the rays are spent (d
        stays, the direction of arrival; their MIS state pdf_prev and no_mis goes with them:
        the emission they found is counted first), and the vertex is set: prim, mat from
        material (T,) per triangle, p, ng, bary if asked. Rays are dropped before their hit
        points are built (Hit is lazy)."""
        carried, spent = self._CARRIED, self._SPENT
        if self.t_mis is not None:
            carried, spent = carried + self._MIS, tuple(n for n in spent if n not in self._MIS)
        if len(rows) < len(self):
            out, hit = self._take(rows, carried, spent), hit.take(rows)
        else:
            out = self._take(None, carried, spent)
        if out.t_mis is not None:
            out.t_mis = out.t_mis + hit.t
        out.prim, out.p, out.ng = hit.prim, hit.p, hit.ng
        out.bary = hit.b if bary else None
        out.mat = material[out.prim]
        if out.bounces is not None and out.bounces.dP is not None:  # the footprint at the hit
            out.bounces.dP = out.bounces.dP + hit.t * out.bounces.dD
        return out

    def leave(self, rows: np.ndarray, wi: np.ndarray, beta: np.ndarray, reflects: bool = False) -> "PathState":
        """The paths `rows` (K,) on the rays leaving their vertices along wi (K,3), with
        throughput beta (K,3), one bounce deeper: origins offset off the surface on wi's side
        of ng (along ng itself when `reflects`: every direction is then on its side). Their
        bounces are taken, not yet counted; pdf_prev and no_mis are the caller's to set."""
        out = PathState(self.idx[rows], rows_of(self.depth, rows) + 1, d=wi, beta=beta, skip=self.prim[rows])
        out.o64 = self.p.take(rows, axis=0)
        n = self.ng.take(rows, axis=0)
        out.o32 = offset_origin(out.o64, n if reflects else towards(n, wi))
        if self.specular is not None:
            out.specular = self.specular[rows]
        if self.medium is not None:  # the caller changes it where the path crosses a boundary
            out.medium, out.volume_bounces = self.medium[rows], self.volume_bounces[rows]
        if self.bounces is not None:
            out.bounces = self.bounces.take(rows)
        return out


class Bounces:
    """Per-path bounce counts as Cycles' path_state_next keeps them, for the light-path
    limits. Arrays a scene does not need are None: total (N,) non-transparent bounces so
    far; last (N,) bool: the path is over a limit, its ray adds the emission it finds and
    goes on only through transparency (TERMINATE_AFTER_TRANSPARENT); stop (N,) bool: the
    transparent limit is reached, the next surface is the last (TERMINATE_ON_NEXT_SURFACE;
    None without transparent materials); counts (N,4) bounces per LABEL_* (None when no
    per-type limit is below the total); ray (N,) RAY_* kind of the path's ray: camera until
    the first non-transparent bounce, then that bounce's kind (None when nothing depends on
    it); min_pdf (N,) the smallest non-delta BSDF pdf so far (Cycles' min_ray_pdf; None
    without Filter Glossy). When none of these is kept and no surface is transparent, every
    path has made the same number of bounces: total and last are then scalars, unless the
    paths sit at different bounces (per_path: path regeneration). max_depth: the limit on
    total, the same for all paths.

    For node programs (track): flag (N,) uint32 Cycles' PATH_RAY_* bits of the path's ray
    (light_path.py; None when no program reads them); dP (N,) the ray footprint's radius at
    its origin, once arrived at the hit (sd->dP), and dD (N,) its spread per unit length
    (Cycles' compact differentials: at a hit dP + t dD, differential_transfer_compact; a
    bounce starts its ray with the hit's dP and keeps dD, shade_surface.h; None when no
    program reads dP); base: bounces the paths made before this trace (1 for gather rays
    leaving a surface), added to the counts a program reads."""

    __slots__ = ("total", "last", "stop", "counts", "ray", "min_pdf", "flag", "dP", "dD", "max_depth", "base")
    _ARRAYS = __slots__[:-2]

    @staticmethod
    def start(n: int, max_depth: int, stop=False, counts=False, ray=False, min_pdf=False,
              per_path=False) -> "Bounces":
        """n paths before their first bounce."""
        b = Bounces.__new__(Bounces)
        uniform = not (stop or counts or ray or min_pdf or per_path)
        b.total = np.int32(0) if uniform else np.zeros(n, np.int32)
        b.last = np.bool_(max_depth <= 0) if uniform else np.full(n, max_depth <= 0)  # 0: emission only
        b.stop = np.zeros(n, bool) if stop else None
        b.counts = np.zeros((n, 4), np.int32) if counts else None
        b.ray = np.full(n, RAY_CAMERA, np.uint8) if ray else None
        b.min_pdf = np.full(n, np.inf) if min_pdf else None
        b.flag = b.dP = b.dD = None
        b.max_depth, b.base = max_depth, 0
        return b

    def track(self, flag=None, dP=None, dD=None, base: int = 0) -> "Bounces":
        """Keep the path flags (flag (N,) uint32 of the first rays) and the ray differentials
        (dP, dD (N,) of the first rays) for node programs; base: see the class. In place."""
        self.flag, self.dP, self.dD, self.base = flag, dP, dD, base
        return self

    def take(self, rows) -> "Bounces":
        b = Bounces.__new__(Bounces)
        b.max_depth, b.base = self.max_depth, self.base
        b.total, b.last = (self.total, self.last) if np.ndim(self.total) == 0 else (self.total[rows], self.last[rows])
        for name in self._ARRAYS[2:]:
            v = getattr(self, name)
            setattr(b, name, None if v is None else v[rows])
        return b

    def join(self, other: "Bounces") -> "Bounces":
        """These paths followed by other's (both per path)."""
        b = Bounces.__new__(Bounces)
        for name in self._ARRAYS:
            v = getattr(self, name)
            setattr(b, name, v if v is None else np.concatenate([v, getattr(other, name)]))
        b.max_depth, b.base = self.max_depth, self.base
        return b

    def record(self, rows=None, t=None) -> RayState:
        """What node programs read of the paths (engine/nodes/hits.py RayState) at their
        vertices; with rows (K,) and t (K,): at the hits of those paths' rays, t along them
        (before arrive: where the emission the rays find is evaluated)."""
        def at(v):
            return v if rows is None or v is None or np.ndim(v) == 0 else v[rows]

        counts = at(self.counts)
        by_label = [self.base if label == LABEL_DIFFUSE else 0 for label in range(4)] if counts is None else \
            [counts[:, label] + (self.base if label == LABEL_DIFFUSE else 0) for label in range(4)]
        dP = at(self.dP)
        if dP is not None and t is not None:
            dP = dP + t * at(self.dD)
        min_pdf = np.inf if self.min_pdf is None else at(self.min_pdf)
        return RayState(lp.CAMERA if self.flag is None else at(self.flag), at(self.total) + self.base,
                        by_label[LABEL_DIFFUSE], by_label[LABEL_GLOSSY], by_label[LABEL_TRANSMIT],
                        by_label[LABEL_TRANSPARENT], dP, min_pdf)

    def count(self, bs, rows, limits: np.ndarray) -> "Bounces":
        """The counts after the bounce sampled in bs (BSDFSample) at rows (N,) (this state's
        paths); limits (4,) per LABEL_*. Updates in place (the arrays are this state's own)."""
        if self.flag is not None:
            self._flag(bs, rows)
        if self.counts is None and self.ray is None and self.min_pdf is None:  # every bounce counts alike
            self.total = self.total + 1  # scalars or arrays alike
            self.last = self.last | (self.total >= self.max_depth)
            return self
        label = bs.label[rows]
        see_through = label == LABEL_TRANSPARENT
        self.total += ~see_through
        over = self.total >= self.max_depth
        if self.counts is not None:
            i = np.arange(len(label))
            self.counts[i, label] += 1
            reached = self.counts[i, label] >= limits[label]
            over |= reached
            if self.stop is not None:  # tracked with counts (transparent materials)
                self.stop |= see_through & reached
        self.last |= ~see_through & over
        if self.ray is not None:
            self.ray = np.where(see_through, self.ray, _RAY_OF_LABEL[label])
        if self.min_pdf is not None:
            self.min_pdf = np.where(bs.delta[rows], self.min_pdf, np.minimum(self.min_pdf, bs.pdf[rows]))
        return self

    def _flag(self, bs, rows) -> None:
        """Cycles' path_state_next on the flags: a transparent bounce adds TRANSPARENT to the
        flags it keeps; any other clears the ray kind (and MIS_SKIP) and sets REFLECT or TRANSMIT
        and DIFFUSE, GLOSSY or GLOSSY | SINGULAR (a delta lobe) by the bounce's label."""
        label = bs.label[rows]
        new = _FLAG_OF_LABEL[label] | np.where(bs.delta[rows] & (label != LABEL_DIFFUSE), np.uint32(lp.SINGULAR),
                                               np.uint32(0))
        self.flag = np.where(label == LABEL_TRANSPARENT, self.flag | np.uint32(lp.TRANSPARENT),
                             (self.flag & _CLEARED) | new).astype(np.uint32)
