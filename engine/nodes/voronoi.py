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
"""
from __future__ import annotations

import itertools

import numpy as np

from . import hash as H
from .base import node, scalar, stack, triple

FLT_MAX = float(np.finfo(np.float32).max)

_POINT_HASH = {2: H.hash_int2_to_float2, 3: H.hash_int3_to_float3, 4: H.hash_int4_to_float4}
_COLOR_HASH = {2: H.hash_int2_to_float3, 3: H.hash_int3_to_float3, 4: H.hash_int4_to_float3}


def _f32(x) -> np.ndarray:
    return np.asarray(x, np.float32)


def _as64(x) -> np.ndarray:
    """A float32 input as the float64 of the very value Cycles reads."""
    return _f32(x).astype(np.float64)


def offsets(radius: int, d: int) -> list:
    """The cell offsets in [-radius, radius]^d in Cycles' loop order: x varies fastest."""
    r = range(-radius, radius + 1)
    return [np.array(t[::-1], np.int32) for t in itertools.product(r, repeat=d)]


class Lattice:
    """The cells around each point of float32 coordinates (..., d): the point's cell and its
    position in it, and each cell's feature point and colour as Cycles hashes them."""

    def __init__(self, coord32: np.ndarray):
        cell = np.floor(coord32)
        self.d = coord32.shape[-1]
        self.local = coord32.astype(np.float64) - cell  # exact: cell and coordinate are float32
        self.cell = cell.astype(np.float64)
        # 1D hashes the float32 cell position, 2D to 4D the integer cell.
        self._key = cell if self.d == 1 else cell.astype(np.int32)

    def key(self, offset=None):
        """The key of the cell at `offset` from the point's (None: the point's own, as is; for
        1D that keeps a -0.0 cell, which adding 0.0 would make +0.0)."""
        if offset is None:
            return self._key
        return self._key + np.asarray(offset).astype(self._key.dtype)

    def hash(self, key) -> np.ndarray:
        """The feature point of cell `key`, relative to the cell's corner, before randomness."""
        if self.d == 1:
            return H.hash_float_to_float(key[..., 0])[..., None]
        return _POINT_HASH[self.d](*np.moveaxis(key, -1, 0))

    def color(self, key, point_hash=None) -> np.ndarray:
        """The cell's colour; 3D and 4D reuse the point's hash (the same numbers in Cycles)."""
        if self.d == 1:
            return H.hash_float_to_float3(key[..., 0])
        if self.d >= 3 and point_hash is not None:
            return point_hash[..., :3]
        return _COLOR_HASH[self.d](*np.moveaxis(key, -1, 0))


def _metric_kind(metric: str, d: int) -> str:
    # Cycles' 1D Voronoi measures |a - b| whatever the metric.
    return "MANHATTAN" if d == 1 else metric


def distance(v, metric: str, exponent) -> np.ndarray:
    """Cycles' voronoi_distance of a difference vector v (..., d)."""
    if metric == "EUCLIDEAN":
        return np.sqrt(np.sum(v * v, axis=-1))
    if metric == "MANHATTAN":
        return np.sum(np.abs(v), axis=-1)
    if metric == "CHEBYCHEV":
        return np.max(np.abs(v), axis=-1)
    with np.errstate(all="ignore"):
        return np.power(np.sum(np.power(np.abs(v), exponent[..., None]), axis=-1), 1.0 / exponent)


def distance_bound(v, metric: str, exponent) -> np.ndarray:
    """Cycles' voronoi_distance_bound: ordered as the distance, without the root."""
    if metric == "EUCLIDEAN":
        return np.sum(v * v, axis=-1)
    if metric == "MINKOWSKI":
        with np.errstate(all="ignore"):
            return np.sum(np.power(np.abs(v), exponent[..., None]), axis=-1)
    return distance(v, metric, exponent)


def _where(mask, a, b):
    return np.where(mask[..., None] if np.ndim(a) > np.ndim(mask) or np.ndim(b) > np.ndim(mask) else mask, a, b)


def voronoi_f1(lat: Lattice, p):
    """Distance to the nearest feature point, its cell's colour, its position."""
    best = np.full(lat.local.shape[:-1], FLT_MAX)
    target_pos = np.zeros_like(lat.local)
    target_key = lat.key(np.zeros(lat.d, np.int32))
    for off in offsets(1, lat.d):
        key = lat.key(off)
        point = off + lat.hash(key) * p.randomness[..., None]
        b = distance_bound(point - lat.local, p.metric, p.exponent)
        closer = b < best
        best = np.where(closer, b, best)
        target_pos = _where(closer, point, target_pos)
        target_key = _where(closer, key, target_key)
    return (distance(target_pos - lat.local, p.metric, p.exponent), lat.color(target_key),
            target_pos + lat.cell)


