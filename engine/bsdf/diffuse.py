"""Lambertian reflection: f = albedo / pi, sampled cosine-weighted around the shading normal."""
import numpy as np

from .. import sampling
from ..vec import scale


def eval(albedo: np.ndarray, cos_i: np.ndarray) -> np.ndarray:
    """f (N,3) for incident cosines cos_i (N,) measured from the shading normal."""
    return scale(albedo, np.where(cos_i > 0, 1.0 / np.pi, 0.0))


def pdf(cos_i: np.ndarray) -> np.ndarray:
    """Solid-angle pdf (N,) of cosine-weighted sampling."""
    return sampling.pdf_cosine_hemisphere(cos_i)


def sample(u: np.ndarray, in_unit=False) -> np.ndarray:
    """Local directions (N,3) around +z; in_unit: u is known to lie in [0, 1) (a Sampler's)."""
    return sampling.sample_cosine_hemisphere(u, in_unit)
