"""The viewport in Blender (Rendered shading): depsgraph updates -> partial re-export ->
engine/viewport.py's render thread; the newest image -> a GPU texture.

view_update (main thread) sorts the depsgraph's updates into parts (`classify`) and
re-exports only those (`LiveExport.update`): a moved or edited mesh re-exports the geometry
(and with it the materials, which the mesh walk indexes); a material, a light, the world, the
camera or the render settings re-export that part alone. The render thread's persistent data
then rebuilds Embree only for a new mesh and the light tables only for new lights, materials
or world. view_draw (main thread) turns the region's view into a camera (`view_camera`,
from the projection Blender draws with, so free views and camera views alike match), hands a
changed one to the render thread and draws the newest buffer. Nothing on the render thread
touches bpy; view_draw asks for another redraw while the render is running.
"""
from __future__ import annotations

import dataclasses
import time
from collections import Counter

import numpy as np

from ..errors import EmberError
from ..scene import Camera, Lights
from ..viewport import ViewportSession
from .export import Warnings, _look_dev, export_scene
from .export_camera import export_camera, fitted_sensor
from .export_light import export_light
from .export_material import DEFAULT_NAME, MaterialTable
from .export_settings import export_settings
from .export_world import export_world

PARTS = ("geometry", "materials", "lights", "world", "camera", "settings")
VIEWPORT_BATCH = 1 << 14  # paths per work item: short items restart quickly


def classify(updates) -> set:
    """The parts (PARTS) that depsgraph updates touch. Objects and meshes count only for
    geometry and transform updates (a material edit also tags its objects for shading)."""
    parts = set()
    for u in updates:
        kind = type(u.id).__name__
        if kind == "Object":
            ob_type = getattr(u.id, "type", "")
            if ob_type == "LIGHT":
                parts.add("lights")
            elif ob_type == "CAMERA":
                parts.add("camera")
            elif u.is_updated_geometry or u.is_updated_transform:
                parts.add("geometry")
        elif kind == "Mesh" and u.is_updated_geometry:
            parts.add("geometry")
        elif kind == "Material":
            parts.add("materials")
        elif kind in ("Light", "PointLight", "SpotLight", "SunLight", "AreaLight"):
            parts.add("lights")
        elif kind == "World":
            parts.add("world")
        elif kind in ("Camera",):
            parts.add("camera")
        elif kind == "Scene":
            parts.add("settings")
        elif kind == "Collection":  # objects added or removed
            parts |= {"geometry", "lights"}
    return parts


def keeps_meshes(updates) -> bool:
    """Whether the meshes extracted for the last export still hold after `updates`: every
    update that touches geometry only moved an object (a transform); a mesh edit, a modifier,
    an object added or deleted (a freed mesh's address may come back) extract again."""
    for u in updates:
        kind = type(u.id).__name__
        if kind == "Object" and getattr(u.id, "type", "") not in ("LIGHT", "CAMERA"):
            if u.is_updated_geometry:
                return False
        elif kind in ("Mesh", "Collection") and (kind == "Collection" or u.is_updated_geometry):
            return False
    return True


def view_camera(view_matrix, window_matrix, clip_start: float, clip_end: float) -> Camera:
    """Camera of a 3D view from its view matrix (camera from world) and window (projection)
    matrix, both 4x4 nested sequences as mathutils gives them: the image rectangle at z = -1
    (perspective) or the view volume (orthographic) is where the projection maps to -1..1."""
    V = np.array(view_matrix, np.float64)
    W = np.array(window_matrix, np.float64)
    ortho = abs(W[3, 3]) > 0.5  # perspective projections have w = -z (W[3,3] = 0)
    if ortho:  # ndc = W00 x + W03
        left, right = (-1 - W[0, 3]) / W[0, 0], (1 - W[0, 3]) / W[0, 0]
        bottom, top = (-1 - W[1, 3]) / W[1, 1], (1 - W[1, 3]) / W[1, 1]
    else:  # at z = -1: ndc = W00 x - W02
        left, right = (-1 + W[0, 2]) / W[0, 0], (1 + W[0, 2]) / W[0, 0]
        bottom, top = (-1 + W[1, 2]) / W[1, 1], (1 + W[1, 2]) / W[1, 1]
    return Camera(world_from_camera=np.linalg.inv(V), window=np.array([left, right, bottom, top]), ortho=ortho,
                  clip_start=float(clip_start), clip_end=float(clip_end))


