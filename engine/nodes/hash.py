"""Cycles' hash functions (util/hash.h), bit for bit: the random numbers procedural textures
draw per cell, so a texture's cells get the colours and positions they get in Cycles.

Two families, as in Cycles:
- Jenkins' lookup3 (hash_uint .. hash_uint4) on uint32 keys, and the float hashes built on it,
  which hash a float32's bit pattern (hash_float_to_float, ...): 1D Voronoi, Gabor, noise.
- PCG (hash_pcg2d_i .. hash_pcg4d_i, from "Hash Functions for GPU Rendering", JCGT 2020) on
  int32 keys, as Cycles writes it with signed integers (so `>>` shifts in the sign bit):
  2D to 4D Voronoi cells.
Integer arithmetic wraps modulo 2^32 (NumPy arrays wrap silently; errstate quiets 0-d ones).
Hashes to floats go through float32 as Cycles converts them, and are returned as float64
holding those float32 values exactly. Arguments are components (each an array or a number,
broadcasting); a vector result is a tuple of its components.
"""
from __future__ import annotations

import numpy as np

_U32 = np.uint32
_DEADBEEF = 0xDEADBEEF
# (float)0xFFFFFFFFu and (float)0x7FFFFFFFu round to 2^32 and 2^31: the scale factors are
# exact powers of two.
_INV_2_32 = 2.0 ** -32
_INV_2_31 = 2.0 ** -31


def _u32(x) -> np.ndarray:
    return np.asarray(x).astype(_U32)


def _rot(x, k: int):
    return (x << _U32(k)) | (x >> _U32(32 - k))


def _final(a, b, c):
    """lookup3's final(a, b, c): returns c, the only word Cycles keeps."""
    c = (c ^ b) - _rot(b, 14)
    a = (a ^ c) - _rot(c, 11)
    b = (b ^ a) - _rot(a, 25)
    c = (c ^ b) - _rot(b, 16)
    a = (a ^ c) - _rot(c, 4)
    b = (b ^ a) - _rot(a, 14)
    c = (c ^ b) - _rot(b, 24)
    return c


def _mix(a, b, c):
    """lookup3's mix(a, b, c)."""
    a = (a - c) ^ _rot(c, 4)
    c = c + b
    b = (b - a) ^ _rot(a, 6)
    a = a + c
    c = (c - b) ^ _rot(b, 8)
    b = b + a
    a = (a - c) ^ _rot(c, 16)
    c = c + b
    b = (b - a) ^ _rot(a, 19)
    a = a + c
    c = (c - b) ^ _rot(b, 4)
    b = b + a
    return a, b, c


def _seed(n: int):
    return _U32((_DEADBEEF + (n << 2) + 13) & 0xFFFFFFFF)


def hash_uint(kx):
    with np.errstate(over="ignore"):
        a = b = c = _seed(1)
        return _final(a + _u32(kx), b, c)


def hash_uint2(kx, ky):
    with np.errstate(over="ignore"):
        a = b = c = _seed(2)
        return _final(a + _u32(kx), b + _u32(ky), c)


def hash_uint3(kx, ky, kz):
    with np.errstate(over="ignore"):
        a = b = c = _seed(3)
        return _final(a + _u32(kx), b + _u32(ky), c + _u32(kz))


def hash_uint4(kx, ky, kz, kw):
    with np.errstate(over="ignore"):
        a = b = c = _seed(4)
        a, b, c = _mix(a + _u32(kx), b + _u32(ky), c + _u32(kz))
        return _final(a + _u32(kw), b, c)


def uint_to_float_incl(n) -> np.ndarray:
    """[0, 2^32 - 1] -> [0, 1]: (float)n / 2^32, the cast rounding to float32."""
    return np.asarray(n).astype(np.float32).astype(np.float64) * _INV_2_32


def float_as_uint(x) -> np.ndarray:
    """The bit pattern of x as a float32 (Cycles' __float_as_uint; -0.0 and 0.0 differ)."""
    return np.asarray(x, np.float32).view(_U32)


def hash_float_to_float(k):
    return uint_to_float_incl(hash_uint(float_as_uint(k)))


def hash_float2_to_float(kx, ky):
    return uint_to_float_incl(hash_uint2(float_as_uint(kx), float_as_uint(ky)))


def hash_float3_to_float(kx, ky, kz):
    return uint_to_float_incl(hash_uint3(float_as_uint(kx), float_as_uint(ky), float_as_uint(kz)))


def hash_float4_to_float(kx, ky, kz, kw):
    return uint_to_float_incl(hash_uint4(float_as_uint(kx), float_as_uint(ky), float_as_uint(kz),
                                         float_as_uint(kw)))


def hash_float_to_float3(k):
    return hash_float_to_float(k), hash_float2_to_float(k, 1.0), hash_float2_to_float(k, 2.0)


def hash_float3_to_float2(kx, ky, kz):
    return hash_float3_to_float(kx, ky, kz), hash_float3_to_float(kz, kx, ky)


def hash_float4_to_float2(kx, ky, kz, kw):
    return hash_float4_to_float(kx, ky, kz, kw), hash_float4_to_float(kz, kx, kw, ky)


def hash_float4_to_float3(kx, ky, kz, kw):
    return (hash_float4_to_float(kx, ky, kz, kw), hash_float4_to_float(kz, kx, kw, ky),
            hash_float4_to_float(kw, kz, ky, kx))


# --- PCG on int32 -----------------------------------------------------------------------------

# int32-typed, so 0-d keys stay int32 too (a Python int would widen them to int64).
_LCG_MUL = np.int32(1664525)
_LCG_ADD = np.int32(1013904223)
_SHIFT = np.int32(16)
_LOW31 = np.int32(0x7FFFFFFF)


def _i32(x) -> np.ndarray:
    return np.asarray(x).astype(np.int32)


def hash_pcg2d_i(x, y):
    with np.errstate(over="ignore"):
        x = _i32(x) * _LCG_MUL + _LCG_ADD
        y = _i32(y) * _LCG_MUL + _LCG_ADD
        x = x + y * _LCG_MUL
        y = y + x * _LCG_MUL
        x, y = x ^ (x >> _SHIFT), y ^ (y >> _SHIFT)
        x = x + y * _LCG_MUL
        y = y + x * _LCG_MUL
        return x & _LOW31, y & _LOW31


def hash_pcg3d_i(x, y, z):
    with np.errstate(over="ignore"):
        x, y, z = (_i32(v) * _LCG_MUL + _LCG_ADD for v in (x, y, z))
        x = x + y * z
        y = y + z * x
        z = z + x * y
        x, y, z = x ^ (x >> _SHIFT), y ^ (y >> _SHIFT), z ^ (z >> _SHIFT)
        x = x + y * z
        y = y + z * x
        z = z + x * y
        return x & _LOW31, y & _LOW31, z & _LOW31


def hash_pcg4d_i(x, y, z, w):
    with np.errstate(over="ignore"):
        x, y, z, w = (_i32(v) * _LCG_MUL + _LCG_ADD for v in (x, y, z, w))
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
