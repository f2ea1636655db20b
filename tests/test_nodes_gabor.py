"""Gabor Texture against Cycles (tests/node_bake.py): 2D and 3D, Value, Phase and Intensity,
over Anisotropy from isotropic to anisotropic (constant and per point), Frequency (down to its
clamp), Orientation (2D angle and 3D direction, constant and per point) and Scale, on the
Generated coordinate and on a UV-driven vector that crosses zero (negative cells)."""
import numpy as np
import pytest

pytestmark = pytest.mark.blender

import node_bake  # noqa: E402
from test_nodes_voronoi import _constant_vector, _socket, sweep, uv_vector  # noqa: E402

OUTPUTS = ("Value", "Phase", "Intensity")


def gabor(kind: str, output: str, **inputs):
    """A case: the Gabor node's `output`; inputs are values or builders of linked sockets."""
    def build(nt):
        g = nt.nodes.new("ShaderNodeTexGabor")
        g.gabor_type = kind
        for name, value in inputs.items():
            socket = _socket(g.inputs, name)
            if callable(value):
                nt.links.new(value(nt), socket)
            else:
                socket.default_value = value
        return _socket(g.outputs, output)
    return build


def _direction(x, y, z):
    def build(nt):
        c = nt.nodes.new("ShaderNodeCombineXYZ")
        for axis, value in zip("XYZ", (x, y, z)):
            if callable(value):
                nt.links.new(value(nt), c.inputs[axis])
            else:
                c.inputs[axis].default_value = value
        return c.outputs[0]
    return build


def test_gabor_matches_cycles():
    cases = {}
    negative = uv_vector(-3.1, 2.9, -0.77)
    for kind in ("2D", "3D"):
        orientation = "Orientation 2D" if kind == "2D" else "Orientation 3D"
        tilted = 2.1 if kind == "2D" else (0.2, -0.7, 0.4)
        per_point = (sweep("X", -1.0, 4.0) if kind == "2D"
                     else _direction(sweep("X", -1.0, 1.0), 0.3, sweep("Y", -0.5, 0.8)))
        for out in OUTPUTS:
            cases[f"{kind}-{out}"] = gabor(kind, out)
            cases[f"{kind}-{out}-negative"] = gabor(kind, out, Vector=negative, Scale=1.9)
            cases[f"{kind}-{out}-isotropic"] = gabor(kind, out, Anisotropy=0.0, Scale=7.1, Frequency=3.3)
            cases[f"{kind}-{out}-partly"] = gabor(kind, out, Anisotropy=0.35, **{orientation: tilted})
        variants = {
            "anisotropy-per-point": dict(Anisotropy=sweep("X", -0.2, 1.2)),
            "frequency-clamped": dict(Frequency=0.0, Anisotropy=0.5),
            "frequency-high": dict(Frequency=9.0, Scale=2.0),
            "frequency-per-point": dict(Frequency=sweep("Y", 0.5, 6.0), Anisotropy=0.6),
            "orientation-per-point": {orientation: per_point, "Anisotropy": 0.7},
            "orientation-anisotropic": {orientation: tilted},
            "scale-negative": dict(Scale=-6.3, Anisotropy=0.2),
            "scale-per-point": dict(Scale=sweep("X", 2.0, 9.0)),
            "constant-vector": dict(Vector=_constant_vector(0.3, -0.6, 0.45), Frequency=sweep("X", 0.5, 6.0),
                                    Anisotropy=sweep("Y", 0.0, 1.0)),
        }
        for name, inputs in variants.items():
            for out in ("Value", "Phase"):
                cases[f"{kind}-{name}-{out}"] = gabor(kind, out, **inputs)
    results = node_bake.bake(cases)
    scores = {name: node_bake.agreement(c, e) for name, (c, e) in results.items()}
    bad = {name: round(s, 4) for name, s in scores.items() if s < 0.999}
    flat = [name for name, (c, _) in results.items() if np.ptp(c) == 0.0]
    assert bad == {} and flat == [], (bad, flat)
