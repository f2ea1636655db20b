"""The lobe table: the surface lobe of each LOBE_* kind of the material table, and the
per-kind facts as arrays indexed by kind (what the closure looks up per pair). A new lobe is a
module here and one entry in LOBES; phase functions (volumes) have the same interface.

    kind  lobe          rays               pass class (reflect / transmit)  delta
    0     Diffuse       diffuse            diffuse                          never
    1     Phong         diffuse + glossy   glossy                           never
    2     Microfacet    glossy             glossy                           roughness <= 0.00376
                        (GGX, Multiscatter GGX, Beckmann, Ashikhmin-Shirley)
    3     Dielectric    glossy + transmit  glossy / transmission            smooth or ior ~ 1
    4     Transparent   none               transmission                     always
    5     OrenNayar     diffuse            diffuse                          never
    6     Sheen         diffuse            diffuse (velvet: glossy)         never
    7     Translucent   diffuse            diffuse                          never
    8     Toon          per component      per component (Diffuse, Glossy)  never
"""
from __future__ import annotations

import numpy as np

from ...scene import LOBE_KINDS
from .base import ANALYSIS_CLASSES, Lobe, SurfaceLobe
from .dielectric import Dielectric
from .diffuse import Diffuse
from .henyey_greenstein import HenyeyGreenstein
from .microfacet import Microfacet
from .oren_nayar import OrenNayar
from .phong import Phong
from .sheen import Sheen
from .toon import Toon
from .translucent import Translucent
from .transparent import Transparent

LOBES: tuple[SurfaceLobe, ...] = (Diffuse(), Phong(), Microfacet(), Dielectric(), Transparent(), OrenNayar(),
                                  Sheen(), Translucent(), Toon())
assert [lobe.kind for lobe in LOBES] == list(range(LOBE_KINDS)), "LOBES is indexed by kind id"
PHASE_FUNCTIONS: tuple[Lobe, ...] = (HenyeyGreenstein(),)

# Per-kind facts, indexed by LOBE_* id.
RAYS = np.array([lobe.rays for lobe in LOBES], np.uint8)
REFLECTION_CLASS = np.array([lobe.reflection_class for lobe in LOBES])
TRANSMISSION_CLASS = np.array([lobe.transmission_class for lobe in LOBES])
STRAIGHT = np.array([lobe.straight for lobe in LOBES])
NEEDS_SIDE = np.array([lobe.needs_side for lobe in LOBES])


def stores_photons(m, min_roughness: float) -> np.ndarray:
    """(K,) bool: the lobes of the material table m that store photons (see
    SurfaceLobe.stores_photons)."""
    out = np.zeros(len(m.lobe_kind), bool)
    for lobe in LOBES:
        rows = np.flatnonzero(m.lobe_kind == lobe.kind)
        if len(rows):
            out[rows] = lobe.stores_photons(m, rows, min_roughness)
    return out


def analysis_albedo(m, color: np.ndarray, min_roughness: float) -> np.ndarray:
    """(K, len(ANALYSIS_CLASSES)) mean albedo of every lobe of m by the scene analysis'
    classes; color (K,3) the lobes' mean colours (see SurfaceLobe.analysis_albedo)."""
    out = np.zeros((len(m.lobe_kind), len(ANALYSIS_CLASSES)))
    for lobe in LOBES:
        rows = np.flatnonzero(m.lobe_kind == lobe.kind)
        if len(rows):
            for name, values in lobe.analysis_albedo(m, rows, color[rows], min_roughness).items():
                out[rows, ANALYSIS_CLASSES.index(name)] = values
    return out
