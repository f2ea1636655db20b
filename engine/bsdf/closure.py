"""The BSDF at N shading points: the sum of their materials' lobes, shaded per lobe kind.

Every (point, lobe) pair of the batch is one row of a flat "pair" table; each lobe kind runs
once over its rows (index groups), so a scene with diffuse surfaces only never touches the
glossy code. A material's BSDF is the sum of its lobes (Scene.Materials):

    f = sum_k w_k f_k,    sampled by picking lobe k with probability P_k proportional to an
    estimate of its albedo at wo, then sampling f_k; pdf = sum_k P_k p_k (the mixture),

so the throughput f cos / pdf and the MIS pdf are those of the whole closure (unbiased whichever
lobe produced the direction). Delta lobes (mirror, smooth glass, transparency) are picked the
same way; their samples carry weight w_k F / (P_k P_branch) and the flag `delta`, and they add
nothing to eval() (a direction has probability 0 of being theirs).

Frames: `ns` and `ng` arrive already flipped to the side of `wo` (two-sided shading, as Cycles).
A reflected wi is valid only on that side of the geometric normal, a refracted one only on the
other (pbrt-v3's rule; Cycles checks Ng the same way when sampling); cosines use the shading
normal. Glass needs the side the ray came from: points whose wo is behind the triangle's own
winding normal are inside (eta -> 1 / eta), with the local frame mirrored so z points out.
Normal maps replace `ns` (tangent space, per-triangle tangents from the UVs), bent toward ng so
the mirror direction stays above the surface (Cycles' ensure_valid_specular_reflection);
the integrator then uses `closure.ns`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import sampling, textures
from ..scene import (FRESNEL_DIELECTRIC, FRESNEL_F82, LOBE_DIELECTRIC, LOBE_DIFFUSE, LOBE_MICROFACET,
                     LOBE_PHONG, LOBE_TRANSPARENT, RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMIT, Scene)
from ..vec import dot, gatherer, max3, normalize, scale, take
from . import dielectric, diffuse, fresnel, layering, microfacet, phong

# Smallest lobe-selection estimate, relative to the lobe's weight: a lobe whose albedo
# estimate is 0 at wo (e.g. Schlick with f0 = 0 at normal incidence) keeps a chance.
_MIN_ESTIMATE = 1e-3
_MIRROR_Z = np.array([1.0, 1.0, -1.0])  # the local frame seen from the other side
_MIRROR_XY = np.array([-1.0, -1.0, 1.0])  # reflection about the normal

# What kind of bounce a sample is (Cycles' labels as its path_state_next counts them): diffuse
# or glossy reflection (mirrors count as glossy), transmission (refraction, rough or smooth),
# transparent pass-through.
LABEL_DIFFUSE, LABEL_GLOSSY, LABEL_TRANSMIT, LABEL_TRANSPARENT = 0, 1, 2, 3
# Which lights' visibility (RAY_* bits) a lobe kind answers to in light sampling: a lobe is
# left out when a light is invisible to all of its kinds (Cycles' _surface_shader_exclude:
# glass is glossy and transmission, left out only when both are; Phong is diffuse + glossy).
_LOBE_RAYS = np.zeros(5, np.uint8)
_LOBE_RAYS[[LOBE_DIFFUSE, LOBE_PHONG, LOBE_MICROFACET, LOBE_DIELECTRIC]] = (
    RAY_DIFFUSE, RAY_DIFFUSE | RAY_GLOSSY, RAY_GLOSSY, RAY_GLOSSY | RAY_TRANSMIT)


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


def _to_local(v: np.ndarray, t: np.ndarray, b: np.ndarray, n: np.ndarray) -> np.ndarray:
    """World vectors v (K,3) in the frames (t, b, n) (K,3 each)."""
    return np.stack([dot(v, t), dot(v, b), dot(v, n)], axis=1)


def _mean3(a: np.ndarray) -> np.ndarray:
    return (a[:, 0] + a[:, 1] + a[:, 2]) / 3.0


def _sum_by(owner: np.ndarray, values: np.ndarray, k: int) -> np.ndarray:
    """Rows of values (P,3) summed per owner (P,) into (k,3)."""
    return np.stack([np.bincount(owner, values[:, c], minlength=k) for c in range(3)], axis=1)


def _ragged(starts: np.ndarray, counts: np.ndarray):
    """Indices starts[i] + 0..counts[i]-1 for all i, flattened, and the i of each."""
    owner = np.repeat(np.arange(len(counts)), counts)
    first = np.cumsum(counts) - counts
    return starts[owner] + np.arange(int(counts.sum())) - first[owner], owner


class Closure:
    # Whether every direction it samples or evaluates as non-zero lies on ng's side: not in
    # general (transmission); LambertClosure says True, which spares side tests.
    reflects_only = False

    def __init__(self, scene: Scene, mat: np.ndarray, ns: np.ndarray, ng: np.ndarray, wo: np.ndarray,
                 prim: np.ndarray, bary: np.ndarray, no_caustics=None, min_alpha=None):
        """mat (N,) material per point; ns, ng (N,3) unit normals on wo's side; wo (N,3) toward
        the previous vertex; prim (N,) triangles and bary (N,3) barycentrics of the hits.
        no_caustics: None, or (drop_reflection, drop_refraction) (N,) bool each: points whose
        glossy reflection / refraction is left out (Cycles' caustics toggles).
        min_alpha: None, or (N,) smallest GGX alpha of glossy and glass lobes (Filter Glossy)."""
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

        textured = np.concatenate([m.lobe_color_tex[lobe], m.lobe_roughness_tex[lobe], m.lobe_opacity_tex[lobe],
                                   m.normal_tex[mat]])
        uv = textures.mesh_uv(scene.mesh.uvs, prim, bary) if np.any(textured >= 0) else None
        mapped = np.any(m.normal_tex[mat] >= 0)
        outward = None  # the triangles' winding normals, only where glass or a normal map needs them
        if mapped or np.any(self.pair_kind == LOBE_DIELECTRIC):
            v = scene.mesh.vertices[scene.mesh.triangles[prim]].astype(np.float64)
            outward = normalize(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]))
        self.ns = self._normal_map(scene, mat, ns, ng, wo, prim, uv, outward) if mapped else ns
        self.t, self.b = sampling.frame_from_z(self.ns)
        self.wo_local = _to_local(wo, self.t, self.b, self.ns)
        # Points whose wo is behind the authored winding: glass sees them from inside.
        self.inside = dot(wo, outward) < 0 if outward is not None else np.zeros(n, bool)

        self._resolve_parameters(uv)
        if no_caustics is not None:
            self._drop_caustics(*no_caustics)
        if min_alpha is not None:
            self._blur(min_alpha)
        mu = self.wo_local[point, 2]
        # Lobes under a specular layer keep 1 - its albedo (Cycles' closure layering).
        rows = np.flatnonzero(m.lobe_layer[lobe] >= 0)
        if len(rows):
            top = self.pair_offset[point[rows]] + (m.lobe_layer[lobe[rows]] - start[mat[point[rows]]])
            f0 = fresnel.f0_from_ior(self.ior[top])[:, None] * self.tint[top]
            self.weight[rows] *= layering.base_weight(f0, self.roughness[top], mu[rows], self.ior[top])[:, None]

        estimate = self._albedo_estimate(mu)
        self.pair_estimate = estimate  # (P,3), for the colour passes (by_class)
        share = np.maximum(_mean3(estimate), _MIN_ESTIMATE * _mean3(self.weight))
        share = np.where(max3(self.weight) > 0, share, 0.0)
        total = share if self.single else np.bincount(point, share, minlength=n)[point]
        self.pair_select = np.divide(share, total, out=np.zeros(len(share)), where=total > 0)
        # Reflectance drives Russian roulette (seed 000: survival from the material).
        self.reflectance = estimate if self.single else _sum_by(point, estimate, n)
        # Points with a non-delta component take part in next-event estimation.
        self.has_smooth = np.bincount(point, ~self.pair_delta & (self.pair_select > 0), minlength=n) > 0

    def _resolve_parameters(self, uv):
        """Per-pair weight, colour, tint (P,3), roughness, alpha, ior (P,) and delta flags,
        textures looked up at the points' UVs (N,2) (None without textures)."""
        m, lobe, point, kind = self.m, self.pair_lobe, self.pair_point, self.pair_kind
        self.weight = m.lobe_weight[lobe].copy()
        rows = np.flatnonzero(m.lobe_opacity_tex[lobe] >= 0)
        if len(rows):
            a = textures.scalar(m, m.lobe_opacity_tex[lobe[rows]], uv[point[rows]])
            self.weight[rows] *= np.where(m.lobe_opacity_invert[lobe[rows]], 1.0 - a, a)[:, None]
        color = m.lobe_color[lobe].copy()
        rows = np.flatnonzero(m.lobe_color_tex[lobe] >= 0)
        if len(rows):
            color[rows] = textures.color(m, m.lobe_color_tex[lobe[rows]], uv[point[rows]])
        rows = np.flatnonzero(m.lobe_color_sqrt[lobe])
        color[rows] = np.sqrt(np.clip(color[rows], 0.0, 1.0))
        self.color = color
        self.tint = np.where(m.lobe_tint_is_color[lobe][:, None], color, m.lobe_tint[lobe])
        roughness = m.lobe_roughness[lobe].copy()
        rows = np.flatnonzero(m.lobe_roughness_tex[lobe] >= 0)
        if len(rows):
            roughness[rows] = textures.scalar(m, m.lobe_roughness_tex[lobe[rows]], uv[point[rows]])
        self.roughness = np.clip(roughness, 0.0, 1.0)
        self.ior = m.lobe_ior[lobe]
        self.alpha = np.zeros(len(lobe))
        self.pair_delta = kind == LOBE_TRANSPARENT
        glossy = np.flatnonzero((kind == LOBE_MICROFACET) | (kind == LOBE_DIELECTRIC))
        if len(glossy):
            self.alpha[glossy] = microfacet.alpha_from_roughness(self.roughness[glossy])
            self.pair_delta[glossy] = np.where(kind[glossy] == LOBE_MICROFACET, microfacet.is_delta(self.alpha[glossy]),
                                               dielectric.is_delta(self.alpha[glossy], self.ior[glossy]))

    def _drop_caustics(self, drop_reflection: np.ndarray, drop_refraction: np.ndarray):
        """Cycles' svm closure setup with caustics off: glossy and metallic closures are not
        made, Glass keeps a zero reflection or transmission tint, Phong (Ember's) loses ks.
        Lobes layered under a dropped one stay as they are."""
        kind, point = self.pair_kind, self.pair_point
        refl, refr = drop_reflection[point], drop_refraction[point]
        self.weight[refl & (kind == LOBE_MICROFACET)] = 0.0
        self.tint[refl & ((kind == LOBE_DIELECTRIC) | (kind == LOBE_PHONG))] = 0.0
        self.color[refr & (kind == LOBE_DIELECTRIC)] = 0.0

    def _blur(self, min_alpha: np.ndarray):
        """Cycles' bsdf_microfacet_blur: alpha = max(alpha, min_alpha) for GGX and glass lobes
        (their albedo estimates keep the authored roughness, as Cycles keeps its energy terms)."""
        kind = self.pair_kind
        rows = np.flatnonzero(((kind == LOBE_MICROFACET) | (kind == LOBE_DIELECTRIC))
                              & (min_alpha[self.pair_point] > self.alpha))
        if len(rows) == 0:
            return
        self.alpha[rows] = min_alpha[self.pair_point[rows]]
        self.pair_delta[rows] = np.where(kind[rows] == LOBE_MICROFACET, microfacet.is_delta(self.alpha[rows]),
                                         dielectric.is_delta(self.alpha[rows], self.ior[rows]))

    @property
    def n(self) -> int:
        return len(self.ns)

    # --- lobe parameters -----------------------------------------------------------------------
    def _albedo_estimate(self, mu: np.ndarray) -> np.ndarray:
        """Per-pair albedo estimate (P,3) at wo: drives lobe selection and Russian roulette."""
        kind, w, color, tint = self.pair_kind, self.weight, self.color, self.tint
        est = w * color  # diffuse, transparent
        rows = np.flatnonzero(kind == LOBE_PHONG)
        if len(rows):
            est[rows] = w[rows] * phong.albedo(color[rows], tint[rows], self.m.lobe_exponent[self.pair_lobe[rows]],
                                               self.wo_local[self.pair_point[rows]])
        rows = np.flatnonzero(kind == LOBE_MICROFACET)
        if len(rows):
            est[rows] = w[rows] * self._fresnel(rows, np.clip(mu[rows], 0.0, 1.0))
        rows = np.flatnonzero(kind == LOBE_DIELECTRIC)
        if len(rows):
            F = fresnel.dielectric(np.abs(mu[rows]), self.ior[rows])[:, None]
            est[rows] = w[rows] * (F * tint[rows] + (1.0 - F) * color[rows])
        return est

    def _fresnel(self, rows: np.ndarray, cos: np.ndarray) -> np.ndarray:
        """Fresnel colour (K,3) of microfacet pairs `rows` at cosines cos (K,) to the microfacet."""
        model = self.m.lobe_fresnel[self.pair_lobe[rows]]
        F = self.color[rows].copy()  # FRESNEL_NONE: the Glossy colour
        r = np.flatnonzero(model == FRESNEL_F82)
        if len(r):
            F[r] = fresnel.f82_tint(self.color[rows[r]], np.minimum(self.tint[rows[r]], 1.0), cos[r])
        r = np.flatnonzero(model == FRESNEL_DIELECTRIC)
        if len(r):
            eta = self.ior[rows[r]]
            F[r] = fresnel.dielectric_remapped(fresnel.f0_from_ior(eta)[:, None] * self.tint[rows[r]], cos[r], eta)
        return F

    def _normal_map(self, scene, mat, ns, ng, wo, prim, uv, outward):
        """Shading normals (N,3) perturbed by tangent-space normal maps (Cycles' Normal Map node)."""
        m = self.m
        rows = np.flatnonzero(m.normal_tex[mat] >= 0)
        side = np.where(dot(ng[rows], outward[rows]) >= 0, 1.0, -1.0)[:, None]
        n_auth = ns[rows] * side  # the smooth normal in its authored orientation
        c = 2.0 * textures.color(m, m.normal_tex[mat[rows]], uv[rows]) - 1.0
        # Per-triangle tangent frame from the UV parametrisation: dp/du, dp/dv.
        tri = scene.mesh.triangles[prim[rows]]
        p = scene.mesh.vertices[tri].astype(np.float64)
        t_uv = scene.mesh.uvs[prim[rows]].astype(np.float64)
        e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        d1, d2 = t_uv[:, 1] - t_uv[:, 0], t_uv[:, 2] - t_uv[:, 0]
        det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
        inv = np.divide(1.0, det, out=np.zeros(len(det)), where=det != 0)[:, None]
        dpdu = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * inv
        dpdv = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * inv
        tangent = normalize(dpdu - n_auth * dot(dpdu, n_auth)[:, None])
        sign = np.where(dot(np.cross(n_auth, tangent), dpdv) < 0, -1.0, 1.0)[:, None]
        bitangent = sign * np.cross(n_auth, tangent)
        mapped = normalize(c[:, 0:1] * tangent + c[:, 1:2] * bitangent + c[:, 2:3] * n_auth)
        strength = np.maximum(m.normal_strength[mat[rows]], 0.0)[:, None]
        mapped = normalize(n_auth + (mapped - n_auth) * strength)
        ok = (det != 0)[:, None] & (dot(mapped, mapped) > 0)[:, None]
        out = ns.copy()
        out[rows] = _valid_reflection_normal(ng[rows], wo[rows], np.where(ok, mapped, n_auth) * side)
        return out

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
        kind = self.pair_kind[pairs]
        r = np.flatnonzero(kind == LOBE_DIFFUSE)
        if len(r):
            f[r] = diffuse.eval(take(self.color, pairs[r]), wi[r, 2])
            pdf[r] = diffuse.pdf(wi[r, 2])
        r = np.flatnonzero(kind == LOBE_PHONG)
        if len(r):
            p = pairs[r]
            args = (self.color[p], self.tint[p], self.m.lobe_exponent[self.pair_lobe[p]], wo[r], wi[r])
            f[r], pdf[r] = phong.eval(*args), phong.pdf(*args)
        r = np.flatnonzero(kind == LOBE_MICROFACET)
        if len(r):
            p = pairs[r]
            h = normalize(wo[r] + wi[r])
            F = self._fresnel(p, np.clip(dot(wo[r], h), 0.0, 1.0))
            f[r] = microfacet.eval_reflection(self.alpha[p], wo[r], wi[r], F)
            pdf[r] = microfacet.pdf_reflection(self.alpha[p], wo[r], wi[r])
        r = np.flatnonzero(kind == LOBE_DIELECTRIC)
        if len(r):
            p = pairs[r]
            mirror = np.where(self.inside[self.pair_point[p]][:, None], _MIRROR_Z, 1.0)
            wo_o, wi_o = wo[r] * mirror, wi[r] * mirror
            reflected = ((wi[r, 2] > 0) == (wo[r, 2] > 0))[:, None]
            # wo under the shading normal (smooth-normal silhouettes) has no glass lobe, as Cycles.
            tint = np.where(reflected, self.tint[p], self.color[p]) * (wo[r, 2:3] > 0)
            f[r] = dielectric.eval_rough(self.alpha[p], self.ior[p], wo_o, wi_o) * tint
            pdf[r] = np.where(wo[r, 2] > 0, dielectric.pdf_rough(self.alpha[p], self.ior[p], wo_o, wi_o), 0.0)
        return f * take(self.weight, pairs), pdf

    def _mixture(self, rows: np.ndarray, wi: np.ndarray, visible=None):
        """f (K,3) and mixture pdf (K,) of the points `rows` (K,) for world directions wi (K,3);
        visible (K,) RAY_* bits of a light: lobes it does not light are left out."""
        k = len(rows)
        at = gatherer(rows, self.n)
        wi_local = _to_local(wi, at(self.t), at(self.b), at(self.ns))
        # Reflection must stay on the geometric normal's side, refraction must cross it.
        agree = (dot(wi, at(self.ng)) > 0) == (wi_local[:, 2] > 0)
        pairs, owner = self._pairs_of(rows)
        if visible is not None:
            lit = (_LOBE_RAYS[self.pair_kind[pairs]] & visible[owner]) != 0
            pairs, owner = pairs[lit], owner[lit]
        f_pair, pdf_pair = self._eval_pairs(pairs, take(self.wo_local, rows[owner]), take(wi_local, owner))
        pdf_pair = self.pair_select[pairs] * pdf_pair
        if self.single:
            f = np.zeros((k, 3))
            pdf = np.zeros(k)
            f[owner], pdf[owner] = f_pair, pdf_pair
        else:
            f, pdf = _sum_by(owner, f_pair, k), np.bincount(owner, pdf_pair, minlength=k)
        return scale(f, agree), np.where(agree, pdf, 0.0)

    def eval(self, wi: np.ndarray, rows: np.ndarray, visible=None):
        """f (K,3) and solid-angle pdf (K,) at the points `rows` (K,) for directions wi (K,3);
        visible (K,) RAY_* bits or None: only lobes of those kinds (a light's visibility)."""
        return self._mixture(rows, wi, visible)

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
        refracted = wi_local[owner, 2] < 0
        cls = _lobe_class(self.pair_kind[pairs], refracted)
        out = np.zeros((k * 3, 3))
        for c in range(3):
            out[:, c] = np.bincount(owner * 3 + cls, f_pair[:, c], minlength=k * 3)
        return out.reshape(k, 3, 3) * agree[:, None, None]

    def albedo_by_class(self) -> np.ndarray:
        """(N,3 classes,3) reflectance estimate at wo per lobe class (the colour passes)."""
        values, kind, owner = self.pair_estimate.copy(), self.pair_kind, self.pair_point
        cls = _lobe_class(kind, np.zeros(len(kind), bool))
        rows = np.flatnonzero(kind == LOBE_DIELECTRIC)
        if len(rows):  # F tint reflects (glossy), (1 - F) colour refracts (transmission)
            F = fresnel.dielectric(np.abs(self.wo_local[owner[rows], 2]), self.ior[rows])[:, None]
            reflected = self.weight[rows] * F * self.tint[rows]
            refracted = values[rows] - reflected
            values[rows] = reflected
            values = np.concatenate([values, refracted])
            owner = np.concatenate([owner, owner[rows]])
            cls = np.concatenate([cls, np.full(len(rows), 2)])
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
        kind = self.pair_kind[pick]
        label = np.full(n, LABEL_DIFFUSE, np.int8)
        everyone = len(live) == n
        at = gatherer(live, n)
        wo = at(self.wo_local)
        wi_local = np.zeros((len(live), 3))
        lobe_weight = np.zeros((len(live), 3))  # delta samples: weight / branch pmf
        branch = np.ones(len(live))  # delta samples: branch pmf
        is_delta = self.pair_delta[pick]
        # A smooth lobe's sample it cannot produce (its own pdf 0: under the surface, wrong side
        # of the microfacet) is dropped, not re-weighted by the other lobes: the mixture pdf
        # counts only the samples each lobe keeps (seed 000: no redraw, zero contribution).
        kept = np.ones(len(live), bool)
        uu = at(u)

        r = np.flatnonzero(kind == LOBE_DIFFUSE)
        wi_local[r] = diffuse.sample(uu[r])
        kept[r] = wi_local[r, 2] > 0
        r = np.flatnonzero(kind == LOBE_PHONG)
        if len(r):
            p = pick[r]
            wi_local[r], _, p_lobe = phong.sample(self.color[p], self.tint[p], self.m.lobe_exponent[self.pair_lobe[p]],
                                                  wo[r], uu[r], u_branch[r])
            kept[r] = p_lobe > 0
            label[live[r]] = np.where(u_branch[r] < phong.diffuse_probability(self.color[p], self.tint[p]),
                                      LABEL_DIFFUSE, LABEL_GLOSSY)
        r = np.flatnonzero(kind == LOBE_MICROFACET)
        if len(r):
            label[live[r]] = LABEL_GLOSSY
            p = pick[r]
            mirror = is_delta[r]
            rs, p_s = r[~mirror], p[~mirror]
            if len(rs):
                wi_local[rs], _, p_lobe = microfacet.sample_reflection(self.alpha[p_s], wo[rs], uu[rs])
                kept[rs] = p_lobe > 0
            rd, p_d = r[mirror], p[mirror]
            if len(rd):
                wi_local[rd] = wo[rd] * _MIRROR_XY
                lobe_weight[rd] = self._fresnel(p_d, np.clip(wo[rd, 2], 0.0, 1.0)) * (wo[rd, 2] > 0)[:, None]
        eta2 = None
        r = np.flatnonzero(kind == LOBE_DIELECTRIC)
        if len(r):
            p = pick[r]
            mirror = np.where(self.inside[live[r]][:, None], _MIRROR_Z, 1.0)
            wo_o = wo[r] * mirror
            # eta_rel = n(wi side) / n(wo side) of a refraction; wo_o.z > 0: wo outside.
            eta2 = np.ones(n)
            eta2[live[r]] = np.where(wo_o[:, 2] > 0, self.ior[p], 1.0 / self.ior[p]) ** 2
            smooth = is_delta[r]
            if smooth.any():
                rd, pd = r[smooth], p[smooth]
                wi_o, w, pmf, refl = dielectric.sample_smooth(self.ior[pd], wo_o[smooth], u_branch[rd])
                wi_local[rd] = wi_o * mirror[smooth]
                above = (wo[rd, 2] > 0)[:, None]
                lobe_weight[rd] = w * np.where(refl[:, None], self.tint[pd], self.color[pd]) * above
                branch[rd] = pmf
            if (~smooth).any():
                rs, ps = r[~smooth], p[~smooth]
                wi_o, _, p_lobe = dielectric.sample_rough(self.alpha[ps], self.ior[ps], wo_o[~smooth], uu[rs], u_branch[rs])
                wi_local[rs] = wi_o * mirror[~smooth]
                kept[rs] = (p_lobe > 0) & (wo[rs, 2] > 0)
        r = np.flatnonzero(kind == LOBE_DIELECTRIC)
        if len(r):
            label[live[r]] = np.where(wi_local[r, 2] * wo[r, 2] < 0, LABEL_TRANSMIT, LABEL_GLOSSY)
        r = np.flatnonzero(kind == LOBE_TRANSPARENT)
        if len(r):
            wi_local[r] = -wo[r]
            lobe_weight[r] = self.color[pick[r]]
            label[live[r]] = LABEL_TRANSPARENT

        if everyone:
            wi = sampling.to_world(wi_local, self.t, self.b, self.ns)
        else:
            wi[live] = sampling.to_world(wi_local, at(self.t), at(self.b), at(self.ns))
        # Delta samples: the chosen lobe alone, divided by its selection probability.
        d = np.flatnonzero(is_delta)
        if len(d):
            rows = live[d]
            crosses = wi_local[d, 2] < 0
            ok = ((dot(wi[rows], self.ng[rows]) > 0) != crosses) | (kind[d] == LOBE_TRANSPARENT)
            w = lobe_weight[d] * self.weight[pick[d]] / share[d][:, None]
            weight[rows] = np.where(ok[:, None], w, 0.0)
            pdf[rows] = np.where(ok, share[d] * branch[d], 0.0)
            delta[rows] = True
        # Smooth samples: the whole closure at wi, f cos / mixture pdf.
        s = np.flatnonzero(~is_delta & kept)
        if len(s):
            rows = live[s]
            if self.single:  # the lobe alone: no need to gather the others
                f, p = self._eval_pairs(pick[s], take(wo, s), take(wi_local, s))
                agree = (dot(take(wi, rows), take(self.ng, rows)) > 0) == (wi_local[s, 2] > 0)
                f, p = scale(f, agree), np.where(agree, p * share[s], 0.0)
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


def _lobe_class(kind: np.ndarray, refracted: np.ndarray) -> np.ndarray:
    """Render-pass class of lobes: 0 diffuse, 1 glossy (Phong, microfacet, glass reflection),
    2 transmission (glass refraction, transparency)."""
    cls = np.where(kind == LOBE_DIFFUSE, 0, 1)
    return np.where((kind == LOBE_TRANSPARENT) | ((kind == LOBE_DIELECTRIC) & refracted), 2, cls)


def _valid_reflection_normal(ng: np.ndarray, wo: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Shading normals (K,3) tilted toward ng just enough that the mirror direction of wo stays
    min(0.9 wo.ng, 0.01) above the surface (Cycles bsdf_util.h ensure_valid_specular_reflection:
    the root of 4 a Nz^4 - 2 b Nz^2 + c = 0 in the plane of n and ng)."""
    R = 2.0 * dot(n, wo)[:, None] * n - wo
    iz = dot(wo, ng)
    threshold = np.minimum(0.9 * iz, 0.01)
    bad = dot(ng, R) < threshold
    if not bad.any():
        return n
    x = n - dot(n, ng)[:, None] * ng
    x_len = np.sqrt(dot(x, x))
    x = np.where((x_len > 0)[:, None], x / np.maximum(x_len, 1e-300)[:, None], n)
    ix = dot(wo, x)
    a = ix * ix + iz * iz
    b = 2.0 * (a + iz * threshold)
    c = (threshold + iz) ** 2
    root = np.sqrt(np.maximum(b * b - 4.0 * a * c, 0.0))
    nz2 = 0.25 * np.divide(np.where(ix < 0, b + root, b - root), a, out=np.ones(len(a)), where=a > 0)
    nz2 = np.clip(nz2, 0.0, 1.0)
    bent = np.sqrt(1.0 - nz2)[:, None] * x + np.sqrt(nz2)[:, None] * ng
    return np.where(bad[:, None], bent, n)