class LiveExport:
    """The scene of a viewport, kept up to date part by part. `calls` counts the re-exports
    of each part (the tests check that an edit re-exports exactly its part)."""

    def __init__(self, depsgraph, overrides: dict):
        self.overrides = overrides
        self.calls = Counter()
        self.warnings: list[str] = []
        self.camera = None  # a view's camera replacing the scene's (free navigation)
        self.protos = {}  # meshes extracted by the last export (export_mesh.MeshCollector)
        self.placed = {}  # and where it placed them (MeshCollector.build)
        self.scene = self._full(depsgraph)

    def _full(self, depsgraph):
        self.calls["geometry"] += 1
        scene, warnings = export_scene(depsgraph, overrides=self.overrides, protos=self.protos, placed=self.placed)
        self.warnings = list(warnings)
        self.origin = np.asarray(scene.settings.origin, np.float64)
        return scene if self.camera is None else scene.replace(camera=self._shift_camera(self.camera))

    def _shift_camera(self, camera: Camera) -> Camera:
        m = np.array(camera.world_from_camera, np.float64)
        m[:3, 3] -= self.origin
        return dataclasses.replace(camera, world_from_camera=m)

    def set_view(self, camera: Camera | None) -> bool:
        """Use a view's camera (world space; None: the scene's). True if it changed."""
        old = self.camera
        if old is not None and camera is not None and np.array_equal(old.window, camera.window) and \
                np.array_equal(old.world_from_camera, camera.world_from_camera) and old.ortho == camera.ortho:
            return False
        self.camera = camera
        if camera is not None:
            self.scene = self.scene.replace(camera=self._shift_camera(camera))
        return True

    def update(self, depsgraph, parts: set, keep_meshes: bool = False) -> set:
        """Re-export `parts` from depsgraph; returns the parts that changed (what the render
        thread must rebuild). keep_meshes: the edit only moved objects (`keeps_meshes`), so
        the geometry is re-placed from the meshes extracted before, not extracted again."""
        if "geometry" in parts:
            if not keep_meshes:
                self.protos, self.placed = {}, {}
            self.scene = self._full(depsgraph)
            return set(PARTS)
        warn = Warnings()
        scene = self.scene
        if "settings" in parts:
            self.calls["settings"] += 1
            settings = export_settings(depsgraph.scene, self.overrides, warn)
            settings = _look_dev(settings, depsgraph, self.overrides, warn)
            scene = scene.replace(settings=settings.replace(origin=tuple(self.origin)))
        if "materials" in parts:
            self.calls["materials"] += 1
            scene = scene.replace(materials=self._materials(depsgraph, warn))
        if "lights" in parts:
            self.calls["lights"] += 1
            scene = scene.replace(lights=self._lights(depsgraph, warn))
        if "world" in parts:
            self.calls["world"] += 1
            scene = scene.replace(world=export_world(depsgraph, depsgraph.scene_eval, warn))
        if "camera" in parts and self.camera is None:
            self.calls["camera"] += 1
            camera = export_camera(depsgraph, depsgraph.scene_eval, scene.settings, warn)
            scene = scene.replace(camera=self._shift_camera(camera))
        self.scene = scene
        self.warnings = warn.finish()
        return set(parts)

    def _materials(self, depsgraph, warn):
        """The material table again, in the order the mesh export indexed it (by name)."""
        import bpy
        table = MaterialTable(warn, depsgraph.scene)
        for name in self.scene.materials.names:
            mat = bpy.data.materials.get(name) if name != DEFAULT_NAME else None
            if mat is None and name != DEFAULT_NAME:
                raise EmberError(f"Material '{name}' disappeared; re-export the geometry.")
            table.index(mat.evaluated_get(depsgraph) if mat is not None else None)
        if len(table) != len(self.scene.materials.names):
            raise EmberError("Material names are not unique; re-export the geometry.")
        return table.materials()

    def _lights(self, depsgraph, warn):
        rows = []
        for inst in depsgraph.object_instances:
            if inst.show_self and inst.object.type == "LIGHT":
                row = export_light(inst.object, inst.matrix_world.copy(), warn)
                if row is not None:
                    row["position"] = np.asarray(row["position"], np.float64) - self.origin
                    rows.append(row)
        return Lights.make(rows)


def viewport_overrides(scene, size) -> dict:
    """Settings a viewport of `size` (width, height) pixels renders with, over the scene's: the
    viewport samples (scene.ember.preview_samples), short work items, no passes."""
    return dict(width=size[0], height=size[1], border=(0, 0) + tuple(size), batch_size=VIEWPORT_BATCH,
                samples=int(scene.ember.preview_samples), passes=())


