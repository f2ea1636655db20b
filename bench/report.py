"""results.json -> report.md (tables) and one log-log relMSE-against-time plot per scene.

    python bench/report.py bench/results/full      # redraw from a saved results.json

Equal-time comparisons interpolate Cycles' relMSE at Ember's time on the straight log-log
line through Cycles' two nearest points (outside Cycles' range: the nearest point moved
along slope -1, the rate of any unbiased estimator), using relMSE with the reference's own
expected relMSE subtracted (bench/metrics.py), so both renderers are measured against the
true image. A ratio > 1 means Ember's error is larger.
"""
from __future__ import annotations

import json
import pathlib
import sys

import numpy as np

EPS_TEXT = "relMSE = mean((x - r)^2 / (r^2 + 1e-2)), no outlier rejection"


def _fmt(v, spec=".3g"):
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "-"
    return format(v, spec)


def cycles_at(points, seconds, key="relmse_corrected"):
    """Cycles' error at `seconds`, interpolated log-log (slope -1 outside its range)."""
    pts = sorted((p["seconds"], p.get(key, p["relmse"])) for p in points if p.get(key, p["relmse"]) > 0)
    if not pts:
        return None
    t, e = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    x = np.log(seconds)
    if x <= t[0]:
        return float(np.exp(e[0] - (x - t[0])))
    if x >= t[-1]:
        return float(np.exp(e[-1] - (x - t[-1])))
    return float(np.exp(np.interp(x, t, e)))


def _ratio(a, b):
    return a / b if a is not None and b and a > 0 else None


