"""Build the benchmark's own scenes from nothing but bpy and NumPy, and save them as .blend.

    python scenes/build_bench.py [--out DIR] [--only NAME ...]

Scenes (bench/scenes.py lists them with the other scene scripts' files):
  interior              a closed diffuse room lit by a sun and a blue sky through one window
  caustic               a glass sphere on a diffuse floor under a small spherical emitter,
                        box pixel filter (so the Mitsuba 3 reference can match it)
  caustic_specular_only the same, but diffuse surfaces and the emitter are black to camera
                        rays: only paths whose first bounce is the glass remain (the part of
                        the caustic reference that Mitsuba's particle tracer cannot give)
  caustic_point         the caustic scene with the emitter replaced by a point light of radius
                        0 at its centre with the same power (a path tracer cannot find L S+ D
                        paths from it at all)
  caustic_point_specular_only  the same with the diffuse surfaces black to camera rays
  hard_tiny_light       Cornell box, light shrunk to 1 cm x 1 cm at the same power
  hard_light_near_wall  Cornell box lit by a 0.6 m area light facing down whose edge is 5 mm
                        from the back wall: a near-singular bright stripe on the wall
  hard_degenerate       Cornell box plus zero-area triangles (one of them emissive), a
                        sliver, and a panel duplicated in place (same material)
  hard_degenerate_clean the same without the zero-area and duplicated triangles: the
                        reference (the right image is the same, a renderer must not change it)
  hard_phong            Cornell box with a near-mirror floor: Beckmann alpha 0.01, the lobe of
                        Phong exponent 19998 (alpha = sqrt(2 / (n + 2)), Walter et al. 2007)
  hard_far_origin       Cornell box moved to (1e4, 1e4, 1e4) m, light 1 cm below the ceiling
                        (Blender stores float32 vertices: 1 mm steps out there)
  hard_grazing          camera 25 cm above a 40 m checkerboard floor looking almost along it

Materials are Blender's own nodes, so Cycles renders the intended scene: Glass BSDF
(caustic), Glossy BSDF Beckmann (hard_phong; Ember renders it as its Phong lobe when
scene.ember.glossy_as_phong is on, which the file sets, and as GGX otherwise). Light Path
'Is Camera Ray' (caustic_specular_only) is only for the Cycles part of the caustic reference.
"""
from __future__ import annotations

import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import build  # noqa: E402  (sets BLENDER_USER_RESOURCES before importing bpy)
from build import (camera_object, diffuse_material, emission_material, light_object,  # noqa: E402
                   look_at_euler, mesh_object, new_empty_file, set_output, triangles_from_quads)

import bpy  # noqa: E402
import bmesh  # noqa: E402

SKY = (0.35, 0.5, 0.8)  # constant sky radiance, W/(m^2 sr)


def sky_world(scene, color=SKY, strength=1.0):
    world = build.black_world(scene)
    bg = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    bg.inputs["Color"].default_value = (*color, 1.0)
    bg.inputs["Strength"].default_value = strength
    return world


