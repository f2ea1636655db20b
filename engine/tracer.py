"""The tracing context of a process.

`Tracer`: everything built once per process that traces - Embree scene, lights, the
integrator's tracing side - in the render process or, identically, in every worker.
"""
from __future__ import annotations

import dataclasses
import time


from .accel import Accel
from .allocator import keep_freed_memory
from .integrators import create
from .integrators.base import Stage, TraceContext
from .integrators.first_hit import FirstHit, computes_alpha
from .lights.light_set import LightSet
from .nodes.material import MaterialPrograms, SurfaceEmission
from .passes import HIT as HIT_PASSES
from .rng import Sampler
from .scene import Scene, part_digests


# What this process has built, for the persistent-data tests and the stats line.
BUILDS = {"embree": 0, "lights": 0}


class Tracer:
    def __init__(self, scene: Scene, previous: "Tracer | None" = None, changed=None):
        """previous: the tracer of this process's last render, whose Embree scene and light
        tables are kept where `changed` (names of the scene parts that differ, see
        scene.part_digests; None = all) allows. The integrator is always new (cheap)."""
        keep_freed_memory()  # in whichever process traces
        s = scene.settings
        self.scene = scene
        changed = None if previous is None or changed is None else set(changed)

        def kept(*parts):
            return changed is not None and not changed.intersection(parts)

        if kept("mesh"):
            self.accel = previous.accel
        else:  # Embree scenes of unchanged big objects are kept (engine/accel.py's blocks)
            self.accel = Accel(scene.mesh, previous.accel if previous is not None else None, split=s.persistent)
            BUILDS["embree"] += 1
        same_settings = previous is not None and (previous.scene.settings.strategy, previous.scene.settings.film_transparent) \
            == (s.strategy, s.film_transparent)
        # A world reading Camera or Window coordinates is built again when the camera moves.
        world_camera = ("camera",) if previous is not None and getattr(previous.lights, "world_reads_camera", False) else ()
        if kept("mesh", "materials", "lights", "world", *world_camera) and same_settings:
            self.lights = previous.lights
        else:
            # A transparent film hides the world from camera rays only; it still lights the scene.
            world = dataclasses.replace(scene.world, visible=False) if s.film_transparent else scene.world
            programs = MaterialPrograms.of(scene.materials)
            emitters = SurfaceEmission(scene, programs) if programs.varying_emission.any() else None
            self.lights = LightSet(scene.lights, scene.mesh, scene.materials, world, self.accel,
                                   self.accel.scene_radius, s.strategy, surface_emission=emitters,
                                   camera=scene.camera)
            BUILDS["lights"] += 1
        self.integrator = create(scene)
        self.integrator.build(TraceContext(scene, self.accel, self.lights, self.integrator.layout))
        needs_hit = computes_alpha(scene) or any(n in HIT_PASSES for n in s.passes)
        self.first_hit = FirstHit(scene, self.accel) if needs_hit else None

    def install(self, version: int, arrays: dict) -> None:
        """Published arrays: the layout's own (layout.*), the rest to the integrator."""
        self.integrator.layout.install(version, arrays)
        rest = {k: v for k, v in arrays.items() if not k.startswith("layout.")}
        if rest:
            self.integrator.install(version, rest)

    def run(self, stage: Stage, item: int, stop=None):
        """(result, rays, embree seconds, seconds) of one work item."""
        t0 = time.perf_counter()
        rays0, embree0 = self.accel.rays, self.accel.embree_seconds
        result = self.integrator.run(stage, item, stop)
        if stage.film and self.first_hit is not None:
            result = with_passes(result, self._first_hit_passes(stage, item))
        return result, self.accel.rays - rays0, self.accel.embree_seconds - embree0, time.perf_counter() - t0

    def _first_hit_passes(self, stage: Stage, item: int) -> dict:
        s, layout = self.scene.settings, self.integrator.layout
        j, sample = layout.locate(stage, item)
        sampler = Sampler(s.seed, layout.pixel[j], sample, s.pattern)
        return self.first_hit.passes(sampler, layout.px[j], layout.py[j])


def with_passes(result, passes: dict):
    """A film item's result (radiance array or dict with "L") with render passes added
    under "passes" (the session hands them to the film)."""
    if not isinstance(result, dict):
        result = {"L": result}
    result["passes"] = {**result.get("passes", {}), **passes}
    return result


_kept: dict = {}  # "tracer": the last persistent Tracer of this process, "digests": its scene's


def forget() -> None:
    """Drop the kept tracer (its Embree scene and tables)."""
    _kept.clear()


def tracer_for(scene: Scene) -> Tracer:
    """A Tracer for `scene` in this process, built on the last one when the scene asks for
    persistent data (and kept for the next render), else from scratch (and nothing kept)."""
    previous, digests = _kept.pop("tracer", None), _kept.pop("digests", None)
    if not scene.settings.persistent:
        return Tracer(scene)
    now = part_digests(scene)
    changed = None if digests is None else {k for k in now if now[k] != digests.get(k)}
    tracer = Tracer(scene, previous, changed)
    _kept.update(tracer=tracer, digests=now)
    return tracer
