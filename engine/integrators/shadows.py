"""Shadow rays as Cycles casts them: through transparent surfaces (its transparent shadows,
integrator/intersect_shadow.h and shade_shadow.h), from origins the shadow terminator's
Geometry Offset lifts (light/sample.h), blocked only by an emitter's blockers (shadow linking);
and the Shading Offset's factor on the BSDF (closure/bsdf.h), which belongs with them.

A shadow ray is blocked by any surface whose material has no transparent closure. Surfaces
of materials with one (Transparent BSDF, Principled Alpha, alpha from a texture) let it
through, multiplying its throughput by their transparency at the hit (the sum of their
transparent closures' weights, textures and nodes evaluated there); a ray crossing more of
them than the path's transparent bounces left (transparent_max_bounce minus the path's
transparent bounces) is blocked, as Cycles records at most that many hits.

Wavefront: one occlusion query against the opaque triangles settles every ray blocked by one
of them and every ray that sees no transparent triangle either; the others step through the
transparent triangles alone, one closest-hit query for all live rays per step, each
re-traced from just past the surface it crossed. A scene without transparent materials makes
the one occlusion query it always made.
"""
from __future__ import annotations

import numpy as np

from ..accel import SHADOW_EPSILON, offset_origin
from ..bsdf.closure import Closure
from ..nodes import light_path
from ..nodes.hits import RayState
from ..scene import LINK_ALL, LOBE_TRANSPARENT, RAY_SHADOW
from ..vec import dot, scale, take
from .surface import flat_normals, shading_frame

ALL = int(LINK_ALL)


def transparent_materials(materials) -> np.ndarray:
    """(M,) bool: materials with a transparent lobe (Cycles' SD_HAS_TRANSPARENT_SHADOW)."""
    out = np.zeros(len(materials.kind), bool)
    out[materials.lobe_material[materials.lobe_kind == LOBE_TRANSPARENT]] = True
    return out


