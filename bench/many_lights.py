"""Many lights: the light tree against choosing lights by power alone, at equal time.

    ./dev python bench/many_lights.py                 # the study (~5-10 min on a quiet machine)
    ./dev python bench/many_lights.py --quick         # smaller images and counts

Scenes: tests/core_scenes.many_lights - n small lights (emissive squares, two triangles each,
or delta point lights) of powers log-uniform over three decades, spread over 30 m x 30 m of a
large diffuse floor with a few boxes, total power the same for every n, seen from above.

For each scene both selections render the same spp on one thread (in-process, so the
`TREE_MIN_LIGHTS` switch reaches the LightSet); the time is the process CPU time (the machine
is shared). relMSE (engine.metrics, EPS 1e-2) against a reference rendered with the tree at
16x the spp, minus the reference's own (its variance estimate / (ref^2 + EPS)): variance
estimates of the renders themselves are no judge here, as power selection rarely picks the
near, bright light and at few samples its variance estimate is far too low. Pixels that see an emitter directly
are left out (their noise is the pixel filter's, the same for both: found by a render with
max_depth 0 at 1024 spp, and their neighbours). Equal time: relMSE x cpu_seconds / T (error
falls as 1/time), T = the power render's time. The raw relMSE against the reference is
printed too ("measured").
The crossover (TREE_MIN_LIGHTS) comes from the same figure over light counts.
"""
import argparse
import json
import pathlib
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
from _bootstrap import load_ember  # noqa: E402

load_ember()
import numpy as np  # noqa: E402

from core_scenes import many_lights  # noqa: E402
from ember.engine import metrics  # noqa: E402
from ember.engine.lights import light_set  # noqa: E402
from ember.engine.session import RenderSession  # noqa: E402


def render(scene, tree: bool):
    """(mean, var_of_mean, cpu seconds) of one in-process render with or without the tree."""
    light_set.TREE_MIN_LIGHTS = 1 if tree else 10**9
    t0 = time.process_time()
    session = RenderSession(scene)
    session.run()
    return session.film.mean(), session.film.variance_of_mean(), time.process_time() - t0


def study(n, kind, size, spp, ref_factor):
    kw = dict(width=size, height=size, threads=1, batch_size=1 << 14, filter="BOX", filter_width=1.0)
    direct, _, _ = render(many_lights(n, kind, samples=1024, max_depth=0, **kw), False)
    seen = np.any(direct != 0, axis=2)
    seen[1:] |= seen[:-1]  # and their neighbours: a few camera samples per pixel can miss them
    seen[:-1] |= seen[1:]
    seen[:, 1:] |= seen[:, :-1]
    seen[:, :-1] |= seen[:, 1:]
    mask = ~seen
    ref, ref_var, _ = render(many_lights(n, kind, samples=spp * ref_factor, seed=7, **kw), True)
    row = dict(n=n, kind=kind, spp=spp, pixels=int(mask.sum()))
    ref_noise = float(np.mean((ref_var / (ref * ref + metrics.EPS))[mask]))
    for name, tree in (("power", False), ("tree", True)):
        mean, var, cpu = render(many_lights(n, kind, samples=spp, **kw), tree)
        measured = metrics.rel_mse(mean, ref, mask)
        row[name] = dict(cpu=cpu, measured=measured, rel_mse=max(measured - ref_noise, 0.0))
    T = row["power"]["cpu"]
    for name in ("power", "tree"):
        row[name]["rel_mse_equal_time"] = row[name]["rel_mse"] * row[name]["cpu"] / T
    row["ratio"] = row["tree"]["rel_mse_equal_time"] / row["power"]["rel_mse_equal_time"]
    return row


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--counts", help="comma-separated light counts (default: the study's)")
    ap.add_argument("--kind", choices=("triangle", "point"), help="only this kind of light")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "many_lights.json"))
    args = ap.parse_args()
    size, spp = (32, 16) if args.quick else (64, 32)
    cases = [(n, "triangle") for n in (8, 32, 64, 128, 1000, 5000)] + [(n, "point") for n in (8, 32, 128, 1000)]
    if args.quick:
        cases = [(8, "triangle"), (64, "triangle"), (1000, "triangle"), (1000, "point")]
    if args.counts:
        cases = [(int(n), k) for k in ("triangle", "point") for n in args.counts.split(",")]
    if args.kind:
        cases = [(n, k) for n, k in cases if k == args.kind]
    rows = []
    print(f"{'lights':>12} {'pixels':>6} {'power cpu s':>11} {'tree cpu s':>10} {'power relMSE':>12} "
          f"{'tree relMSE':>11} {'equal-time ratio':>16} {'measured p/t':>14}")
    for n, kind in cases:
        r = study(n, kind, size, spp, 16)
        rows.append(r)
        p, t = r["power"], r["tree"]
        print(f"{n:>6} {kind:>5} {r['pixels']:>6} {p['cpu']:>11.2f} {t['cpu']:>10.2f} {p['rel_mse']:>12.4g} "
              f"{t['rel_mse']:>11.4g} {r['ratio']:>16.3f} {p['measured']:>6.3g}/{t['measured']:<7.3g}", flush=True)
    pathlib.Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    pathlib.Path(args.out).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
