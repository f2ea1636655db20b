"""Ember's render settings, stored in the .blend at `scene.ember`.

Generated from the declarations (engine/settings.py): one bpy property per setting whose
source is scene.ember (or the UI alone), with its label, description, default, range, unit
and items. engine/blender/export_settings.py turns them into engine.scene.Settings.
"""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty

from ..engine import settings as declared
from ..engine.integrators import items

# A declared unit -> (subtype, unit) of a FloatProperty.
_UNITS = {"s": ('TIME_ABSOLUTE', 'TIME_ABSOLUTE'), "m": ('DISTANCE', 'LENGTH')}


def bpy_property(s: declared.Setting):
    """The bpy property of a declared setting (enum identifiers upper case, as Blender's)."""
    kw = dict(name=s.label, description=s.description)
    # One rule for every setting, wherever its value comes from: a value out of its declared
    # range is refused when the render starts (engine/validation.py, one line), never clamped.
    # Blender clamps to a property's hard limits silently (a script, a typed value), so the
    # declared range is the soft one (sliders and drags stay in it) and the panel shows an
    # out-of-range value in red.
    limits = dict(soft_min=s.min if s.soft_min is None else s.soft_min,
                  soft_max=s.max if s.soft_max is None else s.soft_max)
    if s.kind is bool:
        return BoolProperty(default=s.blender_default, **kw)
    if s.kind is int:
        return IntProperty(default=s.blender_default, **kw, **{k: int(v) for k, v in limits.items() if v is not None})
    if s.kind is float:
        ui = s.ui or declared.Ui()
        extra = {k: v for k, v in (("precision", ui.precision), ("step", ui.step)) if v is not None}
        if s.unit in _UNITS:
            extra["subtype"], extra["unit"] = _UNITS[s.unit]
        return FloatProperty(default=s.blender_default, **kw, **extra,
                             **{k: float(v) for k, v in limits.items() if v is not None})
    if s.kind is str:
        return EnumProperty(items=[(v.upper(), label, text) for v, label, text in items(s)],
                            default=s.blender_default.upper(), **kw)
    raise TypeError(f"setting {s.name}: no Blender property for {s.kind.__name__}")


class EmberSceneSettings(bpy.types.PropertyGroup):
    __annotations__ = {s.bpy_prop: bpy_property(s) for s in declared.DECLARED.values() if s.bpy_prop}


class EmberViewLayerSettings(bpy.types.PropertyGroup):
    """Passes Blender has no view-layer checkbox for (engine/passes.py: "ember.*")."""

    denoising_store_passes: BoolProperty(
        name="Denoising Data", default=False,
        description="Denoising Albedo and Denoising Normal passes, for the compositor's Denoise node")
    pass_sample_count: BoolProperty(name="Sample Count", default=False,
                                    description="Debug pass: samples taken in each pixel")
    pass_variance: BoolProperty(name="Variance", default=False,
                                description="Debug pass: estimated variance of each pixel's mean")
    pass_caustics: BoolProperty(name="Caustics", default=False,
                                description="The caustic photon map's estimate (photon-map integrators)")


classes = (EmberSceneSettings, EmberViewLayerSettings)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.ember = PointerProperty(type=EmberSceneSettings, name="Ember",
                                            description="Ember render settings")
    bpy.types.ViewLayer.ember = PointerProperty(type=EmberViewLayerSettings, name="Ember",
                                                description="Ember view layer settings")


def unregister():
    if hasattr(bpy.types.Scene, "ember"):
        del bpy.types.Scene.ember
    if hasattr(bpy.types.ViewLayer, "ember"):
        del bpy.types.ViewLayer.ember
    for cls in reversed(classes):
        if getattr(cls, "is_registered", False):
            bpy.utils.unregister_class(cls)