def voronoi_f2(lat: Lattice, p):
    """Distance to the second nearest feature point, its cell's colour, its position."""
    shape = lat.local.shape[:-1]
    d1, d2 = np.full(shape, FLT_MAX), np.full(shape, FLT_MAX)
    zero = lat.key(np.zeros(lat.d, np.int32))
    key1, key2 = zero, zero
    pos1, pos2 = np.zeros_like(lat.local), np.zeros_like(lat.local)
    for off in offsets(1, lat.d):
        key = lat.key(off)
        point = off + lat.hash(key) * p.randomness[..., None]
        dist = distance(point - lat.local, p.metric, p.exponent)
        first = dist < d1
        second = ~first & (dist < d2)
        d2 = np.where(first, d1, np.where(second, dist, d2))
        key2 = _where(first, key1, _where(second, key, key2))
        pos2 = _where(first, pos1, _where(second, point, pos2))
        d1 = np.where(first, dist, d1)
        key1 = _where(first, key, key1)
        pos1 = _where(first, point, pos1)
    return d2, lat.color(key2), pos2 + lat.cell


def smoothstep01(x):
    """Cycles' smoothstep(0, 1, x)."""
    return np.where(x < 0.0, 0.0, np.where(x >= 1.0, 1.0, (3.0 - 2.0 * x) * (x * x)))


def voronoi_smooth_f1(lat: Lattice, p):
    """F1 blended smoothly over the 5^d neighbourhood (Quilez's smooth Voronoi): each cell in
    turn is mixed in by a smoothstep of how much nearer it is than the running blend."""
    s = np.where(p.smoothness != 0.0, p.smoothness, 1.0)  # zero smoothness is F1 (below)
    smooth_d = np.zeros(lat.local.shape[:-1])
    smooth_c = np.zeros(lat.local.shape[:-1] + (3,))
    smooth_p = np.zeros_like(lat.local)
    for n, off in enumerate(offsets(2, lat.d)):
        key = lat.key(off)
        h_point = lat.hash(key)
        point = off + h_point * p.randomness[..., None]
        dist = distance(point - lat.local, p.metric, p.exponent)
        h = 1.0 if n == 0 else smoothstep01(0.5 + 0.5 * (smooth_d - dist) / s)
        correction = s * h * (1.0 - h)
        smooth_d = smooth_d + h * (dist - smooth_d) - correction
        correction = (correction / (1.0 + 3.0 * s))[..., None]
        h = np.asarray(h)[..., None]
        smooth_c = smooth_c + h * (lat.color(key, h_point) - smooth_c) - correction
        smooth_p = smooth_p + h * (point - smooth_p) - correction
    return smooth_d, smooth_c, lat.cell + smooth_p


def voronoi_distance_to_edge(lat: Lattice, p):
    """Distance to the nearest edge of the (Euclidean) cells: the least distance to the
    bisector between the nearest point and another of the 3^d."""
    if lat.d == 1:
        r = p.randomness
        mid = lat.hash(lat.key())[..., 0] * r
        left = -1.0 + lat.hash(lat.key(-np.ones(1, np.int32)))[..., 0] * r
        right = 1.0 + lat.hash(lat.key(np.ones(1, np.int32)))[..., 0] * r
        x = lat.local[..., 0]
        return np.minimum(np.abs((mid + left) / 2.0 - x), np.abs((mid + right) / 2.0 - x))
    vectors = []
    best = np.full(lat.local.shape[:-1], FLT_MAX)
    closest = np.zeros_like(lat.local)
    for off in offsets(1, lat.d):
        v = off + lat.hash(lat.key(off)) * p.randomness[..., None] - lat.local
        vectors.append(v)
        dist = np.sum(v * v, axis=-1)
        closer = dist < best
        best = np.where(closer, dist, best)
        closest = _where(closer, v, closest)
    edge = np.full(lat.local.shape[:-1], FLT_MAX)
    for v in vectors:
        perp = v - closest
        length2 = np.sum(perp * perp, axis=-1)
        far = length2 > 0.0001  # not the nearest point itself
        with np.errstate(all="ignore"):
            to_edge = np.sum((closest + v) / 2.0 * perp, axis=-1) / np.sqrt(length2)
        edge = np.where(far, np.minimum(edge, to_edge), edge)
    return edge


