"""Voronoi Texture, as Cycles computes it (kernel/svm/voronoi.h, Blender 5.0): 1D to 4D cells,
features F1, F2, Smooth F1, Distance to Edge and N-Sphere Radius, the four distance metrics,
and the fractal sum over octaves (Detail, Roughness, Lacunarity, Normalize).

Space is cut into unit cells, each holding one point at cell + hash(cell) * randomness (PCG
integer hashes of the cell for 2D to 4D, float hashes of its float32 position for 1D:
engine/nodes/hash.py). A shading point looks at the 3^d cells around its own (5^d for Smooth
F1), one offset at a time over all the points at once, in Cycles' order (x fastest) and with
its strict comparisons, so ties resolve as Cycles resolves them.

Cycles works in float32. Where that decides which cell a point is in, the coordinate is formed
as Cycles forms it, in float32 (input * scale, then * the octave's scale); from the cell on,
the arithmetic is float64, which differs from float32's only in rounding.

Vectors are tuples of components, each (N,) or 0-d (NumPy is fastest on whole contiguous
arrays), and the points go through in chunks that stay in the processor's cache.
"""
from __future__ import annotations

import functools
import itertools
import operator

import numpy as np

from . import hash as H
from . import texture_mapping
from .base import node, scalar, stack, triple

FLT_MAX = float(np.finfo(np.float32).max)
CHUNK = 32768  # points per pass: fewer passes pay less per-call overhead; larger ones leave the cache

_POINT_HASH = {2: H.hash_int2_to_float2, 3: H.hash_int3_to_float3, 4: H.hash_int4_to_float4}
_COLOR_HASH = {2: H.hash_int2_to_float3, 3: H.hash_int3_to_float3, 4: H.hash_int4_to_float3}
_AFTER_LCG = {2: H.pcg2d_after_lcg, 3: H.pcg3d_after_lcg, 4: H.pcg4d_after_lcg}


def _f32(x) -> np.ndarray:
    return np.asarray(x, np.float32)


def _as64(x) -> np.ndarray:
    """A float32 input as the float64 of the very value Cycles reads."""
    return _f32(x).astype(np.float64)


def _sum(parts):
    return functools.reduce(operator.add, parts)


def offsets(radius: int, d: int) -> list:
    """The cell offsets in [-radius, radius]^d (tuples) in Cycles' loop order: x fastest."""
    r = range(-radius, radius + 1)
    return [t[::-1] for t in itertools.product(r, repeat=d)]


class Lattice:
    """The cells around each point of float32 coordinates (a tuple of d components): the
    point's cell and its position in it, and each cell's feature point and colour as Cycles
    hashes them."""

    def __init__(self, coord32):
        cells = [np.floor(c) for c in coord32]
        self.d = len(cells)
        # exact: the cell and the coordinate are float32
        self.local = tuple(c.astype(np.float64) - k for c, k in zip(coord32, cells))
        self.cell = tuple(k.astype(np.float64) for k in cells)
        # 1D hashes the float32 cell position, 2D to 4D the integer cell.
        self._type = np.float32 if self.d == 1 else np.int32
        self._key = tuple(k.astype(self._type) for k in cells)
        # The PCG hash's first step of the point's own cell: a neighbour's adds a constant.
        self._lcg = None if self.d == 1 else tuple(H.lcg(k) for k in self._key)

    def key(self, offset=None):
        """The key of the cell at `offset` (ints, or per-point int arrays) from the point's
        (None: the point's own as it is; for 1D that keeps a -0.0 cell, which adding 0.0
        would make +0.0)."""
        if offset is None:
            return self._key
        return tuple(k + np.asarray(o, self._type) for k, o in zip(self._key, offset))

    def hash(self, key):
        """The feature point of cell `key`, relative to the cell's corner, before randomness."""
        if self.d == 1:
            return (H.hash_float(key[0]),)
        return _POINT_HASH[self.d](*key)

    def feature(self, offset, randomness):
        """The feature point of the cell at `offset` (ints), relative to the point's cell: as
        point(), from the cell's hash started at the shared first step and the unit scale
        folded into the randomness (a power of two: the same products)."""
        if self.d == 1:
            return self.point(offset, randomness)[0]
        with np.errstate(over="ignore"):
            start = tuple(s + H.lcg_step(o) for s, o in zip(self._lcg, offset))
        h = _AFTER_LCG[self.d](*start)
        unit = randomness * H.INT_UNIT
        return tuple(o + np.multiply(hc.astype(np.float32), unit, dtype=np.float64) for o, hc in zip(offset, h))

    def point(self, offset, randomness, key=None):
        """The feature point of the cell at `offset`, relative to the point's cell, and its hash."""
        h = self.hash(self.key(offset) if key is None else key)
        return tuple(o + hc * randomness for o, hc in zip(offset, h)), h

    def color(self, key, point_hash=None):
        """The cell's colour; 3D and 4D reuse the point's hash (the same numbers in Cycles)."""
        if self.d == 1:
            return H.hash_float_to_float3(key[0])
        if self.d >= 3 and point_hash is not None:
            return point_hash[:3]
        return _COLOR_HASH[self.d](*key)

    def chosen(self, table, index):
        """Per point, the offset `table[index]` (index: per-point positions in `table`)."""
        rows = np.asarray(table, np.int32)[index]
        return tuple(rows[..., a] for a in range(self.d))


