"""IES Texture: a light's intensity by direction from a photometric profile (IES LM-63 file),
as Cycles reads it (util/ies.cpp IESFile: parse and process; kernel/util/ies.h
kernel_ies_interp; svm/ies.h svm_node_ies).

The profile (the node's `ies` prop: the file's text, exported from the node's Text datablock
or its external file) is parsed once: the TILT block skipped, the header's candela multiplier
x ballast factor x ballast-lamp photometric factor x 4 pi / 177.83 (Cycles' candela-to-watt
factor, D65's luminous efficacy) scales the candela values. Photometric types C and B are
processed as Cycles does into a table over horizontal angles 0..360 degrees (mirrored from one
quadrant or half, the 360 degree column added) and vertical angles from 0 or 90 degrees, in
float32 radians; type A, or a table Cycles cannot process, is no profile: Cycles then gives
100 everywhere (its missing-profile value), and so does Ember, with a note.

Fac = Strength x the table at (h, v) of the normalised Vector: v = acos(-z) (0 straight down
the light's -z), h = atan2(x, y) + pi; 0 outside the table's angles; Catmull-Rom
interpolation in v, then in h (wrapping where the table covers a full turn or reaches a pole,
else repeating the end values as Cycles does), negative results 0. The unlinked Vector is
Texture Coordinate's Normal: the shading normal in object space (on a light, the direction
from the light toward the receiver, in the light's frame).
"""
from __future__ import annotations

import re
from functools import lru_cache

import numpy as np

from .base import components, node, scalar, triple
from .vector_math import safe_normalize, transform_direction_transposed

F32 = np.float32
CANDELA_TO_WATT = 0.0706650768394  # 4 pi / 177.83 (util/ies.cpp)
MISSING = 100.0  # kernel_ies_interp without a profile
TYPE_A, TYPE_B, TYPE_C = 3, 2, 1
_DOUBLE = re.compile(r"\s*([+-]?(?:\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?))")
_LONG = re.compile(r"\s*([+-]?\d+)")


class _Parser:
    """IESTextParser: strtod / strtol over the text after the TILT line, commas as spaces."""

    def __init__(self, text: str, pos: int):
        self.text, self.pos, self.error = text, pos, False

    def _get(self, pattern, kind):
        m = pattern.match(self.text, self.pos) if self.pos is not None else None
        if m is None:
            self.error, self.pos = True, None
            return kind(0)
        self.pos = m.end()
        return kind(m.group(1))

    def double(self) -> float:
        return self._get(_DOUBLE, float)

    def long(self) -> int:
        return self._get(_LONG, int)


def parse(text: str):
    """IESFile::parse: (type, v_angles, h_angles (degrees, float32), intensity (h, v) float32
    watts per steradian), or None where Cycles' parser fails."""
    if not text:
        return None
    text = text.replace(",", " ")
    at = text.find("\nTILT=")
    if at < 0:
        return None
    if text.startswith("\nTILT=INCLUDE", at):
        p = _Parser(text, at + 13)
        p.double()  # lamp to luminaire geometry
        for _ in range(2 * p.long()):  # tilt angles and factors
            p.double()
        pos = p.pos
        if p.error:
            return None
    else:
        pos = text.find("\n", at + 1)
        if pos < 0:
            return None
    p = _Parser(text, pos + 1)
    p.long()  # number of lamps
    p.double()  # lumens per lamp
    factor = p.double()  # candela multiplier
    v_num, h_num, kind = p.long(), p.long(), p.long()
    if kind not in (TYPE_B, TYPE_C):
        return None
    p.long()  # units
    p.double(), p.double(), p.double()  # width, length, height
    factor *= p.double()  # ballast factor
    factor *= p.double()  # ballast-lamp photometric factor
    p.double()  # input watts
    factor *= CANDELA_TO_WATT
    if v_num < 0 or h_num < 0:
        return None
    v = np.array([p.double() for _ in range(v_num)], F32)
    h = np.array([p.double() for _ in range(h_num)], F32)
    values = np.array([[F32(factor * p.double()) for _ in range(v_num)] for _ in range(h_num)], F32)
    if p.error:
        return None
    return kind, v, h, values.reshape(h_num, v_num)


