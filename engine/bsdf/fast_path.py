"""The Lambertian fast path: a batch whose points are all plain Lambertian (one untextured
diffuse lobe) gets `LambertClosure`, the same BSDF as the general `Closure` without its lobe
table (about half the cost of a bounce); a mixed batch gets the general closure with
LambertClosure's numbers at its plain points, so a path's value never depends on what the
other paths of its batch hit. `make_closure` chooses.
"""
from __future__ import annotations

import numpy as np

from .. import sampling
from ..scene import LOBE_DIFFUSE, RAY_DIFFUSE, Scene
from ..vec import dot, gatherer, max3, scale, take
from . import diffuse
from .closure import LABEL_DIFFUSE, BSDFSample, Closure


def plain_lambert_albedo(m) -> np.ndarray:
    """(M,3) albedo of materials that are one untextured diffuse lobe (no normal map, no
    layering, no node program) or have no lobe at all (black, e.g. pure emitters), NaN for
    every other material."""
    n_mat = len(m.kind)
    count = np.bincount(m.lobe_material, minlength=n_mat)
    first = np.searchsorted(m.lobe_material, np.arange(n_mat))
    lobe = np.minimum(first, max(len(m.lobe_kind) - 1, 0))
    if len(m.lobe_kind) == 0:
        return np.where((m.normal_tex < 0)[:, None], 0.0, np.nan) * np.ones((n_mat, 3))
    plain = ((count == 1) & (m.lobe_kind[lobe] == LOBE_DIFFUSE) & (m.lobe_color_tex[lobe] < 0)
             & (m.lobe_roughness_tex[lobe] < 0) & (m.lobe_opacity_tex[lobe] < 0) & ~m.lobe_color_sqrt[lobe]
             & (m.lobe_layer[lobe] < 0) & (m.normal_tex < 0))
    albedo = np.where((count == 1)[:, None], m.lobe_weight[lobe] * m.lobe_color[lobe], 0.0)
    black = (count == 0) & (m.normal_tex < 0)
    if m.graphs:  # a node program varies the material over the surface
        varies = np.array([g is not None for g in m.graphs])
        plain, black = plain & ~varies, black & ~varies
    return np.where((plain | black)[:, None], albedo, np.nan)


class LambertClosure:
    """The closure of a batch whose points all have a plain Lambertian material: the same
    BSDF as `Closure` gives them (one diffuse lobe, chosen with probability 1), without the
    lobe table - the most common case, about half the cost of a bounce otherwise."""

    # Every direction it samples or evaluates as non-zero lies on ng's side (no transmission).
    reflects_only = True

    def __init__(self, albedo: np.ndarray, ns: np.ndarray, ng: np.ndarray, frame=None):
        """frame: (t, b) = sampling.frame_from_z(ns) if the caller has it already."""
        self.ns, self.ng = ns, ng
        self.albedo = albedo
        self.reflectance = albedo
        self.has_smooth = max3(albedo) > 0
        self.t, self.b = sampling.frame_from_z(ns) if frame is None else frame

    def eval(self, wi: np.ndarray, rows: np.ndarray, visible=None, shading_side=None):
        at = gatherer(rows, len(self.ns))
        above = dot(wi, at(self.ng)) > 0
        cos_i = np.where(above if shading_side is None else above | shading_side, dot(wi, at(self.ns)), 0.0)
        if visible is not None:
            cos_i = np.where((visible & RAY_DIFFUSE) != 0, cos_i, 0.0)
        return diffuse.eval(at(self.albedo), cos_i), diffuse.pdf(cos_i)

    def eval_by_class(self, wi: np.ndarray, rows: np.ndarray) -> np.ndarray:
        out = np.zeros((len(rows), 3, 3))
        out[:, 0] = self.eval(wi, rows)[0]
        return out

    def albedo_by_class(self) -> np.ndarray:
        out = np.zeros((len(self.ns), 3, 3))
        out[:, 0] = self.albedo
        return out

    def sample(self, u: np.ndarray, u_lobe: np.ndarray, in_unit=False) -> BSDFSample:
        return self.sample_at(None, u, in_unit)

    def sample_at(self, rows, u: np.ndarray, in_unit=False) -> BSDFSample:
        """Samples at points rows (K,) (repeats allowed; None: all), uniforms u (K,2) (in_unit:
        known to lie in [0, 1), a Sampler's numbers: not clamped again)."""
        at = (lambda a: a) if rows is None else gatherer(rows, len(self.ns))  # noqa: E731
        local = diffuse.sample(u, in_unit)
        wi = sampling.to_world(local, at(self.t), at(self.b), at(self.ns))
        ok = (dot(wi, at(self.ng)) > 0) & (local[:, 2] > 0) & (self.has_smooth if rows is None else self.has_smooth[rows])
        # f cos / pdf = albedo for cosine-weighted sampling of a Lambertian lobe.
        weight = scale(at(self.albedo), ok)
        pdf = np.where(ok, diffuse.pdf(local[:, 2]), 0.0)
        return BSDFSample(wi=wi, weight=weight, pdf=pdf, delta=np.zeros(len(ok), bool), valid=ok,
                          label=np.full(len(ok), LABEL_DIFFUSE, np.int8))