def _sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def distance(v, metric: str, exponent):
    """Cycles' voronoi_distance of a difference vector v (components)."""
    if metric == "EUCLIDEAN":
        return np.sqrt(_sum(x * x for x in v))
    if metric == "MANHATTAN":
        return _sum(np.abs(x) for x in v)
    if metric == "CHEBYCHEV":
        return functools.reduce(np.maximum, (np.abs(x) for x in v))
    with np.errstate(all="ignore"):
        return np.power(_sum(np.power(np.abs(x), exponent) for x in v), 1.0 / exponent)


def distance_bound(v, metric: str, exponent):
    """Cycles' voronoi_distance_bound: ordered as the distance, without the root."""
    if metric == "EUCLIDEAN":
        return _sum(x * x for x in v)
    if metric == "MINKOWSKI":
        with np.errstate(all="ignore"):
            return _sum(np.power(np.abs(x), exponent) for x in v)
    return distance(v, metric, exponent)


def voronoi_f1(lat: Lattice, p):
    """Distance to the nearest feature point, its cell's colour, its position."""
    table = offsets(1, lat.d)
    best, winner = FLT_MAX, 0
    for n, off in enumerate(table):
        point = lat.feature(off, p.randomness)
        b = distance_bound(_sub(point, lat.local), p.metric, p.exponent)
        closer = b < best
        best, winner = np.where(closer, b, best), np.where(closer, n, winner)
    off = lat.chosen(table, winner)
    key = lat.key(off)
    point, h = lat.point(off, p.randomness, key)
    return (distance(_sub(point, lat.local), p.metric, p.exponent), lat.color(key, h),
            tuple(x + c for x, c in zip(point, lat.cell)))


def voronoi_f2(lat: Lattice, p):
    """Distance to the second nearest feature point, its cell's colour, its position."""
    table = offsets(1, lat.d)
    d1 = d2 = FLT_MAX
    n1 = n2 = table.index((0,) * lat.d)  # Cycles starts both at the zero offset
    for n, off in enumerate(table):
        point = lat.feature(off, p.randomness)
        dist = distance(_sub(point, lat.local), p.metric, p.exponent)
        first = dist < d1
        second = ~first & (dist < d2)
        d2, n2 = np.where(first, d1, np.where(second, dist, d2)), np.where(first, n1, np.where(second, n, n2))
        d1, n1 = np.where(first, dist, d1), np.where(first, n, n1)
    off = lat.chosen(table, n2)
    key = lat.key(off)
    point, h = lat.point(off, p.randomness, key)
    return d2, lat.color(key, h), tuple(x + c for x, c in zip(point, lat.cell))


def smoothstep01(x):
    """Cycles' smoothstep(0, 1, x)."""
    return np.where(x < 0.0, 0.0, np.where(x >= 1.0, 1.0, (3.0 - 2.0 * x) * (x * x)))