def voronoi_n_sphere_radius(lat: Lattice, p):
    """Half the distance from the nearest point to its own nearest point: the radius of the
    largest sphere around the nearest point that no other cell's sphere overlaps."""
    best = np.full(lat.local.shape[:-1], FLT_MAX)
    closest = np.zeros_like(lat.local)
    closest_off = np.zeros(lat.local.shape, np.int32)
    for off in offsets(1, lat.d):
        point = off + lat.hash(lat.key(off)) * p.randomness[..., None]
        dist = np.sum((point - lat.local) ** 2, axis=-1)
        closer = dist < best
        best = np.where(closer, dist, best)
        closest = _where(closer, point, closest)
        closest_off = _where(closer, off, closest_off)
    best = np.full(lat.local.shape[:-1], FLT_MAX)
    neighbour = np.zeros_like(lat.local)
    for off in offsets(1, lat.d):
        if not off.any():
            continue
        cell_off = off + closest_off
        point = cell_off + lat.hash(lat.key(cell_off)) * p.randomness[..., None]
        dist = np.sum((closest - point) ** 2, axis=-1)
        closer = dist < best
        best = np.where(closer, dist, best)
        neighbour = _where(closer, point, neighbour)
    return np.sqrt(np.sum((neighbour - closest) ** 2, axis=-1)) / 2.0


class Params:
    """The node's settings and inputs as Cycles clamps them (svm_node_tex_voronoi); each input
    0-d or per point (N,), float64 holding Cycles' float32 values."""

    def __init__(self, node, inputs, d: int):
        self.feature = node.prop("feature", "F1")
        self.metric = _metric_kind(node.prop("distance", "EUCLIDEAN"), d)
        self.normalize = bool(node.prop("normalize", False))
        self.scale32 = _f32(inputs["Scale"])
        self.scale = self.scale32.astype(np.float64)
        self.detail = np.clip(_as64(inputs["Detail"]), 0.0, 15.0)
        self.roughness = np.clip(_as64(inputs["Roughness"]), 0.0, 1.0)
        self.lacunarity = _f32(inputs["Lacunarity"])
        self.smoothness = np.clip(_as64(inputs["Smoothness"]) / 2.0, 0.0, 0.5)
        self.exponent = _as64(inputs["Exponent"])
        self.randomness = np.clip(_as64(inputs["Randomness"]), 0.0, 1.0)
        # The distance from a cell's centre to its corner: what Normalize divides by.
        half = np.full(np.shape(self.randomness) + (d,), 1.0) * (0.5 + 0.5 * self.randomness)[..., None]
        self.max_distance = distance(half, self.metric, self.exponent) * (2.0 if self.feature == "F2" else 1.0)


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
    return tuple(_where(use, a, b) for a, b in zip(smooth, sharp))


def _octave_count(detail) -> int:
    return int(np.ceil(np.max(detail))) + 1


def fractal_voronoi(coord32, p: Params):
    """Octaves of the feature summed as fBM noise is, with lerps for the positions: octave i at
    coordinates * lacunarity^i weighs roughness^i; a fractional Detail fades the last one in."""
    amplitude = np.float64(1.0)
    max_amplitude = np.float64(0.0)
    scale32 = np.ones_like(p.lacunarity)
    shape = np.broadcast_shapes(coord32.shape, np.shape(p.detail) + (1,), np.shape(p.lacunarity) + (1,))
    dist, color, position = np.zeros(shape[:-1]), np.zeros(shape[:-1] + (3,)), np.zeros(shape)
    zero_input = (p.detail == 0.0) | (p.roughness == 0.0)
    remainder = p.detail - np.floor(p.detail)
    for i in range(_octave_count(p.detail)):  # past a point's own count, its weight t is 0
        o_dist, o_color, o_pos = _octave(Lattice(coord32 * scale32[..., None]), p)
        if i == 0:  # zero Detail or Roughness: the first octave alone, not normalised by sums
            first = (o_dist, o_color, o_pos)
        full = i <= p.detail
        fade = (i == np.ceil(p.detail)) & ~full  # the last octave of a fractional Detail
        scale = scale32.astype(np.float64)
        a_c = np.asarray(amplitude)[..., None]
        blended_pos = position + a_c * (o_pos / scale[..., None] - position)
        t = np.where(full, 1.0, np.where(fade, remainder, 0.0))
        t_c = t[..., None]
        max_amplitude = max_amplitude + t * amplitude
        dist = dist + t * o_dist * amplitude
        color = color + t_c * a_c * o_color
        position = position + t_c * (blended_pos - position)
        # the octave's scale and amplitude advance only after full octaves
        scale32 = np.where(full, scale32 * p.lacunarity, scale32).astype(np.float32)
        amplitude = np.where(full, amplitude * p.roughness, amplitude)
    dist = np.where(zero_input, first[0], dist)
    color = _where(zero_input, first[1], color)
    position = _where(zero_input, first[2], position)
    max_amplitude = np.where(zero_input, 1.0, max_amplitude)
    if p.normalize:
        with np.errstate(all="ignore"):
            dist = dist / (max_amplitude * p.max_distance)
            color = color / max_amplitude[..., None]
    safe_scale = np.where(p.scale != 0.0, p.scale, 1.0)[..., None]
    position = np.where(p.scale[..., None] != 0.0, position / safe_scale, 0.0)
    return dist, color, position


