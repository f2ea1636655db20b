"""Transparent shadows, the shadow terminator and light linking against Cycles 5.0
(bench/results/closures/shadows.md).

    ./dev python bench/closures_shadows.py [--size 32] [--samples 16] [--seeds 8] [--reference 4096]
        [--cpu-base /tmp/base]

Scenes of tests/shadow_scenes.py: the leaf card (an alpha-textured card's shadow under an area
light), the smooth icosphere under a grazing sun with Blender's default terminator offsets,
Geometry Offset 0 and Shading Offset 0.5, and the linking scene (two lights each linked to one
sphere, a blocker collection, an emissive card linked to one sphere). For each:

- bias: the mean over --seeds Ember renders at --samples samples of the image mean, against a
  Cycles render at --reference samples (the reference), with its standard error;
- relMSE (engine/metrics.py, EPS 1e-2) of single renders at --samples samples against the
  reference, Ember's and Cycles' (mean over the seeds), and their ratio;
- noise: the per-pixel standard deviation over the seeds (pooled over the image), Ember's /
  Cycles'.

--cpu-base: a checkout of Ember before this work (git archive main | tar -x -C /tmp/base); the
script then appends bench/cpu_ab.py's CPU time per path on the Cornell box (no transparency,
no linking, flat-shaded) of that checkout against this one. --before: such a checkout, whose
table (this script and tests/shadow_scenes.py copied into it, run there) is added beside.
"""
from __future__ import annotations

import argparse
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

import _bootstrap  # noqa: E402

_bootstrap.load_ember()
import ember  # noqa: E402
from ember.engine.metrics import EPS, rel_mse  # noqa: E402

import shadow_scenes  # noqa: E402
from cycles_renders import cycles_image, ember_image  # noqa: E402

OUT = ROOT / "bench" / "results" / "closures" / "shadows.md"


def _limits(sc):
    """The same light-path limits in both renderers (Ember counts interactions: Cycles' + 1)."""
    sc.cycles.max_bounces = sc.cycles.diffuse_bounces = sc.cycles.glossy_bounces = 3
    sc.cycles.transmission_bounces, sc.cycles.transparent_max_bounces = 3, 8
    sc.ember.max_depth = sc.ember.diffuse_bounces = sc.ember.glossy_bounces = sc.ember.transmission_bounces = 4
    sc.ember.transparent_bounces = 8


CASES = {
    "leaf card (transparent shadow)": lambda size: shadow_scenes.leaf_card(size),
    "terminator, default offsets": lambda size: shadow_scenes.terminator(size),
    "terminator, Geometry Offset 0": lambda size: shadow_scenes.terminator(size, 0.0),
    "terminator, Shading Offset 0.5": lambda size: shadow_scenes.terminator(size, None, 0.5),
    "light and shadow linking": lambda size: shadow_scenes.linking(size),
}


def measure(name, args, tmp) -> dict:
    sc = CASES[name](args.size)
    _limits(sc)
    ref = cycles_image(sc, args.reference, 1000, tmp / "ref.exr")
    e = np.array([ember_image(sc, "PATH", args.samples, s) for s in range(args.seeds)])
    c = np.array([cycles_image(sc, args.samples, s, tmp / f"c{s}.exr") for s in range(args.seeds)])
    means = e.reshape(len(e), -1).mean(axis=1)
    bias = means.mean() / ref.mean() - 1.0
    se = means.std(ddof=1) / np.sqrt(len(means)) / ref.mean()
    cycles_means = c.reshape(len(c), -1).mean(axis=1)
    rel_e = np.mean([rel_mse(x, ref) for x in e])
    rel_c = np.mean([rel_mse(x, ref) for x in c])
    noise = np.sqrt(e.var(axis=0, ddof=1).mean() / c.var(axis=0, ddof=1).mean())
    return dict(bias=bias, se=se, cycles_bias=cycles_means.mean() / ref.mean() - 1.0, rel_e=rel_e, rel_c=rel_c,
                noise=noise)


def cpu_ab(base: str) -> str:
    out = subprocess.run([sys.executable, str(ROOT / "bench" / "cpu_ab.py"), base, str(ROOT), "--rounds", "6"],
                         capture_output=True, text=True, cwd=ROOT)
    return out.stdout + (out.stderr[-2000:] if out.returncode else "")


def before(root: str, args) -> str:
    """The table of the checkout at root (the same measurement with its code)."""
    import shutil
    for rel in ("bench/closures_shadows.py", "tests/shadow_scenes.py"):
        shutil.copy(ROOT / rel, pathlib.Path(root) / rel)
    with tempfile.TemporaryDirectory() as d:
        out = pathlib.Path(d) / "before.md"
        subprocess.run([sys.executable, str(pathlib.Path(root) / "bench" / "closures_shadows.py"), "--size",
                        str(args.size), "--samples", str(args.samples), "--seeds", str(args.seeds), "--reference",
                        str(args.reference), "--out", str(out)], cwd=root, capture_output=True, check=True)
        return "\n".join(line for line in out.read_text().splitlines() if line.startswith("|"))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=32)
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--reference", type=int, default=4096)
    ap.add_argument("--cpu-base", default=None)
    ap.add_argument("--before", default=None)
    ap.add_argument("--out", default=str(OUT))
    args = ap.parse_args(argv)
    ember.register()
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for name in CASES:
            r = measure(name, args, pathlib.Path(d))
            rows.append((name, r))
            print(name, r, flush=True)
    lines = ["# Transparent shadows, shadow terminator, light linking: Ember against Cycles 5.0", "",
             f"Written by `bench/closures_shadows.py` (one machine, one run): {args.size}x{args.size} pixels, "
             f"path tracer, {args.samples} samples per render, {args.seeds} seeds; reference Cycles at "
             f"{args.reference} samples. Bias: Ember's image mean over the seeds / the reference's - 1 "
             "(+- one standard error; Cycles' own at the same samples beside it). relMSE (EPS "
             f"{EPS:g}): mean over the seeds of one render's against the reference. Noise ratio: per-pixel "
             "standard deviation over the seeds, Ember's / Cycles'. Targets: bias within 1 %, relMSE at most "
             "1.5x Cycles'.", "",
             "| scene | bias | Cycles' bias | relMSE Ember | relMSE Cycles | ratio | noise ratio | targets |",
             "|---|---|---|---|---|---|---|---|"]
    for name, r in rows:
        ratio = r["rel_e"] / r["rel_c"]
        met = abs(r["bias"]) <= 0.01 and ratio <= 1.5
        lines.append(f"| {name} | {100 * r['bias']:+.2f} % +- {100 * r['se']:.2f} | {100 * r['cycles_bias']:+.2f} % | "
                     f"{r['rel_e']:.5f} | {r['rel_c']:.5f} | {ratio:.2f} | {r['noise']:.2f} | "
                     f"{'met' if met else 'NOT met'} |")
    if args.before:
        lines += ["", f"## Before this work (the checkout at {args.before}, same measurement)", "",
                  before(args.before, args)]
    if args.cpu_base:
        lines += ["", "## CPU per path without transparency or linking", "",
                  f"`bench/cpu_ab.py {args.cpu_base} . --rounds 6` (Cornell box; the first root is the code before "
                  "this work):", "", "```", cpu_ab(args.cpu_base).strip(), "```"]
    pathlib.Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    pathlib.Path(args.out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    os.environ.setdefault("PYTHONDONTWRITEBYTECODE", "1")
    main()
