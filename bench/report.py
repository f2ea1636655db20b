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


def write(results, out_dir):
    out_dir = pathlib.Path(out_dir)
    run = results["run"]
    m = run["machine"]
    lines = [f"# Ember speed against error ({'quick' if run['quick'] else 'full'} run, {run['date']})", "",
             f"{m['cpu']}, {m['cores']} cores (shared: 1-minute load average {run['load_start']:.1f} at the start, "
             f"{run.get('load_end', float('nan')):.1f} at the end); Blender {m['blender']}, numpy {m['numpy']}, "
             f"embreex {m['embreex']}, Python {m['python']}. Budgets {', '.join(f'{b:g}' for b in run['budgets'])} s, "
             f"seed {run['seed']}, one run per point. {EPS_TEXT}. Wall time {run.get('wall_s', 0):.0f} s.", ""]
    lines += [f"- {n}" for n in run["notes"]] + ([""] if run["notes"] else [])
    lines += ["## Headline: Ember's last image (time limit = the largest budget)", ""] + headline(results) + [""]
    lines += machine_tables(results)
    lines += throughput_tables(results)
    lines += ["## Error against time, per scene", ""]
    for name, sc in results["scenes"].items():
        lines += scene_table(name, sc)
        if "runs" in sc:
            plot(name, sc, out_dir / f"{name}.png")
            lines += [f"![{name}]({name}.png)", ""]
    (out_dir / "report.md").write_text("\n".join(lines))


if __name__ == "__main__":
    folder = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "bench/results/quick")
    write(json.loads((folder / "results.json").read_text()), folder)
    print(f"wrote {folder}/report.md")
