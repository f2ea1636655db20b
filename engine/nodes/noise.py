"""Perlin noise in 1 to 4 dimensions and its fractal sums, as Cycles computes them
(svm/noise.h, svm/fractal_noise.h).

Coordinates are float32 arrays: Cycles computes in float32, and which lattice cell a point
falls in (a floor) and the coordinate of each octave (lacunarity^i times the point, with a
float32 rounding at each product) are decided in that precision. One octave's gradients,
fades and interpolation are float32 too, as Cycles' (half the memory traffic of float64, which
is what bounds NumPy here); the fractal sums over octaves are float64. Noise evaluations
whose coordinates are known together (an fBm's octaves; the Noise node's colour channels and
distortion lookups, engine/nodes/textures.py) go through as one batch of all their points, as
NumPy's cost per call is large against a batch of a few thousand points.

Shapes: every coordinate array has the same shape S (any, 0-d for constants); results are
float64 of shape S.
"""
from __future__ import annotations

import threading

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
    """What perlin() looks up for dimension d: per axis, the gradient coefficient of each hash
    value (its low bits, `mask`), contiguous for np.take."""
    return {"gradient": tuple(np.ascontiguousarray(g[:, k], F32) for k in range(d)), "mask": np.uint32(len(g) - 1)}


_LATTICE = {d: _lattice(d, g) for d, g in _gradient_tables().items()}
# Points per chunk: 2^17 corner values (2^d per point). Each chunk pays some forty NumPy calls
# whatever its size, and larger chunks than this fall out of the cache.
CORNERS = 1 << 17


def fade(t):
    """Perlin's quintic fade 6t^5 - 15t^4 + 10t^3 (svm/noise.h fade)."""
    return t * t * t * (t * (t * F32(6.0) - F32(15.0)) + F32(10.0))


class _Workspace:
    """The per-corner arrays of perlin() for up to n points in d dimensions, kept per thread
    (workspace()) and reused by every call: large temporaries allocated per operation cost
    more (page faults of fresh memory) than the arithmetic on them."""

    def __init__(self, d: int, n: int):
        m = n << d
        self.u32 = [np.empty(m, np.uint32) for _ in range(5)]  # a, b, c and two scratch
        self.index = np.empty(m, np.intp)
        self.flt = [np.empty(m, F32) for _ in range(2)]  # the gradients, a term

    def arrays(self, n: int, d: int):
        """(uint32 a, b, c, scratch, scratch), intp index, (float32 gradients, term), each
        shaped (2^d, n)."""
        m = n << d
        shape = (1 << d, n)
        return ([u[:m].reshape(shape) for u in self.u32], self.index[:m].reshape(shape),
                [f[:m].reshape(shape) for f in self.flt])


_LOCAL = threading.local()


def workspace(d: int, n: int) -> _Workspace:
    """This thread's workspace for n points in d dimensions (grown when too small)."""
    spaces = _LOCAL.__dict__.setdefault("spaces", {})
    work = spaces.get(d)
    if work is None or len(work.index) < n << d:
        work = spaces[d] = _Workspace(d, n)
    return work


def _side(d: int, k: int, bit: int) -> tuple:
    """Index of the corners on side `bit` (0 or 1) of lattice axis k in the corner arrays,
    shaped (2,) * d + (n,) with axis 0 for lattice axis d - 1, ..., axis d - 1 for x."""
    return (slice(None),) * (d - 1 - k) + (bit,)


def perlin(coords, work: _Workspace | None = None) -> np.ndarray:
    """Perlin noise (perlin_1d .. perlin_4d) at float32 coordinates `coords` (1 to 4 arrays of
    one shape S), unscaled, float32 of shape S. All 2^d corners are hashed in one lookup3 pass
    over arrays (2^d, n) in `work`'s memory (where `work` is given, the result is a view
    into it, valid until its next use).
    Per axis a corner's key and offset take one of two values (cell or cell + 1, f or f - 1),
    computed per point and spread over the corners."""
    d = len(coords)
    shape = np.shape(coords[0])
    coords = [np.ravel(x) for x in coords]
    n = coords[0].size
    own = work is None
    work = workspace(d, n) if own else work
    corners = (2,) * d + (n,)
    (a, b, c, t, u), index, (g, term) = work.arrays(n, d)
    lattice = _LATTICE[d]
    cells, fracs = [], []
    for x in coords:
        cell = np.floor(x)
        fracs.append(x - cell)  # exact: x and floor(x) share their leading bits
        cells.append(cell.astype(np.int32).view(np.uint32))
    seed = hash_seed(d)
    with np.errstate(over="ignore"):
        # lookup3 starts a, b, c at seed + key for the keys x, y, z (seed alone past d keys);
        # 4D mixes the 8 (x, y, z) corners before it adds w, so it mixes 8, not 16.
        mixed = min(d, 3)
        keys = [v[: 1 << mixed].reshape((2,) * mixed + (n,)) for v in (a, b, c)]
        for k in range(3):
            if k < d:
                low = cells[k] + seed
                keys[k][_side(mixed, k, 0)] = low
                keys[k][_side(mixed, k, 1)] = low + np.uint32(1)
            else:
                keys[k].fill(seed)
        if d == 4:
            mix(a[:8], b[:8], c[:8], t[:8], u[:8])
            np.add(a[:8], cells[3] + np.uint32(1), out=a[8:])
            a[:8] += cells[3]
            b[8:], c[8:] = b[:8], c[:8]
        h = final(a, b, c, t, u)
    h &= lattice["mask"]
    np.copyto(index, h)  # take() on in-range intp indices is its fast path
    for k in range(d):
        into = g if k == 0 else term
        np.take(lattice["gradient"][k], index, mode="wrap", out=into)
        v = into.reshape(corners)
        v[_side(d, k, 0)] *= fracs[k]
        v[_side(d, k, 1)] *= fracs[k] - F32(1.0)
        if k:
            g += term
    # Multilinear interpolation, x first, as Cycles' bi_mix / tri_mix / quad_mix.
    v = g.reshape(corners)
    for k in range(d):
        lo, hi = v[_side(d - k, 0, 0)], v[_side(d - k, 0, 1)]
        hi -= lo
        hi *= fade(fracs[k])
        hi += lo
        v = hi
    return v.reshape(shape).copy() if own else v.reshape(shape)