class _MixedClosure(Closure):
    """The general closure of a batch in which some points (`plain`) are plain Lambertian:
    at those points every number is LambertClosure's, which equals the general closure's only
    up to rounding. So a path's value never depends on what the other paths of its batch hit
    (batch size, run-time unit sizes, path regeneration): the image stays bit for bit the same."""

    def __init__(self, plain: np.ndarray, albedo: np.ndarray, scene, mat, ns, ng, *args):
        super().__init__(scene, mat, ns, ng, *args)
        self.plain = plain
        self.lambert = LambertClosure(take(albedo, plain), take(ns, plain), take(ng, plain))
        self.position = np.full(self.n, -1, np.int64)  # a point's row in self.lambert, or -1
        self.position[plain] = np.arange(len(plain))
        self.reflectance = self.reflectance.copy()
        self.reflectance[plain] = self.lambert.reflectance
        self.has_smooth = self.has_smooth.copy()
        self.has_smooth[plain] = self.lambert.has_smooth

    def _plain_of(self, rows):
        """(K',) entries of rows that are plain points, (K',) their rows in self.lambert."""
        pos = self.position[rows]
        sel = np.flatnonzero(pos >= 0)
        return sel, pos[sel]

    def eval(self, wi: np.ndarray, rows: np.ndarray, visible=None, shading_side=None):
        f, p = super().eval(wi, rows, visible, shading_side)
        sel, pos = self._plain_of(rows)
        if len(sel):
            f[sel], p[sel] = self.lambert.eval(take(wi, sel), pos, None if visible is None else visible[sel],
                                               None if shading_side is None else shading_side[sel])
        return f, p

    def eval_by_class(self, wi: np.ndarray, rows: np.ndarray) -> np.ndarray:
        out = super().eval_by_class(wi, rows)
        sel, pos = self._plain_of(rows)
        if len(sel):
            out[sel] = self.lambert.eval_by_class(take(wi, sel), pos)
        return out

    def albedo_by_class(self) -> np.ndarray:
        out = super().albedo_by_class()
        out[self.plain] = self.lambert.albedo_by_class()
        return out

    def sample(self, u: np.ndarray, u_lobe: np.ndarray) -> BSDFSample:
        bs = super().sample(u, u_lobe)
        rows = self.plain
        s = self.lambert.sample(take(u, rows), u_lobe[rows])
        for name in ("wi", "weight", "pdf", "delta", "valid", "label"):
            getattr(bs, name)[rows] = getattr(s, name)
        if bs.refraction_eta2 is not None:
            bs.refraction_eta2[rows] = 1.0
        return bs


def make_closure(scene: Scene, lambert_albedo: np.ndarray, mat, ns, ng, wo, prim, bary, no_caustics=None,
                 min_alpha=None, frame=None, programs=None, p=None, ray=None, adjoint=False):
    """LambertClosure when every point's material is plain Lambertian, else the general Closure
    (with LambertClosure's numbers at the plain points of a mixed batch: _MixedClosure).
    lambert_albedo: plain_lambert_albedo(scene.materials), computed once per render;
    no_caustics, min_alpha, programs, p, ray, adjoint: see Closure (nothing to drop, blur or
    evaluate in a Lambertian, which is reciprocal); frame: (t, b) = sampling.frame_from_z(ns), if known."""
    albedo = take(lambert_albedo, mat)
    plain = ~np.isnan(albedo[:, 0])
    if plain.all():
        return LambertClosure(albedo, ns, ng, frame)
    if plain.any():
        return _MixedClosure(np.flatnonzero(plain), albedo, scene, mat, ns, ng, wo, prim, bary, no_caustics,
                             min_alpha, programs, p, ray, adjoint)
    return Closure(scene, mat, ns, ng, wo, prim, bary, no_caustics, min_alpha, programs, p, ray, adjoint)
