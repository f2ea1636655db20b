"""Ray visibility (Cycles' object visibility): which triangles each kind of ray can hit.

embreex has no per-ray masks or filter callbacks, so each ray kind whose view differs from
the full scene gets its own Embree scene over the triangles it sees (Accel.subset; kinds
that see the same triangles share one). A scene without hidden objects uses the one full
Accel and costs nothing more; with them, a bounce makes one Embree call per ray kind present.
"""
from __future__ import annotations

import numpy as np

from .accel import Accel, Hit
from .scene import HOLDOUT, RAY_CAMERA, RAY_DIFFUSE, RAY_GLOSSY, RAY_SHADOW, RAY_TRANSMIT, Mesh

KINDS = (RAY_CAMERA, RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMIT, RAY_SHADOW)


class RayVisibility:
    def __init__(self, accel: Accel, mesh: Mesh):
        self.accel = accel
        vis = mesh.visibility
        self.views = {}  # ray kind -> Accel, only for kinds that do not see everything
        self.holdout = None  # (T,) bool where camera rays see a hole, or None
        if vis is None:
            return
        shared = {}
        for kind in KINDS:
            seen = (vis & kind) != 0
            if seen.all():
                continue
            key = seen.tobytes()
            if key not in shared:
                shared[key] = accel.subset(np.flatnonzero(seen), mesh)
            self.views[kind] = shared[key]
        if np.any(vis & HOLDOUT):
            self.holdout = (vis & HOLDOUT) != 0

    @property
    def trivial(self) -> bool:
        return not self.views and self.holdout is None

    def intersect(self, o32, d, tmax, skip, kind: np.ndarray) -> Hit:
        """Accel.intersect for rays of kinds `kind` (N,) (one RAY_* bit each)."""
        hidden = [k for k in np.unique(kind).tolist() if k in self.views] if self.views else []
        if not hidden:
            return self.accel.intersect(o32, d, tmax, skip)
        n = len(d)
        out = Hit(np.empty(n, np.int64), np.empty(n), np.empty(n), np.empty(n), self.accel.rows)
        groups = [(self.views[k], np.flatnonzero(kind == k)) for k in hidden]
        rest = np.flatnonzero(~np.isin(kind, hidden))
        if len(rest):
            groups.append((self.accel, rest))
        for accel, rows in groups:
            h = accel.intersect(o32[rows], d[rows], None if tmax is None else tmax[rows],
                                None if skip is None else skip[rows])
            for name in ("prim", "t", "_b1", "_b2"):
                getattr(out, name)[rows] = getattr(h, name)
        return out
