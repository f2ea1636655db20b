"""Perlin noise in 1 to 4 dimensions and its fractal sums, as Cycles computes them
(svm/noise.h, svm/fractal_noise.h).

Coordinates are float32 arrays: Cycles computes in float32, and which lattice cell a point
falls in (a floor) and the coordinate of each octave (lacunarity^i times the point, with a
float32 rounding at each product) are decided in that precision; the gradients, fades and
sums after the floor are continuous in the coordinate and computed in float64. A point's
octaves, the colour's offset copies and the distortion lookups are separate noise
evaluations, each one pass over all the points.

Shapes: every coordinate array has the same shape S (any, 0-d for constants); results are
float64 of shape S.
"""
from __future__ import annotations

import numpy as np

from .hash import final, mix
from .hash import seed as hash_seed

F32 = np.float32
# noise_scale1..4: Perlin noise remapped to about [-1, 1] (constants found by OSL's authors).
_SCALE = (None, float(F32(0.25)), float(F32(0.6616)), float(F32(0.9820)), float(F32(0.8344)))


def _gradient_tables():
    """Per dimension, the gradient of each hash value (h & mask) as coefficients on the
    offsets (x, y, z, w) from the lattice point: grad1..grad4 of svm/noise.h as tables."""
    g1 = np.array([[(1 + (h & 7)) * (-1 if h & 8 else 1)] for h in range(16)], np.float64)
    g2 = np.zeros((8, 2))
    for h in range(8):
        u, v = (0, 1) if h < 4 else (1, 0)  # u on x, v (doubled) on y, or the other way round
        g2[h, u] += -1 if h & 1 else 1
        g2[h, v] += -2 if h & 2 else 2
    g3 = np.zeros((16, 3))
    for h in range(16):
        u = 0 if h < 8 else 1
        v = 1 if h < 4 else (0 if h in (12, 14) else 2)
        g3[h, u] += -1 if h & 1 else 1
        g3[h, v] += -1 if h & 2 else 1
    g4 = np.zeros((32, 4))
    for h in range(32):
        u = 0 if h < 24 else 1
        v = 1 if h < 16 else 2
        s = 2 if h < 8 else 3
        g4[h, u] += -1 if h & 1 else 1
        g4[h, v] += -1 if h & 2 else 1
        g4[h, s] += -1 if h & 4 else 1
    return {1: g1, 2: g2, 3: g3, 4: g4}


def _lattice(d: int, g: np.ndarray) -> dict:
    """What perlin() looks up for dimension d, with corner c of the 2^d lattice points around
    a point at offset (c >> k) & 1 along axis k:
    keys: per axis, the corner offsets as uint32, plus lookup3's seed on the axes it seeds
      (x, y, z start a, b, c at seed + key); in 4D the x, y, z keys of the 8 corners of
      w = 0 only (lookup3 mixes x, y, z before it adds w, so 4D mixes 8 corners, not 16);
    offset: per axis, the corner offsets as float64;
    gradient: per axis, the gradient coefficient of each hash value (the hash's low bits)."""
    bits = np.array([[(c >> k) & 1 for k in range(d)] for c in range(1 << d)])
    seed = int(hash_seed(d))
    mixed = bits[: 1 << min(d, 3)]
    keys = tuple(((mixed[:, k] + seed) & 0xFFFFFFFF).astype(np.uint32) for k in range(min(d, 3)))
    return {"keys": keys, "offset": tuple(bits[:, k].astype(np.float64) for k in range(d)),
            "gradient": tuple(np.ascontiguousarray(g[:, k]) for k in range(d)), "mask": np.uint32(len(g) - 1)}


_LATTICE = {d: _lattice(d, g) for d, g in _gradient_tables().items()}
_W = np.array([0, 1], np.uint32)


def fade(t):
    """Perlin's quintic fade 6t^5 - 15t^4 + 10t^3 (svm/noise.h fade)."""
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


