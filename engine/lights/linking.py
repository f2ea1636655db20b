"""Light and shadow linking over a LightSet's emitters (Cycles' light sets,
kernel/light/light.h light_link_light_match and light_link_object_match).

Every triangle belongs to a receiver set and a blocker set (its object's: Mesh.link_sets);
every emitter (analytic light, emissive triangle by its object, the world) has a mask of the
receiver sets it lights and of the blocker sets that shadow it. A point on a triangle of
receiver set s is lit by emitter i only where bit s of i's receiver mask is set: i is then
neither light-sampled there nor counted when a ray leaving it finds i. Rays without a vertex
behind them (camera rays: receiver -1) see every emitter. A shadow ray toward emitter i is
blocked only by triangles whose blocker set is in i's blocker mask.
"""
from __future__ import annotations

import numpy as np

from ..scene import LINK_ALL

ALL = np.uint64(LINK_ALL)


class Links:
    def __init__(self, lights, mesh, tri_prim: np.ndarray, count: int):
        """lights: Scene.lights; mesh: Scene.mesh; tri_prim (E,) the emissive triangles (the
        LightSet's emitters L .. L+E-1); count: the LightSet's emitters (the world last)."""
        n_analytic = len(lights.kind)
        self.n_triangles = mesh.n_triangles
        self.receive = np.full(count, ALL, np.uint64)
        self.block = np.full(count, ALL, np.uint64)
        if lights.links is not None:
            self.receive[:n_analytic] = lights.links[:, 0]
            self.block[:n_analytic] = lights.links[:, 1]
        self.tri_receiver = self.tri_blocker = None
        if mesh.link_sets is not None and mesh.objects is not None:
            counts = np.diff(mesh.objects)
            self.tri_receiver = np.repeat(mesh.link_sets[:, 0].astype(np.int64), counts)
            self.tri_blocker = np.repeat(mesh.link_sets[:, 1].astype(np.int64), counts)
            if len(tri_prim):
                obj = np.searchsorted(mesh.objects, tri_prim, side="right") - 1
                self.receive[n_analytic:n_analytic + len(tri_prim)] = mesh.link_membership[obj, 0]
                self.block[n_analytic:n_analytic + len(tri_prim)] = mesh.link_membership[obj, 1]
        self.light_linked = bool(np.any(self.receive != ALL))
        self.shadow_linked = bool(np.any(self.block != ALL))
        # The receiver sets present (set 0 always: the objects in no collection, or none at all).
        self.sets = np.unique(np.concatenate([[0], self.tri_receiver])) if self.tri_receiver is not None else np.zeros(1, np.int64)

    @property
    def active(self) -> bool:
        return self.light_linked or self.shadow_linked

    def receiver(self, prim: np.ndarray) -> np.ndarray:
        """(N,) receiver set of the points on triangles prim (N,); -1 where prim < 0 (no vertex)."""
        if self.tri_receiver is None:
            return np.where(np.asarray(prim) < 0, -1, 0)
        return np.where(prim < 0, -1, self.tri_receiver[np.maximum(prim, 0)])

    def lights(self, index, receiver) -> np.ndarray:
        """(N,) bool: emitters index (N,) light points of receiver sets receiver (N,) (-1: all)."""
        mask = self.receive[index]
        bit = np.left_shift(np.uint64(1), np.maximum(receiver, 0).astype(np.uint64))
        return (receiver < 0) | ((mask & bit) != 0)

    def lit_mask(self, receiver_set: int) -> np.ndarray:
        """(count,) bool: the emitters that light receiver set receiver_set."""
        return (self.receive & np.left_shift(np.uint64(1), np.uint64(receiver_set))) != 0

    def blockers(self, mask: np.uint64) -> np.ndarray | None:
        """(T,) bool: the triangles that shadow an emitter of blocker mask `mask` (None: all)."""
        if mask == ALL:
            return None
        if self.tri_blocker is None:  # every triangle in set 0
            return np.full(self.n_triangles, bool(np.uint64(mask) & np.uint64(1)))
        return (np.right_shift(np.uint64(mask), self.tri_blocker.astype(np.uint64)) & np.uint64(1)) != 0
