"""Sampler study: cost of `Sampler.get` per pattern and convergence of the sobol pattern.

    ./dev python bench/rng_study.py            # timings and convergence figures
    ./dev python bench/rng_study.py --quick    # fewer repeats, no convergence tables
    ./dev python bench/rng_study.py --cornell 4,16,64 --seeds 4   # + Cornell box relMSE

Timings are the best of many interleaved repeats (the machine is shared). NumPy's large
temporaries come from fresh pages by default, so the same loop is also worth timing with
MALLOC_TOP_PAD_=268435456 in the environment (glibc keeps freed heap for reuse).
"""
import argparse
import os
import pathlib
import sys
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
from _bootstrap import load_ember  # noqa: E402

load_ember()
import numpy as np  # noqa: E402

from ember.engine import rng  # noqa: E402
from ember.engine.rng import Sampler  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))
from test_rng import _rms_errors as errors, _slope as slope  # noqa: E402  (the tests' own measure)


def best_time(fns, repeats, inner=5):
    """Best mean time (s) of each function over `repeats` interleaved rounds of `inner` calls."""
    best = [np.inf] * len(fns)
    for _ in range(repeats):
        for i, f in enumerate(fns):
            t = time.perf_counter()
            for _ in range(inner):
                f()
            best[i] = min(best[i], (time.perf_counter() - t) / inner)
    return best


def timings(repeats):
    n = 65536
    pix, smp = np.arange(n), np.full(n, 37)
    cases = [(p, k) for k in (1, 2, 4) for p in ("random", "sobol")]
    samplers = {p: Sampler(1, pix, smp, pattern=p) for p in ("random", "sobol")}
    rows = np.flatnonzero(np.random.default_rng(0).random(n) < 0.6)
    fns = [lambda p=p, k=k: samplers[p].get(3, None, k) for p, k in cases]
    fns += [lambda p=p: samplers[p].get(3, rows, 2) for p in ("random", "sobol")]
    fns += [lambda p=p: Sampler(1, pix, smp, pattern=p) for p in ("random", "sobol")]
    t = best_time(fns, repeats)
    print(f"get on {n} rows, ms (best of {repeats}):")
    for (p, k), s in zip(cases, t):
        print(f"  {p:6s} k={k}: {s * 1e3:6.3f}")
    for p, s in zip(("random", "sobol"), t[len(cases):len(cases) + 2]):
        print(f"  {p:6s} k=2, 60% of rows: {s * 1e3:6.3f}")
    for p, s in zip(("random", "sobol"), t[len(cases) + 2:]):
        print(f"  {p:6s} constructor: {s * 1e3:6.3f}")

    # Bit reversal to a double: swap steps (used) against four byte-table gathers.
    y = np.random.default_rng(1).integers(0, 2 ** 32, 2 * n, dtype=np.uint64).astype(np.uint32)
    rev8 = np.array([int(f"{b:08b}"[::-1], 2) for b in range(256)])
    tables = [rev8 * 2.0 ** (-8 * (p + 1)) for p in range(4)]

    def by_swaps():
        x = y.copy()
        rng._reverse_bits_(x, np.empty_like(x))
        u = x.astype(np.float64)
        u *= 2.0 ** -32
        return u

    def by_tables():
        v = y.view(np.uint8).reshape(-1, 4)
        u, t = np.empty(len(y)), np.empty(len(y))
        np.take(tables[0], v[:, 0], out=u, mode="clip")
        for p in range(1, 4):
            u += np.take(tables[p], v[:, p], out=t, mode="clip")
        return u

    assert np.array_equal(by_swaps(), by_tables())
    a, b = best_time([by_swaps, by_tables], repeats)
    print(f"reverse + to double, {2 * n} words: swaps {a * 1e3:.3f} ms, byte tables {b * 1e3:.3f} ms")


def smooth(x, y):
    return np.exp(-x) * np.sin(3 * y) + x * y


SMOOTH_INTEGRAL = (1 - np.exp(-1)) * (1 - np.cos(3)) / 3 + 0.25


def disk(x, y):
    return ((x - 0.5) ** 2 + (y - 0.5) ** 2 < 0.16).astype(np.float64)


