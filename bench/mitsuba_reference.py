"""Caustic reference: Mitsuba 3's particle tracer where a path tracer is too noisy.

    python bench/mitsuba_reference.py [--scene caustic|caustic_point] [--resolution 64] [--out FILE]
    (or bench/references.py --only NAME)

Light from a small emitter through a glass sphere onto a diffuse floor (L S+ D E) is found
by a path tracer only when a BSDF-sampled ray happens to refract onto the emitter; a
particle tracer (Mitsuba's `ptracer`, scalar_rgb variant: no LLVM needed) follows light
from the emitter and connects every non-specular vertex to the camera, so it converges
there. It cannot connect through a specular vertex, so image = sum of two disjoint parts,
split by the first surface the camera ray meets:
- non-specular first vertex (floor, walls, the emitter seen directly): Mitsuba ptracer on
  the same triangles (read from the .blend), materials and camera, box filter 1 px;
- specular first vertex (the camera sees the glass): Cycles on caustic_specular_only.blend,
  where diffuse surfaces and the emitter are black to camera rays only.
Each part is a mean over independent runs with its variance; the sum's variance is the sum.

Check: a long plain Cycles run of caustic.blend; where it looks converged (relative
standard error below 2 %), the two must agree. They do in sum and median, but not pixel by
pixel to 3 sigma: every diffuse point also sees the emitter reflected and refracted by the
sphere (L S+ D paths), which Cycles finds only by rare BSDF-sampled hits, so it mostly
misses that light and its variance estimate does not show it. The header records both
parts' samples and times, the versions and the agreement.

caustic_point (`--scene caustic_point`): a Blender point light of radius 0 becomes Mitsuba's
`point` emitter with I = strength / (4 pi) W/sr, Cycles' convention. Cycles cannot find
L S+ D paths from it at all: the header records plain Cycles' mean in the caustic region
(bench/regions.py; 0.5 % of the reference's), and the reference's own Cycles part (camera
sees the glass) lacks the caustic seen through the sphere for the same reason.

Not used: Cycles' MNEE caustics, which on a glass sphere under a small sphere light were
measured to carry about a quarter of the caustic's energy.
"""
from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
MITSUBA_RUNS, MITSUBA_SPP = 16, 1024  # light paths per run: spp x pixels
CYCLES_SPECULAR = (16, 1024)  # runs x samples, first vertex specular
CYCLES_CHECK = (16, 256)  # runs x samples, the whole image
CONVERGED = 0.02  # relative standard error under which a Cycles pixel counts as converged


def _ply(path, vertices, triangles):
    """Binary little-endian PLY with float32 vertices and int32 triangles."""
    v = np.ascontiguousarray(vertices, "<f4")
    f = np.zeros(len(triangles), dtype=[("n", "u1"), ("i", "<i4", 3)])
    f["n"], f["i"] = 3, triangles
    with open(path, "wb") as fh:
        fh.write((f"ply\nformat binary_little_endian 1.0\nelement vertex {len(v)}\n"
                  "property float x\nproperty float y\nproperty float z\n"
                  f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n").encode())
        fh.write(v.tobytes())
        fh.write(f.tobytes())


def _material(mat) -> tuple[dict, list | None]:
    """(Mitsuba BSDF dict, emitted radiance or None) for the node types the scene uses."""
    from ember.engine.blender.export_material import find_output, follow_link, rgb
    node = follow_link(find_output(mat.node_tree, "ShaderNodeOutputMaterial").inputs["Surface"])
    kind = node.bl_idname
    if kind == "ShaderNodeBsdfDiffuse":
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(rgb(node.inputs["Color"]))}}, None
    if kind == "ShaderNodeBsdfGlass" and node.inputs["Roughness"].default_value == 0:
        return {"type": "dielectric", "int_ior": float(node.inputs["IOR"].default_value), "ext_ior": 1.0}, None
    if kind == "ShaderNodeEmission":
        le = np.array(rgb(node.inputs["Color"])) * float(node.inputs["Strength"].default_value)
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}, le.tolist()
    raise ValueError(f"material '{mat.name}': {node.bl_label} has no Mitsuba counterpart here")


