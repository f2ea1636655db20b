"""HDRI scene: direct-light strategies at equal samples, and Ember vs Cycles.

    python bench/environment_compare.py [--samples 256] [--cycles]

On scenes/hdri.blend at the reference's resolution (tests/data/hdri_cycles.exr):
1. Ember with BSDF sampling only, environment sampling only and MIS, same samples and seed:
   per region (sky seen directly, sunlit ground, ground in the umbra, shadow edges, the two
   spheres; see `regions`) the mean
   per-sample variance (variance of the pixel mean x samples, averaged over pixels and RGB)
   and the relMSE against the Cycles reference.
   --resolution renders this part at another size (larger shadows: more umbra pixels).
2. --cycles: relMSE against the reference of Ember (MIS) and of one independent Cycles run
   (seed 1000, not part of the reference) at equal samples, and at equal time (Cycles gets
   the samples it renders in Ember's time, from its measured time per sample).
Both renderers use the same two cores. relMSE = mean((x - ref)^2 / (ref^2 + 0.01)).
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import ndimage

ROOT = Path(__file__).resolve().parents[1]
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))
import bpy  # noqa: E402

sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scenes"))
from _bootstrap import load_ember  # noqa: E402

load_ember()
import reference  # noqa: E402  (scenes/reference.py)
from ember.engine import camera as camera_mod  # noqa: E402
from ember.engine import imageio  # noqa: E402
from ember.engine.accel import Accel, offset_origin  # noqa: E402
from ember.engine.blender.export import export_scene  # noqa: E402
from ember.engine.lights.environment import EnvironmentMap  # noqa: E402
from ember.engine.session import RenderSession  # noqa: E402

EPS = 1e-2


def rel_mse(x, ref):
    return float(np.mean((x - ref) ** 2 / (ref**2 + EPS)))


def regions(scene):
    """Label image (H, W) by the primary hit at each pixel centre: sky, the spheres, and the
    ground split by how much of the sun its hit points see (64 directions spread over the sun's
    pixels): sunlit / umbra where the whole 5 x 5 pixel neighbourhood sees all / none of it
    (the pixel filter reaches 1.5 pixels), shadow edges otherwise."""
    s = scene.settings
    ys, xs = np.mgrid[0:s.height, 0:s.width]
    px, py = xs.ravel(), ys.ravel()
    o, d, tmax = camera_mod.generate_rays(scene.camera, s, px, py, np.full((len(px), 2), 0.5))
    accel = Accel(scene.mesh)
    hit = accel.intersect(o.astype(np.float32), d, tmax)
    names = scene.materials.names
    mat = np.where(hit.prim >= 0, scene.mesh.material[np.maximum(hit.prim, 0)], -1)
    label = np.array(["sky" if m < 0 else names[m] for m in mat], object).reshape(s.height, s.width)
    ground = (label == "Ground").ravel()
    sun_only = np.where(scene.world.image.mean(axis=2, keepdims=True) > 100, scene.world.image, 0)
    sun = EnvironmentMap(sun_only, scene.world.color, scene.world.projection, scene.world.env_from_world)
    u = (np.stack(np.mgrid[0:8, 0:8], -1).reshape(-1, 2) + 0.5) / 8
    sun_dirs = sun.sample(u).wi  # (64, 3) stratified over the sun
    p = hit.p[ground]
    origin = offset_origin(np.repeat(p, len(sun_dirs), 0), np.broadcast_to([0.0, 0.0, 1.0], (len(p) * len(sun_dirs), 3)))
    dirs = np.tile(sun_dirs, (len(p), 1))
    seen = ~accel.occluded(origin, origin + dirs * 1e30)
    fraction = np.full(len(px), np.nan)
    fraction[ground] = seen.reshape(len(p), len(sun_dirs)).mean(axis=1)
    fraction = fraction.reshape(s.height, s.width)
    g = ground.reshape(s.height, s.width)
    label[g] = "ground, edges"
    label[ndimage.binary_erosion(g & (fraction == 1), np.ones((5, 5)))] = "ground, sunlit"
    label[ndimage.binary_erosion(g & (fraction == 0), np.ones((5, 5)))] = "ground, umbra"
    return label


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blend", default=str(ROOT / "scenes" / "hdri.blend"))
    ap.add_argument("--ref", default=str(ROOT / "tests" / "data" / "hdri_cycles.exr"))
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--cycles", action="store_true", help="also render Cycles at equal samples and time")
    ap.add_argument("--resolution", help="WxH for the strategy table (default: the reference's; "
                    "another size skips the comparisons with Cycles)")
    args = ap.parse_args()
    ch, _ = imageio.read_exr(args.ref)
    ref = np.stack([ch[c] for c in "RGB"], axis=-1).astype(np.float64)
    h, w = ref.shape[:2]
    if args.resolution:
        w, h = (int(v) for v in args.resolution.lower().split("x"))
    same_size = (h, w) == ref.shape[:2]
    bpy.ops.wm.open_mainfile(filepath=args.blend)
    scene, warnings = export_scene(bpy.context.evaluated_depsgraph_get())
    for message in warnings:
        print("warning:", message)
    scene = scene.replace(settings=scene.settings.replace(width=w, height=h, border=(0, 0, w, h),
                                                          samples=args.samples, seed=1))
    label = regions(scene)
    names = [n for n in ("sky", "ground, sunlit", "ground, umbra", "ground, edges", "White", "Blue", "BlueGlossy")
             if np.any(label == n)]
    results = {}
    for strategy in ("bsdf", "light", "mis"):
        session = RenderSession(scene.replace(settings=scene.settings.replace(strategy=strategy)))
        t0 = time.perf_counter()
        session.run()
        elapsed = time.perf_counter() - t0
        mean, var = session.film.mean(), session.film.variance_of_mean()
        per_sample = (var * args.samples).mean(axis=2)
        results[strategy] = dict(mean=mean, time=elapsed, region={n: float(per_sample[label == n].mean()) for n in names},
                                 rel=rel_mse(mean, ref) if same_size else np.nan)
    print(f"\nPer-sample variance by region, {w}x{h}, {args.samples} spp, seed 1 (lower is better)")
    print(f"{'region':16s} {'pixels':>6s} " + " ".join(f"{s:>12s}" for s in ("BSDF only", "env only", "MIS")) + "   MIS / best")
    for n in names:
        v = [results[s]["region"][n] for s in ("bsdf", "light", "mis")]
        print(f"{n:16s} {int(np.sum(label == n)):6d} " + " ".join(f"{x:12.4g}" for x in v)
              + f"   {v[2] / max(min(v[:2]), 1e-300):8.3f}")
    print(f"{'relMSE vs Cycles':23s} " + " ".join(f"{results[s]['rel']:12.4g}" for s in ("bsdf", "light", "mis")))
    print(f"{'time (s)':23s} " + " ".join(f"{results[s]['time']:12.2f}" for s in ("bsdf", "light", "mis")))
    if not (args.cycles and same_size):
        return
    t_ember = results["mis"]["time"]
    bpy.ops.wm.open_mainfile(filepath=args.blend)
    sc = bpy.context.scene
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = w, h, 100
    reference.unbiased_cycles(sc, args.samples, threads=2)
    with tempfile.TemporaryDirectory(prefix="ember_cmp_") as tmp:
        reference.render_rgb(sc, os.path.join(tmp, "warm.exr"), 999)  # sync and kernels once
        img, t_cycles = reference.render_rgb(sc, os.path.join(tmp, "same.exr"), 1000)
        spp_time = max(1, int(round(args.samples * t_ember / t_cycles)))
        sc.cycles.samples = spp_time
        img_time, t_cycles_time = reference.render_rgb(sc, os.path.join(tmp, "time.exr"), 1001)
    print(f"\nAgainst the Cycles reference ({args.ref}):")
    print(f"equal samples ({args.samples} spp): Ember MIS relMSE {results['mis']['rel']:.4g} in {t_ember:.1f} s; "
          f"Cycles relMSE {rel_mse(img, ref):.4g} in {t_cycles:.1f} s")
    print(f"equal time ({t_ember:.1f} s): Ember {args.samples} spp relMSE {results['mis']['rel']:.4g}; "
          f"Cycles {spp_time} spp relMSE {rel_mse(img_time, ref):.4g} in {t_cycles_time:.1f} s")


if __name__ == "__main__":
    main()
