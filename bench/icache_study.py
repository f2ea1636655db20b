"""Irradiance cache study: the cache against brute-force final gathering, gradients at
equal records, the accuracy a, Ward's weight against Tabellion-Lamorlette's.

    ./dev python bench/icache_study.py --parts converged         # converged indirect images (slow)
    ./dev python bench/icache_study.py --parts brute,gradients,accuracy,weights
    ./dev python bench/icache_study.py --report                  # OUT/report.md (with bench/run.py's tables)

Scenes: interior and cornell_box (scenes/*.blend), 64 bounces, seed 0, the integrators'
default settings unless a part says otherwise. Parts:

  converged  the reference for the indirect term at --small x --small: the photon integrator's
             debug view photon_view="indirect" (final gathering alone, no emission, no direct
             light, no caustics) with radiance photons off and 392 gather rays per camera
             sample, as two independent halves of --converged-spp samples each. Same seed and
             photon counts give the same photon map as the cache's; the camera and gather
             streams are shifted to other seeds (rng.Sampler wrapped in this process, threads=1),
             so they share no sample with the runs measured against them. Its own relMSE is
             relMSE(A, B) / 4 (two independent halves), subtracted as bench/metrics.py does.
  brute      (a) brute force against the cache, at --small, threads=1, at --brute-spp samples:
             photon_view="indirect", gather_rays = icache_rays = 392 at every camera sample,
             against icache_view="indirect"; relMSE against the converged indirect; CPU and
             wall time (photon map included; also without it); and the cache at a tenth of
             the brute force's wall time (a time limit: as many passes as fit, records refined).
  gradients  (b) icache with and without gradients (the record set does not depend on the
             flag: checked): indirect view at --small (--gradient-spp samples: the records
             refined, so that their noise does not hide the interpolation error) against the
             converged indirect, and the full image at --res (--spp samples, both cores)
             against the Cycles reference.
  accuracy   (c) a in {0.1, 0.2, 0.35}: records, records per megapixel, share interpolated,
             time per stage and relMSE against Cycles at --res (--spp samples, both cores);
             and the indirect view at --small against the converged indirect.
  weights    (d) records placed with one weight, interpolated with each (the tracing side's
             octree rebuilt with the other weight after every records round; threads=1):
             indirect view at --small against the converged indirect, full image at --res
             against Cycles (--weights-spp samples).

Every measurement records the 1-minute load average. Writes OUT/study.json and OUT/study.md
(OUT: bench/results/icache); --report rewrites OUT/report.md from bench/run.py's
OUT/results.json (bench/report.py) followed by the study's tables.
"""
from __future__ import annotations

import argparse
import contextlib
import datetime
import json
import os
import pathlib
import sys
import tempfile
import time
from types import SimpleNamespace

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))

SCENES = ("interior", "cornell_box")
PARTS = ("converged", "brute", "gradients", "accuracy", "weights")
A_VALUES = (0.1, 0.2, 0.35)
SEED_SHIFT = (1000, 2000)  # the converged halves' camera and gather streams
MAX_DEPTH = 64  # as bench/render_ember.py and the references


def _load():
    return os.getloadavg()[0]


# ----------------------------------------------------------------------------------------------
# Rendering

@contextlib.contextmanager
def shifted_streams(shift):
    """Every sampler but the photons' on seed + shift: the same photon map, independent camera
    and gather samples (the render runs in this process: threads=1)."""
    from ember.engine import rng

    original = rng.Sampler

    class Shifted(original):
        def __init__(self, seed, pixel, sample, pattern="sobol", domain=rng.CAMERA):
            super().__init__(seed if domain == rng.PHOTONS else seed + shift, pixel, sample, pattern, domain)

    rng.Sampler = Shifted
    try:
        yield
    finally:
        rng.Sampler = original


@contextlib.contextmanager
def interpolation_weight(weight):
    """The tracing side interpolates with `weight` whatever icache_weight placed the records
    with (the render process's octree, which decides coverage and placement, keeps it)."""
    from ember.engine.integrators.irradiance import integrator as icache

    cls = icache.IrradianceCacheIntegrator
    original = cls.install

    def install(self, version, arrays):
        original(self, version, arrays)
        if "records.position" in arrays:
            self.octree = icache.RecordOctree(self.records, self.scene.settings.icache_a, weight)

    cls.install = install
    try:
        yield
    finally:
        cls.install = original


