"""Ambient Occlusion and Bevel against Cycles' bakes (tests/node_bake.py bake_traced): a cube
(flat and smooth shaded) and a corner (a floor and a wall of one object), each texel the mean of
SAMPLES bake samples in Cycles and of as many evaluations in Ember, compared within their noise.

Per case the texels' differences are pooled in blocks of BLOCK x BLOCK texels (edges run
through some of them), each block's sum over the square root of its summed variance a z-score;
every block's must be under Z. Cycles' variance is taken to be Ember's, from Ember's spread
over its evaluations. A bevel's whole effect, how far its normal turns from N summed over the
cube (dot(bevel, N) per texel), is pooled over every texel: a test of little noise where a
block sees few edge texels. Both sides stratify the rays of one evaluation with the sample's others
(path_branched_rng), and their stratifications differ in detail: Z allows for that."""
import itertools

import numpy as np
import pytest

pytestmark = pytest.mark.blender

import bpy  # noqa: E402
import node_bake  # noqa: E402
from node_bake import Placed  # noqa: E402

SAMPLES = 128
SIZE = 24
BLOCK = 4
Z = 5.5
Z_POOLED = 4.0


def _uv_grid(mesh, cells):
    """UV map: face i fills cell cells[i] = (column, row, columns, rows) of the unit square."""
    uv = mesh.uv_layers.new(name="UVMap")
    for face, (i, j, nx, ny) in zip(mesh.polygons, cells):
        corners = ((0, 0), (1, 0), (1, 1), (0, 1))
        for loop, (a, b) in zip(face.loop_indices, corners):
            uv.data[loop].uv = ((i + a) / nx, (j + b) / ny)


