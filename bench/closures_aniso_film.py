"""Anisotropy, thin film, the physical conductor, the Refraction BSDF, Principled transmission's
Specular Tint and Beckmann glass against Cycles 5.0 (bench/results/closures/aniso_film.md).

    ./dev python bench/closures_aniso_film.py [--samples 64] [--runs 8] [--ref-samples 2048]
                                              [--ref-runs 4] [--cpu-rounds 6] [--no-cpu]

The scenes are the two rows of spheres the tests compare (tests/test_anisotropy.py SPHERES,
tests/test_thin_film.py SPHERES; tests/feature_spheres.py: an area light and a dim white world,
orthographic), one feature per sphere. Per sphere (its disc inside 0.9 of the radius):
- bias: Ember's mean over the disc at `samples` x `runs` against Cycles' reference
  (`ref-samples` x `ref-runs`), with its standard error (run to run, both sides);
- relMSE at equal samples: the mean over the disc of (x - ref)^2 / (ref^2 + 1e-2) of one run
  of `samples`, averaged over the runs, less the reference's own (bench/metrics.py), for Ember
  and for Cycles, and their ratio;
- bias in a white furnace: every sphere with the light removed under a white world, Ember
  against Cycles per channel at equal samples (no fireflies: a sharper bias check);
- CPU per path before / after on scenes without any of these features: bench/cpu_ab.py on the
  Cornell box and the glossy Cornell box, --base (git archive, default main) against this
  checkout.
"""
from __future__ import annotations

import argparse
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
import feature_spheres as fs  # noqa: E402
from ember.engine.metrics import EPS  # noqa: E402

OUT = ROOT / "bench" / "results" / "closures" / "aniso_film.md"


def _discs(n):
    """(n, H, W) bool: each sphere's disc (the union of its quadrants)."""
    masks = fs.quadrant_masks(n)
    return np.stack([np.any([m for i, _, m in masks if i == k], axis=0) for k in range(n)])


def _rel_mse(images, ref, disc):
    """Mean over runs of the disc's relMSE of each run (runs, H, W, 3) against ref (H, W, 3)."""
    r = ref[disc]
    return float(np.mean([np.mean((img[disc] - r) ** 2 / (r * r + EPS)) for img in images]))


def measure(bpy, specs, args):
    import ember
    ember.register()
    try:
        sc = fs.build(bpy, specs)
        ref_images = fs.cycles_images(bpy, sc, args.ref_samples, args.ref_runs, seed=1000)
        cycles = fs.cycles_images(bpy, sc, args.samples, args.runs, seed=100)
        emb = fs.ember_images(bpy, args.samples, args.runs, seed=1)
    finally:
        ember.unregister()
    ref = ref_images.mean(axis=0)
    ref_var = ref_images.var(axis=0, ddof=1) / len(ref_images)
    rows = []
    for k, disc in enumerate(_discs(len(specs))):
        e = emb[:, disc].mean(axis=(1, 2))
        r = ref_images[:, disc].mean(axis=(1, 2))
        bias = e.mean() / r.mean() - 1.0
        se = np.sqrt(e.var(ddof=1) / len(e) + r.var(ddof=1) / len(r)) / r.mean()
        own = float(np.mean(ref_var[disc] / (ref[disc] ** 2 + EPS)))
        rel_e = _rel_mse(emb, ref, disc) - own
        rel_c = _rel_mse(cycles, ref, disc) - own
        rows.append(dict(name=specs[k]["name"], bias=bias, se=se, rel_e=rel_e, rel_c=rel_c, own=own))
    return rows


def furnace(bpy, specs, args):
    """Per sphere and channel, Ember / Cycles - 1 and its standard error in a white furnace (the
    light removed, the world white): a bias check without the area light's fireflies."""
    import ember
    ember.register()
    try:
        sc = fs.build(bpy, specs)
        bpy.data.objects.remove(bpy.data.objects["Area"])
        sc.world.node_tree.nodes["Background"].inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
        cycles = fs.cycles_images(bpy, sc, args.furnace_samples, args.furnace_runs, seed=300)
        emb = fs.ember_images(bpy, args.furnace_samples, args.furnace_runs, seed=30)
    finally:
        ember.unregister()
    lines = [f"| {spec['name']} |" for spec in specs]
    for k, disc in enumerate(_discs(len(specs))):
        e, c = emb[:, disc].mean(axis=1), cycles[:, disc].mean(axis=1)  # (runs, 3)
        d = e.mean(axis=0) / c.mean(axis=0) - 1.0
        se = np.sqrt(e.var(axis=0, ddof=1) / len(e) + c.var(axis=0, ddof=1) / len(c)) / c.mean(axis=0)
        lines[k] += " | ".join(f" {x:+.2%} ({y:.2%})" for x, y in zip(d, se)) + " |"
    return lines