def box_object(scene, name, lo, hi, mat, inward=False):
    """Axis-aligned closed box, faces outward (inward for a room)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    c = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
         (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    idx = [(0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    quads = np.array([[c[i] for i in q] for q in idx], float)
    centre = quads.reshape(-1, 3).mean(axis=0)
    sign = -1.0 if inward else 1.0
    v, t = triangles_from_quads(quads, lambda cc, n: sign * np.dot(cc - centre, n) > 0)
    return mesh_object(scene, name, v, t, mat)


def icosphere_object(scene, name, centre, radius, subdivisions, mat):
    """Flat-shaded icosphere: the same facets in every renderer (no normal interpolation)."""
    bm = bmesh.new()
    bmesh.ops.create_icosphere(bm, subdivisions=subdivisions, radius=radius)
    v = np.array([tuple(x.co) for x in bm.verts]) + np.asarray(centre, float)
    faces = [tuple(x.index for x in f.verts) for f in bm.faces]
    bm.free()
    return mesh_object(scene, name, v, faces, mat)


def replace_object(name):
    ob = bpy.data.objects[name]
    me = ob.data
    bpy.data.objects.remove(ob)
    bpy.data.meshes.remove(me)


# ------------------------------------------------------------------------------------------
def build_interior():
    """6 x 5 x 3 m room, window 1.6 x 1.4 m in the left wall; sun (15 W/m^2, 1 deg) and sky
    outside. Most of the room sees only light that bounced off the sunlit floor patch."""
    scene = new_empty_file()
    scene.name = "Interior"
    set_output(scene, 256)
    sky_world(scene)
    wall = diffuse_material("Wall", (0.75, 0.72, 0.68))
    floor = diffuse_material("Floor", (0.45, 0.3, 0.18))
    ceiling = diffuse_material("Ceiling", (0.8, 0.8, 0.8))
    sofa = diffuse_material("Sofa", (0.15, 0.3, 0.55))
    table = diffuse_material("Table", (0.6, 0.45, 0.3))
    X, Y, H = 3.0, 2.5, 3.0
    wy0, wy1, wz0, wz1 = -0.8, 0.8, 0.9, 2.3  # window in the x = -X wall

    def inward(c, n):
        return np.dot(-c * np.array([1, 1, 0]) + np.array([0, 0, H / 2 - c[2]]), n) > 0

    quads = {
        "Floor": (floor, [[(-X, -Y, 0), (X, -Y, 0), (X, Y, 0), (-X, Y, 0)]]),
        "Ceiling": (ceiling, [[(-X, -Y, H), (X, -Y, H), (X, Y, H), (-X, Y, H)]]),
        "Walls": (wall, [
            [(X, -Y, 0), (X, Y, 0), (X, Y, H), (X, -Y, H)],
            [(-X, Y, 0), (X, Y, 0), (X, Y, H), (-X, Y, H)],
            [(-X, -Y, 0), (X, -Y, 0), (X, -Y, H), (-X, -Y, H)],
            # window wall: four quads around the opening
            [(-X, -Y, 0), (-X, Y, 0), (-X, Y, wz0), (-X, -Y, wz0)],
            [(-X, -Y, wz1), (-X, Y, wz1), (-X, Y, H), (-X, -Y, H)],
            [(-X, -Y, wz0), (-X, wy0, wz0), (-X, wy0, wz1), (-X, -Y, wz1)],
            [(-X, wy1, wz0), (-X, Y, wz0), (-X, Y, wz1), (-X, wy1, wz1)],
        ]),
    }
    for name, (mat, qs) in quads.items():
        v, t = triangles_from_quads(np.array(qs, float), inward)
        mesh_object(scene, name, v, t, mat)
    box_object(scene, "Sofa", (-0.5, 1.5, 0.0), (1.8, 2.4, 0.8), sofa)
    box_object(scene, "Table", (-0.6, -0.5, 0.0), (0.6, 0.5, 0.7), table)
    box_object(scene, "Cabinet", (2.3, -1.5, 0.0), (2.9, 0.5, 1.8), wall)
    sun = light_object(scene, "Sun", "SUN", (-6.0, 0.0, 5.0), energy=15.0, angle=math.radians(1.0))
    sun.rotation_euler = look_at_euler((-4.0, -1.0, 2.8), (0.0, 0.0, 0.0))  # through the window
    loc = (2.7, -2.2, 1.6)
    camera_object(scene, "Camera", loc, look_at_euler(loc, (-1.5, 0.8, 1.0)), 20.0, 36.0)
    return scene


CAUSTIC_LIGHT = dict(centre=(0.9, 0.7, 1.7), radius=0.03, radiance=(4000.0, 3800.0, 3400.0))


def icosphere_area(radius, subdivisions):
    """Surface area of bmesh's icosphere (the emitter's facets, not the true sphere's)."""
    bm = bmesh.new()
    bmesh.ops.create_icosphere(bm, subdivisions=subdivisions, radius=radius)
    area = sum(f.calc_area() for f in bm.faces)
    bm.free()
    return area


