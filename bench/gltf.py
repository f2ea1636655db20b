"""Real assets through Blender's own glTF importer: Ember against Cycles at equal samples.

    ./dev python bench/gltf.py --sample-models PATH [--blender-io PATH] [--only NAME ...]
        [--resolution 128] [--samples 16,64] [--ref-runs 8] [--ref-samples 256]
        [--cache DIR] [--out bench/results/gltf]

Each asset is imported with `bpy.ops.import_scene.gltf` into an empty scene, framed by a
camera (its bounding sphere fills the view, seen from the front, a little from the right and
above), and lit by one of Blender's studio-light HDRIs (datafiles/studiolights/world) as the
world, through an Environment Texture. A Cycles reference (scenes/reference.py's unbiased
settings: mean and variance of `ref-runs` independent runs) is rendered once and cached; then
Cycles and Ember (the path tracer) render the same scene at each equal sample count with
seeds the reference does not use. The report gives each one's relMSE against the reference
(bench/metrics.py: EPS 1e-2, no outlier rejection), the reference's own expected relMSE, the
ratio Ember / Cycles (the target is at most 1.5), and the warnings Ember's export printed.

Assets are not kept in this repository. --sample-models is a checkout of
KhronosGroup/glTF-Sample-Models (the folder holding 2.0/) or a git directory of one, from
which the files an asset needs are read with `git cat-file` (snapshots may lack large
blobs: an asset whose files are missing is skipped with a note). --blender-io is the same
for KhronosGroup/glTF-Blender-IO, whose tests/roundtrip scenes exercise the KHR material
extensions the importer turns into nodes. Licences are each asset's own (ASSETS below).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))
sys.path.insert(0, str(ROOT))
import bpy  # noqa: E402

from _bootstrap import load_ember  # noqa: E402

load_ember()
import ember  # noqa: E402
from ember.engine import imageio  # noqa: E402
from ember.engine.blender.export import export_scene  # noqa: E402

from bench.metrics import reference_rel_mse, rel_mse  # noqa: E402
from bench.render_cycles import cycles_reference  # noqa: E402

TARGET = 1.5
HDRI = "studio.exr"
FOV = math.radians(40.0)


@dataclass(frozen=True)
class Asset:
    name: str
    source: str  # "sample-models" or "blender-io"
    folder: str  # inside the source: every file under it is the asset's
    file: str  # the .gltf / .glb inside folder
    licence: str
    what: str  # what of the importer's output it exercises


ASSETS = (
    Asset("WaterBottle", "sample-models", "2.0/WaterBottle/glTF", "WaterBottle.gltf",
          "CC0 (donated by Microsoft; Patrick Ryan)",
          "base colour, packed occlusion-roughness-metallic map, normal map, emissive map"),
    Asset("Avocado", "sample-models", "2.0/Avocado/glTF", "Avocado.gltf", "CC0 (donated by Microsoft)",
          "base colour, roughness-metallic map, normal map"),
    Asset("DamagedHelmet", "sample-models", "2.0/DamagedHelmet/glTF", "DamagedHelmet.gltf",
          "CC BY-NC 4.0 (theblueturtle_)", "the above plus an emissive map and an occlusion map"),
    Asset("Suzanne", "sample-models", "2.0/Suzanne/glTF", "Suzanne.gltf", "donated by Norbert Nopper for glTF testing",
          "base colour, metallic-roughness map"),
    Asset("NormalTangentTest", "sample-models", "2.0/NormalTangentTest/glTF", "NormalTangentTest.gltf",
          "CC BY 4.0 (Analytical Graphics, Inc.; Ed Mackey)", "normal maps against real geometry, double-sided"),
    Asset("TextureSettingsTest", "sample-models", "2.0/TextureSettingsTest/glTF", "TextureSettingsTest.gltf",
          "CC BY 4.0 (Analytical Graphics, Inc.; Ed Mackey)", "wrap modes (Math nodes on UVs), single/double-sided"),
    Asset("io_transmission", "blender-io", "tests/roundtrip/15_transmission", "15_transmission.gltf",
          "Apache 2.0 (glTF-Blender-IO)", "KHR_materials_transmission, with textures"),
    Asset("io_ior", "blender-io", "tests/roundtrip/17_ior", "17_ior.gltf", "Apache 2.0 (glTF-Blender-IO)",
          "KHR_materials_ior"),
    Asset("io_specular", "blender-io", "tests/roundtrip/20_specular", "20_specular.gltf",
          "Apache 2.0 (glTF-Blender-IO)", "KHR_materials_specular, with textures"),
    Asset("io_emission_strength", "blender-io", "tests/roundtrip/14_emission_strength", "14_emission_strength.gltf",
          "Apache 2.0 (glTF-Blender-IO)", "KHR_materials_emissive_strength, specular-glossiness"),
    Asset("io_texture_transform", "blender-io", "tests/roundtrip/09_texture_transform", "09_texture_transform.gltf",
          "Apache 2.0 (glTF-Blender-IO)", "KHR_texture_transform (a Mapping node)"),
    Asset("io_alpha_blend", "blender-io", "tests/roundtrip/01_alpha_blend", "01_alpha_blend.gltf",
          "Apache 2.0 (glTF-Blender-IO)", "alpha blend"),
    Asset("io_alpha_mask", "blender-io", "tests/roundtrip/01_alpha_mask", "01_alpha_mask.gltf",
          "Apache 2.0 (glTF-Blender-IO)", "alpha clip (Math nodes on the alpha)"),
    Asset("io_vertex_color", "blender-io", "tests/roundtrip/22_vertex_color", "22_vertex_color.gltf",
          "Apache 2.0 (glTF-Blender-IO)", "COLOR_0 (a Color Attribute node)"),
    Asset("io_sheen", "blender-io", "tests/roundtrip/19_sheen", "19_sheen.gltf", "Apache 2.0 (glTF-Blender-IO)",
          "KHR_materials_sheen"),
)


# --- where the files come from ------------------------------------------------------------
def _git_dir(path: pathlib.Path) -> pathlib.Path | None:
    if (path / "HEAD").is_file() and (path / "objects").is_dir():
        return path
    if (path / ".git").is_dir():
        return path / ".git"
    return None


def materialise(asset: Asset, sources: dict, cache: pathlib.Path) -> pathlib.Path | str:
    """The asset's main file on disk, or a note saying why not: a checkout is read in place; a
    git directory's files are written under cache once (`git cat-file`, as a snapshot may miss
    blobs: a missing one skips the asset)."""
    root = sources.get(asset.source)
    if root is None:
        return f"no --{asset.source} given"
    root = pathlib.Path(root)
    git = _git_dir(root)
    if git is None or (root / asset.folder / asset.file).exists():
        path = root / asset.folder / asset.file
        return path if path.exists() else f"{path} not found"
    dest = cache / "assets" / asset.source / asset.folder
    main = dest / asset.file
    if main.exists():
        return main
    listing = subprocess.run(["git", "--git-dir", str(git), "ls-tree", "-r", "HEAD", asset.folder],
                             capture_output=True, text=True, check=True).stdout.splitlines()
    if not listing:
        return f"{asset.folder} is not in {root}"
    files = {}
    for line in listing:
        meta, path = line.split("\t", 1)
        blob = subprocess.run(["git", "--git-dir", str(git), "cat-file", "-p", meta.split()[2]],
                              capture_output=True)
        if blob.returncode != 0:
            return f"{path} is missing from {root} (a snapshot without its blob)"
        files[path] = blob.stdout
    for path, data in files.items():
        out = dest / pathlib.Path(path).relative_to(asset.folder)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_bytes(data)
    return main


# --- the scene ------------------------------------------------------------------------------
def studio_hdri() -> str:
    return os.path.join(bpy.utils.system_resource("DATAFILES", path="studiolights/world"), HDRI)


def build(path: pathlib.Path, resolution: int):
    """An empty scene with the asset imported, a camera framing it and the HDRI world."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.import_scene.gltf(filepath=str(path))
    bpy.context.view_layer.update()
    corners = [ob.matrix_world @ _vec(c) for ob in scene.objects if ob.type == "MESH" for c in ob.bound_box]
    lo, hi = np.min(corners, axis=0), np.max(corners, axis=0)
    centre, radius = (lo + hi) / 2.0, float(np.linalg.norm(hi - lo) / 2.0)
    direction = np.array([0.35, -1.0, 0.3])
    direction /= np.linalg.norm(direction)
    distance = radius / math.sin(FOV / 2.0) * 0.8
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.data.angle = FOV
    cam.data.clip_start = distance * 1e-3
    cam.data.clip_end = distance * 10.0
    scene.collection.objects.link(cam)
    cam.location = tuple(centre + direction * distance)
    cam.rotation_euler = _vec(-direction).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    world = bpy.data.worlds.new("Studio")
    nt = world.node_tree
    nt.nodes.clear()
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(studio_hdri())
    bg = nt.nodes.new("ShaderNodeBackground")
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs[0], out.inputs["Surface"])
    scene.world = world
    scene.render.resolution_x = scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    return scene


