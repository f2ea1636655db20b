"""Speed against error: every Ember integrator and Cycles, every scene, a ladder of budgets.

    python bench/run.py --quick          # ~1.5 min: the quick scenes, budgets 1, 2, 4 s
    python bench/run.py                  # ~23 min: every scene, budgets 1-30 s, 2048x2048 memory
    python bench/run.py --scenes cornell_box,interior --budgets 1,4 --no-cycles --out /tmp/b

For each scene of bench/scenes.py that exists and has a reference (bench/references.py):
one progressive Ember render per integrator, snapshotted at each budget, and a Cycles
render per budget plus one at Ember's final sample count (equal samples), all at the
references' resolution (64x64; --resolution N: N x N against bench/references/<scene>_N.exr)
on this machine in this run, one render at a time. Then, on the
Cornell box at 256x256: throughput of Ember and Cycles, embreex alone (bench/probe_embree.py,
1 and 2 threads); and peak memory of render.py at 512x512 (and 2048x2048 without --quick)
in separate processes. Every measurement records the 1-minute load average.

Writes OUT/results.json (everything), OUT/report.md (tables) and OUT/<scene>.png (log-log
relMSE against time); OUT defaults to bench/results/quick or bench/results/full.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import pathlib
import platform
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))

QUICK_BUDGETS = (1.0, 2.0, 4.0)
FULL_BUDGETS = (1.0, 2.0, 4.0, 8.0, 16.0, 30.0)
THROUGHPUT_SIZE = 256


class BenchError(Exception):
    """Bad input: one line, exit code 2."""


def _budgets(text):
    try:
        values = sorted(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds such as 1,2,4, got {text!r}")
    if not values or values[0] <= 0:
        raise argparse.ArgumentTypeError("budgets must be positive")
    return tuple(values)


def parse_args(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="quick scenes, short budgets, no 2048x2048")
    ap.add_argument("--scenes", help="comma-separated scene names (default: all, or the quick ones)")
    ap.add_argument("--integrators", help="comma-separated Ember integrators (default: all)")
    ap.add_argument("--variant", action="append", default=[], metavar="LABEL=INTEGRATOR:KEY=VALUE,...",
                    help="an extra, labelled Ember run with non-default settings, e.g. "
                         "'photon_no_rp=photon:radiance_photons=0' (repeatable; bool values 0/1)")
    ap.add_argument("--budgets", type=_budgets, help="comma-separated seconds")
    ap.add_argument("--no-cycles", action="store_true", help="Ember only")
    ap.add_argument("--no-throughput", action="store_true", help="skip the 256x256 throughput study")
    ap.add_argument("--no-memory", action="store_true", help="skip the peak-memory renders")
    ap.add_argument("--resolution", type=int, metavar="N",
                    help="N x N renders against bench/references/<scene>_N.exr (default: the references' 64)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", help="output folder")
    ap.add_argument("--merge", action="store_true",
                    help="keep the scenes of an existing OUT/results.json that this run does not measure")
    ap.add_argument("--add-runs", action="store_true",
                    help="with --merge: add this run's renders to the scenes already there (same-named "
                         "runs replaced) instead of replacing those scenes; e.g. a --variant with "
                         "--integrators none --no-cycles")
    return ap.parse_args(argv)


def _load():
    return os.getloadavg()[0]


def _machine():
    cpu = ""
    try:
        with open("/proc/cpuinfo") as fh:
            cpu = next((l.split(":", 1)[1].strip() for l in fh if l.startswith("model name")), "")
    except OSError:
        pass
    import bpy
    import embreex
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(),
            "blender": bpy.app.version_string, "numpy": np.__version__,
            "embreex": getattr(embreex, "__version__", "")}


def _reference(scene, resolution):
    from ember.engine import imageio
    from bench.references import reference_path
    path = reference_path(scene, resolution)
    if not path.exists():
        return None
    ch, header = imageio.read_exr(path)
    ref = np.stack([ch[c] for c in "RGB"], axis=-1).astype(np.float64)
    var = np.stack([ch[f"var.{c}"] for c in "RGB"], axis=-1).astype(np.float64) if "var.R" in ch else None
    keep = ("renderer", "samples", "runs", "total_samples", "time_s", "blender_version", "mitsuba_version",
            "agreement", "point_light_note")
    return {"path": str(path.relative_to(ROOT)), "image": ref, "variance": var,
            "header": {k: (v.decode() if isinstance(v, bytes) else v) for k, v in header.items() if k in keep}}


def _points(snapshots, ref):
    """Metrics per snapshot."""
    from bench import metrics
    return [dict(budget=s.budget, seconds=s.seconds, samples=s.samples,
                 **metrics.evaluate(s.image, ref["image"], ref["variance"]))
            for s in snapshots]


def _open(path, resolution):
    import bpy
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    scene.render.use_border = False
    return scene


def parse_variant(text):
    """'label=integrator:key=value,key=value' -> (label, integrator, {key: value})."""
    try:
        label, rest = text.split("=", 1)
        integ, _, opts = rest.partition(":")
        settings = {}
        for kv in filter(None, opts.split(",")):
            k, v = kv.split("=", 1)
            settings[k.strip()] = _value(v.strip())
    except ValueError:
        raise BenchError(f"--variant {text!r}: expected LABEL=INTEGRATOR:KEY=VALUE,...")
    return label.strip(), integ.strip(), settings


def _value(v):
    for conv in (int, float):
        try:
            return conv(v)
        except ValueError:
            pass
    return {"true": True, "false": False}.get(v.lower(), v)


def _keep_images(store, key, snapshots):
    """Every snapshot's image into `store` (saved as OUT/images.npz: region metrics and
    figures can be recomputed without re-rendering)."""
    for i, s in enumerate(snapshots):
        store[f"{key}|{i}"] = np.asarray(s.image, np.float32)


def bench_scene(bs, args, budgets, integrators, resolution, images=None):
    from bench import metrics, render_cycles, render_ember
    ref = _reference(bs, resolution)
    result = {"note": bs.note, "file": f"scenes/{bs.file}"}
    if ref is None:
        result["skipped"] = (f"no reference: run  python bench/references.py --only {bs.name}"
                             f" --resolution {resolution}")
        return result
    h, w = ref["image"].shape[:2]
    result["reference"] = {"path": ref["path"], **ref["header"], "relmse_ref": (
        None if ref["variance"] is None else metrics.reference_rel_mse(ref["image"], ref["variance"]))}
    result["resolution"] = f"{w}x{h}"
    runs = {}
    final_samples = None
    jobs = [(integ, integ, {}) for integ in integrators] + [parse_variant(v) for v in args.variant]
    for label, integ, overrides in jobs:
        scene = _open(bs.path, w)
        load0 = _load()
        try:
            r = render_ember.render(scene, integ, budgets, args.seed, overrides)
            if not r.snapshots:
                raise RuntimeError(f"no image within {max(budgets):g} s")
        except RuntimeError as e:
            runs[f"ember:{label}"] = {"error": str(e)}
            print(f"  ember:{label}: failed: {e}", flush=True)
            continue
        st = r.stats
        if images is not None:
            _keep_images(images, f"{bs.name}|ember:{label}", r.snapshots)
        if integ == "path" and not overrides:
            final_samples = r.snapshots[-1].samples  # equal samples: the path tracer's count
        runs[f"ember:{label}"] = {
            "points": _points(r.snapshots, ref),
            "throughput": {"samples_per_second": r.snapshots[-1].samples / max(st.elapsed, 1e-9),
                           "rays_per_second": st.rays_per_second, "rays": st.rays,
                           "rays_per_path": st.rays / max(r.snapshots[-1].samples * w * h, 1),
                           "embree_share": st.embree_share, "processes": st.processes},
            "phases": {"export_s": r.export_seconds, "build_s": st.build_seconds,
                       "trace_s": r.session_seconds - st.build_seconds,
                       "other_s": r.wall_seconds - r.export_seconds - r.session_seconds},
            "stage_seconds": dict(st.stage_seconds), "counters": {k: str(v) for k, v in st.counters.items()},
            "integrator": integ, "overrides": overrides, "settings": _integrator_settings(scene),
            "auto": list(getattr(st, "auto", ())),  # integrator auto: its choice, the analysis, what it left out
            "film_nonfinite_samples": int(st.nonfinite), "stopped_by": st.stopped_by,
            "load": [load0, _load()]}
        print(f"  ember:{label}: {r.snapshots[-1].samples:.0f} spp in {st.elapsed:.1f} s, "
              f"relMSE {runs[f'ember:{label}']['points'][-1]['relmse']:.3e}", flush=True)
    if not args.no_cycles:
        scene = _open(bs.path, w)
        load0 = _load()
        extra = [max(1, round(final_samples))] if final_samples else []
        c = render_cycles.render(scene, budgets, args.seed, extra_samples=extra)
        pts = _points(c.snapshots, ref)
        if images is not None:
            _keep_images(images, f"{bs.name}|cycles", c.snapshots)
        runs["cycles"] = {"points": pts[:len(budgets)], "equal_samples": pts[len(budgets):],
                          "samples_per_second": c.samples_per_second, "sync_s": c.sync_seconds,
                          "load": [load0, _load()]}
        print(f"  cycles: {c.samples_per_second:.1f} spp/s, relMSE at {budgets[-1]:g} s "
              f"{pts[len(budgets) - 1]['relmse']:.3e}", flush=True)
    result["runs"] = runs
    return result


def _integrator_settings(scene):
    """The photon settings the render used (the integrators' defaults unless the .blend sets
    them): scene.ember's photon/ppm properties by name."""
    e = scene.ember
    keys = [k for k in e.bl_rna.properties.keys()
            if any(w in k for w in ("photon", "gather", "radius", "alpha", "knn", "k_nearest", "caustic"))]
    out = {}
    for k in keys:
        v = getattr(e, k)
        out[k] = v if isinstance(v, (int, float, str, bool)) else str(v)
    return out


