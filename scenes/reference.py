"""Render a Cycles reference for a .blend: mean and variance of independent runs, as EXR.

    python scenes/reference.py scenes/cornell_box.blend --out tests/data/cornell_box_cycles.exr \
        --resolution 64x64 --runs 16 --samples 1024

Cycles on the CPU, unbiased settings: denoising, adaptive sampling and clamping off, light
threshold 0, filter glossy 0, caustics on, every bounce limit 64, the scene's own pixel
filter, `use_animated_seed` off and seed = run index (plus --seed-offset) per run.
--keep-light-paths keeps the file's own bounce limits, caustics and clamping instead (the
light-path test scenes of scenes/build_light_paths.py).

Output channels (float32, rows top-down, row 0 = top of the image):
  R, G, B            mean over runs
  var.R, var.G, var.B  variance of that mean = sample variance across runs (ddof 1) / runs
Header: samples (per run), runs, time_s (total render time), blender_version, resolution,
settings (JSON of the Cycles settings used), scene file.

Pixels come from rendering each run to a float 32-bit OPEN_EXR (write_still), read back with
engine.imageio. Blender writes EXR scene-linear (no view transform, no display curve);
scenes/probe_cycles_conventions.py checks it on an emitter of known radiance.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))
import bpy  # noqa: E402

sys.path.insert(0, ROOT)
from _bootstrap import load_ember  # noqa: E402

load_ember()
from ember.engine import imageio  # noqa: E402

BOUNCES = 64


def unbiased_cycles(scene, samples: int, threads: int = 0, keep_light_paths: bool = False) -> dict:
    """Set Cycles to an unbiased CPU configuration; return the settings as a dict.
    keep_light_paths: leave the file's bounce limits, caustics and clamping as they are."""
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = samples
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.light_sampling_threshold = 0.0
    c.blur_glossy = 0.0  # "Filter Glossy"
    if not keep_light_paths:
        c.sample_clamp_direct = 0.0
        c.sample_clamp_indirect = 0.0
        c.caustics_reflective = True
        c.caustics_refractive = True
        c.max_bounces = BOUNCES
        c.diffuse_bounces = BOUNCES
        c.glossy_bounces = BOUNCES
        c.transmission_bounces = BOUNCES
        c.transparent_max_bounces = BOUNCES
        c.volume_bounces = BOUNCES
    c.use_animated_seed = False
    scene.render.use_persistent_data = True  # sync the scene once for all runs
    scene.render.threads_mode = "FIXED" if threads else "AUTO"
    if threads:
        scene.render.threads = threads
    scene.render.film_transparent = False
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    return {
        "device": c.device, "samples": c.samples, "adaptive_sampling": c.use_adaptive_sampling,
        "denoising": c.use_denoising, "sample_clamp_direct": c.sample_clamp_direct,
        "sample_clamp_indirect": c.sample_clamp_indirect,
        "light_sampling_threshold": c.light_sampling_threshold, "filter_glossy": c.blur_glossy,
        "caustics_reflective": c.caustics_reflective,
        "caustics_refractive": c.caustics_refractive, "max_bounces": c.max_bounces,
        "diffuse_bounces": c.diffuse_bounces, "glossy_bounces": c.glossy_bounces,
        "transmission_bounces": c.transmission_bounces,
        "transparent_max_bounces": c.transparent_max_bounces,
        "volume_bounces": c.volume_bounces, "use_light_tree": getattr(c, "use_light_tree", None),
        "sampling_pattern": getattr(c, "sampling_pattern", None),
        "pixel_filter_type": c.pixel_filter_type, "filter_width": c.filter_width,
        "use_animated_seed": c.use_animated_seed,
        "threads": scene.render.threads if threads else "AUTO",
    }


def exr_output(scene, path: str):
    s = scene.render.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "IMAGE"
    s.file_format = "OPEN_EXR"
    s.color_depth = "32"
    s.color_mode = "RGBA"
    s.exr_codec = "ZIP"
    scene.render.filepath = path
    scene.render.use_file_extension = False


def render_rgb(scene, path: str, seed: int) -> tuple[np.ndarray, float]:
    """One Cycles render with `seed` to an EXR at `path`; returns ((H,W,3) top-down, seconds)."""
    scene.cycles.seed = seed
    exr_output(scene, path)
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    dt = time.perf_counter() - t0
    return imageio.read_rgb(path).astype(np.float64), dt


def main(argv=None):
    if argv is None:
        argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("blend")
    ap.add_argument("--out", required=True, help="output .exr")
    ap.add_argument("--resolution", default=None, help="WxH (default: the file's, at 100%%)")
    ap.add_argument("--runs", type=int, default=16)
    ap.add_argument("--samples", type=int, default=1024, help="samples per pixel per run")
    ap.add_argument("--threads", type=int, default=0, help="0 = Blender's automatic count")
    ap.add_argument("--seed-offset", type=int, default=0, help="run i uses seed offset + i")
    ap.add_argument("--keep-light-paths", action="store_true",
                    help="keep the file's bounce limits, caustics and clamping")
    args = ap.parse_args(argv)
    if args.runs < 2:
        ap.error("--runs must be at least 2 (the variance needs it)")

    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(args.blend))
    scene = bpy.context.scene
    if args.resolution:
        w, h = (int(v) for v in args.resolution.lower().split("x"))
        scene.render.resolution_x, scene.render.resolution_y = w, h
    scene.render.resolution_percentage = 100
    settings = unbiased_cycles(scene, args.samples, args.threads, args.keep_light_paths)
    W, H = scene.render.resolution_x, scene.render.resolution_y

    total = np.zeros((H, W, 3))
    total_sq = np.zeros((H, W, 3))
    times = []
    with tempfile.TemporaryDirectory(prefix="ember_ref_") as tmp:
        for i in range(args.runs):
            img, dt = render_rgb(scene, os.path.join(tmp, f"run{i}.exr"), args.seed_offset + i)
            if img.shape != (H, W, 3):
                raise RuntimeError(f"render has shape {img.shape}, expected {(H, W, 3)}")
            total += img
            total_sq += img * img
            times.append(dt)
            print(f"run {i + 1}/{args.runs}: seed {args.seed_offset + i}, {dt:.1f} s, "
                  f"mean {img.mean():.5f}", flush=True)
    n = args.runs
    mean = total / n
    var_runs = np.maximum(total_sq - n * mean * mean, 0.0) / (n - 1)  # sample variance
    var_mean = var_runs / n
    header = {
        "renderer": "Cycles",
        "blender_version": bpy.app.version_string,
        "scene_file": os.path.basename(args.blend),
        "samples": args.samples,
        "runs": n,
        "total_samples": args.samples * n,
        "time_s": float(sum(times)),
        "resolution": f"{W}x{H}",
        "seeds": f"{args.seed_offset}..{args.seed_offset + n - 1}",
        "settings": json.dumps(settings, sort_keys=True),
        "rows": "top-down",
        "variance": "var.* = sample variance across runs (ddof 1) / runs",
    }
    chans = {c: mean[:, :, i] for i, c in enumerate("RGB")}
    chans.update({f"var.{c}": var_mean[:, :, i] for i, c in enumerate("RGB")})
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    imageio.write_exr(args.out, chans, header)
    print(f"wrote {args.out}: {W}x{H}, {n} runs x {args.samples} spp, {sum(times):.1f} s total, "
          f"mean {mean.mean():.5f}, median rel. std. error "
          f"{np.median(np.sqrt(var_mean) / np.maximum(mean, 1e-8)):.4f}")


if __name__ == "__main__":
    main()
