"""The procedural textures of Cycles' noise family and the simple patterns: Noise, White Noise,
Gradient, Checker, Magic, Wave and Brick (svm/noisetex.h, white_noise.h, gradient.h,
checker.h, magic.h, wave.h, brick.h).

A texture whose Vector is unlinked reads the Generated coordinate (Cycles' LINK_TEXTURE_
GENERATED), except White Noise, whose unlinked Vector is its socket value (Cycles gives that
socket no default link); the vector then goes through the node's texture mapping
(texture_mapping.py). A texture whose Vector is linked reads nothing of the shading state, so
one fed constants is folded at compile time. Coordinates are scaled in float32 as Cycles does, so the float32 roundings that
decide a cell (a floor, an integer cast) are the kernel's; what follows a cell decision is
float64, except Magic, whose folds amplify rounding and follow the kernel's float32 steps.
"""
from __future__ import annotations

import numpy as np

from . import texture_mapping
from .base import components, node, scalar, stack, triple
from .hash import hash_float, hash_float_to_float3
from .noise import F32, fractal, offset, snoise

_GENERATED = texture_mapping.unlinked_reads("generated")
_DIMENSIONS = {"1D": 1, "2D": 2, "3D": 3, "4D": 4}
_2PI = float(F32(2.0 * np.pi))  # M_2PI_F
_PI_2 = float(F32(0.5 * np.pi))  # M_PI_2_F


def f32(x) -> np.ndarray:
    return np.asarray(x).astype(F32)


def _broadcast(coords, *params):
    """The coordinates broadcast to the shape of all the per-point values among them and
    `params` (a constant node with one per-point parameter evaluates per point)."""
    shape = np.broadcast_shapes(*(np.shape(c) for c in coords), *(np.shape(p) for p in params))
    return tuple(np.broadcast_to(c, shape) for c in coords)


def _memo(fn):
    """fn() computed once, on first call (an output shared by lazily read outputs)."""
    cache = []

    def once():
        if not cache:
            cache.append(fn())
        return cache[0]
    return once


# --- Noise Texture --------------------------------------------------------------------------

def _seed_offset(dimensions: int, seed: float) -> tuple:
    """random_float{,2,3,4}_offset: per-axis float32 offsets in [100, 200] from a seed, which
    give the distortion and colour channels their own copies of the noise."""
    if dimensions == 1:
        hashes = (hash_float(seed),)
    else:
        hashes = tuple(hash_float(seed, float(k)) for k in range(dimensions))
    return tuple(F32(100.0) + F32(h) * F32(100.0) for h in hashes)


# Per dimension: seeds 0..d-1 offset the distortion of each axis, seeds d and d+1 the colour's
# green and blue channels (1D distorts with seed 0 only).
_SEEDS = {d: tuple(_seed_offset(d, float(s)) for s in range(d + 2)) for d in range(1, 5)}


@node("ShaderNodeTexNoise", "Texture", reads=_GENERATED)
def noise_texture(node, inputs, state):
    """svm_node_tex_noise: detail clamped to [0, 15], roughness to >= 0; the point (and W)
    scaled, distorted by snoise at seed offsets, then the fractal; the colour's green and blue
    are the fractal at two more seed offsets."""
    dimensions = _DIMENSIONS[node.prop("noise_dimensions", "3D")]
    kind = node.prop("noise_type", "FBM")
    normalize = bool(node.prop("normalize", True))
    scale = f32(inputs["Scale"])
    detail = np.clip(scalar(inputs["Detail"]), 0.0, 15.0)
    roughness = np.maximum(scalar(inputs["Roughness"]), 0.0)
    lacunarity, offset_, gain, distortion = (scalar(inputs[k]) for k in ("Lacunarity", "Offset", "Gain", "Distortion"))
    coords = []
    if dimensions >= 2:
        coords = list(components(texture_mapping.coordinate(node, inputs, state)))[:min(dimensions, 3)]
    if dimensions in (1, 4):
        coords.append(scalar(inputs["W"]))
    coords = _broadcast(tuple(f32(c) * scale for c in coords), detail, roughness, lacunarity, offset_, gain, distortion)
    seeds = _SEEDS[dimensions]
    if np.any(distortion != 0.0):
        shifts = _together(snoise, [offset(coords, seeds[k]) for k in range(len(coords))], ())
        coords = tuple(c + (n * distortion).astype(F32) for c, n in zip(coords, shifts))
    params = (detail, roughness, lacunarity, offset_, gain)

    def channels(shifts):
        sets = [coords if shift is None else offset(coords, shift) for shift in shifts]
        return _together(lambda p, *q: fractal(kind, p, *q, normalize), sets, params)

    known = []  # Fac, once computed (alone, or with the colour's other channels)
    colour_seeds = (seeds[dimensions], seeds[dimensions + 1])

    def fac():
        if not known:
            known.append(channels([None])[0])
        return known[0]

    def color():
        if known:
            return stack(known[0], *channels(colour_seeds))
        first, green, blue = channels((None,) + colour_seeds)
        known.append(first)
        return stack(first, green, blue)

    return {"Fac": fac, "Color": color}


