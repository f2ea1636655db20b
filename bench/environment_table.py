"""Build time and memory of the environment-map sampling table.

    python bench/environment_table.py [--sizes 8192x4096 16384x8192] [--repeat 3]

For each size: a synthetic float32 sky + sun map (as the exporter delivers it), then the MIS
table, EnvironmentMap(..., compensate=True), timed (best of --repeat) with the peak of NumPy
allocations traced by tracemalloc during the build (the image itself excluded), the table's
resident bytes, and the time of 1M samples and 1M pdf/eval lookups.
"""
import argparse
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from _bootstrap import load_ember  # noqa: E402

load_ember()
from ember.engine.lights.environment import EnvironmentMap  # noqa: E402


def synthetic_map(width, height):
    img = np.empty((height, width, 3), np.float32)
    theta = ((np.arange(height) + 0.5) / height * np.pi).astype(np.float32)
    img[:] = (0.2 + np.cos(theta).clip(0, None))[:, None, None] * np.array([0.5, 0.7, 1.0], np.float32)
    img[height // 5: height // 5 + 4, width // 3: width // 3 + 4] = 1e5
    return img


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", nargs="+", default=["8192x4096"])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    for size in args.sizes:
        w, h = (int(v) for v in size.split("x"))
        img = synthetic_map(w, h)
        best = np.inf
        for _ in range(args.repeat):
            env = None
            tracemalloc.start()
            t0 = time.perf_counter()
            env = EnvironmentMap(img, (1.0, 1.0, 1.0), compensate=True)  # as MIS renders build it
            best = min(best, time.perf_counter() - t0)
            peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
        u = rng.random((1_000_000, 2))
        t0 = time.perf_counter()
        wi = env.sample(u).wi
        t_sample = time.perf_counter() - t0
        t0 = time.perf_counter()
        env.pdf(wi)
        env.eval(wi)
        t_lookup = time.perf_counter() - t0
        print(f"{w}x{h}: build {best:.2f} s (best of {args.repeat}), build peak {peak / 2**20:.0f} MiB, "
              f"table {env.nbytes / 2**20:.0f} MiB, image {img.nbytes / 2**20:.0f} MiB; "
              f"1M samples {t_sample:.2f} s, 1M pdf+eval {t_lookup:.2f} s", flush=True)
        del env, img


if __name__ == "__main__":
    main()
