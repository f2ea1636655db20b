"""Build the procedural-materials scene from bpy and NumPy, and save it as .blend.

    python scenes/build_procedural.py [--out DIR]

procedural.blend: a still life as an artist shades one with nodes only. Four objects on a
tiled floor under the Courtyard HDRI that ships with Blender (datafiles/studiolights/world,
CC0, Poly Haven), packed into the file:
- a marble sphere: distorted fBm noise through a sine into a vein ramp, a second noise for
  colour variation, bump from the veins;
- a rusted metal Suzanne: Voronoi cells and noise make a rust mask (ramps, Math), which
  mixes painted metal and rust colour, metallic and roughness; bump from rust and pits;
- a wooden cylinder: noise-distorted rings (Wave) and grain noise through ramps, bump;
- a stone cube: Voronoi crackle (F2 - F1) and noise through ramps, bump from both;
- the floor: Brick Texture tiles with dirt noise and a checker of two glazes, mortar bump.
Each material is 25-35 nodes, the last ten a wear layer (grime noises, ramp, hue/saturation, gamma) (Texture Coordinate, Mapping, Noise, Voronoi, Wave, Brick, Checker,
Color Ramp, Math, Mix, Map Range, Bump, Principled BSDF); every surface reads its varying inputs from nodes.
Render settings are Blender's defaults except the resolution and the camera.
Needs the bpy module or `blender -b -P scenes/build_procedural.py --`.
"""
from __future__ import annotations

import math
import os
import sys
import tempfile

os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))
import bpy  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import build  # noqa: E402  (scenes/build.py: shared helpers)

HDRI = "courtyard.exr"


class Nodes:
    """A material's node tree with short calls: add(kind, **inputs/props), link(a, b)."""

    def __init__(self, name):
        self.mat = bpy.data.materials.new(name)
        self.nt, self.out = build._clear_nodes(self.mat)
        self.count = 1

    def add(self, kind, props=None, **inputs):
        n = self.nt.nodes.new(kind)
        self.count += 1
        for k, v in (props or {}).items():
            setattr(n, k, v)
        for k, v in inputs.items():
            self.set(n, k, v)
        return n

    def set(self, n, name, value):
        socket = self._input(n, name)
        if isinstance(value, tuple) and not isinstance(value[0], (int, float)):
            self.link(value, socket)
        elif hasattr(value, "bl_idname") and hasattr(value, "outputs"):
            self.link(value.outputs[0], socket)
        elif hasattr(value, "is_output"):
            self.link(value, socket)
        else:
            if isinstance(value, tuple) and len(value) == 3 and socket.type == "RGBA":
                value = (*value, 1.0)
            socket.default_value = value

    @staticmethod
    def _input(n, name):
        for s in n.inputs:  # Mix: A_Color, B_Color, Factor_Float ... by identifier first
            if s.identifier == name and s.enabled:
                return s
        for s in n.inputs:
            if s.name == name and s.enabled:
                return s
        raise KeyError(f"{n.bl_idname} has no input {name}")

    def link(self, output, socket):
        if hasattr(output, "bl_idname") and hasattr(output, "outputs"):
            output = output.outputs[0]
        if isinstance(socket, tuple):
            socket = self._input(*socket)
        self.nt.links.new(output, socket)

    def ramp(self, fac, stops, interpolation="LINEAR"):
        r = self.add("ShaderNodeValToRGB")
        r.color_ramp.interpolation = interpolation
        els = r.color_ramp.elements
        while len(els) < len(stops):
            els.new(0.5)
        for e, (pos, color) in zip(els, stops):
            e.position = pos
            e.color = (*color, 1.0) if len(color) == 3 else color
        self.link(fac, (r, "Fac"))
        return r

    def mix(self, fac, a, b, blend="MIX", data_type="RGBA"):
        m = self.add("ShaderNodeMix", props=dict(data_type=data_type, blend_type=blend))
        suffix = {"RGBA": "Color", "FLOAT": "Float", "VECTOR": "Vector"}[data_type]
        self.set(m, "Factor_Float", fac)
        self.set(m, f"A_{suffix}", a)
        self.set(m, f"B_{suffix}", b)
        return m.outputs[f"Result_{suffix}"] if f"Result_{suffix}" in m.outputs else m.outputs[2]

    def math(self, op, a, b=0.5, c=0.0, clamp=False):
        m = self.add("ShaderNodeMath", props=dict(operation=op, use_clamp=clamp))
        for i, value in enumerate((a, b, c)):
            self._set_index(m, i, value)
        return m

    def _set_index(self, n, i, value):
        socket = n.inputs[i]
        if isinstance(value, (int, float)):
            socket.default_value = value
        else:
            self.link(value, socket)

    def coords(self, output="Object", scale=(1.0, 1.0, 1.0), rotation=(0.0, 0.0, 0.0), location=(0.0, 0.0, 0.0)):
        tc = self.add("ShaderNodeTexCoord")
        mp = self.add("ShaderNodeMapping", props=dict(vector_type="POINT"),
                      Location=location, Rotation=rotation, Scale=scale)
        self.link(tc.outputs[output], (mp, "Vector"))
        return mp

    def principled(self, **inputs):
        p = self.add("ShaderNodeBsdfPrincipled", **inputs)
        self.link(p.outputs["BSDF"], self.out.inputs["Surface"])
        return p


