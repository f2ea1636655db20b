"""Sheen and coat against Cycles 5.0: bias against a high-sample reference and relMSE at equal
samples (bench/results/closures/coat_sheen.md).

    ./dev python bench/closures_coat_sheen.py [--resolution 48] [--samples 64] [--runs 4]
        [--ref-runs 4] [--ref-samples 2048] [--only NAME ...]

One-feature scenes (tests/test_sheen_coat.py ONE_FEATURE): one sphere under the studio-light
HDRI of the tests, seen by an orthographic camera. A Cycles reference (scenes/reference.py's
unbiased settings, mean of ref-runs runs); then `runs` runs of Cycles and of Ember (the path
tracer) at `samples` spp with seeds the reference does not use. Over the pixels inside the
sphere's disc: bias = Ember's mean over its runs / the reference's - 1, with the standard
error of that ratio from the runs' spread and the reference's variance (target within 1 %);
relMSE (bench/metrics.py, EPS 1e-2) of each run against the reference, averaged over runs,
and the ratio Ember / Cycles (target at most 1.5). The table also gives Cycles' own bias at
equal samples (it shows what noise alone does) and Ember's table against Cycles' sheen table
found in the bpy binary, where it is found (compared, never used).
"""
from __future__ import annotations

import argparse
import os
import pathlib
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
import bpy  # noqa: E402

from _bootstrap import load_ember  # noqa: E402

load_ember()
import ember  # noqa: E402
from ember.engine import imageio  # noqa: E402
from ember.engine.bsdf import sheen  # noqa: E402

from bench.metrics import rel_mse  # noqa: E402
from bench.render_cycles import cycles_reference  # noqa: E402
from test_sheen_coat import HDRI, ONE_FEATURE, spheres_scene  # noqa: E402

OUT = ROOT / "bench" / "results" / "closures" / "coat_sheen.md"
BIAS_TARGET, RATIO_TARGET = 0.01, 1.5


def render_ember(scene, samples: int, seed: int, path: str):
    scene.render.engine = "EMBER"
    e = scene.ember
    e.integrator, e.samples, e.seed = "PATH", samples, seed
    e.time_limit, e.noise_target = 0.0, 0.0
    e.max_depth = cycles_reference.BOUNCES
    cycles_reference.exr_output(scene, path)
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return imageio.read_rgb(path).astype(np.float64), time.perf_counter() - t0


def render_cycles(scene, samples: int, seed: int, path: str):
    cycles_reference.unbiased_cycles(scene, samples)
    return cycles_reference.render_rgb(scene, path, seed)


def disc(size: int) -> np.ndarray:
    """(size, size) bool: pixels whose centre lies inside 0.95 of the sphere's radius (the
    orthographic view of tests/test_sheen_coat.py: the sphere spans 1 / 1.1 of the half-width)."""
    c = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    x, y = np.meshgrid(c, c)
    return np.hypot(x, y) < 0.95 / 1.1


def measure(name: str, args, tmp: str) -> dict:
    scene = spheres_scene([ONE_FEATURE[name]], size=args.resolution)
    mask = disc(args.resolution)
    refs = [render_cycles(scene, args.ref_samples, k, os.path.join(tmp, "ref.exr"))[0] for k in range(args.ref_runs)]
    ref = np.mean(refs, axis=0)
    ref_mean = ref[mask].mean()
    ref_se = np.std([r[mask].mean() for r in refs], ddof=1) / np.sqrt(args.ref_runs)
    row = dict(name=name, ref_mean=ref_mean)
    for who, render in (("cycles", render_cycles), ("ember", render_ember)):
        imgs, secs = [], 0.0
        for k in range(args.runs):
            img, dt = render(scene, args.samples, 1000 + k, os.path.join(tmp, f"{who}.exr"))
            imgs.append(img)
            secs += dt
        means = np.array([img[mask].mean() for img in imgs])
        bias = means.mean() / ref_mean - 1.0
        se = np.hypot(means.std(ddof=1) / np.sqrt(args.runs), ref_se) / ref_mean
        rel = np.mean([rel_mse(img[mask], ref[mask]) for img in imgs])
        row.update({f"{who}_bias": bias, f"{who}_se": se, f"{who}_relmse": rel, f"{who}_seconds": secs / args.runs})
    row["ratio"] = row["ember_relmse"] / max(row["cycles_relmse"], 1e-30)
    print(f"{name}: bias Ember {100 * row['ember_bias']:+.2f} % +- {100 * row['ember_se']:.2f}, Cycles "
          f"{100 * row['cycles_bias']:+.2f} %, relMSE ratio {row['ratio']:.2f}", flush=True)
    return row