def _process_type_b(v, h, intensity):
    """IESFile::process_type_b: the table transposed (B's horizontal angles are C's vertical
    ones), both axes shifted or mirrored to 0..180 (vertical) and 0..360 (horizontal)."""
    intensity = [list(row) for row in np.asarray(intensity).T]
    h, v = list(v), list(h)
    if h[-1] != F32(90.0):
        return None
    if h[0] == 0.0:
        n = len(h)
        h = [F32(90.0) - h[i] for i in range(n - 1, 0, -1)] + [F32(90.0) + h[i] for i in range(n)]
        intensity = [intensity[i] for i in range(n - 1, 0, -1)] + intensity
    elif h[0] == F32(-90.0):
        h = [x + F32(90.0) for x in h]
    h.append(F32(360.0))
    intensity.append(intensity[0])
    if v[-1] != F32(90.0):
        return None
    if v[0] == 0.0:
        n = len(v)
        v = [F32(90.0) - v[i] for i in range(n - 1, 0, -1)] + [F32(90.0) + v[i] for i in range(n)]
        intensity = [row[n - 2::-1] + row for row in intensity]
    elif v[0] == F32(-90.0):
        v = [x + F32(90.0) for x in v]
    return v, h, intensity


def _process_type_c(v, h, intensity):
    """IESFile::process_type_c: horizontal angles rotated from 90..270, mirrored from one
    quadrant or half to the full turn, the 360 degree column added; vertical from 0 or 90."""
    h, v, intensity = list(h), list(v), [list(row) for row in np.asarray(intensity)]
    if h[0] == F32(90.0):
        h = [x - F32(90.0) for x in h]
    if h[0] != 0.0:
        return None
    if len(h) == 1:
        h.append(F32(360.0))
        intensity.append(intensity[0])
    if h[-1] == F32(90.0):
        n = len(h)
        for i in range(n - 2, -1, -1):
            h.append(F32(180.0) - h[i])
            intensity.append(intensity[i])
    if h[-1] == F32(180.0):
        n = len(h)
        for i in range(n - 2, -1, -1):
            h.append(F32(360.0) - h[i])
            intensity.append(intensity[i])
    if h[-1] != F32(360.0):
        last, first, gap = F32(h[-1] - h[-2]), F32(h[1] - h[0]), F32(F32(360.0) - h[-1])
        if last == gap or first == gap:
            h.append(F32(360.0))
            intensity.append(intensity[0])
        else:
            return None
    if v[0] == F32(90.0):
        if v[-1] != F32(180.0):
            return None
    elif v[0] != 0.0:
        return None
    return v, h, intensity


@lru_cache(maxsize=16)
def profile(text: str):
    """IESFile::load: (h_angles (H,), v_angles (V,) float32 radians, intensity (H, V) float32),
    or None (Cycles' missing profile)."""
    parsed = parse(text)
    if parsed is None:
        return None
    kind, v, h, intensity = parsed
    if len(h) == 0 or len(v) == 0:
        return None
    done = (_process_type_b if kind == TYPE_B else _process_type_c)(v, h, intensity)
    if done is None:
        return None
    v, h, intensity = done
    to_rad = F32(np.pi) / F32(180.0)
    h = np.array(h, F32) * to_rad
    v = np.array(v, F32) * to_rad
    table = np.array(intensity, F32).reshape(len(h), len(v))
    for a in (h, v, table):
        a.setflags(write=False)
    return h, v, table


