"""Light through a glass sphere: independent references against Ember's photon integrators.

    ./dev python bench/glass_flux.py [--photons 4000000] [--spp 16] [--cycles-spp 256]
                                     [--cycles-runs 4] [--out bench/results/photon/glass_flux.md]

The bench scenes caustic.blend (an emissive icosphere of radius 3 cm) and caustic_point.blend
(a radius-0 point light of the same power), and caustic_point with its light given a radius
(Blender's sphere light, Soft Falloff off). Two measurements:

1. The flux that reaches the floor through the glass sphere (the caustic photons' flux, red
   channel, W): Ember's photon tracer (its caustic stream, as the caustic map stores it)
   against (a) the NumPy particle tracer of bench/glass_particles.py on the scene's facets and
   (b) for the point light, a smooth sphere of the same radius traced the same way with
   photons aimed at it (a cone of directions: every photon meets the sphere). The light's
   power comes from the Blender light or material here, not from Ember's export.
2. Image regions at 64 x 64 (box filter): the sphere's shadow (floor pixels whose whole
   footprint lies in the shadow of the light's centre, caustic included), the shadow outside
   the caustic (less the caustic region of bench/regions.py grown by 2 px), the caustic
   region, and directly lit floor. References: the particle tracer's floor irradiance per
   pixel footprint (RHO / pi x E), Mitsuba 3's particle tracer (bench/references/*_64.exr,
   bench/mitsuba_reference.py) and Cycles (the mesh emitter; sphere lights of shrinking radius
   for the point light). Ember: photon, ppm, icache, path_caustic (all share the photon
   tracer and the caustic map) and path.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import pathlib
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))

from _bootstrap import load_ember  # noqa: E402

load_ember()
import bpy  # noqa: E402

from bench import glass_particles as gp  # noqa: E402
from bench import regions  # noqa: E402
from ember.engine import imageio, rng  # noqa: E402
from ember.engine.blender.export import export_scene  # noqa: E402
from ember.engine.session import RenderSession  # noqa: E402
from ember.engine.tracer import Tracer  # noqa: E402

W = 64
SUBPIXELS = 8  # per pixel side, for the shadow and floor coverage of a pixel
LIGHT_RADII = (0.2, 0.1, 0.05)  # sphere lights in place of the point light (Cycles finds them)
INTEGRATORS = {"photon": dict(samples=16), "ppm": dict(samples=32, photons=100_000), "icache": dict(samples=16),
               "path_caustic": dict(samples=16), "path": dict(samples=64)}
PHOTON_BATCH = 250_000
FINDINGS = "\n## Findings"  # a hand-written section of the results file, kept when it is rewritten


def _cycles_module():
    spec = importlib.util.spec_from_file_location("ember_scenes_reference", ROOT / "scenes" / "reference.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def open_scene(name: str, radius: float | None = None):
    """Open scenes/<name>.blend at 64 x 64; radius: give the point light that radius (Soft
    Falloff off: a sphere)."""
    bpy.ops.wm.open_mainfile(filepath=str(ROOT / "scenes" / f"{name}.blend"), load_ui=False)
    sc = bpy.context.scene
    sc.render.resolution_x = sc.render.resolution_y = W
    sc.render.resolution_percentage = 100
    if radius is not None:
        lamp = bpy.data.objects["PointLight"].data
        lamp.shadow_soft_size = radius
        lamp.use_soft_falloff = False
    return sc


def blender_geometry(sc):
    """Glass facets (F,3,3), emitter facets or None, the light's centre, and its red-channel
    strength from Blender's own data: a point light's intensity I = power x colour / (4 pi)
    W/sr (docs/cycles_conventions.md), an emission shader's radiance colour x strength."""
    dg = bpy.context.evaluated_depsgraph_get()
    tris = {}
    for inst in dg.object_instances:
        ob = inst.object
        if ob.type != "MESH":
            continue
        me = ob.to_mesh()
        me.calc_loop_triangles()
        t = np.zeros(len(me.loop_triangles) * 3, np.int32)
        co = np.zeros(len(me.vertices) * 3, np.float32)
        me.loop_triangles.foreach_get("vertices", t)
        me.vertices.foreach_get("co", co)
        mw = np.array(inst.matrix_world, np.float64)
        v = co.reshape(-1, 3) @ mw[:3, :3].T + mw[:3, 3]
        tris[ob.name] = v[t.reshape(-1, 3)]
        ob.to_mesh_clear()
    if "PointLight" in bpy.data.objects:
        ob = bpy.data.objects["PointLight"]
        strength = ob.data.energy * ob.data.color[0] / (4 * np.pi)
        return tris["GlassSphere"], None, np.array(ob.location, np.float64), strength
    em = bpy.data.materials["Emitter"].node_tree.nodes["Emission"]
    strength = em.inputs["Color"].default_value[0] * em.inputs["Strength"].default_value
    return tris["GlassSphere"], tris["Emitter"], tris["Emitter"].reshape(-1, 3).mean(0), strength