def voronoi_smooth_f1(lat: Lattice, p):
    """F1 blended smoothly over the 5^d neighbourhood (Quilez's smooth Voronoi): each cell in
    turn is mixed in by a smoothstep of how much nearer it is than the running blend."""
    s = np.where(p.smoothness != 0.0, p.smoothness, 1.0)  # zero smoothness is F1 (_octave)
    color_scale = 1.0 / (1.0 + 3.0 * s)
    smooth_d, smooth_c, smooth_p = 0.0, (0.0,) * 3, (0.0,) * lat.d
    for n, off in enumerate(offsets(2, lat.d)):
        key = lat.key(off)
        point, h_point = lat.point(off, p.randomness, key)
        dist = distance(_sub(point, lat.local), p.metric, p.exponent)
        if n == 0:  # Cycles' h starts at 1: the first cell is taken as it is
            smooth_d, smooth_c, smooth_p = dist, lat.color(key, h_point), point
            continue
        h = smoothstep01(0.5 + 0.5 * (smooth_d - dist) / s)
        correction = s * h * (1.0 - h)
        smooth_d = smooth_d + h * (dist - smooth_d) - correction
        correction = correction * color_scale
        smooth_c = tuple(a + h * (b - a) - correction for a, b in zip(smooth_c, lat.color(key, h_point)))
        smooth_p = tuple(a + h * (b - a) - correction for a, b in zip(smooth_p, point))
    return smooth_d, smooth_c, tuple(c + x for c, x in zip(lat.cell, smooth_p))


def voronoi_distance_to_edge(lat: Lattice, p):
    """Distance to the nearest edge of the (Euclidean) cells: the least distance to the
    bisector between the nearest point and another of the 3^d."""
    r = p.randomness
    if lat.d == 1:
        mid = lat.hash(lat.key())[0] * r
        left = -1.0 + lat.hash(lat.key((-1,)))[0] * r
        right = 1.0 + lat.hash(lat.key((1,)))[0] * r
        x = lat.local[0]
        return np.minimum(np.abs((mid + left) / 2.0 - x), np.abs((mid + right) / 2.0 - x))
    table = offsets(1, lat.d)
    best, winner = FLT_MAX, 0
    for n, off in enumerate(table):
        v = _sub(lat.point(off, r)[0], lat.local)
        dist = _sum(x * x for x in v)
        closer = dist < best
        best, winner = np.where(closer, dist, best), np.where(closer, n, winner)
    closest = _sub(lat.point(lat.chosen(table, winner), r)[0], lat.local)
    edge = FLT_MAX
    for off in table:  # the hashes again, as Cycles: cheaper than keeping 3^d vectors
        v = _sub(lat.point(off, r)[0], lat.local)
        perp = _sub(v, closest)
        length2 = _sum(x * x for x in perp)
        far = length2 > 0.0001  # not the nearest point itself
        with np.errstate(all="ignore"):
            to_edge = _sum((c + x) / 2.0 * q for c, x, q in zip(closest, v, perp)) / np.sqrt(length2)
        edge = np.where(far, np.minimum(edge, to_edge), edge)
    return edge


def voronoi_n_sphere_radius(lat: Lattice, p):
    """Half the distance from the nearest point to its own nearest point: the radius of the
    largest sphere around the nearest point that no other cell's sphere overlaps."""
    r = p.randomness
    table = offsets(1, lat.d)
    best, winner = FLT_MAX, 0
    for n, off in enumerate(table):
        dist = _sum(x * x for x in _sub(lat.point(off, r)[0], lat.local))
        closer = dist < best
        best, winner = np.where(closer, dist, best), np.where(closer, n, winner)
    closest_off = lat.chosen(table, winner)
    closest = lat.point(closest_off, r)[0]
    best, winner = FLT_MAX, 0
    for n, off in enumerate(table):
        if not any(off):
            continue
        cell_off = tuple(o + c for o, c in zip(off, closest_off))
        dist = _sum(x * x for x in _sub(closest, lat.point(cell_off, r)[0]))
        closer = dist < best
        best, winner = np.where(closer, dist, best), np.where(closer, n, winner)
    neighbour_off = tuple(o + c for o, c in zip(lat.chosen(table, winner), closest_off))
    neighbour = lat.point(neighbour_off, r)[0]
    return np.sqrt(_sum(x * x for x in _sub(neighbour, closest))) / 2.0


class Params:
    """The node's settings and inputs as Cycles clamps them (svm_node_tex_voronoi); each input
    0-d or per point (N,), float64 holding Cycles' float32 values."""

    def __init__(self, node, inputs: dict, d: int):
        self.d = d
        self.feature = node.prop("feature", "F1")
        # Cycles' 1D Voronoi measures |a - b| whatever the metric.
        self.metric = "MANHATTAN" if d == 1 else node.prop("distance", "EUCLIDEAN")
        self.normalize = bool(node.prop("normalize", False))
        self.scale = _as64(inputs["Scale"])
        self.detail = np.clip(_as64(inputs["Detail"]), 0.0, 15.0)
        self.roughness = np.clip(_as64(inputs["Roughness"]), 0.0, 1.0)
        self.lacunarity = _f32(inputs["Lacunarity"])
        self.smoothness = np.clip(_as64(inputs["Smoothness"]) / 2.0, 0.0, 0.5)
        self.exponent = _as64(inputs["Exponent"])
        self.randomness = np.clip(_as64(inputs["Randomness"]), 0.0, 1.0)
        # The distance from a cell's centre to its corner: what Normalize divides by.
        half = 0.5 + 0.5 * self.randomness
        self.max_distance = distance((half,) * d, self.metric, self.exponent) * (2.0 if self.feature == "F2" else 1.0)

    def part(self, rows: slice) -> "Params":
        """These parameters at the points `rows` (constants stay whole)."""
        out = object.__new__(Params)
        for name, value in vars(self).items():
            out.__dict__[name] = value[rows] if isinstance(value, np.ndarray) and value.ndim else value
        return out