def _vec(v):
    from mathutils import Vector
    return Vector(tuple(float(x) for x in v))


def ember_warnings(scene) -> list[str]:
    scene.render.engine = "EMBER"
    _, warnings = export_scene(bpy.context.evaluated_depsgraph_get())
    return warnings


def render_ember(scene, samples: int, seed: int, path: str) -> tuple[np.ndarray, float]:
    scene.render.engine = "EMBER"
    e = scene.ember
    e.integrator = "PATH"
    e.samples = samples
    e.seed = seed
    e.time_limit = 0.0
    e.noise_target = 0.0
    e.max_depth = cycles_reference.BOUNCES
    if hasattr(e, "glossy_as_phong"):
        e.glossy_as_phong = False
    cycles_reference.exr_output(scene, path)
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return imageio.read_rgb(path).astype(np.float64), time.perf_counter() - t0


def render_cycles(scene, samples: int, seed: int, path: str) -> tuple[np.ndarray, float]:
    cycles_reference.unbiased_cycles(scene, samples)
    return cycles_reference.render_rgb(scene, path, seed)


def reference(scene, asset: Asset, args, cache: pathlib.Path) -> tuple[np.ndarray, np.ndarray, dict]:
    """Mean and variance of the mean of ref_runs Cycles runs (seeds 0..runs-1), cached by
    asset, resolution and sample counts."""
    out = cache / f"{asset.name}_{args.resolution}_{args.ref_runs}x{args.ref_samples}.exr"
    if not out.exists():
        cycles_reference.unbiased_cycles(scene, args.ref_samples)
        total = total_sq = 0.0
        seconds = 0.0
        with tempfile.TemporaryDirectory(prefix="ember_gltf_") as tmp:
            for i in range(args.ref_runs):
                img, dt = cycles_reference.render_rgb(scene, os.path.join(tmp, "ref.exr"), i)
                total, total_sq, seconds = total + img, total_sq + img * img, seconds + dt
        n = args.ref_runs
        mean = total / n
        var = np.maximum(total_sq - n * mean * mean, 0.0) / (n - 1) / n
        chans = {c: mean[:, :, i] for i, c in enumerate("RGB")}
        chans.update({f"var.{c}": var[:, :, i] for i, c in enumerate("RGB")})
        imageio.write_exr(str(out), chans, {"renderer": "Cycles", "samples": args.ref_samples, "runs": n,
                                            "time_s": seconds, "blender_version": bpy.app.version_string})
    ch, _ = imageio.read_exr(str(out))
    mean = np.stack([ch[c] for c in "RGB"], axis=-1).astype(np.float64)
    var = np.stack([ch[f"var.{c}"] for c in "RGB"], axis=-1).astype(np.float64)
    return mean, var, {}


