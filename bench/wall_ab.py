"""Wall time of whole renders (worker processes as a user gets them) of two or more
versions of Ember, alternating, on a bench scene exported once through bpy.

    git archive <commit> | (mkdir -p /tmp/base && tar -x -C /tmp/base); ln -s $PWD/.venv /tmp/base/.venv
    ./dev python bench/wall_ab.py /tmp/base . --scene caustic --samples 64 --rounds 4

Each render runs in a fresh interpreter of that root's venv (path tracer, the root's default
batch size unless root@batch). Prints each render's seconds and image mean (equal means: the
same image), then per root the median and the median of per-round ratios to the first root.
`bench/cpu_ab.py` measures CPU per path in one process instead; its batch-size effects do
not carry over to two-worker renders (bench/results/tail/notes.md).
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]

_CHILD = r'''
import importlib.util, json, os, sys, time
root, npz, batch, samples = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
spec = importlib.util.spec_from_file_location("ember", os.path.join(root, "__init__.py"),
                                              submodule_search_locations=[root])
module = importlib.util.module_from_spec(spec)
sys.modules["ember"] = module
spec.loader.exec_module(module)
from ember.engine.scene import Scene
from ember.engine.session import RenderSession
sc = Scene.load(npz)
settings = dict(samples=samples, integrator="path") | (dict(batch_size=batch) if batch else {})
sc = sc.replace(settings=sc.settings.replace(**settings))
t = time.perf_counter()
session = RenderSession(sc)
session.run()
print(json.dumps(dict(seconds=time.perf_counter() - t, mean=float(session.film.mean().mean()),
                      processes=session.processes)))
'''


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("roots", nargs="+", help="Ember checkouts with a .venv (root or root@batch_size)")
    ap.add_argument("--scene", default="cornell_box", help="bench scene (bench/scenes.py), 256x256")
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--rounds", type=int, default=4)
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from _bootstrap import load_ember
    load_ember().register()
    from bench.tail import export_bench_scene
    npz = os.path.join(tempfile.mkdtemp(), f"{args.scene}.npz")
    export_bench_scene(name=args.scene).save(npz)
    times = {spec: [] for spec in args.roots}
    for k in range(args.rounds):
        for spec in (args.roots if k % 2 == 0 else args.roots[::-1]):
            root, _, batch = spec.partition("@")
            root = os.path.abspath(root)
            out = subprocess.run([os.path.join(root, ".venv", "bin", "python"), "-c", _CHILD, root, npz,
                                  batch or "0", str(args.samples)], capture_output=True, text=True)
            if out.returncode:
                sys.exit(out.stderr[-3000:])
            r = json.loads(out.stdout.strip().splitlines()[-1])
            times[spec].append(r["seconds"])
            print(f"round {k} {spec}: {r['seconds']:.2f} s, mean {r['mean']:.6g}, {r['processes']} workers, "
                  f"load {os.getloadavg()[0]:.2f}", flush=True)
    first = times[args.roots[0]]
    for spec, t in times.items():
        print(f"{spec}: median {statistics.median(t):.3f} s, ratio to the first "
              f"{statistics.median([a / b for a, b in zip(t, first)]):.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