def noise(nt, vector, scale, detail=4.0, roughness=0.5, distortion=0.0, lacunarity=2.0, dims="3D", ntype="FBM"):
    return nt.add("ShaderNodeTexNoise", props=dict(noise_dimensions=dims, noise_type=ntype),
                  Vector=vector, Scale=scale, Detail=detail, Roughness=roughness, Distortion=distortion,
                  Lacunarity=lacunarity)


def voronoi(nt, vector, scale, feature="F1", randomness=1.0, distance="EUCLIDEAN"):
    return nt.add("ShaderNodeTexVoronoi", props=dict(feature=feature, distance=distance, voronoi_dimensions="3D"),
                  Vector=vector, Scale=scale, Randomness=randomness)


def bump(nt, height, strength, distance=0.02, normal=None):
    b = nt.add("ShaderNodeBump", Strength=strength, Distance=distance)
    nt.link(height, (b, "Height"))
    if normal is not None:
        nt.link(normal, (b, "Normal"))
    return b


def wear(nt, co, color, rough, scale=8.0):
    """The layer every material gets last: grime in the crevices of two noises, which darkens
    and desaturates the colour and roughens the surface. (colour, roughness) sockets."""
    coarse = noise(nt, co, scale, detail=4.0, roughness=0.55)
    fine = noise(nt, co, 3.0 * scale, detail=2.0)
    both = nt.math("MULTIPLY_ADD", fine.outputs["Fac"], 0.35, coarse.outputs["Fac"])
    grime = nt.ramp(both, [(0.55, (1, 1, 1)), (0.8, (0.45, 0.42, 0.4))])
    grime_v = nt.add("ShaderNodeRGBToBW", Color=grime.outputs["Color"])
    dirty = nt.mix(1.0, color, grime.outputs["Color"], blend="MULTIPLY")
    hsv = nt.add("ShaderNodeHueSaturation", Hue=0.5, Saturation=0.9, Value=1.0, Fac=1.0, Color=dirty)
    gamma = nt.add("ShaderNodeGamma", Color=hsv, Gamma=1.05)
    rough_add = nt.math("MULTIPLY_ADD", grime_v, -0.3, 0.3)
    rougher = nt.math("ADD", rough, rough_add, clamp=True)
    return gamma.outputs["Color"], rougher