def caustic_point_light():
    """(colour, Blender power W) of the point light that replaces the caustic scene's emitter.

    The icosphere (area A, radiance L, one-sided Lambertian outward) emits P = pi A L per
    channel; a convex Lambertian emitter's intensity averaged over directions is P / (4 pi)
    (its mean projected area is A / 4). Cycles gives a radius-0 point light of power P the
    intensity I = P / (4 pi) W/sr (blender.md, light.cpp), so power = pi A L gives the same
    power and the same mean intensity: 131.94 W for the red channel (colour (1, 0.95, 0.85)),
    I = 10.50 W/sr. 4 pi^2 r^2 L = 142.12 W is the true sphere's; the 80 facets of the
    subdivision-2 icosphere have 0.928 of its area, and the emissive scene emits pi A L."""
    L = np.asarray(CAUSTIC_LIGHT["radiance"], float)
    area = icosphere_area(CAUSTIC_LIGHT["radius"], CAUSTIC_LIGHT_SUBDIVISIONS)
    power = math.pi * area * L.max()
    return tuple(L / L.max()), power


CAUSTIC_LIGHT_SUBDIVISIONS = 2


def build_caustic(specular_only: bool = False, point: bool = False):
    """Glass sphere (r 0.5, IOR 1.5, 5120 flat facets) on a 4 x 4 m floor with a back wall;
    one emissive icosphere of radius 3 cm (point=True: a radius-0 point light of the same
    power at its centre); black world; box filter 1 px."""
    scene = new_empty_file()
    scene.name = ("CausticPoint" if point else "Caustic") + ("SpecularOnly" if specular_only else "")
    set_output(scene, 256)
    build.black_world(scene)
    scene.cycles.pixel_filter_type = "BOX"
    scene.cycles.filter_width = 1.0
    grey = diffuse_material("Grey", (0.8, 0.8, 0.8))
    glass = bpy.data.materials.new("Glass")
    nt, out = build._clear_nodes(glass)
    g = nt.nodes.new("ShaderNodeBsdfGlass")
    g.distribution = "GGX"
    g.inputs["Roughness"].default_value = 0.0
    g.inputs["IOR"].default_value = 1.5
    g.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    nt.links.new(g.outputs["BSDF"], out.inputs["Surface"])
    light = emission_material("Emitter", CAUSTIC_LIGHT["radiance"], 1.0)
    if specular_only:
        for mat in (grey, light):
            camera_black(mat)

    floor = [[(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)]]
    v, t = triangles_from_quads(np.array(floor, float), lambda c, n: n[2] > 0)
    mesh_object(scene, "Floor", v, t, grey)
    back = [[(-2, 2, 0), (2, 2, 0), (2, 2, 2.5), (-2, 2, 2.5)]]
    v, t = triangles_from_quads(np.array(back, float), lambda c, n: n[1] < 0)
    mesh_object(scene, "BackWall", v, t, grey)
    icosphere_object(scene, "GlassSphere", (0.0, 0.0, 0.501), 0.5, 4, glass)
    if point:
        colour, power = caustic_point_light()
        lamp = light_object(scene, "PointLight", "POINT", CAUSTIC_LIGHT["centre"], color=colour,
                            energy=power, shadow_soft_size=0.0)
        if hasattr(lamp.data, "use_soft_falloff"):
            lamp.data.use_soft_falloff = False  # no effect at radius 0; stated anyway
    else:
        icosphere_object(scene, "Emitter", CAUSTIC_LIGHT["centre"], CAUSTIC_LIGHT["radius"],
                         CAUSTIC_LIGHT_SUBDIVISIONS, light)
    loc = (0.0, -3.2, 2.2)
    camera_object(scene, "Camera", loc, look_at_euler(loc, (-0.2, 0.1, 0.3)), 40.0, 36.0)
    return scene


def camera_black(mat):
    """Make `mat` black and opaque to camera rays (Light Path 'Is Camera Ray' -> a black
    surface), unchanged for every other ray."""
    nt = mat.node_tree
    out = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    shader = out.inputs["Surface"].links[0].from_socket
    mix = nt.nodes.new("ShaderNodeMixShader")
    path = nt.nodes.new("ShaderNodeLightPath")
    black = nt.nodes.new("ShaderNodeEmission")
    black.inputs["Strength"].default_value = 0.0
    nt.links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
    nt.links.new(shader, mix.inputs[1])
    nt.links.new(black.outputs["Emission"], mix.inputs[2])
    nt.links.new(mix.outputs["Shader"], out.inputs["Surface"])


# ------------------------------------------------------------------------------------------
# Hard cases on the Cornell box (scenes/build.py): one difficulty each.
# ------------------------------------------------------------------------------------------
def _cornell_light_quad(scale_about_centre=1.0, drop=0.0):
    q = np.array(build.CORNELL_LIGHT, float)
    c = q.mean(axis=0)
    q = c + (q - c) * scale_about_centre
    q[:, 1] -= drop
    return q


