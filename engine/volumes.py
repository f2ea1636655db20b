"""Homogeneous participating media: Cycles' volume shader coefficients and the per-material
media table the path tracer reads.

Coefficients per unit length, RGB (Cycles, kernel/svm/closure.h svm_node_closure_volume,
svm_node_principled_volume; the density is clamped at 0 first):

  Volume Absorption   sigma_a = (1 - color) density
  Volume Scatter      sigma_s = color density (no absorption; Henyey-Greenstein phase)
  Principled Volume   sigma_s = color density,
                      sigma_a = max(1 - color, 0) max(1 - sqrt(absorption color), 0) density,
                      emission = emission strength x emission color (radiance per unit length,
                      not scaled by the density)

Shaders added together sum their coefficients (Cycles sums the extinction and keeps each
scatter closure, weighted by its sigma_s); a mix scales them by its factor.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scene import LOBE_TRANSPARENT


@dataclass(frozen=True)
class Coefficients:
    """One homogeneous medium: sigma_s, sigma_a, emission (3,) and the HG mean cosine g."""
    sigma_s: np.ndarray
    sigma_a: np.ndarray
    emission: np.ndarray
    g: float = 0.0

    @staticmethod
    def none() -> "Coefficients":
        return Coefficients(np.zeros(3), np.zeros(3), np.zeros(3), 0.0)

    def scaled(self, w) -> "Coefficients":
        w = np.asarray(w, np.float64)
        return Coefficients(self.sigma_s * w, self.sigma_a * w, self.emission * w, self.g)

    def __add__(self, other: "Coefficients") -> "Coefficients":
        s = self.sigma_s + other.sigma_s
        total = float(s.sum())
        # The phase functions mix by their scattering weight; one HG of the weighted mean g
        # stands for the mixture (exact where the two g are equal).
        g = (self.g * float(self.sigma_s.sum()) + other.g * float(other.sigma_s.sum())) / total if total > 0 else 0.0
        return Coefficients(s, self.sigma_a + other.sigma_a, self.emission + other.emission, g)

    def as_row(self) -> dict:
        return dict(sigma_s=tuple(self.sigma_s), sigma_a=tuple(self.sigma_a), emission=tuple(self.emission),
                    g=float(self.g))


def _rgb(c) -> np.ndarray:
    return np.asarray(c, np.float64).reshape(3)


def volume_absorption(color, density: float) -> Coefficients:
    d = max(float(density), 0.0)
    return Coefficients(np.zeros(3), np.maximum(1.0 - _rgb(color), 0.0) * d, np.zeros(3))


def volume_scatter(color, density: float, g: float) -> Coefficients:
    d = max(float(density), 0.0)
    return Coefficients(np.maximum(_rgb(color), 0.0) * d, np.zeros(3), np.zeros(3), float(g))


def principled_volume(color, density: float, anisotropy: float, absorption_color,
                      emission_strength: float, emission_color) -> Coefficients:
    d = max(float(density), 0.0)
    c = np.maximum(_rgb(color), 0.0)
    absorption = np.maximum(1.0 - c, 0.0) * np.maximum(1.0 - np.sqrt(np.maximum(_rgb(absorption_color), 0.0)), 0.0)
    strength = float(emission_strength)
    emission = strength * _rgb(emission_color) if strength > 0 else np.zeros(3)
    return Coefficients(c * d, absorption * d, emission, float(anisotropy))


@dataclass(frozen=True, eq=False)
class Media:
    """Per material (M+1 rows: the last row is vacuum, so a path's medium index -1 reads it):
    sigma_s, sigma_t, emission (M+1,3); g (M+1,); has (M,) bool: the material bounds a
    medium; passable (M,) bool: its surface is a plain transparent boundary (a volume-only
    material), which shadow rays cross."""
    sigma_s: np.ndarray
    sigma_t: np.ndarray
    emission: np.ndarray
    g: np.ndarray
    has: np.ndarray
    passable: np.ndarray

    @classmethod
    def of(cls, materials) -> "Media | None":
        """The scene's media, or None where no material has one (the tracer then skips them)."""
        s = getattr(materials, "volume_sigma_s", None)
        if s is None:
            return None
        a, e = materials.volume_sigma_a, materials.volume_emission
        has = np.any(s > 0, axis=1) | np.any(a > 0, axis=1) | np.any(e != 0, axis=1)
        if not has.any():
            return None
        m = len(has)
        passable = np.zeros(m, bool)
        kinds = materials.lobe_kind
        opaque = np.zeros(m, bool)
        np.logical_or.at(opaque, materials.lobe_material, kinds != LOBE_TRANSPARENT)
        seen = np.zeros((m, 3))
        np.add.at(seen, materials.lobe_material[kinds == LOBE_TRANSPARENT],
                  (materials.lobe_weight * materials.lobe_color)[kinds == LOBE_TRANSPARENT])
        passable = ~opaque & np.all(np.abs(seen - 1.0) < 1e-6, axis=1)

        def ext(x):
            return np.concatenate([x, np.zeros((1,) + x.shape[1:])])

        return cls(ext(s), ext(s + a), ext(e), ext(materials.volume_g), has, passable)

    @property
    def any_scatter(self) -> bool:
        return bool(np.any(self.sigma_s > 0))
