"""The node registry: every node kind the evaluator builds, from the modules that implement
them. The coverage table (README) and the compiler read it; a kind not listed here is
reported and falls back (engine/nodes/program.py)."""
from __future__ import annotations

from . import (ambient_occlusion, attribute, bevel, bump, closures, color, curves, displacement, environment, fresnel, gabor, geometry, ies,
               image_texture, light_path, map_range, mapping, math, normal_map, object_info, particle_info, radial_tiling,
               shaders, sky, squeeze, tangent, textures, vector, vector_math, voronoi)

MODULES = (closures, shaders, math, vector, vector_math, map_range, mapping, color, curves, textures, voronoi, gabor,
           sky, environment, image_texture, ies, geometry, object_info, attribute, fresnel, light_path, tangent,
           normal_map, bump, displacement, radial_tiling, particle_info, squeeze,
           ambient_occlusion, bevel)
REGISTRY = {t.kind: t for module in MODULES for t in module.NODES}
