"""Render Properties panels for Ember, and opting Blender's stock panels in.

Blender shows a stock panel only for the engines listed in its COMPAT_ENGINES set. We add
'EMBER' to every panel that supports the old internal renderer ('BLENDER_RENDER': format,
output, colour management, lens, ...) plus the EEVEE panels whose settings we read
(material slots and surface node, world surface, light colour/power/radius, camera depth
of field). unregister() takes 'EMBER' out of exactly the sets it was added to.
"""
import bpy

from ..engine.integrators import REGISTRY
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


class EmberRenderPanel:
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


class EMBER_RENDER_PT_sampling(EmberRenderPanel, bpy.types.Panel):
    bl_label = "Sampling"

    def draw_header_preset(self, context):
        self.layout.menu("EMBER_MT_sampling_presets", text="", icon='PRESET')

    def draw(self, context):
        """As Cycles' Sampling > Render: noise threshold (adaptive), max/min samples, time limit."""
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.ember
        col = layout.column()
        col.prop(settings, "integrator")
        heading = layout.column(align=True, heading="Noise Threshold")
        row = heading.row(align=True)
        row.prop(settings, "use_adaptive_sampling", text="")
        sub = row.row()
        sub.active = settings.use_adaptive_sampling
        sub.prop(settings, "adaptive_threshold", text="")
        col = layout.column(align=True)
        if settings.use_adaptive_sampling:
            col.prop(settings, "samples", text="Max Samples")
            col.prop(settings, "adaptive_min_samples", text="Min Samples")
        else:
            col.prop(settings, "samples", text="Samples")
        col.prop(settings, "preview_samples")
        col.prop(settings, "time_limit")
        col = layout.column()
        col.prop(settings, "noise_target")
        row = col.row(align=True)
        row.prop(settings, "seed")
        row.prop(settings, "use_animated_seed", text="", icon='TIME')
        col.prop(settings, "pattern")


class EMBER_RENDER_PT_sampling_advanced(EmberRenderPanel, bpy.types.Panel):
    bl_label = "Advanced"
    bl_parent_id = "EMBER_RENDER_PT_sampling"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(context.scene.ember, "sample_offset")


class EMBER_RENDER_PT_light_paths(EmberRenderPanel, bpy.types.Panel):
    bl_label = "Light Paths"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.ember
        layout.prop(settings, "max_depth")
        path_only = settings.integrator in ('PATH', 'AUTO')  # auto: these make it choose the path tracer
        col = layout.column(heading="Bounces", align=True)
        col.active = path_only  # the photon integrators use Max Bounces alone
        col.prop(settings, "diffuse_bounces")
        col.prop(settings, "glossy_bounces")
        col.prop(settings, "transmission_bounces")
        col.prop(settings, "transparent_bounces")
        col = layout.column(heading="Clamping", align=True)
        col.active = path_only
        col.prop(settings, "clamp_direct")
        col.prop(settings, "clamp_indirect")
        col = layout.column(heading="Caustics", align=True)
        col.active = path_only
        col.prop(settings, "filter_glossy")
        col.prop(settings, "caustics_reflective", text="Reflective")
        col.prop(settings, "caustics_refractive", text="Refractive")
        if not path_only:
            layout.label(text="Per-type bounces, clamping and caustics apply to Path Tracing only",
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


class EMBER_RENDER_PT_performance(EmberRenderPanel, bpy.types.Panel):
    bl_label = "Performance"
    bl_options = {'DEFAULT_CLOSED'}

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
        layout.prop(context.scene.ember, "batch_size")


class EMBER_RENDER_PT_photons(EmberRenderPanel, bpy.types.Panel):
    bl_label = "Photon Mapping"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and context.scene.ember.integrator in ('PHOTON', 'PPM', 'PATH_CAUSTIC', 'AUTO')

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.ember
        col = layout.column()
        if settings.integrator == 'PPM':
            col.prop(settings, "photons", text="Photons per Pass")
            col.prop(settings, "ppm_radius")
            col.prop(settings, "ppm_alpha")
            return
        col.prop(settings, "photons")
        col.prop(settings, "caustic_photons")
        col.prop(settings, "photon_k")
        col.prop(settings, "photon_kernel")
        col.prop(settings, "global_radius")
        col.prop(settings, "caustic_radius")
        col.prop(settings, "gather_rays")
        col.prop(settings, "radiance_photons")
        col.prop(settings, "photon_view")


class EMBER_RENDER_PT_icache(EmberRenderPanel, bpy.types.Panel):
    bl_label = "Irradiance Cache"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and context.scene.ember.integrator in ('ICACHE', 'AUTO')

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.ember
        col = layout.column()
        for name in ("icache_a", "icache_rays", "icache_gradients", "icache_weight", "icache_gather", "icache_view"):
            col.prop(settings, name)
        col.prop(settings, "icache_radiance")
        sub = col.column()
        sub.active = settings.icache_radiance
        sub.prop(settings, "icache_radiance_order")
        col = layout.column(heading="Photons")
        if settings.icache_gather == 'PHOTON':
            col.prop(settings, "photons")
            col.prop(settings, "global_radius")
            col.prop(settings, "radiance_photons")
        col.prop(settings, "caustic_photons")
        col.prop(settings, "caustic_radius")
        col.prop(settings, "photon_k")
        col.prop(settings, "gather_rays", text="Gather Rays (uncached)")


class EMBER_RENDER_PT_film(EmberRenderPanel, bpy.types.Panel):
    """Settings Ember reads from Blender and Cycles that had no panel under Ember."""
    bl_label = "Film"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        scene = context.scene
        col = layout.column()
        col.prop(scene.render, "film_transparent", text="Transparent")
        cycles = getattr(scene, "cycles", None)
        if cycles is not None:  # Ember reads Cycles' pixel filter (engine/blender/export_settings.py)
            col.prop(cycles, "pixel_filter_type", text="Pixel Filter")
            sub = col.column()
            sub.active = cycles.pixel_filter_type != 'BOX'
            sub.prop(cycles, "filter_width", text="Width")
        world = scene.world
        if world is not None and hasattr(world, "cycles_visibility"):
            col.prop(world.cycles_visibility, "camera", text="World Visible to Camera")
        col.prop(context.view_layer, "material_override")


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