def _set_cornell_light(scene, quad, radiance):
    replace_object("Light")
    mat = emission_material("Light", tuple(radiance), 1.0)
    v, t = triangles_from_quads(build.cornell_to_blender(np.array([quad])), lambda c, n: n[2] < 0)
    mesh_object(scene, "Light", v, t, mat)


def build_hard_tiny_light():
    scene = build.build_cornell_box()
    scene.name = "HardTinyLight"
    full = _cornell_light_quad()
    side = 1.0  # Cornell units (1 cm)
    scale = side / np.linalg.norm(full[0] - full[3])
    quad = _cornell_light_quad(scale_about_centre=scale)
    area_ratio = (130.0 * 105.0) / (np.linalg.norm(quad[0] - quad[3]) * np.linalg.norm(quad[0] - quad[1]))
    _set_cornell_light(scene, quad, np.array(build.CORNELL_LIGHT_RADIANCE) * area_ratio)
    return scene


def build_hard_light_near_wall():
    """The ceiling light replaced by a 0.6 m square Area light facing down at mid height,
    its back edge 5 mm from the back wall. The wall just below that edge gets irradiance
    growing like 1/(2h) down to h ~ 5 mm: a bright stripe that defeats area sampling."""
    scene = build.build_cornell_box()
    scene.name = "HardLightNearWall"
    replace_object("Light")
    back_y = build.CORNELL_QUADS["BackWall"][1][0][0][2] * build.CORNELL_SCALE  # Blender Y of the wall
    size = 0.6
    # Area lights are one-sided and, in Blender 5, hidden from the camera by default.
    # L = P / (pi A) = 80 / (pi 0.36) ~ 71 W/(m^2 sr).
    light_object(scene, "WallLight", "AREA", (-2.78, back_y - 0.005 - size / 2, 3.5),
                 energy=80.0, shape="SQUARE", size=size, color=(1.0, 0.85, 0.7))
    return scene


def build_hard_degenerate(clean: bool = False):
    scene = build.build_cornell_box()
    scene.name = "HardDegenerateClean" if clean else "HardDegenerate"
    yellow = diffuse_material("Panel", (0.8, 0.7, 0.2))
    # A panel in front of the tall block, tilted 45 degrees to face the camera and the light,
    # as a fan of two real triangles and a 1 mm sliver (kept in both versions).
    x0, x1, z0, z1, y0, y1 = -4.2, -3.4, 0.6, 1.5, 0.3, 1.2
    verts = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z1), (x0, y1, z1), (x0 + 1e-3, y1, z1)]
    faces = [(0, 1, 2), (0, 2, 4), (0, 4, 3)]  # (0, 4, 3) is a 1 mm wide sliver
    degenerate = []
    if not clean:
        verts += [(x0, 0.5 * (y0 + y1), 0.5 * (z0 + z1)), (x0, y0 + 0.2, z0 + 0.2)]  # on the left edge
        degenerate = [(0, 5, 6),  # collinear: zero area
                      (1, 1, 2)]  # repeated vertex: zero area (validate() would remove it)
    me = bpy.data.meshes.new("Panel")
    me.from_pydata(verts, [], faces + degenerate)  # no validate(): keep what it would drop
    me.update()
    me.materials.append(yellow)
    ob = bpy.data.objects.new("Panel", me)
    scene.collection.objects.link(ob)
    if not clean:
        twin = bpy.data.objects.new("PanelTwin", me.copy())  # the same triangles in place
        scene.collection.objects.link(twin)
        hot = emission_material("ZeroAreaEmitter", (1e4, 1e4, 1e4), 1.0)
        me2 = bpy.data.meshes.new("ZeroAreaEmitter")
        me2.from_pydata([(-2.0, 3.0, 4.0), (-2.5, 3.0, 4.0), (-3.0, 3.0, 4.0)], [], [(0, 1, 2)])
        me2.update()
        me2.materials.append(hot)
        ob2 = bpy.data.objects.new("ZeroAreaEmitter", me2)
        scene.collection.objects.link(ob2)
    return scene