class Renderer:
    def __init__(self):
        from _bootstrap import load_ember

        self.ember = load_ember()
        self.ember.register()
        self._scenes = {}
        self._refs = {}
        self._memo = {}

    def scene(self, name, res):
        if (name, res) not in self._scenes:
            import bpy
            from ember.engine.blender.export import export_scene

            bpy.ops.wm.open_mainfile(filepath=str(ROOT / "scenes" / f"{name}.blend"), load_ui=False)
            sc = bpy.context.scene
            sc.render.resolution_x = sc.render.resolution_y = res
            sc.render.resolution_percentage = 100
            sc.render.use_border = False
            self._scenes[name, res], _ = export_scene(bpy.context.evaluated_depsgraph_get(),
                                                      overrides=dict(max_depth=MAX_DEPTH, seed=0))
        return self._scenes[name, res]

    def cycles_reference(self, name, res):
        """(image, its own expected relMSE) of bench/references at res."""
        if (name, res) not in self._refs:
            from bench import metrics
            from bench.references import reference_path
            from bench.scenes import by_name
            from ember.engine import imageio

            path = reference_path(by_name(name), res)
            ch, _ = imageio.read_exr(path)
            ref = np.stack([ch[c] for c in "RGB"], axis=-1).astype(np.float64)
            var = np.stack([ch[f"var.{c}"] for c in "RGB"], axis=-1).astype(np.float64)
            self._refs[name, res] = (ref, metrics.reference_rel_mse(ref, var), str(path.relative_to(ROOT)))
        return self._refs[name, res]

    def render(self, name, res, variant="", **kw):
        """One render; returns (image (H,W,3) float64, facts dict (a copy), the records).
        The indirect views keep the emission camera paths see (light sources, at their
        anti-aliased edges the largest pixel noise): it is taken off, rendered on its own
        (gather_rays=0) from the same camera samples, so the images hold the indirect term alone.
        variant: names a patch in force (interpolation_weight), for the memo of renders."""
        key = (name, res, variant, tuple(sorted(kw.items())))
        if key in self._memo:  # the same render asked for by two parts
            img, facts, integ = self._memo[key]
            return img, json.loads(json.dumps(facts)), integ
        img, facts, integ = self._render(name, res, **kw)
        if kw.get("photon_view") == "indirect" or kw.get("icache_view") == "indirect":
            seen = {k: kw[k] for k in ("threads",) if k in kw}
            seen["samples"] = int(facts["samples"])  # a time-limited render: the passes it made
            emission, _, _ = self._render(name, res, integrator="photon", photon_view="indirect", gather_rays=0,
                                          photons=1000, caustic_photons=0, **seen)
            img = img - emission
        self._memo[key] = img, facts, SimpleNamespace(records=getattr(integ, "records", None))
        return self.render(name, res, variant, **kw)

    def _render(self, name, res, **kw):
        from ember.engine.session import RenderSession

        scene = self.scene(name, res)
        scene = scene.replace(settings=scene.settings.replace(**kw))
        load0, c0, t0 = _load(), time.process_time(), time.perf_counter()
        session = RenderSession(scene)
        stats = session.run()
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        integ = session.integrator
        facts = {"settings": {k: v for k, v in kw.items()}, "resolution": res, "samples": stats.samples,
                 "wall_s": wall, "cpu_s": cpu, "processes": stats.processes, "build_s": stats.build_seconds,
                 "stage_seconds": dict(stats.stage_seconds), "counters": dict(stats.counters),
                 "nonfinite": int(stats.nonfinite), "load": [load0, _load()]}
        if hasattr(integ, "records"):
            n = len(integ.records)
            shaded = integ.interpolated + integ.fallback
            facts.update(records=n, records_per_mpix=n / (res * res / 1e6),
                         interpolated_share=integ.interpolated / shaded if shaded else None)
        return session.film.mean().astype(np.float64), facts, integ


def relmse(image, ref):
    from ember.engine.metrics import rel_mse
    return rel_mse(image, ref)


# ----------------------------------------------------------------------------------------------
# Parts

def _indirect_photon(args):
    """The brute-force indirect view: photon integrator, final gathering alone."""
    return dict(integrator="photon", photon_view="indirect", radiance_photons=False, gather_rays=args.rays,
                icache_rays=args.rays, threads=1)


