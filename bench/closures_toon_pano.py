"""Translucent, Toon (Diffuse, Glossy), Holdout and every panoramic camera against Cycles 5.0
on one-feature scenes (the tests' scenes: tests/test_toon_translucent.py, test_holdout.py,
test_panorama.py), written to bench/results/closures/toon_pano.md.

    ./dev python bench/closures_toon_pano.py [--size 48] [--samples 64] [--runs 4] [--only NAME]

Per scene: a Cycles reference (runs x 16 x samples per pixel); bias = Ember's mean over the
image (runs x 4 x samples) / the reference's - 1, with its standard error from the runs (the
Holdout scene: colour and alpha apart); relMSE at equal samples (`samples`) of Ember and of
Cycles against the reference, less the reference's own expected relMSE (bench/metrics.py),
each the mean over `runs` seeds, and their ratio. Targets: |bias| <= 1 %, ratio <= 1.5.
"""
from __future__ import annotations

import argparse
import pathlib
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

import _bootstrap  # noqa: E402

_bootstrap.load_ember()
from metrics import EPS  # noqa: E402
from cycles_renders import rgba_cycles, rgba_ember  # noqa: E402
from cycles_scenes import addon  # noqa: E402
import test_holdout  # noqa: E402
import test_panorama  # noqa: E402
import test_toon_translucent  # noqa: E402

OUT = ROOT / "bench" / "results" / "closures" / "toon_pano.md"


def _scenes(size):
    """name -> builder of the bpy scene at `size` pixels across."""
    def sized(build):
        def made():
            sc = build()
            ratio = sc.render.resolution_y / sc.render.resolution_x
            sc.render.resolution_x, sc.render.resolution_y = size, max(1, int(round(size * ratio)))
            return sc
        return made

    tt = test_toon_translucent
    out = {"translucent leaf": sized(tt.leaf_scene),
           "toon diffuse": sized(lambda: tt.toon_scene(("DIFFUSE",))),
           "toon glossy": sized(lambda: tt.toon_scene(("GLOSSY",))),
           "holdout (opaque film)": sized(lambda: test_holdout.holdout_scene(False))}
    for kind in test_panorama.KINDS:
        out[f"camera {kind.lower()}"] = sized(lambda kind=kind: test_panorama._cycles_scene(
            kind, 32, test_panorama.BLENDER_PROPS.get(kind, {})))
    out["camera fisheye_equidistant + DoF"] = sized(lambda: test_panorama._cycles_scene(
        "FISHEYE_EQUIDISTANT", 32, dict(dof_use_dof=True, dof_focus_distance=2.0, dof_aperture_fstop=0.5)))
    return out


def _rel_mse(image, reference, ref_var):
    """relMSE against the reference, less the reference's own expected part."""
    r = reference
    return float(np.mean((image - r) ** 2 / (r * r + EPS)) - np.mean(ref_var / (r * r + EPS)))


def measure(build, samples: int, runs: int, tmp: pathlib.Path) -> dict:
    sc = build()
    t0 = time.perf_counter()
    refs = np.array([rgba_cycles(sc, 16 * samples, 1000 + k, tmp / f"r{k}.exr") for k in range(runs)])
    t_ref = time.perf_counter() - t0
    reference, ref_var = refs.mean(axis=0), refs.var(axis=0, ddof=1) / runs
    cycles = np.array([rgba_cycles(sc, samples, 2000 + k, tmp / f"c{k}.exr") for k in range(runs)])
    ember = np.array([rgba_ember(sc, samples, k) for k in range(runs)])
    long = np.array([rgba_ember(sc, 4 * samples, 100 + k) for k in range(runs)])
    out = {"size": f"{sc.render.resolution_x}x{sc.render.resolution_y}", "reference seconds": t_ref}
    for part, ch in (("colour", slice(0, 3)), ("alpha", slice(3, 4))):
        ref_mean = reference[..., ch].mean()
        if part == "alpha" and np.all(reference[..., 3] == 1) and np.all(long[..., 3] == 1):
            continue  # every pixel opaque in both
        means = long[..., ch].mean(axis=(1, 2, 3))
        bias, se = means.mean() / ref_mean - 1, means.std(ddof=1) / np.sqrt(runs) / ref_mean
        e = np.mean([_rel_mse(x[..., ch], reference[..., ch], ref_var[..., ch]) for x in ember])
        c = np.mean([_rel_mse(x[..., ch], reference[..., ch], ref_var[..., ch]) for x in cycles])
        out[part] = dict(bias=bias, se=se, ember=e, cycles=c)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=48)
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--only", default=None, help="scenes whose name contains this")
    args = ap.parse_args()
    rows = []
    with addon(), tempfile.TemporaryDirectory() as tmp:
        for name, build in _scenes(args.size).items():
            if args.only and args.only not in name:
                continue
            r = measure(build, args.samples, args.runs, pathlib.Path(tmp))
            for part in ("colour", "alpha"):
                if part in r:
                    m = r[part]
                    ratio = m["ember"] / m["cycles"] if m["cycles"] > 0 else float("nan")
                    ok_bias = abs(m["bias"]) <= 0.01
                    ok_noise = ratio <= 1.5
                    rows.append(f"| {name}{'' if part == 'colour' else ' (alpha)'} | {r['size']} | "
                                f"{100 * m['bias']:+.2f} ± {100 * m['se']:.2f} | {m['ember']:.5f} | {m['cycles']:.5f} | "
                                f"{ratio:.2f} | {'met' if ok_bias else 'NOT met'} / {'met' if ok_noise else 'NOT met'} |")
                    print(rows[-1], flush=True)
    head = [
        "# Translucent, Toon, Holdout and panoramic cameras against Cycles 5.0", "",
        f"Written by `bench/closures_toon_pano.py --size {args.size} --samples {args.samples} --runs {args.runs}` "
        "(one machine, one run). Reference: Cycles at 16x the samples, "
        f"{args.runs} seeds. Bias: Ember at 4x the samples ({args.runs} seeds), its image mean / the "
        "reference's - 1, ± one standard error over the seeds. relMSE at equal samples "
        f"({args.samples} per pixel, EPS = {EPS}), less the reference's own expected relMSE, mean of "
        f"{args.runs} seeds. Targets: |bias| <= 1 %, Ember / Cycles relMSE <= 1.5.", "",
        "| scene | pixels | bias % | relMSE Ember | relMSE Cycles | ratio | bias / noise target |",
        "|---|---|---|---|---|---|---|"]
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text("\n".join(head + rows) + "\n")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
