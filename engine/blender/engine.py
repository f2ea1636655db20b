"""The RenderEngine Blender talks to. Thin: every callback is one line into a driver module
(final.py for F12 / bpy.ops.render.render, viewport.py for Rendered shading). With
bl_use_eevee_viewport, Material Preview uses EEVEE."""
import bpy

from . import final, passes, viewport


class EmberRenderEngine(bpy.types.RenderEngine):
    bl_idname = "EMBER"
    bl_label = "Ember"
    bl_use_shading_nodes_custom = False  # keep Cycles/EEVEE shader nodes (we read Principled BSDF)
    bl_use_postprocess = True  # compositor and sequencer run on our result
    bl_use_eevee_viewport = True  # Material Preview through EEVEE
    bl_use_preview = False  # no material/light/world preview renders

    # Blender 4.4+: the constructor must take and forward *args/**kwargs.
    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.viewport = viewport.ViewportDriver()

    def __del__(self):
        try:
            driver = getattr(self, "viewport", None)
        except ReferenceError:  # Blender freed the struct first (an interrupted render.py exits)
            return
        if driver is not None:
            driver.free()

    def render(self, depsgraph):
        final.render(self, depsgraph)

    def view_update(self, context, depsgraph):
        self.viewport.view_update(self, context, depsgraph)

    def view_draw(self, context, depsgraph):
        self.viewport.view_draw(self, context, depsgraph)

    def update_render_passes(self, scene=None, renderlayer=None):
        passes.register_passes(self, scene, renderlayer)
