"""Ember's render settings, stored in the .blend at `scene.ember`.

These are user-facing values only; engine/blender/export.py turns them into
engine.scene.Settings.
"""
import bpy
from bpy.props import EnumProperty, FloatProperty, IntProperty, PointerProperty

from ..engine.integrators import REGISTRY

# One item per registered integrator (engine/integrators/__init__.py is the one list).
INTEGRATOR_ITEMS = [(cls.name.upper(), cls.label, cls.description) for cls in REGISTRY.values()]


PATTERN_ITEMS = [
    ('SOBOL', "Sobol-Burley", "Owen-scrambled Sobol sequence (as Cycles): lower noise per sample"),
    ('RANDOM', "Independent", "Independent random numbers per sample (for studies)"),
]


class EmberSceneSettings(bpy.types.PropertyGroup):
    integrator: EnumProperty(
        name="Integrator",
        description="Method used to compute light transport",
        items=INTEGRATOR_ITEMS,
        default='PATH',
    )
    samples: IntProperty(
        name="Samples",
        description="Samples per pixel (full passes over the image)",
        default=64, min=1, soft_max=4096,
    )
    max_depth: IntProperty(
        name="Max Bounces",
        description="Longest light path, in surface interactions",
        default=64, min=1, max=1024,
    )
    seed: IntProperty(
        name="Seed",
        description="Random seed; a render with the same seed and settings is reproducible",
        default=0, min=0,
    )
    time_limit: FloatProperty(
        name="Time Limit",
        description="Stop after this many seconds (0 = no limit); the last pass finishes first",
        default=0.0, min=0.0, soft_max=3600.0, subtype='TIME_ABSOLUTE', unit='TIME_ABSOLUTE',
    )
    noise_target: FloatProperty(
        name="Noise Target",
        description="Stop once the estimated relative noise (RMS over pixels of the standard "
                    "error of the mean over mean + 0.01) falls to this value (0 = off)",
        default=0.0, min=0.0, soft_max=0.1, step=0.1, precision=4,
    )
    pattern: EnumProperty(
        name="Pattern",
        description="Random number pattern used to place samples",
        items=PATTERN_ITEMS,
        default='SOBOL',
    )
    batch_size: IntProperty(
        name="Batch Size",
        description="Rays traced together in one wavefront; bigger is faster but uses more memory",
        default=131072, min=1024, soft_max=1 << 20,
    )


classes = (EmberSceneSettings,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.ember = PointerProperty(type=EmberSceneSettings, name="Ember",
                                            description="Ember render settings")


def unregister():
    if hasattr(bpy.types.Scene, "ember"):
        del bpy.types.Scene.ember
    for cls in reversed(classes):
        if getattr(cls, "is_registered", False):
            bpy.utils.unregister_class(cls)
