"""Light Path (svm/light_path.h svm_node_light_path): what kind of ray reached the point, and how
many bounces of each kind the path has made.

The ray's kind is Cycles' path flag, a uint32 of PATH_RAY_* bits (kernel/types.h) the path
tracer keeps per path and gives per point (state.path_flag); the depths are its bounce
counters (state.bounce, diffuse_bounce, ...). A bake's path is a camera path that has not
bounced: CAMERA | MIS_SKIP | TRANSPARENT_BACKGROUND and every count 0 (integrator/path_state.h
path_state_init_integrator).
"""
from __future__ import annotations

import numpy as np

from .base import node, scalar

# kernel/types.h PathRayFlag.
CAMERA = 1 << 0
REFLECT = 1 << 1
TRANSMIT = 1 << 2
DIFFUSE = 1 << 3
GLOSSY = 1 << 4
SINGULAR = 1 << 5
TRANSPARENT = 1 << 6
VOLUME_SCATTER = 1 << 7
SHADOW_OPAQUE = 1 << 9
SHADOW_TRANSPARENT = 1 << 10
SHADOW = SHADOW_OPAQUE | SHADOW_TRANSPARENT
MIS_SKIP = 1 << 12
TRANSPARENT_BACKGROUND = 1 << 15
EMISSION = 1 << 20

# Output -> the flag bits it tests.
_FLAGS = {"Is Camera Ray": CAMERA, "Is Shadow Ray": SHADOW, "Is Diffuse Ray": DIFFUSE, "Is Glossy Ray": GLOSSY,
          "Is Singular Ray": SINGULAR, "Is Reflection Ray": REFLECT, "Is Transmission Ray": TRANSMIT,
          "Is Volume Scatter Ray": VOLUME_SCATTER}
# Output -> the bounce counter it reads.
_DEPTHS = {"Diffuse Depth": "diffuse_bounce", "Glossy Depth": "glossy_bounce",
           "Transparent Depth": "transparent_bounce", "Transmission Depth": "transmission_bounce",
           "Portal Depth": "portal_bounce"}

_READS = {**{name: ("path_flag",) for name in _FLAGS}, "Ray Length": ("ray_length",),
          "Ray Depth": ("bounce", "path_flag"), **{name: (field,) for name, field in _DEPTHS.items()}}


def _is(flags, bits):
    return np.where((np.asarray(flags).astype(np.uint32) & np.uint32(bits)) != 0, 1.0, 0.0)


def ray_depth(bounce, flags):
    """The path's bounce count, one more for a shadow ray or a light's or the world's emission
    seen from a surface (they are a bounce further than the surface that cast them)."""
    return scalar(bounce) + _is(flags, SHADOW | EMISSION)


@node("ShaderNodeLightPath", "Input", reads=_READS)
def light_path_node(node, inputs, state):
    out = {name: (lambda bits=bits: _is(state.path_flag, bits)) for name, bits in _FLAGS.items()}
    out.update({name: (lambda field=field: scalar(getattr(state, field))) for name, field in _DEPTHS.items()})
    out["Ray Length"] = lambda: scalar(state.ray_length)
    out["Ray Depth"] = lambda: ray_depth(state.bounce, state.path_flag)
    return out


NODES = (light_path_node,)