def fractal_voronoi_distance_to_edge(coord32, p: Params):
    """Octaves of Distance to Edge: the running minimum of each octave's distance (in the
    first octave's units) faded in by its amplitude."""
    max_distance = 0.5 + 0.5 * p.randomness
    amplitude = np.float64(1.0)
    max_amplitude = max_distance
    scale32 = np.ones_like(p.lacunarity)
    dist = np.float64(8.0)
    zero_input = (p.detail == 0.0) | (p.roughness == 0.0)
    remainder = p.detail - np.floor(p.detail)
    for i in range(_octave_count(p.detail)):
        o_dist = voronoi_distance_to_edge(Lattice(coord32 * scale32[..., None]), p)
        if i == 0:
            first = o_dist
        full = i <= p.detail
        fade = (i == np.ceil(p.detail)) & ~full  # the last octave of a fractional Detail
        scale = scale32.astype(np.float64)
        lerp_max = max_amplitude + amplitude * (max_distance / scale - max_amplitude)
        lerp_dist = dist + amplitude * (np.minimum(dist, o_dist / scale) - dist)
        faded_max = max_amplitude + remainder * (lerp_max - max_amplitude)
        faded_dist = dist + remainder * (np.minimum(dist, lerp_dist) - dist)
        max_amplitude = np.where(full, lerp_max, np.where(fade, faded_max, max_amplitude))
        dist = np.where(full, lerp_dist, np.where(fade, faded_dist, dist))
        scale32 = np.where(full, scale32 * p.lacunarity, scale32).astype(np.float32)
        amplitude = np.where(full, amplitude * p.roughness, amplitude)
    dist = np.where(zero_input, first, dist)
    if p.normalize:
        with np.errstate(all="ignore"):
            dist = dist / np.where(zero_input, max_distance, max_amplitude)
    return dist


def _coordinates(node, inputs, state, d: int) -> np.ndarray:
    """The float32 coordinates (..., d) Cycles' kernel sees: (Vector, W) * Scale, the Vector
    being the Generated coordinate where nothing is linked."""
    vector_input = node.input("Vector")
    vector = state.generated if vector_input is not None and vector_input.link is None else inputs["Vector"]
    scale = _f32(inputs["Scale"])
    w = _f32(inputs["W"]) * scale
    xyz = _f32(triple(vector)) * scale[..., None]
    if d == 1:
        return w[..., None]
    if d == 4:
        lead = np.broadcast_shapes(xyz.shape[:-1], w.shape)
        return np.concatenate([np.broadcast_to(xyz, lead + (3,)), np.broadcast_to(w, lead)[..., None]], axis=-1)
    return xyz[..., :d]


def _split_position(position, d: int):
    """Position and W outputs from a d-dimensional position (1D: W only; 2D: z = 0)."""
    zero = np.zeros(position.shape[:-1])
    if d == 1:
        return stack(zero, zero, zero), position[..., 0]
    if d == 2:
        return stack(position[..., 0], position[..., 1], zero), zero
    return position[..., :3], (position[..., 3] if d == 4 else zero)


@node("ShaderNodeTexVoronoi", "Texture", reads=("generated",))
def voronoi_texture(node, inputs, state):
    """Cycles' svm_node_tex_voronoi: the outputs a feature does not compute are zero."""
    d = int(node.prop("voronoi_dimensions", "3D")[0])
    p = Params(node, inputs, d)
    coord32 = _coordinates(node, inputs, state, d)
    if p.feature == "DISTANCE_TO_EDGE":
        with np.errstate(all="ignore"):
            return {"Distance": scalar(fractal_voronoi_distance_to_edge(coord32, p))}
    if p.feature == "N_SPHERE_RADIUS":
        return {"Radius": scalar(voronoi_n_sphere_radius(Lattice(coord32), p))}
    with np.errstate(all="ignore"):
        dist, color, position = fractal_voronoi(coord32, p)
    position, w = _split_position(position, d)
    return {"Distance": scalar(dist), "Color": color, "Position": position, "W": scalar(w)}


NODES = (voronoi_texture,)
