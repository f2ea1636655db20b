"""The lobe interface: one kind of scattering - a BSDF lobe or a phase function - with every
method vectorised over K rows of that kind (one row per shading point and lobe).

A Closure (engine/bsdf/closure.py) is a mixture of lobes: it asks each kind present for its
rows' parameters, albedo estimates, values and samples, and keeps the mixture weights, the
selection probabilities and the mixture pdf itself. Lobe methods work in a local frame:
for a surface lobe z is the shading normal (already on wo's side); a phase function has no
normal and is the same in any frame. wo points back toward the previous vertex, wi toward the
next, both unit (K,3) float64. f is per unit solid angle, without the cosine and without the
lobe's mixture weight; pdfs are per unit solid angle, except a delta sample's, which is the
probability of its branch (reflect or refract: a discrete pmf, never used in MIS).
"""
from __future__ import annotations

import abc
import dataclasses
from dataclasses import dataclass

import numpy as np

from ...vec import max3

# What kind of bounce a sample is (Cycles' labels as its path_state_next counts them): diffuse
# or glossy reflection (mirrors count as glossy), transmission (refraction, rough or smooth),
# transparent pass-through, scattering in a volume (a phase function).
LABEL_DIFFUSE, LABEL_GLOSSY, LABEL_TRANSMIT, LABEL_TRANSPARENT, LABEL_SCATTER = 0, 1, 2, 3, 4
# Render-pass classes (engine/passes.py LOBE_CLASSES: Diffuse, Glossy, Transmission).
CLASS_DIFFUSE, CLASS_GLOSSY, CLASS_TRANSMISSION = 0, 1, 2
# The scene analysis' material classes (engine/choice/analysis.py): what a lobe's albedo counts as.
ANALYSIS_CLASSES = ("diffuse", "glossy", "specular", "transparent")


@dataclass
class Params:
    """Parameters of K rows of one lobe kind, resolved at their shading points; every field of
    a subclass is an array of K rows (float64 unless said otherwise). `adjoint` (not a field):
    the closure carries light particles (photons) whose wo is the light's side, so a lobe that
    is not reciprocal (Multiscatter GGX's factor of the viewing direction) evaluates its adjoint,
    f(wi, wo)."""

    adjoint = False

    def __len__(self) -> int:
        return len(getattr(self, dataclasses.fields(self)[0].name))

    def take(self, i: np.ndarray) -> Rows:
        """Rows i (K',) of this record (repeats allowed), gathered as they are read."""
        return Rows(self, i)


class Rows:
    """Rows i of a parameter record, read like the record itself; a field is gathered when
    first read (a lobe's method reads a few of its fields: gathering them all would cost a
    good part of the method)."""

    def __init__(self, params: Params, i: np.ndarray):
        self._params, self._i = params, i

    def __len__(self) -> int:
        return len(self._i)

    def __getattr__(self, name: str):
        if name.startswith("_"):
            raise AttributeError(name)
        value = getattr(self._params, name)
        value = None if value is None else np.take(value, self._i, axis=0)  # None: an optional field
        setattr(self, name, value)  # read once
        return value

    def take(self, j: np.ndarray) -> Rows:
        return Rows(self._params, np.take(self._i, j))

    @property
    def adjoint(self) -> bool:
        return self._params.adjoint


@dataclass
class LobeSample:
    """K samples of one lobe kind in the local frame.

    wi (K,3) unit; pdf (K,) the lobe's solid-angle pdf of wi (= pdf(p, wo, wi)), 0 where the
    lobe cannot produce wi (under the surface, wrong side of the microfacet: the sample is
    dropped, not redrawn; seed 000); for a delta sample the pmf of its branch; delta (K,)
    bool or one bool for all; weight (K,3) of the delta samples: f |cos| / pmf, the discrete weight (None if
    there are none; a sample that is not delta is weighed by the mixture it came from, f cos /
    pdf of the whole closure, which the closure evaluates); label (K,) int8 or one LABEL_*
    for all; eta2 (K,) eta_rel^2 where the sample would refract, 1 elsewhere (None: the lobe
    never refracts)."""

    wi: np.ndarray
    pdf: np.ndarray
    delta: np.ndarray | bool
    label: np.ndarray | int
    weight: np.ndarray | None = None
    eta2: np.ndarray | None = None