def build_hard_phong():
    scene = build.build_cornell_box()
    scene.name = "HardPhong"
    mirror = bpy.data.materials.new("NearMirror")
    nt, out = build._clear_nodes(mirror)
    g = nt.nodes.new("ShaderNodeBsdfGlossy")
    g.distribution = "BECKMANN"
    g.inputs["Roughness"].default_value = 0.1  # Blender roughness r: alpha = r^2 = 0.01
    g.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    nt.links.new(g.outputs["BSDF"], out.inputs["Surface"])
    floor = bpy.data.objects["Floor"]
    floor.data.materials[0] = mirror
    # Ember reads Glossy as its Phong lobe with scene.ember.glossy_as_phong (n = 2 / alpha^2 - 2
    # = 19998); stored as an ID property, it takes effect once the add-on defines the setting.
    scene["ember"] = {"glossy_as_phong": True}
    return scene


FAR_OFFSET = (1e4, 1e4, 1e4)


def build_hard_far_origin():
    scene = build.build_cornell_box()
    scene.name = "HardFarOrigin"
    _set_cornell_light(scene, _cornell_light_quad(drop=1.0), build.CORNELL_LIGHT_RADIANCE)
    for ob in scene.collection.objects:
        if ob.type == "MESH":
            co = np.zeros(len(ob.data.vertices) * 3, np.float64)
            ob.data.vertices.foreach_get("co", co)
            ob.data.vertices.foreach_set("co", (co.reshape(-1, 3) + FAR_OFFSET).ravel())
            ob.data.update()
        else:
            ob.location = tuple(np.array(ob.location) + FAR_OFFSET)
    return scene


def build_hard_grazing():
    """Camera 25 cm above a 40 x 40 m checkerboard of 1 m tiles, looking 4 degrees down (the
    floor at the image centre is seen at 4 degrees from grazing); sun 39 degrees up from the
    front right, sky; a box 12 m ahead."""
    scene = new_empty_file()
    scene.name = "HardGrazing"
    set_output(scene, 256)
    sky_world(scene, strength=0.5)
    light, dark = diffuse_material("Light", (0.8, 0.8, 0.8)), diffuse_material("Dark", (0.1, 0.1, 0.1))
    ij = np.stack(np.meshgrid(np.arange(-20, 20), np.arange(-5, 35), indexing="ij"), -1).reshape(-1, 2)
    for parity, mat in ((0, light), (1, dark)):
        cells = ij[(ij.sum(axis=1) % 2) == parity].astype(float)
        quads = np.stack([np.c_[cells[:, 0] + dx, cells[:, 1] + dy, np.zeros(len(cells))]
                          for dx, dy in ((0, 0), (1, 0), (1, 1), (0, 1))], axis=1)
        v, t = triangles_from_quads(quads, lambda c, n: n[2] > 0)
        mesh_object(scene, f"Floor{parity}", v, t, mat)
    box_object(scene, "Box", (-1.0, 12.0, 0.0), (1.0, 14.0, 2.0), diffuse_material("Red", (0.7, 0.1, 0.05)))
    sun = light_object(scene, "Sun", "SUN", (0, 0, 10), energy=3.0, angle=math.radians(1.0))
    sun.rotation_euler = look_at_euler((6.0, -6.0, 6.9), (0.0, 0.0, 0.0))
    loc = (0.3, -4.5, 0.25)
    camera_object(scene, "Camera", loc, (math.radians(86.0), 0.0, 0.0), 35.0, 36.0)
    return scene


SCENES = {
    "interior": build_interior,
    "caustic": build_caustic,
    "caustic_specular_only": lambda: build_caustic(specular_only=True),
    "caustic_point": lambda: build_caustic(point=True),
    "caustic_point_specular_only": lambda: build_caustic(specular_only=True, point=True),
    "hard_tiny_light": build_hard_tiny_light,
    "hard_light_near_wall": build_hard_light_near_wall,
    "hard_degenerate": build_hard_degenerate,
    "hard_degenerate_clean": lambda: build_hard_degenerate(clean=True),
    "hard_phong": build_hard_phong,
    "hard_far_origin": build_hard_far_origin,
    "hard_grazing": build_hard_grazing,
}


def main(argv=None):
    build.save_scenes(SCENES, build.scene_arguments(__doc__, SCENES).parse_args(build.script_argv(argv)))


if __name__ == "__main__":
    main()