def cpu_ab(base_rev: str, scene: str, rounds: int) -> str:
    """bench/cpu_ab.py's report on `scene`: base_rev of this repository against this checkout."""
    with tempfile.TemporaryDirectory(prefix="ember_base_") as base:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", base_rev], check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", base], input=archive, check=True)
        out = subprocess.run([sys.executable, str(ROOT / "bench" / "cpu_ab.py"), base, str(ROOT), "--rounds", str(rounds),
                              "--scene", scene], capture_output=True, text=True, cwd=ROOT)
    return (out.stdout + out.stderr).strip()


def table(title, rows, args) -> str:
    lines = [f"### {title}", "",
             f"Ember and Cycles at {args.samples} samples x {args.runs} runs; reference Cycles at "
             f"{args.ref_samples} x {args.ref_runs}.", "",
             "| sphere | bias vs reference | its s.e. | relMSE Ember | relMSE Cycles | ratio | reference's own |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        ratio = r["rel_e"] / r["rel_c"] if r["rel_c"] > 0 else float("nan")
        lines.append(f"| {r['name']} | {r['bias']:+.2%} | {r['se']:.2%} | {r['rel_e']:.4g} | {r['rel_c']:.4g} | "
                     f"{ratio:.2f} | {r['own']:.2g} |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--ref-samples", type=int, default=2048)
    ap.add_argument("--ref-runs", type=int, default=4)
    ap.add_argument("--cpu-rounds", type=int, default=6)
    ap.add_argument("--no-cpu", action="store_true")
    ap.add_argument("--furnace-samples", type=int, default=128)
    ap.add_argument("--furnace-runs", type=int, default=6)
    ap.add_argument("--base", default="main", help="the revision measured before (default main)")
    ap.add_argument("--cpu-scenes", nargs="*", default=["cornell_box", "cornell_glossy"])
    args = ap.parse_args(argv)
    import test_anisotropy
    import test_thin_film
    bpy = fs.bpy_module()
    parts = ["# Anisotropy, thin film, physical conductor, Refraction BSDF against Cycles 5.0", "",
             "Written by `bench/closures_aniso_film.py` (one machine, one run). Targets: bias within 1 % of the "
             "reference, relMSE at equal samples at most 1.5x Cycles', CPU per path within 2 % on a scene "
             "without these features. relMSE: mean over the sphere's disc of (x - ref)^2 / (ref^2 + 0.01), "
             "less the reference's own.", ""]
    parts.append(table("Anisotropy (tests/test_anisotropy.py SPHERES)", measure(bpy, test_anisotropy.SPHERES, args),
                       args))
    parts.append("")
    parts.append(table("Thin film, conductor, refraction, transmission tint, Beckmann glass "
                       "(tests/test_thin_film.py SPHERES)", measure(bpy, test_thin_film.SPHERES, args), args))
    parts += ["", "### Bias in a white furnace (no light, white world)", "",
              f"Ember / Cycles - 1 of each sphere's mean per channel (its standard error), both at "
              f"{args.furnace_samples} samples x {args.furnace_runs} runs: without the area light's fireflies the "
              "bias shows at the 0.1 % level.", "",
              "| sphere | R | G | B |", "|---|---:|---:|---:|"]
    parts += furnace(bpy, test_anisotropy.SPHERES + test_thin_film.SPHERES, args)
    if not args.no_cpu:
        parts += ["", "### CPU per path on scenes without these features (bench/cpu_ab.py)", "",
                  f"First root: {args.base}; second: this branch. cornell_glossy has microfacet and glass lobes "
                  "(the code paths changed), cornell_box diffuse ones only."]
        for scene in args.cpu_scenes:
            parts += ["", f"{scene}:", "", "```", cpu_ab(args.base, scene, args.cpu_rounds), "```"]
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text("\n".join(parts) + "\n")
    print("\n".join(parts))


if __name__ == "__main__":
    main()
