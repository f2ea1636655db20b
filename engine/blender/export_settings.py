"""Render settings: scene.render + scene.ember (+ Cycles' pixel filter) -> Settings.

Resolution and border follow Blender's render pipeline exactly (RE_InitState):
width = resolution_x * resolution_percentage // 100 (integer division), and the border
rectangle is `int(border_fraction * width)` computed in float32 and truncated. Blender's
border y is measured from the bottom; Settings.border is top-left origin, half-open.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import EmberError
from ..parallel.workers import available_cores
from ..rng import PATTERNS, animated_seed
from ..integrators import NAMES as INTEGRATORS
from ..scene import FILTERS, Settings
from ..validation import (icache_problems, light_path_problems, photon_problems, sample_offset_problems,
                          sampling_problems)

_DEFAULTS = Settings()

# scene.ember field -> Settings field (same name); read with getattr so plain bpy works.
_EMBER_FIELDS = ("samples", "sample_offset", "max_depth", "seed", "time_limit", "noise_target", "batch_size",
                 "photons", "caustic_photons", "photon_k", "global_radius", "caustic_radius", "gather_rays",
                 "radiance_photons", "ppm_radius", "ppm_alpha", "icache_rays", "icache_a", "icache_gradients",
                 "icache_radiance", "icache_radiance_order",
                 "diffuse_bounces", "glossy_bounces", "transmission_bounces", "transparent_bounces",
                 "caustics_reflective", "caustics_refractive", "clamp_direct", "clamp_indirect", "filter_glossy",
                 "adaptive_threshold", "adaptive_min_samples")
_INTEGRATOR_ENUM = {name.upper(): name for name in INTEGRATORS}  # UI enum id -> registry name


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


def _integrator_name(value) -> str:
    name = _INTEGRATOR_ENUM.get(str(value), str(value).lower())
    if name not in INTEGRATORS:
        raise EmberError(f"Integrator '{value}' is not available (choose one of: {', '.join(INTEGRATORS)}).")
    return name


def _validate(s: Settings) -> None:
    if s.width < 1 or s.height < 1:
        raise EmberError(f"Resolution {s.width}x{s.height} is too small; set at least 1x1 pixels.")
    x0, y0, x1, y1 = s.border
    if not (0 <= x0 < x1 <= s.width and 0 <= y0 < y1 <= s.height):
        raise EmberError(f"Render region {tuple(s.border)} is empty or outside the {s.width}x{s.height} frame; "
                         "enlarge the render region or disable it.")
    if s.samples < 1:
        raise EmberError("Samples must be at least 1.")
    if s.max_depth < 0:
        raise EmberError("Max depth must not be negative.")
    if s.batch_size < 1:
        raise EmberError("Batch size must be at least 1.")
    if s.time_limit < 0:
        raise EmberError("Time limit must not be negative (0 = no limit).")
    if s.filter not in FILTERS:
        raise EmberError(f"Pixel filter '{s.filter}' is not supported (choose one of: {', '.join(FILTERS)}).")
    if not s.filter_width > 0:
        raise EmberError("Pixel filter width must be positive.")
    if s.pattern not in PATTERNS:
        raise EmberError(f"Sampling pattern '{s.pattern}' is not supported (choose one of: {', '.join(PATTERNS)}).")


def export_settings(scene, overrides: dict | None = None, warn=None) -> Settings:
    """Settings from a (preferably evaluated) bpy Scene; `overrides` (Settings field ->
    value, None = keep) win. Raises EmberError on unknown override keys or bad values."""
    render = scene.render
    width, height = render_size(render)
    kw = dict(width=width, height=height, threads=render_threads(render),
              persistent=bool(getattr(render, "use_persistent_data", False)))

    ember = getattr(scene, "ember", None)
    for name in _EMBER_FIELDS:
        value = getattr(ember, name, None) if ember is not None else None
        if value is not None:
            kw[name] = type(getattr(_DEFAULTS, name))(value)
    if ember is not None and getattr(ember, "integrator", None) is not None:
        kw["integrator"] = _integrator_name(ember.integrator)
    if ember is not None and getattr(ember, "pattern", None) is not None:
        kw["pattern"] = str(ember.pattern).lower()
    for name in ("photon_view", "photon_kernel", "icache_weight", "icache_gather", "icache_view"):  # UI ids: upper case
        if ember is not None and getattr(ember, name, None) is not None:
            kw[name] = str(getattr(ember, name)).lower()
    if ember is not None and getattr(ember, "use_adaptive_sampling", None) is not None:
        kw["adaptive"] = bool(ember.use_adaptive_sampling)
    if ember is not None and getattr(ember, "use_animated_seed", False):
        kw["seed"] = animated_seed(kw.get("seed", _DEFAULTS.seed), int(scene.frame_current),
                                   float(getattr(scene, "frame_subframe", 0.0)))

    cycles = getattr(scene, "cycles", None)
    filt = getattr(cycles, "pixel_filter_type", None) if cycles is not None else None
    if filt in FILTERS:
        kw["filter"] = filt
        # Cycles' Blender sync renders a box filter one pixel wide whatever filter_width says
        # (intern/cycles/blender/sync.cpp).
        kw["filter_width"] = 1.0 if filt == "BOX" else float(getattr(cycles, "filter_width", _DEFAULTS.filter_width))

    overrides = {k: v for k, v in (overrides or {}).items() if v is not None}
    known = {f.name for f in dataclasses.fields(Settings)}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise EmberError(f"Unknown setting(s): {', '.join(unknown)} (known: {', '.join(sorted(known))}).")
    for name, value in overrides.items():
        if name == "integrator":
            kw[name] = _integrator_name(value)
        elif name == "border":
            kw[name] = tuple(int(v) for v in value)
        elif name == "filter":
            kw[name] = str(value).upper()
        elif name == "pattern":
            kw[name] = str(value).lower()
        else:
            kw[name] = type(getattr(_DEFAULTS, name))(value)

    if "border" not in overrides:
        if render.use_border:
            kw["border"] = border_pixels((render.border_min_x, render.border_min_y,
                                          render.border_max_x, render.border_max_y),
                                         kw["width"], kw["height"])
        else:
            kw["border"] = (0, 0, kw["width"], kw["height"])

    settings = Settings(**kw)
    _validate(settings)
    problems = photon_problems(settings)
    if problems:
        raise EmberError("Invalid photon settings: " + "; ".join(problems) + ".")
    problems = icache_problems(settings)
    if problems:
        raise EmberError("Invalid irradiance-cache settings: " + "; ".join(problems) + ".")
    problems = sample_offset_problems(settings)
    if problems:
        raise EmberError(problems[0][0].upper() + problems[0][1:] + ".")
    problems = light_path_problems(settings)
    if problems:
        raise EmberError("Invalid light path settings: " + "; ".join(problems) + ".")
    problems = sampling_problems(settings)
    if problems:
        raise EmberError("Invalid sampling settings: " + "; ".join(problems) + ".")
    return settings
