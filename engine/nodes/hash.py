"""Cycles' integer hashes, bit for bit (util/hash.h): Bob Jenkins' lookup3 `final` and `mix`
over 1 to 4 keys, and the float hashes built on them (a float's IEEE bits hashed, the result
mapped to [0, 1] in float32). Perlin noise hashes its lattice points with these, White Noise
hashes its coordinates, the noise textures derive their seed offsets from them.

Keys and results are uint32 arrays of any shape (0-d for constants); arithmetic wraps modulo
2^32 as C's unsigned arithmetic does.
"""
from __future__ import annotations

import numpy as np

_U32 = np.uint32
# lookup3's initial value for n keys: 0xdeadbeef + (n << 2) + 13.
_SEED = tuple(_U32((0xDEADBEEF + (n << 2) + 13) & 0xFFFFFFFF) for n in range(5))
# uint_to_float_incl: float(n) * (1 / (float)0xFFFFFFFF), where (float)0xFFFFFFFF rounds to 2^32.
_INCL = 2.0 ** -32


def _keys(*keys):
    """The keys as uint32 arrays broadcast to one shape (copies: the hash works in place)."""
    out = np.broadcast_arrays(*(np.asarray(k).astype(_U32, copy=False) for k in keys))
    return [np.array(k, _U32) for k in out]


def _rot(x, k: int, out, tmp):
    """x rotated left by k bits, into `out` (`tmp` is scratch): no allocation per step."""
    np.left_shift(x, _U32(k), out=out)
    np.right_shift(x, _U32(32 - k), out=tmp)
    out |= tmp
    return out


def mix(a, b, c, t=None, u=None) -> None:
    """lookup3's mix, in place on uint32 arrays a, b, c of one shape (t, u: scratch arrays of
    that shape, allocated if not given)."""
    with np.errstate(over="ignore"):
        t = np.empty_like(a) if t is None else t
        u = np.empty_like(a) if u is None else u
        a -= c; a ^= _rot(c, 4, t, u); c += b  # noqa: E702 (lookup3's rows, kept as rows)
        b -= a; b ^= _rot(a, 6, t, u); a += c  # noqa: E702
        c -= b; c ^= _rot(b, 8, t, u); b += a  # noqa: E702
        a -= c; a ^= _rot(c, 16, t, u); c += b  # noqa: E702
        b -= a; b ^= _rot(a, 19, t, u); a += c  # noqa: E702
        c -= b; c ^= _rot(b, 4, t, u); b += a  # noqa: E702


def final(a, b, c, t=None, u=None):
    """lookup3's final, in place on uint32 arrays a, b, c of one shape; returns c (t, u:
    scratch arrays of that shape, allocated if not given)."""
    with np.errstate(over="ignore"):
        t = np.empty_like(a) if t is None else t
        u = np.empty_like(a) if u is None else u
        c ^= b; c -= _rot(b, 14, t, u)  # noqa: E702
        a ^= c; a -= _rot(c, 11, t, u)  # noqa: E702
        b ^= a; b -= _rot(a, 25, t, u)  # noqa: E702
        c ^= b; c -= _rot(b, 16, t, u)  # noqa: E702
        a ^= c; a -= _rot(c, 4, t, u)  # noqa: E702
        b ^= a; b -= _rot(a, 14, t, u)  # noqa: E702
        c ^= b; c -= _rot(b, 24, t, u)  # noqa: E702
    return c


def seed(n: int):
    """lookup3's initial value for n keys, 0xdeadbeef + (n << 2) + 13, as uint32."""
    return _SEED[n]


def hash_uint(kx):
    (a,) = _keys(kx)
    with np.errstate(over="ignore"):
        a += _SEED[1]
    return final(a, np.full_like(a, _SEED[1]), np.full_like(a, _SEED[1]))


def hash_uint2(kx, ky):
    a, b = _keys(kx, ky)
    with np.errstate(over="ignore"):
        a += _SEED[2]
        b += _SEED[2]
    return final(a, b, np.full_like(a, _SEED[2]))


def hash_uint3(kx, ky, kz):
    a, b, c = _keys(kx, ky, kz)
    with np.errstate(over="ignore"):
        a += _SEED[3]
        b += _SEED[3]
        c += _SEED[3]
    return final(a, b, c)


def hash_uint4(kx, ky, kz, kw):
    a, b, c, w = _keys(kx, ky, kz, kw)
    with np.errstate(over="ignore"):
        a += _SEED[4]
        b += _SEED[4]
        c += _SEED[4]
        mix(a, b, c)
        a += w
    return final(a, b, c)


_HASHES = (None, hash_uint, hash_uint2, hash_uint3, hash_uint4)


def uint_to_float(n) -> np.ndarray:
    """Cycles' uint_to_float_incl: n rounded to float32, times 2^-32 (exact), as float64."""
    return np.asarray(n).astype(np.float32).astype(np.float64) * _INCL


def float_bits(x) -> np.ndarray:
    """The IEEE bits of x as float32 (Cycles' __float_as_uint of a float socket value)."""
    return np.asarray(x, np.float64).astype(np.float32).view(_U32)


def hash_float(*k) -> np.ndarray:
    """hash_float_to_float, hash_float2_to_float, ... : 1 to 4 floats -> [0, 1]."""
    return uint_to_float(_HASHES[len(k)](*(float_bits(x) for x in k)))


