"""What shader-node programs cost inside a render: CPU time per node kind, per million points.

    ./dev python bench/nodes_cost.py                         # procedural scene, 128x128
    ./dev python bench/nodes_cost.py --scene procedural --size 256 --passes 4 --json out.json

Renders film items of a bench scene (bench/scenes.py, exported through bpy, every bounce limit
64) with the path tracer in this process, each node kind's evaluation timed (CPU time,
time.process_time, so the machine's other load counts little) around NodeType.run and around
its lazily computed outputs when the program reads them. A kind is labelled with the modes
that change its work (Math's operation, Noise's type and dimensions, Voronoi's feature, Mix's
data type); "offset" rows are the copies a Bump node evaluates at the two moved points.
Reports, per label: points evaluated, CPU seconds, microseconds per point (= seconds per
million points), share of the render's CPU time; and the render's share in node programs.
"""
from __future__ import annotations

import argparse
import collections
import json
import os
import pathlib
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

_MODES = ("operation", "noise_type", "noise_dimensions", "feature", "data_type", "blend_type", "wave_type")


def label(node) -> str:
    kind = node.kind.replace("ShaderNode", "")
    props = dict(node.props)
    modes = [str(props[k]) for k in _MODES if k in props and k != "noise_dimensions"]
    return f"{kind} {' '.join(modes)}".strip()


class Timings:
    """process_time per (label, offset) and points, gathered by a wrapped NodeType.run."""

    def __init__(self):
        self.seconds = collections.Counter()
        self.points = collections.Counter()
        self.calls = collections.Counter()

    def install(self):
        from ember.engine.nodes import base, program
        from ember.engine.nodes.differentials import OffsetState
        original = base.NodeType.run
        timings = self

        def timed(self_, node, inputs, state, used):
            key = (label(node), isinstance(state, OffsetState))
            t0 = time.process_time()
            out = original(self_, node, inputs, state, used)
            timings.seconds[key] += time.process_time() - t0
            if state is not None:
                timings.points[key] += state.n
                timings.calls[key] += 1
            if isinstance(out, dict):
                out = {k: timings._lazy(key, v) if callable(v) else v for k, v in out.items()}
            return out

        base.NodeType.run = timed
        run = program.Program.run

        def program_run(self_, state=None):
            t0 = time.process_time()
            try:
                return run(self_, state)
            finally:
                timings.seconds[("(all programs)", False)] += time.process_time() - t0

        program.Program.run = program_run

    def _lazy(self, key, fn):
        def call():
            t0 = time.process_time()
            try:
                return fn()
            finally:
                self.seconds[key] += time.process_time() - t0
        return call


def measure(scene_name: str, size: int, passes: int) -> dict:
    from _bootstrap import load_ember
    load_ember().register()
    from bench.tail import export_bench_scene
    from ember.engine.tracer import Tracer
    sc = export_bench_scene(size=size, name=scene_name)
    sc = sc.replace(settings=sc.settings.replace(samples=passes, integrator="path"))
    tracer = Tracer(sc)
    stage = tracer.integrator.stages(0)[0]
    tracer.run(stage, 0)  # warm-up: compiles the programs, fills caches
    timings = Timings()
    timings.install()
    t0 = time.process_time()
    paths = rays = 0
    for item in range(stage.items):
        result, n_rays = tracer.run(stage, item)[:2]
        L = result["L"] if isinstance(result, dict) else result
        paths, rays = paths + len(L), rays + n_rays
    total = time.process_time() - t0
    rows = []
    programs = timings.seconds.pop(("(all programs)", False), 0.0)
    for (name, moved), seconds in sorted(timings.seconds.items(), key=lambda kv: -kv[1]):
        points = timings.points[(name, moved)]
        rows.append(dict(node=name, offset=moved, points=points, calls=timings.calls[(name, moved)], seconds=seconds,
                         us_per_point=1e6 * seconds / max(points, 1), share=seconds / total))
    return dict(scene=scene_name, size=size, passes=passes, paths=paths, rays=rays, cpu_seconds=total,
                programs_seconds=programs, programs_share=programs / total, load=os.getloadavg()[0], rows=rows)


def table(result: dict) -> str:
    lines = [f"Scene `{result['scene']}` at {result['size']}x{result['size']}, {result['passes']} passes: "
             f"{result['paths']} paths, {result['rays']} rays, {result['cpu_seconds']:.2f} s CPU "
             f"({result['rays'] / result['cpu_seconds'] / 1e6:.3f} M rays/s on one core); node programs "
             f"{result['programs_seconds']:.2f} s ({100 * result['programs_share']:.1f} %), load "
             f"{result['load']:.2f}.", "",
             "| node (mode) | at | M points | CPU s | s per M points | share of render |", "|---|---|---|---|---|---|"]
    for r in result["rows"]:
        lines.append(f"| {r['node']} | {'bump offset' if r['offset'] else 'point'} | {r['points'] / 1e6:.3f} | "
                     f"{r['seconds']:.3f} | {r['us_per_point']:.3f} | {100 * r['share']:.1f} % |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="procedural")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--passes", type=int, default=4, help="passes of the film per item (samples)")
    ap.add_argument("--json", help="write the measurement here")
    args = ap.parse_args(argv)
    result = measure(args.scene, args.size, args.passes)
    print(table(result))
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
