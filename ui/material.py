"""Ember's material settings and panels.

Per material (`material.ember`): the model, either the shader node tree (default) or Ember's
physically plausible Phong BRDF of seed 000, f = kd / pi + ks (n + 2) / (2 pi) cos^n(alpha),
with its diffuse colour kd, specular colour ks and exponent n. Per scene
(`scene.ember.glossy_as_phong`): render Glossy, Metallic and Principled reflection with Phong
instead of GGX, the exponent from the roughness (n = 2 / alpha^2 - 2, alpha = roughness^2);
this reproduces Veach's MIS scene and the seed's figures. engine/blender/export_material.py
reads both.
"""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty, PointerProperty

from . import properties

ENGINE = 'EMBER'
MODEL_ITEMS = [
    ('NODES', "Shader Nodes", "Render the material's node tree (Principled, Glossy, Glass, ...)"),
    ('PHONG', "Phong", "Ember's physically plausible Phong BRDF: diffuse + specular lobe of exponent n"),
]


class EmberMaterialSettings(bpy.types.PropertyGroup):
    model: EnumProperty(
        name="Model",
        description="How Ember shades this material",
        items=MODEL_ITEMS,
        default='NODES',
    )
    diffuse_color: FloatVectorProperty(
        name="Diffuse Color",
        description="Diffuse reflectance kd (diffuse + specular must not exceed 1 per channel)",
        subtype='COLOR', size=3, min=0.0, max=1.0, default=(0.5, 0.5, 0.5),
    )
    specular_color: FloatVectorProperty(
        name="Specular Color",
        description="Specular reflectance ks at normal incidence",
        subtype='COLOR', size=3, min=0.0, max=1.0, default=(0.3, 0.3, 0.3),
    )
    exponent: FloatProperty(
        name="Exponent",
        description="Phong exponent n: larger is sharper (n = 2 / alpha^2 - 2 for Beckmann roughness alpha)",
        default=100.0, min=0.0, max=1e6, soft_max=1e4,
    )


GLOSSY_AS_PHONG = BoolProperty(
    name="Render Glossy with Phong",
    description="Shade Glossy, Metallic and Principled reflection with Ember's Phong BRDF instead of GGX "
                "(exponent from the roughness: n = 2 / alpha^2 - 2, alpha = roughness^2)",
    default=False,
)


class EMBER_MATERIAL_PT_model(bpy.types.Panel):
    bl_label = "Ember Material"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "material"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES and context.material is not None

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.material.ember
        layout.prop(settings, "model")
        if settings.model == 'PHONG':
            col = layout.column()
            col.prop(settings, "diffuse_color")
            col.prop(settings, "specular_color")
            col.prop(settings, "exponent")
            if max(a + b for a, b in zip(settings.diffuse_color, settings.specular_color)) > 1.0:
                col.label(text="Diffuse + specular > 1: scaled down when rendering", icon='ERROR')


class EMBER_RENDER_PT_materials(bpy.types.Panel):
    bl_label = "Materials"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"
    bl_options = {'DEFAULT_CLOSED'}
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(context.scene.ember, "glossy_as_phong")


classes = (EmberMaterialSettings, EMBER_MATERIAL_PT_model, EMBER_RENDER_PT_materials)


def register():
    """After properties.register(): adds scene.ember.glossy_as_phong and material.ember."""
    bpy.utils.register_class(EmberMaterialSettings)
    bpy.types.Material.ember = PointerProperty(type=EmberMaterialSettings, name="Ember",
                                               description="Ember material settings")
    properties.EmberSceneSettings.glossy_as_phong = GLOSSY_AS_PHONG
    bpy.utils.register_class(EMBER_MATERIAL_PT_model)
    bpy.utils.register_class(EMBER_RENDER_PT_materials)


def unregister():
    for cls in (EMBER_RENDER_PT_materials, EMBER_MATERIAL_PT_model):
        if getattr(cls, "is_registered", False):
            bpy.utils.unregister_class(cls)
    if hasattr(properties.EmberSceneSettings, "glossy_as_phong"):
        del properties.EmberSceneSettings.glossy_as_phong
    if hasattr(bpy.types.Material, "ember"):
        del bpy.types.Material.ember
    if getattr(EmberMaterialSettings, "is_registered", False):
        bpy.utils.unregister_class(EmberMaterialSettings)
