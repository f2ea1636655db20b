"""The registry: the one list of integrators. The UI enum, `render.py --integrator`, the
exporter and validation all derive from it (through the `integrator` declaration of
engine/settings.py, whose items are this registry's)."""
from __future__ import annotations

from .. import settings as declared
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


def items(setting: declared.Setting) -> tuple:
    """An enum setting's (value, label, description) items: its declared ones, or the
    registry's for the integrator."""
    if setting.items == declared.REGISTERED:
        return tuple((cls.name, cls.label, cls.description) for cls in REGISTRY.values())
    return setting.items


def choices(setting: declared.Setting) -> tuple:
    """An enum setting's core values."""
    return tuple(v for v, _, _ in items(setting))


def honours(setting: declared.Setting, integrator: str, get) -> bool:
    """Whether `integrator` honours `setting` (get(name) -> another setting's value, for the
    conditions); `auto` honours what one of the integrators it chooses from honours."""
    names = auto.CANDIDATES if integrator == auto.AutoIntegrator.name else (integrator,)
    return any(declared.honours(setting, name, get) for name in names)
