"""All emitters of a scene behind one interface: choose one by power, sample it, evaluate it.

Lights are the analytic ones of `Scene.lights` (indices 0..L-1), the emissive triangles
(L..L+E-1) and, last, the world's light when the world varies (index L+E): an environment
image's map (environment.EnvironmentMap) or a node program's table (world.WorldMap; see
world.world_emitters). A constant world is not sampled (BSDF sampling covers it well); rays
that escape the scene collect the world through `escaped` - the image's pixel, or the
program's value for the ray's kind and bounces (Light Path) - with the balance heuristic
against the world's light-sampling pdf. Like Cycles, light objects
are not geometry: they neither occlude shadow rays nor stop other rays; a ray passing through
one collects its emission.
Emissive triangles are ordinary (two-sided) geometry found through `light_of_prim`.

Many lights: from TREE_MIN_LIGHTS finite lights on (analytic lights other than suns, and
emissive triangles) spread over TREE_MIN_SPREAD of the scene or more, a light tree (`light_tree`) chooses among them by their estimated
contribution at the shading point; the infinite lights (suns, environment) keep their share of
the power, P_inf, and are chosen among themselves by power. The pmf of a finite light then
depends on the shading point: `pmf(index, p)`, also for the emitter-hit MIS weights (the
previous vertex of the ray, the point NEE would have sampled from).

Seed 000: one light per shading point, chosen with probability proportional to its power;
that pmf enters every light-sampling pdf (also the one used for the emitter-hit MIS weight).
As Cycles, a light of negative strength emits negative radiance and is chosen by |power|
(the estimate of a signed integrand stays unbiased). Lights of zero power (a sun in a scene
without geometry, a zero-width spot cone) are never chosen; with no power at all nothing is
light-sampled (`empty`) and emission is found by rays only, with MIS weight 1.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import sampling
from ..scene import LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN, RAY_ALL, RAY_CAMERA, Lights, Materials, Mesh, World
from ..nodes import light_path as lp
from ..nodes.hits import EMISSION_RAY, RayState
from ..vec import dot, max3, scale, take
from . import light_shader, light_tree, linking, shapes, world as world_light
from .emission_maps import EmissionMaps

# From this many finite lights on, a light tree chooses them (below: power alone, as the seed
# says): below it the tree's cost per shading point is not reliably repaid at equal time
# (measured in bench/results/many_lights/report.md).
TREE_MIN_LIGHTS = 32
# ... and only when the lights spread over at least this share of the scene's bounding radius:
# lights clustered far from most receivers (a chandelier, an emissive sphere of many triangles)
# are all at about the same distance and orientation from a shading point, where the tree's
# choice is power selection at a higher price.
TREE_MIN_SPREAD = 0.25


def avg(c: np.ndarray) -> np.ndarray:
    """Mean of RGB: the scalar 'power' of a colour (never 0 for a non-black colour)."""
    return np.asarray(c, np.float64).mean(axis=-1)


@dataclass(frozen=True, slots=True)
class LightSample:
    """One light sample for each of N shading points p.

    wi (N,3) unit direction from p to the light; Le (N,3) radiance arriving along -wi
    (W/(m^2 sr); delta lights: the irradiance at normal incidence, W/m^2); pdf (N,) solid-angle
    pdf (1/sr) times the selection pmf, for delta lights the pmf alone, 0 where not valid;
    delta (N,) bool; target (N,3) the point sampled on the light (m), p + wi 1e30 for the
    infinitely far ones (suns, environment); target_prim (N,) int64 emissive triangle the
    target lies on, -1 for other lights; finite (N,) bool, False where target stands for
    infinity (the occlusion test of p -> target then runs to infinity); valid (N,) bool, False
    where nothing can be sampled (pdf 0 or radiance 0); visibility (N,) uint8 RAY_* bits of the
    lights sampled (which lobes they light), None when every light lights all lobes.
    """

    wi: np.ndarray
    Le: np.ndarray
    pdf: np.ndarray
    delta: np.ndarray
    target: np.ndarray
    target_prim: np.ndarray
    finite: np.ndarray
    valid: np.ndarray
    visibility: np.ndarray | None = None
    light: np.ndarray | None = None  # (N,) the emitters sampled, where light linking needs them


class LightSet:
    def __init__(self, lights: Lights, mesh: Mesh, materials: Materials, world: World, accel, scene_radius: float,
                 strategy: str = "mis", tree_min_lights: int | None = None, surface_emission=None, camera=None):
        """strategy: Settings.strategy; under "mis" the environment's table is MIS-compensated.
        tree_min_lights: the light tree's threshold (default TREE_MIN_LIGHTS).
        surface_emission: for materials whose emission varies over the surface (textured
        emitters), an object with `varying` (M,) bool per material and a call (prim, bary, p,
        n, wo) -> (K,3) radiance at points of triangles (engine/nodes/material.py
        SurfaceEmission), or None. Such triangles are chosen by their mean radiance and sampled
        by their emission maps (emission_maps.py); a sample's radiance is the material's at its
        point. camera: the scene's Camera, for a world program's Camera and Window coordinates
        (None: at the origin, looking down -z)."""
        self.lights = lights
        self.n_analytic = len(lights)
        self.scene_radius = scene_radius
        # Lights whose shader varies: their programs multiply Le per sample and hit.
        self.shaders = light_shader.LightShaders(lights) if lights.graphs else None
        # Emissive triangles.
        tri_Le = materials.emission[mesh.material] if mesh.n_triangles else np.zeros((0, 3))
        emissive = np.any(tri_Le != 0, axis=-1) & (accel.area > 0) if mesh.n_triangles else np.zeros(0, bool)
        self.tri_prim = np.flatnonzero(emissive)
        self.tri_Le = tri_Le[self.tri_prim]
        self.surface_emission, self.tri_varying, self.maps = surface_emission, None, None
        if surface_emission is not None and len(self.tri_prim):
            varying = surface_emission.varying[mesh.material[self.tri_prim]]
            if varying.any():
                self.tri_varying = varying
                self.map_row = np.cumsum(varying) - 1  # a varying triangle's row in the maps
                self.maps = EmissionMaps(int(varying.sum()),
                                         lambda i, b: self._emission_at(accel, self.tri_prim[varying][i], b))
                self.tri_Le[varying] = self.maps.mean
        self.tri_area = accel.area[self.tri_prim]
        self.tri_v0 = accel.v0[self.tri_prim]
        self.tri_e1 = accel.e1[self.tri_prim]
        self.tri_e2 = accel.e2[self.tri_prim]
        self.tri_ng = accel.ng[self.tri_prim]
        # One row per emissive triangle (v0, e1, e2, ng, area): light samples read one row, not five.
        self.tri_rows = np.concatenate([self.tri_v0, self.tri_e1, self.tri_e2, self.tri_ng, self.tri_area[:, None]],
                                       axis=1)
        self.tri_lit = max3(np.abs(self.tri_Le)) > 0 if len(self.tri_Le) else np.zeros(0, bool)
        self.light_of_prim = np.full(max(mesh.n_triangles, 1), -1, np.int64)
        self.light_of_prim[self.tri_prim] = self.n_analytic + np.arange(len(self.tri_prim))
        # World: a constant radiance (not sampled), or an image's map or a node program with its
        # table (sampled, last index); `background` the program escaped rays evaluate.
        self.world, self.background, self.env = world_light.world_emitters(world, strategy == "mis", camera)
        bg = self.background
        # What the world's Light Path reads of the paths: integrators give their RayStates then.
        self.world_reads = bg.reads_path if bg is not None else frozenset()
        self.world_reads_camera = bg is not None and bg.reads_camera  # the table follows the camera
        self.world_visible = bool(world.visible)
        # Environment power as pbrt-v4's infinite lights: pi R^2 x integral of L over the sphere.
        env_power = [np.pi * scene_radius**2 * avg(self.env.power_integral)] if self.env is not None else []
        power = np.abs(np.concatenate([shapes.analytic_power(lights, scene_radius),
                                       2.0 * np.pi * self.tri_area * avg(np.abs(self.tri_Le)), env_power]))
        power = np.where(np.isfinite(power), power, 0.0)
        self.power = power  # (count,) W, mean over RGB: what selection by power uses
        self.count = len(power)
        self.env_index = self.count - 1 if self.env is not None else -1
        self.select = sampling.Distribution1D(power) if self.count and power.sum() > 0 else None
        self.delta = np.zeros(self.count, bool)
        self.delta[:self.n_analytic] = shapes.is_delta(lights)
        threshold = TREE_MIN_LIGHTS if tree_min_lights is None else tree_min_lights
        self._build_tree(power, threshold)
        self._link(lights, mesh, power)
        self.env_pmf = float(self.pmf(np.array([self.env_index]))[0]) if self.env is not None and self.select is not None else 0.0
        self.kinds_present = sorted(set(lights.kind.tolist()))
        self.hittable = np.flatnonzero(~shapes.is_delta(lights) & (lights.kind != LIGHT_SUN))
        self.suns = np.flatnonzero(~shapes.is_delta(lights) & (lights.kind == LIGHT_SUN))
        self.sees_escaped = (bool(len(self.suns)) or bool(np.abs(self.world).max() > 0) or self.env is not None
                             or bg is not None)  # a negative world subtracts, as in Cycles
        # Ray visibility (Cycles' light and world visibility): None where everything sees all.
        tri_vis = mesh.visibility[self.tri_prim] if mesh.visibility is not None else np.full(len(self.tri_prim), RAY_ALL)
        vis = np.concatenate([lights.ray_visibility, tri_vis, [world.ray_visibility] if self.env is not None else []
                              ]).astype(np.int64)
        lobes = RAY_ALL & ~RAY_CAMERA
        self.nee_visibility = vis.astype(np.uint8) if np.any((vis & lobes) != lobes) else None
        self.light_visibility = lights.ray_visibility
        self.world_visibility = (int(world.ray_visibility) & ~RAY_CAMERA) | (RAY_CAMERA if world.visible else 0)
        self.partial_visibility = bool(np.any(lights.ray_visibility != lights.ray_visibility | lobes)
                                       or (self.world_visibility & lobes) != lobes)

    @property
    def empty(self) -> bool:
        return self.select is None

    def _link(self, lights, mesh, power):
        """Light and shadow linking (linking.py), or None. Chosen by power, a point's light is
        chosen among those linked to its receiver set (one distribution per set); the light
        tree chooses among all and a light not linked gives nothing."""
        links = linking.Links(lights, mesh, self.tri_prim, self.count)
        self.links = links if links.active else None
        self.select_by_set = None
        if self.links is None or not links.light_linked or self.tree is not None or self.select is None:
            return
        self.select_by_set = {}
        for s in links.sets.tolist():
            p = np.where(links.lit_mask(s), power, 0.0)
            self.select_by_set[s] = sampling.Distribution1D(p) if p.sum() > 0 else None

    @property
    def light_linked(self) -> bool:
        return self.links is not None and self.links.light_linked

    def receivers(self, prim):
        """(N,) receiver sets of points on triangles prim (N,) (-1: none), or None without light linking."""
        return None if self.links is None or not self.links.light_linked else self.links.receiver(prim)

    def _by_set(self, receiver):
        """[(rows, distribution or None)] of the points by receiver set (-1: the scene's)."""
        out = []
        for s in np.unique(receiver).tolist():
            rows = np.flatnonzero(receiver == s)
            out.append((rows, self.select if s < 0 else self.select_by_set.get(s)))
        return out

    def _build_tree(self, power, threshold):
        """The light tree over the finite lights of positive power, if there are enough."""
        self.tree = None
        finite = np.ones(self.count, bool)
        finite[:self.n_analytic] = self.lights.kind != LIGHT_SUN
        if self.env is not None:
            finite[self.env_index] = False
        local = np.flatnonzero(finite & (power > 0))
        if len(local) < threshold or self.select is None:
            return
        lo, hi = self._light_bounds(local)
        if 0.5 * np.linalg.norm(hi.max(axis=0) - lo.min(axis=0)) < TREE_MIN_SPREAD * self.scene_radius:
            return
        self.tree_light = local  # tree light j -> light index
        self.tree_slot = np.full(self.count, -1, np.int64)
        self.tree_slot[local] = np.arange(len(local))
        infinite_power = np.where(finite, 0.0, power)
        self.p_infinite = float(infinite_power.sum() / power.sum())
        self.select_infinite = sampling.Distribution1D(infinite_power) if self.p_infinite > 0 else None
        self.tree = light_tree.LightTree(lo, hi, power[local], *self._light_cones(local))

    def _light_bounds(self, index):
        """Boxes lo, hi (K,3) of finite lights `index` (analytic lights before triangles)."""
        a = index[index < self.n_analytic]
        t = index[index >= self.n_analytic] - self.n_analytic
        lights = self.lights
        c = lights.position[a]
        half = np.zeros((len(a), 3))
        sphere = (lights.kind[a] == LIGHT_POINT) | (lights.kind[a] == LIGHT_SPOT)
        half[sphere] = lights.radius[a][sphere, None]
        flat = ~sphere  # rect and disk: the box of the rectangle c +- hx x +- hy y
        hx, hy = lights.size[a, 0], lights.size[a, 1]
        half[flat] = (np.abs(lights.frame[a, 0]) * hx[:, None] + np.abs(lights.frame[a, 1]) * hy[:, None])[flat]
        corners = np.stack([self.tri_v0[t], self.tri_v0[t] + self.tri_e1[t], self.tri_v0[t] + self.tri_e2[t]], axis=1)
        lo = np.concatenate([c - half, corners.min(axis=1)])
        hi = np.concatenate([c + half, corners.max(axis=1)])
        return lo, hi

    def _light_cones(self, index):
        """Orientation cones axis (K,3), theta_o, theta_e (K,) and two_sided (K,) of finite
        lights `index`."""
        a = index[index < self.n_analytic]
        t = index[index >= self.n_analytic] - self.n_analytic
        kind = self.lights.kind[a]
        axis_a = -self.lights.frame[a, 2]  # spot axis and the emitting side of rects and disks
        theta_o = np.select([kind == LIGHT_POINT, kind == LIGHT_SPOT],
                            [np.pi, np.arccos(np.clip(self.lights.spot_cos_half[a], -1.0, 1.0))], 0.0)
        # Area lights and spheres spread their light over a hemisphere about each normal;
        # a delta spot emits only inside its cone.
        theta_e = np.where((kind == LIGHT_SPOT) & (self.lights.radius[a] <= 0), 0.0, np.pi / 2)
        axis = np.concatenate([axis_a, self.tri_ng[t]])
        axis /= np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-300)
        theta_o = np.concatenate([theta_o, np.zeros(len(t))])  # triangles: two-sided about ng
        theta_e = np.concatenate([theta_e, np.full(len(t), np.pi / 2)])
        two_sided = np.arange(len(index)) >= len(a)
        return axis, theta_o, theta_e, two_sided

    def pmf(self, index: np.ndarray, p: np.ndarray | None = None, receiver=None) -> np.ndarray:
        """Selection probability of lights `index` (N,) chosen at shading points p (N,3) (0 for
        all when nothing has power). p may be left out without a light tree and for infinite
        lights (suns, environment), whose pmf does not depend on the point. receiver (N,):
        the points' receiver sets (light linking; -1 or None: all lights)."""
        if self.select is None:
            return np.zeros(np.shape(index))
        if receiver is not None and self.select_by_set is not None:
            index = np.broadcast_to(index, np.shape(receiver))
            out = np.zeros(np.shape(receiver))
            for rows, select in self._by_set(receiver):
                if select is not None:
                    out[rows] = select.pmf(index[rows])
            return out
        if self.tree is None:
            return self.select.pmf(index)
        index = np.asarray(index)
        out = np.zeros(index.shape)
        slot = self.tree_slot[index]
        inf = slot < 0
        if inf.any() and self.select_infinite is not None:
            out[inf] = self.p_infinite * self.select_infinite.pmf(index[inf])
        if not inf.all():
            rows = np.flatnonzero(~inf)
            out[rows] = (1.0 - self.p_infinite) * self.tree.pmf(slot[rows], p[rows])
        return out

    def _choose(self, p, u, receiver=None):
        """Light index (N,) and its pmf (N,) for points p (N,3) from uniforms u (N,), among the
        lights linked to the points' receiver sets receiver (N,) (None: all)."""
        if receiver is not None and self.select_by_set is not None:
            index, pmf = np.zeros(len(u), np.int64), np.zeros(len(u))
            for rows, select in self._by_set(receiver):
                if select is not None:
                    index[rows] = select.sample_index(u[rows])
                    pmf[rows] = select.pmf(index[rows])
            return index, pmf
        if self.tree is None:
            index = self.select.sample_index(u)
            pmf = self.select.pmf(index)
            return index, pmf
        index = np.zeros(len(p), np.int64)
        pmf = np.zeros(len(p))
        inf = u < self.p_infinite
        if inf.any():
            r = np.flatnonzero(inf)
            index[r], pmf_inf, _ = self.select_infinite.sample_discrete(u[r] / self.p_infinite)
            pmf[r] = self.p_infinite * pmf_inf
        if not inf.all():
            r = np.flatnonzero(~inf)
            v = np.minimum((u[r] - self.p_infinite) / (1.0 - self.p_infinite), light_tree.ONE_MINUS_EPSILON)
            j, pmf_tree = self.tree.sample(p[r], v)
            index[r], pmf[r] = self.tree_light[j], (1.0 - self.p_infinite) * pmf_tree
        return index, pmf

    # ---- next-event estimation ------------------------------------------------------------
    def sample(self, p: np.ndarray, u_select: np.ndarray, u: np.ndarray, in_unit=False, ray=None,
               receiver=None) -> LightSample:
        """One light sample per shading point p (N,3) float64; u_select (N,), u (N,2) (in_unit:
        known to lie in [0, 1), a Sampler's numbers: not clamped again); ray: the N paths'
        RayState, for a world program reading them (world_reads), or None; receiver (N,) the
        points' receiver sets (receivers(); None: no light linking)."""
        n = len(p)
        if self.tree is None and self.n_analytic == 0 and self.env is None and self.links is None:
            return self._sample_triangles(p, u_select, u, in_unit)
        index, pmf = self._choose(p, np.asarray(u_select, np.float64), receiver)
        out = {}  # ShapeSample field -> (N,...) array; every row belongs to exactly one kind of light

        def put(rows, sample: shapes.ShapeSample):
            values = dict(wi=sample.wi, Le=sample.Le, pdf=sample.pdf, target=sample.target, finite=sample.finite)
            if len(rows) == n:  # one kind for all rows (the common case): no scatter
                out.update(values)
                return
            for key, v in values.items():
                if key not in out:
                    out[key] = np.zeros((n,) + v.shape[1:], v.dtype)
                out[key][rows] = v

        def rows_of(mask):
            if mask is np.True_:
                return np.arange(n), slice(None)
            rows = np.flatnonzero(mask)
            return rows, (rows if len(rows) < n else slice(None))  # (indices, what to gather with)

        only_triangles = self.n_analytic == 0 and self.env is None
        is_tri = np.True_ if only_triangles else (index >= self.n_analytic) & (index < self.n_analytic + len(self.tri_prim))
        is_env = np.False_ if only_triangles else index == self.env_index
        if is_env.any():
            rows, r = rows_of(is_env)
            e = self.env.sample(u[r]) if ray is None else self.env.sample(u[r], ray.take(rows).for_emission())
            put(rows, shapes.ShapeSample(e.wi, e.Le, e.pdf, p[r] + e.wi * 1e30, np.zeros(len(rows), bool)))
        target_prim = np.full(n, -1, np.int64)
        if is_tri.any():
            rows, r = rows_of(is_tri)
            t = index[r] - self.n_analytic
            put(rows, self._triangle_sample(p[r], t, u[r]))
            target_prim[r] = self.tri_prim[t]
        for kind in self.kinds_present:
            rows, r = rows_of((index < self.n_analytic)
                              & (self.lights.kind[np.minimum(index, max(self.n_analytic - 1, 0))] == kind))
            if len(rows):
                ss = shapes.sample_analytic(kind, self.lights, index[r], p[r], u[r])
                if self.shaders is not None:  # shaders that vary: their emission at the points sampled
                    Le = self.shaders.apply(index[r], p[r], ss.wi, ss.Le, ss.target, ss.finite)
                    ss = shapes.ShapeSample(ss.wi, Le, ss.pdf, ss.target, ss.finite)
                put(rows, ss)
        wi, Le, pdf_dir, target, finite = (out[k] for k in ("wi", "Le", "pdf", "target", "finite"))
        delta = self.delta[index]
        pdf = np.where(delta, pmf, pmf * pdf_dir)
        valid = (pdf > 0) & np.isfinite(pdf) & (max3(np.abs(Le)) > 0)  # negative lights count
        if receiver is not None and self.links is not None:
            valid &= self.links.lights(index, receiver)
        return LightSample(wi=wi, Le=Le, pdf=np.where(valid, pdf, 0.0), delta=delta, target=target,
                           target_prim=target_prim, finite=finite, valid=valid,
                           visibility=None if self.nee_visibility is None else self.nee_visibility[index],
                           light=index if self.links is not None else None)

    def _sample_triangles(self, p: np.ndarray, u_select, u: np.ndarray, in_unit: bool) -> LightSample:
        """sample() when every light is an emissive triangle chosen by power (the common case):
        the same numbers, with one gather of each triangle's row and no per-kind bookkeeping."""
        n = len(p)
        index = self.select.sample_index(np.asarray(u_select, np.float64))
        pmf = self.select.pmf(index)
        t = self._triangle_sample(p, index, u, in_unit)
        pdf = pmf * t.pdf  # no delta lights among triangles
        valid = (pdf > 0) & np.isfinite(pdf) & self.tri_lit[index]
        return LightSample(wi=t.wi, Le=t.Le, pdf=np.where(valid, pdf, 0.0), delta=np.zeros(n, bool), target=t.target,
                           target_prim=self.tri_prim[index], finite=t.finite, valid=valid,
                           visibility=None if self.nee_visibility is None else self.nee_visibility[index])

    def _triangle_sample(self, p: np.ndarray, t: np.ndarray, u: np.ndarray, in_unit=False) -> shapes.ShapeSample:
        """A uniform point on each of the emissive triangles t (N,) seen from p (N,3) (one gather
        of each triangle's row); in_unit as `sample`."""
        b = sampling.sample_uniform_triangle(u, in_unit)
        r = np.flatnonzero(self.tri_varying[t]) if self.tri_varying is not None else ()
        if len(r):  # textured emitters: points where they shine
            b[r], density = self.maps.sample(self.map_row[t[r]], u[r])
        row = take(self.tri_rows, t)
        y = row[:, 0:3] + scale(row[:, 3:6], b[:, 1]) + scale(row[:, 6:9], b[:, 2])
        wi, pdf = shapes.area_to_solid_angle(p, y, row[:, 9:12], row[:, 12], two_sided=True)
        Le = take(self.tri_Le, t)
        if len(r):
            pdf[r] *= density
            Le[r] = self.triangle_emission(t[r], b[r], y[r], -wi[r])
        return shapes.ShapeSample(wi, Le, pdf, y, np.ones(len(t), bool))

    def triangle_emission(self, t: np.ndarray, b: np.ndarray, y: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """Radiance (K,3) leaving points y (K,3) (barycentrics b) of emissive triangles t (K,)
        toward wo (K,3), where their material's emission varies over the surface."""
        ng = take(self.tri_ng, t)
        n = ng * np.where(dot(ng, wo) < 0, -1.0, 1.0)[:, None]  # two-sided: the side wo leaves
        return self.surface_emission(self.tri_prim[t], b, y, n, wo)

    def barycentrics(self, t: np.ndarray, y: np.ndarray) -> np.ndarray:
        """(K,3) barycentrics of points y (K,3) in the planes of emissive triangles t (K,)."""
        e1, e2, d = take(self.tri_e1, t), take(self.tri_e2, t), y - take(self.tri_v0, t)
        g11, g12, g22 = dot(e1, e1), dot(e1, e2), dot(e2, e2)
        r1, r2 = dot(d, e1), dot(d, e2)
        det = g11 * g22 - g12 * g12
        b1 = np.divide(g22 * r1 - g12 * r2, det, out=np.zeros_like(det), where=det > 0)
        b2 = np.divide(g11 * r2 - g12 * r1, det, out=np.zeros_like(det), where=det > 0)
        return np.column_stack([1.0 - b1 - b2, b1, b2])

    def _emission_at(self, accel, prim: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(K,3) radiance of triangles prim (K,) at barycentrics b (K,3), along their normal."""
        y = accel.v0[prim] + scale(accel.e1[prim], b[:, 1]) + scale(accel.e2[prim], b[:, 2])
        ng = accel.ng[prim]
        return self.surface_emission(prim, b, y, ng, ng)

    # ---- emission found by rays (BSDF sampling or camera rays) -----------------------------
    def pdf_triangle_hit(self, prim: np.ndarray, p_prev: np.ndarray, t: np.ndarray, cos_light: np.ndarray,
                         b: np.ndarray, receiver=None):
        """Selection pmf x solid-angle pdf with which NEE at p_prev (of receiver sets receiver
        (N,), or None) would have sampled the hit point (barycentrics b (N,3)) on emissive
        triangle `prim` at distance t with |cos| at the light."""
        index = self.light_of_prim[prim]
        tri = index - self.n_analytic
        area = self.tri_area[tri]
        pdf = self.pmf(index, p_prev, receiver) * np.divide(t * t, area * cos_light, out=np.zeros_like(t), where=(area * cos_light) > 0)
        if self.maps is not None:
            r = np.flatnonzero(self.tri_varying[tri])
            pdf[r] *= self.maps.pdf_in_triangle(self.map_row[tri[r]], b[r])
        return np.where(np.isfinite(pdf), pdf, 0.0)

    def emission_along(self, o: np.ndarray, d: np.ndarray, tmax: np.ndarray, pdf_bsdf: np.ndarray,
                       use_mis: np.ndarray, camera: np.ndarray, kind: np.ndarray = None,
                       tmin: np.ndarray = None, receiver: np.ndarray = None, through=None) -> np.ndarray:
        """Radiance (N,3) that rays o + t d, 0 < t < tmax, collect from the finite analytic lights
        they pass through, each weighted by the balance heuristic
        pdf_bsdf / (pdf_bsdf + pdf_light) where use_mis, else 1. camera (N,) bool: camera rays
        see only lights marked visible; kind (N,) RAY_* bit of each ray or None: rays see only
        lights visible to their kind; tmin (N,) or None: only lights past it (a ray gone on
        through transparent surfaces, o the vertex its MIS state is from); receiver (N,) or
        None: the receiver sets of the rays' origins (light linking: only lights linked to them);
        through: t (N,) -> (N,3) factor on the radiance of a light met at distance t (a
        medium's), or None."""
        total = np.zeros((len(o), 3))
        lights = self.lights
        for i in self.hittable.tolist():
            h = shapes.hit_analytic(int(lights.kind[i]), lights, i, o, d, tmax)
            if tmin is not None:
                h = shapes.LightHit(h.hit & (h.t > tmin), h.gain, h.pdf, h.t)
            if through is None:
                self._add_weighted(total, i, h, pdf_bsdf, use_mis, camera, kind, o, d, receiver)
            else:
                part = np.zeros_like(total)
                self._add_weighted(part, i, h, pdf_bsdf, use_mis, camera, kind, o, d, receiver)
                total += part * through(np.where(h.hit, h.t, 0.0))
        return total

    def escaped(self, d: np.ndarray, pdf_bsdf: np.ndarray, use_mis: np.ndarray, camera: np.ndarray,
                kind: np.ndarray = None, ray=None, receiver=None) -> np.ndarray:
        """Radiance (N,3) for rays leaving the scene along d: suns and the world's light
        (MIS-weighted like `emission_along`; a world program without a table and the constant
        world weigh 1: they are never light-sampled). Camera rays see the world only if it is
        visible; with kind (N,), rays see only what is visible to their kind. A world program
        whose Light Path reads the paths (world_reads) reads ray, the N rays' RayState; without
        one, a camera ray's first hit where camera, else a ray leaving a diffuse bounce.
        receiver: as emission_along."""
        total = np.zeros((len(d), 3))
        for i in self.suns.tolist():
            self._add_weighted(total, i, shapes.sun_hit(self.lights, i, d), pdf_bsdf, use_mis, camera, kind, None, d,
                               receiver)
        seen = ~camera | self.world_visible
        if kind is not None and self.partial_visibility:
            seen = seen & ((kind & self.world_visibility) != 0)
        if self.background is not None:
            rows = np.flatnonzero(seen)
            Le = np.zeros((len(d), 3))
            if len(rows):
                state = EMISSION_RAY
                if self.world_reads:
                    state = ray.take(rows) if ray is not None else \
                        RayState(np.where(camera[rows], lp.CAMERA, lp.REFLECT | lp.DIFFUSE).astype(np.uint32), 0)
                    state = state.escaped()
                Le[rows] = self.background.radiance(take(d, rows), state)
        elif self.env is not None:
            Le = self.env.eval(d)
        if self.env is not None or self.background is not None:
            w = np.ones(len(d))
            if self.env is not None and np.any(use_mis):
                pmf = self.env_pmf if receiver is None or self.select_by_set is None else \
                    self.pmf(np.full(len(d), self.env_index), receiver=receiver)
                pdf_light = pmf * self.env.pdf(d)
                w = np.where(use_mis, pdf_bsdf / np.maximum(pdf_bsdf + pdf_light, 1e-300), 1.0)
            total += np.where(seen[:, None], Le * w[:, None], 0.0)
        elif np.abs(self.world).max() > 0:
            total += np.where(seen[:, None], self.world, 0.0)
        return total

    def _add_weighted(self, total, i, h: shapes.LightHit, pdf_bsdf, use_mis, camera, kind=None, o=None, d=None,
                      receiver=None):
        """total += gain x Le[i] x MIS weight on the rays that hit light i (h; from origins o,
        (N,3), None for infinite lights; along d (N,3), for a light whose shader varies;
        receiver (N,): the receiver sets of the origins, or None)."""
        hit = h.hit
        if not self.lights.visible[i]:
            hit = hit & ~camera
        if kind is not None and self.partial_visibility:
            hit = hit & ((kind & self.light_visibility[i]) != 0)
        if receiver is not None and self.links is not None:
            hit = hit & self.links.lights(np.full(len(hit), i), receiver)
        if not hit.any():
            return
        if receiver is not None and self.select_by_set is not None:
            pmf = self.pmf(np.full(len(hit), i), receiver=receiver)
        elif o is None or self.tree is None:
            pmf = self.pmf(np.array([i]))[0]
        else:  # the point-dependent pmf, on the rays that hit only
            pmf = np.zeros(len(hit))
            r = np.flatnonzero(hit)
            pmf[r] = self.pmf(np.full(len(r), i), o[r])
        pdf_light = pmf * h.pdf
        w = np.where(use_mis, pdf_bsdf / np.maximum(pdf_bsdf + pdf_light, 1e-300), 1.0)
        a = np.where(hit, h.gain * w, 0.0)
        if self.shaders is not None and self.shaders.has[i]:
            r = np.flatnonzero(hit)
            P = -d[r] if o is None else o[r] + d[r] * h.t[r, None]  # a sun: the direction it shines along
            total[r] += a[r, None] * self.lights.Le[i] * self.shaders.factor(i, P, d[r], h.t[r])
            return
        for k in range(3):
            total[:, k] += a * self.lights.Le[i, k]