DISK_INTEGRAL = np.pi * 0.16


def convergence():
    for label, f, exact in (("smooth f = exp(-x) sin(3y) + xy", smooth, SMOOTH_INTEGRAL),
                            ("disk indicator (centre 0.5, radius 0.4)", disk, DISK_INTEGRAL)):
        print(f"{label}, 2000 pixels:")
        ns, er = errors("random", f, exact, 1024, 2000)
        _, es = errors("sobol", f, exact, 1024, 2000)
        for n, a, b in zip(ns, er, es):
            if n >= 16:
                print(f"  N={n:5d}: rms random {a:.3e}  sobol {b:.3e}  ratio {b / a:.4f}")
        print(f"  slopes N=16..1024: random {slope(ns, er, 16, 1024):.3f}, sobol {slope(ns, es, 16, 1024):.3f}")
    # The slope over several seeds and groups: how much the fitted exponent varies.
    s = [slope(*errors("sobol", disk, DISK_INTEGRAL, 1024, 1000, seed=sd, dim=d), 16, 1024)
         for sd in range(4) for d in (0, 5)]
    print(f"  sobol slope over 8 (seed, group), 1000 pixels: min {min(s):.3f} max {max(s):.3f}")


def cornell(spps, seeds):
    """relMSE of the bundled Cornell box (64x64) against Cycles' reference, per pattern, at equal
    samples: render.py's own path, with the render traced in this process (worker processes
    would import the unpatched sampler) and the tracer's Sampler given the pattern."""
    import contextlib
    import functools
    import io
    import re

    import render  # noqa: F401  (repository root)
    from ember.engine.integrators import path as tracer  # where the Sampler is made
    from ember.engine.parallel import workers
    root = pathlib.Path(__file__).resolve().parents[1]
    workers.can_spawn = lambda: False
    spent = [0.0]

    class TimedSampler(Sampler):  # time spent drawing numbers, for the sampler's share
        def get(self, *a, **kw):
            t = time.perf_counter()
            try:
                return super().get(*a, **kw)
            finally:
                spent[0] += time.perf_counter() - t
    print("Cornell box 64x64, relMSE against tests/data/cornell_box_cycles.exr (mean over seeds):")
    for spp in spps:
        line = f"  {spp:5d} spp:"
        res = {}
        for pattern in ("random", "sobol"):
            tracer.Sampler = functools.partial(TimedSampler, pattern=pattern)
            errs, secs = [], []
            spent[0] = 0.0
            for seed in range(seeds):
                out = io.StringIO()
                t = time.perf_counter()
                saved = os.dup(1)  # Blender's own messages go to the C-level stdout
                with open(os.devnull, "w") as devnull, contextlib.redirect_stdout(out):
                    os.dup2(devnull.fileno(), 1)
                    try:
                        code = render.run([str(root / "scenes/cornell_box.blend"), "-o", "/tmp/rng_study.exr",
                                           "--samples", str(spp), "--seed", str(seed), "--resolution", "64x64",
                                           "--reference", str(root / "tests/data/cornell_box_cycles.exr"),
                                           "--no-progress"])
                    finally:
                        os.dup2(saved, 1)
                        os.close(saved)
                secs.append(time.perf_counter() - t)
                assert code == 0, out.getvalue()
                errs.append(float(re.findall(r"relMSE (\S+) \(eps", out.getvalue())[-1]))
            res[pattern] = np.mean(errs)
            line += f"  {pattern} {np.mean(errs):.3e} ({np.mean(secs):.1f} s, get {spent[0] / seeds:.2f} s)"
        print(line + f"  random/sobol {res['random'] / res['sobol']:.2f}")
    tracer.Sampler = Sampler


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--cornell", default="", help="comma-separated spp for the Cornell box study")
    ap.add_argument("--seeds", type=int, default=4)
    args = ap.parse_args()
    if args.cornell:
        cornell([int(v) for v in args.cornell.split(",")], args.seeds)
        sys.exit(0)
    timings(15 if args.quick else 60)
    if not args.quick:
        convergence()
