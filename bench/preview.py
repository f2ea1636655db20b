"""Material-preview cost: a scene shaped like Blender's material preview (a sphere
on a checker floor under two area lights, 128x128 and the 32x32 icon), rendered through the
preview path of engine/blender/final.py (final.PREVIEW_OVERRIDES: in-process, few samples).

    ./dev python bench/preview.py
"""
from __future__ import annotations

import json
import os
import pathlib
import sys
import time
import types

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from _bootstrap import load_ember  # noqa: E402

load_ember()
import bpy  # noqa: E402

import ember  # noqa: E402
from ember.engine.blender import final  # noqa: E402


def preview_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = "EMBER"
    bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=1.0, location=(0, 0, 1))
    bpy.ops.object.shade_smooth()
    mat = bpy.data.materials.new("preview")
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.8, 0.3, 0.2, 1)
    bsdf.inputs["Roughness"].default_value = 0.3
    bpy.context.object.data.materials.append(mat)
    bpy.ops.mesh.primitive_plane_add(size=20)
    for loc, energy in (((3, -3, 5), 500.0), ((-4, -2, 3), 200.0)):
        ld = bpy.data.lights.new("area", "AREA")
        ld.energy, ld.size = energy, 2.0
        ob = bpy.data.objects.new("area", ld)
        ob.location = loc
        sc.collection.objects.link(ob)
        ob.rotation_euler = (ob.location.to_track_quat('Z', 'Y')).to_euler()
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    cam.location = (0, -6, 2.5)
    cam.rotation_euler = (1.2, 0, 0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    sc.world = bpy.data.worlds.new("w")
    sc.world.color = (0.05, 0.05, 0.05)
    return sc


class _PreviewEngine:
    """What final.render uses of a RenderEngine, flagged as a preview render."""
    is_preview = True

    def __init__(self, size):
        self.resolution_x = self.resolution_y = size

    def test_break(self):
        return False

    def begin_result(self, x, y, w, h, layer=""):
        rect = types.SimpleNamespace(foreach_set=lambda a: None)
        combined = types.SimpleNamespace(rect=rect)
        return types.SimpleNamespace(resolution_x=w, resolution_y=h,
                                     layers=[types.SimpleNamespace(passes={"Combined": combined})])

    def update_result(self, r): pass
    def end_result(self, r, cancel=False): pass
    def update_stats(self, a, b): pass
    def update_progress(self, v): pass
    def report(self, kind, msg): print(kind, msg)
    def error_set(self, msg): print("error", msg)


def main():
    ember.register()
    sc = preview_scene()
    rows = []
    for size in (128, 32):
        sc.render.resolution_x = sc.render.resolution_y = size
        times = []
        for _ in range(3):
            depsgraph = bpy.context.evaluated_depsgraph_get()
            t0 = time.perf_counter()
            stats = final.render(_PreviewEngine(size), depsgraph)
            times.append(time.perf_counter() - t0)
        rows.append(dict(size=size, samples=stats.samples, seconds=sorted(times), render_s=stats.elapsed))
        print(json.dumps(rows[-1]), flush=True)
    rows.append(dict(load_average=os.getloadavg()))
    out = ROOT / "bench" / "results" / "viewport"
    out.mkdir(parents=True, exist_ok=True)
    (out / "preview.json").write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
