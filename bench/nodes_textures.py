"""Cost per shading point of the procedural texture nodes (engine/nodes/textures.py): each
texture in a compiled program, its Vector (and W) linked to the Generated coordinate, run
over a batch of points spread over many cells; the best of several runs, in microseconds
per point. No Blender needed.

    ./dev python bench/nodes_textures.py              # 100k points, every texture
    ./dev python bench/nodes_textures.py --points 20000 --only noise
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from _bootstrap import load_ember  # noqa: E402

load_ember()
from ember.engine.nodes.graph import Graph, Input, Link, Node  # noqa: E402
from ember.engine.nodes.program import compile  # noqa: E402
from ember.engine.nodes.state import ShadingState  # noqa: E402

NOISE_INPUTS = {"W": 0.3, "Scale": 5.0, "Detail": 2.0, "Roughness": 0.5, "Lacunarity": 2.0, "Offset": 0.0,
                "Gain": 1.0, "Distortion": 0.0}


COORD = Node("ShaderNodeTexCoord", "coord", (), (), (("Generated", "vector"),))
SPLIT = Node("ShaderNodeSeparateXYZ", "split", (), (Input("Vector", "vector", link=Link(0, "Generated", "vector")),),
             (("X", "value"), ("Y", "value"), ("Z", "value")))


def _node(kind, props, inputs, outputs):
    """The texture as node 2 after COORD and SPLIT: Vector from Generated, W from its x."""
    sockets = [Input("Vector", "vector", (0.0, 0.0, 0.0), Link(0, "Generated", "vector"))]
    for name, value in inputs.items():
        kind_of = "rgba" if isinstance(value, tuple) else "value"
        sockets.append(Input(name, kind_of, value, Link(1, "X", "value") if name == "W" else None))
    return Node(kind, kind, tuple(sorted(props.items())), tuple(sockets), tuple(outputs))


TEXTURE_OUTPUTS = (("Color", "rgba"), ("Fac", "value"))
WAVE = {"Scale": 5.0, "Distortion": 0.0, "Detail": 2.0, "Detail Scale": 1.0, "Detail Roughness": 0.5,
        "Phase Offset": 0.0}
BRICK = {"Color1": (0.8, 0.8, 0.8), "Color2": (0.2, 0.2, 0.2), "Mortar": (0.0, 0.0, 0.0), "Scale": 5.0,
         "Mortar Size": 0.02, "Mortar Smooth": 0.1, "Bias": 0.0, "Brick Width": 0.5, "Row Height": 0.25}


def _noise(d, kind="FBM", **inputs):
    return _node("ShaderNodeTexNoise", {"noise_dimensions": d, "noise_type": kind, "normalize": True},
                 dict(NOISE_INPUTS, **inputs), (("Fac", "value"), ("Color", "rgba")))


def cases():
    """(label, node, output read)."""
    out = [(f"noise {d} fBM detail 2", _noise(d), "Fac") for d in ("1D", "2D", "3D", "4D")]
    out += [(f"noise 3D {t} detail 2", _noise("3D", t), "Fac")
            for t in ("MULTIFRACTAL", "HYBRID_MULTIFRACTAL", "HETERO_TERRAIN", "RIDGED_MULTIFRACTAL")]
    out += [("noise 3D fBM detail 0", _noise("3D", Detail=0.0), "Fac"),
            ("noise 3D fBM detail 2 colour", _noise("3D"), "Color"),
            ("noise 3D fBM detail 2 distorted", _noise("3D", Distortion=0.5), "Fac")]
    out += [(f"white noise {d} colour", _node("ShaderNodeTexWhiteNoise", {"noise_dimensions": d}, {"W": 0.0},
                                              (("Value", "value"), ("Color", "rgba"))), "Color")
            for d in ("1D", "3D", "4D")]
    out += [(f"gradient {t}", _node("ShaderNodeTexGradient", {"gradient_type": t}, {}, TEXTURE_OUTPUTS), "Fac")
            for t in ("LINEAR", "SPHERICAL", "RADIAL")]
    out.append(("checker", _node("ShaderNodeTexChecker", {}, {k: BRICK[k] for k in ("Color1", "Color2", "Scale")},
                                 TEXTURE_OUTPUTS), "Color"))
    out += [(f"magic depth {depth}", _node("ShaderNodeTexMagic", {"turbulence_depth": depth},
                                           {"Scale": 5.0, "Distortion": 1.0}, TEXTURE_OUTPUTS), "Color")
            for depth in (2, 10)]
    out.append(("wave bands sine", _node("ShaderNodeTexWave", {"wave_type": "BANDS", "bands_direction": "X",
                                                               "wave_profile": "SIN"}, WAVE, TEXTURE_OUTPUTS), "Fac"))
    out.append(("wave rings distorted detail 2",
                _node("ShaderNodeTexWave", {"wave_type": "RINGS", "rings_direction": "SPHERICAL",
                                            "wave_profile": "SIN"}, dict(WAVE, Distortion=2.0), TEXTURE_OUTPUTS),
                "Fac"))
    out.append(("brick", _node("ShaderNodeTexBrick", {"offset": 0.5, "offset_frequency": 2, "squash": 1.0,
                                                      "squash_frequency": 2}, BRICK, TEXTURE_OUTPUTS), "Color"))
    return out


def measure(node, output, points: int, repeats: int) -> float:
    """Best-of-`repeats` microseconds per point of the node's `output`."""
    kind = dict(node.outputs)[output]
    graph = Graph((COORD, SPLIT, node), (("out", Input("out", kind, link=Link(2, output, kind))),))
    program = compile(graph, {"out": kind})
    rng = np.random.default_rng(7)
    generated = rng.random((points, 3)) * 4.0 - 1.0
    best = float("inf")
    for _ in range(repeats):
        state = ShadingState(points, generated=generated)
        start = time.process_time()
        program.run(state)
        best = min(best, time.process_time() - start)
    return best / points * 1e6


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--only", default="", help="labels containing this text")
    args = parser.parse_args(argv)
    print(f"{'texture':40s} us/point  ({args.points} points, best of {args.repeats}, load {os.getloadavg()[0]:.1f})")
    for label, node, output in cases():
        if args.only in label:
            print(f"{label:40s} {measure(node, output, args.points, args.repeats):8.3f}")


if __name__ == "__main__":
    main()