def measure(asset: Asset, path: pathlib.Path, args, cache: pathlib.Path) -> dict:
    scene = build(path, args.resolution)
    warnings = ember_warnings(scene)
    t0 = time.perf_counter()
    ref, var, _ = reference(scene, asset, args, cache)
    row = {"asset": asset.name, "licence": asset.licence, "what": asset.what, "warnings": warnings,
           "reference_seconds": time.perf_counter() - t0, "relmse_ref": reference_rel_mse(ref, var), "points": []}
    with tempfile.TemporaryDirectory(prefix="ember_gltf_") as tmp:
        for k, spp in enumerate(args.samples):
            seed = 1000 + k
            cyc, t_cyc = render_cycles(scene, spp, seed, os.path.join(tmp, "cycles.exr"))
            emb, t_emb = render_ember(scene, spp, seed, os.path.join(tmp, "ember.exr"))
            point = {"samples": spp, "cycles": rel_mse(cyc, ref), "ember": rel_mse(emb, ref),
                     "cycles_seconds": t_cyc, "ember_seconds": t_emb,
                     "cycles_mean": float(cyc.mean()), "ember_mean": float(emb.mean()), "ref_mean": float(ref.mean())}
            point["ratio"] = point["ember"] / max(point["cycles"], 1e-30)
            row["points"].append(point)
            if args.images:
                np.savez_compressed(cache / f"{asset.name}_{spp}.npz", ref=ref, cycles=cyc, ember=emb)
            print(f"{asset.name} {spp} spp: relMSE Cycles {point['cycles']:.4g}, Ember {point['ember']:.4g}, "
                  f"ratio {point['ratio']:.2f} (mean ref {point['ref_mean']:.4f} cycles {point['cycles_mean']:.4f} "
                  f"ember {point['ember_mean']:.4f})", flush=True)
    return row