def _octave(lat: Lattice, p: Params):
    if p.feature == "F2":
        return voronoi_f2(lat, p)
    if p.feature != "SMOOTH_F1" or not np.any(p.smoothness != 0.0):
        return voronoi_f1(lat, p)
    smooth = voronoi_smooth_f1(lat, p)
    if np.all(p.smoothness != 0.0):
        return smooth
    sharp = voronoi_f1(lat, p)
    use = p.smoothness != 0.0
    return (np.where(use, smooth[0], sharp[0]), tuple(np.where(use, a, b) for a, b in zip(smooth[1], sharp[1])),
            tuple(np.where(use, a, b) for a, b in zip(smooth[2], sharp[2])))


def _octave_count(detail) -> int:
    return int(np.ceil(np.max(detail))) + 1


def _lerp(a, b, t):
    return a + t * (b - a)


def fractal_voronoi(coord32, p: Params):
    """Octaves of the feature summed as fBM noise is, with lerps for the positions: octave i at
    coordinates * lacunarity^i weighs roughness^i; a fractional Detail fades the last one in."""
    amplitude, max_amplitude = 1.0, 0.0
    scale32 = np.float32(1.0)
    dist, color, position = 0.0, (0.0,) * 3, (0.0,) * p.d
    zero_input = (p.detail == 0.0) | (p.roughness == 0.0)
    remainder = p.detail - np.floor(p.detail)
    for i in range(_octave_count(p.detail)):  # past a point's own count, its weight t is 0
        o_dist, o_color, o_pos = _octave(Lattice(tuple(c * scale32 for c in coord32)), p)
        if i == 0:  # zero Detail or Roughness: the first octave alone, not normalised by sums
            first = (o_dist, o_color, o_pos)
        full = i <= p.detail
        fade = (i == np.ceil(p.detail)) & ~full  # the last octave of a fractional Detail
        t = np.where(full, 1.0, np.where(fade, remainder, 0.0))
        scale = scale32.astype(np.float64)
        max_amplitude = max_amplitude + t * amplitude
        dist = dist + t * o_dist * amplitude
        color = tuple(c + t * amplitude * o for c, o in zip(color, o_color))
        position = tuple(_lerp(x, _lerp(x, o / scale, amplitude), t) for x, o in zip(position, o_pos))
        # the octave's scale and amplitude advance only after full octaves
        scale32 = np.where(full, scale32 * p.lacunarity, scale32).astype(np.float32)
        amplitude = np.where(full, amplitude * p.roughness, amplitude)
    dist = np.where(zero_input, first[0], dist)
    color = tuple(np.where(zero_input, a, b) for a, b in zip(first[1], color))
    position = tuple(np.where(zero_input, a, b) for a, b in zip(first[2], position))
    max_amplitude = np.where(zero_input, 1.0, max_amplitude)
    if p.normalize:
        dist = dist / (max_amplitude * p.max_distance)
        color = tuple(c / max_amplitude for c in color)
    safe_scale = np.where(p.scale != 0.0, p.scale, 1.0)
    position = tuple(np.where(p.scale != 0.0, x / safe_scale, 0.0) for x in position)
    return dist, color, position


