"""Probe Cycles' light and emission conventions with tiny renders and print a table.

    python scenes/probe_cycles_conventions.py [--samples N]

Each probe builds a small scene from an empty file, renders it with Cycles (CPU, no
denoising/adaptive sampling/clamping) to a float32 EXR and reads the linear pixel values:

 (a) square area light of power P and size s seen directly: visible by default?  value
     vs P/(pi s^2); also its back side, and a disk of diameter d vs P/(pi * pi d^2/4)
 (b) point light of radius r seen directly: visible?  value vs P/(pi * 4 pi r^2)
 (c) Emission-shader quad: front vs back radiance; does it light a plane on its back side?
 (d) sun of strength E straight down on an albedo-0.8 diffuse plane seen from above:
     value vs 0.8 E/pi, with view transform Standard and AgX (EXR must not depend on it)
 (e) spot light profile across the cone edge, divided by the point-light irradiance
     I cos(theta)/d^2 (I = P/(4 pi)), against smoothstep((cos t - cos(a/2)) /
     ((1 - cos(a/2)) blend)) (Cycles 4+) and the old cos(t) * smoothstep form.
A few seconds in total on two cores.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))
import bpy  # noqa: E402

sys.path.insert(0, ROOT)
from _bootstrap import load_ember  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from reference import unbiased_cycles  # noqa: E402  (scenes/reference.py)

load_ember()
from ember.engine import imageio  # noqa: E402

TMP = tempfile.mkdtemp(prefix="ember_probe_")
SAMPLES = 64
ROWS = []


def row(probe, quantity, measured, expected=None, note=""):
    ratio = "" if expected in (None, 0) else f"{measured / expected:.4f}"
    exp = "" if expected is None else f"{expected:.5g}"
    ROWS.append((probe, quantity, f"{measured:.5g}", exp, ratio, note))


def fresh(res=(16, 16)):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    unbiased_cycles(sc, SAMPLES)
    sc.render.resolution_x, sc.render.resolution_y = res
    sc.render.resolution_percentage = 100
    world = bpy.data.worlds.new("W")
    bg = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    bg.inputs["Color"].default_value = (0, 0, 0, 1)
    sc.world = world
    sc.view_settings.view_transform = "Standard"
    return sc


def ortho_camera(sc, location, rotation, scale):
    cam = bpy.data.cameras.new("Cam")
    cam.type = "ORTHO"
    cam.ortho_scale = scale
    ob = bpy.data.objects.new("Cam", cam)
    ob.location, ob.rotation_euler = location, rotation
    sc.collection.objects.link(ob)
    sc.camera = ob
    return ob


def plane(sc, name, size, location, rotation=(0, 0, 0), material=None):
    h = size / 2
    me = bpy.data.meshes.new(name)
    me.from_pydata([(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], [], [(0, 1, 2, 3)])
    if material is not None:
        me.materials.append(material)
    ob = bpy.data.objects.new(name, me)
    ob.location, ob.rotation_euler = location, rotation
    sc.collection.objects.link(ob)
    return ob  # normal +Z (before rotation)


def material(name, kind, color, strength=1.0):
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    if kind == "diffuse":
        n = nt.nodes.new("ShaderNodeBsdfDiffuse")
        n.inputs["Color"].default_value = (*color, 1)
        nt.links.new(n.outputs["BSDF"], out.inputs["Surface"])
    else:
        n = nt.nodes.new("ShaderNodeEmission")
        n.inputs["Color"].default_value = (*color, 1)
        n.inputs["Strength"].default_value = strength
        nt.links.new(n.outputs["Emission"], out.inputs["Surface"])
    return mat


def light(sc, ltype, location, rotation=(0, 0, 0), **props):
    data = bpy.data.lights.new(ltype, ltype)
    for k, v in props.items():
        setattr(data, k, v)
    ob = bpy.data.objects.new(ltype, data)
    ob.location, ob.rotation_euler = location, rotation
    sc.collection.objects.link(ob)
    return ob


def render(sc, name):
    s = sc.render.image_settings
    s.file_format = "OPEN_EXR"
    s.color_depth = "32"
    sc.render.filepath = os.path.join(TMP, name + ".exr")
    sc.render.use_file_extension = False
    bpy.ops.render.render(write_still=True)
    return imageio.read_rgb(sc.render.filepath).astype(np.float64)


def centre(img, k=2):
    h, w, _ = img.shape
    return img[h // 2 - k:h // 2 + k, w // 2 - k:w // 2 + k].mean(axis=(0, 1))


# Camera at +Z looking down -Z (identity rotation) everywhere below.
DOWN = (0.0, 0.0, 0.0)
FLIP_X = (math.pi, 0.0, 0.0)  # turns an object's +Z normal (or a light's -Z axis) around


def probe_area():
    P, s = 100.0, 1.0
    expect = P / (math.pi * s * s)
    sc = fresh()
    # Area light emits along its local -Z: flip it so it faces the camera above.
    L = light(sc, "AREA", (0, 0, 0), FLIP_X, energy=P, shape="SQUARE", size=s)
    ortho_camera(sc, (0, 0, 5), DOWN, 0.5)  # frame fully inside the light
    row("a", "area: Object.visible_camera default", float(L.visible_camera), None,
        f"light.normalize default={getattr(L.data, 'normalize', 'n/a')}")
    v = centre(render(sc, "area_default"))[0]
    row("a", "square area, default visibility", v, None, "0 = hidden from camera rays")
    L.visible_camera = True  # the rest of (a) with camera visibility switched on
    v = centre(render(sc, "area_front"))[0]
    row("a", "square area P=100 s=1, front", v, expect, "expected P/(pi s^2)")
    L.rotation_euler = DOWN  # now faces away from the camera
    v = centre(render(sc, "area_back"))[0]
    row("a", "square area, back side", v, 0.0, "one-sided")
    L.rotation_euler = FLIP_X
    L.data.shape, L.data.size = "DISK", 1.0
    v = centre(render(sc, "disk_front"))[0]
    row("a", "disk area P=100 d=1, front", v, P / (math.pi * math.pi / 4),
        "expected P/(pi * pi d^2/4)")
    L.data.shape, L.data.size, L.data.size_y = "RECTANGLE", 1.0, 2.0
    ortho_camera(sc, (0, 0, 5), DOWN, 0.5)
    v = centre(render(sc, "rect_front"))[0]
    row("a", "rectangle 1x2 P=100, front", v, P / (math.pi * 2.0), "expected P/(pi A)")


def probe_point():
    P, r = 100.0, 0.5
    expect = P / (math.pi * 4 * math.pi * r * r)
    sc = fresh()
    L = light(sc, "POINT", (0, 0, 0), energy=P, shadow_soft_size=r)
    ortho_camera(sc, (0, 0, 5), DOWN, 0.2)  # the central part of the sphere's disc
    row("b", "point: Object.visible_camera default", float(L.visible_camera))
    v = centre(render(sc, "point_default"))[0]
    row("b", "point, default visibility", v, None, "0 = hidden from camera rays")
    L.visible_camera = True  # the rest of (b) with camera visibility switched on
    v = centre(render(sc, "point"))[0]
    row("b", "point P=100 r=0.5, centre of disc", v, expect, "expected P/(pi 4 pi r^2)")
    ortho_camera(sc, (0, 0, 5), DOWN, 1.2)  # whole disc, 16 px across 1.2 m
    prof = render(sc, "point_disc")[7:9, :, 0].mean(axis=0)  # the two middle rows
    for i in (9, 11, 12):  # pixel centres at (i + 0.5 - 8) * 0.075 m from the axis
        off = (i + 0.5 - 8) * 1.2 / 16 / r
        row("b", f"point disc at {off:.2f} r off centre", float(prof[i]), expect,
            "uniform-radiance disc if ratio 1")
    sc = fresh()
    L = light(sc, "SPOT", (0, 0, 0), FLIP_X, energy=P, shadow_soft_size=r,
              spot_size=math.radians(120))
    L.visible_camera = True
    ortho_camera(sc, (0, 0, 5), DOWN, 0.2)
    v = centre(render(sc, "spot_disc"))[0]
    row("b", "spot P=100 r=0.5 seen on axis", v, expect, "expected P/(pi 4 pi r^2)")


def probe_emission_mesh():
    Le = 2.0
    sc = fresh()
    em = material("Em", "emission", (Le, Le, Le), 1.0)
    plane(sc, "Emitter", 2.0, (0, 0, 0), DOWN, em)  # normal +Z, towards the camera
    ortho_camera(sc, (0, 0, 5), DOWN, 1.0)
    v = centre(render(sc, "em_front"))[0]
    row("c", "emission quad Le=2, front", v, Le)
    sc.objects["Emitter"].rotation_euler = FLIP_X  # normal -Z, camera sees the back
    v = centre(render(sc, "em_back"))[0]
    row("c", "emission quad Le=2, back", v, Le, "two-sided if ratio 1")
    # Does it light a receiver on its back side?  A 1x1 emitter at z=1 above a 4x4 diffuse
    # receiver at z=0; the camera above sees the receiver around the emitter. Compare the
    # emitter's normal pointing away from the receiver (+Z) with pointing at it (-Z).
    sc = fresh((32, 32))
    em = material("Em", "emission", (Le, Le, Le), 1.0)
    white = material("White", "diffuse", (0.8, 0.8, 0.8))
    plane(sc, "Receiver", 4.0, (0, 0, 0), DOWN, white)
    plane(sc, "Emitter", 1.0, (0, 0, 1), DOWN, em)  # normal +Z: away from the receiver
    ortho_camera(sc, (0, 0, 5), DOWN, 4.0)
    img_away = render(sc, "em_light_away")[:, :, 0]
    sc.objects["Emitter"].rotation_euler = FLIP_X  # normal -Z: towards the receiver
    img_to = render(sc, "em_light_to")[:, :, 0]
    ring = np.zeros((32, 32), bool)
    ring[4:28, 4:28] = True
    ring[10:22, 10:22] = False  # receiver pixels around (not under) the 1 m emitter
    a, t = float(img_away[ring].mean()), float(img_to[ring].mean())
    row("c", "receiver behind emitter / in front", a / t if t else 0.0, 1.0,
        f"lit from back side if ratio ~1 (back {a:.4g}, front {t:.4g})")


def probe_sun():
    E, albedo = 2.0, 0.8
    expect = albedo * E / math.pi
    for view in ("Standard", "AgX"):
        sc = fresh()
        white = material("White", "diffuse", (albedo, albedo, albedo))
        plane(sc, "Floor", 4.0, (0, 0, 0), DOWN, white)
        light(sc, "SUN", (0, 0, 3), DOWN, energy=E, angle=0.0)  # sun shines along -Z
        ortho_camera(sc, (0, 0, 5), DOWN, 1.0)
        sc.view_settings.view_transform = view
        v = centre(render(sc, f"sun_{view}"))[0]
        row("d", f"sun E=2 on albedo 0.8, view {view}", v, expect, "expected 0.8 E/pi")
    sc.view_settings.view_transform = "Standard"
    sun = sc.objects["SUN"]
    sun.data.angle = math.radians(5.0)
    v = centre(render(sc, "sun_angle5"))[0]
    row("d", "same, sun angle 5 deg", v, expect)
    sun.rotation_euler = (math.radians(60.0), 0.0, 0.0)
    v = centre(render(sc, "sun_tilt60"))[0]
    row("d", "same, angle 5, tilted 60 deg", v, expect * 0.5, "expected 0.8 E cos60/pi")


def smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def probe_spot():
    P, h, albedo = 1000.0, 1.0, 0.8
    size, blend = math.radians(60.0), 0.3
    W = 256
    sc = fresh((W, 4))
    white = material("White", "diffuse", (albedo, albedo, albedo))
    plane(sc, "Floor", 4.0, (0, 0, 0), DOWN, white)
    light(sc, "SPOT", (0, 0, h), DOWN, energy=P, shadow_soft_size=0.0, spot_size=size,
          spot_blend=blend)  # points down -Z
    sc.cycles.pixel_filter_type = "BOX"
    sc.cycles.filter_width = 1.0
    sc.cycles.samples = 256
    ortho_camera(sc, (0, 0, 5), DOWN, 2.0)  # x in [-1, 1] over 256 px
    img = render(sc, "spot_profile")[:, :, 0].mean(axis=0)
    x = (np.arange(W) + 0.5) / W * 2.0 - 1.0
    theta = np.arctan2(np.abs(x), h)
    d2 = h * h + x * x
    I = P / (4 * math.pi)
    unatt = albedo / math.pi * I * np.cos(theta) / d2  # point light of the same power
    meas = img / unatt
    cos_half = math.cos(size / 2)
    new = smoothstep((np.cos(theta) - cos_half) / ((1 - cos_half) * blend))
    old = np.cos(theta) * smoothstep((np.cos(theta) - cos_half) / ((1 - cos_half) * blend))
    row("e", "spot 60deg blend .3 on axis: atten", float(meas[W // 2 - 2:W // 2 + 2].mean()),
        1.0, "1 = power not concentrated in the cone")
    for deg in (0, 10, 20, 24, 26, 27, 28, 29, 29.5, 30, 31):
        i = W // 2 + int(round(math.tan(math.radians(deg)) * h / 2.0 * W))
        i = min(i, W - 1)
        t = math.degrees(theta[i])
        row("e", f"atten at theta={t:5.2f} deg", float(meas[i]), float(new[i]),
            f"old cos*smoothstep form {old[i]:.4f}")
    err_new = float(np.abs(meas - new).max())
    err_old = float(np.abs(meas - old).max())
    row("e", "max |atten - smoothstep form|", err_new, None, f"old form: {err_old:.4f}")


def main(argv=None):
    global SAMPLES
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=64)
    args = ap.parse_args(argv if argv is not None else sys.argv[1:])
    SAMPLES = args.samples
    probe_area()
    probe_point()
    probe_emission_mesh()
    probe_sun()
    probe_spot()
    print(f"\nCycles {bpy.app.version_string}, {SAMPLES} spp (spot profile 256 spp), EXR linear\n")
    head = ("probe", "quantity", "measured", "expected", "ratio", "note")
    widths = [max(len(str(r[i])) for r in ROWS + [head]) for i in range(len(head))]
    fmt = "  ".join(f"{{:{w}}}" for w in widths)
    print(fmt.format(*head))
    print(fmt.format(*("-" * w for w in widths)))
    for r in ROWS:
        print(fmt.format(*r))


if __name__ == "__main__":
    main()