def _together(fn, sets, params):
    """[fn(coords, *params) for coords in sets], in one call over all the sets' points: the
    NumPy calls of a noise evaluation cost as much for a batch of a thousand points as for
    three, and a Noise node's channels and distortion lookups are such batches. Per-point
    params are repeated for each set; every point's value is what its own call gives."""
    if len(sets) == 1 or np.ndim(sets[0][0]) != 1:
        return [fn(coords, *params) for coords in sets]
    joined = tuple(np.concatenate(axis) for axis in zip(*sets))
    tiled = tuple(np.tile(p, len(sets)) if np.ndim(p) == 1 else p for p in params)
    return np.split(fn(joined, *tiled), len(sets))


# --- White Noise ----------------------------------------------------------------------------

@node("ShaderNodeTexWhiteNoise", "Texture")
def white_noise_texture(node, inputs, state):
    """Hashes of the coordinate's float32 bits (svm/white_noise.h): equal inputs, equal noise."""
    dimensions = _DIMENSIONS[node.prop("noise_dimensions", "3D")]
    x, y, z = components(triple(inputs["Vector"]))
    w = scalar(inputs["W"])
    keys = {1: (w,), 2: (x, y), 3: (x, y, z), 4: (x, y, z, w)}[dimensions]
    return {"Value": lambda: hash_float(*keys), "Color": lambda: stack(*hash_float_to_float3(*keys))}


# --- Gradient -------------------------------------------------------------------------------

def gradient(kind: str, x, y, z):
    """svm_gradient, before the clamp to [0, 1]."""
    if kind == "LINEAR":
        return x
    if kind == "QUADRATIC":
        r = np.maximum(x, 0.0)
        return r * r
    if kind == "EASING":
        r = np.clip(x, 0.0, 1.0)
        t = r * r
        return 3.0 * t - 2.0 * t * r
    if kind == "DIAGONAL":
        return (x + y) * 0.5
    if kind == "RADIAL":
        return np.arctan2(y, x) / _2PI + 0.5
    # 0.999999: a unit vector gives exactly 0 (Cycles' bias against float noise).
    r = np.maximum(0.999999 - np.sqrt(x * x + y * y + z * z), 0.0)
    if kind == "QUADRATIC_SPHERE":
        return r * r
    if kind == "SPHERICAL":
        return r
    return np.zeros_like(x)


@node("ShaderNodeTexGradient", "Texture", reads=_GENERATED)
def gradient_texture(node, inputs, state):
    x, y, z = components(texture_mapping.coordinate(node, inputs, state).astype(F32).astype(np.float64))
    fac = _memo(lambda: np.clip(gradient(node.prop("gradient_type", "LINEAR"), x, y, z), 0.0, 1.0))
    return {"Fac": fac, "Color": lambda: stack(fac(), fac(), fac())}


# --- Checker --------------------------------------------------------------------------------

def checker(x, y, z):
    """svm_checker on float32 coordinates: 1 where the parities of the cells agree, else 0;
    the nudge (p + 1e-6) * 0.999999 keeps unit coordinates off cell edges."""
    parity = []
    for c in (x, y, z):
        c = (c + F32(0.000001)) * F32(0.999999)
        parity.append(np.abs(np.floor(c).astype(np.int64)) % 2)
    return ((parity[0] == parity[1]) == (parity[2] == 1)).astype(np.float64)


@node("ShaderNodeTexChecker", "Texture", reads=_GENERATED)
def checker_texture(node, inputs, state):
    scale = f32(inputs["Scale"])
    x, y, z = (c * scale for c in components(f32(texture_mapping.coordinate(node, inputs, state))))
    fac = _memo(lambda: checker(x, y, z))
    color = lambda: np.where(fac()[..., None] == 1.0, triple(inputs["Color1"]), triple(inputs["Color2"]))  # noqa: E731
    return {"Fac": fac, "Color": color}