def _point_emitter(light, matrix_world) -> dict:
    """Mitsuba `point` emitter for a Blender point light of radius 0: intensity I = strength /
    (4 pi) W/sr (Cycles' convention, blender.md; Ember's Lights.Le for radius 0), strength =
    colour x energy x 2^exposure x the light's emission node (engine/blender/export_light)."""
    from ember.engine.blender.export_light import light_strength
    if light.type != "POINT" or float(light.shadow_soft_size) != 0.0:
        raise ValueError(f"light '{light.name}': only point lights of radius 0 are converted")
    if not getattr(light, "normalize", True):
        raise ValueError(f"light '{light.name}': 'normalize' off is not converted")
    intensity = light_strength(light, lambda msg: None) / (4.0 * np.pi)
    return {"type": "point", "position": matrix_world[:3, 3].tolist(),
            "intensity": {"type": "rgb", "value": intensity.tolist()}}


def mitsuba_scene(blend, resolution: int, tmp: str) -> dict:
    """The .blend's meshes (world space, flat), materials, camera and box filter as a Mitsuba
    scene dict; the black world is Mitsuba's default (no emitter)."""
    import bpy
    from ember.engine.blender.export import export_scene
    bpy.ops.wm.open_mainfile(filepath=str(blend), load_ui=False)
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    dg = bpy.context.evaluated_depsgraph_get()
    cam = export_scene(dg)[0].camera
    left, right, bottom, top = cam.window
    if not np.allclose([left + right, bottom + top], 0) or not np.isclose(right, top):
        raise ValueError("only a centred camera with a square image is converted")
    m = np.asarray(cam.world_from_camera, np.float64)
    eye, forward, up = m[:3, 3], -m[:3, 2], m[:3, 1]
    import mitsuba as mi
    out = {"type": "scene", "integrator": {"type": "ptracer", "max_depth": 65},
           "sensor": {"type": "perspective", "fov_axis": "x", "fov": float(np.degrees(2 * np.arctan(right))),
                      "near_clip": float(cam.clip_start), "far_clip": float(cam.clip_end),
                      "to_world": mi.ScalarTransform4f().look_at(origin=eye.tolist(), target=(eye + forward).tolist(),
                                                                 up=up.tolist()),
                      "film": {"type": "hdrfilm", "width": resolution, "height": resolution,
                               "rfilter": {"type": "box"}, "pixel_format": "rgb"},
                      "sampler": {"type": "independent"}}}
    for inst in dg.object_instances:
        ob = inst.object
        if ob.type == "LIGHT":
            out[f"light_{ob.name}"] = _point_emitter(ob.data, np.array(inst.matrix_world, np.float64))
            continue
        if ob.type != "MESH":
            continue
        me = ob.to_mesh()
        me.calc_loop_triangles()
        n = len(me.loop_triangles)
        tri = np.zeros(n * 3, np.int32)
        mat_index = np.zeros(n, np.int32)
        co = np.zeros(len(me.vertices) * 3, np.float32)
        me.loop_triangles.foreach_get("vertices", tri)
        me.loop_triangles.foreach_get("material_index", mat_index)
        me.vertices.foreach_get("co", co)
        mw = np.array(inst.matrix_world, np.float64)
        world = co.reshape(-1, 3) @ mw[:3, :3].T + mw[:3, 3]
        for k, slot in enumerate(ob.material_slots):
            sel = tri.reshape(-1, 3)[mat_index == k]
            if not len(sel):
                continue
            bsdf, le = _material(slot.material)
            path = os.path.join(tmp, f"{ob.name}_{k}.ply")
            _ply(path, world, sel)
            shape = {"type": "ply", "filename": path, "face_normals": True, "bsdf": bsdf}
            if le is not None:
                shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": le}}
            out[f"{ob.name}_{k}"] = shape
        ob.to_mesh_clear()
    return out


def render_mitsuba(scene_dict, runs: int, spp: int):
    """(mean, variance of the mean, seconds) over `runs` seeds."""
    import mitsuba as mi
    scene = mi.load_dict(scene_dict)
    imgs, t0 = [], time.perf_counter()
    for i in range(runs):
        imgs.append(np.array(mi.render(scene, spp=spp, seed=i), np.float64)[..., :3])
    imgs = np.stack(imgs)
    return imgs.mean(0), imgs.var(0, ddof=1) / runs, time.perf_counter() - t0


def _cycles(blend, out, resolution, runs, samples):
    subprocess.run([sys.executable, str(ROOT / "scenes" / "reference.py"), str(blend), "--out", str(out),
                    "--resolution", f"{resolution}x{resolution}", "--runs", str(runs), "--samples", str(samples)],
                   check=True)
    from ember.engine import imageio
    ch, header = imageio.read_exr(out)
    mean = np.stack([ch[c] for c in "RGB"], -1).astype(np.float64)
    var = np.stack([ch[f"var.{c}"] for c in "RGB"], -1).astype(np.float64)
    return mean, var, float(header["time_s"])