def _indirect_cache(args, **kw):
    """The cache's indirect view (points no record covers are final-gathered with as many rays),
    with photon-map gathers as the brute force's (the default path-traced gathers converge to
    the true indirect term, not to the photon map's)."""
    return dict(integrator="icache", icache_view="indirect", icache_rays=args.rays, gather_rays=args.rays,
                icache_gather="photon", threads=1, **kw)


def converged(R, args, out, name):
    path = out / f"converged_{name}_{args.small}.npz"
    if path.exists() and not args.force:
        z = np.load(path)
        if int(z["spp"]) == args.converged_spp and int(z["rays"]) == args.rays:
            return _converged_facts(z["A"], z["B"], json.loads(str(z["facts"])))
    halves, facts = [], []
    for shift in SEED_SHIFT:
        with shifted_streams(shift):
            img, f, _ = R.render(name, args.small, variant=f"seed shift {shift}", samples=args.converged_spp,
                                 **_indirect_photon(args))
        f["seed_shift"] = shift
        halves.append(img)
        facts.append(f)
        print(f"  converged half (seed shift {shift}): {f['wall_s']:.0f} s, {f['counters'].get('photons')}", flush=True)
    np.savez_compressed(path, A=halves[0].astype(np.float32), B=halves[1].astype(np.float32),
                        spp=args.converged_spp, rays=args.rays, facts=json.dumps(facts))
    z = np.load(path)
    return _converged_facts(z["A"], z["B"], facts)


def _converged_facts(A, B, facts):
    A, B = A.astype(np.float64), B.astype(np.float64)
    ref = 0.5 * (A + B)
    return ref, {"halves": facts, "spp": 2 * facts[0]["samples"], "own_relmse": relmse(A, B) / 4.0,
                 "photons": facts[0]["counters"].get("photons"), "mean": float(ref.mean())}


def _against(img, ref, own):
    e = relmse(img, ref)
    return {"relmse": e, "relmse_corrected": e - own, "mean_ratio": float(img.mean() / ref.mean())}


def part_converged(R, args, out, name, res):
    _, facts = converged(R, args, out, name)
    res["converged"][name] = facts
    print(f"  converged indirect: {facts['spp']} spp x {args.rays} gather rays, own relMSE "
          f"{facts['own_relmse']:.2e}", flush=True)


def part_brute(R, args, out, name, res):
    ref, cf = converged(R, args, out, name)
    rows = []
    for spp in args.brute_spp:
        for label, kw in (("brute force", _indirect_photon(args)), ("icache", _indirect_cache(args))):
            img, f, _ = R.render(name, args.small, samples=spp, **kw)
            f.update(label=label, **_against(img, ref, cf["own_relmse"]))
            f["photon_map_s"] = f["stage_seconds"].get("photons", 0.0)
            f["photons"] = f["counters"].get("photons")
            rows.append(f)
            print(f"  {label} {spp} spp: relMSE {f['relmse_corrected']:.2e} (corrected), cpu {f['cpu_s']:.1f} s, "
                  f"wall {f['wall_s']:.1f} s, load {f['load'][0]:.1f}", flush=True)
        for rays in args.extra_rays:  # more rays per record (brute force keeps args.rays)
            img, f, _ = R.render(name, args.small, samples=spp, **{**_indirect_cache(args), "icache_rays": rays})
            f.update(label=f"icache, {rays} rays per record", **_against(img, ref, cf["own_relmse"]))
            f["photon_map_s"] = f["stage_seconds"].get("photons", 0.0)
            f["photons"] = f["counters"].get("photons")
            rows.append(f)
        b = next(f for f in rows if f["label"] == "brute force" and f["samples"] == spp)
        # The cache at a tenth of the brute force's time: as many passes as fit, the records
        # refined between blocks (the time limit counts the whole render; the brute force's
        # CPU time, which a loaded machine does not inflate as it does the wall time). The
        # limit is 9 % of it: the render ends at a whole block, up to ~5 % past its limit.
        img, f, _ = R.render(name, args.small, samples=1 << 20, time_limit=0.09 * min(b["cpu_s"], b["wall_s"]),
                             **_indirect_cache(args))
        f.update(label="icache, 1/10 of the brute force's time", **_against(img, ref, cf["own_relmse"]))
        f["photon_map_s"] = f["stage_seconds"].get("photons", 0.0)
        f["photons"] = f["counters"].get("photons")
        rows.append(f)
        for c in rows[rows.index(b) + 1:]:
            if b["photons"] != c["photons"] or b["photons"] != cf["photons"]:
                print(f"  warning: photon maps differ: {b['photons']} / {c['photons']} / {cf['photons']}", flush=True)
            c["error_ratio"] = c["relmse_corrected"] / b["relmse_corrected"]
            c["time_ratio_cpu"] = c["cpu_s"] / b["cpu_s"]
            c["time_ratio_wall"] = c["wall_s"] / b["wall_s"]
            c["target_met"] = bool(c["error_ratio"] <= 1.2 and c["time_ratio_cpu"] <= 0.1)
            print(f"  {c['label']} {spp} spp: relMSE {c['relmse_corrected']:.2e}, {c['error_ratio']:.2f}x brute force "
                  f"in {c['time_ratio_cpu']:.3f}x its CPU time", flush=True)
    res["brute"][name] = {"converged": cf, "rows": rows}