# --- Magic ----------------------------------------------------------------------------------

def _sinf(x):
    """sinf of float32 x: the float64 sine rounded to float32 (a correctly rounded sinf)."""
    return np.sin(x.astype(np.float64)).astype(F32)


def _cosf(x):
    return np.cos(x.astype(np.float64)).astype(F32)


# svm_magic's folding steps after the first, in order: (which of x, y, z it sets, from what).
_MAGIC_STEPS = ((0, lambda x, y, z: _cosf(x - y - z)),
                (2, lambda x, y, z: _sinf(-x - y - z)),
                (0, lambda x, y, z: -_cosf(-x + y - z)),
                (1, lambda x, y, z: -_sinf(-x + y + z)),
                (1, lambda x, y, z: -_cosf(-x + y + z)),
                (0, lambda x, y, z: _cosf(x + y + z)),
                (2, lambda x, y, z: _sinf(x + y - z)),
                (0, lambda x, y, z: -_cosf(-x - y + z)),
                (1, lambda x, y, z: -_sinf(x - y + z)))


def magic(x, y, z, scale, depth: int, distortion) -> tuple:
    """svm_magic: three sines of the coordinate, folded into each other `depth` times (0-10),
    each fold scaled by the distortion. Computed in float32, step by step as the kernel: the
    folds amplify rounding differences by the distortion at each step, and from depth 8 on
    float64 arithmetic no longer agrees with Cycles at 1e-4."""
    x, y, z = (np.fmod(f32(c), F32(_2PI)) for c in (x, y, z))  # Cycles' guard: sin/cos of large values
    scale, distortion = f32(scale), f32(distortion)
    five = F32(5.0)
    x, y, z = _sinf((x + y + z) * five * scale), _cosf((-x + y - z) * five * scale), -_cosf((-x - y + z) * five * scale)
    if depth > 0:
        x, y, z = x * distortion, y * distortion, z * distortion
        y = -_cosf(x - y + z) * distortion
        for target, fold in _MAGIC_STEPS[:depth - 1]:
            v = [x, y, z]
            v[target] = fold(x, y, z) * distortion
            x, y, z = v
    # Cycles divides by 2 * distortion only where distortion != 0.
    d = np.where(distortion != 0.0, F32(2.0) * distortion, F32(1.0))
    return tuple((F32(0.5) - c / d).astype(np.float64) for c in (x, y, z))


@node("ShaderNodeTexMagic", "Texture", reads=_GENERATED)
def magic_texture(node, inputs, state):
    x, y, z = components(texture_mapping.coordinate(node, inputs, state))
    depth = int(node.prop("turbulence_depth", 2))
    color = _memo(lambda: stack(*magic(x, y, z, inputs["Scale"], depth, inputs["Distortion"])))
    return {"Color": color, "Fac": lambda: color().mean(axis=-1)}


# --- Wave -----------------------------------------------------------------------------------

_BAND_AXIS = {"X": 0, "Y": 1, "Z": 2}
_RING_AXES = {"X": (1, 2), "Y": (0, 2), "Z": (0, 1), "SPHERICAL": (0, 1, 2)}


def wave(node, p, distortion, detail, detail_scale, detail_roughness, phase):
    """svm_wave at float32 point p (3 arrays), nudged off unit coordinates as Cycles does."""
    p = tuple((c + F32(0.000001)) * F32(0.999999) for c in p)
    q = tuple(c.astype(np.float64) for c in p)
    if node.prop("wave_type", "BANDS") == "BANDS":
        direction = node.prop("bands_direction", "X")
        n = q[0] + q[1] + q[2] if direction == "DIAGONAL" else q[_BAND_AXIS[direction]]
        n = n * (10.0 if direction == "DIAGONAL" else 20.0)
    else:
        n = np.sqrt(sum(q[k] * q[k] for k in _RING_AXES[node.prop("rings_direction", "X")])) * 20.0
    n = n + phase
    if np.any(distortion != 0.0):
        p = tuple(c * f32(detail_scale) for c in p)
        n = n + distortion * (fractal("FBM", p, detail, detail_roughness, 2.0) * 2.0 - 1.0)
    profile = node.prop("wave_profile", "SIN")
    if profile == "SIN":
        return 0.5 + 0.5 * np.sin(n - _PI_2)
    n = n / _2PI
    if profile == "SAW":
        return n - np.floor(n)
    return np.abs(n - np.floor(n + 0.5)) * 2.0