def throughput(args, seconds):
    """Cornell box at 256x256: Ember and Cycles samples/s and rays/s, embreex alone."""
    import bpy
    from bench import probe_embree, render_cycles, render_ember
    from bench.scenes import by_name
    from ember.engine.blender.export import export_scene
    n = THROUGHPUT_SIZE
    bs = by_name("cornell_box")
    out = {"scene": bs.name, "resolution": f"{n}x{n}", "seconds": seconds}
    scene = _open(bs.path, n)
    load0 = _load()
    r = render_ember.render(scene, "path", (seconds,), args.seed)
    st = r.stats
    spp = r.snapshots[-1].samples
    out["ember"] = {"samples": spp, "render_s": st.elapsed, "samples_per_second": spp / st.elapsed,
                    "rays_per_second": st.rays_per_second, "rays_per_path": st.rays / (spp * n * n),
                    "embree_share": st.embree_share, "processes": st.processes, "build_s": st.build_seconds,
                    "export_s": r.export_seconds, "load": [load0, _load()]}
    print(f"  ember: {out['ember']['samples_per_second']:.2f} spp/s, "
          f"{st.rays_per_second / 1e6:.2f} M rays/s, Embree {st.embree_share:.0%}", flush=True)
    if not args.no_cycles:
        scene = _open(bs.path, n)
        load0 = _load()
        c = render_cycles.render(scene, (seconds,), args.seed)
        s = c.snapshots[-1]
        cyc_sps = s.samples / s.seconds
        out["cycles"] = {"samples": s.samples, "render_s": s.seconds, "samples_per_second": cyc_sps,
                         "rays_per_second_estimate": cyc_sps * n * n * out["ember"]["rays_per_path"],
                         "load": [load0, _load()]}
        print(f"  cycles: {cyc_sps:.2f} spp/s", flush=True)
    scene = _open(bs.path, n)
    sc, _ = export_scene(bpy.context.evaluated_depsgraph_get(),
                         overrides=dict(width=n, height=n, border=(0, 0, n, n)))
    load0 = _load()
    probe = probe_embree.probe(sc, size=n, seconds=2.0 if args.quick else 6.0)
    out["embreex_alone"] = {str(k): v for k, v in probe.items()}
    out["embreex_alone"]["load"] = [load0, _load()]
    print("  embreex alone: " + ", ".join(f"{k} thread(s) {v['mix'] / 1e6:.2f} M rays/s"
                                          for k, v in probe.items()), flush=True)
    return out


