"""The viewport through Blender without a GPU (engine/blender/viewport.py): depsgraph updates
sort into the right parts, each edit re-exports exactly its part, a view's camera matches the
scene camera's export, and the driver renders, restarts on change and stops cleanly, up to
the buffer it would hand to the GPU."""
from __future__ import annotations

import pathlib
import time
import types

import numpy as np
import pytest

pytestmark = pytest.mark.blender
bpy = pytest.importorskip("bpy")

import ember  # noqa: E402
from ember.engine.blender import viewport as bviewport  # noqa: E402
from ember.engine.blender import export_mesh  # noqa: E402
from ember.engine.blender.export import export_scene  # noqa: E402
from ember.engine import viewport as core_viewport  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
KEEPS_MESHES = []  # keeps_meshes() of each depsgraph update the cornell fixture saw


@pytest.fixture(scope="module", autouse=True)
def addon():
    ember.register()
    yield
    ember.unregister()


@pytest.fixture
def cornell():
    bpy.ops.wm.open_mainfile(filepath=str(ROOT / "scenes" / "cornell_box.blend"), load_ui=False)
    sc = bpy.context.scene
    sc.render.engine = "EMBER"
    sc.ember.preview_samples = 4
    light = bpy.data.lights.new("lamp", "POINT")
    light.energy = 10.0
    lamp = bpy.data.objects.new("lamp", light)
    lamp.location = (0.0, 0.0, 1.5)
    sc.collection.objects.link(lamp)
    bpy.context.view_layer.update()
    captured = []

    def handler(scene, depsgraph):
        captured.append(bviewport.classify(depsgraph.updates))
        KEEPS_MESHES.append(bviewport.keeps_meshes(depsgraph.updates))

    bpy.app.handlers.depsgraph_update_post.append(handler)
    yield sc, captured
    bpy.app.handlers.depsgraph_update_post.remove(handler)


def _diffuse_input(mat):
    node = next(n for n in mat.node_tree.nodes if n.type in ("BSDF_PRINCIPLED", "BSDF_DIFFUSE"))
    return node.inputs[0]


EDITS = {
    "transform": (lambda sc: setattr(bpy.data.objects["TallBlock"], "location", (0.1, 0.2, 0.0)), {"geometry"}),
    "geometry": (lambda sc: (bpy.data.objects["TallBlock"].data.vertices[0].co.__setitem__(2, 0.1),
                             bpy.data.objects["TallBlock"].data.update()), {"geometry"}),
    "material": (lambda sc: setattr(_diffuse_input(bpy.data.materials["Red"]), "default_value", (0.1, 0.9, 0.1, 1)),
                 {"materials"}),
    "light": (lambda sc: setattr(bpy.data.lights["lamp"], "energy", 20.0), {"lights"}),
    "light moved": (lambda sc: setattr(bpy.data.objects["lamp"], "location", (0.1, 0.0, 1.5)), {"lights"}),
    "world": (lambda sc: setattr(sc.world, "color", (0.3, 0.2, 0.1)), {"world"}),
    "camera": (lambda sc: setattr(sc.camera, "location", (0.0, -3.5, 1.0)), {"camera"}),
    "settings": (lambda sc: setattr(sc.render, "film_transparent", True), {"settings"}),
}


@pytest.mark.parametrize("edit", list(EDITS))
def test_an_edit_reexports_exactly_its_part(cornell, edit, monkeypatch):
    """Each kind of edit classifies to its part, LiveExport re-exports that part alone, and
    the updated scene equals a full export of the edited scene in that part."""
    sc, captured = cornell
    depsgraph = bpy.context.evaluated_depsgraph_get()
    live = bviewport.LiveExport(depsgraph, dict(width=32, height=32, passes=()))
    live.calls.clear()
    fn, want = EDITS[edit]
    captured.clear()
    KEEPS_MESHES.clear()
    fn(sc)
    bpy.context.view_layer.update()
    parts = set().union(*captured)
    assert parts == want, (edit, captured)
    keep = all(KEEPS_MESHES)
    assert keep == (edit != "geometry")  # a moved object's mesh is not extracted again
    extracted = []
    monkeypatch.setattr(export_mesh, "extract_mesh",
                        lambda ob, real=export_mesh.extract_mesh: extracted.append(ob.name) or real(ob))
    live.update(depsgraph, parts, keep)
    assert set(live.calls) == want and all(n == 1 for n in live.calls.values())
    if edit == "transform":
        assert extracted == []
    elif edit == "geometry":
        assert len(extracted) >= 2  # every mesh again (the edited one among them)
    full, _ = export_scene(bpy.context.evaluated_depsgraph_get(), overrides=dict(width=32, height=32, passes=()))
    part = {"geometry": "mesh", "materials": "materials", "lights": "lights", "world": "world",
            "camera": "camera", "settings": "settings"}[next(iter(want))]
    mine, theirs = getattr(live.scene, part), getattr(full, part)
    for field in mine.__dataclass_fields__:
        a, b = getattr(mine, field), getattr(theirs, field)
        if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
            np.testing.assert_allclose(np.asarray(a, float), np.asarray(b, float), rtol=1e-6, atol=1e-9,
                                       err_msg=f"{part}.{field}")
        else:
            assert a == b, (part, field)