class ShadowRays:
    """The shadow rays of one render. trace() answers which segments light passes and with
    what transmittance."""

    def __init__(self, scene, visibility, programs=None, links=None):
        """visibility: the render's RayVisibility (shadow rays see what RAY_SHADOW sees);
        programs: the scene's MaterialPrograms (textured transparency); links: the LightSet's
        light linking (engine/lights/linking.py), or None."""
        self.scene, self.programs = scene, programs
        self.geometry_offset, self.shading_offset = terminator_offsets(scene.mesh)
        self.limit = int(scene.settings.transparent_bounces)
        self.links = links if links is not None and links.shadow_linked else None
        mesh = scene.mesh
        self.transparent = transparent_materials(scene.materials)
        self.any_transparent = bool(self.transparent.any())
        self.accel = visibility.accel
        self.seen = None if mesh.visibility is None else (mesh.visibility & RAY_SHADOW) != 0
        self.flat_normal = flat_normals(mesh) if self.any_transparent else None
        self._views = {ALL: self._build(visibility.views.get(RAY_SHADOW, visibility.accel), None)}

    def _build(self, full, blocks):
        """(full, opaque, clear): the Embree views of the triangles that shadow a light, and of
        its opaque and transparent ones (None without transparent materials); full: that view
        if built already, else None; blocks (T,) bool or None: the light's blockers (shadow
        linking)."""
        mesh = self.scene.mesh
        seen = self.seen
        if blocks is not None:
            seen = blocks if seen is None else seen & blocks
        if full is None:
            full = self.accel if seen is None else self.accel.subset(np.flatnonzero(seen), mesh)
        if not self.any_transparent:
            return full, None, None
        seen = np.ones(mesh.n_triangles, bool) if seen is None else seen
        see_through = self.transparent[mesh.material]
        return (full, self.accel.subset(np.flatnonzero(seen & ~see_through), mesh),
                self.accel.subset(np.flatnonzero(seen & see_through), mesh))

    def _views_of(self, mask):
        mask = int(mask)
        if mask not in self._views:
            self._views[mask] = self._build(None, self.links.blockers(np.uint64(mask)))
        return self._views[mask]

    def origin(self, p, n_off, prim, bary=None, n_smooth=None, ng=None, wi=None):
        """(o32 (K,3) float32, skip (K,)) the shadow rays' origins at points p (K,3) on
        triangles prim (K,), pushed off the surface to n_off's side, and the triangle each
        may skip (-1 none). Smooth triangles of objects with a shadow terminator Geometry
        Offset first rise by terminator_lift (bary (K,3), n_smooth the shading normal before
        normal maps, ng the geometric normal, both toward the viewer, wi toward the light)."""
        if self.geometry_offset is None or bary is None:
            return offset_origin(p, n_off), prim
        cutoff = self.geometry_offset[prim].astype(np.float64)
        if not np.any(cutoff > 0):
            return offset_origin(p, n_off), prim
        lift, keep = terminator_lift(self.scene.mesh, prim, bary, p, n_smooth, ng, wi, cutoff)
        return offset_origin(p + lift, n_off), np.where(keep, prim, -1)

    def lifted(self, prim):
        """(K,) bool where shadow rays from triangles prim (K,) may rise by the terminator
        offset (the BSDF there is Cycles', judged by the shading normal alone), or None."""
        return None if self.geometry_offset is None else self.geometry_offset[prim] > 0

    def shading_factor(self, prim, ns, wi):
        """(K,) the Shading Offset's factor on the BSDF at triangles prim (K,) for light from
        wi (K,3) (shift_cos_in against the shading normal ns), or None where no object has one."""
        if self.shading_offset is None:
            return None
        return shift_cos_in(dot(ns, wi), self.shading_offset[prim])

    def trace(self, o32, target, skip_prim=None, target_prim=None, passed=None, light=None):
        """Shadow segments from o32 (N,3) float32 (already offset) to target (N,3):
        (lit, T): lit (L,) the rows light reaches, T (L,3) its transmittance there, or None
        (all 1: no transparent surface in the scene). skip_prim (N,) the triangle each ray
        leaves, target_prim (N,) the emitter it aims at (-1 none); passed (N,) transparent
        bounces the paths made (None: 0); light (N,) the emitters aimed at (shadow linking:
        only their blockers shadow them), or None."""
        if self.links is None or light is None:
            return self._trace(self._views[ALL], o32, target, skip_prim, target_prim, passed)
        mask = self.links.block[light]
        lit, T = [], []
        for m in np.unique(mask).tolist():
            rows = np.flatnonzero(mask == np.uint64(m))
            pick = lambda a: None if a is None else a[rows]  # noqa: E731
            r, t = self._trace(self._views_of(m), o32[rows], target[rows], pick(skip_prim), pick(target_prim),
                               pick(passed))
            lit.append(rows[r])
            T.append(t)
        lit = np.concatenate(lit)
        order = np.argsort(lit, kind="stable")
        return lit[order], None if T[0] is None else np.concatenate(T)[order]

    def _trace(self, views, o32, target, skip_prim, target_prim, passed):
        """trace() against one light's views (_build)."""
        full, opaque, clear = views
        if opaque is None:
            return np.flatnonzero(~full.occluded(o32, target, skip_prim, target_prim)), None
        clear_rows = np.flatnonzero(~opaque.occluded(o32, target, skip_prim, target_prim))
        T = np.ones((len(clear_rows), 3))
        if len(clear_rows) == 0:
            return clear_rows, T
        target = np.asarray(target, np.float64)
        o = np.ascontiguousarray(o32, np.float32)[clear_rows]
        end = target[clear_rows]
        skip = np.full(len(clear_rows), -1, np.int64) if skip_prim is None else skip_prim[clear_rows]
        aim = None if target_prim is None else target_prim[clear_rows]
        left = np.full(len(clear_rows), self.limit, np.int64)
        passed = None if passed is None else np.asarray(passed, np.int64)[clear_rows]
        if passed is not None:
            left = np.maximum(left - passed, 0)
        # Each step stops the same distance short of the target as the first segment does.
        margin = SHADOW_EPSILON * np.linalg.norm(end - o.astype(np.float64), axis=1)
        live = np.arange(len(clear_rows))
        blocked = np.zeros(len(clear_rows), bool)
        while len(live):
            seg = end[live] - o[live].astype(np.float64)
            length = np.linalg.norm(seg, axis=1)
            d = seg / np.where(length > 0, length, 1.0)[:, None]
            hit = clear.intersect(o[live], d, np.maximum(length - margin[live], 0.0), skip[live])
            found = hit.prim >= 0
            if aim is not None:
                found &= hit.prim != aim[live]
            k = np.flatnonzero(found)
            if len(k) == 0:
                break
            rows, h = live[k], hit.take(k)
            left[rows] -= 1
            T[rows] *= self._transparency(h, take(d, k), None if passed is None else passed[rows])
            dead = (left[rows] < 0) | np.all(T[rows] == 0.0, axis=1)
            blocked[rows[dead]] = True
            go = np.flatnonzero(~dead)
            rows, dk = rows[go], take(d, k[go])
            ng = h.ng[go]
            through = scale(ng, np.where(dot(dk, ng) >= 0, 1.0, -1.0))
            o[rows] = offset_origin(h.p[go], through)
            skip[rows] = h.prim[go]
            live = rows
        keep = np.flatnonzero(~blocked)
        return clear_rows[keep], T[keep]

    def _transparency(self, hit, d, passed) -> np.ndarray:
        """(K,3) the transparent closures' summed weight at K shadow-ray hits along d (K,3)
        (Cycles' surface_shader_transparency), the material's nodes evaluated for a shadow ray."""
        mesh = self.scene.mesh
        wo = -d
        ng, ns = shading_frame(mesh, self.flat_normal, hit.prim, hit.b, hit.ng, wo)
        ray = RayState(np.uint32(light_path.SHADOW), transparent_bounce=0 if passed is None else passed)
        bsdf = Closure(self.scene, mesh.material[hit.prim], ns, ng, wo, hit.prim, hit.b, programs=self.programs,
                       p=hit.p, ray=ray)
        return bsdf.transparency()


