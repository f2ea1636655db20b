"""Light objects -> rows for Lights.make, in Cycles' units.

Confirmed in blender/blender (5.x):
- intern/cycles/blender/light.cpp (sync_light): strength = color [* temperature_color if
  use_temperature] * energy * 2^exposure; normalize = light.normalize; point/spot size =
  radius (shadow_soft_size, not scaled by the object); area size_u/size_v = size/size_y.
- intern/cycles/scene/light.cpp: Light::area() = 4 pi r^2 for point/spot (4 when r = 0);
  |axis_u| size_u * |axis_v| size_v (* pi/4 for disk/ellipse) for area lights, where the
  axes are the object transform's x/y columns (object scale included); pi sin^2(angle/2)
  for the sun (1 when angle = 0). invarea = normalize ? 1/area : 1.
  Point/spot eval_fac = invarea / pi; area eval_fac = invarea / pi (kernel/light/area.h);
  sun eval_fac = invarea (kernel/light/distant.h). Emitted value = strength * eval_fac:
  radiance, or for delta lights intensity (point/spot r = 0: strength/(4 pi)) and
  irradiance (sun angle = 0: strength).
- kernel/light/spot.h: attenuation smoothstep((cos - cos(size/2)) / ((1 - cos(size/2)) * blend)),
  power is not concentrated into the cone.
- kernel/light/point.h: with use_soft_falloff (the default) a point/spot of radius r is a
  disk of radius r through its centre facing the shading point (uniform by area); without
  it, a sphere (uniform in the subtended cone).
- Light node trees (light_shader): the Surface's graph through the node evaluator; a constant
  (Emission colour x strength, Blackbody, Math...) multiplies the strength, as the kernel
  multiplies the shader's emission into strength x eval_fac (light/sample.h
  light_sample_shader_eval); a shader that varies is kept as the light's graph and evaluated
  per light sample and hit.
Approximations: area spread, per-ray-type visibility, photon emission of lights
whose shader varies, and non-uniformly scaled spot cones are not modelled (warned).
"""
from __future__ import annotations

import math

import numpy as np

from ..scene import (LINK_ALL, LIGHT_DISK, LIGHT_POINT, LIGHT_RECT, LIGHT_SPOT, LIGHT_SUN, RAY_CAMERA, RAY_DIFFUSE, RAY_GLOSSY,
                     RAY_SHADOW, RAY_TRANSMIT)
from ..nodes.closures import closures
from ..nodes.program import compile
from .export_material import find_output, follow_link
from .export_nodes import export_graph


def _unsupported(warn, what: str, name: str) -> None:
    """One warning per feature listing the lights (export.Warnings.group), else per light."""
    group = getattr(warn, "group", None)
    if group is not None:
        group(what, name)
    else:
        warn(f"{what}: '{name}'.")


def light_strength(light, warn) -> np.ndarray:
    """Cycles' strength (3,): colour x temperature colour x energy x 2^exposure x the shader's
    emission where it is a constant (light_shader)."""
    return _base_strength(light, warn) * light_shader(light, warn)[0]


def _base_strength(light, warn) -> np.ndarray:
    """colour x temperature colour x energy x 2^exposure (blender/light.cpp sync_light)."""
    color = np.array(light.color[:3], np.float64)
    if getattr(light, "use_temperature", False):
        tc = getattr(light, "temperature_color", None)
        if tc is not None:
            color = color * np.array(tc[:3], np.float64)
        else:  # pragma: no cover - older Blender
            warn(f"Light '{light.name}': colour temperature is ignored.")
    return color * float(light.energy) * 2.0 ** float(getattr(light, "exposure", 0.0))


def light_shader(light, warn) -> tuple:
    """(factor (3,), graph or None): the light's shader as Cycles evaluates it (light/sample.h
    light_sample_shader_eval: the emission and background closures its Surface makes multiply
    the strength x eval_fac). A shader that folds to a constant (Emission colour x strength,
    Blackbody, Math...) is that constant and no graph; one that varies over the light's
    samples (Light Falloff, IES, a texture of the direction) is factor 1 and its graph, which
    the light set evaluates per sample and hit (engine/lights/light_shader.py). No node tree
    (or use_nodes off): Cycles' default emission of 1; a tree without a Light Output node:
    nothing (as Cycles renders it)."""
    tree = getattr(light, "node_tree", None) if getattr(light, "use_nodes", True) else None
    if tree is None:
        return np.ones(3), None
    out = find_output(tree, "ShaderNodeOutputLight")
    owner = f"Light '{light.name}'"
    if out is None:  # Cycles' graph then has nothing at its output
        warn(f"{owner}: its node tree has no Light Output node for Cycles; it emits nothing.")
        return np.zeros(3), None
    if follow_link(out.inputs["Surface"]) is None:
        warn(f"{owner}: its node tree has nothing connected to Surface; it emits nothing.")
        return np.zeros(3), None
    notes = []
    graph = export_graph({"surface": out.inputs["Surface"]}, notes.append)
    try:
        program = compile(graph, {"surface": "shader"})
    except (ValueError, KeyError, TypeError, IndexError) as exc:
        warn(f"{owner}: its node tree could not be evaluated ({exc}); the light colour is used alone.")
        return np.ones(3), None
    for note in notes + list(program.warnings):
        warn(f"{owner}: {note}")
    if program.constant:
        made = closures(program.run()["surface"])
        return sum((np.asarray(c.weight, np.float64) for c in made if c.kind in ("emission", "background")),
                   np.zeros(3)), None
    varying = ", ".join(dict.fromkeys(f"'{op.node.label}'" for op in program.ops))
    warn(f"{owner}: its shader varies over the light ({varying}): evaluated per light sample and hit; "
         "photon emission takes its emission as 1.")
    return np.ones(3), graph