def part_gradients(R, args, out, name, res):
    entry = res["gradients"].setdefault(name, {})
    for key in args.images:
        d, recs = {}, {}
        for grad in (True, False):
            if key == "small":
                ref, cf = converged(R, args, out, name)
                img, f, integ = R.render(name, args.small, samples=args.gradient_spp, icache_gradients=grad,
                                         **_indirect_cache(args))
                d[grad] = {**f, **_against(img, ref, cf["own_relmse"])}
            else:
                cyc, own, path = R.cycles_reference(name, args.res)
                img, f, integ = R.render(name, args.res, samples=args.spp, icache_gradients=grad, icache_a=0.2,
                                         icache_weight="ward", integrator="icache", threads=0)
                d[grad] = {**f, **_against(img, cyc, own), "reference": path, "reference_own_relmse": own}
            recs[grad] = integ.records.position
            print(f"  {key}, gradients {grad}: {f['records']} records, relMSE {d[grad]['relmse_corrected']:.2e}",
                  flush=True)
        entry[key] = {"with": d[True], "without": d[False], "same_records": bool(np.array_equal(recs[True], recs[False])),
                      "ratio": d[False]["relmse_corrected"] / d[True]["relmse_corrected"]}


def part_accuracy(R, args, out, name, res):
    entry = res["accuracy"].setdefault(name, {})
    for key in args.images:
        rows = []
        for a in A_VALUES:
            if key == "small":
                ref, cf = converged(R, args, out, name)
                img, f, _ = R.render(name, args.small, samples=args.brute_spp[-1], icache_a=a, **_indirect_cache(args))
                f.update(a=a, **_against(img, ref, cf["own_relmse"]))
            else:
                cyc, own, path = R.cycles_reference(name, args.res)
                img, f, _ = R.render(name, args.res, samples=args.spp, icache_gradients=True, icache_a=a,
                                     icache_weight="ward", integrator="icache", threads=0)
                f.update(a=a, **_against(img, cyc, own), reference=path, reference_own_relmse=own)
            rows.append(f)
            print(f"  {key}, a = {a}: {f['records']} records, relMSE {f['relmse_corrected']:.2e}, stages {_stages(f)}",
                  flush=True)
        entry[key] = rows


def part_weights(R, args, out, name, res):
    entry = res["weights"].setdefault(name, {})
    for key in args.images:
        rows = []
        for place in ("ward", "tabellion"):
            for interp in ("ward", "tabellion"):
                with interpolation_weight(interp):
                    if key == "small":
                        ref, cf = converged(R, args, out, name)
                        img, f, _ = R.render(name, args.small, samples=args.brute_spp[-1], icache_weight=place,
                                             variant=interp, **_indirect_cache(args))
                        f.update(_against(img, ref, cf["own_relmse"]))
                    else:
                        cyc, own, path = R.cycles_reference(name, args.res)
                        # the patch needs the tracing side in this process; without it, both cores
                        swap = place != interp
                        img, f, _ = R.render(name, args.res, samples=args.weights_spp, icache_gradients=True,
                                             icache_a=0.2, icache_weight=place, variant=interp if swap else "",
                                             integrator="icache", threads=1 if swap else 0)
                        f.update(_against(img, cyc, own), reference=path, reference_own_relmse=own)
                f.update(placed_with=place, interpolated_with=interp)
                rows.append(f)
                print(f"  {key}, placed {place}, interpolated {interp}: {f['records']} records, "
                      f"{_share(f)} interpolated, relMSE {f['relmse_corrected']:.2e}", flush=True)
        entry[key] = rows