def snoise(coords) -> np.ndarray:
    """Signed noise in about [-1, 1] (snoise_1d .. snoise_4d): the coordinates wrapped every
    100000 (nudged by a half where |p| >= 1e6, as Cycles does against float32 loss), Perlin
    noise scaled per dimension. Many points go through in chunks of CORNERS corner values,
    which keeps the corner arrays in cache."""
    d = len(coords)
    shape = np.shape(coords[0])
    wrapped = []
    for x in coords:
        x = np.ravel(x)
        if np.max(np.abs(x), initial=F32(0.0)) >= F32(100000.0):  # else fmod leaves x as it is
            big = np.abs(x) >= F32(1000000.0)
            x = np.fmod(x, F32(100000.0))
            if np.any(big):
                x = x + np.where(big, F32(0.5), F32(0.0))
        wrapped.append(x)
    n = wrapped[0].size
    chunk = max(CORNERS >> d, 1)
    work = workspace(d, min(n, chunk))
    out = np.empty(n)
    for start in range(0, n, chunk):
        part = slice(start, start + chunk)
        out[part] = perlin([x[part] for x in wrapped], work)
    out *= _SCALE[d]
    return out.reshape(shape)


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


def snoise_sets(sets) -> list:
    """[snoise(coords) for coords in sets] (each a tuple of (N,) arrays), in one call over all
    their points: the NumPy calls of a noise evaluation cost as much for a thousand points as
    for a few times more, and a batch's octaves are such sets. Every point's value is the one
    its own call gives (a point's noise does not depend on the others)."""
    if len(sets) == 1 or any(np.ndim(x) != 1 for coords in sets for x in coords):
        return [snoise(coords) for coords in sets]
    return np.split(snoise(tuple(np.concatenate(axis) for axis in zip(*sets))), len(sets))


def fbm(coords, detail, roughness, lacunarity, normalize: bool):
    """Fractal Brownian motion (noise_fbm): octaves of snoise at lacunarity^i times the point,
    weighted roughness^i; a fractional detail blends in one more octave; normalised to [0, 1]
    by the sum of weights when asked. The octaves' coordinates do not depend on the noise, so
    all octaves are evaluated in one snoise call."""
    whole, top, rmd = _octaves(detail)
    lac = np.asarray(lacunarity).astype(F32)
    fscale = F32(1.0) * np.ones_like(lac)
    sets = []
    for i in range(top + 1):
        sets.append(scaled(coords, fscale))
        fscale = _where(i <= whole, fscale * lac, fscale)
    fractional = bool(np.any(rmd != 0.0))
    noises = snoise_sets(sets + [scaled(coords, fscale)] if fractional else sets)
    amp, maxamp, total = 1.0, 0.0, 0.0
    for i in range(top + 1):
        t = noises[i]
        on = i <= whole
        total = _where(on, total + t * amp, total)
        maxamp = _where(on, maxamp + amp, maxamp)
        amp = _where(on, amp * roughness, amp)
    plain = 0.5 * total / maxamp + 0.5 if normalize else total
    if not fractional:
        return plain + np.zeros(np.shape(coords[0]))
    t = noises[top + 1]
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


_FRACTALS = {
    "FBM": lambda p, detail, roughness, lacunarity, offset_, gain, normalize: fbm(p, detail, roughness, lacunarity,
                                                                                 normalize),
    "MULTIFRACTAL": lambda p, detail, roughness, lacunarity, offset_, gain, normalize: multi_fractal(
        p, detail, roughness, lacunarity),
    "HETERO_TERRAIN": lambda p, detail, roughness, lacunarity, offset_, gain, normalize: hetero_terrain(
        p, detail, roughness, lacunarity, offset_),
    "HYBRID_MULTIFRACTAL": lambda p, detail, roughness, lacunarity, offset_, gain, normalize: hybrid_multi_fractal(
        p, detail, roughness, lacunarity, offset_, gain),
    "RIDGED_MULTIFRACTAL": lambda p, detail, roughness, lacunarity, offset_, gain, normalize: ridged_multi_fractal(
        p, detail, roughness, lacunarity, offset_, gain),
}


def fractal(kind: str, coords, detail, roughness, lacunarity, offset_=0.0, gain=1.0, normalize=True):
    """The Noise Texture's fractal `kind` (Blender's noise_type identifier), as noise_select."""
    return _FRACTALS[kind](coords, detail, roughness, lacunarity, offset_, gain, normalize)
