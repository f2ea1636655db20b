"""depsgraph -> Scene: the one entry point of the Blender export.

    scene, warnings = export_scene(depsgraph, overrides=None, test_break=None, progress=None)

Walks depsgraph.object_instances once (the depsgraph has already applied modifiers,
instancing and the render/viewport visibility of its mode), hands MESH instances to
export_mesh and LIGHT instances to export_light, and reads camera, world and settings.
Raises EmberError for scenes Ember cannot render and Cancelled when test_break() is True.
"""
from __future__ import annotations

import numpy as np

from ..errors import Cancelled, EmberError
from ..scene import HOLDOUT, RAY_ALL, Lights, Scene, recentred, scene_origin  # noqa: F401 (recentred: tests use it here)
from .export_camera import export_camera
from .export_light import export_light, ray_visibility
from .export_linking import LinkSets
from .export_material import MaterialTable
from .export_mesh import MeshCollector
from .export_settings import export_settings
from .export_world import export_world
from .passes import enabled_passes

CHECK_EVERY = 1000  # instances between test_break() polls
REPORT_EVERY = 5000  # instances between progress reports
_UNRENDERED_TYPES = {"CURVES": "hair curves", "POINTCLOUD": "point clouds", "VOLUME": "volumes",
                     "GREASEPENCIL": "grease pencil", "GPENCIL": "grease pencil"}


class Warnings(list):
    """User-facing warnings, each message once, in order of first occurrence.
    `group(what, name)` collects names for one summary line per feature (`finish()`)."""

    def __init__(self):
        super().__init__()
        self._groups: dict[str, list] = {}

    def __call__(self, message: str) -> None:
        if message not in self:
            self.append(message)

    def group(self, what: str, name: str) -> None:
        self._groups.setdefault(what, []).append(name)

    def finish(self) -> list[str]:
        for what, names in self._groups.items():
            self(f"{what}: {_names(names)}.")
        self._groups.clear()
        return list(self)


def export_scene(depsgraph, *, overrides: dict | None = None, test_break=None,
                 progress=None, protos: dict | None = None, placed: dict | None = None) -> tuple[Scene, list[str]]:
    """protos: meshes already extracted (MeshCollector's cache, kept by the viewport across
    edits that leave every mesh's geometry alone); filled with the ones extracted now.
    placed: where the last export put them in world space (MeshCollector.build)."""
    warn = Warnings()
    report = progress or (lambda message: None)

    def check():
        if test_break is not None and test_break():
            raise Cancelled("Export cancelled.")

    scene = depsgraph.scene_eval
    report("Export: settings")
    # Settings from the original scene: add-on PropertyGroups (scene.ember, scene.cycles)
    # do not tag the depsgraph when edited, so the evaluated copy can be stale.
    settings = export_settings(depsgraph.scene, overrides, warn)
    settings = _look_dev(settings, depsgraph, overrides or {}, warn)
    camera = export_camera(depsgraph, scene, settings, warn)
    check()

    materials = MaterialTable(warn, depsgraph.scene)
    links = LinkSets(depsgraph.scene, warn)
    meshes = MeshCollector(materials, warn, getattr(depsgraph.view_layer_eval, "material_override", None), protos,
                           links if links.active else None)
    light_rows = []
    visibility = {}  # original object pointer -> render it?
    report("Export: objects")
    for i, inst in enumerate(depsgraph.object_instances):
        if i % CHECK_EVERY == 0:
            check()
            if i and i % REPORT_EVERY == 0:
                report(f"Export: objects {i} ({meshes.n_meshes} meshes)")
        if not inst.show_self:
            continue
        ob = inst.object
        kind = ob.type
        if kind == "MESH":
            key = ob.original.as_pointer()
            flags = visibility.get(key)
            if flags is None:  # Cycles' ray visibility; an object no ray sees is left out
                flags = visibility[key] = ray_visibility(ob) | (HOLDOUT if getattr(ob, "is_holdout", False) else 0)
            if flags & RAY_ALL:
                meshes.add(ob, inst.matrix_world.copy(), flags, inst)
        elif kind == "LIGHT":
            row = export_light(ob, inst.matrix_world.copy(), warn, links if links.active else None)
            if row is not None:
                light_rows.append(row)
        elif kind in _UNRENDERED_TYPES:
            warn.group(f"Ember does not render {_UNRENDERED_TYPES[kind]} yet; skipped", ob.name)
    check()

    origin = scene_origin(meshes.bounds(), [r["position"] for r in light_rows], camera)
    mesh = meshes.build(check, report, origin, placed)
    check()
    lights = Lights.make(light_rows)
    report("Export: world")
    world = export_world(depsgraph, scene, warn)
    # A camera looking at a lit world renders the world (as Cycles); only a scene with
    # nothing at all to show is refused.
    if mesh.n_triangles == 0 and len(lights) == 0 and not (world.visible and np.any(world.color != 0)):
        raise EmberError("Nothing to render: the scene has no visible geometry, no lights and a black world.")
    report(f"Export: done ({mesh.n_triangles} triangles, {len(lights)} lights, "
           f"{len(materials)} materials)")
    out = Scene(mesh=mesh, materials=materials.materials(), lights=lights, world=world,
                camera=camera, settings=settings)
    return recentred(out, origin, mesh_done=True), warn.finish()


def _look_dev(settings, depsgraph, overrides: dict, warn):
    """Render passes from the view layer's checkboxes and film transparency from the scene
    (overrides win)."""
    kw = {}
    if overrides.get("passes") is None:
        names = enabled_passes(depsgraph.view_layer, settings.integrator)
        left_out = [n for n in enabled_passes(depsgraph.view_layer, settings.integrator, written_only=False)
                    if n not in names]
        if left_out:
            warn(f"The '{settings.integrator}' integrator does not write the passes {_names(left_out, 3)}; "
                 "the path tracer does.")
        kw["passes"] = names
    if overrides.get("film_transparent") is None:
        kw["film_transparent"] = bool(getattr(depsgraph.scene.render, "film_transparent", False))
    return settings.replace(**kw)


def _names(names, limit=5) -> str:
    unique = list(dict.fromkeys(names))
    text = ", ".join(f"'{n}'" for n in unique[:limit])
    return text + (f" and {len(unique) - limit} more" if len(unique) > limit else "")