def test_view_camera_matches_the_scene_camera(cornell):
    """The projection Blender draws a camera view with gives Ember's export of that camera."""
    sc, _ = cornell
    sc.render.resolution_x, sc.render.resolution_y = 48, 32
    depsgraph = bpy.context.evaluated_depsgraph_get()
    scene, _ = export_scene(depsgraph)
    cam = sc.camera.evaluated_get(depsgraph)
    proj = cam.calc_matrix_camera(depsgraph, x=48, y=32)
    camera = bviewport.view_camera(cam.matrix_world.inverted(), proj, cam.data.clip_start, cam.data.clip_end)
    np.testing.assert_allclose(camera.window, scene.camera.window, rtol=1e-5)
    m = np.array(camera.world_from_camera)
    m[:3, 3] -= np.asarray(scene.settings.origin)
    np.testing.assert_allclose(m, scene.camera.world_from_camera, atol=1e-5)


class _Engine:
    def __init__(self):
        self.redraws, self.stats = 0, []

    def get_preview_pixel_size(self, scene):
        return 2

    def tag_redraw(self):
        self.redraws += 1

    def update_stats(self, a, b):
        self.stats.append(b)


def test_driver_renders_restarts_and_stops(cornell, monkeypatch):
    """view_update + view_draw with a fake region: the first image comes coarse, the session
    refines to the viewport samples, a light edit re-renders without rebuilding Embree, a view
    change restarts with the new camera; the drawn buffer is the film's (bottom-up, clamped)."""
    sc, _ = cornell
    drawn = []
    monkeypatch.setattr(bviewport, "draw", lambda engine, scene, latest: drawn.append(latest))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    cam = sc.camera.evaluated_get(depsgraph)
    region = types.SimpleNamespace(width=40, height=30)
    r3d = types.SimpleNamespace(view_matrix=cam.matrix_world.inverted(),
                                window_matrix=cam.calc_matrix_camera(depsgraph, x=40, y=30))
    space = types.SimpleNamespace(clip_start=0.1, clip_end=100.0)
    context = types.SimpleNamespace(region=region, region_data=r3d, space_data=space, scene=sc)
    engine = _Engine()
    driver = bviewport.ViewportDriver()

    def settle(after=0):
        for _ in range(3000):
            driver.view_draw(engine, context, depsgraph)
            if drawn and drawn[-1][0] > after and drawn[-1][4] >= 4 and not driver.session.busy():
                return drawn[-1]
            time.sleep(0.01)
        raise AssertionError(driver.session.error)

    try:
        driver.view_update(engine, context, depsgraph)
        first = settle()
        assert first[2:4] == (40, 30) and driver.session.stats[0]["first_image"] is not None
        assert engine.redraws > 0
        buf = first[1].reshape(30, 40, 4)
        assert buf.dtype == np.float32 and np.isfinite(buf).all() and buf[..., :3].max() > 0
        # Blender calls view_update while the depsgraph holds its updates: from a handler here.
        def on_update(scene, dg):
            driver.view_update(engine, context, dg)

        bpy.app.handlers.depsgraph_update_post.append(on_update)
        try:
            bpy.data.lights["lamp"].energy = 500.0
            bpy.context.view_layer.update()
        finally:
            bpy.app.handlers.depsgraph_update_post.remove(on_update)
        assert driver.timings[-1][0] == ("lights",)
        second = settle(first[0])
        assert driver.session.stats[-1]["builds"]["embree"] == 0 and second[0] > first[0]
        assert second[1].reshape(30, 40, 4)[..., :3].sum() > buf[..., :3].sum()
        r3d.view_matrix = r3d.view_matrix.copy()
        r3d.view_matrix[0][3] += 0.2  # the user pans the view
        third = settle(second[0])
        assert third[0] > second[0] and not np.array_equal(third[1], second[1])
    finally:
        driver.free()
    assert driver.session is None
