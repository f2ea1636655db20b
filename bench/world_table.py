"""The world program's importance table (engine/lights/world.py): build time and memory by the
resolution rule, per kind of world, and the program's cost per escaped ray.

    ./dev python bench/world_table.py            # prints a table (seconds, MB)

Worlds: the default Sky Texture (its sun guided apart: 512 x 256), a Noise texture of the
direction (Cycles' default 1024 x 512), an Environment Texture of a 2048 x 1024 image read
with Linear interpolation (one pixel per texel: 2048 x 1024, the cap). Each table is built
twice (the first run pays for the sky's scattering texture and NumPy's warm-up); the second
is reported. Memory: WorldMap.nbytes (the table's CDFs and the values kept for photons).
"""
from __future__ import annotations

import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from _bootstrap import load_ember  # noqa: E402

load_ember()
from ember.engine.lights.world import Background, WorldMap, guided_suns, map_size  # noqa: E402
from ember.engine.nodes.graph import Graph, Input, Link, Node  # noqa: E402
from ember.engine.nodes.image import Texels  # noqa: E402


def _world(texture: Node) -> Graph:
    bg = Node("ShaderNodeBackground", "Background", (), (Input("Color", "rgba", (0.8, 0.8, 0.8), Link(0, "Color", "rgba")),
                                                         Input("Strength", "value", 1.0)), (("Background", "shader"),))
    return Graph((texture, bg), (("surface", Input("Surface", "shader", 0.0, Link(1, "Background", "shader"))),))


def worlds() -> dict:
    vector = (Input("Vector", "vector", (0.0, 0.0, 0.0)),)
    sky = Node("ShaderNodeTexSky", "Sky", (("sky_type", "MULTIPLE_SCATTERING"),), vector, (("Color", "rgba"),))
    noise = Node("ShaderNodeTexNoise", "Noise", (("noise_dimensions", "3D"), ("noise_type", "FBM"), ("normalize", True)),
                 vector + (Input("Scale", "value", 5.0), Input("Detail", "value", 2.0), Input("Roughness", "value", 0.5),
                           Input("Lacunarity", "value", 2.0), Input("Offset", "value", 0.0), Input("Gain", "value", 1.0),
                           Input("Distortion", "value", 0.0)),
                 (("Fac", "value"), ("Color", "rgba")))
    h, w = 1024, 2048
    pixels = np.random.default_rng(0).random((h, w, 4)).astype(np.float32)
    env = Node("ShaderNodeTexEnvironment", "Env", (("image", Texels("hdr", pixels)), ("interpolation", "Linear"),
                                                   ("projection", "EQUIRECTANGULAR")), vector,
               (("Color", "rgba"), ("Alpha", "value")))
    return {"sky (default)": _world(sky), "noise": _world(noise), "environment 2048x1024": _world(env)}


def main() -> int:
    print(f"{'world':24s} {'table':>11s} {'build s':>8s} {'MB':>7s} {'us / escaped ray':>17s}")
    d = np.random.default_rng(1).normal(size=(200_000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    for name, graph in worlds().items():
        background = Background(graph)
        size = map_size(graph, 0, bool(guided_suns(graph)))
        for _ in range(2):
            t0 = time.perf_counter()
            table = WorldMap(background, size, compensate=True)
            seconds = time.perf_counter() - t0
        t0 = time.perf_counter()
        background.radiance(d)
        per_ray = (time.perf_counter() - t0) / len(d) * 1e6
        print(f"{name:24s} {size[0]:>5d}x{size[1]:<5d} {seconds:8.2f} {table.nbytes / 1e6:7.1f} {per_ray:17.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
