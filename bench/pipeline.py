"""Pipeline overheads: per-frame cost of an animation with and without persistent
data, and Dask against a local render of the same work.

    ./dev python bench/pipeline.py                 # both studies, ~2 min on 2 cores
    ./dev python bench/pipeline.py --frames 6 --triangles 400000 --no-dask

Per-frame overhead: an animation whose camera moves (so every frame is a new image, but the
mesh, lights and world stay) rendered through bpy.ops.render.render with two worker
processes, few samples so that the fixed costs show; the same frames with Blender's
Persistent Data off (every frame starts its workers and builds Embree) and on. Reports the median wall time of frames 2..N and the builds they made.

Dask overhead: the same frames with --dask-samples samples, by `render.py --frames` on this
machine (two worker processes, persistent data) and by `render.py --scheduler local:2` (a
LocalCluster of two single-threaded workers, one render.py per task), whole frames and
frames split in two sample ranges; wall time of the whole command each.
"""
from __future__ import annotations

import argparse
import math
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def build_scene(path: pathlib.Path, triangles: int, frames: int) -> None:
    import bpy
    import mathutils

    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 64, 64, 100
    n = max(int(math.sqrt(triangles / 2)), 2)  # an n x n grid of quads, two triangles each
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=n, y_subdivisions=n, size=8)
    ld = bpy.data.lights.new("lamp", 'POINT')
    ld.energy = 800.0
    lo = bpy.data.objects.new("lamp", ld)
    lo.location = (1, -1, 3)
    sc.collection.objects.link(lo)
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    sc.collection.objects.link(cam)
    sc.camera = cam
    for f in range(1, frames + 1):
        cam.location = (0.1 * f, -5, 4)
        cam.rotation_euler = (mathutils.Vector((0, 0, 0)) - cam.location).to_track_quat('-Z', 'Y').to_euler()
        cam.keyframe_insert("location", frame=f)
        cam.keyframe_insert("rotation_euler", frame=f)
    sc.frame_start, sc.frame_end = 1, frames
    bpy.ops.wm.save_as_mainfile(filepath=str(path))


def per_frame(blend: pathlib.Path, frames: int, persistent: bool, samples: int) -> list[tuple[float, dict]]:
    import bpy
    from _bootstrap import load_ember

    ember = load_ember()
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    ember.register()
    from ember.engine.blender import final

    sc = bpy.context.scene
    sc.render.engine = 'EMBER'
    sc.ember.samples, sc.ember.batch_size = samples, 4096
    sc.render.threads_mode, sc.render.threads = 'FIXED', 2
    sc.render.use_persistent_data = persistent

    class Listener:
        stats = None

        def on_layer_done(self, layer, stats, image, border):
            self.stats = stats

    out = []
    listener = Listener()
    final.listeners.append(listener)
    try:
        for f in range(1, frames + 1):
            sc.frame_set(f)
            t0 = time.perf_counter()
            bpy.ops.render.render(write_still=False)
            out.append((time.perf_counter() - t0, dict(listener.stats.builds), listener.stats.elapsed))
    finally:
        final.listeners.remove(listener)
    from ember.engine.parallel import workers
    workers.release_kept()
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--triangles", type=int, default=200_000)
    ap.add_argument("--samples", type=int, default=4)
    ap.add_argument("--dask-samples", type=int, default=64)
    ap.add_argument("--no-dask", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        blend = pathlib.Path(tmp) / "frames.blend"
        build_scene(blend, args.triangles, args.frames)
        print(f"{args.frames} frames, 64x64, {args.samples} samples, ~{args.triangles} triangles, 2 worker processes")
        for persistent in (False, True):
            rows = per_frame(blend, args.frames, persistent, args.samples)
            later = [t for t, _, _ in rows[1:]]
            sampling = [e for _, _, e in rows[1:]]
            print(f"persistent data {'on ' if persistent else 'off'}: frame 1 {rows[0][0]:.2f} s, frames 2..N "
                  f"median {statistics.median(later):.2f} s (of which session run {statistics.median(sampling):.2f} s), "
                  f"builds of frame 2: {rows[1][1]}")
        if not args.no_dask:
            dask_overhead(blend, args.frames, args.dask_samples)


def dask_overhead(blend: pathlib.Path, frames: int, samples: int) -> None:
    base = [sys.executable, str(ROOT / "render.py"), str(blend), "--frames", f"1-{frames}", "--samples",
            str(samples), "--no-progress"]
    runs = {"local, 2 worker processes": ["--threads", "2"],
            "Dask local:2, whole frames": ["--scheduler", "local:2"],
            f"Dask local:2, {samples // 2}-sample ranges": ["--scheduler", "local:2", "--chunk-samples", str(samples // 2)]}
    for label, extra in runs.items():
        out = blend.parent / f"{label.split(',')[0].split()[0].lower()}_{len(extra)}_#.exr"
        t0 = time.perf_counter()
        proc = subprocess.run(base + extra + ["-o", str(out)], capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr[-2000:]
        print(f"{label}: {frames} frames x {samples} samples in {time.perf_counter() - t0:.2f} s")


if __name__ == "__main__":
    main()
