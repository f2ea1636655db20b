"""The node registry: every node kind the evaluator builds, from the modules that implement
them. The coverage table (README) and the compiler read it; a kind not listed here is
reported and falls back (engine/nodes/program.py)."""
from __future__ import annotations

from . import (closures, color, curves, environment, gabor, ies, image_texture, map_range, mapping, math, shaders, sky,
               textures, vector, vector_math, voronoi)

MODULES = (closures, shaders, math, vector, vector_math, map_range, mapping, color, curves, textures, voronoi, gabor, sky,
           environment, image_texture, ies)
REGISTRY = {t.kind: t for module in MODULES for t in module.NODES}
