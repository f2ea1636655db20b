"""Viewport speed: time to the first image and to N samples, export and update
times, on the Cornell box and on the Cornell box with a ~1M-triangle sphere, through the
same driver Blender calls (engine/blender/viewport.py) with a fake region and no GPU.

    ./dev python bench/viewport.py [--size 480x270] [--samples 16] [--out bench/results/viewport]

Times are wall seconds from the call that started the render (view_update or the view
change) to the first buffer handed to drawing and to the buffer with N samples. `restart`
is an edit made while a render is running (at 4 samples): `restart_stopped_s` is the time
from the update until the running render has stopped (its items in the workers cancelled),
the cancel latency. The 1-minute load average is recorded before and after each scene: the
machine is shared.
"""
from __future__ import annotations

import argparse
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
from ember.engine.blender import viewport as bviewport  # noqa: E402


class _Engine:
    def get_preview_pixel_size(self, scene):
        return 2

    def tag_redraw(self):
        pass

    def update_stats(self, a, b):
        pass


def _context(sc, depsgraph, width, height):
    cam = sc.camera.evaluated_get(depsgraph)
    r3d = types.SimpleNamespace(view_matrix=cam.matrix_world.inverted(),
                                window_matrix=cam.calc_matrix_camera(depsgraph, x=width, y=height))
    return types.SimpleNamespace(region=types.SimpleNamespace(width=width, height=height), region_data=r3d,
                                 space_data=types.SimpleNamespace(clip_start=0.01, clip_end=100.0), scene=sc)


def _run_until(driver, engine, context, depsgraph, samples, t0, after=0, fresh=None):
    """(time to first image, time to `samples`) after t0, drawing as Blender would; fresh:
    the number of renders started before t0 (only a later render's images count)."""
    first = None
    drawn = []
    bviewport.draw = lambda engine, scene, latest: drawn.append(latest)
    while True:
        driver.view_draw(engine, context, depsgraph)
        new = fresh is None or (len(driver.session.stats) > fresh and driver.session.stats[-1]["first_image"])
        if drawn and drawn[-1][0] > after and new:
            now = time.perf_counter() - t0
            first = first if first is not None else now
            if drawn[-1][4] >= samples:
                return first, now, drawn[-1][0]
        if driver.session.error:
            raise RuntimeError(driver.session.error)
        time.sleep(0.005)


def measure(label, sc, width, height, samples):
    sc.ember.preview_samples = samples
    engine, driver = _Engine(), bviewport.ViewportDriver()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    context = _context(sc, depsgraph, width, height)
    out = dict(scene=label, size=f"{width}x{height}", samples=samples)
    try:
        t0 = time.perf_counter()
        driver.view_update(engine, context, depsgraph)
        out["export_s"] = time.perf_counter() - t0
        first, full, version = _run_until(driver, engine, context, depsgraph, samples, t0)
        out.update(first_image_s=first, samples_s=full, builds=driver.session.stats[-1]["builds"],
                   triangles=int(driver.export.scene.mesh.n_triangles))
        # Edits through the depsgraph, as Blender delivers them to view_update.
        def edit(fn):
            def on_update(scene, dg):
                driver.view_update(engine, context, dg)
            bpy.app.handlers.depsgraph_update_post.append(on_update)
            t = time.perf_counter()
            try:
                fn()
                bpy.context.view_layer.update()
            finally:
                bpy.app.handlers.depsgraph_update_post.remove(on_update)
            return t

        for name, fn in (("light", lambda: setattr(bpy.data.lights["bench_lamp"], "energy", 40.0)),
                         ("material", lambda: setattr(bpy.data.materials["Red"].node_tree.nodes["Diffuse BSDF"]
                                                      .inputs[0], "default_value", (0.2, 0.8, 0.2, 1))),
                         ("transform", lambda: setattr(bpy.data.objects["TallBlock"], "location", (0.05, 0, 0)))):
            t = edit(fn)
            out[f"update_{name}_s"] = driver.timings[-1][1]
            first, full, version = _run_until(driver, engine, context, depsgraph, samples, t, version)
            out[f"{name}_first_image_s"], out[f"{name}_samples_s"] = first, full
            out[f"{name}_builds"] = driver.session.stats[-1]["builds"]
        t = time.perf_counter()
        context.region_data.view_matrix = context.region_data.view_matrix.copy()
        context.region_data.view_matrix[0][3] += 0.05
        first, full, version = _run_until(driver, engine, context, depsgraph, samples, t, version)
        out["view_first_image_s"], out["view_samples_s"] = first, full
        out["view_builds"] = driver.session.stats[-1]["builds"]
        # An edit while the render runs: how soon it stops, and the new first image.
        sc.ember.preview_samples = 1000
        t = edit(lambda: setattr(bpy.data.lights["bench_lamp"], "energy", 30.0))
        _run_until(driver, engine, context, depsgraph, 4, t, version)
        n = len(driver.session.stats)
        t = edit(lambda: setattr(bpy.data.lights["bench_lamp"], "energy", 35.0))
        first, _, version = _run_until(driver, engine, context, depsgraph, 1, t, fresh=n)
        out["restart_first_image_s"] = first
        out["restart_stopped_s"] = driver.session.stats[-1]["stopped"]
        out["processes"] = driver.session.stats[-1].get("processes", 0)
        out["workers_started"] = sum(r["builds"].get("workers", 0) for r in driver.session.stats)
    finally:
        driver.free()
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", default="480x270")
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "viewport"))
    args = ap.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    ember.register()
    rows = []
    for label, sphere in (("cornell_box", False), ("cornell_box + 1M-triangle sphere", True)):
        bpy.ops.wm.open_mainfile(filepath=str(ROOT / "scenes" / "cornell_box.blend"), load_ui=False)
        sc = bpy.context.scene
        sc.render.engine = "EMBER"
        light = bpy.data.lights.new("bench_lamp", "POINT")
        light.energy = 20.0
        lamp = bpy.data.objects.new("bench_lamp", light)
        lamp.location = (0.3, -0.3, 1.5)
        sc.collection.objects.link(lamp)
        if sphere:
            bpy.ops.mesh.primitive_uv_sphere_add(segments=1000, ring_count=500, radius=0.25, location=(0.3, -0.2, 1.0))
        bpy.context.view_layer.update()
        load = os.getloadavg()[0]
        rows.append(measure(label, sc, width, height, args.samples))
        rows[-1]["load_average_1min"] = (load, os.getloadavg()[0])
        print(json.dumps(rows[-1]), flush=True)
    rows.append(dict(load_average=os.getloadavg()))
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
