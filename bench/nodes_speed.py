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
relMSE at most Cycles' at the largest budget. Then, as wall time on a loaded machine says as
much about the other processes as about the renderers, paths per CPU second of each (in this
process: Cycles' threads count in its CPU time) and the ratio at equal CPU time that follows
from it and the per-sample error (relMSE x samples: both are unbiased). Writes
OUT/results.json and OUT/table.md (OUT: bench/results/nodes_speed).
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import tempfile
import time
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


def cpu_throughput(scene_name: str, resolution: int, cycles_samples: int = 32, ember_passes: int = 8) -> dict:
    """Paths per CPU second of each renderer on this scene, which a loaded machine changes far
    less than wall time: Cycles' render (its threads run in this process, so process_time
    counts them) after a warm-up render, and Ember's path tracer run in this process on the
    same exported scene (as bench/nodes_cost.py)."""
    import bpy
    from bench.run import _open
    from bench.render_cycles import cycles_reference, render_samples
    from bench.scenes import by_name
    from bench.tail import export_bench_scene
    from ember.engine.tracer import Tracer
    bs = by_name(scene_name)
    scene = _open(bs.path, resolution)
    cycles_reference.unbiased_cycles(scene, 1)
    with tempfile.TemporaryDirectory(prefix="ember_bench_") as tmp:
        path = os.path.join(tmp, "c.exr")
        render_samples(scene, 1, 0, path)  # sync and BVH
        t0 = time.process_time()
        render_samples(scene, cycles_samples, 1, path)
        cycles_cpu = time.process_time() - t0
    cycles_paths = cycles_samples * resolution * resolution
    sc = export_bench_scene(size=resolution, name=scene_name)
    sc = sc.replace(settings=sc.settings.replace(samples=ember_passes, integrator="path"))
    tracer = Tracer(sc)
    stage = tracer.integrator.stages(0)[0]
    tracer.run(stage, 0)  # warm-up: programs compiled, caches filled
    t0 = time.process_time()
    paths = 0
    for item in range(stage.items):
        result = tracer.run(stage, item)[0]
        paths += len(result["L"] if isinstance(result, dict) else result)
    ember_cpu = time.process_time() - t0
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return {"cycles_paths_per_cpu_s": cycles_paths / cycles_cpu, "ember_paths_per_cpu_s": paths / ember_cpu,
            "cycles_samples": cycles_samples, "ember_paths": paths, "load": os.getloadavg()[0]}


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
            # Cycles' samples come from a rate measured before its render, so its render may
            # end short of the budget (or past it) under a changing load: its relMSE at
            # Ember's seconds, as relMSE falls as 1/time.
            row["ratio_at_ember_seconds"] = row["ratio"] * row["ember"]["seconds"] / row["cycles"]["seconds"]
            cpu = result.get("cpu", {}).get(name)
            if cpu:  # relMSE falls as 1/samples (both unbiased): the ratio at equal CPU time
                per_sample = {k: row[k]["relmse"] * row[k]["samples"] for k in ("ember", "cycles")}
                row["equal_cpu_ratio"] = (per_sample["ember"] / per_sample["cycles"] *
                                          cpu["cycles_paths_per_cpu_s"] / cpu["ember_paths_per_cpu_s"])
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
             "Ember / Cycles | the same, Cycles scaled to Ember's seconds | reference's own relMSE | target (<= 1x) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for key, r in rows.items():
        e, c = r["ember"], r["cycles"]
        lines.append(f"| {key} s | {e['samples']:.0f} | {e['seconds']:.1f} | {e['relmse']:.4f} | {c['samples']:.0f} | "
                     f"{c['seconds']:.1f} | {c['relmse']:.4f} | {r['ratio']:.2f}x | {r['ratio_at_ember_seconds']:.2f}x | "
                     f"{r['reference_relmse']:.5f} | "
                     f"{'met' if r['met'] else 'not met'} |")
    loads = [run["runs"][w]["load"] for runs in result["scenes"].values() for run in runs for w in run.get("runs", {})
             if "load" in run["runs"][w]]
    if loads:
        lines += ["", f"1-minute load average during the renders: {min(min(l) for l in loads):.1f}-"
                      f"{max(max(l) for l in loads):.1f} on {result['machine']['cores']} cores."]
    for name, cpu in result.get("cpu", {}).items():
        lines += ["", f"`{name}`, paths per CPU second (load {cpu['load']:.1f}): Cycles "
                      f"{cpu['cycles_paths_per_cpu_s']:.0f}, Ember {cpu['ember_paths_per_cpu_s']:.0f} "
                      f"({cpu['cycles_paths_per_cpu_s'] / cpu['ember_paths_per_cpu_s']:.2f}x fewer)."]
        for key, r in rows.items():
            if key.startswith(name + "@") and "equal_cpu_ratio" in r:
                lines.append(f"- {key} s: per-sample error (relMSE x spp) Ember {r['ember']['relmse'] * r['ember']['samples']:.3f}, "
                             f"Cycles {r['cycles']['relmse'] * r['cycles']['samples']:.3f}; Ember / Cycles at equal CPU "
                             f"time {r['equal_cpu_ratio']:.2f}x")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="procedural")
    ap.add_argument("--budgets", default="30")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--integrator", default="auto")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "nodes_speed"))
    ap.add_argument("--no-cpu", action="store_true", help="skip the paths-per-CPU-second study")
    ap.add_argument("--summary-of", help="results.json of an earlier run: only the CPU study and the table")
    args = ap.parse_args(argv)
    budgets = sorted(float(b) for b in args.budgets.split(","))
    seeds = [int(s) for s in args.seeds.split(",")]
    names = [s.strip() for s in args.scenes.split(",")]
    if args.summary_of:  # re-summarise an earlier run, adding the CPU throughput study
        result = json.loads(pathlib.Path(args.summary_of).read_text())["result"]
        from _bootstrap import load_ember
        load_ember().register()
    else:
        result = measure(names, budgets, seeds, args.resolution, args.integrator)
    if not args.no_cpu:
        result["cpu"] = {name: cpu_throughput(name, result["resolution"]) for name in result["scenes"]}
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
