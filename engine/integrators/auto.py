"""`auto` in the registry: what the integrator chosen from the scene may be asked for.

The choice itself (scene analysis, rule, resolution) is engine/choice/, which the session runs
once before anything is built; this entry only declares what the UI, CLI and validation need.
"""
from __future__ import annotations

from .base import Integrator
from .irradiance.integrator import IrradianceCacheIntegrator
from .path import PathIntegrator
from .photon.integrator import PhotonIntegrator

# The integrators `auto` chooses from (engine/choice/rule.py).
CANDIDATES = {cls.name: cls for cls in (PathIntegrator, PhotonIntegrator, IrradianceCacheIntegrator)}


class AutoIntegrator(Integrator):
    name = "auto"
    label = "Automatic"
    description = ("Chooses from the scene: path tracing, photon mapping for caustics, or the irradiance "
                   "cache for enclosed diffuse interiors, with parameters; the stats say why")
    # What the chosen integrator must then allow (resolve picks the path tracer otherwise).
    noise_target = sample_offset = adaptive = light_passes = True

    @classmethod
    def memory_estimate(cls, scene) -> int:
        return max(c.memory_estimate(scene) for c in CANDIDATES.values())

    @classmethod
    def batch_rays(cls, scene, paths: int) -> int:
        return max(c.batch_rays(scene, paths) for c in CANDIDATES.values())