# ----------------------------------------------------------------------------------------------
# Tables

def _stages(f):
    return ", ".join(f"{k} {v:.1f}" for k, v in f["stage_seconds"].items())


def _share(f):
    s = f.get("interpolated_share")
    return "-" if s is None else f"{s:.1%}"


def markdown(res):
    run = res.get("run", {})
    L = ["## Irradiance cache study (`bench/icache_study.py`)", "",
         f"Run {run.get('date', '?')}; relMSE = mean((x - r)^2 / (r^2 + 1e-2)), the reference's own "
         "expected relMSE subtracted (\"corrected\"); load = 1-minute load average at the start of each render.",
         ""]
    conv = res.get("converged", {})
    if conv:
        L += ["### The converged indirect term", "",
              "| scene | samples x gather rays | photon map | own relMSE | mean |", "|---|---|---|---:|---:|"]
        for name, c in conv.items():
            L.append(f"| {name} | {c['spp']} x {c['halves'][0]['settings']['gather_rays']} | {c['photons']} | "
                     f"{c['own_relmse']:.2e} | {c['mean']:.4f} |")
        L.append("")
    if res.get("brute"):
        L += ["### (a) Brute-force final gathering against the cache (indirect term, one thread)", "",
              "| scene | samples | method | relMSE (corrected) | mean / converged | CPU s | wall s | photon map s | "
              "records | interpolated | load | cache / brute: error, CPU time |",
              "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
        for name, d in res["brute"].items():
            for f in d["rows"]:
                ratio = (f"{f['error_ratio']:.2f}x, {f['time_ratio_cpu']:.3f}x "
                         f"({'met' if f['target_met'] else 'not met'})") if "error_ratio" in f else ""
                L.append(f"| {name} | {f['samples']} | {f['label']} | {f['relmse_corrected']:.2e} | "
                         f"{f['mean_ratio']:.3f} | {f['cpu_s']:.1f} | {f['wall_s']:.1f} | {f['photon_map_s']:.2f} | "
                         f"{f.get('records', '-')} | {_share(f)} | {f['load'][0]:.1f} | {ratio} |")
        L.append("")
    what = {"small": "indirect term vs converged", "full": "full image vs Cycles"}
    if res.get("gradients"):
        L += ["### (b) Gradients at equal record count", "",
              "| scene | image | records (with / without) | same record set | relMSE with | relMSE without | "
              "without / with |", "|---|---|---|---|---:|---:|---:|"]
        for name, d in res["gradients"].items():
            for key in ("small", "full"):
                if key not in d:
                    continue
                g = d[key]
                w, wo = g["with"], g["without"]
                L.append(f"| {name} | {what[key]}, {w['resolution']}^2, {w['samples']} spp | {w['records']} / "
                         f"{wo['records']} | {'yes' if g['same_records'] else 'NO'} | {w['relmse_corrected']:.2e} | "
                         f"{wo['relmse_corrected']:.2e} | {g['ratio']:.2f}x |")
        L.append("")
    if res.get("accuracy"):
        L += ["### (c) Accuracy a", "",
              "| scene | image | a | records | per megapixel | interpolated | relMSE | mean / reference | "
              "seconds per stage | total s | load |", "|---|---|---:|---:|---:|---:|---:|---:|---|---:|---:|"]
        for name, d in res["accuracy"].items():
            for key in ("full", "small"):
                for f in d.get(key, []):
                    L.append(f"| {name} | {what[key]}, {f['resolution']}^2, {f['samples']} spp | {f['a']} | "
                             f"{f['records']} | {f['records_per_mpix']:.0f} | {_share(f)} | {f['relmse_corrected']:.2e} | "
                             f"{f['mean_ratio']:.3f} | {_stages(f)} | {f['wall_s']:.1f} | {f['load'][0]:.1f} |")
        L.append("")
    if res.get("weights"):
        L += ["### (d) Ward against Tabellion-Lamorlette at equal records", "",
              "| scene | image | placed with | interpolated with | records | interpolated | relMSE | mean / reference |",
              "|---|---|---|---|---:|---:|---:|---:|"]
        for name, d in res["weights"].items():
            for key in ("small", "full"):
                for f in d.get(key, []):
                    L.append(f"| {name} | {what[key]}, {f['resolution']}^2, {f['samples']} spp | {f['placed_with']} | "
                             f"{f['interpolated_with']} | {f['records']} | {_share(f)} | {f['relmse_corrected']:.2e} | "
                             f"{f['mean_ratio']:.3f} |")
        L.append("")
    return "\n".join(L)


def _point_at(points, budget, last=False):
    """The first image past `budget`; for the largest budget (last=True) the end image, taken
    when the time limit (= that budget) stops the render, if no update passed it before."""
    p = next((p for p in points if p["budget"] == budget), None)
    if p is None and last:
        p = next((p for p in points if p["budget"] is None), None)
    return p


def equal_time(results, targets=((8.0, "interior", 0.25), (30.0, "interior", 1 / 3), (8.0, "cornell_box", 1.0))):
    """bench/run.py's equal-time runs: relMSE (less the reference's own) per budget, the targets,
    and the cache's records and stages."""
    from bench.report import cycles_at

    run = results["run"]
    L = ["## Equal time (`bench/run.py`)", "",
         f"{run.get('resolution', 64)}x{run.get('resolution', 64)}, budgets {', '.join(f'{b:g}' for b in run['budgets'])} s, "
         "one progressive render per Ember integrator (the first image past each budget), one Cycles render per "
         "budget; relMSE less the reference's own; a cell is relMSE (seconds, samples/px); '-': no image yet.", ""]
    for name, sc in results["scenes"].items():
        runs = sc.get("runs", {})
        if not runs:
            continue
        names = [r for r in runs if r != "cycles"] + (["cycles"] if "cycles" in runs else [])
        L += [f"### {name}", "", "| budget s | " + " | ".join(n.replace("ember:", "") for n in names) + " |",
              "|---:|" + "---:|" * len(names)]
        for b in run["budgets"]:
            cells = []
            for n in names:
                p = None if "error" in runs[n] else _point_at(runs[n]["points"], b, b == max(run["budgets"]))
                cells.append("-" if p is None else f"{p['relmse_corrected']:.2e} ({p['seconds']:.1f} s, {p['samples']:.0f})")
            L.append(f"| {b:g} | " + " | ".join(cells) + " |")
        L.append("")
        L += ["| run | records | per megapixel | interpolated | seconds per stage (whole render) | load |",
              "|---|---:|---:|---:|---|---|"]
        for n in names:
            r = runs[n]
            if n == "cycles" or "error" in r:
                continue
            rec = r.get("counters", {}).get("records", "-")
            parts_ = rec.split(" ")
            count = parts_[0] if rec != "-" else "-"
            per = rec.split("(")[1].split(" ")[0] if "(" in rec else "-"
            share = rec.split(", ")[1].split(" ")[0] if ", " in rec else "-"
            stages = ", ".join(f"{k} {v:.1f}" for k, v in r.get("stage_seconds", {}).items())
            L.append(f"| {n.replace('ember:', '')} | {count} | {per} | {share} | {stages} | "
                     f"{r['load'][0]:.1f}-{r['load'][1]:.1f} |")
        L.append("")
    L += ["### Targets", "", "| target | icache | Cycles, same budget | Cycles at icache's time | ratio | |",
          "|---|---:|---:|---:|---:|---|"]
    e = lambda p: "-" if p is None else f"{p['relmse_corrected']:.2e} ({p['seconds']:.1f} s)"  # noqa: E731
    for b, name, bound in targets:
        runs = results["scenes"].get(name, {}).get("runs", {})
        ic, cy = runs.get("ember:icache", {}), runs.get("cycles", {})
        last = b == max(run["budgets"])
        p, c = _point_at(ic.get("points", []), b, last), _point_at(cy.get("points", []), b, last)
        what = f"{name} {b:g} s: <= {bound:.2g} x Cycles"
        if p is None or c is None:
            L.append(f"| {what} | {e(p)} | {e(c)} | - | - | not met (no image by then) |")
            continue
        at = cycles_at(cy["points"], p["seconds"])
        ratio = p["relmse_corrected"] / at
        L.append(f"| {what} | {e(p)} | {e(c)} | {at:.2e} | {ratio:.2f} | {'met' if ratio <= bound else 'not met'} |")
    L += ["", "Ratio: icache's error over Cycles' interpolated at icache's own time (log-log between Cycles' "
          "points, bench/report.py): icache's first image past a budget can come a little after it.", ""]
    return "\n".join(L)


def report(out):
    """OUT/report.md: bench/run.py's tables (bench/report.py), the targets, then the study's."""
    from bench import report as bench_report

    parts = []
    if (out / "results.json").exists():
        results = json.loads((out / "results.json").read_text())
        bench_report.write(results, out)
        parts.append(equal_time(results))
        parts.append((out / "report.md").read_text())
    if (out / "study.md").exists():
        parts.append((out / "study.md").read_text())
    (out / "report.md").write_text("\n\n".join(parts))


# ----------------------------------------------------------------------------------------------

def parse_args(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", default=",".join(PARTS[1:]), help=f"comma-separated, of {', '.join(PARTS)}")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--small", type=int, default=64, help="resolution of the indirect-term studies")
    ap.add_argument("--res", type=int, default=256, help="resolution of the full-image studies (Cycles reference)")
    ap.add_argument("--spp", type=int, default=16, help="samples of the full-image renders")
    ap.add_argument("--brute-spp", default="1,4", help="samples of the brute-force comparison (comma-separated)")
    ap.add_argument("--gradient-spp", type=int, default=64,
                    help="samples of part gradients' indirect images (records refined every 16)")
    ap.add_argument("--converged-spp", type=int, default=8, help="samples of each converged half")
    ap.add_argument("--weights-spp", type=int, default=16, help="samples of part weights' full images (0: none)")
    ap.add_argument("--extra-rays", default="", help="part brute: extra icache rows with these rays per record")
    ap.add_argument("--rays", type=int, default=392, help="gather rays per record and per brute-force sample")
    ap.add_argument("--images", default="small,full",
                    help="parts gradients, accuracy, weights: the indirect term at --small ('small'), the full "
                         "image at --res ('full'), or both")
    ap.add_argument("--force", action="store_true", help="re-render the converged images")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "icache"))
    ap.add_argument("--report", action="store_true", help="only rewrite OUT/report.md")
    args = ap.parse_args(argv)
    args.brute_spp = [int(v) for v in args.brute_spp.split(",")]
    args.images = [v.strip() for v in args.images.split(",")]
    args.extra_rays = [int(v) for v in args.extra_rays.split(",") if v.strip()]
    return args