def cubic(a, b, c, d, x):
    """Cycles' cubic_interp: Catmull-Rom between b and c."""
    return 0.5 * (((d + 3.0 * (b - c) - a) * x + (2.0 * a - 5.0 * b + 4.0 * c - d)) * x + (c - a)) * x + b


def interpolate(table, h_angle, v_angle) -> np.ndarray:
    """kernel_ies_interp at angles (N,) (radians) of a profile (h, v, intensity)."""
    H, V, I = (np.asarray(x, np.float64) for x in table)
    h_num, v_num = len(H), len(V)
    h_angle, v_angle = np.asarray(h_angle, np.float64), np.asarray(v_angle, np.float64)
    inside = (v_angle >= V[0]) & (v_angle < V[-1]) & (h_angle >= H[0]) & (h_angle < H[-1])
    if h_num < 2 or v_num < 2:
        return np.zeros(np.shape(h_angle))
    wrap_h = H[0] < 1e-7 and H[-1] > float(F32(2.0 * np.pi)) - 1e-7
    wrap_vlow, wrap_vhigh = V[0] < 1e-7, V[-1] > float(F32(np.pi)) - 1e-7
    hi = np.clip(np.searchsorted(H, h_angle, side="left") - 1, 0, h_num - 2)
    vi = np.clip(np.searchsorted(V, v_angle, side="left") - 1, 0, v_num - 2)
    with np.errstate(all="ignore"):
        h_frac = (h_angle - H[hi]) / (H[hi + 1] - H[hi])
        v_frac = (v_angle - V[vi]) / (V[vi + 1] - V[vi])

    def vertical(h):
        """interpolate_ies_vertical along column(s) h (N,): the ends wrap at the poles."""
        b, c = I[h, vi], I[h, vi + 1]
        a = np.where(vi > 0, I[h, np.maximum(vi - 1, 0)], I[h, 1] if wrap_vlow else b)
        d = np.where(vi + 2 < v_num, I[h, np.minimum(vi + 2, v_num - 1)], I[h, v_num - 2] if wrap_vhigh else c)
        return cubic(a, b, c, d, v_frac)

    b, c = vertical(hi), vertical(hi + 1)
    a = np.where(hi > 0, vertical(np.maximum(hi - 1, 0)), vertical(np.full_like(hi, h_num - 2)) if wrap_h else b)
    d = np.where(hi + 2 < h_num, vertical(np.minimum(hi + 2, h_num - 1)),
                 vertical(np.full_like(hi, 1)) if wrap_h else b)  # b, not c: Cycles' fallback
    out = np.maximum(cubic(a, b, c, d, h_frac), 0.0)
    return np.where(inside, np.nan_to_num(out), 0.0)


def _reads(node, outputs):
    socket = node.input("Vector")
    return () if socket is not None and socket.link is not None else ("N", "world_from_object")


def _notes(node) -> list:
    return [] if profile(node.prop("ies") or "") is not None else \
        ["no IES profile Cycles can read (missing, or photometric type A): 100 in every direction, as Cycles"]


@node("ShaderNodeTexIES", "Texture", reads=_reads, notes=_notes)
def ies_texture(node, inputs, state):
    socket = node.input("Vector")
    if socket is not None and socket.link is not None:
        vector = triple(inputs["Vector"])
    else:  # Texture Coordinate's Normal: N in object space
        vector = transform_direction_transposed(state.world_from_object, state.N)
    strength = scalar(inputs["Strength"])
    table = profile(node.prop("ies") or "")
    if table is None:
        return {"Fac": strength * MISSING}
    with np.errstate(all="ignore"):
        x, y, z = components(safe_normalize(vector))
    v_angle = np.arccos(np.clip(-z, -1.0, 1.0))
    h_angle = np.arctan2(x, y) + np.pi
    fac = interpolate(table, np.ravel(h_angle), np.ravel(v_angle)).reshape(np.shape(h_angle))
    return {"Fac": strength * fac}


NODES = (ies_texture,)