def light_row(light, name: str, matrix_world: np.ndarray, visible_camera: bool, warn) -> dict | None:
    """One Lights row for light datablock `light` placed by `matrix_world` (4,4).
    Returns None for lights that cannot contribute (zero strength or zero area)."""
    m = np.asarray(matrix_world, np.float64).reshape(4, 4)
    axes = m[:3, :3].T.copy()  # rows = world x, y, z axes (with scale)
    lengths = np.linalg.norm(axes, axis=1)
    factor, graph = light_shader(light, warn)
    strength = _base_strength(light, warn) * factor
    if not np.any(strength != 0.0):
        return None
    normalize = bool(getattr(light, "normalize", True))
    frame = axes / np.where(lengths > 0, lengths, 1.0)[:, None]
    row = dict(position=m[:3, 3].copy(), frame=frame, visible=bool(visible_camera), name=name, matrix=m[:3, :3].copy())
    if graph is not None:
        row["graph"] = graph
    kind = light.type

    if kind in ("POINT", "SPOT"):
        r = max(float(light.shadow_soft_size), 0.0)
        if r > 0:
            Le = strength / (math.pi * (4.0 * math.pi * r * r)) if normalize else strength / math.pi
        else:
            Le = strength / (4.0 * math.pi) if normalize else strength / math.pi
        row.update(kind=LIGHT_POINT, radius=r, Le=Le, soft=bool(getattr(light, "use_soft_falloff", True)))
        if kind == "SPOT":
            cos_half = math.cos(0.5 * float(light.spot_size))
            row.update(kind=LIGHT_SPOT, spot_cos_half=cos_half,
                       spot_smooth=(1.0 - cos_half) * float(light.spot_blend))
            if not np.allclose(lengths, lengths[0], rtol=1e-5):
                _unsupported(warn, "Non-uniformly scaled spot lights (elliptic cones) are not "
                                   "supported; using round cones", name)
    elif kind == "SUN":
        half = 0.5 * float(light.angle)
        if half > 0:
            Le = strength / (math.pi * math.sin(half) ** 2) if normalize else strength
        else:
            Le = strength
        row.update(kind=LIGHT_SUN, sun_half_angle=half, Le=Le)
    elif kind == "AREA":
        shape = light.shape
        sx = float(light.size)
        sy = float(light.size_y) if shape in ("RECTANGLE", "ELLIPSE") else sx
        ex, ey = abs(sx) * lengths[0], abs(sy) * lengths[1]  # full world extents
        ellipse = shape in ("DISK", "ELLIPSE")
        area = ex * ey * (math.pi / 4.0 if ellipse else 1.0)
        if not area > 0:
            return None
        Le = strength / (math.pi * area) if normalize else strength / math.pi
        row.update(kind=LIGHT_DISK if ellipse else LIGHT_RECT, size=(0.5 * ex, 0.5 * ey), Le=Le)
        spread = float(getattr(light, "spread", math.pi))
        if spread < math.pi - 1e-6:
            _unsupported(warn, "Area light spread below 180 degrees is not supported; "
                               "emitting over the full hemisphere", name)
    else:
        warn(f"Light '{name}' has unsupported type {kind}; skipped.")
        return None
    return row


def export_light(ob, matrix_world, warn, links=None) -> dict | None:
    """Row for an evaluated LIGHT object instance (None if it contributes nothing); links:
    the scene's LinkSets (export_linking.py), or None. A light without shadows is shadowed by
    no set of objects (Cycles casts no shadow ray for it)."""
    light = ob.data
    row = light_row(light, ob.name, matrix_world, getattr(ob, "visible_camera", True), warn)
    if row is not None:
        row["ray_visibility"] = ray_visibility(ob)
        receive, block = links.masks(ob) if links is not None else (None, None)
        if not getattr(light, "use_shadow", True):
            block = 0
        if receive is not None or block is not None:
            row["links"] = (LINK_ALL if receive is None else int(receive), LINK_ALL if block is None else int(block))
    return row


def ray_visibility(ob) -> int:
    """RAY_* bits of an object's Cycles ray visibility (Object.visible_*)."""
    bits = 0
    for prop, bit in (("visible_camera", RAY_CAMERA), ("visible_diffuse", RAY_DIFFUSE), ("visible_glossy", RAY_GLOSSY),
                      ("visible_transmission", RAY_TRANSMIT), ("visible_shadow", RAY_SHADOW)):
        if getattr(ob, prop, True):
            bits |= bit
    return bits
