"""Procedural materials at equal time against Cycles: relMSE of Ember (auto) and of Cycles after
the same seconds on the same machine, against a long Cycles reference.

    ./dev python bench/references.py --only procedural --resolution 128    # the reference, once
    ./dev python bench/nodes_speed.py                        # 30 s each, seeds 0 and 1
    ./dev python bench/nodes_speed.py --budgets 10,30 --seeds 0 --out /tmp/ns

bench/run.py's measurement (bench_scene) on the scenes given (default: procedural, 128x128):
Ember's integrator `auto` through bpy.ops.render.render, snapshotted at each budget (the time
from the end of export: build, worker start-up, tracing), and a Cycles render per budget with
the references' settings (scenes/reference.py unbiased_cycles: CPU, adaptive sampling,
denoising and clamping off, every bounce limit 64, the scene's pixel filter; its time from
render_pre to render_post after a warm-up render has synced the scene). relMSE (EPS 1e-2)
against bench/references/<scene>_<N>.exr, per seed and their mean; the target is Ember's
relMSE at most Cycles' at the largest budget. Writes OUT/results.json and OUT/table.md
(OUT: bench/results/nodes_speed).
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import tempfile
import types

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))


def measure(scene_names, budgets, seeds, resolution, integrator="auto") -> dict:
    from _bootstrap import load_ember
    load_ember().register()
    from bench.run import _machine, bench_scene
    from bench.scenes import available
    scenes, notes = available(scene_names)
    for n in notes:
        print("note:", n, flush=True)
    out = {"budgets": list(budgets), "seeds": list(seeds), "resolution": resolution, "integrator": integrator,
           "machine": _machine(), "scenes": {}}
    for bs in scenes:
        runs = []
        for seed in seeds:
            print(f"{bs.name}, seed {seed}:", flush=True)
            args = types.SimpleNamespace(variant=[], seed=seed, no_cycles=False)
            result = bench_scene(bs, args, budgets, [integrator], resolution)
            if "skipped" in result:
                print("  skipped:", result["skipped"], flush=True)
                break
            runs.append(result)
        out["scenes"][bs.name] = runs
    return out


def summary(result: dict) -> dict:
    """Per scene and budget: mean over seeds of relMSE, samples and seconds, Ember and Cycles."""
    rows = {}
    integ = f"ember:{result['integrator']}"
    for name, runs in result["scenes"].items():
        if not runs:
            continue
        for b in result["budgets"]:
            row = {"reference_relmse": runs[0]["reference"]["relmse_ref"]}
            for who, key in ((integ, "ember"), ("cycles", "cycles")):
                pts = [_at(r["runs"][who]["points"], b) for r in runs if "points" in r["runs"].get(who, {})]
                row[key] = {"relmse": float(np.mean([p["relmse"] for p in pts])),
                            "relmse_runs": [p["relmse"] for p in pts],
                            "samples": float(np.mean([p["samples"] for p in pts])),
                            "seconds": float(np.mean([p["seconds"] for p in pts]))}
            row["ratio"] = row["ember"]["relmse"] / row["cycles"]["relmse"]
            row["met"] = row["ratio"] <= 1.0
            rows[f"{name}@{b:g}"] = row
    return rows


def _at(points, budget):
    """The image for `budget`: the first snapshot labelled with it or a larger one (an image can
    stand for several budgets), else the end image."""
    later = [p for p in points if p["budget"] is not None and p["budget"] >= budget]
    return later[0] if later else points[-1]


def table(result: dict, rows: dict) -> str:
    lines = [f"{result['resolution']}x{result['resolution']}, seeds {result['seeds']}, Ember `{result['integrator']}` "
             f"vs Cycles (unbiased reference settings), relMSE (EPS 1e-2) against the reference; mean over seeds.", "",
             "| scene @ budget | Ember spp | Ember s | Ember relMSE | Cycles spp | Cycles s | Cycles relMSE | "
             "Ember / Cycles | reference's own relMSE | target (<= 1x) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for key, r in rows.items():
        e, c = r["ember"], r["cycles"]
        lines.append(f"| {key} s | {e['samples']:.0f} | {e['seconds']:.1f} | {e['relmse']:.4f} | {c['samples']:.0f} | "
                     f"{c['seconds']:.1f} | {c['relmse']:.4f} | {r['ratio']:.2f}x | {r['reference_relmse']:.5f} | "
                     f"{'met' if r['met'] else 'not met'} |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="procedural")
    ap.add_argument("--budgets", default="30")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--integrator", default="auto")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "nodes_speed"))
    args = ap.parse_args(argv)
    budgets = sorted(float(b) for b in args.budgets.split(","))
    seeds = [int(s) for s in args.seeds.split(",")]
    result = measure([s.strip() for s in args.scenes.split(",")], budgets, seeds, args.resolution, args.integrator)
    rows = summary(result)
    text = table(result, rows)
    print(text)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps({"result": result, "summary": rows}, indent=1))
    (out / "table.md").write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
