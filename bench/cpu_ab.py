"""CPU time per path of two or more versions of the path tracer, side by side in one process.

    git archive <commit> | (mkdir -p /tmp/base && tar -x -C /tmp/base)
    ./dev python bench/cpu_ab.py /tmp/base . --rounds 8            # A against B
    ./dev python bench/cpu_ab.py . .@262144                        # batch sizes (root@batch)
    ./dev python bench/cpu_ab.py . --profile                       # cProfile of one version

Each root is a checkout of Ember, loaded under its own package name; all trace a bench scene
(--scene, the Cornell box by default) at 256x256 (every bounce limit 64, exported once through
bpy), the root's film items in this process, in alternating order (A, B, B, A, ...) so that the machine's load
falls on all alike. Reports CPU time (time.process_time) per path, per ray, the share of
it in bounces with fewer than --narrow live paths (the tail), and whether the images are
bit for bit the same; ratios are medians of per-round ratios to the first root, and the ratio
of the fastest rounds (what the code costs with the least interference from a loaded machine).
"""
from __future__ import annotations

import argparse
import cProfile
import importlib
import importlib.util
import os
import pathlib
import pstats
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _load(root: str, name: str):
    spec = importlib.util.spec_from_file_location(name, os.path.join(root, "__init__.py"),
                                                  submodule_search_locations=[root])
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return importlib.import_module(name + ".engine.scene"), importlib.import_module(name + ".engine.tracer")


class Version:
    """One root's tracer over `items` items of the Cornell box (root@batch: that batch size)."""

    def __init__(self, spec: str, name: str, npz: str, items: int):
        root, _, batch = spec.partition("@")
        scene_mod, tracer_mod = _load(os.path.abspath(root), name)
        sc = scene_mod.Scene.load(npz)
        batch = int(batch) if batch else sc.settings.batch_size
        passes = 2 * items * batch // 131072  # the same paths whatever the batch size
        sc = sc.replace(settings=sc.settings.replace(samples=passes, integrator="path", batch_size=batch))
        self.spec, self.tracer = spec, tracer_mod.Tracer(sc)
        self.stage = self.tracer.integrator.stages(0)[0]
        vis, self.log = self.tracer.integrator.tracer.visibility, []
        intersect = vis.intersect

        def timed(o, d, *a, **k):  # one closest-hit call per bounce: its width and start time
            self.log.append((len(d), time.process_time()))
            return intersect(o, d, *a, **k)

        vis.intersect = timed
        self.tracer.run(self.stage, 0)  # warm-up

    def run(self, narrow: int):
        """(CPU us per path, us per ray, tail share, the radiance of all paths)."""
        spent = tail = 0.0
        paths = rays = 0
        out = []
        for item in range(self.stage.items):
            self.log.clear()
            t0 = time.process_time()
            result, n_rays = self.tracer.run(self.stage, item)[:2]
            t1 = time.process_time()
            self.log.append((0, t1))
            L = result["L"] if isinstance(result, dict) else result
            out.append(L)
            spent, paths, rays = spent + t1 - t0, paths + len(L), rays + n_rays
            tail += sum(b - a for (n, a), (_, b) in zip(self.log, self.log[1:]) if n < narrow)
        return 1e6 * spent / paths, 1e6 * spent / rays, tail / spent, np.concatenate(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("roots", nargs="+", help="Ember checkouts (root or root@batch_size)")
    ap.add_argument("--items", type=int, default=2, help="items of 131072 paths per round")
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("--narrow", type=int, default=2000, help="live paths below which a bounce is tail")
    ap.add_argument("--profile", action="store_true", help="cProfile the first root instead")
    ap.add_argument("--scene", default="cornell_box", help="bench scene (bench/scenes.py)")
    args = ap.parse_args(argv)
    npz = os.path.join(tempfile.mkdtemp(), f"{args.scene}256.npz")
    from _bootstrap import load_ember
    load_ember().register()
    from bench.tail import export_bench_scene
    export_bench_scene(name=args.scene).save(npz)
    versions = [Version(spec, f"ember_v{i}", npz, args.items) for i, spec in enumerate(args.roots)]
    if args.profile:
        profile = cProfile.Profile(time.process_time)
        profile.runcall(versions[0].run, args.narrow)
        stats = pstats.Stats(profile)
        stats.sort_stats("tottime").print_stats(30)
        stats.sort_stats("cumulative").print_stats(40)
        return 0
    print(f"load {os.getloadavg()[0]:.2f}", flush=True)
    rows = {i: [] for i in range(len(versions))}
    first = None
    for k in range(args.rounds):
        for i in (range(len(versions)) if k % 2 == 0 else reversed(range(len(versions)))):
            us_path, us_ray, tail, L = versions[i].run(args.narrow)
            rows[i].append((us_path, us_ray, tail))
            if k == 0:
                first = L if first is None else first
                m = min(len(L), len(first))
                print(f"{versions[i].spec}: image bit for bit the first root's (first {m} paths): "
                      f"{np.array_equal(L[:m], first[:m])}", flush=True)
        print(f"round {k}, load {os.getloadavg()[0]:.2f}: " +
              ", ".join(f"{v.spec} {rows[i][-1][0]:.3f} us/path {100 * rows[i][-1][2]:.1f} % tail"
                        for i, v in enumerate(versions)), flush=True)
    base = np.array(rows[0])
    for i, v in enumerate(versions):
        a = np.array(rows[i])
        print(f"{v.spec}: median {np.median(a[:, 0]):.3f} us/path, {np.median(a[:, 1]):.4f} us/ray, tail "
              f"{100 * np.median(a[:, 2]):.2f} %, ratio to the first {np.median(a[:, 0] / base[:, 0]):.4f}; "
              f"fastest round {np.min(a[:, 0]):.3f} us/path, ratio of the fastest {np.min(a[:, 0]) / np.min(base[:, 0]):.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