def cube_mesh(smooth: bool):
    """A unit-half-size cube, its six faces in a 3 x 2 grid of the UV square."""
    def make():
        mesh = bpy.data.meshes.new("cube")
        v = [(x, y, z) for z in (-0.5, 0.5) for y in (-0.5, 0.5) for x in (-0.5, 0.5)]
        faces = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
        mesh.from_pydata(v, [], faces)
        _uv_grid(mesh, [(i % 3, i // 3, 3, 2) for i in range(6)])
        for p in mesh.polygons:
            p.use_smooth = smooth
        return mesh
    return make


def corner_mesh():
    """A floor (z = 0, [-1, 1] x [-1, 1]) and a wall (x = 0.3, up to z = 1.2) as one object: the
    floor fills the UV square's lower half, the wall its upper half."""
    mesh = bpy.data.meshes.new("corner")
    v = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0), (0.3, -1, 0), (0.3, 1, 0), (0.3, 1, 1.2), (0.3, -1, 1.2)]
    mesh.from_pydata(v, [], [(0, 1, 2, 3), (4, 5, 6, 7)])
    _uv_grid(mesh, [(0, 0, 1, 2), (0, 1, 1, 2)])
    return mesh


def _shifted(nt, socket):
    """0.5 v + 0.5: a normal as a colour without negative components."""
    m = nt.nodes.new("ShaderNodeVectorMath")
    m.operation = "MULTIPLY_ADD"
    nt.links.new(socket, m.inputs[0])
    m.inputs[1].default_value, m.inputs[2].default_value = (0.5, 0.5, 0.5), (0.5, 0.5, 0.5)
    return m.outputs[0]


def _bevel(radius, samples: int, linked_normal=False, radius_field=False):
    def build(nt):
        n = nt.nodes.new("ShaderNodeBevel")
        n.samples = samples
        n.inputs["Radius"].default_value = radius
        if radius_field:  # radius 0.05 .. 0.3 across the UV square
            coord = nt.nodes.new("ShaderNodeTexCoord")
            split = nt.nodes.new("ShaderNodeSeparateXYZ")
            m = nt.nodes.new("ShaderNodeMath")
            m.operation = "MULTIPLY_ADD"
            nt.links.new(coord.outputs["UV"], split.inputs[0])
            nt.links.new(split.outputs["X"], m.inputs[0])
            m.inputs[1].default_value, m.inputs[2].default_value = 0.25, 0.05
            nt.links.new(m.outputs[0], n.inputs["Radius"])
        if linked_normal == "constant":
            c = nt.nodes.new("ShaderNodeCombineXYZ")
            c.inputs[0].default_value, c.inputs[1].default_value, c.inputs[2].default_value = 0.3, -0.2, 0.9
            nt.links.new(c.outputs[0], n.inputs["Normal"])
        elif linked_normal:  # the normal tilted by the UV
            geometry, coord = nt.nodes.new("ShaderNodeNewGeometry"), nt.nodes.new("ShaderNodeTexCoord")
            m = nt.nodes.new("ShaderNodeVectorMath")
            m.operation = "MULTIPLY_ADD"
            nt.links.new(coord.outputs["UV"], m.inputs[0])
            m.inputs[1].default_value = (0.4, -0.3, 0.0)
            nt.links.new(geometry.outputs["Normal"], m.inputs[2])
            nt.links.new(m.outputs[0], n.inputs["Normal"])
        return _shifted(nt, n.outputs["Normal"])
    return build


def _ao(distance, samples: int, inside=False, only_local=False, output="Color"):
    def build(nt):
        n = nt.nodes.new("ShaderNodeAmbientOcclusion")
        n.samples, n.inside, n.only_local = samples, inside, only_local
        n.inputs["Distance"].default_value = distance
        n.inputs["Color"].default_value = (0.9, 0.6, 0.3, 1.0)
        return n.outputs[output]
    return build


def _cases():
    cases = {}
    for smooth, (radius, samples) in itertools.product((False, True), ((0.1, 4), (0.3, 2))):
        cases[f"bevel_{radius}_{samples}_{'smooth' if smooth else 'flat'}"] = Placed(
            _bevel(radius, samples), mesh=cube_mesh(smooth))
    cases["bevel_normal"] = Placed(_bevel(0.2, 4, linked_normal=True), mesh=cube_mesh(False))
    cases["bevel_normal_constant"] = Placed(_bevel(0.2, 4, linked_normal="constant"), mesh=cube_mesh(False))
    cases["bevel_radius_field"] = Placed(_bevel(0.0, 4, radius_field=True), mesh=cube_mesh(False),
                                         rotation=(0.3, 0.2, 0.5))
    cases["bevel_zero"] = Placed(_bevel(0.0, 4), mesh=cube_mesh(False))
    cases["ao_corner"] = Placed(_ao(1.0, 4), mesh=corner_mesh)
    cases["ao_corner_local"] = Placed(_ao(0.6, 2, only_local=True, output="AO"), mesh=corner_mesh)
    cases["ao_cube_inside"] = Placed(_ao(0.7, 4, inside=True), mesh=cube_mesh(False))
    cases["ao_cube_inside_smooth"] = Placed(_ao(0.7, 2, inside=True, output="AO"), mesh=cube_mesh(True))
    return cases


def _block_z(cycles, ember, var) -> float:
    """The largest |z| of a case's blocks (all channels)."""
    nb = SIZE // BLOCK
    d = (cycles - ember).reshape(nb, BLOCK, nb, BLOCK, 3).sum(axis=(1, 3))
    v = (2.0 * var / SAMPLES).reshape(nb, BLOCK, nb, BLOCK, 3).sum(axis=(1, 3))
    return float(np.max(np.abs(d) / np.sqrt(v + 1e-10)))


def test_ambient_occlusion_and_bevel_match_cycles_bakes():
    cases = _cases()
    results = node_bake.bake_traced(cases, SAMPLES, size=SIZE, columns=6)
    scores = {name: _block_z(*r) for name, r in results.items()}
    assert {name: z for name, z in scores.items() if z > Z} == {}, scores
    assert len(scores) == len(cases)
    # The cases vary: edges darken and bend where they should; a zero radius changes nothing.
    assert np.ptp(results["ao_corner"][0]) > 0.3 and np.ptp(results["bevel_0.1_4_flat"][0]) > 0.1
    assert np.ptp(results["bevel_0.3_2_smooth"][1]) > 0.1 and np.all(results["bevel_zero"][2] == 0.0)


def _turn(radius, samples: int):
    """dot(Bevel's normal, N): 1 inside the faces, less toward the edges."""
    def build(nt):
        n = nt.nodes.new("ShaderNodeBevel")
        n.samples = samples
        n.inputs["Radius"].default_value = radius
        geometry = nt.nodes.new("ShaderNodeNewGeometry")
        m = nt.nodes.new("ShaderNodeVectorMath")
        m.operation = "DOT_PRODUCT"
        nt.links.new(n.outputs["Normal"], m.inputs[0])
        nt.links.new(geometry.outputs["Normal"], m.inputs[1])
        return m.outputs["Value"]
    return build


def test_bevel_turns_the_normal_as_much_as_cycles():
    cases = {f"turn_{radius}_{samples}": Placed(_turn(radius, samples), mesh=cube_mesh(False))
             for radius, samples in ((0.15, 8), (0.25, 4))}
    results = node_bake.bake_traced(cases, SAMPLES, size=32, columns=6)
    for name, (cycles, ember, var) in results.items():
        d, v = (cycles - ember)[:, 0], 2.0 * var[:, 0] / SAMPLES + 1e-10
        assert abs(d.sum() / np.sqrt(v.sum())) < Z_POOLED, (name, (1.0 - cycles).mean(), (1.0 - ember).mean())
        assert (1.0 - cycles[:, 0]).mean() > 0.02  # the edges turn the normal