# ----------------------------------------------------------------------------------------------
# 1. Flux through the glass

def smooth_sphere_flux(light, centre, radius, intensity, n, seed=0):
    """Flux (through, reflected, se of through) onto the floor from a point light through a
    smooth sphere: photons aimed uniformly in the cone the sphere subtends (flux I Omega / n)."""
    g = np.random.default_rng(seed)
    axis = centre - light
    dist = np.linalg.norm(axis)
    axis /= dist
    cos_max = np.sqrt(1 - (radius / dist) ** 2)
    omega = 2 * np.pi * (1 - cos_max)
    mu = 1 - g.random(n) * (1 - cos_max)
    t, b = gp._frame(axis[None])
    phi = 2 * np.pi * g.random(n)
    s = np.sqrt(1 - mu * mu)
    d = mu[:, None] * axis + (s * np.cos(phi))[:, None] * t + (s * np.sin(phi))[:, None] * b
    o = np.repeat(light[None], n, 0)
    w = np.full(n, intensity * omega / n)
    per = np.zeros(n)
    idx = np.arange(n)
    inside, entered = np.zeros(n, bool), np.zeros(n, bool)
    reflected = 0.0
    for _ in range(128):
        if not len(o):
            break
        oc = o - centre
        bb = np.einsum("ij,ij->i", oc, d)
        disc = np.maximum(bb * bb - (np.einsum("ij,ij->i", oc, oc) - radius * radius), 0.0)
        tt = np.where(inside, -bb + np.sqrt(disc), -bb - np.sqrt(disc))
        p = o + tt[:, None] * d
        nf = (p - centre) / radius * np.where(inside, -1.0, 1.0)[:, None]
        cos_i = -np.einsum("ij,ij->i", d, nf)
        eta = np.where(inside, 1 / gp.IOR, gp.IOR)
        F, cos_t = gp.fresnel(cos_i, eta)
        refl = g.random(len(o)) < F
        nd = np.where(refl[:, None], d + 2 * cos_i[:, None] * nf, d / eta[:, None] + (cos_i / eta - cos_t)[:, None] * nf)
        nd /= np.linalg.norm(nd, axis=1)[:, None]
        new_inside = inside ^ ~refl
        leaving = inside & ~new_inside | ~inside & refl
        tp, _, wall = gp._planes(p[leaving], nd[leaving])
        floor = np.isfinite(tp) & ~wall
        through = entered[leaving] & floor
        np.add.at(per, idx[leaving][through], w[leaving][through])
        reflected += w[leaving][~entered[leaving] & floor].sum()
        keep = ~leaving
        o, d, w, idx = p[keep] + 1e-9 * nd[keep], nd[keep], w[keep], idx[keep]
        entered, inside = (entered | ~refl)[keep], new_inside[keep]
    return per.sum(), reflected, float(np.sqrt(max((per ** 2).sum() - per.sum() ** 2 / n, 0.0)))


