"""Render Properties panels for Ember, and opting Blender's stock panels in.

Blender shows a stock panel only for the engines listed in its COMPAT_ENGINES set. We add
'EMBER' to every panel that supports the old internal renderer ('BLENDER_RENDER': format,
output, colour management, lens, ...) plus the EEVEE panels whose settings we read
(material slots and surface node, world surface, light colour/power/radius, camera depth
of field). unregister() takes 'EMBER' out of exactly the sets it was added to.
"""
import bpy

from ..engine import settings as declared
from ..engine.integrators import REGISTRY, honours
from ..engine.passes import COMBINED, PASSES

ENGINE = 'EMBER'

# EEVEE-only panels that draw data Ember reads (blender.md section 1, "Panels").
EXTRA_PANELS = (
    'EEVEE_MATERIAL_PT_context_material',
    'EEVEE_MATERIAL_PT_surface',
    'EEVEE_WORLD_PT_surface',
    'DATA_PT_EEVEE_light',
    'DATA_PT_camera_dof',
    'DATA_PT_camera_dof_aperture',
)
# BLENDER_RENDER panels left out: DATA_PT_light only draws the light-type row, which
# DATA_PT_EEVEE_light draws too; the previews need bl_use_preview, which we do not set.
EXCLUDED_PANELS = {'DATA_PT_light', 'DATA_PT_preview', 'TEXTURE_PT_preview'}
GROUPS = {g.name: g for g in declared.GROUPS}


# ---- settings drawn from their declarations (engine/settings.py) ---------------------------------
def _owner(scene, s: declared.Setting):
    """(bpy struct, property name) holding a declared setting, or None (e.g. no scene.cycles)."""
    if s.bpy_prop:
        return scene.ember, s.bpy_prop
    owner, _, prop = s.blender.rpartition(".")
    struct = getattr(scene, owner, None) if owner else None
    return (struct, prop) if struct is not None and hasattr(struct, prop) else None


def _value(scene, name: str):
    """A declared setting's value as the core holds it (enum identifiers lower case)."""
    s = declared.DECLARED[name]
    found = _owner(scene, s)
    return s.core(getattr(*found)) if found else s.default


def _honoured(scene, s: declared.Setting) -> bool:
    return honours(s, _value(scene, "integrator"), lambda name: _value(scene, name))


def draw_settings(layout, scene, group: str, subpanel: str = "", hide_unhonoured: bool = True):
    """The group's declared settings in declaration order, with their Ui hints: columns under
    headings, a setting beside the one before, texts, icons, conditions. Settings the chosen
    integrator does not honour are left out (hide_unhonoured) or greyed out."""
    holds = lambda condition: declared.holds(condition, lambda name: _value(scene, name))  # noqa: E731
    col = row = layout.column()
    for s in GROUPS[group].settings:
        ui, found = s.ui, _owner(scene, s)
        if ui is None or found is None or ui.subpanel != subpanel or (ui.shown_if and not holds(ui.shown_if)):
            continue
        honoured = _honoured(scene, s)
        if hide_unhonoured and not honoured:
            continue
        if ui.column is not None:
            col = layout.column(align=True, heading=ui.column)
        if not ui.beside:
            row = col.row(align=True)
        sub = row.row(align=True)
        sub.active = honoured and (not ui.active_if or holds(ui.active_if))
        sub.alert = declared.problem(s, _value(scene, s.name)) is not None  # F12 refuses it (properties.py)
        text = next((t for condition, t in ui.texts if holds(condition)), s.label if ui.text is None else ui.text)
        sub.prop(*found, text=text, icon=ui.icon or 'NONE')


class EmberRenderPanel:
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


class EmberSettingsPanel(EmberRenderPanel):
    """A panel of one group of declared settings (its sub-panel's); settings the integrator
    does not honour are left out, and the panel with them when none is left (hide_unhonoured),
    or greyed out."""
    group = ""
    subpanel = ""
    hide_unhonoured = True

    @classmethod
    def poll(cls, context):
        drawn = [s for s in GROUPS[cls.group].settings if s.ui is not None and s.ui.subpanel == cls.subpanel]
        return super().poll(context) and (not cls.hide_unhonoured or any(_honoured(context.scene, s) for s in drawn))

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        draw_settings(layout, context.scene, self.group, self.subpanel, self.hide_unhonoured)


