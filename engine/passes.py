"""Render passes: the one list, under Blender's standard pass names (those Cycles writes),
so compositor setups made for Cycles work unchanged on Ember images.

Every pass but Combined is optional and costs nothing unless requested (Settings.passes):

- "hit" passes describe the camera ray's first hit (engine/integrators/first_hit.py, the
  same camera sample every integrator uses): Depth (distance along the view axis, 1e10 where
  every sample escaped), Position (world space), Normal (the shading normal facing the
  camera, world space), Denoising Normal (the same in camera
  space, as Cycles gives it to the denoiser), Denoising Albedo (the closure's reflectance at
  the first hit; Cycles looks through mirror and glass to the next rough hit, Ember does
  not). All averaged over the samples, as Cycles averages them (its Depth and Position
  passes are means, not the first sample's hit).
- "light" passes split Combined by what the camera sees (Emission, Environment) and, for the
  rest, by the kind of lobe at the first bounce (diffuse, glossy, transmission) and whether
  the light arrived after one bounce (Direct) or more (Indirect); the Color passes are the
  lobes' albedo at the first hit. As Cycles, Direct and Indirect are stored divided by
  Color, so that
      Combined = Emission + Environment + sum over kinds of (Direct + Indirect) x Color.
  The path tracer writes them (engine/integrators/light_passes.py).
- "debug" passes: the sample count and the estimated variance of each pixel's mean.
- "integrator" passes: an integrator's own terms (Caustics: the caustic map's estimate).

`prop` is the view-layer property that enables a pass in Blender: Blender's own pass
checkboxes, or "ember.*" for the ones Blender has none for (Cycles keeps its denoising and
debug passes under view_layer.cycles; engine/blender/passes.py accepts those too).
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Pass:
    name: str  # Blender's pass name (the Render Layers socket, the EXR layer)
    chan_id: str  # one letter per channel, as RenderEngine.register_pass wants
    kind: str  # "COLOR", "VECTOR" or "VALUE" (register_pass's type)
    prop: str  # view-layer property that enables it
    group: str  # "hit", "light", "color", "debug" or "integrator"

    @property
    def channels(self) -> int:
        return len(self.chan_id)


COMBINED = Pass("Combined", "RGBA", "COLOR", "use_pass_combined", "combined")
LOBE_CLASSES = ("Diffuse", "Glossy", "Transmission")  # the first bounce's lobe kind

PASSES = (
    COMBINED,
    Pass("Depth", "Z", "VALUE", "use_pass_z", "hit"),
    Pass("Position", "XYZ", "VECTOR", "use_pass_position", "hit"),
    Pass("Normal", "XYZ", "VECTOR", "use_pass_normal", "hit"),
    Pass("Denoising Normal", "XYZ", "VECTOR", "ember.denoising_store_passes", "hit"),
    Pass("Denoising Albedo", "RGB", "COLOR", "ember.denoising_store_passes", "hit"),
    *(Pass(f"{c} {part}", "RGB", "COLOR", f"use_pass_{c.lower()}_{part.lower()}",
           "color" if part == "Color" else "light")
      for c in LOBE_CLASSES for part in ("Direct", "Indirect", "Color")),
    Pass("Emission", "RGB", "COLOR", "use_pass_emit", "light"),
    Pass("Environment", "RGB", "COLOR", "use_pass_environment", "light"),
    Pass("Caustics", "RGB", "COLOR", "ember.pass_caustics", "integrator"),
    Pass("Debug Sample Count", "X", "VALUE", "ember.pass_sample_count", "debug"),
    Pass("Debug Variance", "X", "VALUE", "ember.pass_variance", "debug"),
)
BY_NAME = {p.name: p for p in PASSES}
NAMES = tuple(BY_NAME)
HIT = tuple(p.name for p in PASSES if p.group == "hit")
# What the path tracer splits Combined into (light and colour passes).
LIGHT = tuple(p.name for p in PASSES if p.group in ("light", "color"))
DEPTH_MISS = 1e10  # Cycles' depth where the camera ray escaped


def needed(names) -> tuple:
    """The passes a render accumulates for `names`: Direct and Indirect need their Color
    (they are divided by it)."""
    out = set(names)
    for n in names:
        if BY_NAME[n].group == "light" and n.rsplit(" ", 1)[0] in LOBE_CLASSES:
            out.add(n.rsplit(" ", 1)[0] + " Color")
    return tuple(n for n in NAMES if n in out)


def light_name(cls: int, part: str) -> str:
    """'Diffuse Direct' etc. for lobe class index cls (LOBE_CLASSES) and part."""
    return f"{LOBE_CLASSES[cls]} {part}"


def check(names) -> tuple:
    """The requested names in list order; ValueError for unknown ones."""
    unknown = sorted(set(names) - set(NAMES))
    if unknown:
        raise ValueError(f"unknown render pass(es): {', '.join(unknown)} (known: {', '.join(NAMES)})")
    return tuple(n for n in NAMES if n in set(names) and n != COMBINED.name)