@node("ShaderNodeTexWave", "Texture", reads=_GENERATED)
def wave_texture(node, inputs, state):
    scale = f32(inputs["Scale"])
    args = tuple(scalar(inputs[k])
                 for k in ("Distortion", "Detail", "Detail Scale", "Detail Roughness", "Phase Offset"))
    p = _broadcast(tuple(c * scale for c in components(f32(texture_mapping.coordinate(node, inputs, state)))), *args)
    fac = _memo(lambda: wave(node, p, *args))
    return {"Fac": fac, "Color": lambda: stack(fac(), fac(), fac())}


# --- Brick ----------------------------------------------------------------------------------

def brick_noise(n):
    """Cycles' fast integer noise of a brick's index (uint32 arithmetic), in [0, 1)."""
    with np.errstate(over="ignore"):
        n = (np.asarray(n, np.uint32) + np.uint32(1013)) & np.uint32(0x7FFFFFFF)
        n = (n >> np.uint32(13)) ^ n
        nn = (n * (n * n * np.uint32(60493) + np.uint32(19990303)) + np.uint32(1376312589)) & np.uint32(0x7FFFFFFF)
    return 0.5 * (nn.astype(F32).astype(np.float64) / 1073741824.0)


def brick(x, y, mortar_size, mortar_smooth, bias, brick_width, row_height,
          offset_amount, offset_frequency: int, squash_amount, squash_frequency: int):
    """svm_brick at float32 (x, y): (tint, mortar). Rows and bricks are counted in float32
    (the divisions and floors that decide a brick); offset and squash every offset_frequency /
    squash_frequency rows."""
    row_height32, brick_width32 = f32(row_height), f32(brick_width)
    row = np.floor(y / row_height32).astype(np.int64)
    shift = F32(0.0)
    if offset_frequency and squash_frequency:
        brick_width32 = np.where(row % squash_frequency != 0, brick_width32, brick_width32 * F32(squash_amount))
        shift = np.where(row % offset_frequency != 0, F32(0.0), brick_width32 * F32(offset_amount))
    xs = x + shift
    index = np.floor(xs / brick_width32).astype(np.int64)
    width, height = brick_width32.astype(np.float64), row_height32.astype(np.float64)
    u = xs.astype(np.float64) - width * index
    v = y.astype(np.float64) - height * row
    key = ((row & 0xFFFF) << 16) + (index & 0xFFFF)  # (rownum << 16) + (bricknum & 0xFFFF) in uint32
    tint = np.clip(brick_noise(key & 0xFFFFFFFF) + bias, 0.0, 1.0)
    edge = np.minimum(np.minimum(u, v), np.minimum(width - u, height - v))
    with np.errstate(all="ignore"):
        t = (1.0 - edge / mortar_size) / mortar_smooth
    smooth = np.where(t <= 0.0, 0.0, np.where(t >= 1.0, 1.0, t * t * (3.0 - 2.0 * t)))
    mortar = np.where(edge >= mortar_size, 0.0, np.where(mortar_smooth == 0.0, 1.0, smooth))
    return tint, mortar


@node("ShaderNodeTexBrick", "Texture", reads=_GENERATED)
def brick_texture(node, inputs, state):
    scale = f32(inputs["Scale"])
    x, y, _ = (c * scale for c in components(f32(texture_mapping.coordinate(node, inputs, state))))
    args = tuple(scalar(inputs[k]) for k in ("Mortar Size", "Mortar Smooth", "Bias", "Brick Width", "Row Height"))
    x, y = _broadcast((x, y), *args)
    result = _memo(lambda: brick(x, y, *args, node.prop("offset", 0.5), int(node.prop("offset_frequency", 2)),
                                 node.prop("squash", 1.0), int(node.prop("squash_frequency", 2))))

    def color():
        tint, mortar = result()
        tint, mortar = tint[..., None], mortar[..., None]
        c1, c2, m = (triple(inputs[k]) for k in ("Color1", "Color2", "Mortar"))
        c1 = np.where(mortar != 1.0, (1.0 - tint) * c1 + tint * c2, c1)
        return c1 * (1.0 - mortar) + m * mortar
    return {"Fac": lambda: result()[1], "Color": color}


NODES = (noise_texture, white_noise_texture, gradient_texture, checker_texture, magic_texture, wave_texture,
         brick_texture)