class EMBER_RENDER_PT_sampling(EmberSettingsPanel, bpy.types.Panel):
    """As Cycles' Sampling > Render: noise threshold (adaptive), max/min samples, time limit."""
    bl_label = "Sampling"
    group = "sampling"
    hide_unhonoured = False

    def draw_header_preset(self, context):
        self.layout.menu("EMBER_MT_sampling_presets", text="", icon='PRESET')


class EMBER_RENDER_PT_sampling_advanced(EmberSettingsPanel, bpy.types.Panel):
    bl_label = "Advanced"
    bl_parent_id = "EMBER_RENDER_PT_sampling"
    bl_options = {'DEFAULT_CLOSED'}
    group = "sampling"
    subpanel = "advanced"
    hide_unhonoured = False


class EMBER_RENDER_PT_light_paths(EmberSettingsPanel, bpy.types.Panel):
    bl_label = "Light Paths"
    bl_options = {'DEFAULT_CLOSED'}
    group = "light_paths"
    hide_unhonoured = False  # greyed out: they still make `auto` choose the path tracer

    def draw(self, context):
        super().draw(context)
        if not all(_honoured(context.scene, s) for s in GROUPS[self.group].settings):
            self.layout.label(text="Per-type bounces, clamping and caustics apply to Path Tracing only",
                              icon='INFO')


class EMBER_RENDER_PT_motion_blur(EmberRenderPanel, bpy.types.Panel):
    """Blender's motion blur switch, shown so that a scene that uses it says what Ember does."""
    bl_label = "Motion Blur"
    bl_options = {'DEFAULT_CLOSED'}

    def draw_header(self, context):
        self.layout.prop(context.scene.render, "use_motion_blur", text="")

    def draw(self, context):
        col = self.layout.column()
        if context.scene.render.use_motion_blur:
            col.label(text="Not supported yet: Ember renders without motion blur", icon='ERROR')
        else:
            col.label(text="Not supported yet by Ember", icon='INFO')


class EMBER_OBJECT_PT_visibility(bpy.types.Panel):
    """Object Properties > Visibility (as Cycles'): which rays see the object; the path tracer
    honours them (engine/visibility.py)."""
    bl_label = "Ray Visibility"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "object"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        ob = context.object
        return context.engine in cls.COMPAT_ENGINES and ob is not None and ob.type in {'MESH', 'LIGHT'}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        ob = context.object
        col = layout.column(heading="Ray Visibility", align=True)
        col.prop(ob, "visible_camera", text="Camera")
        col.prop(ob, "visible_diffuse", text="Diffuse")
        col.prop(ob, "visible_glossy", text="Glossy")
        col.prop(ob, "visible_transmission", text="Transmission")
        if ob.type == 'MESH':
            col.prop(ob, "visible_shadow", text="Shadow")
            layout.prop(ob, "is_holdout")
        if context.scene.ember.integrator not in ('PATH', 'AUTO'):
            layout.label(text="Ray visibility applies to Path Tracing only", icon='INFO')


class EMBER_WORLD_PT_visibility(bpy.types.Panel):
    """World Properties > Ray Visibility (as Cycles')."""
    bl_label = "Ray Visibility"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "world"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES and context.world is not None

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        vis = context.world.cycles_visibility
        col = layout.column(align=True)
        col.prop(vis, "camera")
        col.prop(vis, "diffuse")
        col.prop(vis, "glossy")
        col.prop(vis, "transmission")


class EMBER_RENDER_PT_performance(EmberSettingsPanel, bpy.types.Panel):
    bl_label = "Performance"
    bl_options = {'DEFAULT_CLOSED'}
    group = "performance"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        rd = context.scene.render
        col = layout.column(heading="Threads")  # Blender's own setting, as Cycles shows it
        col.prop(rd, "threads_mode")
        sub = col.column(align=True)
        sub.enabled = rd.threads_mode == 'FIXED'
        sub.prop(rd, "threads")
        draw_settings(layout, context.scene, self.group)