def scene_table(name, sc):
    lines = [f"### {name}", "", f"{sc['note']}. `{sc['file']}`, {sc.get('resolution', '')}."]
    if "skipped" in sc:
        return lines + ["", f"Skipped: {sc['skipped']}", ""]
    ref = sc["reference"]
    lines.append(f"Reference `{ref['path']}`: {ref.get('renderer', 'Cycles')}, "
                 f"{ref.get('total_samples', '?')} samples, {_fmt(ref.get('time_s'), '.0f')} s; "
                 f"its own expected relMSE {_fmt(ref.get('relmse_ref'))}."
                 + (f" {ref['agreement']}" if ref.get("agreement") else ""))
    lines += ["", "| renderer | budget s | time s | samples/px | relMSE | relMSE - ref | RMSE | HDR-FLIP | NaN px |",
              "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for rname, run in sc["runs"].items():
        if "error" in run:
            lines.append(f"| {rname} | failed: {run['error']} |||||||")
            continue
        end = "end" if rname.startswith("ember") else "-"
        rows = [dict(p, budget=end if p["budget"] is None else f"{p['budget']:g}") for p in run["points"]]
        rows += [dict(p, budget="equal spp") for p in run.get("equal_samples", [])]
        for p in rows:
            lines.append(f"| {rname} | {p['budget']} | "
                         f"{p['seconds']:.2f} | {p['samples']:.1f} | {p['relmse']:.3e} | "
                         f"{_fmt(p.get('relmse_corrected'), '.3e')} | {p['rmse']:.3e} | {p['flip']:.4f} | {p['nan']} |")
    lines.append("")
    return lines


def throughput_tables(results):
    lines = ["## Throughput and phases (error-ladder renders, Ember's whole run; build includes the "
             "worker processes' start-up)", "",
             "| scene | integrator | samples/s | M rays/s | rays/path | Embree share | export s | build s | "
             "trace s | other s | Cycles samples/s | load (1 min) |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for name, sc in results["scenes"].items():
        for rname, run in sc.get("runs", {}).items():
            if not rname.startswith("ember:") or "error" in run:
                continue
            t, ph = run["throughput"], run["phases"]
            cyc = sc["runs"].get("cycles", {}).get("samples_per_second")
            lines.append(f"| {name} | {rname[6:]} | {t['samples_per_second']:.2f} | {t['rays_per_second'] / 1e6:.2f} | "
                         f"{t['rays_per_path']:.2f} | {t['embree_share']:.0%} | {ph['export_s']:.2f} | "
                         f"{ph['build_s']:.2f} | {ph['trace_s']:.2f} | {ph['other_s']:.2f} | {_fmt(cyc, '.1f')} | "
                         f"{run['load'][0]:.1f}-{run['load'][1]:.1f} |")
    return lines + [""]


def headline(results):
    """One row per scene: error at the largest budget, Ember against Cycles at equal time and
    at equal samples."""
    lines = ["| scene | Ember integrator | time s | samples/px | relMSE | Cycles relMSE, same time | ratio | "
             "Cycles relMSE, same samples | ratio | Ember / Cycles samples/s |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name, sc in results["scenes"].items():
        runs = sc.get("runs", {})
        cyc = runs.get("cycles")
        for rname, run in runs.items():
            if not rname.startswith("ember:") or "error" in run:
                continue
            p = run["points"][-1]
            e = p.get("relmse_corrected", p["relmse"])
            c_time = cycles_at(cyc["points"], p["seconds"]) if cyc else None
            eq = cyc["equal_samples"][0] if cyc and cyc.get("equal_samples") and rname == "ember:path" else None
            c_spp = eq.get("relmse_corrected", eq["relmse"]) if eq else None
            sps = _ratio(run["throughput"]["samples_per_second"], cyc["samples_per_second"]) if cyc else None
            lines.append(f"| {name} | {rname[6:]} | {p['seconds']:.1f} | {p['samples']:.0f} | {_fmt(e, '.3e')} | "
                         f"{_fmt(c_time, '.3e')} | {_fmt(_ratio(e, c_time), '.2f')} | {_fmt(c_spp, '.3e')} | "
                         f"{_fmt(_ratio(e, c_spp), '.2f')} | {_fmt(sps, '.3f')} |")
    return lines


def machine_tables(results):
    lines = []
    tp = results.get("throughput")
    if tp:
        e, c, probe = tp["ember"], tp.get("cycles"), tp["embreex_alone"]
        lines += [f"## Cornell box {tp['resolution']}, {tp['seconds']:g} s budget", "",
                  "| | samples/s | M rays/s | rays/path | Embree share | load (1 min) |", "|---|---:|---:|---:|---:|---|",
                  f"| Ember path ({e['processes']} worker processes) | {e['samples_per_second']:.2f} | "
                  f"{e['rays_per_second'] / 1e6:.2f} | {e['rays_per_path']:.2f} | {e['embree_share']:.0%} | "
                  f"{e['load'][0]:.1f}-{e['load'][1]:.1f} |"]
        if c:
            lines.append(f"| Cycles | {c['samples_per_second']:.2f} | {c['rays_per_second_estimate'] / 1e6:.2f} "
                         f"(estimate: Cycles' paths/s x Ember's rays/path) | - | - | {c['load'][0]:.1f}-{c['load'][1]:.1f} |")
        lines += ["", "embreex alone on the same scene (bench/probe_embree.py), M rays/s:", "",
                  "| threads | camera | bounce | shadow | equal mix |", "|---:|---:|---:|---:|---:|"]
        for k, v in probe.items():
            if k != "load":
                lines.append(f"| {k} | {v['camera'] / 1e6:.2f} | {v['bounce'] / 1e6:.2f} | {v['shadow'] / 1e6:.2f} | "
                             f"{v['mix'] / 1e6:.2f} |")
        lines += [f"", f"Load during the probe: {probe['load'][0]:.1f}-{probe['load'][1]:.1f}.", ""]
    mem = results.get("memory")
    if mem:
        base = mem[0]["peak_tree_mib"]
        lines += ["## Peak memory (render.py, cornell_box, 1 sample, separate process each)", "",
                  "| resolution | all processes MiB | render process MiB | above the 8x8 baseline MiB | s | load |",
                  "|---|---:|---:|---:|---:|---:|"]
        for m in mem:
            lines.append(f"| {m['resolution']} | {m['peak_tree_mib']:.0f} | {m['peak_main_mib']:.0f} | "
                         f"{m['peak_tree_mib'] - base:.0f} | {m['seconds']:.1f} | {m['load']:.1f} |")
        lines.append("")
    return lines


def plot_region(name, reg, path):
    """Caustic region: relMSE (raw) and the region's mean ratio against time."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 4.2))
    for rname, pts in reg["runs"].items():
        pts = sorted((p for p in pts if not p["equal_samples"]), key=lambda p: p["seconds"])
        t = [p["seconds"] for p in pts]
        style = "o-" if rname.startswith("ember") else "s--"
        ax.loglog(t, [max(p["relmse"], 1e-6) for p in pts], style, label=_label(rname))
        bx.semilogx(t, [p["mean_ratio"] for p in pts], style, label=_label(rname))
    ax.axhline(reg["reference_relmse"], color="grey", lw=0.8, ls=":", label="reference's own relMSE")
    ax.set_title(f"{name}: relMSE in the caustic region ({reg['pixels']} px)", fontsize=8)
    bx.axhspan(0.97, 1.03, color="lightgreen", alpha=0.4, label="within 3 %")
    bx.set_ylim(0.8, 1.2)
    bx.set_title(f"{name}: region mean / reference's (clipped to 0.8-1.2)", fontsize=8)
    for a in (ax, bx):
        a.set_xlabel("seconds to the image")
        a.grid(True, which="both", lw=0.3)
        a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot(name, sc, path, eps_text=EPS_TEXT):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4.2))
    for rname, run in sc["runs"].items():
        if "error" in run:
            continue
        pts = sorted(run["points"], key=lambda p: p["seconds"])
        t = [p["seconds"] for p in pts]
        e = [p["relmse"] for p in pts]
        ax.loglog(t, e, "o-" if rname.startswith("ember") else "s--", label=rname.replace("ember:", "Ember "))
    floor = sc["reference"].get("relmse_ref")
    if floor:
        ax.axhline(floor, color="grey", lw=0.8, ls=":", label="reference's own relMSE")
    lo, hi = ax.get_xlim()
    ylo, yhi = ax.get_ylim()
    if lo > 0 and ylo > 0:
        xs = np.array([lo, hi])
        ax.loglog(xs, np.sqrt(ylo * yhi) * np.sqrt(lo * hi) / xs, color="lightgrey", lw=0.8, label="slope -1")
    ax.set_xlabel("seconds to the image (Ember: after export; Cycles: after sync)")
    ax.set_ylabel("relMSE")
    ax.set_title(f"{name} ({sc['resolution']}): {eps_text}", fontsize=8)
    ax.grid(True, which="both", lw=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _label(rname):
    return rname.replace("ember:", "")


def at_budget(points, b, last):
    """The first image past budget b; for the largest budget (`last`) the end image when no
    progress update came after it (the run ended with its last batches)."""
    p = next((q for q in points if q["budget"] == b), None)
    if p is None and b == last:
        p = next((q for q in points if q["budget"] is None), None)
    return p


def pivot_table(name, sc, key="relmse_corrected", region=None):
    """Error against time at a glance: one row per budget, one column per renderer, the
    value at that renderer's first image past the budget (its time in brackets)."""
    runs = {r: v for r, v in sc.get("runs", {}).items() if "error" not in v}
    if not runs:
        return []
    budgets = sorted({p["budget"] for v in runs.values() for p in v["points"] if p["budget"] is not None})
    head = "| budget s | " + " | ".join(_label(r) for r in runs) + " |"
    lines = [head, "|---:|" + "---:|" * len(runs)]
    for b in budgets:
        cells = []
        for r, v in runs.items():
            pts = region[r] if region is not None else v["points"]
            p = at_budget(pts, b, budgets[-1])
            val = None if p is None else p.get(key, p["relmse"])
            cells.append("-" if p is None else f"{_fmt(val, '.3e')} ({p['seconds']:.1f} s)")
        lines.append(f"| {b:g} | " + " | ".join(cells) + " |")
    return lines


def _load_images(out_dir):
    path = pathlib.Path(out_dir) / "images.npz"
    if not path.exists():
        return None
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def caustic_regions(results, out_dir):
    """Region metrics of every saved snapshot of the caustic scenes (bench/regions.py), into
    results['scenes'][name]['caustic_region']; needs OUT/images.npz and the references."""
    images = _load_images(out_dir)
    if images is None:  # images.npz is not committed (5 MB): the metrics it gave are
        saved = pathlib.Path(out_dir) / "caustic_region.json"
        if saved.exists():
            for name, reg in json.loads(saved.read_text()).items():
                if name in results["scenes"]:
                    results["scenes"][name]["caustic_region"] = reg
        return
    root = pathlib.Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(root))
    from _bootstrap import load_ember
    load_ember()
    from ember.engine import imageio
    from bench import regions
    for name, sc in results["scenes"].items():
        if name not in regions.CAUSTIC_SCENES or "runs" not in sc:
            continue
        ch, _ = imageio.read_exr(root / sc["reference"]["path"])
        ref = np.stack([ch[c] for c in "RGB"], -1).astype(np.float64)
        var = np.stack([ch[f"var.{c}"] for c in "RGB"], -1).astype(np.float64)
        mask = regions.caustic_region(name, ref)
        out = {"pixels": int(mask.sum()), "bbox": [*map(int, np.argwhere(mask).min(0)), *map(int, np.argwhere(mask).max(0))],
               "reference_mean": float(ref[mask].mean()),
               "reference_relmse": float(np.mean(var[mask] / (ref[mask] ** 2 + 1e-2))),
               "reference_mean_rel_sigma": float(np.sqrt(var[mask].sum()) / ref[mask].sum()), "runs": {}}
        for rname, run in sc["runs"].items():
            if "error" in run:
                continue
            pts = run["points"] + run.get("equal_samples", [])
            rows = []
            for i, p in enumerate(pts):
                img = images.get(f"{name}|{rname}|{i}")
                if img is None:
                    continue
                m = regions.region_metrics(img, ref, mask, var)
                rows.append(dict(budget=p["budget"], seconds=p["seconds"], samples=p["samples"],
                                 equal_samples=i >= len(run["points"]), **m))
            out["runs"][rname] = rows
        sc["caustic_region"] = out


def caustic_targets(results, out_dir=None):
    """The caustic targets from the region metrics, as table lines."""
    lines = []
    for name, sc in results["scenes"].items():
        reg = sc.get("caustic_region")
        if not reg:
            continue
        runs = {r: [p for p in v if not p["equal_samples"]] for r, v in reg["runs"].items()}
        lines += [f"### {name}: caustic region", "",
                  f"{reg['pixels']} pixels (rows {reg['bbox'][0]}-{reg['bbox'][2]}, columns {reg['bbox'][1]}-{reg['bbox'][3]}), "
                  f"bench/regions.py; the reference's mean there {reg['reference_mean']:.3f} "
                  f"(its own 1-sigma uncertainty {reg['reference_mean_rel_sigma']:.2%}), its own expected relMSE there "
                  f"{reg['reference_relmse']:.2e} (subtracted in 'relMSE - ref').", "",
                  "relMSE in the region minus the reference's own (first image past each budget, its time in brackets):", ""]
        lines += pivot_table(name, sc, "relmse_corrected", runs) + [""]
        lines += ["Region mean / reference's region mean:", ""]
        lines += pivot_table(name, sc, "mean_ratio", runs) + [""]
        if out_dir is not None:
            plot_region(name, reg, pathlib.Path(out_dir) / f"{name}_region.png")
            lines += [f"![{name} caustic region]({name}_region.png)", ""]
        if name == "caustic":
            lines += ["Target: at equal time 8 s and 30 s, relMSE in the region of `photon` and `ppm` at most "
                      "1/5 of Cycles' and at most 1/10 of Ember's path tracer (both read at the photon run's own time on "
                      "their log-log line, slope -1 outside their range; relMSE less the reference's own):", "",
                      "| integrator | budget | time s | relMSE - ref | raw relMSE | Cycles, same time | ratio (<= 0.2) | "
                      "path, same time | ratio (<= 0.1) | met |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
            for integ in [r for r in runs if r.startswith("ember:") and r != "ember:path"]:
                for b in (8.0, 30.0):
                    p = at_budget(runs[integ], b, 30.0)
                    if p is None:
                        continue
                    e = p["relmse_corrected"]
                    c = cycles_at(runs["cycles"], p["seconds"]) if "cycles" in runs else None
                    pa = cycles_at(runs["ember:path"], p["seconds"]) if "ember:path" in runs else None
                    rc, rp = _ratio(e, c), _ratio(e, pa)
                    if e <= 0:
                        rc = rp = 0.0
                    met = rc is not None and rp is not None and rc <= 0.2 and rp <= 0.1
                    lines.append(f"| {_label(integ)} | {b:g} | {p['seconds']:.1f} | {e:.3e} | {p['relmse']:.3e} | "
                                 f"{_fmt(c, '.3e')} | {_fmt(rc, '.3f')} | {_fmt(pa, '.3e')} | {_fmt(rp, '.3f')} | "
                                 f"{'met' if met else 'not met'} |")
            lines.append("")
        if name == "caustic_point":
            lines += ["Target: the point-light caustic within 3 % of the reference's caustic energy (region mean) "
                      "in under 10 s; every image before 10 s:", "",
                      "| renderer | budget | time s | region mean / reference | within 3 % |", "|---|---:|---:|---:|---|"]
            for rname, pts in runs.items():
                for p in pts:
                    if p["seconds"] < 10.0:
                        ok = abs(p["mean_ratio"] - 1) <= 0.03
                        lines.append(f"| {_label(rname)} | {_fmt(p['budget'], 'g')} | {p['seconds']:.1f} | "
                                     f"{p['mean_ratio']:.4f} | {'yes' if ok else 'no'} |")
            lines.append("")
    return lines


def photon_stage_table(results):
    lines = ["| scene | run | settings | stages s (all rounds) | figures |", "|---|---|---|---|---|"]
    any_ = False
    for name, sc in results["scenes"].items():
        for rname, run in sc.get("runs", {}).items():
            if not rname.startswith("ember:") or "error" in run or run.get("integrator", rname[6:]) == "path":
                continue
            any_ = True
            st = run.get("settings", {})
            keys = ("photons", "caustic_photons", "photon_k", "gather_rays", "radiance_photons") if run.get(
                "integrator", "") != "ppm" else ("photons", "caustic_photons", "ppm_radius", "ppm_alpha")
            sets = ", ".join(f"{k}={st[k]:.3g}" if isinstance(st.get(k), float) else f"{k}={st.get(k)}" for k in keys)
            stages = ", ".join(f"{k} {v:.2f}" for k, v in run.get("stage_seconds", {}).items())
            figs = "; ".join(run.get("counters", {}).values())
            lines.append(f"| {name} | {_label(rname)} | {sets} | {stages} | {figs} |")
    return lines + [""] if any_ else []


def write(results, out_dir):
    out_dir = pathlib.Path(out_dir)
    run = results["run"]
    m = run["machine"]
    lines = [f"# Ember speed against error ({out_dir.name} run, {run['date']})", "",
             f"{m['cpu']}, {m['cores']} cores (shared: 1-minute load average {run['load_start']:.1f} at the start, "
             f"{run.get('load_end', float('nan')):.1f} at the end); Blender {m['blender']}, numpy {m['numpy']}, "
             f"embreex {m['embreex']}, Python {m['python']}. Budgets {', '.join(f'{b:g}' for b in run['budgets'])} s, "
             f"seed {run['seed']}, one run per point. {EPS_TEXT}. Wall time {run.get('wall_s', 0):.0f} s.", ""]
    lines += [f"- {n}" for n in run["notes"]] + ([""] if run["notes"] else [])
    if run.get("merged"):
        lines += [f"Scenes {', '.join(run['merged']['scenes_kept'])} are from the earlier run of "
                  f"{run['merged']['earlier_run']['date']} (load {run['merged']['earlier_run']['load_start']:.1f} at its "
                  f"start); the others from this one.", ""]
    for a in run.get("added", []):
        lines += [f"Added on {a['date']} (load {a['load_start']:.1f}-{a.get('load_end', float('nan')):.1f}), to "
                  f"{', '.join(a['scenes'])}: {', '.join(a['variants'] + a['integrators'])} (labelled rows, "
                  "not the defaults).", ""]
    notes = out_dir / "notes.md"
    if notes.exists():  # hand-written reading of the numbers, kept across re-runs
        lines += [notes.read_text().rstrip(), ""]
    tp = out_dir / "photon_throughput.json"
    if tp.exists():
        from bench.photon_throughput import table
        lines += ["## Photon throughput (bench/photon_throughput.py: 1 M photon paths, 2 cores)", ""]
        lines += table(json.loads(tp.read_text())["best"]) + [""]
    lines += ["## Headline: Ember's last image (time limit = the largest budget)", ""] + headline(results) + [""]
    caustic_regions(results, out_dir)
    if any("caustic_region" in sc for sc in results["scenes"].values()):
        lines += ["## Caustic region", ""] + caustic_targets(results, out_dir)
    lines += ["## Error against time (relMSE less the reference's own, first image past each budget)", ""]
    for name, sc in results["scenes"].items():
        if "runs" in sc:
            lines += [f"### {name}", ""] + pivot_table(name, sc) + [""]
    stages = photon_stage_table(results)
    if stages:
        lines += ["## Photon integrators: settings and time per stage (the error-ladder renders)", ""] + stages
    lines += machine_tables(results)
    lines += throughput_tables(results)
    lines += ["## Error against time, per scene", ""]
    for name, sc in results["scenes"].items():
        lines += scene_table(name, sc)
        if "runs" in sc:
            plot(name, sc, out_dir / f"{name}.png")
            lines += [f"![{name}]({name}.png)", ""]
    (out_dir / "report.md").write_text("\n".join(lines))
    if any("caustic_region" in sc for sc in results["scenes"].values()):
        (out_dir / "caustic_region.json").write_text(json.dumps(
            {n: sc["caustic_region"] for n, sc in results["scenes"].items() if "caustic_region" in sc}, indent=1))


if __name__ == "__main__":
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
    folder = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "bench/results/quick")
    write(json.loads((folder / "results.json").read_text()), folder)
    print(f"wrote {folder}/report.md")