def fractal_voronoi_distance_to_edge(coord32, p: Params):
    """Octaves of Distance to Edge: the running minimum of each octave's distance (in the
    first octave's units) faded in by its amplitude."""
    max_distance = 0.5 + 0.5 * p.randomness
    amplitude, max_amplitude = 1.0, max_distance
    scale32 = np.float32(1.0)
    dist = 8.0
    zero_input = (p.detail == 0.0) | (p.roughness == 0.0)
    remainder = p.detail - np.floor(p.detail)
    for i in range(_octave_count(p.detail)):
        o_dist = voronoi_distance_to_edge(Lattice(tuple(c * scale32 for c in coord32)), p)
        if i == 0:
            first = o_dist
        full = i <= p.detail
        fade = (i == np.ceil(p.detail)) & ~full
        scale = scale32.astype(np.float64)
        lerp_max = _lerp(max_amplitude, max_distance / scale, amplitude)
        lerp_dist = _lerp(dist, np.minimum(dist, o_dist / scale), amplitude)
        faded_max = _lerp(max_amplitude, lerp_max, remainder)
        faded_dist = _lerp(dist, np.minimum(dist, lerp_dist), remainder)
        max_amplitude = np.where(full, lerp_max, np.where(fade, faded_max, max_amplitude))
        dist = np.where(full, lerp_dist, np.where(fade, faded_dist, dist))
        scale32 = np.where(full, scale32 * p.lacunarity, scale32).astype(np.float32)
        amplitude = np.where(full, amplitude * p.roughness, amplitude)
    dist = np.where(zero_input, first, dist)
    if p.normalize:
        dist = dist / np.where(zero_input, max_distance, max_amplitude)
    return dist


def _coordinates(node, inputs, state, d: int):
    """The float32 coordinates (d components) Cycles' kernel sees: (Vector, W) * Scale, the
    Vector being the Generated coordinate where nothing is linked (through the node's mapping)."""
    vector = texture_mapping.coordinate(node, inputs, state)
    scale = _f32(inputs["Scale"])
    w = _f32(inputs["W"]) * scale
    if d == 1:
        return (w,)
    xyz = _f32(triple(vector))
    xyz = tuple(np.ascontiguousarray(xyz[..., a]) * scale for a in range(3))
    return xyz[:d] if d < 4 else xyz + (w,)


def evaluate(coord32, p: Params):
    """The node's outputs as Cycles stores them: {output: components}."""
    with np.errstate(all="ignore"):
        if p.feature == "DISTANCE_TO_EDGE":
            return {"Distance": fractal_voronoi_distance_to_edge(coord32, p)}
        if p.feature == "N_SPHERE_RADIUS":
            return {"Radius": voronoi_n_sphere_radius(Lattice(coord32), p)}
        dist, color, position = fractal_voronoi(coord32, p)
    return {"Distance": dist, "Color": color, "Position": position}


def _in_chunks(coord32, p: Params) -> dict:
    """evaluate() over the points in chunks of CHUNK, filled into whole arrays."""
    per_point = [v for v in coord32 + tuple(vars(p).values()) if isinstance(v, np.ndarray) and v.ndim]
    n = max((len(v) for v in per_point), default=1)
    if n <= CHUNK:
        return evaluate(coord32, p)
    coord32 = tuple(np.broadcast_to(c, (n,)) for c in coord32)
    out: dict = {}
    for start in range(0, n, CHUNK):
        rows = slice(start, min(start + CHUNK, n))
        for name, value in evaluate(tuple(c[rows] for c in coord32), p.part(rows)).items():
            parts = value if isinstance(value, tuple) else (value,)
            whole = out.setdefault(name, (isinstance(value, tuple), [np.empty(n) for _ in parts]))[1]
            for target, part in zip(whole, parts):
                target[rows] = part
    return {name: tuple(arrays) if is_tuple else arrays[0] for name, (is_tuple, arrays) in out.items()}


def _split_position(position, d: int):
    """Position and W outputs from a d-dimensional position (1D: W only; 2D: z = 0)."""
    zero = np.zeros(np.shape(position[0]))
    if d == 1:
        return stack(zero, zero, zero), position[0]
    if d == 2:
        return stack(position[0], position[1], zero), zero
    return stack(*position[:3]), (position[3] if d == 4 else zero)


@node("ShaderNodeTexVoronoi", "Texture", reads=texture_mapping.unlinked_reads("generated"))
def voronoi_texture(node, inputs, state):
    """Cycles' svm_node_tex_voronoi: the outputs a feature does not compute are zero."""
    d = int(node.prop("voronoi_dimensions", "3D")[0])
    p = Params(node, inputs, d)
    out = _in_chunks(_coordinates(node, inputs, state, d), p)
    if "Position" not in out:
        return {name: scalar(value) for name, value in out.items()}
    position, w = _split_position(out["Position"], d)
    return {"Distance": scalar(out["Distance"]), "Color": stack(*out["Color"]), "Position": position,
            "W": scalar(w)}


NODES = (voronoi_texture,)
