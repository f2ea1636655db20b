"""The tail of a wavefront batch and the path tracer's throughput.

    ./dev python bench/tail.py --tail            # in one process: CPU time per path and the
                                                 # tail's share
    ./dev python bench/tail.py --throughput      # bench/run.py's throughput study: Ember's
                                                 # whole pipeline (two workers), Cycles, embreex alone
    ./dev python bench/tail.py --tail --throughput --json out.json

Cornell box at 256x256, every bounce limit 64 (as bench/run.py). --tail renders items of one
batch (131072 paths, two passes) in this process and times every bounce: "tail" is the time spent in bounces with fewer than --narrow live paths
(each still pays a whole bounce's NumPy calls), its share is of the whole item; CPU time
(time.process_time) rather than wall time, as the machine is shared. Every figure is printed
with the 1-minute load average.
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import time
import types

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SIZE = 256


def export_bench_scene(size: int = SIZE, name: str = "cornell_box"):
    """Bench scene `name` (bench/scenes.py) as an Ember Scene (bpy), every bounce limit 64."""
    import bpy
    from bench.run import _open
    from bench.scenes import by_name
    from ember.engine.blender.export import export_scene
    scene = _open(by_name(name).path, size)
    scene.render.engine = "EMBER"
    scene.ember.max_depth = 64
    sc, _ = export_scene(bpy.context.evaluated_depsgraph_get(),
                         overrides=dict(width=size, height=size, border=(0, 0, size, size)))
    return sc


def tail_study(scene, items: int, rounds: int, narrow: int) -> dict:
    """CPU microseconds per path (median over rounds), bounces per item, and the share of
    the time in bounces with fewer than `narrow` live paths (the tail)."""
    from ember.engine.tracer import Tracer
    scene = scene.replace(settings=scene.settings.replace(samples=2 * items))
    tracer = Tracer(scene)
    stage = tracer.integrator.stages(0)[0]
    vis = tracer.integrator.tracer.visibility
    intersect, log = vis.intersect, []

    def timed(o, d, *a, **k):  # one intersect call per bounce
        log.append((len(d), time.process_time()))
        return intersect(o, d, *a, **k)

    vis.intersect = timed
    tracer.run(stage, 0)  # warm-up
    out = {"us_per_path": [], "tail_share": [], "bounces_per_item": []}
    for _ in range(rounds):
        spent, tail, bounces, paths = 0.0, 0.0, 0, 0
        for i in range(items):
            log.clear()
            t0 = time.process_time()
            tracer.run(stage, i % stage.items)
            t1 = time.process_time()
            log.append((0, t1))
            spent += t1 - t0
            paths += stage.stop // stage.items
            bounces += len(log) - 1
            tail += sum(t2 - t for (n, t), (_, t2) in zip(log, log[1:]) if n < narrow)
        out["us_per_path"].append(1e6 * spent / paths)
        out["tail_share"].append(tail / spent)
        out["bounces_per_item"].append(bounces / items)
    out["median_us_per_path"] = float(np.median(out["us_per_path"]))
    out["median_tail_share"] = float(np.median(out["tail_share"]))
    print(f"  {out['median_us_per_path']:.2f} us/path CPU ({', '.join(f'{x:.2f}' for x in out['us_per_path'])}), "
          f"{np.mean(out['bounces_per_item']):.0f} bounces per item, bounces with < {narrow} live paths: "
          f"{100 * out['median_tail_share']:.1f} % of the time "
          f"({', '.join(f'{100 * x:.1f}' for x in out['tail_share'])})", flush=True)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tail", action="store_true", help="in-process study of the tail")
    ap.add_argument("--throughput", action="store_true", help="bench/run.py's throughput study")
    ap.add_argument("--seconds", type=float, default=20.0, help="throughput: render time each")
    ap.add_argument("--items", type=int, default=4, help="tail: items (batches) per round")
    ap.add_argument("--rounds", type=int, default=5, help="tail: rounds (the median is reported)")
    ap.add_argument("--narrow", type=int, default=2000, help="tail: live paths below which a bounce is tail")
    ap.add_argument("--no-cycles", action="store_true")
    ap.add_argument("--json", help="write the figures here")
    args = ap.parse_args(argv)
    from _bootstrap import load_ember
    ember = load_ember()
    ember.register()
    result = {"load_start": os.getloadavg()[0]}
    if args.tail:
        print(f"tail, cornell_box {SIZE}x{SIZE} (load {os.getloadavg()[0]:.1f}):", flush=True)
        result["tail"] = tail_study(export_bench_scene(), args.items, args.rounds, args.narrow)
    if args.throughput:
        from bench.run import throughput
        print(f"throughput, cornell_box {SIZE}x{SIZE} (load {os.getloadavg()[0]:.1f}):", flush=True)
        ns = types.SimpleNamespace(seed=0, quick=False, no_cycles=args.no_cycles)
        result["throughput"] = t = throughput(ns, args.seconds)
        if "embreex_alone" in t:
            ratio = t["ember"]["rays_per_second"] / t["embreex_alone"]["2"]["mix"]
            print(f"  whole pipeline / embreex alone (2 threads): {ratio:.3f}", flush=True)
            t["pipeline_over_embreex"] = ratio
        if "cycles" in t:
            print(f"  Ember / Cycles samples per second: "
                  f"{t['ember']['samples_per_second'] / t['cycles']['samples_per_second']:.3f}", flush=True)
    result["load_end"] = os.getloadavg()[0]
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(result, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
