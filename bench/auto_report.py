"""The `auto` integrator against the hand-picked ones, from a bench/run.py
results.json with runs of path, photon, icache and auto:

    python bench/run.py --integrators path,photon,icache,auto --budgets 8,30 --no-cycles \
        --no-throughput --no-memory --out bench/results/auto
    python bench/auto_report.py bench/results/auto        # writes bench/results/auto/report.md

Per scene: what the analysis found, what auto chose, auto's relMSE at 8 s and 30 s (the
reference's own noise subtracted), the best of path, photon and icache at each budget, the
ratios (target <= 1.25) and the analysis's time against a 30 s render (target < 5 %).
"""
from __future__ import annotations

import json
import pathlib
import sys

HAND = ("path", "photon", "icache")
TARGET_RATIO, TARGET_SHARE = 1.25, 0.05


def _at(points, budget, last):
    """relMSE (less the reference's own) of the first image past `budget` s; for the largest
    budget (last) the end image when no update came past it (None: no image)."""
    first = [p for p in points if p["budget"] == budget]
    if not first and not last:
        return None
    p = first[0] if first else points[-1]
    value = p.get("relmse_corrected")
    return p["relmse"] if value is None else value


def _found(lines):
    """The analysis in a few words, from auto's stats lines (engine/choice/analysis.py's summary)."""
    out = []
    for line in lines[1:]:
        if line.startswith("lights:"):
            out.append(line[len("lights: "):].split(" (power")[0].split(";")[0])
        elif line.startswith("materials by area:"):
            shares = [part.strip() for part in line.split(":", 1)[1].split(",")]
            out.append(", ".join(p for p in shares if not p.endswith(" 0 %")))
        elif line.startswith("caustics possible"):
            out.append("caustics " + line.split(": ", 1)[1].split(" of")[0])
        elif line.startswith(("open:", "enclosed:")):
            out.append(line.split(" of probe")[0].replace(":", ""))
        elif line.startswith("indirect / direct"):
            ratio, noise = line.split(": ", 1)[1].split(";")[0], line.rsplit(" ", 1)[1]
            out.append(f"indirect/direct {ratio}, noise {noise}")
    return "; ".join(out)


def _seconds(lines):
    for line in lines:
        if line.startswith("analysis:"):
            return float(line.rsplit(",", 1)[1].split()[0])
    return None


def rows(results, budgets):
    out = []
    for name, scene in results["scenes"].items():
        runs = scene.get("runs", {})
        auto = runs.get("ember:auto")
        if not auto or "points" not in auto:
            continue
        row = {"scene": name, "found": _found(auto.get("auto", [])), "analysis_s": _seconds(auto.get("auto", [])),
               "analysis_stage_s": auto.get("stage_seconds", {}).get("analysis"),
               "chose": auto.get("auto", ["?"])[0].split("'")[1] if auto.get("auto") else "?",
               "load": auto.get("load")}
        for b in budgets:
            last = b == budgets[-1]
            hand = {h: _at(runs[f"ember:{h}"]["points"], b, last) for h in HAND
                    if "points" in runs.get(f"ember:{h}", {})}
            hand = {h: v for h, v in hand.items() if v is not None}
            best = min(hand, key=hand.get) if hand else None
            mine = _at(auto["points"], b, last)
            row[b] = dict(auto=mine, best=best, best_value=hand.get(best), hand=hand,
                          ratio=(mine / hand[best]) if best and mine is not None and hand[best] > 0 else None)
        out.append(row)
    return out


def _e(x):
    return "-" if x is None else f"{x:.2e}"


def report(results, out_dir):
    run = results["run"]
    budgets = tuple(run["budgets"])
    table = rows(results, budgets)
    lines = ["# `auto` against the hand-picked integrators", "",
             f"{run['date']}, {run['resolution']}x{run['resolution']}, load {run['load_start']:.1f} at the start, "
             f"{run['load_end']:.1f} at the end; relMSE less the reference's own noise, one run per "
             "point on a shared 2-core machine (1-minute load per row). Target: auto within "
             f"{TARGET_RATIO}x of the best of path, photon, icache (defaults) at each budget; analysis < 5 % of "
             f"{budgets[-1]:g} s.", "",
             "| scene | the analysis found | auto chose | " + " | ".join(f"auto {b:g} s | best at {b:g} s | ratio"
                                                                   for b in budgets)
             + f" | analysis s (share of {budgets[-1]:g} s) | load |",
             "|---|---|---|" + "---:|---|---:|" * len(budgets) + "---:|---|"]
    met = {b: 0 for b in budgets}
    for r in table:
        cells = []
        for b in budgets:
            c = r[b]
            ok = c["ratio"] is not None and c["ratio"] <= TARGET_RATIO
            met[b] += ok
            cells += [_e(c["auto"]), f"{c['best']} {_e(c['best_value'])}",
                      "-" if c["ratio"] is None else f"{c['ratio']:.2f}{'' if ok else ' (not met)'}"]
        a = r["analysis_stage_s"] or r["analysis_s"]
        load = "-" if not r["load"] else f"{r['load'][0]:.1f}-{r['load'][1]:.1f}"
        lines.append(f"| {r['scene']} | {r['found']} | {r['chose']} | {' | '.join(cells)} | "
                     f"{'-' if a is None else f'{a:.2f} ({a / budgets[-1]:.1%})'} | {load} |")
    lines += ["", f"Within {TARGET_RATIO}x: " + ", ".join(f"{met[b]} of {len(table)} scenes at {b:g} s" for b in budgets) + ".",
              "", "Every hand-picked integrator's relMSE:", "", "| scene | budget | " + " | ".join(HAND) + " | auto |",
              "|---|---:|" + "---:|" * (len(HAND) + 1)]
    for r in table:
        for b in budgets:
            c = r[b]
            lines.append(f"| {r['scene']} | {b:g} | " + " | ".join(_e(c["hand"].get(h)) for h in HAND)
                         + f" | {_e(c['auto'])} |")
    text = "\n".join(lines) + "\n"
    (pathlib.Path(out_dir) / "report.md").write_text(text)
    return text


def main(argv=None):
    args = sys.argv[1:] if argv is None else argv
    out = pathlib.Path(args[0] if args else "bench/results/auto")
    results = json.loads((out / "results.json").read_text())
    print(report(results, out))


if __name__ == "__main__":
    main()
