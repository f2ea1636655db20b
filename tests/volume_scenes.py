"""Small bpy scenes with homogeneous media, shared by tests/test_volumes.py and
bench/volumes.py: a cube of Volume Scatter lit by a sun, a sphere of Volume Absorption (no
surface shader: a transparent boundary) in front of a bright background, the same sphere
under glass, the cube as an emitting Principled Volume with multiple scattering, and the
cube lit by an area light inside it."""
import math

import bpy


def _base(size: int, world_color):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    world = bpy.data.worlds.new("World")
    world.color = world_color
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*world_color, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    sc.world = world
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.angle = math.radians(40.0)
    cam.location = (0.0, -6.0, 1.0)
    cam.rotation_euler = (math.radians(82.0), 0.0, 0.0)
    sc.collection.objects.link(cam)
    sc.camera = cam
    sc.render.resolution_x = sc.render.resolution_y = size
    sc.render.resolution_percentage = 100
    sc.render.film_transparent = False
    sc.cycles.device = "CPU"
    sc.cycles.use_denoising = False
    sc.cycles.use_adaptive_sampling = False
    sc.cycles.volume_bounces = 0  # Cycles' default: single scattering (Ember's volume_bounces 1)
    sc.cycles.filter_width = 1.5
    return sc


def _volume_material(name: str, kind: str, **inputs):
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    node = nt.nodes.new(kind)
    for k, v in inputs.items():
        node.inputs[k].default_value = v
    nt.links.new(node.outputs[0], nt.nodes["Material Output"].inputs["Volume"])
    return mat


def scatter_cube(size: int = 24):
    """A 2 m cube of Volume Scatter (grey-blue, density 1.2, g 0.3) over a diffuse floor, lit
    by a sun from the side, black world."""
    sc = _base(size, (0.0, 0.0, 0.0))
    bpy.ops.mesh.primitive_cube_add(size=2.0, location=(0.0, 0.0, 1.3))  # off the floor: no coplanar faces
    cube = bpy.context.object
    cube.data.materials.append(_volume_material("fog", "ShaderNodeVolumeScatter", Color=(0.9, 0.8, 0.6, 1.0),
                                                Density=1.2, Anisotropy=0.3))
    bpy.ops.mesh.primitive_plane_add(size=12.0, location=(0.0, 0.0, 0.0))
    floor = bpy.context.object
    mat = bpy.data.materials.new("floor")
    mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.5, 0.5, 0.5, 1.0)
    mat.node_tree.nodes["Principled BSDF"].inputs["Specular IOR Level"].default_value = 0.0
    floor.data.materials.append(mat)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy, sun.data.angle = 3.0, 0.0
    sun.rotation_euler = (math.radians(50.0), 0.0, math.radians(30.0))
    sc.collection.objects.link(sun)
    return sc


def absorbing_sphere(size: int = 24):
    """A unit sphere of Volume Absorption (density 1.5, colour (0.2, 0.5, 0.8)) in front of a
    uniform bright background."""
    sc = _base(size, (2.0, 2.0, 2.0))
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, location=(0.0, 0.0, 1.0), segments=48, ring_count=24)
    sphere = bpy.context.object
    bpy.ops.object.shade_smooth()
    sphere.data.materials.append(_volume_material("ink", "ShaderNodeVolumeAbsorption", Color=(0.2, 0.5, 0.8, 1.0),
                                                  Density=1.5))
    return sc


def glass_of_ink(size: int = 24):
    """absorbing_sphere with a smooth Glass BSDF (IOR 1.33) as its surface: the medium behind
    a refracting boundary."""
    sc = absorbing_sphere(size)
    nt = bpy.data.materials["ink"].node_tree
    glass = nt.nodes.new("ShaderNodeBsdfGlass")
    glass.inputs["IOR"].default_value, glass.inputs["Roughness"].default_value = 1.33, 0.0
    nt.links.new(glass.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return sc


def principled_fog(size: int = 24):
    """scatter_cube with a Principled Volume (absorption colour, backward anisotropy,
    emission) and four volume bounces (Cycles' 3)."""
    sc = scatter_cube(size)
    nt = bpy.data.materials["fog"].node_tree
    node = nt.nodes.new("ShaderNodeVolumePrincipled")
    for k, v in (("Color", (0.7, 0.5, 0.3, 1.0)), ("Density", 0.8), ("Absorption Color", (0.2, 0.4, 0.8, 1.0)),
                 ("Anisotropy", -0.3), ("Emission Strength", 0.2), ("Emission Color", (1.0, 0.5, 0.2, 1.0))):
        node.inputs[k].default_value = v
    nt.links.new(node.outputs[0], nt.nodes["Material Output"].inputs["Volume"])
    sc.cycles.volume_bounces, sc.ember.volume_bounces = 3, 4
    return sc


def area_light_in_fog(size: int = 24, visible: bool = True):
    """scatter_cube lit by an area light inside the cube instead of the sun, facing the
    camera (seen through the fog where `visible`): light samples and phase samples that both
    reach it, across the cube's boundary."""
    sc = scatter_cube(size)
    bpy.data.objects.remove(bpy.data.objects["Sun"])
    area = bpy.data.objects.new("Area", bpy.data.lights.new("Area", "AREA"))
    area.data.energy, area.data.size = 30.0, 0.6
    area.location, area.rotation_euler = (0.2, 0.0, 1.3), (math.radians(-80.0), 0.0, 0.0)  # facing the camera
    area.visible_camera = visible
    sc.collection.objects.link(area)
    return sc


SCENES = {"scatter_cube": scatter_cube, "absorbing_sphere": absorbing_sphere, "glass_of_ink": glass_of_ink,
          "principled_fog": principled_fog, "area_light_in_fog": area_light_in_fog,
          "hidden_area_light_in_fog": lambda size=24: area_light_in_fog(size, visible=False)}
