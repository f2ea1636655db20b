"""What every integrator is: a sequence of stages of independent work items.

The render session (engine/session.py) knows nothing of light transport. It asks the
integrator for the stages of each round, runs every item of a stage in a worker process (or
in the render process for small renders), and then either adds the items' radiance to the
film (film stages) or hands the items' results, in item order, to `reduce`, whose arrays are
published read-only to every worker (`install`) before the next stage starts.

    path tracer   round 0: pixels (all samples)
    photon map    round 0: photons -> publish maps; round 1: pixels
    ppm           round r: photons -> publish; pixels (one pass) -> publish radii

An integrator object lives in the render process (stages, reduce: cheap, no Embree) and, as a
separate object, in each process that traces (`build` gives it the Embree scene and lights,
then `run` and `install`). `run` must be a pure function of (seed, stage, item, installed
arrays), so that an image never depends on timing, batch size or the number of workers.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Sequence

import numpy as np

from ..scene import Scene
from ..layout import BatchLayout


@dataclass(frozen=True)
class Stage:
    """One kind of work. items: worker calls. film: each item returns radiance (N,3) for the
    flat path indices [start, stop) cut into batches (BatchLayout), or a dict with that as
    "L" and other arrays; publish: the items' results (without "L") are reduced and
    published to every worker. active: 0, or the version of the active-pixel list the flat
    indices run over (adaptive sampling; BatchLayout.locate)."""

    name: str
    items: int
    film: bool = False
    publish: bool = False
    start: int = 0
    stop: int = 0
    active: int = 0


@dataclass
class TraceContext:
    """What a tracing process builds once per render (engine/tracer.py)."""

    scene: Scene
    accel: object  # engine.accel.Accel
    lights: object  # engine.lights.light_set.LightSet
    layout: object  # engine.tracer.BatchLayout


class Integrator:
    name: ClassVar[str] = ""
    label: ClassVar[str] = ""
    description: ClassVar[str] = ""
    # Whether the film's noise estimate (passes as independent samples of one mean) describes
    # the image, so that a noise target can stop the render.
    noise_target: ClassVar[bool] = True
    # Whether a render may take samples [K, K + N) of the sequence (Settings.sample_offset):
    # every sample independent of the others given the published data.
    sample_offset: ClassVar[bool] = True
    # Render passes of the "integrator" group (engine/passes.py) this integrator writes into
    # its film items' "passes" (Caustics, the irradiance cache's records, ...).
    own_passes: ClassVar[tuple] = ()
    # Whether it splits its radiance into the light passes (Diffuse Direct, ..., Emission).
    light_passes: ClassVar[bool] = False
    # Whether its film-only stages may run over a subset of the pixels (adaptive sampling):
    # its `run` places paths with BatchLayout.locate.
    adaptive: ClassVar[bool] = False
    # Stages whose items depend only on the scene without its camera and view settings (photon
    # maps): a viewport keeps their results across camera moves (engine/stage_cache.py).
    view_independent: ClassVar[tuple] = ()

    def __init__(self, scene: Scene):
        self.scene = scene
        self.layout = BatchLayout(scene)
        self.ctx: TraceContext | None = None

    # --- render process -----------------------------------------------------------------
    def stages(self, round: int) -> Sequence[Stage]:
        """The stages of round `round` (0, 1, ...); empty when the render is complete."""
        raise NotImplementedError

    def reduce(self, stage: Stage, results: list) -> dict[str, np.ndarray]:
        """Arrays to publish from a publish stage's item results (in item order)."""
        raise NotImplementedError

    def counters(self) -> dict:
        """Figures for the stats line (photons stored, ...), render process."""
        return {}

    def overlay(self) -> np.ndarray | None:
        """(H*W,3) radiance added to the film's mean (progressive photon mapping's photon
        term), or None."""
        return None

    @classmethod
    def memory_estimate(cls, scene: Scene) -> int:
        """Bytes of published data (photon maps, ...) one process holds at the peak."""
        return 0

    @classmethod
    def batch_rays(cls, scene: Scene, paths: int) -> int:
        """Rays one batch of a work item traces together at the most, in a render of `paths`
        camera paths (engine/validation.py's memory estimate): a batch of paths, unless every
        path spawns several rays."""
        return min(int(scene.settings.batch_size), paths)

    def work_items(self) -> int:
        """About how many items the render has (worker processes pay off from a few)."""
        return self.layout.n_batches

    def film_paths(self) -> int:
        """Flat path indices the film stages cover in all (for progress)."""
        return self.layout.total_paths

    # --- tracing processes ----------------------------------------------------------------
    def build(self, ctx: TraceContext) -> None:
        self.ctx = ctx

    def run(self, stage: Stage, item: int, stop=None):
        """Result of one item: radiance (N,3) for film stages, else arrays for `reduce`."""
        raise NotImplementedError

    def install(self, version: int, arrays: dict[str, np.ndarray]) -> None:
        """Published arrays (read-only views), before any item of the next stage runs."""

    # --- helpers --------------------------------------------------------------------------
    def samples_stage(self) -> Stage:
        """The film stage over all of the render's samples [offset, offset + samples)."""
        first = self.layout.first_path
        return self.pixel_stage(first, first + self.layout.total_paths)

    def pixel_stage(self, start: int, stop: int, name: str = "pixels") -> Stage:
        """A film stage over flat path indices [start, stop) (pass = k // pixels)."""
        return Stage(name, -(-(stop - start) // self.layout.batch_size), film=True, start=start, stop=stop)
