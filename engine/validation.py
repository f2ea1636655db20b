"""Checks of a Scene before rendering: settings in range, something that emits light.

One place for them, so the CLI, F12 and tests give the same message for the same problem.
"""
from __future__ import annotations

import numpy as np

from .errors import EmberError
from .rng import PATTERNS
from .integrators import NAMES as INTEGRATORS
from .scene import FILTERS, STRATEGIES, Scene


def validate(scene: Scene) -> None:
    s = scene.settings
    problems = []
    if s.width < 1 or s.height < 1:
        problems.append(f"resolution must be at least 1x1 (got {s.width}x{s.height})")
    x0, y0, x1, y1 = s.border
    if not (0 <= x0 < x1 <= s.width and 0 <= y0 < y1 <= s.height):
        problems.append(f"render border {s.border} is empty or outside the {s.width}x{s.height} frame")
    if s.samples < 1:
        problems.append(f"samples must be at least 1 (got {s.samples})")
    if s.max_depth < 0:
        problems.append(f"max depth must be >= 0 (got {s.max_depth})")
    if s.time_limit < 0:
        problems.append(f"time limit must be >= 0 (got {s.time_limit})")
    if s.batch_size < 1:
        problems.append(f"batch size must be positive (got {s.batch_size})")
    if s.filter not in FILTERS:
        problems.append(f"unknown pixel filter {s.filter!r} (use one of {', '.join(FILTERS)})")
    if not s.filter_width > 0:
        problems.append(f"filter width must be positive (got {s.filter_width})")
    if s.strategy not in STRATEGIES:
        problems.append(f"unknown strategy {s.strategy!r} (use one of {', '.join(STRATEGIES)})")
    if s.pattern not in PATTERNS:
        problems.append(f"unknown sampling pattern {s.pattern!r} (use one of {', '.join(PATTERNS)})")
    if not s.noise_target >= 0:
        problems.append(f"noise target must be >= 0 (got {s.noise_target})")
    if s.integrator not in INTEGRATORS:
        problems.append(f"unknown integrator {s.integrator!r} (use one of {', '.join(INTEGRATORS)})")
    if problems:
        raise EmberError("Invalid render settings: " + "; ".join(problems))


def has_light(scene: Scene) -> bool:
    world = scene.world
    return (len(scene.lights) > 0 or bool(np.any(scene.materials.emission > 0))
            or bool(np.max(world.color) > 0 and (getattr(world, "image", None) is None or np.max(world.image) > 0)))