def hash_float_to_float3(*k) -> tuple:
    """hash_float{,2,3,4}_to_float3: three hashes of the key, each a permutation of the key or
    the key with a constant appended (Cycles' choice, per dimension)."""
    if len(k) == 1:
        (x,) = k
        return hash_float(x), hash_float(x, 1.0), hash_float(x, 2.0)
    if len(k) == 2:
        x, y = k
        return hash_float(x, y), hash_float(x, y, 1.0), hash_float(x, y, 2.0)
    if len(k) == 3:
        x, y, z = k
        return hash_float(x, y, z), hash_float(x, y, z, 1.0), hash_float(x, y, z, 2.0)
    x, y, z, w = k
    return hash_float(x, y, z, w), hash_float(z, x, w, y), hash_float(w, z, y, x)


def hash_float_to_float2(*k) -> tuple:
    """hash_float3_to_float2, hash_float4_to_float2: the key and a permutation of it."""
    if len(k) == 3:
        x, y, z = k
        return hash_float(x, y, z), hash_float(z, x, y)
    x, y, z, w = k
    return hash_float(x, y, z, w), hash_float(z, x, w, y)


# --- PCG on int32 -----------------------------------------------------------------------------

# int32-typed, so 0-d keys stay int32 too (a Python int would widen them to int64).
_INV_2_31 = 2.0 ** -31
INT_UNIT = _INV_2_31  # (float)h / 2^31 of a 31-bit hash is its float32 rounding times this
_LCG_MUL = np.int32(1664525)
_LCG_ADD = np.int32(1013904223)
_SHIFT = np.int32(16)
_LOW31 = np.int32(0x7FFFFFFF)


def _i32(x) -> np.ndarray:
    return np.asarray(x).astype(np.int32)


def lcg(x) -> np.ndarray:
    """The PCG hashes' first step on an int32 key, x * 1664525 + 1013904223 (wrapping). It is
    affine, so the step of key + k is lcg(key) + lcg_step(k): a lattice's neighbours share it."""
    with np.errstate(over="ignore"):
        return _i32(x) * _LCG_MUL + _LCG_ADD


def lcg_step(k: int) -> np.int32:
    """k * 1664525 as a wrapped int32: what lcg() adds for a key k larger."""
    return np.int32(((k * int(_LCG_MUL)) + (1 << 31)) % (1 << 32) - (1 << 31))


def hash_pcg2d_i(x, y):
    return pcg2d_after_lcg(lcg(x), lcg(y))


def pcg2d_after_lcg(x, y):
    """hash_pcg2d_i of keys whose lcg() is x, y."""
    with np.errstate(over="ignore"):
        x = x + y * _LCG_MUL
        y = y + x * _LCG_MUL
        x, y = x ^ (x >> _SHIFT), y ^ (y >> _SHIFT)
        x = x + y * _LCG_MUL
        y = y + x * _LCG_MUL
        return x & _LOW31, y & _LOW31


def hash_pcg3d_i(x, y, z):
    return pcg3d_after_lcg(lcg(x), lcg(y), lcg(z))


def pcg3d_after_lcg(x, y, z):
    """hash_pcg3d_i of keys whose lcg() is x, y, z."""
    with np.errstate(over="ignore"):
        x = x + y * z
        y = y + z * x
        z = z + x * y
        x, y, z = x ^ (x >> _SHIFT), y ^ (y >> _SHIFT), z ^ (z >> _SHIFT)
        x = x + y * z
        y = y + z * x
        z = z + x * y
        return x & _LOW31, y & _LOW31, z & _LOW31


def hash_pcg4d_i(x, y, z, w):
    return pcg4d_after_lcg(lcg(x), lcg(y), lcg(z), lcg(w))


def pcg4d_after_lcg(x, y, z, w):
    """hash_pcg4d_i of keys whose lcg() is x, y, z, w."""
    with np.errstate(over="ignore"):
        x = x + y * w
        y = y + z * x
        z = z + x * y
        w = w + y * z
        x, y, z, w = x ^ (x >> _SHIFT), y ^ (y >> _SHIFT), z ^ (z >> _SHIFT), w ^ (w >> _SHIFT)
        x = x + y * w
        y = y + z * x
        z = z + x * y
        w = w + y * z
        return x & _LOW31, y & _LOW31, z & _LOW31, w & _LOW31


def _int_to_unit(h) -> np.ndarray:
    """(float)h / 2^31 for h in [0, 2^31): the cast rounds to float32."""
    return h.astype(np.float32).astype(np.float64) * _INV_2_31


def hash_int2_to_float2(x, y):
    return tuple(_int_to_unit(h) for h in hash_pcg2d_i(x, y))


def hash_int3_to_float3(x, y, z):
    return tuple(_int_to_unit(h) for h in hash_pcg3d_i(x, y, z))


def hash_int4_to_float4(x, y, z, w):
    return tuple(_int_to_unit(h) for h in hash_pcg4d_i(x, y, z, w))


def hash_int2_to_float3(x, y):
    return hash_int3_to_float3(x, y, 0)


def hash_int4_to_float3(x, y, z, w):
    return hash_int4_to_float4(x, y, z, w)[:3]