def ember_caustic_flux(name, radius, n, seed=7):
    """Flux (mean, se) of Ember's caustic photons on the floor (red channel) per emitted path."""
    open_scene(name, radius)
    scene = export_scene(bpy.context.evaluated_depsgraph_get())[0]
    tracer = Tracer(scene.replace(settings=scene.settings.replace(integrator="photon", width=W, height=W)))
    photon_tracer = tracer.integrator.photon_tracer
    per_batch = []
    for b in range(max(1, n // PHOTON_BATCH)):
        sampler = rng.Sampler(seed, np.zeros(PHOTON_BATCH, np.int64),
                              np.arange(b * PHOTON_BATCH, (b + 1) * PHOTON_BATCH), "random", domain=rng.PHOTONS)
        out = photon_tracer.trace(sampler, True)
        floor = np.abs(out["position"][:, 2]) < 1e-3
        per_batch.append(out["flux"][floor, 0].astype(np.float64).sum() / PHOTON_BATCH)
    per_batch = np.array(per_batch)
    return per_batch.mean(), per_batch.std(ddof=1) / np.sqrt(len(per_batch))


# ----------------------------------------------------------------------------------------------
# 2. Image regions

def pixel_masks(sc, glass, light):
    """Boolean (W,W) masks: floor (footprint all on visible floor), shadow (and floor), lit."""
    scene = export_scene(bpy.context.evaluated_depsgraph_get())[0]
    cam = scene.camera
    left, right, bottom, top = cam.window
    m = np.asarray(cam.world_from_camera, np.float64)
    n = W * SUBPIXELS
    u = (np.arange(n) + 0.5) / n
    X, Y = np.meshgrid(left + u * (right - left), top - u * (top - bottom))
    d = np.stack([X, Y, -np.ones_like(X)], -1).reshape(-1, 3) @ m[:3, :3].T
    d /= np.linalg.norm(d, axis=1)[:, None]
    e = np.repeat(m[:3, 3][None], len(d), 0)
    sphere = gp.Sphere(glass)
    t_glass, _ = sphere.enter(e, d)
    t_plane, normal, wall = gp._planes(e, d)
    floor = np.isfinite(t_plane) & ~wall & (t_plane < t_glass)
    p = e + np.where(np.isfinite(t_plane), t_plane, 0)[:, None] * d
    to_light = light - p
    dist = np.linalg.norm(to_light, axis=1)
    t_block, _ = sphere.enter(p + 1e-6 * to_light / dist[:, None], to_light / dist[:, None])
    shadow = floor & (t_block < dist)
    cover = lambda a: a.reshape(W, SUBPIXELS, W, SUBPIXELS).mean(axis=(1, 3))  # noqa: E731
    floor_px = cover(floor) == 1
    shadow_px = floor_px & (cover(shadow) == 1)
    near = cover(shadow) > 0
    for _ in range(3):
        near = _grow(near)
    return {"floor": floor_px, "shadow": shadow_px, "lit": floor_px & ~near}


def _grow(mask):
    out = mask.copy()
    out[1:] |= mask[:-1]
    out[:-1] |= mask[1:]
    out[:, 1:] |= mask[:, :-1]
    out[:, :-1] |= mask[:, 1:]
    return out


def region_masks(base, reference):
    """The masks of the table (from the geometry and the reference's caustic region)."""
    caustic = regions.bright_region(reference, regions.CAUSTIC_SEEDS["caustic"])
    grown = _grow(_grow(caustic))
    return {"shadow": base["shadow"], "shadow outside caustic": base["shadow"] & ~grown,
            "caustic": caustic, "lit floor": base["lit"]}


def particle_run(glass, emitter, light, n, seed, radius=None):
    """The particle tracer on the scene (gp.trace's dict, per unit strength) with the camera."""
    scene = export_scene(bpy.context.evaluated_depsgraph_get())[0]
    sphere = gp.Sphere(glass)
    cam = gp.Camera(scene.camera.world_from_camera, scene.camera.window, W, sphere)
    if emitter is not None:
        emit = lambda m, g: gp.emit_mesh(emitter, m, g)  # noqa: E731
    elif radius:
        emit = lambda m, g: gp.emit_sphere(light, radius, m, g)  # noqa: E731
    else:
        emit = lambda m, g: gp.emit_point(light, m, g)  # noqa: E731
    return gp.trace(sphere, emit, n, seed, camera=cam)


def particle_image(run, strength, colour):
    """(W,W,3) floor radiance RHO / pi x E of a particle run (floor pixels only), and its
    caustic (L S+ D) part's irradiance (W,W)."""
    E = (run["E_direct"] + run["E_caustic"] + run["E_rest"]).reshape(W, W) * strength
    return (gp.RHO / np.pi) * E[..., None] * np.asarray(colour) / colour[0], run["E_caustic"].reshape(W, W) * strength


def ember_image(name, radius, integrator, seed=1, **kw):
    """(W,W,3) Ember's render of a bench scene (radius: see open_scene), and its seconds."""
    open_scene(name, radius)
    scene = export_scene(bpy.context.evaluated_depsgraph_get())[0]
    s = scene.settings.replace(width=W, height=W, border=(0, 0, W, W), integrator=integrator, seed=seed, **kw)
    t0 = time.perf_counter()
    session = RenderSession(scene.replace(settings=s))
    session.run()
    return session.film.mean().reshape(W, W, 3), time.perf_counter() - t0


def cycles_image(name, radius, spp, runs, tmp):
    ref = _cycles_module()
    sc = open_scene(name, radius)
    ref.unbiased_cycles(sc, spp)
    imgs = [ref.render_rgb(sc, os.path.join(tmp, f"cycles_{k}.exr"), 100 + k)[0] for k in range(runs)]
    return np.mean(imgs, axis=0), imgs


def region_ratios(image, reference, masks, variance=None):
    """{region: (mean ratio, its relative standard error or None)} over all channels."""
    out = {}
    for key, m in masks.items():
        r = reference[m].mean()
        se = None if variance is None else float(np.sqrt(variance[m].sum()) / (m.sum() * 3) / r)
        out[key] = (float(image[m].mean() / r), se)
    return out


def _fmt(v):
    ratio, se = v
    return f"{ratio:.4f}" if se is None else f"{ratio:.4f} ± {se:.4f}"


def _light_colour(emitter):
    if emitter is None:
        return np.array(bpy.data.objects["PointLight"].data.color)
    node = bpy.data.materials["Emitter"].node_tree.nodes["Emission"]
    return np.array(node.inputs["Color"].default_value[:3])


def _table_head(masks):
    return ["| renderer | " + " | ".join(f"{k} ({m.sum()} px)" for k, m in masks.items()) + " | time |",
            "|---" * (len(masks) + 2) + "|"]


def _cycles_rows(name, radius, masks, mine, args, tmp):
    t0 = time.perf_counter()
    cy, runs = cycles_image(name, radius, args.cycles_spp, args.cycles_runs, tmp)
    label = f"Cycles {args.cycles_runs} x {args.cycles_spp} spp (run range)"
    cells = []
    for k, m in masks.items():
        per = [img[m].mean() / mine[m].mean() for img in runs]
        cells.append(f"{cy[m].mean() / mine[m].mean():.4f} ({min(per):.3f}-{max(per):.3f})")
    return f"| {label} | " + " | ".join(cells) + f" | {time.perf_counter() - t0:.0f} s |"


def _ember_row(name, radius, integrator, kw, masks, mine, seeds=1):
    """A table row of Ember's region ratios: one seed, or the mean and its standard error
    over `seeds` seeds (photon maps and camera samples both change with the seed)."""
    ratios, dt = [], 0.0
    for seed in range(1, seeds + 1):
        img, t = ember_image(name, radius, integrator, seed=seed, **kw)
        ratios.append(region_ratios(img, mine, masks))
        dt += t
    cells = []
    for k in masks:
        r = np.array([x[k][0] for x in ratios])
        cells.append(_fmt((r.mean(), r.std(ddof=1) / np.sqrt(seeds) if seeds > 1 else None)))
    label = f"Ember {integrator} {kw['samples']} spp" + (f", {seeds} seeds" if seeds > 1 else "")
    return f"| {label} | " + " | ".join(cells) + f" | {dt:.0f} s |"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photons", type=int, default=3_000_000, help="particle-tracer photons per scene")
    ap.add_argument("--ember-photons", type=int, default=1_000_000, help="Ember photon paths for the flux")
    ap.add_argument("--spp", type=float, default=1.0, help="scale of the Ember samples")
    ap.add_argument("--seeds", type=int, default=3, help="seeds of the photon integrator's renders")
    ap.add_argument("--cycles-spp", type=int, default=256)
    ap.add_argument("--cycles-runs", type=int, default=4)
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "photon" / "glass_flux.md"))
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    out = pathlib.Path(args.out)
    lines = ["# Light through a glass sphere: independent references", "",
             "Written by `./dev python bench/glass_flux.py " + " ".join(argv if argv is not None else sys.argv[1:])
             + "` (its docstring says what each number is). Red channel for the flux; ± one standard error.", ""]

    def emit(*new):
        lines.extend(new)
        print("\n".join(new), flush=True)

    runs, scenes = {}, {}
    for name in ("caustic_point", "caustic"):
        sc = open_scene(name)
        glass, emitter, light, strength = blender_geometry(sc)
        scenes[name] = (glass, emitter, light, strength, _light_colour(emitter), pixel_masks(sc, glass, light))
        runs[name] = particle_run(glass, emitter, light, args.photons, 21)

    # 1. Flux
    emit("## Flux onto the floor through the glass (W, red)", "",
         "| light | reference | through the glass | reflected by the sphere | through + reflected "
         "| Ember caustic photons | Ember / reference |", "|---|---|---|---|---|---|---|")
    for name, radius, label in (("caustic_point", None, "point light, radius 0"),
                                ("caustic", None, "emissive icosphere r 3 cm"),
                                ("caustic_point", 0.03, "sphere light r 3 cm")):
        glass, emitter, light, strength = scenes[name][:4]
        run = runs[name]
        th, se, rf = run["through"] * strength, run["through_se"] * strength, run["reflected"] * strength
        e, e_se = ember_caustic_flux(name, radius, args.ember_photons)
        ref = "facets, particle tracer" + (" of the point light (a sphere light differs by ~(r/d)^2)" if radius else "")
        emit(f"| {label} | {ref} | {th:.4f} ± {se:.4f} | {rf:.4f} | {th + rf:.4f} | "
             f"{e:.4f} ± {e_se:.4f} | {e / (th + rf):.4f} ± {np.hypot(e_se, se) / (th + rf):.4f} |")
        if name == "caustic_point" and radius is None:
            sphere = gp.Sphere(glass)
            sm = smooth_sphere_flux(light, sphere.c, sphere.r, strength, args.photons)
            emit(f"| {label} | smooth sphere (r {sphere.r:.3f}), photons aimed at it | {sm[0]:.4f} ± {sm[2]:.4f} "
                 f"| {sm[1]:.4f} | {sm[0] + sm[1]:.4f} | | {e / (sm[0] + sm[1]):.4f} |")
    emit("", "The facets pass a little less light than a smooth sphere; Ember's geometry is the facets.", "")

    # 2. Regions
    emit("## Image regions at 64 x 64: mean over the region / the particle tracer's", "",
         "Ember's ±: the standard error over seeds where there are several; one seed has none.", "")
    with tempfile.TemporaryDirectory(prefix="ember_glass_") as tmp:
        for name in ("caustic_point", "caustic"):
            glass, emitter, light, strength, colour, base = scenes[name]
            mine, caustic_part = particle_image(runs[name], strength, colour)
            ch, _ = imageio.read_exr(ROOT / "bench" / "references" / f"{name}_64.exr")
            mitsuba = np.stack([ch[c] for c in "RGB"], -1).astype(np.float64)
            masks = region_masks(base, mitsuba)
            emit(f"### {name}", "", *_table_head(masks))
            red = mine[..., 0] * np.pi / gp.RHO
            emit("| particle tracer: the share of L S+ D light (through or off the glass) | "
                 + " | ".join(f"{caustic_part[m].sum() / red[m].sum():.3f}" for m in masks.values()) + " | |")
            emit("| Mitsuba 3 ptracer (bench/references) | "
                 + " | ".join(f"{mitsuba[m].mean() / mine[m].mean():.4f}" for m in masks.values()) + " | |")
            if emitter is not None:
                emit(_cycles_rows(name, None, masks, mine, args, tmp))
            for integrator, kw in INTEGRATORS.items():
                kw = dict(kw, samples=max(1, int(kw["samples"] * args.spp)))
                emit(_ember_row(name, None, integrator, kw, masks, mine, args.seeds if integrator == "photon" else 1))
            emit("")
            if emitter is None:
                point_masks = masks

        # 3. Sphere lights of shrinking radius in place of the point light
        emit("## The point light as the limit of sphere lights (caustic_point, Soft Falloff off)", "",
             "Each row's ratio is to the particle tracer with the same sphere light.", "")
        glass, emitter, light, strength, colour, base = scenes["caustic_point"]
        for radius in LIGHT_RADII:
            open_scene("caustic_point", radius)
            mine, _ = particle_image(particle_run(glass, None, light, args.photons // 2, 31, radius),
                                     strength / (np.pi * radius * radius), colour)
            emit(f"### sphere light r {radius * 100:g} cm", "", *_table_head(point_masks))
            emit(_cycles_rows("caustic_point", radius, point_masks, mine, args, tmp))
            emit(_ember_row("caustic_point", radius, "photon", dict(samples=max(1, int(16 * args.spp))),
                            point_masks, mine), "")
    emit(f"Total {time.perf_counter() - t_start:.0f} s on a shared 2-core machine.")
    out.parent.mkdir(parents=True, exist_ok=True)
    kept = out.read_text().split(FINDINGS, 1) if out.exists() else []
    out.write_text("\n".join(lines) + "\n" + (FINDINGS + kept[1] if len(kept) == 2 else ""))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
