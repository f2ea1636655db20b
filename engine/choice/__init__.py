"""`auto`: the integrator chosen from the scene.

Not a light-transport method of its own: before a render, `resolve` analyses the scene
(analysis.py), applies the rule (rule.py) and returns the scene with the chosen integrator and
parameters in its Settings. The session renders that scene, so workers, stages and images are
exactly the chosen integrator's; the stats carry the analysis, the choice and its reasons, and
what was left out and why. The registry lists `auto` (engine/integrators/auto.py) without
importing this package: nothing that traces needs it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import passes as passes_mod
from ..integrators import REGISTRY
from ..scene import Scene
from ..validation import path_only_warnings
from ..volumes import Media
from .analysis import SceneAnalysis, analyse
from .rule import Choice, choose


@dataclass(frozen=True)
class Resolved:
    scene: Scene  # with Settings.integrator the chosen one
    analysis: SceneAnalysis
    choice: Choice
    lines: tuple  # for the stats: the choice, the analysis, what is not built and why


def resolve(scene: Scene) -> Resolved:
    """The scene with the integrator and parameters `auto` chooses for it."""
    s = scene.settings
    a = analyse(scene)  # one seed: the choice does not change with the render's (animated) seed
    choice = choose(a, s, _path_only(scene))
    cls = REGISTRY[choice.integrator]
    unsupported = [what for what, used, ok in (
        ("a noise target", s.noise_target > 0, cls.noise_target), ("adaptive sampling", s.adaptive, cls.adaptive),
        ("a sample offset", s.sample_offset > 0, cls.sample_offset)) if used and not ok]
    if unsupported:
        choice = Choice("path", {}, (f"'{choice.integrator}' would fit, but the render asks for "
                                     f"{', '.join(unsupported)}, which it does not support",), ())
    chosen = scene.replace(settings=s.replace(integrator=choice.integrator, **choice.settings))
    lines = (choice.text(), *a.summary.splitlines(), *choice.notes, *_left_out(a, choice, chosen.settings))
    return Resolved(chosen, a, choice, lines)


def _path_only(scene: Scene) -> tuple:
    """What the scene asks for that only the path tracer does (engine/validation.py's list)."""
    out = []
    w = scene.world
    if (np.any(scene.lights.Le < 0) or np.any(scene.materials.emission < 0) or np.any(w.color < 0)
            or (w.image is not None and np.min(w.image) < 0)):
        out.append("negative light")
    if any(n in passes_mod.LIGHT for n in passes_mod.needed(scene.settings.passes)):
        out.append("light passes")
    if Media.of(scene.materials) is not None:
        out.append("volumes")
    probe = scene.replace(settings=scene.settings.replace(integrator="photon"))
    for w in path_only_warnings(probe):
        out.append("ray visibility or holdouts" if "visibility" in w else "per-kind bounce limits or clamping")
    return tuple(out)


def _left_out(a, choice, settings) -> tuple:
    """Tables and maps the render does not build, and why (the photon integrators add their
    own: 'no caustic map: ...')."""
    out = []
    if "environment" not in a.light_kinds:
        out.append("no environment table: " + ("the world is a constant colour" if "constant" in a.light_kinds
                                               else "the world is black"))
    if not a.has_light:
        out.append("no light-sampling table: no lights")
    if choice.integrator == "path":
        out.append("no photon maps, no irradiance cache: path tracing")
    if choice.integrator == "icache" and settings.icache_gather == "path":
        out.append("no global photon map: the records' gather rays trace paths")
    return tuple(out)