def perlin(coords) -> np.ndarray:
    """Perlin noise (perlin_1d .. perlin_4d) at float32 coordinates `coords` (1 to 4 arrays of
    one shape S), unscaled, float64 of shape S. All 2^d corners are hashed in one lookup3 pass
    over arrays (2^d, *S)."""
    d = len(coords)
    shape = np.shape(coords[0])
    lift = (slice(None),) + (None,) * len(shape)  # a per-corner vector against shape S
    lattice = _LATTICE[d]
    cells, fracs = [], []
    for x in coords:
        cell = np.floor(x)
        fracs.append((x - cell).astype(np.float64))  # exact: x and floor(x) share their leading bits
        cells.append(cell.astype(np.int32).view(np.uint32))
    with np.errstate(over="ignore"):
        keys = [cell + key[lift] for cell, key in zip(cells, lattice["keys"])]
        if d == 1:
            a = keys[0]
            b, c = np.full_like(a, hash_seed(1)), np.full_like(a, hash_seed(1))
        elif d == 2:
            (a, b), c = keys, np.full_like(keys[0], hash_seed(2))
        elif d == 3:
            a, b, c = keys
        else:  # mix the 8 (x, y, z) corners, then add w and w + 1: corners w = 0, then w = 1
            a, b, c = keys
            mix(a, b, c)
            a = (a[None] + (cells[3] + _W[lift])[:, None]).reshape((16,) + shape)
            b = np.concatenate([b, b])
            c = np.concatenate([c, c])
        h = final(a, b, c)
    h &= lattice["mask"]
    index = h.astype(np.intp)  # take() on in-range intp indices is its fast path
    g = None
    for k in range(d):
        term = np.take(lattice["gradient"][k], index, mode="wrap")
        term *= fracs[k] - lattice["offset"][k][lift]
        g = term if g is None else np.add(g, term, out=g)
    # Multilinear interpolation: corners reshaped so that axis k of the lattice is the
    # (d - 1 - k)-th leading axis; x first, as Cycles' bi_mix / tri_mix / quad_mix.
    g = g.reshape((2,) * d + shape)
    for k in range(d):
        lo, hi = g[(slice(None),) * (d - 1 - k) + (0,)], g[(slice(None),) * (d - 1 - k) + (1,)]
        hi -= lo
        hi *= fade(fracs[k])
        hi += lo
        g = hi
    return g


def snoise(coords) -> np.ndarray:
    """Signed noise in about [-1, 1] (snoise_1d .. snoise_4d): the coordinates wrapped every
    100000 (nudged by a half where |p| >= 1e6, as Cycles does against float32 loss), Perlin
    noise scaled per dimension. Long point arrays go through in chunks of 2^16 corner values,
    which keeps the corner arrays in cache."""
    d = len(coords)
    wrapped = []
    for x in coords:
        if np.max(np.abs(x), initial=F32(0.0)) >= F32(100000.0):  # else fmod leaves x as it is
            big = np.abs(x) >= F32(1000000.0)
            x = np.fmod(x, F32(100000.0))
            if np.any(big):
                x = x + np.where(big, F32(0.5), F32(0.0))
        wrapped.append(x)
    chunk = 1 << (16 - d)
    if wrapped[0].ndim != 1 or len(wrapped[0]) <= chunk:
        return _SCALE[d] * perlin(wrapped)
    out = np.empty(len(wrapped[0]))
    for start in range(0, len(out), chunk):
        part = slice(start, start + chunk)
        out[part] = perlin([x[part] for x in wrapped])
    out *= _SCALE[d]
    return out


def scaled(coords, factor) -> tuple:
    """Every coordinate times `factor`, rounded to float32 (Cycles' float3 * float)."""
    f = np.asarray(factor).astype(F32)
    return tuple(x * f for x in coords)


def offset(coords, shift) -> tuple:
    """Coordinates plus per-axis float32 constants `shift` (the seed offsets)."""
    return tuple(x + F32(s) for x, s in zip(coords, shift))


def _octaves(detail):
    """The octaves 0..n each point runs (n = the detail truncated, Cycles' float_to_int), the
    largest n, and the weight of the fractional octave (detail - floor(detail))."""
    detail = np.asarray(detail, np.float64)
    whole = np.trunc(detail)
    return whole, int(np.max(whole)), detail - np.floor(detail)


def _where(mask, new, old):
    """new where mask, else old; `mask` True for all points skips the select."""
    if mask is True or (np.ndim(mask) == 0 and bool(mask)):
        return new
    return np.where(mask, new, old)


def _fold(mask, new, old) -> tuple:
    return tuple(_where(mask, n, o) for n, o in zip(new, old))


def fbm(coords, detail, roughness, lacunarity, normalize: bool):
    """Fractal Brownian motion (noise_fbm): octaves of snoise at lacunarity^i times the point,
    weighted roughness^i; a fractional detail blends in one more octave; normalised to [0, 1]
    by the sum of weights when asked."""
    whole, top, rmd = _octaves(detail)
    lac = np.asarray(lacunarity).astype(F32)
    fscale = F32(1.0) * np.ones_like(lac)
    amp, maxamp, total = 1.0, 0.0, 0.0
    for i in range(top + 1):
        t = snoise(scaled(coords, fscale))
        on = i <= whole
        total = _where(on, total + t * amp, total)
        maxamp = _where(on, maxamp + amp, maxamp)
        amp = _where(on, amp * roughness, amp)
        fscale = _where(on, fscale * lac, fscale)
    plain = 0.5 * total / maxamp + 0.5 if normalize else total
    if not np.any(rmd != 0.0):
        return plain + np.zeros(np.shape(coords[0]))
    t = snoise(scaled(coords, fscale))
    total2 = total + t * amp
    if normalize:
        blend = plain + rmd * (0.5 * total2 / (maxamp + amp) + 0.5 - plain)
    else:
        blend = total + rmd * (total2 - total)
    return np.where(rmd != 0.0, blend, plain)