def marble():
    nt = Nodes("Marble")
    co = nt.coords(scale=(1.6, 1.6, 1.6), rotation=(0.3, 0.0, 0.5))
    warp = noise(nt, co, 2.5, detail=6.0, roughness=0.55, distortion=0.4)
    warped = nt.mix(0.35, co.outputs[0], warp.outputs["Color"], data_type="VECTOR")
    sep = nt.add("ShaderNodeSeparateXYZ", Vector=warped)
    stripes = nt.math("MULTIPLY", sep.outputs["X"], 9.0)
    wobble = nt.math("MULTIPLY", warp.outputs["Fac"], 6.0)
    phase = nt.math("ADD", stripes, wobble)
    sine = nt.math("SINE", phase)
    veins = nt.math("ABSOLUTE", sine)
    sharp = nt.math("POWER", veins, 0.25)
    vein_col = nt.ramp(sharp, [(0.0, (0.08, 0.07, 0.06)), (0.35, (0.45, 0.42, 0.38)), (0.6, (0.85, 0.83, 0.8)),
                               (1.0, (0.93, 0.92, 0.9))])
    tint_noise = noise(nt, co, 1.2, detail=2.0)
    tint = nt.ramp(tint_noise.outputs["Fac"], [(0.3, (0.95, 0.9, 0.85)), (0.7, (0.85, 0.9, 0.95))])
    color = nt.mix(1.0, vein_col.outputs["Color"], tint.outputs["Color"], blend="MULTIPLY")
    rough = nt.add("ShaderNodeMapRange", props=dict(data_type="FLOAT"), Value=sharp, **{"To Min": 0.35, "To Max": 0.12})
    fine = noise(nt, co, 40.0, detail=2.0)
    height = nt.math("MULTIPLY_ADD", fine.outputs["Fac"], 0.15, sharp)
    bn = bump(nt, height, 0.15, distance=0.05)
    color, rough = wear(nt, co, color, rough.outputs["Result"], scale=3.0)
    nt.principled(**{"Base Color": color, "Roughness": rough, "Normal": bn.outputs["Normal"]})
    return nt


def rusty_metal():
    nt = Nodes("RustyMetal")
    co = nt.coords(scale=(2.0, 2.0, 2.0))
    cells = voronoi(nt, co, 4.0)
    cell_n = noise(nt, co, 6.0, detail=8.0, roughness=0.6, distortion=0.2)
    big = noise(nt, co, 1.5, detail=3.0)
    mask_in = nt.math("MULTIPLY_ADD", cells.outputs["Distance"], 0.6, cell_n.outputs["Fac"])
    mask_in2 = nt.math("ADD", mask_in, big.outputs["Fac"])
    mask_in3 = nt.math("MULTIPLY", mask_in2, 0.5)
    mask = nt.ramp(mask_in3, [(0.45, (0, 0, 0)), (0.62, (1, 1, 1))])
    mask_val = nt.add("ShaderNodeRGBToBW", Color=mask.outputs["Color"])
    rust_col = nt.ramp(cell_n.outputs["Fac"], [(0.3, (0.18, 0.05, 0.02)), (0.55, (0.45, 0.16, 0.05)),
                                               (0.8, (0.6, 0.3, 0.1))])
    paint = nt.add("ShaderNodeRGB")
    paint.outputs[0].default_value = (0.08, 0.25, 0.35, 1.0)
    paint_var = nt.mix(big.outputs["Fac"], paint, (0.05, 0.18, 0.28), blend="MIX")
    color = nt.mix(mask_val, paint_var, rust_col.outputs["Color"])
    metallic = nt.math("SUBTRACT", 1.0, mask_val, clamp=True)
    rough = nt.add("ShaderNodeMapRange", props=dict(data_type="FLOAT"), Value=mask_val,
                   **{"To Min": 0.25, "To Max": 0.85})
    pits = voronoi(nt, co, 25.0, feature="F1")
    pit_h = nt.math("POWER", pits.outputs["Distance"], 0.5)
    rust_h = nt.math("MULTIPLY", mask_val, cell_n.outputs["Fac"])
    height = nt.math("MULTIPLY_ADD", pit_h, 0.3, rust_h)
    bn = bump(nt, height, 0.35, distance=0.03)
    color, rough = wear(nt, co, color, rough.outputs["Result"], scale=5.0)
    nt.principled(**{"Base Color": color, "Metallic": metallic, "Roughness": rough,
                     "Normal": bn.outputs["Normal"]})
    return nt


