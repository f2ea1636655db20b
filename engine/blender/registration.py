"""register()/unregister() for the whole add-on: settings, engine, panels.

Order matters: the PropertyGroup before the panels that draw it; unregister in reverse.
Both are safe to call again (re-enable after disable works, a second register() first
unregisters what is there).
"""
import bpy

from ...ui import material, panels, presets, properties
from . import engine

_registered = False


def register():
    global _registered
    if _registered:
        unregister()
    properties.register()
    material.register()
    bpy.utils.register_class(engine.EmberRenderEngine)
    presets.register()
    panels.register()
    _registered = True


def unregister():
    global _registered
    panels.unregister()
    presets.unregister()
    if getattr(engine.EmberRenderEngine, "is_registered", False):
        bpy.utils.unregister_class(engine.EmberRenderEngine)
    material.unregister()
    properties.unregister()
    _registered = False


def check_runtime() -> None:
    """Import what every render needs but loads lazily (Embree's wheel), so that a broken
    install fails before a render starts rather than in its first frame."""
    import importlib

    for module in ("embreex.rtcore", "embreex.rtcore_scene", "embreex.mesh_construction"):
        importlib.import_module(module)