def main(argv=None):
    args = parse_args(sys.argv[1:] if argv is None else argv)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.report:
        report(out)
        return 0
    parts = [p.strip() for p in args.parts.split(",")]
    bad = sorted(set(parts) - set(PARTS))
    if bad:
        print(f"icache_study.py: error: unknown part(s) {', '.join(bad)} (known: {', '.join(PARTS)})", file=sys.stderr)
        return 2
    R = Renderer()
    path = out / "study.json"
    res = json.loads(path.read_text()) if path.exists() else {}
    for p in PARTS:
        res.setdefault(p, {})
    res["run"] = {"date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"), "load_start": _load(),
                  "args": {k: v for k, v in vars(args).items() if k != "report"}}
    fns = dict(converged=part_converged, brute=part_brute, gradients=part_gradients, accuracy=part_accuracy,
               weights=part_weights)
    for name in args.scenes.split(","):
        for p in parts:
            print(f"{name}: {p}", flush=True)
            fns[p](R, args, out, name, res)
            # merge: other runs of this script may have written other parts or images meanwhile
            latest = json.loads(path.read_text()) if path.exists() else {}
            for q in PARTS:
                latest.setdefault(q, {})
            latest["run"] = res["run"]
            if isinstance(latest[p].get(name), dict) and isinstance(res[p][name], dict) and p != "brute":
                latest[p][name].update(res[p][name])
            else:
                latest[p][name] = res[p][name]
            path.write_text(json.dumps(latest, indent=1))
            (out / "study.md").write_text(markdown(latest))
    return 0


if __name__ == "__main__":
    sys.exit(main())