def terminator_offsets(mesh):
    """Per triangle (T,) float32 each, or None where no triangle has one: Cycles' shadow
    terminator Geometry Offset of the triangle's object where the triangle is smooth-shaded
    (its corner normals differ: Cycles' SHADER_SMOOTH_NORMAL), and the frequency multiplier
    of its Shading Offset s, 1 / (1 - s / 2) (Cycles' object sync), where that exceeds 1."""
    if mesh.terminator is None or mesh.objects is None or mesh.n_triangles == 0:
        return None, None
    per_object = np.asarray(mesh.terminator, np.float32)
    counts = np.diff(mesh.objects)
    geometry = shading = None
    if np.any(per_object[:, 0] > 0):
        geometry = np.repeat(per_object[:, 0], counts)
        n = mesh.normals
        geometry[np.all(n == n[:, :1], axis=(1, 2))] = 0.0
        if not np.any(geometry > 0):
            geometry = None
    multiplier = 1.0 / (1.0 - 0.5 * np.clip(per_object[:, 1], 0.0, 1.0))
    if np.any(multiplier > 1.0):
        shading = np.repeat(multiplier.astype(np.float32), counts)
    return geometry, shading


def shift_cos_in(cos_in: np.ndarray, multiplier: np.ndarray) -> np.ndarray:
    """(N,) Cycles' shading terminator factor (closure/bsdf.h shift_cos_in, after appleseed):
    max(cos(multiplier acos(cos_in)), 0) / cos_in for light on the shading normal's side
    (cos_in >= 0), 1 elsewhere and where multiplier <= 1."""
    c = np.minimum(cos_in, 1.0)
    lit = (c > 0.0) & (multiplier > 1.0)
    out = np.ones(len(c))
    angle = np.arccos(c[lit])
    out[lit] = np.maximum(np.cos(angle * multiplier[lit]), 0.0) / c[lit]
    out[(c == 0.0) & (multiplier > 1.0)] = 0.0
    return out


def terminator_lift(mesh, prim, b, p, n_smooth, ng, wi, cutoff):
    """(lift (K,3), skip (K,) bool) of shadow rays leaving smooth triangles prim (K,) at points
    p (K,3) (barycentrics b (K,3)) toward wi (K,3) (Cycles' light/sample.h shadow_ray_offset):
    near the terminator (the light grazing the shading normal n_smooth or the geometric normal
    ng, both on the viewer's side, within `cutoff` (K,) in cosine) the origin rises onto a
    parabolic surface through the corners with their normals (Hanika, "Hacking the shadow
    terminator"), blending in over the cutoff; skip: the ray may still skip its own triangle
    (the light is on ng's side)."""
    NL = dot(n_smooth, wi)
    transmit = NL < 0.0
    NL = np.abs(NL)
    Ng = scale(ng, np.where(transmit, -1.0, 1.0))
    NgL = dot(Ng, wi)
    cut = np.maximum(cutoff, 1e-30)
    amount = np.where(NL < cutoff, np.clip(2.0 - (NgL + NL) / cut, 0.0, 1.0), np.clip(1.0 - NgL / cut, 0.0, 1.0))
    amount = np.where(cutoff > 0, amount, 0.0)
    lift = np.zeros((len(prim), 3))
    rows = np.flatnonzero(amount > 0)
    if len(rows) == 0:
        return lift, np.ones(len(prim), bool)
    V = mesh.vertices[mesh.triangles[prim[rows]]].astype(np.float64)  # (K,3 corners,3)
    N = mesh.normals[prim[rows]].astype(np.float64)
    u, v = b[rows, 0], b[rows, 1]
    n = np.einsum("kc,kci->ki", b[rows], N)  # interpolated, not normalised (as Cycles)
    P = p[rows]
    a_ = dot(N[:, 2] - N[:, 0], V[:, 0] - V[:, 2])
    b_ = dot(N[:, 2] - N[:, 1], V[:, 1] - V[:, 2])
    c_ = dot(N[:, 1] - N[:, 0], V[:, 1] - V[:, 0])
    h = a_ * u * (u - 1.0) + (a_ + b_ + c_) * u * v + b_ * v * (v - 1.0)
    front = dot(n, Ng[rows]) > 0.0
    # The local linear envelope: the height over each corner's tangent plane, the lowest of three.
    e = np.empty((len(rows), 3))
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        sign = np.where(front, 1.0, -1.0)
        up = np.maximum(np.maximum(sign * dot(V[:, j] - V[:, i], N[:, i]), sign * dot(V[:, k] - V[:, i], N[:, i])), 0.0)
        e[:, i] = np.maximum(sign * dot(V[:, i] - P, N[:, i]) + up, 0.0)
    low = e.min(axis=1)
    h = np.where(front, np.maximum(low, 0.5 * h), np.minimum(-low, 0.5 * h))
    lift[rows] = scale(n, h * amount[rows])
    return lift, np.where(amount > 0, NgL > 0.0, True)
