"""The Material Output's Volume socket as one homogeneous medium (engine/volumes.py):
Volume Absorption, Volume Scatter, Principled Volume, Volume Coefficients and Emission,
added (Add Shader) and mixed (Mix Shader). Inputs are constants: a linked input is taken at
its own value, with a note (a density that varies over space needs the heterogeneous media
of a later version)."""
from __future__ import annotations

import numpy as np

from .. import volumes
from .sockets import follow_socket

_PHASES = {"HENYEY_GREENSTEIN"}


def _value(node, name, note) -> float:
    sock = node.inputs[name]
    src, out = follow_socket(sock)
    if src is not None:
        if src.bl_idname in ("ShaderNodeValue", "ShaderNodeRGB"):
            v = np.asarray(out.default_value, np.float64).ravel()
            return float(v[:3].mean())
        note(f"'{node.name}' {name} is linked (used the input's own value)")
    return float(sock.default_value)


def _color(node, name, note) -> np.ndarray:
    sock = node.inputs[name]
    src, out = follow_socket(sock)
    if src is not None:
        if src.bl_idname in ("ShaderNodeValue", "ShaderNodeRGB"):
            v = np.asarray(out.default_value, np.float64).ravel()
            return np.full(3, v[0]) if len(v) == 1 else v[:3].copy()
        note(f"'{node.name}' {name} is linked (used the input's own value)")
    return np.asarray(sock.default_value, np.float64).ravel()[:3].copy()


def _phase_g(node, note) -> float:
    phase = getattr(node, "phase", "HENYEY_GREENSTEIN")
    if phase not in _PHASES:
        note(f"'{node.name}' {phase.replace('_', '-').title()} phase (rendered as Henyey-Greenstein "
             "of the node's Anisotropy)")
    return _value(node, "Anisotropy", note)


def medium_of(socket, note):
    """The Coefficients of the shader feeding `socket` (a Volume socket), or None when
    nothing is connected; note(text) receives what is approximated."""
    node = follow_socket(socket)[0]
    if node is None:
        return None
    kind = node.bl_idname
    if kind == "ShaderNodeAddShader":
        parts = [medium_of(s, note) for s in node.inputs[:2]]
        parts = [p for p in parts if p is not None]
        return None if not parts else parts[0] if len(parts) == 1 else parts[0] + parts[1]
    if kind == "ShaderNodeMixShader":
        f = float(np.clip(_value(node, "Fac", note), 0.0, 1.0))
        a, b = medium_of(node.inputs[1], note), medium_of(node.inputs[2], note)
        parts = [m.scaled(w) for m, w in ((a, 1.0 - f), (b, f)) if m is not None]
        return None if not parts else parts[0] if len(parts) == 1 else parts[0] + parts[1]
    if kind == "ShaderNodeVolumeAbsorption":
        m = volumes.volume_absorption(_color(node, "Color", note), _value(node, "Density", note))
    elif kind == "ShaderNodeVolumeScatter":
        m = volumes.volume_scatter(_color(node, "Color", note), _value(node, "Density", note), _phase_g(node, note))
    elif kind == "ShaderNodeVolumePrincipled":
        if _value(node, "Blackbody Intensity", note) > 0:
            note(f"'{node.name}' blackbody emission (ignored)")
        m = volumes.principled_volume(_color(node, "Color", note), _value(node, "Density", note),
                                      _value(node, "Anisotropy", note), _color(node, "Absorption Color", note),
                                      _value(node, "Emission Strength", note), _color(node, "Emission Color", note))
    elif kind == "ShaderNodeVolumeCoefficients":
        m = volumes.Coefficients(np.maximum(_color(node, "Scatter Coefficients", note), 0.0),
                                 np.maximum(_color(node, "Absorption Coefficients", note), 0.0),
                                 _color(node, "Emission Coefficients", note), _phase_g(node, note))
    elif kind == "ShaderNodeEmission":
        m = volumes.Coefficients(np.zeros(3), np.zeros(3),
                                 _color(node, "Color", note) * _value(node, "Strength", note))
    else:
        note(f"volume node '{node.name}' ({kind}) is not supported (ignored)")
        return None
    return m