class Lobe(abc.ABC):
    """One kind of scattering: what a BSDF lobe and a phase function have in common."""

    @abc.abstractmethod
    def parameters(self, *inputs) -> Params:
        """The record of K rows from the kind's own data (a surface lobe: the material table
        with its textures looked up at the shading points)."""

    @abc.abstractmethod
    def albedo(self, p: Params, wo: np.ndarray) -> np.ndarray:
        """(K,3) estimate of the fraction of light it scatters at wo: drives the choice of
        lobe in a mixture and Russian roulette."""

    @abc.abstractmethod
    def eval(self, p: Params, wo: np.ndarray, wi: np.ndarray):
        """(f (K,3), pdf (K,)) at wo, wi of rows that are not delta."""

    def pdf(self, p: Params, wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        """(K,) solid-angle pdf of `sample` at wi (rows that are not delta)."""
        return self.eval(p, wo, wi)[1]

    @abc.abstractmethod
    def sample(self, p: Params, wo: np.ndarray, u: np.ndarray, u_branch: np.ndarray) -> LobeSample:
        """Sample wi from u (K,2) in [0, 1)^2; u_branch (K,) in [0, 1) chooses a branch inside
        the lobe (Phong's diffuse or glossy part, glass's reflection or refraction)."""

    def is_delta(self, p: Params) -> np.ndarray:
        """(K,) bool: rows sampled as a Dirac (no eval, no MIS) at these parameters."""
        return np.zeros(len(p), bool)


@dataclass
class SurfaceParams(Params):
    """color (K,3) the colour input; delta (K,) bool: is_delta at these parameters."""

    color: np.ndarray
    delta: np.ndarray


class SurfaceLobe(Lobe):
    """A BSDF lobe of the material table (Materials.lobe_kind == kind), and the facts about it
    that the closure, the photon tracer and the scene analysis ask for."""

    kind: int  # its LOBE_* id in the material table
    rays: int  # RAY_* bits of the lights that light it (Cycles' _surface_shader_exclude)
    # Render-pass class of the light it reflects (wi on wo's side) and transmits.
    reflection_class: int
    transmission_class: int
    needs_side = False  # its parameters need `inside` (wo behind the triangle's winding)
    # A delta sample that keeps wo's line (pass-through) is valid on either side of ng.
    straight = False

    @abc.abstractmethod
    def parameters(self, m, lobe: np.ndarray, point: np.ndarray, src, inside) -> SurfaceParams:
        """Parameters of lobes `lobe` (K,) of the material table m at shading points `point`
        (K,); src: where the inputs come from besides the table (inputs.Sources: the points'
        UVs for textures, node programs' values); inside (N,) bool per point: wo is behind the
        triangle's winding normal (known where some lobe needs_side)."""

    def drop_caustics(self, p: SurfaceParams, reflection: np.ndarray, refraction: np.ndarray):
        """Cycles' caustics toggles: reflection, refraction (K,) bool: rows whose glossy
        reflection / refraction is left out. Changes p in place; returns the rows (K,) bool
        left out whole, or None."""
        return None

    def blur(self, p: SurfaceParams, min_alpha: np.ndarray) -> None:
        """Filter Glossy: rows with a GGX alpha below min_alpha (K,) get min_alpha (p in place)."""

    def row_facts(self, p: SurfaceParams):
        """(render-pass class of its reflection (K,), RAY_* bits of the lights that light it (K,))
        per row, for a lobe whose rows differ in them (components of different kinds in one
        lobe); None: every row has the kind's reflection_class and rays."""
        return None

    def layer_weight(self, p: SurfaceParams, wo: np.ndarray) -> np.ndarray:
        """(K,) or (K,3) weight it leaves to the lobes under it (Cycles'
        closure_layering_weight: 1 - max_rgb of its albedo)."""
        return np.clip(1.0 - max3(self.albedo(p, wo)), 0.0, 1.0)

    def albedo_parts(self, p: SurfaceParams, wo: np.ndarray, weight: np.ndarray, estimate: np.ndarray):
        """The albedo estimate (K,3) (weighted by weight (K,3)) split by render-pass class:
        [(class, (K,3)), ...], summing to the estimate."""
        return [(self.reflection_class, estimate)]

    @abc.abstractmethod
    def stores_photons(self, m, lobe: np.ndarray, min_roughness: float) -> np.ndarray:
        """(K,) bool: lobes `lobe` of m store photons (followed as diffuse), GGX lobes
        sharper than Blender roughness min_roughness being followed as specular."""

    @abc.abstractmethod
    def analysis_albedo(self, m, lobe: np.ndarray, color: np.ndarray, min_roughness: float) -> dict:
        """{ANALYSIS_CLASSES name: (K,)}: the mean albedo of lobes `lobe` (K,) of m by the
        scene analysis' classes (those left out: 0); color (K,3) their mean colours (textures:
        the mean texel); GGX lobes sharper than Blender roughness min_roughness are specular."""


def mean_albedo(m, lobe: np.ndarray, color: np.ndarray) -> np.ndarray:
    """(K,) mean over RGB of weight x colour of lobes `lobe` (the scene analysis' albedo)."""
    return (m.lobe_weight[lobe] * color).mean(axis=1)
