"""Node conformance against Cycles: a node's output routed to Emission, baked by Cycles at the
texel centres of a plane, and the same graph evaluated by Ember's node programs at the same
points (exact values, no sampling noise on either side).

Each case is a function that builds a material's nodes and returns the output socket to
test; cases run in one bake (one plane per case, side by side), so hundreds cost about a
second. Cycles bakes EMIT at each texel (u, v) = ((i + 0.5) / S, (j + 0.5) / S) of the plane's
UV map (nudged by BAKE_OFFSET), which spans the plane corner to corner: object position (2u - 1, 2v - 1, 0), normal
+z, the ray arriving along -z.
"""
from __future__ import annotations

import numpy as np

import bpy

from ember.engine.blender.export_nodes import export_graph
from ember.engine.nodes.closures import closures
from ember.engine.nodes.program import compile
from ember.engine.nodes.state import ShadingState

SIZE = 32
SPACING = 3.0
# Where in a texel Blender's baker puts its point: the centre, nudged by these fractions of a
# texel in u and v (measured from a baked UV coordinate: the same at 16 to 128 texels).
BAKE_OFFSET = (0.001, 0.002)


def _plane(k: int):
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(SPACING * k, 0.0, 0.0))
    return bpy.context.active_object


def _material(name: str, build):
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    emission = nt.nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = 1.0
    nt.links.new(emission.outputs[0], out.inputs["Surface"])
    socket = build(nt)
    if socket is not None:
        nt.links.new(socket, emission.inputs["Color"])
    return mat, out


def _state(ob, size: int) -> ShadingState:
    i = np.arange(size) + 0.5
    u, v = (a.ravel() for a in np.meshgrid((i + BAKE_OFFSET[0]) / size, (i + BAKE_OFFSET[1]) / size))
    obj = np.stack([2.0 * u - 1.0, 2.0 * v - 1.0, np.zeros_like(u)], axis=1)
    world = obj + np.asarray(ob.location, np.float64)
    loc = np.asarray(ob.data.texspace_location, np.float64)
    half = np.asarray(ob.data.texspace_size, np.float64)
    n = np.tile([0.0, 0.0, 1.0], (len(u), 1))
    return ShadingState(len(u), P=world, N=n, Ng=n, I=n, backfacing=np.zeros(len(u), bool),
                        uv=np.stack([u, v, np.zeros_like(u)], axis=1), generated=(obj - loc + half) / (2.0 * half),
                        object=obj, ray_length=np.ones(len(u)))


def bake(cases: dict, size: int = SIZE) -> dict:
    """{name: (cycles (S*S,3), ember (S*S,3))} for cases {name: build(node_tree) -> socket}."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 1
    made = {}
    for k, (name, build) in enumerate(cases.items()):
        ob = _plane(k)
        mat, out = _material(name, build)
        image = bpy.data.images.new(f"bake_{k}", size, size, float_buffer=True)
        tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
        tex.image = image
        mat.node_tree.nodes.active = tex
        ob.data.materials.append(mat)
        made[name] = (ob, out, image)
    bpy.ops.object.select_all(action="DESELECT")
    for ob, _, _ in made.values():
        ob.select_set(True)
    bpy.context.view_layer.objects.active = next(iter(made.values()))[0]
    bpy.ops.object.bake(type="EMIT")
    results = {}
    for name, (ob, out, image) in made.items():
        cycles = np.array(image.pixels[:], np.float64).reshape(size * size, 4)[:, :3]
        results[name] = (cycles, evaluate(out, _state(ob, size)))
    return results


def evaluate(output_node, state: ShadingState) -> np.ndarray:
    """Ember's emitted radiance (N,3) of a material output node's Surface at the state's points."""
    warnings = []
    graph = export_graph({"surface": output_node.inputs["Surface"]}, warnings.append)
    program = compile(graph, {"surface": "shader"})
    assert not warnings and not program.warnings, warnings + list(program.warnings)
    total = np.zeros((state.n, 3))
    for c in closures(program.run(state)["surface"]):
        if c.kind == "emission":
            total = total + c.weight
    return total


def agreement(cycles: np.ndarray, ember: np.ndarray, tol: float = 1e-4) -> float:
    """Share of texels whose three channels all agree within tol: absolute up to 1, relative
    above (Cycles computes in float32, whose steps at 1000 are 6e-5)."""
    return float(np.mean(np.all(np.abs(cycles - ember) <= tol * np.maximum(1.0, np.abs(cycles)), axis=1)))
