"""The BSDF at N shading points: the sum of their materials' lobes, a mixture over the lobe table.

Every (point, lobe) pair of the batch is one row of a flat "pair" table; each lobe kind present
(engine/bsdf/lobes/: parameters, albedo, eval, sample and the facts about it) runs once over
its rows, so a scene with diffuse surfaces only never touches the glossy code. A material's
BSDF is the sum of its lobes (Scene.Materials):

    f = sum_k w_k f_k,    sampled by picking lobe k with probability P_k proportional to an
    estimate of its albedo at wo, then sampling f_k; pdf = sum_k P_k p_k (the mixture),

so the throughput f cos / pdf and the MIS pdf are those of the whole closure (unbiased whichever
lobe produced the direction). Delta lobes (mirror, smooth glass, transparency) are picked the
same way; their samples carry weight w_k F / (P_k P_branch) and the flag `delta`, and they add
nothing to eval() (a direction has probability 0 of being theirs). The closure keeps the
weights w_k (lobe_weight x opacity, less what a layer on top takes: Cycles' closure layering),
the selection probabilities and the mixture; the lobes know nothing of each other.

Frames: `ns` and `ng` arrive already flipped to the side of `wo` (two-sided shading, as Cycles).
A reflected wi is valid only on that side of the geometric normal, a refracted one only on the
other (pbrt-v3's rule; Cycles checks Ng the same way when sampling); cosines use the shading
normal. Lobes that need the side the ray came from (glass) get `inside`: wo is behind the
triangle's own winding normal. Normal maps replace `ns` (engine/bsdf/normal_map.py); the
integrator then uses `closure.ns`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .. import sampling, textures
from ..scene import Scene
from ..vec import dot, gatherer, max3, normalize, scale, take
from .lobes import LOBES, NEEDS_SIDE, RAYS, REFLECTION_CLASS, STRAIGHT, TRANSMISSION_CLASS, inputs
from .lobes.base import (CLASS_DIFFUSE, LABEL_DIFFUSE, LABEL_GLOSSY, LABEL_TRANSMIT, LABEL_TRANSPARENT, Params,
                         SurfaceLobe)
from ..nodes.hits import SurfaceHits
from .normal_map import normal_map, valid_reflection_normal

__all__ = ["BSDFSample", "Closure", "LABEL_DIFFUSE", "LABEL_GLOSSY", "LABEL_TRANSMIT", "LABEL_TRANSPARENT"]

# Smallest lobe-selection estimate, relative to the lobe's weight: a lobe whose albedo
# estimate is 0 at wo (e.g. Schlick with f0 = 0 at normal incidence) keeps a chance.
_MIN_ESTIMATE = 1e-3


@dataclass
class BSDFSample:
    """wi (N,3); weight (N,3) = f |cos| / pdf (the throughput factor); pdf (N,) solid-angle
    pdf of the whole closure (for delta lobes the lobe's selection probability, never used in
    MIS); delta (N,) bool: chosen from a delta lobe; valid (N,) bool."""

    wi: np.ndarray
    weight: np.ndarray
    pdf: np.ndarray
    delta: np.ndarray
    valid: np.ndarray
    # (N,) eta_rel^2 of refracted samples, 1 elsewhere (None: no refraction in the batch).
    # weight carries radiance's 1 / eta_rel^2; light particles (photons) carry flux, which
    # does not scale, so they multiply it back (Veach 1997 sec. 5.2; pbrt-v4 TransportMode).
    refraction_eta2: np.ndarray = None
    label: np.ndarray = None  # (N,) int8 LABEL_* of each sample


# Directions closer to the shading plane than this cosine lie on it: there a microfacet lobe's
# f cos_i depends on cos_i / (cos_i + cos_o), which rounding decides when both are tiny, so a
# direction and its round trip through world space would weigh differently.
GRAZING = 1e-9


def _on_plane(local: np.ndarray) -> np.ndarray:
    """local (K,3) with z set to 0 where |z| < GRAZING (in place; returned)."""
    z = local[:, 2]
    z[np.abs(z) < GRAZING] = 0.0
    return local


def _to_local(v: np.ndarray, t: np.ndarray, b: np.ndarray, n: np.ndarray) -> np.ndarray:
    """World vectors v (K,3) in the frames (t, b, n) (K,3 each), grazing ones on the plane."""
    return _on_plane(np.stack([dot(v, t), dot(v, b), dot(v, n)], axis=1))


def _mean3(a: np.ndarray) -> np.ndarray:
    return (a[:, 0] + a[:, 1] + a[:, 2]) / 3.0


def _sum_by(owner: np.ndarray, values: np.ndarray, k: int) -> np.ndarray:
    """Rows of values (P,3) summed per owner (P,) into (k,3)."""
    return np.stack([np.bincount(owner, values[:, c], minlength=k) for c in range(3)], axis=1)


def _set_labels(label: np.ndarray, rows: np.ndarray, value) -> None:
    """label[rows] = value (K,) or one LABEL_* for all; label starts as LABEL_DIFFUSE."""
    if not (np.isscalar(value) and value == LABEL_DIFFUSE):
        label[rows] = value


def _ragged(starts: np.ndarray, counts: np.ndarray):
    """Indices starts[i] + 0..counts[i]-1 for all i, flattened, and the i of each."""
    owner = np.repeat(np.arange(len(counts)), counts)
    first = np.cumsum(counts) - counts
    return starts[owner] + np.arange(int(counts.sum())) - first[owner], owner


class _Group(NamedTuple):
    """The pairs of one lobe kind: its lobe, their pair ids (K,) ascending, their parameters."""

    lobe: SurfaceLobe
    rows: np.ndarray
    p: Params


class Closure:
    # Whether every direction it samples or evaluates as non-zero lies on ng's side: not in
    # general (transmission); LambertClosure says True, which spares side tests.
    reflects_only = False

    def __init__(self, scene: Scene, mat: np.ndarray, ns: np.ndarray, ng: np.ndarray, wo: np.ndarray,
                 prim: np.ndarray, bary: np.ndarray, no_caustics=None, min_alpha=None, programs=None, p=None,
                 ray=None, adjoint=False):
        """mat (N,) material per point; ns, ng (N,3) unit normals on wo's side; wo (N,3) toward
        the previous vertex; prim (N,) triangles and bary (N,3) barycentrics of the hits.
        no_caustics: None, or (drop_reflection, drop_refraction) (N,) bool each: points whose
        glossy reflection / refraction is left out (Cycles' caustics toggles).
        min_alpha: None, or (N,) smallest GGX alpha of glossy and glass lobes (Filter Glossy).
        programs: the scene's MaterialPrograms (engine/nodes/material.py), for materials whose
        node graphs vary over the surface; p (N,3) the hit points they are evaluated at; ray the
        path's record of the points (engine/nodes/hits.py RayState: path flags, bounce counts,
        ray differential; None: camera rays' first hits). adjoint: the closure scatters light
        particles (wo toward the light): lobes evaluate their adjoint (Params.adjoint)."""
        m = scene.materials
        self.m = m
        self.ng, self.wo = ng, wo
        n = len(mat)
        # The pair table: the lobes of point i are pairs pair_offset[i] .. pair_offset[i+1]-1.
        all_materials = np.arange(len(m.kind))
        start = np.searchsorted(m.lobe_material, all_materials)
        count = (np.searchsorted(m.lobe_material, all_materials, side="right") - start)[mat]
        self.pair_offset = np.concatenate([[0], np.cumsum(count)])
        lobe, point = _ragged(start[mat], count)
        self.pair_lobe, self.pair_point, self.pair_kind = lobe, point, m.lobe_kind[lobe]
        self.single = bool(np.all(count == 1))  # one lobe per point: no mixture to form
        kinds = np.flatnonzero(np.bincount(self.pair_kind, minlength=len(LOBES)))

        textured = np.concatenate([m.lobe_color_tex[lobe], m.lobe_roughness_tex[lobe], m.lobe_opacity_tex[lobe],
                                   m.normal_tex[mat]])
        uv = textures.mesh_uv(scene.mesh.uvs, prim, bary) if np.any(textured >= 0) else None
        values = {}
        self.n_smooth = ns  # Cycles' sd->N, before a BSDF's own Normal or a normal map
        if programs and programs.has[mat].any():  # node programs: inputs per point, perhaps a normal
            hits = SurfaceHits(scene, prim, bary, p, ns, ng, wo, ray=ray)
            values, normal, rows, smooth = programs.pair_values(mat, self.pair_offset, len(lobe), hits)
            if normal is not None:
                ns = ns.copy()
                ns[rows] = valid_reflection_normal(ng[rows], wo[rows], normalize(normal))
                bumped = np.flatnonzero(np.isfinite(smooth[:, 0]))
                if len(bumped):  # a displacement's bump is Cycles' sd->N itself
                    self.n_smooth = self.n_smooth.copy()
                    s = normalize(smooth[bumped])
                    s = s * np.where(dot(s, ng[rows[bumped]]) < 0, -1.0, 1.0)[:, None]
                    same = np.all(normal[bumped] == smooth[bumped], axis=1)  # no Normal of its own
                    self.n_smooth[rows[bumped]] = np.where(same[:, None], ns[rows[bumped]], s)
        src = inputs.Sources(uv, values)
        mapped = np.any(m.normal_tex[mat] >= 0)
        outward = None  # the triangles' winding normals, only where glass or a normal map needs them
        if mapped or NEEDS_SIDE[kinds].any():
            v = scene.mesh.vertices[scene.mesh.triangles[prim]].astype(np.float64)
            outward = normalize(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]))
        self.ns = normal_map(scene, mat, ns, ng, wo, prim, uv, outward) if mapped else ns
        self.t, self.b = sampling.frame_from_z(self.ns)
        src.frame = (self.t, self.b)
        self.wo_local = _to_local(wo, self.t, self.b, self.ns)
        # Points whose wo is behind the authored winding: glass sees them from inside.
        self.inside = dot(wo, outward) < 0 if outward is not None else np.zeros(n, bool)

        self.groups, self.pair_pos = self._group_pairs(kinds, src)
        self._facts = None  # _pair_facts
        if adjoint:
            for g in self.groups:
                g.p.adjoint = True
        self.weight = inputs.weight(m, lobe, point, src)
        if no_caustics is not None:
            self._drop_caustics(*no_caustics)
        if min_alpha is not None:
            for g in self.groups:  # Filter Glossy; albedo estimates keep the authored roughness
                g.lobe.blur(g.p, min_alpha[point[g.rows]])
        if len(self.groups) == 1:
            self.pair_delta = self.groups[0].p.delta
        else:
            self.pair_delta = np.zeros(len(lobe), bool)
            for g in self.groups:
                self.pair_delta[g.rows] = g.p.delta
        self._layer(start[mat])

        estimate = self._albedo_estimate()
        self.pair_estimate = estimate  # (P,3), for the colour passes (by_class)
        share = np.maximum(_mean3(estimate), _MIN_ESTIMATE * _mean3(self.weight))
        share = np.where(max3(self.weight) > 0, share, 0.0)
        total = share if self.single else np.bincount(point, share, minlength=n)[point]
        self.pair_select = np.divide(share, total, out=np.zeros(len(share)), where=total > 0)
        # Reflectance drives Russian roulette (seed 000: survival from the material).
        self.reflectance = estimate if self.single else _sum_by(point, estimate, n)
        # Points with a non-delta component take part in next-event estimation.
        self.has_smooth = np.bincount(point, ~self.pair_delta & (self.pair_select > 0), minlength=n) > 0

    @property
    def n(self) -> int:
        return len(self.ns)

    # --- the pairs, grouped by lobe kind -------------------------------------------------------
    def _group_pairs(self, kinds: np.ndarray, src):
        """([_Group] of the lobe kinds present `kinds`, with their pairs' parameters; pair_pos
        (P,) a pair's row in its group, or None for one group: its rows are the pairs).
        src: where the pairs' inputs come from besides the table (inputs.Sources)."""
        lobe, point = self.pair_lobe, self.pair_point
        if len(kinds) == 1:
            kind = LOBES[kinds[0]]
            return [_Group(kind, np.arange(len(lobe)), kind.parameters(self.m, lobe, point, src, self.inside))], None
        groups, pos = [], np.empty(len(lobe), np.int64)
        for k in kinds:
            rows = np.flatnonzero(self.pair_kind == k)
            pos[rows] = np.arange(len(rows))
            params = LOBES[k].parameters(self.m, lobe[rows], point[rows], src.take(rows), self.inside)
            groups.append(_Group(LOBES[k], rows, params))
        return groups, pos

    def _pair_facts(self):
        """(render-pass class of the reflection (P,), RAY_* bits of the lights that light it
        (P,)) of every pair: its kind's, or its row's where a lobe's rows differ (row_facts)."""
        if self._facts is None:
            cls, rays = REFLECTION_CLASS[self.pair_kind], RAYS[self.pair_kind]
            for g in self.groups:
                facts = g.lobe.row_facts(g.p)
                if facts is not None:
                    cls[g.rows], rays[g.rows] = facts
            self._facts = cls, rays
        return self._facts

    def _params(self, g: _Group, pairs: np.ndarray) -> Params:
        """The parameters of pairs (K,) of group g."""
        return g.p.take(pairs if self.pair_pos is None else self.pair_pos[pairs])

    def _split(self, kind: np.ndarray):
        """Per lobe kind present in `kind` (K,) (the kinds of some pairs): its group and the
        positions in `kind` of its pairs (None when they are all of one kind: all of them)."""
        if len(self.groups) == 1:
            yield self.groups[0], None
            return
        for g in self.groups:
            r = np.flatnonzero(kind == g.lobe.kind)
            if len(r) == len(kind):
                yield g, None
                return
            if len(r):
                yield g, r

    def _wo_of(self, pairs: np.ndarray) -> np.ndarray:
        """Local wo (K,3) at the points of pairs (K,)."""
        return gatherer(self.pair_point[pairs], self.n)(self.wo_local)

    # --- lobe weights ---------------------------------------------------------------------------
    def _drop_caustics(self, drop_reflection: np.ndarray, drop_refraction: np.ndarray):
        """Cycles' svm closure setup with caustics off: each lobe changes its parameters or is
        left out whole. Lobes layered under a dropped one stay as they are."""
        refl, refr = drop_reflection[self.pair_point], drop_refraction[self.pair_point]
        for g in self.groups:
            whole = g.lobe.drop_caustics(g.p, refl[g.rows], refr[g.rows])
            if whole is not None:
                self.weight[g.rows[whole]] = 0.0

    def _layer(self, first: np.ndarray):
        """Lobes under a layer keep what the layer leaves them (Cycles' closure layering), and
        what the layers above that one left it: a stack (sheen over coat over specular over
        diffuse) multiplies down; first (N,) the points' first lobe ids."""
        m, lobe = self.m, self.pair_lobe
        rows = np.flatnonzero(m.lobe_layer[lobe] >= 0)
        if len(rows) == 0:
            return
        point = self.pair_point[rows]
        top = self.pair_offset[point] + (m.lobe_layer[lobe[rows]] - first[point])
        wo = take(self.wo_local, point)
        left = np.ones((len(rows), 3))
        for g, r in self._split(self.pair_kind[top]):
            r = np.arange(len(rows)) if r is None else r
            w = g.lobe.layer_weight(self._params(g, top[r]), wo[r])
            left[r] = w if w.ndim == 2 else w[:, None]
        # Up the stack: the layer's own layer, and so on (a chain is at most a material long).
        below = np.full(len(lobe), -1)
        below[rows] = np.arange(len(rows))
        total, up = left.copy(), below[top]
        for _ in range(len(rows)):
            has = np.flatnonzero(up >= 0)
            if not len(has):
                break
            total[has] *= left[up[has]]
            up[has] = below[top[up[has]]]
        self.weight[rows] *= total

    def _albedo_estimate(self) -> np.ndarray:
        """Per-pair albedo estimate (P,3) at wo: drives lobe selection and Russian roulette."""
        if len(self.groups) == 1:
            g = self.groups[0]
            return self.weight * g.lobe.albedo(g.p, self._wo_of(g.rows))
        estimate = np.empty((len(self.weight), 3))
        for g in self.groups:
            estimate[g.rows] = take(self.weight, g.rows) * g.lobe.albedo(g.p, self._wo_of(g.rows))
        return estimate

    # --- evaluation ----------------------------------------------------------------------------
    def _pairs_of(self, rows: np.ndarray):
        """Non-delta pairs of the points `rows` (K,): (pair ids, position in rows of each)."""
        if self.single:
            pairs, owner = rows, np.arange(len(rows))
        else:
            pairs, owner = _ragged(self.pair_offset[rows], self.pair_offset[rows + 1] - self.pair_offset[rows])
        keep = ~self.pair_delta[pairs] & (self.pair_select[pairs] > 0)
        return pairs[keep], owner[keep]

    def _eval_pairs(self, pairs, wo, wi):
        """f (P,3) weighted, and the lobe pdfs (P,), of non-delta pairs at local wo, wi (P,3)."""
        f = np.zeros((len(pairs), 3))
        pdf = np.zeros(len(pairs))
        if len(pairs):
            for g, r in self._split(self.pair_kind[pairs]):
                if r is None:
                    f, pdf = g.lobe.eval(self._params(g, pairs), wo, wi)
                else:
                    f[r], pdf[r] = g.lobe.eval(self._params(g, pairs[r]), take(wo, r), take(wi, r))
        return f * take(self.weight, pairs), pdf

    def _bump_shadowing(self, pairs, owner, rows, wi, cos_ni):
        """(P,) Cycles' bump_shadowing_term (closure/bsdf.h, after Conty Estevez et al. 2019) of
        pairs at world directions wi (K,3) of the points rows (K,), cos_ni (K,) = wi.ns; None
        where no point's shading normal differs from its smooth one. A direction on different
        sides of the smooth normal and of the shading normal (light through the back of the
        geometry a normal map tilts towards it) counts 0; a diffuse lobe's light is softened
        towards grazing by a GGX shadowing term whose roughness grows with the normal's tilt
        (the material's Bump Map Correction, on by default)."""
        if self.n_smooth is self.ns:
            return None
        ns_s, n = take(self.n_smooth, rows), take(self.ns, rows)
        if np.array_equal(ns_s, n):
            return None
        cos_si, cos_sn = dot(wi, ns_s), dot(ns_s, n)
        tilted = np.any(ns_s != n, axis=1)
        factor = np.where(tilted & (cos_si * cos_sn * cos_ni < 0.0), 0.0, 1.0)
        cos_i, cos_d = np.abs(cos_si), np.abs(cos_sn)
        soft = tilted & (cos_d < 1.0) & (cos_i < 1.0)
        alpha2 = np.clip(0.125 * (1.0 / np.maximum(cos_d, 1e-12) ** 2 - 1.0), 0.0, 1.0)
        tan2 = 1.0 / np.maximum(cos_i, 1e-6) ** 2 - 1.0
        g = np.where(cos_i < 1e-6, 0.0, 1.0 / (1.0 + 0.5 * (np.sqrt(1.0 + alpha2 * tan2) - 1.0)))
        diffuse_factor = factor * np.where(soft, g, 1.0)
        diffuse = self._pair_facts()[0][pairs] == CLASS_DIFFUSE  # Cycles' CLOSURE_IS_BSDF_DIFFUSE
        return np.where(diffuse, diffuse_factor[owner], factor[owner])

    def _mixture(self, rows: np.ndarray, wi: np.ndarray, visible=None, shading_side=None):
        """f (K,3) and mixture pdf (K,) of the points `rows` (K,) for world directions wi (K,3);
        visible (K,) RAY_* bits of a light: lobes it does not light are left out;
        shading_side (K,) bool or None: see eval."""
        k = len(rows)
        at = gatherer(rows, self.n)
        wi_local = _to_local(wi, at(self.t), at(self.b), at(self.ns))
        # Reflection must stay on the geometric normal's side, refraction must cross it.
        agree = (dot(wi, at(self.ng)) > 0) == (wi_local[:, 2] > 0)
        if shading_side is not None:
            agree |= shading_side
        pairs, owner = self._pairs_of(rows)
        if visible is not None:
            lit = (self._pair_facts()[1][pairs] & visible[owner]) != 0
            pairs, owner = pairs[lit], owner[lit]
        f_pair, pdf_pair = self._eval_pairs(pairs, take(self.wo_local, rows[owner]), take(wi_local, owner))
        pdf_pair = self.pair_select[pairs] * pdf_pair
        bump = self._bump_shadowing(pairs, owner, rows, wi, wi_local[:, 2])
        if bump is not None:
            f_pair, pdf_pair = scale(f_pair, bump), np.where(bump > 0, pdf_pair, 0.0)
        if self.single:
            f = np.zeros((k, 3))
            pdf = np.zeros(k)
            f[owner], pdf[owner] = f_pair, pdf_pair
        else:
            f, pdf = _sum_by(owner, f_pair, k), np.bincount(owner, pdf_pair, minlength=k)
        return scale(f, agree), np.where(agree, pdf, 0.0)

    def eval(self, wi: np.ndarray, rows: np.ndarray, visible=None, shading_side=None):
        """f (K,3) and solid-angle pdf (K,) at the points `rows` (K,) for directions wi (K,3);
        visible (K,) RAY_* bits or None: only lobes of those kinds (a light's visibility);
        shading_side (K,) bool or None: where True, the shading normal alone decides between
        reflection and transmission (Cycles' convention: light leaks around the terminator and
        the shadow ray, lifted by the terminator offset, decides), else the geometric normal
        must agree."""
        return self._mixture(rows, wi, visible, shading_side)

    def transparency(self) -> np.ndarray:
        """(N,3) the summed weight of the transparent lobes at each point: what a shadow ray
        keeps passing it (Cycles' surface_shader_transparency): the lobes that pass light
        straight through."""
        t = np.where(STRAIGHT[self.pair_kind][:, None], self.pair_estimate, 0.0)
        return t if self.single else _sum_by(self.pair_point, t, self.n)

    # --- render passes: the closure split by lobe class (diffuse, glossy, transmission) -------
    def eval_by_class(self, wi: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """f (K,3 classes,3) of the points `rows` for directions wi, split by lobe class (they
        sum to eval's f). Glass reflection is glossy, its refraction transmission (Cycles)."""
        k = len(rows)
        at = gatherer(rows, self.n)
        wi_local = _to_local(wi, at(self.t), at(self.b), at(self.ns))
        agree = (dot(wi, at(self.ng)) > 0) == (wi_local[:, 2] > 0)
        pairs, owner = self._pairs_of(rows)
        f_pair, _ = self._eval_pairs(pairs, take(self.wo_local, rows[owner]), take(wi_local, owner))
        bump = self._bump_shadowing(pairs, owner, rows, wi, wi_local[:, 2])
        if bump is not None:
            f_pair = scale(f_pair, bump)
        kind = self.pair_kind[pairs]
        cls = np.where(wi_local[owner, 2] < 0, TRANSMISSION_CLASS[kind], self._pair_facts()[0][pairs])
        out = np.zeros((k * 3, 3))
        for c in range(3):
            out[:, c] = np.bincount(owner * 3 + cls, f_pair[:, c], minlength=k * 3)
        return out.reshape(k, 3, 3) * agree[:, None, None]

    def albedo_by_class(self) -> np.ndarray:
        """(N,3 classes,3) reflectance estimate at wo per lobe class (the colour passes)."""
        values, owner = self.pair_estimate.copy(), self.pair_point
        cls = REFLECTION_CLASS[self.pair_kind]
        more = []  # the parts of lobes that split, after every pair's first part
        for g in self.groups:
            rows = g.rows
            (first_cls, first), *rest = g.lobe.albedo_parts(g.p, self._wo_of(rows), self.weight[rows], values[rows])
            values[rows], cls[rows] = first, first_cls
            more += [(c, v, owner[rows]) for c, v in rest]
        if more:
            values = np.concatenate([values] + [v for _, v, _ in more])
            cls = np.concatenate([cls] + [np.full(len(v), c) for c, v, _ in more])
            owner = np.concatenate([owner] + [o for _, _, o in more])
        out = np.zeros((self.n * 3, 3))
        for c in range(3):
            out[:, c] = np.bincount(owner * 3 + cls, values[:, c], minlength=self.n * 3)
        return out.reshape(self.n, 3, 3)

    def cos_i(self, wi: np.ndarray) -> np.ndarray:
        return np.abs(dot(wi, self.ns))

    # --- sampling ------------------------------------------------------------------------------
    def _choose_lobes(self, u_lobe: np.ndarray):
        """Per point with a lobe: (points (K,), chosen pairs (K,), their shares (K,), u_lobe
        rescaled to [0, 1) within the share (K,)): the first pair whose cumulative share
        exceeds u_lobe."""
        n = self.n
        cdf = np.cumsum(self.pair_select)
        before = np.concatenate([[0.0], cdf])[self.pair_offset[:-1]]
        count = np.diff(self.pair_offset)
        live = np.flatnonzero((count > 0) & (np.bincount(self.pair_point, self.pair_select, minlength=n) > 0))
        # searchsorted never stops on a zero share (its cdf equals the one before); only the
        # clip for u_lobe rounded past the point's last cdf could, hence the last positive pair.
        target = before[live] + u_lobe[live]
        pick = np.searchsorted(cdf, target, side="right")
        positive = np.where(self.pair_select > 0, np.arange(len(cdf)), -1)
        last = np.maximum.reduceat(positive, self.pair_offset[live]) if len(live) else pick
        pick = np.clip(pick, self.pair_offset[live], last)
        share = self.pair_select[pick]
        u_branch = np.clip((target - (cdf[pick] - share)) / share, 0.0, sampling.ONE_MINUS_EPSILON)
        return live, pick, share, u_branch

    def _sample_lobes(self, pick, wo, u, u_branch, live, label):
        """Sample the chosen pairs pick (K,) at local wo (K,3): (wi (K,3), weight of delta
        samples (K,3) or None, lobe pdf or branch pmf (K,), eta_rel^2 (N,) or None); label
        (N,), LABEL_DIFFUSE to begin with, is filled in at live."""
        k = len(pick)
        if k == 0:
            return np.zeros((0, 3)), None, np.zeros(0), None
        wi = weight = pdf = eta2 = None
        for g, r in self._split(self.pair_kind[pick]):
            if r is None:  # one kind: its sample is the closure's
                s = g.lobe.sample(self._params(g, pick), wo, u, u_branch)
                wi, weight, pdf, r = s.wi, s.weight, s.pdf, slice(None)
            else:
                if wi is None:
                    wi, pdf = np.empty((k, 3)), np.empty(k)
                s = g.lobe.sample(self._params(g, pick[r]), take(wo, r), take(u, r), u_branch[r])
                wi[r], pdf[r] = s.wi, s.pdf
                if s.weight is not None:
                    weight = np.zeros((k, 3)) if weight is None else weight
                    weight[r] = s.weight
            _set_labels(label, live[r], s.label)
            if s.eta2 is not None:
                eta2 = np.ones(len(label)) if eta2 is None else eta2
                eta2[live[r]] = s.eta2
        return wi, weight, pdf, eta2

    def sample(self, u: np.ndarray, u_lobe: np.ndarray) -> BSDFSample:
        """Sample wi at every point; u (N,2) for the direction, u_lobe (N,) to choose a lobe
        (and, rescaled to [0, 1) within the chosen lobe's share, a branch inside it)."""
        n = self.n
        wi = np.zeros((n, 3))
        wi[:, 2] = 1.0
        weight = np.zeros((n, 3))
        pdf = np.zeros(n)
        delta = np.zeros(n, bool)
        if self.single:  # pair i is point i, chosen with probability 1
            live = np.flatnonzero(self.pair_select > 0)
            # u in [0, 1) as _choose_lobes leaves it: u = 1 picked refraction under total
            # internal reflection (F = 1), a wi of length 1.2 (found by tests/test_fuzz.py)
            pick, share = live, self.pair_select[live]
            u_branch = np.minimum(u_lobe[live], sampling.ONE_MINUS_EPSILON)
        else:
            live, pick, share, u_branch = self._choose_lobes(u_lobe)
        label = np.full(n, LABEL_DIFFUSE, np.int8)
        everyone = len(live) == n
        at = gatherer(live, n)
        wo = at(self.wo_local)
        # A smooth lobe's sample it cannot produce (its own pdf 0: under the surface, wrong side
        # of the microfacet) is dropped, not re-weighted by the other lobes: the mixture pdf
        # counts only the samples each lobe keeps (seed 000: no redraw, zero contribution).
        wi_local, lobe_weight, lobe_pdf, eta2 = self._sample_lobes(pick, wo, at(u), u_branch, live, label)
        wi_local = _on_plane(wi_local)
        is_delta = self.pair_delta[pick]

        if everyone:
            wi = sampling.to_world(wi_local, self.t, self.b, self.ns)
        else:
            wi[live] = sampling.to_world(wi_local, at(self.t), at(self.b), at(self.ns))
        # Delta samples: the chosen lobe alone, divided by its selection probability.
        d = np.flatnonzero(is_delta)
        if len(d):
            rows = live[d]
            crosses = wi_local[d, 2] < 0
            ok = ((dot(wi[rows], self.ng[rows]) > 0) != crosses) | STRAIGHT[self.pair_kind[pick[d]]]
            w = lobe_weight[d] * self.weight[pick[d]] / share[d][:, None]
            weight[rows] = np.where(ok[:, None], w, 0.0)
            pdf[rows] = np.where(ok, share[d] * lobe_pdf[d], 0.0)
            delta[rows] = True
        # Smooth samples: the whole closure at wi, f cos / mixture pdf.
        s = np.flatnonzero(~is_delta & (lobe_pdf > 0))
        if len(s):
            rows = live[s]
            if self.single:  # the lobe alone: no need to gather the others
                f, p = self._eval_pairs(pick[s], take(wo, s), take(wi_local, s))
                agree = (dot(take(wi, rows), take(self.ng, rows)) > 0) == (wi_local[s, 2] > 0)
                f, p = scale(f, agree), np.where(agree, p * share[s], 0.0)
                bump = self._bump_shadowing(pick[s], np.arange(len(s)), rows, take(wi, rows), wi_local[s, 2])
                if bump is not None:
                    f, p = scale(f, bump), np.where(bump > 0, p, 0.0)
            else:
                f, p = self._mixture(rows, take(wi, rows))
            cos = np.abs(wi_local[s, 2])
            w = scale(f, np.divide(cos, p, out=np.zeros(len(s)), where=p > 0))
            if len(s) == n:
                weight, pdf = w, p
            else:
                weight[rows] = w
                pdf[rows] = p
        valid = (pdf > 0) & (max3(weight) > 0)
        if eta2 is not None:  # only where the sample crossed the surface
            eta2 = np.where(dot(wi, self.ng) < 0, eta2, 1.0)
        return BSDFSample(wi=wi, weight=weight, pdf=pdf, delta=delta, valid=valid, refraction_eta2=eta2,
                          label=label)
