"""Build the example and test scenes from nothing but bpy and NumPy, and save them as .blend.

    python scenes/build.py [--out DIR] [--only cornell_box|lights]

Writes DIR/cornell_box.blend and DIR/lights.blend (DIR defaults to this folder). Needs the
`bpy` module (Blender as a Python module) or `blender -b -P scenes/build.py -- [--out DIR]`.

Every scene starts from Blender's factory settings with an empty scene, so all render
settings are Blender/Cycles defaults (pixel filter Blackman-Harris 1.5 px, default engine)
except what is set here on purpose: resolution, camera, a black world, materials, lights.
The render engine is left at the file default; tests and scenes/reference.py switch it.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile

import numpy as np

os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))
import bpy  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))

# ------------------------------------------------------------------------------------------
# Cornell box.
# Geometry: the measured data of the Cornell Program of Computer Graphics, "Cornell Box Data",
# http://www.graphics.cornell.edu/online/box/data.html (mirror:
# https://www.graphicon.ru/oldgr/courses/cg_el99/c_box/data.htm). Units as published (the
# box is about 550 wide); right-handed, y up, the camera at (278, 273, -800) looks along +z,
# so x = 556 is the camera's left (the red wall).
# Colours: the RGB set of Mitsuba 3's `cornell_box()` (mitsuba3, src/python/python/util.py).
# ------------------------------------------------------------------------------------------
CORNELL_SCALE = 0.01  # published units -> metres (box about 5.5 m, as Mitsuba's test scene)

CORNELL_QUADS = {  # name: (material, [quads of 4 points]); the quad lists are the data page's
    "Floor": ("white", [[(552.8, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 559.2),
                         (549.6, 0.0, 559.2)]]),
    "Ceiling": ("white", [[(556.0, 548.8, 0.0), (556.0, 548.8, 559.2), (0.0, 548.8, 559.2),
                           (0.0, 548.8, 0.0)]]),
    "BackWall": ("white", [[(549.6, 0.0, 559.2), (0.0, 0.0, 559.2), (0.0, 548.8, 559.2),
                            (556.0, 548.8, 559.2)]]),
    "RightWall": ("green", [[(0.0, 0.0, 559.2), (0.0, 0.0, 0.0), (0.0, 548.8, 0.0),
                             (0.0, 548.8, 559.2)]]),
    "LeftWall": ("red", [[(552.8, 0.0, 0.0), (549.6, 0.0, 559.2), (556.0, 548.8, 559.2),
                          (556.0, 548.8, 0.0)]]),
}
# Blocks: the top face as published; the sides are the top face dropped to the floor (the
# data page lists exactly these side quads), so each block is a closed box.
CORNELL_BLOCK_TOPS = {
    "ShortBlock": (165.0, [(130.0, 65.0), (82.0, 225.0), (240.0, 272.0), (290.0, 114.0)]),
    "TallBlock": (330.0, [(423.0, 247.0), (265.0, 296.0), (314.0, 456.0), (472.0, 406.0)]),
}
# Light: 130 x 105 at y = 548.8 on the data page (flush with the ceiling); we lower it by
# 0.1 units (1 mm) so it does not coincide with the ceiling.
CORNELL_LIGHT = [(343.0, 548.7, 227.0), (343.0, 548.7, 332.0), (213.0, 548.7, 332.0),
                 (213.0, 548.7, 227.0)]
CORNELL_CAMERA = dict(position=(278.0, 273.0, -800.0), focal_mm=35.0, sensor_mm=25.0)  # fov 39.3077

CORNELL_COLORS = {
    "white": (0.885809, 0.698859, 0.666422),
    "green": (0.105421, 0.37798, 0.076425),
    "red": (0.570068, 0.0430135, 0.0443706),
}
CORNELL_LIGHT_RADIANCE = (18.387, 13.9873, 6.75357)


def cornell_to_blender(p) -> np.ndarray:
    """Cornell (x, y up, z into the box) -> Blender (X, Y, Z up), metres.

    (X, Y, Z) = 0.01 * (-x, z, y): a proper rotation (det +1), so handedness is kept and the
    red wall stays on the camera's left; the camera then looks along +Y.
    """
    p = np.asarray(p, dtype=np.float64)
    return CORNELL_SCALE * np.stack([-p[..., 0], p[..., 2], p[..., 1]], axis=-1)


# ------------------------------------------------------------------------------------------
# Helpers
# ------------------------------------------------------------------------------------------
def new_empty_file():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.materials, bpy.data.lights,
                 bpy.data.cameras, bpy.data.worlds):
        for block in list(coll):
            coll.remove(block)
    return scene


def set_output(scene, size=256):
    scene.render.resolution_x = size
    scene.render.resolution_y = size
    scene.render.resolution_percentage = 100


def black_world(scene):
    world = bpy.data.worlds.new("World")
    nt = world.node_tree
    bg = next(n for n in nt.nodes if n.type == "BACKGROUND")
    bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    scene.world = world
    return world


def _clear_nodes(mat):
    nt = mat.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    out.location = (300, 0)
    return nt, out


def diffuse_material(name, color):
    """Diffuse BSDF (roughness 0: Lambertian) with base colour `color` (linear RGB)."""
    mat = bpy.data.materials.new(name)
    nt, out = _clear_nodes(mat)
    bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.0
    nt.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    mat.diffuse_color = (*color, 1.0)  # viewport colour only
    return mat


def emission_material(name, color, strength=1.0):
    """Emission shader only: emitted radiance = color x strength (Cycles units)."""
    mat = bpy.data.materials.new(name)
    nt, out = _clear_nodes(mat)
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (*color, 1.0)
    em.inputs["Strength"].default_value = strength
    nt.links.new(em.outputs["Emission"], out.inputs["Surface"])
    return mat


def _newell_normal(pts):
    pts = np.asarray(pts, dtype=np.float64)
    n = np.zeros(3)
    for i in range(len(pts)):
        a, b = pts[i], pts[(i + 1) % len(pts)]
        n += np.cross(a, b)
    return n / np.linalg.norm(n)


def triangles_from_quads(quads, facing):
    """Quads (Q,4,3) -> vertices (4Q,3), triangles (2Q,3), each quad split (0,1,2),(0,2,3).

    facing(centroid, normal) -> True if the quad's winding already gives the wanted normal;
    otherwise the quad is reversed first. Explicit triangles make the split of the
    non-planar walls of the measured box deterministic for every renderer.
    """
    verts, tris = [], []
    for q in quads:
        q = np.asarray(q, dtype=np.float64)
        if not facing(q.mean(axis=0), _newell_normal(q)):
            q = q[::-1]
        base = len(verts)
        verts.extend(q)
        tris += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return np.array(verts), tris


def mesh_object(scene, name, verts, faces, material):
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(map(float, v)) for v in verts], [], [tuple(f) for f in faces])
    me.validate()
    me.update()
    if hasattr(me, "shade_flat"):
        me.shade_flat()
    me.materials.append(material)
    ob = bpy.data.objects.new(name, me)
    scene.collection.objects.link(ob)
    return ob


def camera_object(scene, name, location, rotation_euler, lens_mm, sensor_mm):
    cam = bpy.data.cameras.new(name)
    cam.lens = lens_mm
    cam.sensor_width = sensor_mm
    cam.sensor_fit = "AUTO"
    ob = bpy.data.objects.new(name, cam)
    ob.location = location
    ob.rotation_euler = rotation_euler
    scene.collection.objects.link(ob)
    scene.camera = ob
    return ob


def look_at_euler(location, target):
    """Euler XYZ that points a camera (or light: local -Z) from location to target, Z up."""
    from mathutils import Vector
    d = Vector(target) - Vector(location)
    return d.to_track_quat("-Z", "Y").to_euler()


def light_object(scene, name, ltype, location, target=None, **props):
    data = bpy.data.lights.new(name, ltype)
    for k, v in props.items():
        setattr(data, k, v)
    ob = bpy.data.objects.new(name, data)
    ob.location = location
    if target is not None:
        ob.rotation_euler = look_at_euler(location, target)
    scene.collection.objects.link(ob)
    return ob


# ------------------------------------------------------------------------------------------
# Scenes
# ------------------------------------------------------------------------------------------
def build_cornell_box():
    scene = new_empty_file()
    scene.name = "CornellBox"
    set_output(scene, 256)
    black_world(scene)
    mats = {k: diffuse_material(k.capitalize(), c) for k, c in CORNELL_COLORS.items()}

    interior = cornell_to_blender((278.0, 274.4, 279.6))  # room centre: walls face it

    def faces_inward(c, n):
        return np.dot(interior - c, n) > 0

    for name, (mat, quads) in CORNELL_QUADS.items():
        v, t = triangles_from_quads(cornell_to_blender(np.array(quads)), faces_inward)
        mesh_object(scene, name, v, t, mats[mat])

    for name, (height, top) in CORNELL_BLOCK_TOPS.items():
        top3 = [(x, height, z) for x, z in top]
        bottom3 = [(x, 0.0, z) for x, z in top]
        quads = [top3, bottom3]
        for i in range(4):
            j = (i + 1) % 4
            quads.append([bottom3[i], top3[i], top3[j], bottom3[j]])
        quads = cornell_to_blender(np.array(quads))
        centre = quads.reshape(-1, 3).mean(axis=0)

        def faces_outward(c, n, centre=centre):
            return np.dot(c - centre, n) > 0

        v, t = triangles_from_quads(quads, faces_outward)
        mesh_object(scene, name, v, t, mats["white"])

    light_mat = emission_material("Light", CORNELL_LIGHT_RADIANCE, 1.0)
    v, t = triangles_from_quads(cornell_to_blender(np.array([CORNELL_LIGHT])),
                                lambda c, n: n[2] < 0)  # faces down
    mesh_object(scene, "Light", v, t, light_mat)

    cam_pos = cornell_to_blender(CORNELL_CAMERA["position"])
    # Blender cameras look down local -Z with local +Y up; rotating 90 deg about X makes
    # them look along +Y (Cornell +z) with +Z (Cornell +y) up.
    camera_object(scene, "Camera", tuple(cam_pos), (math.pi / 2, 0.0, 0.0),
                  CORNELL_CAMERA["focal_mm"], CORNELL_CAMERA["sensor_mm"])
    return scene


LIGHTS_GREY = (0.6, 0.6, 0.6)
LIGHTS_BOX_COLOR = (0.8, 0.25, 0.05)


def build_lights():
    """A floor, a back wall and a left wall (grey diffuse), a grey pillar and an orange box,
    lit by one light of each kind. Each light has its own visible footprint:
      point (r 0.1, 40 W)     warm pool on the floor, front left
      spot (r 0.05, 500 W)    45 deg cone, blend 0.3, bluish ellipse on the floor, right
      sun (5 deg, E 2)        from the front right, everywhere; casts the box's and the
                              pillar's shadows back and to the left
      area square (1 m, 150 W) on the left wall, facing +X: the box's left side, the floor
                              and back wall on the left
      area disk (0.6 m, 150 W) high at the back, tilted down and towards the camera; visible
                              to the camera (deliberately), lights the floor behind the box
                              (in the box's sun shadow) and the pillar
    """
    scene = new_empty_file()
    scene.name = "Lights"
    set_output(scene, 256)
    black_world(scene)
    grey = diffuse_material("Grey", LIGHTS_GREY)
    orange = diffuse_material("Orange", LIGHTS_BOX_COLOR)

    def up(c, n):  # floor faces +Z
        return n[2] > 0

    floor = [[(-4, -3, 0), (4, -3, 0), (4, 5, 0), (-4, 5, 0)]]
    v, t = triangles_from_quads(np.array(floor, float), up)
    mesh_object(scene, "Floor", v, t, grey)
    back = [[(-4, 5, 0), (4, 5, 0), (4, 5, 4), (-4, 5, 4)]]
    v, t = triangles_from_quads(np.array(back, float), lambda c, n: n[1] < 0)
    mesh_object(scene, "BackWall", v, t, grey)
    left = [[(-4, -3, 0), (-4, 5, 0), (-4, 5, 4), (-4, -3, 4)]]
    v, t = triangles_from_quads(np.array(left, float), lambda c, n: n[0] > 0)
    mesh_object(scene, "LeftWall", v, t, grey)

    def box(name, lo, hi, mat):
        (x0, y0, z0), (x1, y1, z1) = lo, hi
        c = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
             (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
        idx = [(0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
        quads = np.array([[c[i] for i in q] for q in idx], float)
        centre = quads.reshape(-1, 3).mean(axis=0)
        v, t = triangles_from_quads(quads, lambda cc, n: np.dot(cc - centre, n) > 0)
        return mesh_object(scene, name, v, t, mat)

    box("Box", (-0.6, 0.4, 0.0), (0.6, 1.6, 1.2), orange)
    box("Pillar", (1.8, 2.6, 0.0), (2.4, 3.2, 2.2), grey)

    light_object(scene, "Point", "POINT", (-2.0, -1.0, 0.8), energy=40.0,
                 color=(1.0, 0.85, 0.6), shadow_soft_size=0.1)
    light_object(scene, "Spot", "SPOT", (2.6, 0.0, 3.0), target=(2.8, 0.6, 0.0), energy=500.0,
                 color=(0.6, 0.8, 1.0), shadow_soft_size=0.05,
                 spot_size=math.radians(45.0), spot_blend=0.3)
    sun = light_object(scene, "Sun", "SUN", (0.0, 0.0, 6.0), energy=2.0,
                       angle=math.radians(5.0))
    # from the front right, 50 deg above the horizon: shadows fall back and to the left
    sun.rotation_euler = look_at_euler((3.0, -3.0, 5.0), (0.0, 0.0, 0.0))
    light_object(scene, "AreaSquare", "AREA", (-3.9, 2.6, 1.2), target=(0.0, 2.6, 0.6),
                 energy=150.0, shape="SQUARE", size=1.0)
    disk = light_object(scene, "AreaDisk", "AREA", (0.9, 4.3, 3.0), target=(0.6, 2.4, 0.0),
                        energy=150.0, shape="DISK", size=0.6, color=(1.0, 0.9, 0.8))
    # Lights are hidden from camera rays by default in Blender 5.0 (Object.visible_camera
    # False). Deliberately show this one, so the scene also tests a directly seen area light
    # (radiance P/(pi A), one-sided); the other lights keep the default.
    disk.visible_camera = True

    loc = (0.6, -7.5, 3.6)
    camera_object(scene, "Camera", loc, look_at_euler(loc, (0.0, 1.4, 0.9)), 30.0, 36.0)
    return scene


SCENES = {"cornell_box": build_cornell_box, "lights": build_lights}


def glossy_material(name, color, roughness):
    """Glossy BSDF, GGX (single scattering), F = colour as in Cycles."""
    mat = bpy.data.materials.new(name)
    nt, out = _clear_nodes(mat)
    g = nt.nodes.new("ShaderNodeBsdfGlossy")
    g.distribution = "GGX"
    g.inputs["Color"].default_value = (*color, 1.0)
    g.inputs["Roughness"].default_value = roughness
    nt.links.new(g.outputs["BSDF"], out.inputs["Surface"])
    return mat


def scene_arguments(doc, scenes):
    """The scene builders' command line: --out DIR, --only NAME (repeatable)."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--out", default=HERE, help="output folder (default: scenes/)")
    ap.add_argument("--only", choices=sorted(scenes), action="append",
                    help="build only this scene (repeatable)")
    return ap


def script_argv(argv=None):
    """Arguments after `--` under `blender -b -P script --`, else the script's own."""
    if argv is not None:
        return argv
    return sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]


def save_scenes(scenes, args):
    """Build each scene of `scenes` (name -> function) chosen by args.only and save it."""
    os.makedirs(args.out, exist_ok=True)
    for name in args.only or scenes:
        scenes[name]()
        path = os.path.join(os.path.abspath(args.out), name + ".blend")
        bpy.ops.wm.save_as_mainfile(filepath=path, compress=True, copy=False)
        print(f"wrote {path} ({os.path.getsize(path)} bytes)")


def main(argv=None):
    save_scenes(SCENES, scene_arguments(__doc__, SCENES).parse_args(script_argv(argv)))


if __name__ == "__main__":
    main()
