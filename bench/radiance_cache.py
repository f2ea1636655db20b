"""Radiance caching: equal-time error of icache with radiance caching against
icache without it (final gathering on the glossy surfaces) and the path tracer.

    ./dev python bench/radiance_cache.py --reference     # the converged reference (slow)
    ./dev python bench/radiance_cache.py --times 2,4,8,16

Scene: scenes/cornell_rough.blend (scenes/build_materials.py), the Cornell box with moderately
rough glossy surfaces (GGX roughness 0.7-0.8; cornell_glossy's lobes, roughness 0.2-0.3, are
sharper than the default order-7 basis serves, harmonics.min_roughness = 0.61). --res x --res
(64: radiance.md, else radiance_RES.md), 64 bounces, seed 0. Reference: Ember's path tracer,
two independent halves (seeds 101 and 102) of --ref-spp samples each, saved in
bench/references/cornell_rough_RES_ember.npz; its own relMSE
is relMSE(A, B) / 4, subtracted from every error (bench/metrics.py). Equal time: measured
by ladders of sample counts (see `measure`), both cores, wall time including the photon and
record stages; the 1-minute load average is recorded with every run (the machine is shared). Writes
bench/results/icache/radiance.json and radiance.md.
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from bench.icache_study import Renderer, relmse  # noqa: E402

SCENE = "cornell_rough"
OUT = ROOT / "bench" / "results" / "icache"


def reference_path(res):
    return ROOT / "bench" / "references" / f"{SCENE}_{res}_ember.npz"


def out_name(res):
    return "radiance" if res == 64 else f"radiance_{res}"
VARIANTS = {  # label: settings
    "path": dict(integrator="path"),
    "icache": dict(integrator="icache", icache_radiance=False),
    "icache + radiance": dict(integrator="icache", icache_radiance=True),
}


def reference(R, spp, res):
    halves = []
    for seed in (101, 102):
        img, facts, _ = R.render(SCENE, res, integrator="path", samples=spp, seed=seed)
        print(f"  reference half, seed {seed}: {spp} spp, {facts['wall_s']:.0f} s, load {facts['load']}", flush=True)
        halves.append(img)
    A, B = halves
    np.savez_compressed(reference_path(res), image=0.5 * (A + B), own_relmse=relmse(A, B) / 4.0, spp=2 * spp)


LADDERS = {"path": (16, 32, 64, 128, 256, 512, 1024), "icache": (1, 2, 4, 8, 16, 32, 64)}


def measure(R, times, res):
    """Every variant at a ladder of sample counts (wall time measured, not limited: a time limit
    stops icache between its record rounds and passes, so equal spp ladders compare more
    cleanly); the error at time t is that of the largest run that finished within t."""
    ref = np.load(reference_path(res))
    image, own = ref["image"], float(ref["own_relmse"])
    rows = []
    for label, kw in VARIANTS.items():
        for spp in LADDERS[kw["integrator"]]:
            img, f, integ = R.render(SCENE, res, samples=spp, **kw)
            e = relmse(img, image)
            row = {"label": label, "relmse": e, "relmse_corrected": e - own,
                   "mean_ratio": float(img.mean() / image.mean()), **{k: f.get(k) for k in (
                       "samples", "wall_s", "load", "records", "records_per_mpix", "interpolated_share",
                       "stage_seconds", "nonfinite")}}
            rows.append(row)
            print(f"  {label:18s} {spp:5d} spp relMSE {row['relmse_corrected']:.2e}, {row['wall_s']:.1f} s wall, "
                  f"records {row['records']}, load {row['load'][0]:.1f}-{row['load'][1]:.1f}, stages {_stages(row)}",
                  flush=True)
    return equal_time({"resolution": res, "reference": str(reference_path(res).relative_to(ROOT)), "reference_spp": int(ref["spp"]),
                       "reference_own_relmse": own, "rows": rows}, times)


def equal_time(res, times):
    rows, equal = res["rows"], []
    for t in times:
        for label in VARIANTS:
            done = [r for r in rows if r["label"] == label and r["wall_s"] <= t]
            equal.append({"time": t, "label": label, "run": max(done, key=lambda r: r["samples"]) if done else None})
    return {**res, "equal_time": equal}


def _stages(row):
    return ", ".join(f"{k} {v:.1f}" for k, v in (row.get("stage_seconds") or {}).items())


def markdown(res):
    L = [f"cornell_rough at {res.get('resolution', 64)} x {res.get('resolution', 64)}. Reference: Ember path tracer, {res['reference_spp']} spp ({res['reference']}), own relMSE "
         f"{res['reference_own_relmse']:.1e} (subtracted). relMSE with EPS = 1e-2. Load = 1-minute load "
         "average before-after (2 cores, shared machine).", "",
         "Equal time (the largest run of the ladder that finished within the time):", "",
         "| time (s) | integrator | spp | wall (s) | relMSE | records | load |", "|---|---|---|---|---|---|---|"]
    for e in res["equal_time"]:
        r = e["run"]
        if r is None:
            L.append(f"| {e['time']:g} | {e['label']} | - | - | (no run within) | - | - |")
            continue
        L.append(f"| {e['time']:g} | {e['label']} | {r['samples']} | {r['wall_s']:.1f} | {r['relmse_corrected']:.2e} | "
                 f"{r['records'] if r['records'] is not None else '-'} | {r['load'][0]:.1f}-{r['load'][1]:.1f} |")
    L += ["", "All runs:", "",
          "| integrator | spp | wall (s) | relMSE | mean / ref | records | interpolated | stages (s) | load |",
          "|---|---|---|---|---|---|---|---|---|"]
    for r in res["rows"]:
        share = f"{r['interpolated_share']:.1%}" if r["interpolated_share"] is not None else "-"
        L.append(f"| {r['label']} | {r['samples']} | {r['wall_s']:.1f} | {r['relmse_corrected']:.2e} | "
                 f"{r['mean_ratio']:.3f} | {r['records'] if r['records'] is not None else '-'} | {share} | {_stages(r)} | "
                 f"{r['load'][0]:.1f}-{r['load'][1]:.1f} |")
    return "\n".join(L) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--reference", action="store_true")
    ap.add_argument("--ref-spp", type=int, default=2048)
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--times", default="2,4,8,16,32")
    ap.add_argument("--report", action="store_true", help="rewrite radiance.md from radiance.json (--times)")
    args = ap.parse_args()
    R = None if args.report else Renderer()
    if args.reference:
        reference(R, args.ref_spp, args.res)
        return
    times = [float(t) for t in args.times.split(",")]
    name = out_name(args.res)
    res = equal_time(json.loads((OUT / f"{name}.json").read_text()), times) if args.report else measure(R, times, args.res)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / f"{name}.json").write_text(json.dumps(res, indent=1))
    (OUT / f"{name}.md").write_text(markdown(res))
    print(markdown(res))


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    main()