def wood():
    nt = Nodes("Wood")
    co = nt.coords(scale=(0.6, 0.6, 3.0))
    warp = noise(nt, co, 1.2, detail=3.0, distortion=0.5)
    warped = nt.mix(0.08, co.outputs[0], warp.outputs["Color"], data_type="VECTOR")
    rings = nt.add("ShaderNodeTexWave", props=dict(wave_type="RINGS", rings_direction="Z", wave_profile="SAW"),
                   Vector=warped, Scale=3.0, Distortion=2.0, Detail=3.0)
    grain = noise(nt, co, 60.0, detail=2.0)
    grain_s = nt.math("MULTIPLY", grain.outputs["Fac"], 0.3)
    ring_g = nt.math("ADD", rings.outputs["Fac"], grain_s)
    col = nt.ramp(ring_g, [(0.1, (0.35, 0.17, 0.06)), (0.5, (0.55, 0.3, 0.12)), (0.9, (0.25, 0.11, 0.04))])
    dark = noise(nt, co, 3.0, detail=2.0)
    dark_r = nt.ramp(dark.outputs["Fac"], [(0.35, (0.7, 0.7, 0.7)), (0.65, (1.0, 1.0, 1.0))])
    color = nt.mix(1.0, col.outputs["Color"], dark_r.outputs["Color"], blend="MULTIPLY")
    rough = nt.add("ShaderNodeMapRange", props=dict(data_type="FLOAT"), Value=ring_g,
                   **{"From Min": 0.0, "From Max": 1.3, "To Min": 0.3, "To Max": 0.6})
    height = nt.math("MULTIPLY", ring_g, 0.5)
    bn = bump(nt, height, 0.2, distance=0.02)
    color, rough = wear(nt, co, color, rough.outputs["Result"], scale=4.0)
    nt.principled(**{"Base Color": color, "Roughness": rough, "Normal": bn.outputs["Normal"]})
    return nt


def stone():
    nt = Nodes("Stone")
    co = nt.coords(scale=(1.5, 1.5, 1.5))
    f1 = voronoi(nt, co, 5.0, feature="F1")
    f2 = voronoi(nt, co, 5.0, feature="F2")
    crack = nt.math("SUBTRACT", f2.outputs["Distance"], f1.outputs["Distance"])
    crack_m = nt.ramp(crack, [(0.0, (0, 0, 0)), (0.08, (1, 1, 1))])
    crack_v = nt.add("ShaderNodeRGBToBW", Color=crack_m.outputs["Color"])
    speck = noise(nt, co, 30.0, detail=5.0, roughness=0.65)
    base = nt.ramp(speck.outputs["Fac"], [(0.3, (0.32, 0.3, 0.28)), (0.5, (0.5, 0.48, 0.44)),
                                          (0.7, (0.62, 0.6, 0.55))])
    cell_tint = nt.mix(0.25, base.outputs["Color"], f1.outputs["Color"], blend="OVERLAY")
    color = nt.mix(crack_v, (0.08, 0.07, 0.06), cell_tint)
    rough = nt.math("MULTIPLY_ADD", speck.outputs["Fac"], 0.3, 0.55)
    h1 = nt.math("MULTIPLY", crack_v, 0.7)
    h2 = nt.math("MULTIPLY_ADD", speck.outputs["Fac"], 0.3, h1)
    bn = bump(nt, h2, 0.4, distance=0.03)
    color, rough = wear(nt, co, color, rough, scale=4.0)
    nt.principled(**{"Base Color": color, "Roughness": rough, "Normal": bn.outputs["Normal"]})
    return nt


