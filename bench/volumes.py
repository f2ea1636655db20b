"""Homogeneous media against Cycles 5.0 (bench/results/volumes/first_step.md).

    ./dev python bench/volumes.py [--size 64] [--samples 64] [--seeds 8] [--reference 4096]

Scenes of tests/volume_scenes.py (a cube of Volume Scatter lit by a sun over a floor; a
sphere of Volume Absorption in front of a bright background; the sphere under glass; the
cube as an emitting Principled Volume at four volume bounces), the others at Cycles' default
volume bounces (single scattering). A Cycles reference at --reference samples per pixel; then
--seeds renders each of Ember and Cycles at --samples: the bias of Ember's mean image
(relative to the reference's mean, with its standard error over seeds, and per quadrant),
and the relMSE of a single render at equal samples, sum (x - ref)^2 / (ref^2 + 1e-2) over
pixels, mean over seeds, Ember and Cycles, with the wall time per render. The reference's own
noise enters both relMSEs alike.
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

import ember  # noqa: E402

from cycles_renders import cycles_image, ember_image, region_means  # noqa: E402
import volume_scenes  # noqa: E402

OUT = ROOT / "bench" / "results" / "volumes" / "first_step.md"


def rel_mse(img, ref) -> float:
    return float(np.mean((img - ref) ** 2 / (ref ** 2 + 1e-2)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--reference", type=int, default=4096)
    args = ap.parse_args()
    ember.register()
    tmp = pathlib.Path(tempfile.mkdtemp())
    rows = []
    for name, build in volume_scenes.SCENES.items():
        sc = build(args.size)
        ref = cycles_image(sc, args.reference, 1000, tmp / "ref.exr")
        e_imgs, c_imgs, e_t, c_t = [], [], [], []
        for k in range(args.seeds):
            t0 = time.perf_counter()
            e_imgs.append(ember_image(sc, "PATH", args.samples, k))
            t1 = time.perf_counter()
            c_imgs.append(cycles_image(sc, args.samples, k, tmp / f"c{k}.exr"))
            t2 = time.perf_counter()
            e_t.append(t1 - t0)
            c_t.append(t2 - t1)
        e_reg = region_means(e_imgs)
        ref_reg = region_means([ref])[0]
        bias = e_reg.mean(axis=0) / ref_reg - 1.0
        se = e_reg.std(axis=0, ddof=1) / np.sqrt(len(e_reg)) / ref_reg
        c_bias = region_means(c_imgs).mean(axis=0) / ref_reg - 1.0
        e_mse = np.mean([rel_mse(x, ref) for x in e_imgs])
        c_mse = np.mean([rel_mse(x, ref) for x in c_imgs])
        rows.append((name, bias, se, c_bias, e_mse, c_mse, np.median(e_t), np.median(c_t)))
        print(name, bias, se, e_mse, c_mse, flush=True)
    lines = ["# Homogeneous media: first step against Cycles 5.0", "",
             f"`./dev python bench/volumes.py --size {args.size} --samples {args.samples} --seeds {args.seeds} "
             f"--reference {args.reference}` (one machine, one run; 2 cores shared with other work, so the "
             "times are indicative only). Scenes: tests/volume_scenes.py, at Cycles' default volume bounces "
             "(single scattering; Ember's volume_bounces 1) but principled_fog (Cycles' 3, Ember's 4).", "",
             "Bias: Ember's mean over the seeds against the Cycles reference, image mean and its four "
             "quadrants (top-left, top-right, bottom-left, bottom-right), with the standard error of "
             "Ember's mean; Cycles' own low-sample mean against its reference for scale. relMSE: one "
             f"render at {args.samples} samples per pixel, mean over seeds.", "",
             "| scene | Ember bias (image) | s.e. | Ember bias per quadrant | Cycles bias (image) "
             "| relMSE Ember | relMSE Cycles | ratio | s / render Ember | s / render Cycles |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for name, bias, se, c_bias, e_mse, c_mse, e_t, c_t in rows:
        quads = " ".join(f"{b:+.2%}" for b in bias[1:])
        lines.append(f"| {name} | {bias[0]:+.3%} | {se[0]:.3%} | {quads} | {c_bias[0]:+.3%} | {e_mse:.3g} | "
                     f"{c_mse:.3g} | {e_mse / c_mse:.2f} | {e_t:.2f} | {c_t:.2f} |")
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text("\n".join(lines) + "\n")
    print(OUT.read_text())
    ember.unregister()


if __name__ == "__main__":
    main()