def multi_fractal(coords, detail, roughness, lacunarity):
    """Multifractal (noise_multi_fractal): the product of (1 + roughness^i snoise) over octaves."""
    whole, top, rmd = _octaves(detail)
    lac = np.asarray(lacunarity).astype(F32)
    value, pwr = 1.0, 1.0
    for i in range(top + 1):
        on = i <= whole
        value = _where(on, value * (pwr * snoise(coords) + 1.0), value)
        pwr = _where(on, pwr * roughness, pwr)
        coords = _fold(on, scaled(coords, lac), coords)
    if np.any(rmd != 0.0):
        value = value * (rmd * pwr * snoise(coords) + 1.0)  # rmd = 0 multiplies by 1
    return value + np.zeros(np.shape(coords[0]))


def hetero_terrain(coords, detail, roughness, lacunarity, offset_):
    """Heterogeneous terrain (noise_hetero_terrain): each octave's (snoise + offset) scaled by
    the value so far, so detail grows where the terrain is high."""
    whole, top, rmd = _octaves(detail)
    lac = np.asarray(lacunarity).astype(F32)
    pwr = roughness
    value = offset_ + snoise(coords)
    coords = scaled(coords, lac)
    for i in range(1, top + 1):
        on = i <= whole
        increment = (snoise(coords) + offset_) * pwr * value
        value = _where(on, value + increment, value)
        pwr = _where(on, pwr * roughness, pwr)
        coords = _fold(on, scaled(coords, lac), coords)
    if np.any(rmd != 0.0):
        increment = (snoise(coords) + offset_) * pwr * value
        value = value + rmd * increment
    return value + np.zeros(np.shape(coords[0]))


def hybrid_multi_fractal(coords, detail, roughness, lacunarity, offset_, gain):
    """Hybrid additive/multiplicative multifractal (noise_hybrid_multi_fractal): octaves
    weighted by the previous signal times gain (capped at 1); a point stops adding octaves
    once its weight falls to 0.001."""
    whole, top, rmd = _octaves(detail)
    lac = np.asarray(lacunarity).astype(F32)
    pwr, value, weight = 1.0, 0.0, 1.0
    for i in range(top + 1):
        on = (weight > 0.001) & (i <= whole)
        if not np.any(on):
            break
        w = np.minimum(weight, 1.0)
        signal = (snoise(coords) + offset_) * pwr
        value = _where(on, value + w * signal, value)
        weight = _where(on, w * gain * signal, weight)
        pwr = _where(on, pwr * roughness, pwr)
        coords = _fold(on, scaled(coords, lac), coords)
    last = (rmd != 0.0) & (weight > 0.001)
    if np.any(last):
        w = np.minimum(weight, 1.0)
        signal = (snoise(coords) + offset_) * pwr
        value = _where(last, value + rmd * w * signal, value)
    return value + np.zeros(np.shape(coords[0]))


def ridged_multi_fractal(coords, detail, roughness, lacunarity, offset_, gain):
    """Ridged multifractal (noise_ridged_multi_fractal): squared (offset - |snoise|) ridges,
    each octave weighted by the previous ridge times gain; whole octaves only (Cycles ignores
    a fractional detail here)."""
    whole, top, _ = _octaves(detail)
    lac = np.asarray(lacunarity).astype(F32)
    pwr = roughness
    signal = offset_ - np.abs(snoise(coords))
    signal = signal * signal
    value = signal
    for i in range(1, top + 1):
        on = i <= whole
        coords = _fold(on, scaled(coords, lac), coords)
        weight = np.clip(signal * gain, 0.0, 1.0)
        s = offset_ - np.abs(snoise(coords))
        s = s * s * weight
        value = _where(on, value + s * pwr, value)
        signal = _where(on, s, signal)
        pwr = _where(on, pwr * roughness, pwr)
    return value + np.zeros(np.shape(coords[0]))


def fractal(kind: str, coords, detail, roughness, lacunarity, offset_=0.0, gain=1.0, normalize=True):
    """The Noise Texture's fractal `kind` (Blender's noise_type identifier), as noise_select."""
    if kind == "FBM":
        return fbm(coords, detail, roughness, lacunarity, normalize)
    if kind == "MULTIFRACTAL":
        return multi_fractal(coords, detail, roughness, lacunarity)
    if kind == "HETERO_TERRAIN":
        return hetero_terrain(coords, detail, roughness, lacunarity, offset_)
    if kind == "HYBRID_MULTIFRACTAL":
        return hybrid_multi_fractal(coords, detail, roughness, lacunarity, offset_, gain)
    if kind == "RIDGED_MULTIFRACTAL":
        return ridged_multi_fractal(coords, detail, roughness, lacunarity, offset_, gain)
    raise ValueError(f"unknown noise type {kind!r}")
