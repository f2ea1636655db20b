"""Cost per shading point of the Image Texture node (engine/nodes/image_texture.py): each
interpolation with each projection in a compiled program, the Vector linked to the Generated
coordinate (spread over several image repeats), the image 1024 x 1024 RGBA, float (16 MiB)
or 8-bit (4 MiB); the best of several runs, in microseconds per point. No Blender needed.

    ./dev python bench/nodes_image.py              # 100k points, every case
    ./dev python bench/nodes_image.py --points 20000 --only BOX
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
from ember.engine.nodes.image import Texels, Tiles  # noqa: E402
from ember.engine.nodes.program import compile  # noqa: E402
from ember.engine.nodes.state import ShadingState  # noqa: E402

COORD = Node("ShaderNodeTexCoord", "coord", (), (), (("Generated", "vector"),))
SIZE = 1024


def _image(srgb: bool = False, tiles: bool = False):
    pixels = np.random.default_rng(3).random((SIZE, SIZE, 4)).astype(np.float32)
    if srgb:
        pixels = np.rint(pixels * 255.0).astype(np.uint8)
    texels = Texels("bench", pixels, srgb=srgb)
    return Tiles("bench", ((1001, texels), (1002, texels), (1011, texels))) if tiles else texels


def cases():
    """(label, props, output)."""
    out = []
    for projection in ("FLAT", "BOX", "SPHERE", "TUBE"):
        for interpolation in ("Closest", "Linear", "Cubic"):
            out.append((f"{projection} {interpolation}", dict(projection=projection, interpolation=interpolation,
                                                              projection_blend=0.3), "Color"))
    out.append(("FLAT Linear CLIP", dict(interpolation="Linear", extension="CLIP"), "Color"))
    out.append(("FLAT Linear 8-bit sRGB", dict(interpolation="Linear", srgb=True), "Color"))
    out.append(("FLAT Linear unassociated", dict(interpolation="Linear"), "both"))
    out.append(("FLAT Linear UDIM (3 tiles)", dict(interpolation="Linear", tiles=True), "Color"))
    return out


def measure(props: dict, output: str, points: int, repeats: int) -> float:
    props = dict(props)
    image = _image(props.pop("srgb", False), props.pop("tiles", False))
    node = Node("ShaderNodeTexImage", "image", tuple(sorted(dict(props, image=image).items())),
                (Input("Vector", "vector", (0.0, 0.0, 0.0), Link(0, "Generated", "vector")),),
                (("Color", "rgba"), ("Alpha", "value")))
    outputs = {"out": ("Color", "rgba")} if output != "both" else {"out": ("Color", "rgba"), "a": ("Alpha", "value")}
    graph = Graph((COORD, node), tuple((k, Input(k, t, link=Link(1, s, t))) for k, (s, t) in outputs.items()))
    program = compile(graph, {k: t for k, (_, t) in outputs.items()})
    rng = np.random.default_rng(7)
    generated = rng.random((points, 3)) * 2.4 - 0.2
    normal = rng.normal(size=(points, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    best = float("inf")
    for _ in range(repeats):
        state = ShadingState(points, generated=generated, uv=generated, N=normal,
                             world_from_object=np.broadcast_to(np.eye(4), (points, 4, 4)))
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
    print(f"{'image texture':32s} us/point  ({args.points} points, best of {args.repeats}, "
          f"load {os.getloadavg()[0]:.1f})")
    for label, props, output in cases():
        if args.only in label:
            print(f"{label:32s} {measure(props, output, args.points, args.repeats):8.3f}")


if __name__ == "__main__":
    main()