# --- the report -----------------------------------------------------------------------------
def report(rows: list, notes: list, args) -> str:
    counts = args.samples
    lines = ["# Real glTF assets: Ember against Cycles at equal samples", "",
             f"`bench/gltf.py` on one machine, one run ({time.strftime('%Y-%m-%d')}, Blender "
             f"{bpy.app.version_string}, load {os.getloadavg()[0]:.1f}). Each asset imported with Blender's glTF "
             f"importer, {args.resolution} x {args.resolution} pixels, lit by the studio-light HDRI `{HDRI}`; "
             f"reference: Cycles {args.ref_runs} x {args.ref_samples} spp. relMSE = mean((x - r)^2 / (r^2 + 0.01)); "
             f"ratio = Ember / Cycles at equal samples (target <= {TARGET}).", ""]
    head = "| asset | ref. own relMSE | " + " | ".join(
        f"Cycles {n} spp | Ember {n} spp | ratio {n}" for n in counts) + " | Ember warnings |"
    lines += [head, "|" + "---|" * (3 * len(counts) + 3)]
    for r in rows:
        cells = []
        for p in r["points"]:
            mark = "" if p["ratio"] <= TARGET else " **over**"
            cells += [f"{p['cycles']:.4g}", f"{p['ember']:.4g}", f"{p['ratio']:.2f}{mark}"]
        warn = "; ".join(r["warnings"]) or "none"
        lines.append(f"| {r['asset']} | {r['relmse_ref']:.2g} | " + " | ".join(cells) + f" | {warn} |")
    lines += ["", "| asset | licence | exercises | image mean: reference / Cycles / Ember (largest count) | "
                  "seconds: Cycles / Ember (largest count) |", "|---|---|---|---|---|"]
    for r in rows:
        p = r["points"][-1]
        lines.append(f"| {r['asset']} | {r['licence']} | {r['what']} | {p['ref_mean']:.4f} / {p['cycles_mean']:.4f} / "
                     f"{p['ember_mean']:.4f} | {p['cycles_seconds']:.1f} / {p['ember_seconds']:.1f} |")
    if notes:
        lines += ["", "Skipped:", ""] + [f"- {n}" for n in notes]
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sample-models", help="KhronosGroup/glTF-Sample-Models: a checkout or its git directory")
    ap.add_argument("--blender-io", help="KhronosGroup/glTF-Blender-IO: a checkout or its git directory")
    ap.add_argument("--only", action="append", help="asset name (repeatable)")
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--samples", default="16,64", help="equal sample counts, comma-separated")
    ap.add_argument("--ref-runs", type=int, default=8)
    ap.add_argument("--ref-samples", type=int, default=256)
    ap.add_argument("--cache", default=str(ROOT / "bench" / "results" / "tmp" / "gltf"),
                    help="references and extracted assets (not committed)")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "gltf"))
    ap.add_argument("--images", action="store_true", help="keep every image in the cache as .npz")
    args = ap.parse_args(argv)
    args.samples = [int(s) for s in args.samples.split(",")]
    sources = {"sample-models": args.sample_models or os.environ.get("EMBER_GLTF_SAMPLE_MODELS"),
               "blender-io": args.blender_io or os.environ.get("EMBER_GLTF_BLENDER_IO")}
    sources = {k: v for k, v in sources.items() if v}
    cache = pathlib.Path(args.cache)
    cache.mkdir(parents=True, exist_ok=True)
    ember.register()
    rows, notes = [], []
    for asset in ASSETS:
        if args.only and asset.name not in args.only:
            continue
        path = materialise(asset, sources, cache)
        if isinstance(path, str):
            notes.append(f"{asset.name}: {path}")
            print(f"{asset.name}: skipped: {path}", flush=True)
            continue
        rows.append(measure(asset, path, args, cache))
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps({"rows": rows, "notes": notes, "args": {
        k: v for k, v in vars(args).items() if k not in ("cache", "out")}}, indent=1))
    (out / "report.md").write_text(report(rows, notes, args))
    print((out / "report.md").read_text())


if __name__ == "__main__":
    main()