def tiles():
    nt = Nodes("Tiles")
    co = nt.coords(scale=(1.0, 1.0, 1.0))
    brick = nt.add("ShaderNodeTexBrick", props=dict(offset=0.5, offset_frequency=2), Vector=co, Scale=1.5,
                   **{"Mortar Size": 0.015, "Mortar Smooth": 0.2, "Bias": 0.0, "Brick Width": 0.5,
                      "Row Height": 0.25, "Color1": (0.55, 0.5, 0.45), "Color2": (0.4, 0.36, 0.32),
                      "Mortar": (0.15, 0.14, 0.13)})
    checker = nt.add("ShaderNodeTexChecker", Vector=co, Scale=3.0, Color1=(1.0, 0.97, 0.92),
                     Color2=(0.85, 0.88, 0.9))
    glaze = nt.mix(1.0, brick.outputs["Color"], checker.outputs["Color"], blend="MULTIPLY")
    dirt = noise(nt, co, 3.0, detail=6.0, roughness=0.6)
    dirt_m = nt.ramp(dirt.outputs["Fac"], [(0.45, (1, 1, 1)), (0.7, (0.55, 0.5, 0.45))])
    color = nt.mix(1.0, glaze, dirt_m.outputs["Color"], blend="MULTIPLY")
    mortar = nt.math("SUBTRACT", 1.0, brick.outputs["Fac"])
    dirt_r = nt.math("MULTIPLY_ADD", dirt.outputs["Fac"], 0.4, 0.1)
    rough = nt.math("MAXIMUM", dirt_r, nt.math("MULTIPLY", brick.outputs["Fac"], 0.9))
    chip = voronoi(nt, co, 12.0)
    chip_h = nt.math("MULTIPLY", chip.outputs["Distance"], 0.1)
    height = nt.math("ADD", mortar, chip_h)
    bn = bump(nt, height, 0.5, distance=0.01)
    color, rough = wear(nt, co, color, rough, scale=2.0)
    nt.principled(**{"Base Color": color, "Roughness": rough, "Normal": bn.outputs["Normal"]})
    return nt


def build_procedural():
    scene = build.new_empty_file()
    build.set_output(scene, 256)
    world = bpy.data.worlds.new("World")
    scene.world = world
    wnt = world.node_tree
    bg = next(n for n in wnt.nodes if n.type == "BACKGROUND")
    env = wnt.nodes.new("ShaderNodeTexEnvironment")
    path = os.path.join(bpy.utils.system_resource("DATAFILES"), "studiolights", "world", HDRI)
    env.image = bpy.data.images.load(path)
    env.image.pack()
    wnt.links.new(env.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = 1.0

    mats = dict(marble=marble(), metal=rusty_metal(), wood=wood(), stone=stone(), tiles=tiles())
    for name, m in mats.items():
        print(f"{name}: {m.count} nodes")

    def place(ob, mat, location, rotation=(0.0, 0.0, 0.0), smooth=True):
        ob.location = location
        ob.rotation_euler = rotation
        ob.data.materials.clear()
        ob.data.materials.append(mat.mat)
        if smooth:
            for poly in ob.data.polygons:
                poly.use_smooth = True

    bpy.ops.mesh.primitive_plane_add(size=14.0)
    place(bpy.context.object, mats["tiles"], (0.0, 0.0, 0.0), smooth=False)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=0.7)
    place(bpy.context.object, mats["marble"], (-1.1, 0.4, 0.7))
    bpy.ops.mesh.primitive_monkey_add(size=1.3)
    monkey = bpy.context.object
    mod = monkey.modifiers.new("Subdivision", "SUBSURF")
    mod.levels = mod.render_levels = 2
    place(monkey, mats["metal"], (0.55, -0.2, 0.62), rotation=(math.radians(-20.0), 0.0, math.radians(25.0)))
    bpy.ops.mesh.primitive_cylinder_add(vertices=64, radius=0.45, depth=1.4)
    place(bpy.context.object, mats["wood"], (1.6, 1.2, 0.7))
    for poly in bpy.context.object.data.polygons:  # the caps stay flat
        poly.use_smooth = len(poly.vertices) == 4
    bpy.ops.mesh.primitive_cube_add(size=0.8)
    place(bpy.context.object, mats["stone"], (2.5, -0.7, 0.4), rotation=(0.0, 0.0, math.radians(30.0)), smooth=False)

    location = (0.8, -5.2, 2.3)
    build.camera_object(scene, "Camera", location, build.look_at_euler(location, (0.2, 0.5, 0.55)), 40.0, 36.0)


SCENES = {"procedural": build_procedural}


def main(argv=None):
    build.save_scenes(SCENES, build.scene_arguments(__doc__, SCENES).parse_args(build.script_argv(argv)))


if __name__ == "__main__":
    main()
