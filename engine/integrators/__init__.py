"""The registry: the one list of integrators. The UI enum, `render.py --integrator`, the
exporter and validation all derive from it."""
from __future__ import annotations

from . import auto
from .photon.caustic_path import CausticPathIntegrator
from .irradiance.integrator import IrradianceCacheIntegrator
from .path import PathIntegrator
from .photon.integrator import PhotonIntegrator
from .photon.ppm import ProgressivePhotonIntegrator

REGISTRY = {cls.name: cls for cls in (PathIntegrator, PhotonIntegrator, ProgressivePhotonIntegrator,
                                      IrradianceCacheIntegrator, CausticPathIntegrator, auto.AutoIntegrator)}
NAMES = tuple(REGISTRY)


def create(scene):
    """The integrator object named by scene.settings.integrator, which must not be "auto"
    (engine/choice resolves that to the integrator it chooses, before anything is built)."""
    if scene.settings.integrator == auto.AutoIntegrator.name:
        raise ValueError("integrator 'auto' is resolved by engine.choice.resolve before a render is built")
    return REGISTRY[scene.settings.integrator](scene)
