"""Compiled node programs are kept per graph: a material table that differs from an earlier one
in one graph compiles only that graph, and the same table gives the same programs (what a
viewport's updates and a series of renders rely on)."""
from __future__ import annotations

import numpy as np

from _bootstrap import load_ember

load_ember()
from ember.engine.nodes import material  # noqa: E402
from ember.engine.nodes.graph import Graph, Input, Link, Node  # noqa: E402
from ember.engine.nodes.image import Texels  # noqa: E402


def _graph(scale: float, prop=("noise_dimensions", "3D")) -> Graph:
    noise = Node("ShaderNodeTexNoise", "n", (prop,),
                 (Input("Vector", "vector", (0.0, 0.0, 0.0)), Input("Scale", "value", scale),
                  Input("Detail", "value", 2.0), Input("Roughness", "value", 0.5), Input("Lacunarity", "value", 2.0),
                  Input("Distortion", "value", 0.0), Input("W", "value", 0.0), Input("Offset", "value", 0.0),
                  Input("Gain", "value", 1.0)),
                 (("Fac", "value"), ("Color", "rgba")))
    diffuse = Node("ShaderNodeBsdfDiffuse", "d", (),
                   (Input("Color", "rgba", (0.8, 0.8, 0.8), Link(0, "Color", "rgba")), Input("Roughness", "value", 0.0),
                    Input("Normal", "vector", (0.0, 0.0, 0.0))),
                   (("BSDF", "shader"),))
    return Graph((noise, diffuse), (("surface", Input("surface", "shader", None, Link(1, "BSDF", "shader"))),))


def test_equal_graphs_compile_once_and_changed_ones_again(monkeypatch):
    calls = []
    compile_material = material.compile_material
    monkeypatch.setattr(material, "compile_material", lambda g: calls.append(g) or compile_material(g))
    monkeypatch.setattr(material, "_GRAPHS", {})
    first = material.compiled_material(_graph(5.0))
    again = material.compiled_material(_graph(5.0))  # an equal graph, exported anew
    assert again is first and len(calls) == 1
    other = material.compiled_material(_graph(6.0))  # one socket value differs
    assert other is not first and len(calls) == 2
    state = material.probe_state(4)
    a, b = first.evaluate(state)[0][0]["color"], other.evaluate(state)[0][0]["color"]
    assert a.shape == (4, 3) and not np.allclose(a, b)


def test_graphs_holding_texels_are_not_kept(monkeypatch):
    monkeypatch.setattr(material, "_GRAPHS", {})
    texels = Texels("t", np.zeros((2, 2, 4), np.float32))
    graph = _graph(5.0, prop=("noise_dimensions", "3D"))
    held = Graph(tuple(Node(n.kind, n.label, n.props + (("image", texels),), n.inputs, n.outputs) for n in graph.nodes),
                 graph.outputs)
    assert material.compiled_material(held) is not material.compiled_material(held)
    assert not material._GRAPHS
