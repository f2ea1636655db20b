"""Bit-for-bit fingerprints of Ember's images: every scene in scenes/ through every integrator.

    ./dev python bench/image_hashes.py --out /tmp/before.json          # record
    ./dev python bench/image_hashes.py --out /tmp/after.json --compare /tmp/before.json

A refactoring that must not change a single pixel is checked with this: each case exports a
.blend through bpy (as F12 does), renders it in this process (small images, few samples,
fewer photons) and hashes the film's sums, sample counts and render passes. Two runs of the
same code give the same hashes; a change of one bit in one pixel changes its case's hash.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SIZE = 32
BENCH = ("cornell_box", "cornell_glossy", "veach_mis", "hdri", "caustic", "caustic_point", "interior",
         "hard_tiny_light", "hard_light_near_wall", "hard_degenerate", "hard_phong", "hard_far_origin",
         "hard_grazing")
INTEGRATORS = ("path", "photon", "ppm", "icache", "path_caustic", "auto")
FEW_PHOTONS = dict(photons=20_000, caustic_photons=40_000)
# (label, scene.ember settings) beyond the integrators' defaults: each a path through code
# the defaults do not reach.
VARIANTS = (
    ("path_light", dict(integrator="path", strategy="light")),
    ("path_bsdf", dict(integrator="path", strategy="bsdf")),
    ("path_random", dict(integrator="path", pattern="random")),
    ("path_adaptive", dict(integrator="path", adaptive=True, samples=32, adaptive_min_samples=4)),
    ("path_limits", dict(integrator="path", diffuse_bounces=2, glossy_bounces=3, transmission_bounces=4,
                         transparent_bounces=2, clamp_direct=2.0, clamp_indirect=1.0, filter_glossy=1.0,
                         caustics_reflective=False, caustics_refractive=False)),
    ("photon_views", dict(integrator="photon", photon_kernel="cone", radiance_photons=False, gather_rays=4)),
    ("icache_photon", dict(integrator="icache", icache_gather="photon", icache_weight="tabellion",
                           icache_gradients=False)),
    ("icache_radiance", dict(integrator="icache", icache_radiance=True, icache_radiance_order=5)),
)
PASSES = ("Diffuse Direct", "Diffuse Indirect", "Diffuse Color", "Glossy Direct", "Glossy Indirect",
          "Glossy Color", "Transmission Direct", "Transmission Indirect", "Emission", "Environment",
          "Depth", "Normal", "Denoising Albedo")


def cases(scene_names):
    for name in scene_names:
        bench = name in BENCH
        for integ in (INTEGRATORS if bench else ("path", "auto")):
            yield name, integ, dict(integrator=integ)
        if name in ("cornell_glossy", "veach_mis", "caustic", "interior", "lp_transmission", "vis_transmission"):
            for label, settings in VARIANTS:
                yield name, label, dict(settings)
        if name in ("cornell_glossy", "lp_glossy", "hdri"):
            yield name, "path_passes", dict(integrator="path", passes=PASSES, film_transparent=True)
            yield name, "photon_passes", dict(integrator="photon", passes=PASSES + ("Caustics",))


def digest(film) -> str:
    h = hashlib.sha1()
    for a in (film.sum, film.count):
        h.update(np.ascontiguousarray(a).tobytes())
    for name in sorted(getattr(film, "pass_sum", {})):
        h.update(name.encode())
        h.update(np.ascontiguousarray(film.pass_sum[name]).tobytes())
    if film.overlay is not None:  # progressive photon mapping's photon term
        h.update(np.ascontiguousarray(film.overlay).tobytes())
    return h.hexdigest()


def render_case(path: pathlib.Path, settings: dict, samples: int) -> str:
    import bpy
    from ember.engine.blender.export import export_scene
    from ember.engine.session import RenderSession

    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
    scene = bpy.context.scene
    scene.render.engine = "EMBER"
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    scene.render.use_border = False
    overrides = dict(width=SIZE, height=SIZE, border=(0, 0, SIZE, SIZE), threads=1, samples=samples, seed=3)
    overrides.update(FEW_PHOTONS)
    overrides.update(settings)
    sc, _ = export_scene(bpy.context.evaluated_depsgraph_get(), overrides=overrides)
    session = RenderSession(sc)
    session.run()
    return digest(session.film)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="JSON of case -> hash")
    ap.add_argument("--compare", help="an earlier --out: print the cases that differ")
    ap.add_argument("--scenes", help="comma-separated scene names (default: every .blend in scenes/)")
    ap.add_argument("--samples", type=int, default=4)
    args = ap.parse_args(argv)
    from _bootstrap import load_ember
    load_ember().register()
    names = (args.scenes.split(",") if args.scenes else
             sorted(p.stem for p in (ROOT / "scenes").glob("*.blend")))
    out = {}
    t0 = time.perf_counter()
    for name, label, settings in cases(names):
        key = f"{name}/{label}"
        try:
            out[key] = render_case(ROOT / "scenes" / f"{name}.blend", settings, settings.pop("samples", args.samples))
        except Exception as exc:  # a case the scene refuses is part of the fingerprint too
            out[key] = f"error: {type(exc).__name__}: {exc}"
        print(f"{time.perf_counter() - t0:7.1f} s  {key}: {out[key]}", flush=True)
    pathlib.Path(args.out).write_text(json.dumps(out, indent=1, sort_keys=True))
    if args.compare:
        before = json.loads(pathlib.Path(args.compare).read_text())
        differ = sorted(k for k in set(before) | set(out) if before.get(k) != out.get(k))
        print(f"{len(out) - len(differ)} of {len(set(before) | set(out))} cases the same; differ: {differ}")
        return 1 if differ else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