class ViewportDriver:
    """What the RenderEngine's view_update / view_draw do (one per engine instance)."""

    def __init__(self):
        self.export = None
        self.session = None
        self.size = None
        self.timings = []  # (parts, seconds) of each view_update export

    def view_update(self, engine, context, depsgraph) -> None:
        t0 = time.perf_counter()
        size = (context.region.width, context.region.height)
        overrides = viewport_overrides(depsgraph.scene, size)
        try:
            if self.export is None or size != self.size:
                self.export = LiveExport(depsgraph, overrides)
                self.export.set_view(_region_camera(context, self.export))
                parts = set(PARTS)
            else:
                parts = classify(depsgraph.updates)
                if not parts:
                    return
                try:
                    parts = self.export.update(depsgraph, parts, keeps_meshes(depsgraph.updates))
                except EmberError:
                    parts = self.export.update(depsgraph, parts | {"geometry"})
        except EmberError as e:
            engine.update_stats("", f"Ember: {e}")
            return
        self.size = size
        self.timings.append((tuple(sorted(parts)), time.perf_counter() - t0))
        self._start(engine, context, parts)

    def _start(self, engine, context, parts) -> None:
        if self.session is None:
            self.session = ViewportSession(pixel_size=max(2, engine.get_preview_pixel_size(context.scene)))
        self.session.update(self.export.scene)

    def view_draw(self, engine, context, depsgraph) -> None:
        if self.export is None:
            return
        if self.export.set_view(_region_camera(context, self.export)):
            self._start(engine, context, {"camera"})
        latest = self.session.latest() if self.session is not None else None
        if latest is not None:
            draw(engine, context.scene, latest)
        if self.session is not None and self.session.busy():
            engine.tag_redraw()  # keep drawing while the render refines (from the main thread)
        if self.session is not None and self.session.error:
            engine.update_stats("", f"Ember: {self.session.error}")

    def free(self) -> None:
        if self.session is not None:
            self.session.close()
            self.session = None


def _region_camera(context, export: LiveExport) -> Camera:
    r3d, space = context.region_data, context.space_data
    scene = getattr(context, "scene", None)
    ob = scene.camera if scene is not None else None
    if getattr(r3d, "view_perspective", "PERSP") == "CAMERA" and ob is not None and ob.type == "CAMERA" \
            and ob.data.type == "PANO" and export.scene.camera.panorama:
        from bpy_extras.view3d_utils import location_3d_to_region_2d
        corners = [location_3d_to_region_2d(context.region, r3d, ob.matrix_world @ v)
                   for v in ob.data.view_frame(scene=scene)]
        if all(c is not None for c in corners):
            xs, ys = [c.x for c in corners], [c.y for c in corners]
            border = (min(xs), max(xs), min(ys), max(ys))
            world = dataclasses.replace(export.scene.camera,
                                        world_from_camera=np.array(export.scene.camera.world_from_camera))
            world.world_from_camera[:3, 3] += export.origin
            return pano_view_camera(world, border, (context.region.width, context.region.height),
                                    fitted_sensor(ob.data, border[1] - border[0], border[3] - border[2]))
    return view_camera(r3d.view_matrix, r3d.window_matrix, space.clip_start, space.clip_end)


def pano_view_camera(camera: Camera, border, size, sensor) -> Camera:
    """A panoramic camera seen through in a 3D view (Cycles' viewport camera view): the region
    of `size` (width, height) pixels shows the panorama's image (u, v) in [0, 1]^2 within the
    camera frame `border` (x min, x max, y min, y max, region pixels from the bottom left)
    and its continuation around it; sensor (width, height) mm fitted to the frame."""
    x0, x1, y0, y1 = border
    bw, bh = max(x1 - x0, 1e-6), max(y1 - y0, 1e-6)
    window = np.array([-x0 / bw, (size[0] - x0) / bw, -y0 / bh, (size[1] - y0) / bh])
    return dataclasses.replace(camera, window=window, sensor=tuple(float(a) for a in sensor))


def draw(engine, scene, latest) -> None:
    """The buffer as a half-float texture through Blender's display-space shader."""
    import gpu
    from gpu_extras.presets import draw_texture_2d
    _, buf, width, height, _ = latest
    pixels = gpu.types.Buffer('FLOAT', len(buf), buf)
    texture = gpu.types.GPUTexture((width, height), format='RGBA16F', data=pixels)
    gpu.state.blend_set('ALPHA_PREMULT')
    engine.bind_display_space_shader(scene)
    draw_texture_2d(texture, (0, 0), width, height)
    engine.unbind_display_space_shader()
    gpu.state.blend_set('NONE')