def memory(args):
    from bench import memory as mem
    from bench.scenes import by_name
    blend = by_name("cornell_box").path
    sizes = [(8, 8), (512, 512)] + ([] if args.quick else [(2048, 2048)])
    out = []
    for w, h in sizes:
        m = mem.measure(blend, w, h, samples=1)
        out.append(m)
        print(f"  {m['resolution']}: peak {m['peak_tree_mib']:.0f} MiB (all processes), "
              f"{m['peak_main_mib']:.0f} MiB (render process)", flush=True)
    return out


def main(argv=None):
    args = parse_args(sys.argv[1:] if argv is None else argv)
    from bench.scenes import available
    budgets = args.budgets or (QUICK_BUDGETS if args.quick else FULL_BUDGETS)
    names = [n.strip() for n in args.scenes.split(",")] if args.scenes else None
    scenes, notes = available(names, quick=args.quick)
    if names and not scenes:
        raise BenchError("; ".join(notes) or "no scenes to run")
    out_dir = pathlib.Path(args.out) if args.out else ROOT / "bench" / "results" / ("quick" if args.quick else "full")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise BenchError(f"cannot create {out_dir}: {e.strerror or e}")

    from _bootstrap import load_ember
    ember = load_ember()
    ember.register()
    from ember.engine.integrators import NAMES as INTEGRATORS
    integrators = [i.strip() for i in args.integrators.split(",")] if args.integrators else list(INTEGRATORS)
    if args.integrators == "none":
        integrators = []
    unknown = sorted(set(integrators) - set(INTEGRATORS))
    if unknown:
        raise BenchError(f"unknown integrator(s) {', '.join(unknown)} (Ember has: {', '.join(INTEGRATORS)})")
    from bench.metrics import EPS
    from bench.references import RESOLUTION
    resolution = args.resolution or RESOLUTION
    if resolution <= 0:
        raise BenchError(f"--resolution must be positive, got {resolution}")

    t_start = time.perf_counter()
    results = {"run": {"quick": args.quick, "date": datetime.datetime.now().isoformat(timespec="seconds"),
                       "budgets": list(budgets), "seed": args.seed, "resolution": resolution, "integrators": integrators,
                       "machine": _machine(), "load_start": _load(), "notes": notes,
                       "relmse_eps": EPS}, "scenes": {}}
    for n in notes:
        print("note:", n, flush=True)
    images = {}
    old_images = {}
    if args.merge and (out_dir / "results.json").exists():
        old = json.loads((out_dir / "results.json").read_text())
        measured = set() if args.add_runs else {bs.name for bs in scenes}
        results["scenes"] = {k: v for k, v in old.get("scenes", {}).items() if k not in measured}
        results["run"] = dict(old["run"]) if args.add_runs else results["run"]
        results["run"]["merged" if not args.add_runs else "added"] = (
            {"earlier_run": old["run"], "scenes_kept": sorted(results["scenes"])} if not args.add_runs else
            old["run"].get("added", []) + [{"date": datetime.datetime.now().isoformat(timespec="seconds"),
                                            "variants": args.variant, "integrators": integrators,
                                            "scenes": [bs.name for bs in scenes], "load_start": _load()}])
        if (out_dir / "images.npz").exists():
            with np.load(out_dir / "images.npz") as z:
                old_images = {k: z[k] for k in z.files if k.split("|")[0] not in measured}

    def save():
        (out_dir / "results.json").write_text(json.dumps(results, indent=1))
        fresh = {"|".join(k.split("|")[:2]) for k in images}
        kept = {k: v for k, v in old_images.items() if "|".join(k.split("|")[:2]) not in fresh}
        np.savez_compressed(out_dir / "images.npz", **kept, **images)

    for bs in scenes:
        print(f"{bs.name}:", flush=True)
        new = bench_scene(bs, args, budgets, integrators, resolution, images)
        if args.add_runs and "runs" in results["scenes"].get(bs.name, {}) and "runs" in new:
            results["scenes"][bs.name]["runs"].update(new["runs"])
        else:
            results["scenes"][bs.name] = new
        if "skipped" in results["scenes"][bs.name]:
            print("  skipped:", results["scenes"][bs.name]["skipped"], flush=True)
        save()  # a long run keeps what it measured if a later step fails
    if not args.no_throughput:
        print(f"throughput, cornell_box {THROUGHPUT_SIZE}x{THROUGHPUT_SIZE}:", flush=True)
        results["throughput"] = throughput(args, 5.0 if args.quick else 20.0)
    if not args.no_memory:
        print("peak memory, cornell_box (render.py, 1 sample):", flush=True)
        results["memory"] = memory(args)
    where = results["run"]["added"][-1] if args.add_runs and results["run"].get("added") else results["run"]
    where["load_end"] = _load()
    where["wall_s"] = time.perf_counter() - t_start

    from bench import report
    save()
    report.write(results, out_dir)
    print(f"wrote {out_dir}/report.md, results.json and plots in {where['wall_s']:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except BenchError as e:
        print(f"bench/run.py: error: {e}", file=sys.stderr)
        sys.exit(2)
    except KeyboardInterrupt:
        print("Interrupted.", file=sys.stderr)
        sys.exit(130)