class EMBER_RENDER_PT_photons(EmberSettingsPanel, bpy.types.Panel):
    bl_label = "Photon Mapping"
    group = "photons"


class EMBER_RENDER_PT_icache(EmberSettingsPanel, bpy.types.Panel):
    bl_label = "Irradiance Cache"
    group = "icache"


class EMBER_RENDER_PT_film(EmberSettingsPanel, bpy.types.Panel):
    """Settings Ember reads from Blender and Cycles (the pixel filter: engine/blender/export_settings.py)."""
    bl_label = "Film"
    bl_options = {'DEFAULT_CLOSED'}
    group = "film"

    def draw(self, context):
        super().draw(context)
        layout = self.layout.column()
        world = context.scene.world
        if world is not None and hasattr(world, "cycles_visibility"):
            layout.prop(world.cycles_visibility, "camera", text="World Visible to Camera")
        layout.prop(context.view_layer, "material_override")


class EMBER_VIEWLAYER_PT_passes(EmberRenderPanel, bpy.types.Panel):
    """The passes of engine/passes.py, each by the checkbox that enables it."""
    bl_label = "Passes"
    bl_context = "view_layer"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        view_layer = context.view_layer
        integrator = REGISTRY.get(str(context.scene.ember.integrator).lower())
        own = getattr(integrator, "own_passes", ())
        col = layout.column(heading="Include")
        drawn = set()
        for p in PASSES:
            if p is COMBINED or p.prop in drawn or (p.group == "integrator" and p.name not in own):
                continue
            drawn.add(p.prop)
            if p.prop.startswith("ember."):
                col.prop(view_layer.ember, p.prop[len("ember."):])
            else:
                col.prop(view_layer, p.prop, text=p.name)


classes = (EMBER_RENDER_PT_sampling, EMBER_RENDER_PT_sampling_advanced, EMBER_RENDER_PT_photons,
           EMBER_RENDER_PT_icache, EMBER_RENDER_PT_light_paths, EMBER_RENDER_PT_motion_blur,
           EMBER_RENDER_PT_performance, EMBER_RENDER_PT_film, EMBER_VIEWLAYER_PT_passes, EMBER_OBJECT_PT_visibility,
           EMBER_WORLD_PT_visibility)

# The COMPAT_ENGINES sets we added ENGINE to (by identity: mixins share one set object).
_added_to: dict = {}


def _panel_classes():
    seen = set()
    stack = list(bpy.types.Panel.__subclasses__())
    while stack:
        cls = stack.pop()
        if cls in seen:
            continue
        seen.add(cls)
        stack.extend(cls.__subclasses__())
    return seen


def stock_panels():
    """Stock panels Ember opts in to: BLENDER_RENDER ones (minus exclusions) + EXTRA_PANELS."""
    all_panels = _panel_classes()
    # Copies such as the node editor's NODE_DATA_PT_light share their original's set object,
    # so exclusion goes by set identity.
    excluded = {id(cls.COMPAT_ENGINES) for cls in all_panels
                if cls.__name__ in EXCLUDED_PANELS and isinstance(getattr(cls, "COMPAT_ENGINES", None), set)}
    chosen = []
    for cls in all_panels:
        engines = getattr(cls, "COMPAT_ENGINES", None)
        if not isinstance(engines, set) or cls in classes:
            continue
        name = cls.__name__
        if name in EXTRA_PANELS or ('BLENDER_RENDER' in engines and id(engines) not in excluded):
            chosen.append(cls)
    return chosen


def _add_engine_to_stock_panels():
    for cls in stock_panels():
        engines = cls.COMPAT_ENGINES
        if ENGINE not in engines:
            engines.add(ENGINE)
            _added_to[id(engines)] = engines


def _remove_engine_from_stock_panels():
    for engines in _added_to.values():
        engines.discard(ENGINE)
    _added_to.clear()


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    _add_engine_to_stock_panels()


def unregister():
    _remove_engine_from_stock_panels()
    for cls in reversed(classes):
        if getattr(cls, "is_registered", False):
            bpy.utils.unregister_class(cls)
