"""Render settings: scene.render + scene.ember (+ Cycles' pixel filter) -> Settings.

Resolution and border follow Blender's render pipeline exactly (RE_InitState):
width = resolution_x * resolution_percentage // 100 (integer division), and the border
rectangle is `int(border_fraction * width)` computed in float32 and truncated. Blender's
border y is measured from the bottom; Settings.border is top-left origin, half-open.
"""
from __future__ import annotations

import numpy as np

from .. import settings as declared
from ..errors import EmberError
from ..parallel.workers import available_cores
from ..rng import animated_seed
from ..settings import Settings
from ..validation import settings_problems

_FILTER = declared.DECLARED["filter"]


def render_size(render) -> tuple[int, int]:
    """Full-frame pixel size with resolution_percentage, rounded as Blender does."""
    pct = int(render.resolution_percentage)
    return (int(render.resolution_x) * pct) // 100, (int(render.resolution_y) * pct) // 100


def border_pixels(fractions, width: int, height: int) -> tuple[int, int, int, int]:
    """Blender border fractions (min_x, min_y, max_x, max_y; y from the bottom) ->
    (x0, y0, x1, y1) pixels, top-left origin, half-open. Matches Blender's disprect:
    float32 product truncated to int."""
    fx0, fy0, fx1, fy1 = (np.float32(f) for f in fractions)
    w, h = np.float32(width), np.float32(height)
    bx0, bx1 = int(fx0 * w), int(fx1 * w)
    by0, by1 = int(fy0 * h), int(fy1 * h)  # from the bottom
    return bx0, height - by1, bx1, height - by0


def render_threads(render) -> int:
    """Threads (worker processes) a render may use, as Cycles reads them. render.threads is
    Blender's effective count (BKE_render_num_threads: `blender -t N`, else the Fixed value,
    else every CPU of the machine) and `-t N` makes threads_mode read FIXED; Auto-detect is
    further held to the process's CPU affinity, which Blender's count ignores."""
    threads = getattr(render, "threads", None)
    if threads is None:
        return 0  # a stand-in scene without the property: all cores
    if getattr(render, "threads_mode", "AUTO") == "FIXED":
        return max(int(threads), 1)
    return max(min(int(threads), available_cores()), 1)


def export_settings(scene, overrides: dict | None = None, warn=None) -> Settings:
    """Settings from a (preferably evaluated) bpy Scene: every declared scene.ember property
    (engine/settings.py), Blender's render settings and Cycles' pixel filter; `overrides`
    (Settings field -> value, None = keep) win. Raises EmberError on unknown override keys or
    bad values."""
    render = scene.render
    width, height = render_size(render)
    kw = dict(width=width, height=height, threads=render_threads(render),
              persistent=bool(getattr(render, "use_persistent_data", False)))

    ember = getattr(scene, "ember", None)
    for s in declared.FIELDS:  # read with getattr: a stand-in scene may lack some
        value = getattr(ember, s.bpy_prop, None) if s.source == declared.EMBER else None
        if value is not None:
            kw[s.name] = s.core(value)
    if getattr(ember, "use_animated_seed", False):
        kw["seed"] = animated_seed(kw.get("seed", Settings.seed), int(scene.frame_current),
                                   float(getattr(scene, "frame_subframe", 0.0)))

    cycles = getattr(scene, "cycles", None)
    filt = getattr(cycles, "pixel_filter_type", None) if cycles is not None else None
    if filt in _FILTER.values:
        kw["filter"] = filt
        # Cycles' Blender sync renders a box filter one pixel wide whatever filter_width says
        # (intern/cycles/blender/sync.cpp).
        kw["filter_width"] = 1.0 if filt == "BOX" else float(getattr(cycles, "filter_width", Settings.filter_width))

    overrides = {k: v for k, v in (overrides or {}).items() if v is not None}
    unknown = sorted(set(overrides) - {s.name for s in declared.FIELDS})
    if unknown:
        raise EmberError(f"Unknown setting(s): {', '.join(unknown)} "
                         f"(known: {', '.join(sorted(s.name for s in declared.FIELDS))}).")
    kw.update({name: declared.DECLARED[name].core(value) for name, value in overrides.items()})

    if "border" not in overrides:
        kw["border"] = (border_pixels((render.border_min_x, render.border_min_y, render.border_max_x,
                                       render.border_max_y), kw["width"], kw["height"])
                        if render.use_border else (0, 0, kw["width"], kw["height"]))

    settings = Settings(**kw)
    problems = settings_problems(settings)
    if problems:
        raise EmberError("Invalid render settings: " + "; ".join(problems) + ".")
    return settings
