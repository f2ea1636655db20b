"""A row of spheres, one shader feature each, lit by an area light and a dim white world, seen
by an orthographic camera; Ember's and Cycles' renders of it over independent seeds, and the
means over each sphere's four quadrants (the anisotropic highlight's orientation shows there).
Shared by tests/test_anisotropy.py, tests/test_thin_film.py and bench/closures_aniso_film.py."""
from __future__ import annotations

import os
import tempfile

import numpy as np

PX = 12  # pixels per unit
RADIUS = 0.4


def bpy_module():
    import pytest
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))
    return pytest.importorskip("bpy")


def node_material(bpy, name, kind, links=(), **inputs_and_props):
    """A material of one shader node `kind` (inputs by name, else node properties); links:
    (node kind, its output, input of the shader, {its props}) linked in."""
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    nt.nodes.clear()
    node = nt.nodes.new(kind)
    for key, value in inputs_and_props.items():
        if key in node.inputs:
            node.inputs[key].default_value = value
        else:
            setattr(node, key, value)
    for src_kind, output, socket, props in links:
        src = nt.nodes.new(src_kind)
        for k, v in props.items():
            setattr(src, k, v)
        nt.links.new(src.outputs[output], node.inputs[socket])
    nt.links.new(node.outputs[0], nt.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    return mat


def build(bpy, specs):
    """The scene: sphere i at x = i - (n - 1) / 2 of the material node_material(bpy, **specs[i]);
    returns the bpy scene."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    materials = [node_material(bpy, **spec) for spec in specs]
    sc = bpy.context.scene
    n = len(materials)
    sc.render.resolution_x, sc.render.resolution_y = PX * n, PX
    sc.render.resolution_percentage = 100
    cam_data = bpy.data.cameras.new("Camera")
    cam_data.type, cam_data.ortho_scale = "ORTHO", float(n)
    cam = bpy.data.objects.new("Camera", cam_data)
    cam.location, cam.rotation_euler = (0.0, -10.0, 0.0), (np.pi / 2, 0.0, 0.0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    world = bpy.data.worlds.new("World")
    sc.world = world
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.2, 0.2, 0.2, 1.0)
    light_data = bpy.data.lights.new("Area", "AREA")
    light_data.energy, light_data.size = 400.0, 1.5
    light = bpy.data.objects.new("Area", light_data)
    light.location = (-2.0, -4.0, 3.0)
    light.rotation_euler = (np.radians(50.0), 0.0, np.radians(-27.0))
    sc.collection.objects.link(light)
    for i, mat in enumerate(materials):
        bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=RADIUS,
                                             location=(i - (n - 1) / 2, 0.0, 0.0))
        bpy.ops.object.shade_smooth()
        bpy.context.active_object.data.materials.append(mat)
    return sc


def cycles_images(bpy, sc, samples, runs, seed=100, bounces=16):
    """(runs, H, W, 3) Cycles' renders (CPU, no clamping, box filter, every bounce limit
    `bounces`, caustics on)."""
    from ember.engine import imageio
    c = sc.cycles
    sc.render.engine = "CYCLES"
    c.device, c.samples, c.use_adaptive_sampling, c.use_denoising = "CPU", samples, False, False
    c.blur_glossy, c.sample_clamp_direct, c.sample_clamp_indirect = 0.0, 0.0, 0.0
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = c.transparent_max_bounces = bounces
    c.caustics_reflective = c.caustics_refractive = True
    c.pixel_filter_type = "BOX"
    c.use_animated_seed = False
    sc.render.use_compositing = sc.render.use_sequencer = False
    sc.render.image_settings.file_format, sc.render.image_settings.color_depth = "OPEN_EXR", "32"
    sc.render.use_file_extension = False
    images = []
    with tempfile.TemporaryDirectory(prefix="ember_spheres_") as tmp:
        for k in range(runs):
            c.seed = seed + k
            sc.render.filepath = f"{tmp}/run{k}.exr"
            bpy.ops.render.render(write_still=True)
            images.append(imageio.read_rgb(sc.render.filepath).astype(np.float64))
    return np.stack(images)


def ember_images(bpy, samples, runs, seed=1):
    """(runs, H, W, 3) Ember's path tracer with the scene's Cycles settings."""
    from ember.engine.blender.export import export_scene
    from ember.engine.session import RenderSession
    r = bpy.context.scene.render
    h, w = r.resolution_y, r.resolution_x
    images = []
    for k in range(runs):
        scene, _ = export_scene(bpy.context.evaluated_depsgraph_get(),
                                overrides=dict(samples=samples, seed=seed + k, integrator="path", threads=2))
        session = RenderSession(scene)
        session.run()
        images.append(session.film.mean().reshape(h, w, 3))
    return np.stack(images)


def quadrant_masks(n):
    """[(sphere, quadrant, (H, W) bool)]: the four quadrants of each sphere's disc (inside 0.9 R)."""
    x = (np.arange(PX * n) + 0.5) / PX - n / 2
    z = 0.5 - (np.arange(PX) + 0.5) / PX
    X, Z = np.meshgrid(x, z)
    out = []
    for i in range(n):
        dx, dz = X - (i - (n - 1) / 2), Z
        disc = dx * dx + dz * dz < (0.9 * RADIUS) ** 2
        for q, m in enumerate(((dx < 0) & (dz > 0), (dx >= 0) & (dz > 0), (dx < 0) & (dz <= 0), (dx >= 0) & (dz <= 0))):
            out.append((i, q, disc & m))
    return out


def region_means(images, n):
    """(runs, 4 n, 3) means over each sphere's quadrants, per channel (a film's colour shows)."""
    return np.stack([images[:, m].mean(axis=1) for _, _, m in quadrant_masks(n)], axis=1)


def compare(ember, cycles, n, tol):
    """Assert every region's and channel's mean agrees within tol plus the Sidak-corrected noise
    band (a t-test, family-wise level 0.01); returns (Ember / Cycles - 1, its standard error),
    each (4 n, 3)."""
    from scipy import stats as st
    from stats import sidak_alpha
    e, c = region_means(ember, n), region_means(cycles, n)
    mean_c = c.mean(axis=0)
    d = e.mean(axis=0) / mean_c - 1.0
    se = np.sqrt(e.var(axis=0, ddof=1) / len(e) + c.var(axis=0, ddof=1) / len(c)) / mean_c
    t = st.t.ppf(1 - sidak_alpha(0.01, d.size) / 2, min(len(e), len(c)) - 1)
    bad = np.argwhere(np.abs(d) > tol + t * se)
    assert not len(bad), [(f"sphere {r // 4} quadrant {r % 4} channel {ch}", f"{d[r, ch]:+.2%} (se {se[r, ch]:.2%})")
                          for r, ch in bad]
    return d, se


def spheres_agree_with_cycles(specs, samples, runs, tol):
    """Build the spheres of `specs`, render them with Cycles and Ember (the add-on registered
    for the time of it) and compare every quadrant of every sphere (compare)."""
    import ember
    bpy = bpy_module()
    ember.register()
    try:
        sc = build(bpy, specs)
        cycles = cycles_images(bpy, sc, samples, runs)
        emb = ember_images(bpy, samples, runs)
    finally:
        ember.unregister()
    compare(emb, cycles, len(specs), tol)
