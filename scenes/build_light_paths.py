"""Build the light-path and lens test scenes and, with --references, their Cycles
references (tests/data/NAME_cycles.exr, 32x32, via scenes/reference.py --keep-light-paths).

    python scenes/build_light_paths.py [--references] [--only NAME]

Each scene is one of the material or Cornell scenes with one control changed, set alike for
Cycles (scene.cycles) and Ember (scene.ember). Ember counts interactions: its Max Bounces and
diffuse, glossy and transmission limits are Cycles' values + 1 (transparent ones are equal).

  lp_diffuse        cornell_box, max bounces 8, diffuse bounces 1 (Cycles' numbers)
  lp_glossy         cornell_glossy, glossy bounces 0: mirror seen, not what it reflects twice
  lp_transmission   glass_sphere, transmission bounces 1: the ray leaving the sphere sees
                    emitters only
  lp_caustics       glass_sphere, reflective and refractive caustics off
  dof_round         textured_plane with depth of field: f/0.05 on 40 mm, focus 4 m
  dof_blades        the same with 5 blades turned 20 degrees and an anamorphic ratio of 2
  vis_camera        cornell_box, the tall block hidden from camera rays
  vis_diffuse       cornell_box, the tall block hidden from diffuse rays
  vis_shadow        cornell_box, both blocks cast no shadow
  vis_holdout       cornell_box, the short block a holdout
  vis_meshlight     cornell_box, the ceiling light hidden from diffuse rays
  vis_glossy        cornell_glossy, the red wall hidden from glossy rays
  vis_transmission  glass_sphere, the floor hidden from transmission rays
  vis_lights        lights, the point light and the sun hidden from diffuse rays
  vis_world         hdri, the world hidden from glossy rays (hidden from diffuse rays, the
                    ground is lit by glossy caustics alone: too spiky for a z-test)
"""
from __future__ import annotations

import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import build as base  # noqa: E402  (sets BLENDER_USER_RESOURCES, imports bpy)
import build_materials  # noqa: E402

bpy = base.bpy
ALL = 64  # every limit not under test (as scenes/reference.py sets them)
DOF = dict(aperture_fstop=0.05, focus_distance=4.0)

# name -> (base scene, Cycles light-path settings, camera dof settings, object name -> properties
# ("World": its cycles_visibility)). Scenes whose images are mostly black use the box filter:
# Cycles' tabulated Blackman-Harris has tails Ember's exact filter does not (a few 1e-4 of a
# bright neighbour, invisible next to lit surfaces, a z-test failure next to black ones).
VARIANTS = {
    "lp_diffuse": ("cornell_box", dict(max_bounces=8, diffuse_bounces=1), None, {}),
    "lp_glossy": ("cornell_glossy", dict(glossy_bounces=0), None, {}),
    "lp_transmission": ("glass_sphere", dict(transmission_bounces=1), None, {}),
    "lp_caustics": ("glass_sphere", dict(caustics_reflective=False, caustics_refractive=False), None, {}),
    "dof_round": ("textured_plane", {}, DOF, {}),
    "dof_blades": ("textured_plane", {}, dict(DOF, aperture_blades=5, aperture_rotation=math.radians(20.0),
                                              aperture_ratio=2.0), {}),
    "vis_camera": ("cornell_box", {}, None, {"TallBlock": dict(visible_camera=False)}),
    "vis_diffuse": ("cornell_box", {}, None, {"TallBlock": dict(visible_diffuse=False)}),
    "vis_shadow": ("cornell_box", {}, None, {"TallBlock": dict(visible_shadow=False),
                                             "ShortBlock": dict(visible_shadow=False)}),
    "vis_holdout": ("cornell_box", {}, None, {"ShortBlock": dict(is_holdout=True)}),
    "vis_meshlight": ("cornell_box", dict(pixel_filter_type="BOX"), None, {"Light": dict(visible_diffuse=False)}),
    "vis_glossy": ("cornell_glossy", {}, None, {"LeftWall": dict(visible_glossy=False)}),
    "vis_transmission": ("glass_sphere", {}, None, {"Floor": dict(visible_transmission=False)}),
    "vis_lights": ("lights", dict(pixel_filter_type="BOX"), None,
                   {"Point": dict(visible_diffuse=False), "Sun": dict(visible_diffuse=False)}),
    "vis_world": ("hdri", dict(pixel_filter_type="BOX"), None, {"World": dict(glossy=False)}),
}
_CYCLES_COUNTED = ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces")


def light_paths(scene, cycles_values: dict) -> None:
    """Set Cycles' light paths (every bounce limit ALL unless given) and Ember's alike."""
    c = scene.cycles
    values = dict({k: ALL for k in _CYCLES_COUNTED}, transparent_max_bounces=ALL, caustics_reflective=True,
                  caustics_refractive=True, sample_clamp_direct=0.0, sample_clamp_indirect=0.0)
    values.update(cycles_values)
    c.pixel_filter_type = values.pop("pixel_filter_type", c.pixel_filter_type)
    for key, value in values.items():
        setattr(c, key, value)
    c.volume_bounces = ALL
    ember = {k.replace("max_bounces", "max_depth"): values[k] + 1 for k in _CYCLES_COUNTED}
    ember.update(transparent_bounces=values["transparent_max_bounces"],
                 caustics_reflective=values["caustics_reflective"],
                 caustics_refractive=values["caustics_refractive"],
                 clamp_direct=values["sample_clamp_direct"], clamp_indirect=values["sample_clamp_indirect"])
    build_materials.ember_settings(scene, **ember)


def build(name: str) -> str:
    source, cycles_values, dof, objects = VARIANTS[name]
    bpy.ops.wm.open_mainfile(filepath=os.path.join(HERE, source + ".blend"))
    scene = bpy.context.scene
    light_paths(scene, cycles_values)
    if dof:
        cam = scene.camera.data
        cam.dof.use_dof = True
        for key, value in dof.items():
            setattr(cam.dof, key, value)
    for ob_name, props in objects.items():
        target = scene.world.cycles_visibility if ob_name == "World" else scene.objects[ob_name]
        for key, value in props.items():
            setattr(target, key, value)
    path = os.path.join(HERE, name + ".blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, compress=True, copy=False)
    print(f"wrote {path} ({os.path.getsize(path)} bytes)")
    return path


def main(argv=None):
    ap = base.scene_arguments(__doc__, VARIANTS)
    ap.add_argument("--references", action="store_true", help="render the Cycles references too")
    ap.add_argument("--runs", type=int, default=16)
    ap.add_argument("--samples", type=int, default=1024)
    args = ap.parse_args(base.script_argv(argv))
    import reference
    for name in args.only or VARIANTS:
        path = build(name)
        if args.references:
            out = os.path.join(ROOT, "tests", "data", f"{name}_cycles.exr")
            reference.main([path, "--out", out, "--resolution", "32x32", "--runs", str(args.runs),
                            "--samples", str(args.samples), "--keep-light-paths"])


if __name__ == "__main__":
    main()
