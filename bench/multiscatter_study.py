"""Multiscatter GGX and Oren-Nayar against Cycles 5.0: the albedo tables, a white furnace of
spheres and a table top (bench/results/multiscatter/report.md).

    ./dev python bench/multiscatter_study.py [--part tables|furnace|table_top] [--runs 4]

tables: Ember's tables (engine/bsdf/ggx_energy.npz) against Cycles' own, found in the bpy
binary by their shape (Cycles compiles them in; located by matching Ember's values, then
compared in full), and the directional albedo of single and multiple scattering GGX by
roughness. furnace: tests/test_multiscatter.py's grid of spheres (gold, plastic, glass, rough
diffuse at roughness 0.3 / 0.7 / 1.0) under a white world, Cycles and Ember with the
distribution set to Multiscatter GGX and to GGX; per sphere Ember / Cycles - 1 and its
standard error. table_top: a Principled plane (roughness 0.5) seen at a grazing angle under a
white world, Cycles (Multiscatter GGX, Blender's default) against Ember rendering it as GGX
(what it did before) and as Multiscatter GGX.
"""
from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

import _bootstrap  # noqa: E402

_bootstrap.load_ember()
from ember.engine.bsdf import multiscatter as ms  # noqa: E402


def _cycles_tables():
    """Cycles' ggx_E (32, 32), ggx_Eavg (32,), ggx_glass_E and ggx_glass_Eavg (eta > 1 and
    their inverse tables stacked) from the bpy binary, or None: Eavg is found as 32 floats
    starting at 1.0 that match Ember's within 3e-3 at three places, the others at their
    offsets next to it."""
    path = next((pathlib.Path(p) / "bpy" / "__init__.so" for p in sys.path
                 if (pathlib.Path(p) / "bpy" / "__init__.so").is_file()), None)
    if path is None:
        return None
    raw = path.read_bytes()
    t = ms.tables()
    for off in range(4):
        a = np.frombuffer(raw[off:off + (len(raw) - off) // 4 * 4], np.float32)
        for c in np.flatnonzero(a == 1.0):
            if c + 1056 <= len(a) and all(abs(a[c + i] - t["E_avg"][i]) < 3e-3 for i in (5, 20, 31)):
                E = a[c + 32:c + 1056].reshape(32, 32)
                if np.abs(E - t["E"]).max() < 0.01:
                    f = lambda lo, hi, *shape: a[c + lo:c + hi].reshape(shape).astype(np.float64)
                    return dict(E_avg=f(0, 32, 32), E=f(32, 1056, 32, 32),
                                glass_E=np.stack([f(-4096, 0, 16, 16, 16), f(-8448, -4352, 16, 16, 16)]),
                                glass_E_avg=np.stack([f(-4352, -4096, 16, 16), f(-8704, -8448, 16, 16)]))
    return None


def tables():
    from test_multiscatter import directional_albedo, _glossy
    from ember.engine.scene import DIST_GGX
    t = ms.tables()
    c = _cycles_tables()
    lines = ["### Albedo tables: Ember's against Cycles'", ""]
    if c is None:
        lines.append("Cycles' tables not found in the bpy binary.")
    else:
        lines += ["| table | nodes | max abs diff | mean abs diff |", "|---|---|---|---|"]
        for name, ours in (("E", t["E"]), ("E_avg", t["E_avg"]), ("glass_E", t["glass_E"]),
                           ("glass_E_avg", t["glass_E_avg"])):
            d = np.abs(ours - c[name])
            lines.append(f"| {name} | {d.size} | {d.max():.4f} | {d.mean():.5f} |")
        lines.append("")
    lines += ["| roughness | E_avg Ember | E_avg Cycles | albedo at 0 deg: single | multi | at 60 deg: single | multi |",
              "|---|---|---|---|---|---|---|"]
    for r in (0.1, 0.3, 0.5, 0.7, 0.85, 1.0):
        cells = []
        for theta in (0.0, 60.0):
            single, _ = directional_albedo(_glossy(r, DIST_GGX), theta)
            multi, _ = directional_albedo(_glossy(r), theta)
            cells += [f"{single[0]:.4f}", f"{multi[0]:.4f}"]
        cyc = f"{np.interp(r, ms.nodes(32), c['E_avg']):.4f}" if c is not None else "-"
        lines.append(f"| {r} | {ms.E_avg([r])[0]:.4f} | {cyc} | " + " | ".join(cells) + " |")
    return lines


def furnace(runs, cycles_samples=64, ember_samples=32):
    import bpy
    import ember
    import test_multiscatter as T
    T.RUNS = runs
    ember.register()
    lines = ["### White furnace: Ember / Cycles - 1 per sphere (standard error)", ""]
    try:
        results = {}
        for dist in ("MULTI_GGX", "GGX"):
            sc = T._furnace_scene(bpy, dist)
            cycles = T._cycles_furnace(bpy, sc, cycles_samples)
            emb = T._ember_furnace(bpy, ember_samples)
            results[dist] = (cycles, emb)
        # Ember as before (Multiscatter rendered as GGX) against Cycles' Multiscatter.
        results["before"] = (results["MULTI_GGX"][0], results["GGX"][1])
    finally:
        ember.unregister()
    header = "| sphere | " + " | ".join(f"r={r}" for r in T.COLUMNS) + " |"
    for label, key in (("Multiscatter GGX on both sides", "MULTI_GGX"), ("GGX on both sides", "GGX"),
                       ("Cycles Multiscatter GGX, Ember GGX (Ember before)", "before")):
        cycles, emb = results[key]
        ratios = T.furnace_ratios(emb, cycles)
        lines += [f"{label}:", "", header, "|---" * (len(T.COLUMNS) + 1) + "|"]
        for i, row in enumerate(T.ROWS):
            cells = [f"{ratios[i, j][0]:+.2%} ({ratios[i, j][1]:.2%})" for j in range(len(T.COLUMNS))]
            lines.append(f"| {row} | " + " | ".join(cells) + " |")
        lines.append("")
    masks = T._masks()
    for dist in ("MULTI_GGX", "GGX"):
        cyc = results[dist][0].mean(axis=0)
        lines += [f"Cycles' sphere means ({dist}):", "", header, "|---" * (len(T.COLUMNS) + 1) + "|"]
        for i, row in enumerate(T.ROWS):
            cells = [f"{cyc[masks[i, j]].mean():.4f}" for j in range(len(T.COLUMNS))]
            lines.append(f"| {row} | " + " | ".join(cells) + " |")
        lines.append("")
    return lines


def table_top(runs, cycles_samples=64, ember_samples=32):
    import bpy
    import ember
    import test_multiscatter as T
    T.RUNS = runs
    ember.register()
    try:
        out = {}
        for dist in ("MULTI_GGX", "GGX"):
            bpy.ops.wm.read_factory_settings(use_empty=True)
            sc = bpy.context.scene
            sc.render.resolution_x, sc.render.resolution_y = T.SIZE_W, T.SIZE_H
            sc.render.resolution_percentage = 100
            cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
            cam.location, cam.rotation_euler = (0.0, -4.0, 1.2), (np.radians(72.0), 0.0, 0.0)
            sc.collection.objects.link(cam)
            sc.camera = cam
            world = bpy.data.worlds.new("World")
            sc.world = world
            world.node_tree.nodes["Background"].inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
            mat = T._material(bpy, "table", "ShaderNodeBsdfPrincipled", Roughness=0.5, distribution=dist,
                              **{"Base Color": (0.35, 0.2, 0.1, 1.0)})
            bpy.ops.mesh.primitive_plane_add(size=40.0)
            bpy.context.active_object.data.materials.append(mat)
            out[dist] = (T._cycles_furnace(bpy, sc, cycles_samples), T._ember_furnace(bpy, ember_samples))
    finally:
        ember.unregister()
    cycles = out["MULTI_GGX"][0].mean(axis=(1, 2, 3))
    lines = ["### Table top (Principled, roughness 0.5, base (0.35, 0.2, 0.1), white world)", "",
             "| | mean | against Cycles (Multiscatter GGX) |", "|---|---|---|"]
    for label, imgs in (("Cycles, Multiscatter GGX", out["MULTI_GGX"][0]), ("Cycles, GGX", out["GGX"][0]),
                        ("Ember before (GGX)", out["GGX"][1]), ("Ember, Multiscatter GGX", out["MULTI_GGX"][1])):
        m = imgs.mean(axis=(1, 2, 3))
        se = np.sqrt(m.var(ddof=1) / len(m) + cycles.var(ddof=1) / len(cycles)) / cycles.mean()
        lines.append(f"| {label} | {m.mean():.4f} | {m.mean() / cycles.mean() - 1:+.2%} (se {se:.2%}) |")
    return lines


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--part", choices=("tables", "furnace", "table_top"), nargs="*",
                    default=["tables", "furnace", "table_top"])
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--cycles-samples", type=int, default=64)
    ap.add_argument("--ember-samples", type=int, default=32)
    args = ap.parse_args()
    for part in args.part:
        spp = (args.cycles_samples, args.ember_samples)
        lines = {"tables": tables, "furnace": lambda: furnace(args.runs, *spp),
                 "table_top": lambda: table_top(args.runs, *spp)}[part]()
        print("\n".join(lines) + "\n", flush=True)


if __name__ == "__main__":
    main()
