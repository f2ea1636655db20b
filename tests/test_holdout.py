"""Holdout (Cycles' integrate_surface_holdout): a Holdout shader's weight (mixed with other
shaders) is taken from camera rays' alpha, film transparent or not, and its share renders
black; a Holdout object is a hole. Without Blender: the material table carries the weight
and the film's alpha loses it. With Blender: colour and alpha per region against Cycles."""
import numpy as np
import pytest

from ember.engine.nodes.graph import Graph, Input, Link, Node
from ember.engine.nodes.material import compile_material
from ember.engine.scene import Lights, MAT_NODES, Materials, Scene, World
from ember.engine.session import RenderSession

from core_scenes import perspective, quads_mesh, settings


def _mix_holdout(fac: float) -> Graph:
    """Mix Shader (Fac = fac) of a Holdout (first) and a white Diffuse BSDF (second)."""
    holdout = Node("ShaderNodeHoldout", "Holdout", (), (), (("Holdout", "shader"),))
    diffuse = Node("ShaderNodeBsdfDiffuse", "Diffuse", (), (Input("Color", "rgba", (1.0, 1.0, 1.0, 1.0)),
                                                             Input("Roughness", "value", 0.0)), (("BSDF", "shader"),))
    mix = Node("ShaderNodeMixShader", "Mix", (), (Input("Fac", "value", fac),
                                                  Input("Shader", "shader", 0.0, Link(0, "Holdout", "shader")),
                                                  Input("Shader_001", "shader", 0.0, Link(1, "BSDF", "shader"))),
               (("Shader", "shader"),))
    return Graph((holdout, diffuse, mix), (("surface", Input("Surface", "shader", 0.0, Link(2, "Shader", "shader"))),))


def test_a_mixed_holdout_takes_its_weight_from_the_alpha_and_the_light():
    """Mix(Holdout, white Diffuse) at fac 0.3: holdout weight 0.7, the diffuse lobe 0.3; a wall
    filling the view under a white world renders 0.3 (its own albedo 0.3 of a furnace that
    it closes: L = 0.3 x 1) with alpha 0.3, on an opaque film too."""
    mp = compile_material(_mix_holdout(0.3))
    assert mp.holdout == pytest.approx(0.7)
    assert len(mp.lobes) == 1 and np.allclose(mp.lobes[0]["weight"], 0.3)
    mats = Materials.make([dict(kind=MAT_NODES, lobes=mp.lobes, holdout=mp.holdout)])
    wall = [[-50, 5, -50], [-50, 5, 50], [50, 5, 50], [50, 5, -50]]
    scene = Scene(quads_mesh([wall], [0]), mats, Lights.make([]), World(color=(1.0, 1.0, 1.0)),
                  perspective((0, 0, 0), (0, 1, 0), 30), settings(samples=4, max_depth=1))
    session = RenderSession(scene)
    session.run()
    rgba = session.film.image()
    np.testing.assert_allclose(rgba[..., 3], 0.3, atol=1e-6)
    assert abs(rgba[..., :3].mean() - 0.3) < 0.01


# ---- against Cycles -------------------------------------------------------------------------------

def holdout_scene(transparent: bool):
    """A floor, a sphere of Mix(Holdout, Diffuse) and a Holdout cube under an area light and a
    grey world."""
    import bpy
    from cycles_scenes import camera, diffuse_floor, new_scene, node_material
    sc = new_scene(32, world=(0.3, 0.3, 0.3))
    sc.render.film_transparent = transparent
    diffuse_floor()
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, location=(-0.8, 0, 1), segments=32, ring_count=16)
    mat, nt, out = node_material("Half")
    h, d, m = (nt.nodes.new(k) for k in ("ShaderNodeHoldout", "ShaderNodeBsdfDiffuse", "ShaderNodeMixShader"))
    m.inputs["Fac"].default_value = 0.35
    d.inputs["Color"].default_value = (0.9, 0.4, 0.2, 1)
    nt.links.new(h.outputs[0], m.inputs[1])
    nt.links.new(d.outputs[0], m.inputs[2])
    nt.links.new(m.outputs[0], out.inputs["Surface"])
    bpy.context.active_object.data.materials.append(mat)
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(1.2, 0.3, 0.5))
    bpy.context.active_object.is_holdout = True
    bpy.ops.object.light_add(type="AREA", location=(2, -2, 4), rotation=(0.5, 0.4, 0.6))
    bpy.context.active_object.data.energy, bpy.context.active_object.data.size = 500, 1.5
    camera(sc, (0, -5.5, 3.0), (1.1, 0, 0))
    return sc


@pytest.mark.blender
@pytest.mark.parametrize("transparent", [False, True])
def test_holdout_colour_and_alpha_as_cycles(transparent, tmp_path):
    from cycles_renders import agree, rgba_cycles, rgba_ember
    from cycles_scenes import addon
    with addon():
        sc = holdout_scene(transparent)
        cycles = [rgba_cycles(sc, 128, 100 + k, tmp_path / f"c{k}.exr") for k in range(4)]
        ember = [rgba_ember(sc, 48, k) for k in range(4)]
    agree([e[..., :3] for e in ember], [c[..., :3] for c in cycles], 4, 0.01)
    agree([e[..., 3:] for e in ember], [c[..., 3:] for c in cycles], 4, 0.01)
    holes = np.mean(cycles, axis=0)[..., 3] < 0.99
    assert holes.mean() > 0.05  # the holdouts cover part of the image
