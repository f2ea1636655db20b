"""Presets of Ember's sampling settings (Render Properties > Sampling, the header's preset menu).

Blender's own preset mechanism (AddPresetBase + a PresetPanel) reads preset files from the
`presets/<subdir>` folders of Blender's script paths; an extension cannot ship files there
without writing into the user's configuration when it is enabled. So the built-in presets
are named sets of values here, applied by one operator (`render.ember_sampling_preset`) from
a menu, like Cycles' Preview and Final sampling presets (presets/cycles/sampling/*.py), with
the values Ember needs (no denoiser: more samples, fewer bounces for Preview).
"""
import bpy
from bpy.props import EnumProperty

# Preset name -> scene.ember property -> value. Tests check every one is applied.
PRESETS = {
    "PREVIEW": {
        "samples": 128,
        "use_adaptive_sampling": True,
        "adaptive_threshold": 0.1,
        "adaptive_min_samples": 0,
        "time_limit": 0.0,
        "noise_target": 0.0,
        "max_depth": 8,
    },
    "FINAL": {
        "samples": 4096,
        "use_adaptive_sampling": True,
        "adaptive_threshold": 0.01,
        "adaptive_min_samples": 0,
        "time_limit": 0.0,
        "noise_target": 0.0,
        "max_depth": 64,
    },
}
PRESET_ITEMS = [
    ('PREVIEW', "Preview", "Fast, noisier: adaptive sampling to noise 0.1, at most 128 samples, 8 bounces"),
    ('FINAL', "Final", "Adaptive sampling to noise 0.01, at most 4096 samples, 64 bounces"),
]


def apply_preset(settings, name: str) -> None:
    """Set the preset's values on scene.ember `settings`."""
    for prop, value in PRESETS[name].items():
        setattr(settings, prop, value)


class EMBER_OT_sampling_preset(bpy.types.Operator):
    """Set Ember's sampling settings to a preset"""

    bl_idname = "render.ember_sampling_preset"
    bl_label = "Ember Sampling Preset"
    bl_options = {'REGISTER', 'UNDO'}

    preset: EnumProperty(name="Preset", items=PRESET_ITEMS)

    @classmethod
    def description(cls, context, properties):
        return dict((i[0], i[2]) for i in PRESET_ITEMS)[properties.preset]

    def execute(self, context):
        apply_preset(context.scene.ember, self.preset)
        return {'FINISHED'}


class EMBER_MT_sampling_presets(bpy.types.Menu):
    bl_label = "Sampling Presets"

    def draw(self, context):
        for ident, label, _ in PRESET_ITEMS:
            self.layout.operator(EMBER_OT_sampling_preset.bl_idname, text=label).preset = ident


classes = (EMBER_OT_sampling_preset, EMBER_MT_sampling_presets)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        if getattr(cls, "is_registered", False):
            bpy.utils.unregister_class(cls)
