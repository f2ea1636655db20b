"""The path tracer's options, one small record per concern, built once per render from the
Settings (Cycles' names in brackets), and Gather: what one trace is asked for.

  Strategy    which estimators of direct light a path combines (strategy)
  Clamp       contributions clamped in brightness (clamp_direct, clamp_indirect)
  LightPaths  bounce limits per kind of bounce, Russian roulette's start, transparency
  ClosureOptions  per-vertex changes to the BSDF (caustics_reflective/refractive, filter_glossy)
  Gather      a trace's own options: camera paths, or gather paths from points shaded apart
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..bsdf.closure import LABEL_DIFFUSE, LABEL_GLOSSY, LABEL_TRANSMIT, LABEL_TRANSPARENT
from ..scene import LOBE_TRANSPARENT, RAY_DIFFUSE
from ..vec import scale
from .path_state import Bounces


@dataclass(frozen=True)
class Strategy:
    """nee: one light sample at every vertex ("mis", "light"); bsdf_hits: emission that BSDF
    sampling finds counts ("mis", "bsdf"; with "light" alone it weighs 0 after non-delta
    bounces); mis: the two combined by the balance heuristic ("mis"; else what a strategy
    finds weighs 1)."""
    nee: bool
    bsdf_hits: bool
    mis: bool

    @classmethod
    def of(cls, name: str) -> "Strategy":
        return cls(nee=name in ("mis", "light"), bsdf_hits=name in ("mis", "bsdf"), mis=name == "mis")


@dataclass(frozen=True)
class Clamp:
    """Limits on |R|+|G|+|B| of a contribution (Cycles stores 3 x the UI value; inf: none),
    for direct light (found after at most one bounce) and indirect light."""
    direct: float
    indirect: float

    @classmethod
    def of(cls, settings) -> "Clamp | None":
        """The settings' clamping, or None when both limits are off (0)."""
        if not (settings.clamp_direct > 0 or settings.clamp_indirect > 0):
            return None
        return cls(*(3.0 * v if v > 0 else np.inf for v in (settings.clamp_direct, settings.clamp_indirect)))

    def __call__(self, c: np.ndarray, direct, rows=None) -> np.ndarray:
        """Contributions c (K,3) clamped as Cycles' film_clamp_light: where |R|+|G|+|B| exceeds
        the limit (direct's where `direct` (K,) (or direct[rows]; or one bool), else
        indirect's), c is scaled to it (hue kept)."""
        limit = np.where(direct if rows is None or np.ndim(direct) == 0 else direct[rows], self.direct, self.indirect)
        total = np.abs(c).sum(axis=1)
        over = total > limit
        if not over.any():
            return c
        return scale(c, np.where(over, limit / np.where(over, total, 1.0), 1.0))


@dataclass(frozen=True, eq=False)
class LightPaths:
    """Cycles' light-path limits (path_state_next) and what per-path state they need.
    max_depth: bounces after the first hit; rr_depth: bounces before Russian roulette starts;
    per_label (4,) limits per LABEL_*; transparent (M,) bool: materials with a transparent
    lobe, which may pass a path at its last vertex; counts, ray, min_pdf: Bounces keeps
    per-type counts, ray kinds, the smallest pdf (see Bounces)."""
    max_depth: int
    rr_depth: int
    per_label: np.ndarray
    transparent: np.ndarray
    any_transparent: bool
    counts: bool
    ray: bool
    min_pdf: bool

    @classmethod
    def of(cls, scene, lights, visibility) -> "LightPaths":
        st, m = scene.settings, scene.materials
        per_label = np.zeros(4, np.int64)
        per_label[[LABEL_DIFFUSE, LABEL_GLOSSY, LABEL_TRANSMIT, LABEL_TRANSPARENT]] = (
            st.diffuse_bounces, st.glossy_bounces, st.transmission_bounces, st.transparent_bounces)
        transparent = np.zeros(len(m.kind), bool)
        transparent[m.lobe_material[m.lobe_kind == LOBE_TRANSPARENT]] = True
        any_transparent = bool(transparent.any())
        return cls(st.max_depth, st.rr_depth, per_label, transparent, any_transparent,
                   counts=bool(np.any(per_label[[LABEL_DIFFUSE, LABEL_GLOSSY, LABEL_TRANSMIT]] < st.max_depth)
                               or any_transparent),
                   ray=bool(lights.partial_visibility or not visibility.trivial or any_transparent
                            or not (st.caustics_reflective and st.caustics_refractive)),
                   min_pdf=st.filter_glossy > 0)

    def start(self, n: int, max_depth: int, per_path: bool) -> Bounces:
        """The bounce counts of n paths on their first rays."""
        return Bounces.start(n, max_depth, self.any_transparent, self.counts, self.ray, self.min_pdf, per_path)

    def rays_at_most(self, max_depth: int) -> int:
        """Rays a path traces at most: its bounces and transparent passes, and the first ray."""
        return max_depth + int(self.per_label[LABEL_TRANSPARENT]) + 1


@dataclass(frozen=True)
class ClosureOptions:
    """Per-vertex changes to the closure: the caustics toggles (reflective, refractive: off
    drops those lobes after a diffuse bounce) and Filter Glossy (0: off)."""
    caustics_reflective: bool
    caustics_refractive: bool
    filter_glossy: float

    @classmethod
    def of(cls, settings) -> "ClosureOptions":
        return cls(settings.caustics_reflective, settings.caustics_refractive, settings.filter_glossy)

    def no_caustics(self, bounces: Bounces):
        """(drop_reflection, drop_refraction) (N,) bool for the closure, or None with both caustics on."""
        if self.caustics_reflective and self.caustics_refractive:
            return None
        after = bounces.ray == RAY_DIFFUSE  # the last non-transparent bounce was diffuse
        return (after & (not self.caustics_reflective), after & (not self.caustics_refractive))

    def blur(self, bounces: Bounces):
        """Filter Glossy (Cycles' surface_shader.h): GGX alpha at least sqrt(1 - p) / 2 with
        p = min_ray_pdf / filter_glossy where p < 1, or None when off."""
        if not self.filter_glossy > 0:
            return None
        p = bounces.min_pdf / self.filter_glossy
        return np.where(p < 1.0, 0.5 * np.sqrt(np.maximum(1.0 - p, 0.0)), 0.0)


@dataclass(frozen=True, eq=False)
class Gather:
    """What one PathTracer.trace is asked for; the defaults are camera paths.
    first_emission False leaves out the emission the rays themselves find (a gather ray
    whose direct light is sampled apart); max_depth: bounces after the first hit (None: the
    scene's); caustic_ends (M,) bool per material, or None: light that a path finds before it
    reaches one of these materials is left out (a gather path from a point whose caustics
    come from a caustic map: that map holds exactly those paths); t_first (N,), if given,
    receives the first hit's distance (inf where the ray escaped)."""
    first_emission: bool = True
    max_depth: int | None = None
    caustic_ends: np.ndarray | None = None
    t_first: np.ndarray | None = None


CAMERA_PATHS = Gather()
