"""Render passes in Blender: which the view layer enables, registered for the compositor.

The view layer's own pass checkboxes (those Cycles uses: use_pass_z, use_pass_diffuse_direct,
...) enable Ember's passes; Ember's own switches (view_layer.ember: denoising data, debug
passes, caustics) also accept Cycles' (view_layer.cycles.denoising_store_passes,
pass_debug_sample_count), so a .blend set up for Cycles renders the same passes.
"""
from __future__ import annotations

from ..integrators import REGISTRY
from ..passes import COMBINED, PASSES

_CYCLES_EQUIVALENT = {"ember.denoising_store_passes": "denoising_store_passes",
                      "ember.pass_sample_count": "pass_debug_sample_count"}


def _enabled(view_layer, prop: str) -> bool:
    if not prop.startswith("ember."):
        return bool(getattr(view_layer, prop, False))
    own = getattr(getattr(view_layer, "ember", None), prop[len("ember."):], False)
    cycles = getattr(view_layer, "cycles", None)
    alias = _CYCLES_EQUIVALENT.get(prop)
    return bool(own) or bool(alias and cycles is not None and getattr(cycles, alias, False))


def enabled_passes(view_layer, integrator: str = "path", written_only: bool = True) -> tuple:
    """Names of the passes besides Combined that view_layer enables (list order). With
    written_only, only those `integrator` writes: the light passes need one that splits its
    radiance (Integrator.light_passes), an integrator's own passes (Caustics, ...) one that
    lists them (Integrator.own_passes)."""
    cls = REGISTRY.get(integrator)
    names = []
    for p in PASSES:
        if p is COMBINED or not _enabled(view_layer, p.prop):
            continue
        if written_only and p.group in ("light", "color") and not getattr(cls, "light_passes", False):
            continue
        if p.group == "integrator" and p.name not in getattr(cls, "own_passes", ()):
            continue
        names.append(p.name)
    return tuple(names)


def register_passes(engine, scene, view_layer) -> None:
    """RenderEngine.update_render_passes: tell the compositor which sockets Ember fills."""
    ember = getattr(scene, "ember", None)
    integrator = str(getattr(ember, "integrator", "PATH")).lower()
    engine.register_pass(scene, view_layer, COMBINED.name, 4, COMBINED.chan_id, COMBINED.kind)
    for name in enabled_passes(view_layer, integrator):
        p = next(q for q in PASSES if q.name == name)
        engine.register_pass(scene, view_layer, p.name, p.channels, p.chan_id, p.kind)