def cycles_sheen_table():
    """Cycles' sheen LTC table (a, b, R as (32, 32) [roughness, mu]) from the bpy binary, or
    None: three consecutive 32 x 32 float blocks whose last matches Ember's R within 0.03."""
    path = next((pathlib.Path(p) / "bpy" / "__init__.so" for p in sys.path
                 if (pathlib.Path(p) / "bpy" / "__init__.so").is_file()), None)
    if path is None:
        return None
    raw = path.read_bytes()
    R = sheen.table()["R"]
    probe = R[-1, 16]  # roughness 1, mu ~ 0.52
    for off in range(4):
        a = np.frombuffer(raw[off:off + (len(raw) - off) // 4 * 4], np.float32)
        for c in np.flatnonzero(np.abs(a - probe) < 0.03):
            start = c - (31 * 32 + 16)
            if start < 2048 or start + 1024 > len(a):
                continue
            block = a[start:start + 1024].reshape(32, 32)
            if np.all(np.isfinite(block)) and np.abs(block - R).max() < 0.03:
                t = a[start - 2048:start + 1024].astype(np.float64).reshape(3, 32, 32)
                return dict(a=t[0], b=t[1], R=t[2])
    return None


def table_lines() -> list:
    c = cycles_sheen_table()
    if c is None:
        return ["Cycles' sheen table was not found in the bpy binary."]
    ours = sheen.table()
    lines = ["| table | max abs diff | mean abs diff | mean rel diff where Cycles' R > 0.01 |", "|---|---|---|---|"]
    used = c["R"] > 0.01
    for k in ("a", "b", "R"):
        d = np.abs(ours[k] - c[k])
        rel = (d[used] / np.maximum(np.abs(c[k][used]), 1e-3)).mean()
        lines.append(f"| {k} | {d.max():.4f} | {d.mean():.5f} | {rel:.4f} |")
    return lines


def report(rows, args) -> str:
    lines = ["# Sheen and coat against Cycles", "",
             f"`bench/closures_coat_sheen.py` on one machine, one run ({time.strftime('%Y-%m-%d')}, Blender "
             f"{bpy.app.version_string}, load {os.getloadavg()[0]:.1f}). One sphere per scene under the studio-light "
             f"HDRI `{HDRI}`, {args.resolution} x {args.resolution} pixels (the pixels inside the sphere's disc); "
             f"reference: Cycles {args.ref_runs} x {args.ref_samples} spp; Cycles and Ember {args.runs} runs of "
             f"{args.samples} spp each. Bias = mean / reference mean - 1 (+- one standard error; target within "
             f"{100 * BIAS_TARGET:.0f} %); relMSE = mean((x - r)^2 / (r^2 + 0.01)) per run, averaged; ratio = Ember / "
             f"Cycles (target <= {RATIO_TARGET}).", "",
             "| scene | Ember bias | Cycles bias (equal spp) | relMSE Cycles | relMSE Ember | ratio | s/run Cycles / Ember |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        bias_ok = abs(r["ember_bias"]) <= BIAS_TARGET + 2 * r["ember_se"]
        mark = "" if bias_ok else " **over**"
        rmark = "" if r["ratio"] <= RATIO_TARGET else " **over**"
        lines.append(f"| {r['name']} | {100 * r['ember_bias']:+.2f} % +- {100 * r['ember_se']:.2f}{mark} | "
                     f"{100 * r['cycles_bias']:+.2f} % +- {100 * r['cycles_se']:.2f} | {r['cycles_relmse']:.4g} | "
                     f"{r['ember_relmse']:.4g} | {r['ratio']:.2f}{rmark} | {r['cycles_seconds']:.1f} / "
                     f"{r['ember_seconds']:.1f} |")
    lines += ["", "### Ember's microfiber table (engine/bsdf/sheen_ltc.npz) against Cycles' own", ""] + table_lines()
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--resolution", type=int, default=48)
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--ref-runs", type=int, default=4)
    ap.add_argument("--ref-samples", type=int, default=2048)
    ap.add_argument("--only", nargs="*")
    ap.add_argument("--table-only", action="store_true", help="only compare the sheen tables")
    args = ap.parse_args(argv)
    if args.table_only:
        print("\n".join(table_lines()))
        return
    ember.register()
    rows = []
    with tempfile.TemporaryDirectory(prefix="ember_coat_sheen_") as tmp:
        for name in ONE_FEATURE:
            if not args.only or name in args.only:
                rows.append(measure(name, args, tmp))
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(report(rows, args))
    print("wrote", OUT)


if __name__ == "__main__":
    main()