def agreement(mean, var, check, check_var) -> str:
    """How the reference and a plain Cycles run agree where Cycles looks converged."""
    lum = lambda a: a.mean(axis=-1)  # noqa: E731
    ok = (lum(check) > 0) & (np.sqrt(lum(check_var)) < CONVERGED * lum(check))
    diff = (lum(mean) - lum(check))[ok]
    z = diff / np.sqrt(lum(var) + lum(check_var))[ok]
    return (f"Against plain Cycles ({CYCLES_CHECK[0]}x{CYCLES_CHECK[1]} spp) on the {ok.mean():.0%} of pixels "
            f"where its relative standard error is below {CONVERGED:.0%}: sum ratio "
            f"{lum(mean)[ok].sum() / lum(check)[ok].sum():.4f}, median relative difference "
            f"{np.median(diff / lum(check)[ok]):+.2%}, {np.mean(np.abs(z) < 3):.1%} of them within 3 sigma; "
            f"whole image sum ratio {lum(mean).sum() / lum(check).sum():.4f}.")


def make(bench_scene, out, resolution: int) -> None:
    """Write the caustic reference EXR for bench_scene (bench/scenes.py) at resolution^2."""
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    from ember.engine import imageio
    import bpy
    blend = bench_scene.path
    spec_blend = blend.with_name(blend.stem + "_specular_only.blend")
    with tempfile.TemporaryDirectory(prefix="ember_mitsuba_") as tmp:
        pt, pt_var, pt_s = render_mitsuba(mitsuba_scene(blend, resolution, tmp), MITSUBA_RUNS, MITSUBA_SPP)
        sp, sp_var, sp_s = _cycles(spec_blend, os.path.join(tmp, "spec.exr"), resolution, *CYCLES_SPECULAR)
        ck, ck_var, ck_s = _cycles(blend, os.path.join(tmp, "check.exr"), resolution, *CYCLES_CHECK)
    mean, var = pt + sp, pt_var + sp_var
    note = agreement(mean, var, ck, ck_var)
    from bench.regions import caustic_region, region_metrics
    region = caustic_region(bench_scene.name, mean)
    if region is not None and region.any():
        m = region_metrics(ck, mean, region)
        note += (f" Plain Cycles in the caustic region ({m['pixels']} px, bench/regions.py): mean "
                 f"{m['mean_ratio']:.4f} of the reference's, relMSE {m['relmse']:.3g}.")
    header = {"renderer": f"Mitsuba {mi.__version__} ptracer (first vertex non-specular) + Cycles "
                          f"(first vertex specular, {spec_blend.name})",
              "mitsuba_version": mi.__version__, "blender_version": bpy.app.version_string,
              "scene_file": blend.name, "resolution": f"{resolution}x{resolution}",
              "samples": MITSUBA_SPP, "runs": MITSUBA_RUNS, "total_samples": MITSUBA_SPP * MITSUBA_RUNS,
              "cycles_specular": json.dumps({"runs": CYCLES_SPECULAR[0], "samples": CYCLES_SPECULAR[1]}),
              "time_s": pt_s + sp_s, "mitsuba_time_s": pt_s, "cycles_time_s": sp_s, "check_time_s": ck_s,
              "agreement": note, "rows": "top-down",
              "point_light_note": ("" if "point" not in bench_scene.name else
                                   "a radius-0 point light: Cycles finds no L S+ D path from it (the "
                                   "plain Cycles check shows no caustic); the part where the camera "
                                   "sees the glass lacks the caustic seen through the sphere for the "
                                   "same reason"),
              "variance": "var.* = variance of the mean: Mitsuba's and Cycles' parts added"}
    chans = {c: mean[..., i] for i, c in enumerate("RGB")}
    chans.update({f"var.{c}": var[..., i] for i, c in enumerate("RGB")})
    imageio.write_exr(out, chans, header)
    print(f"wrote {out}: {note}")


def main(argv=None):
    import argparse
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--resolution", type=int, default=64)
    ap.add_argument("--scene", default="caustic", help="bench scene (caustic or caustic_point)")
    ap.add_argument("--out", help="default: bench/references/<scene>_<resolution>.exr")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))
    from _bootstrap import load_ember
    load_ember()
    from bench.references import reference_path
    from bench.scenes import by_name
    scene = by_name(args.scene)
    make(scene, args.out or reference_path(scene, args.resolution), args.resolution)


if __name__ == "__main__":
    main()
