"""Gabor Texture, as Cycles computes it (kernel/svm/gabor.h, Blender 4.3+): sparse Gabor
convolution noise (Lagae et al. 2009) with Tavernier et al.'s stratified impulses and
Bernoulli weights (2019), evaluated as a phasor (Tricard et al. 2019) for its Phase and
Intensity.

Each unit cell holds 8 impulses: a kernel centre, a weight of +-1 and an orientation, drawn
from Jenkins float hashes of (cell, 3i + k) (engine/nodes/hash.py). A point sums the kernels
of the 3^d cells around its own that reach it (a kernel is windowed to radius 1). The hashes
depend only on the cell, so they are drawn once per distinct cell of the batch and gathered
to its points; the kernels, which need sines and exponentials, only at the points they reach.

Cycles works in float32; the cell of a point (floor of coordinates * scale) is found in
float32 as there, everything after it in float64.
"""
from __future__ import annotations

import itertools

import numpy as np

from . import hash as H
from . import texture_mapping
from .base import node, scalar, triple

IMPULSES_COUNT = 8
# Six standard deviations of the summed kernels map to [-1, 1]; Cycles' approximations of the
# deviation: sqrt(impulses * second moment of the weights (1/2) * integral of a kernel squared
# (1/4 in 2D, 1/(4 sqrt 2) in 3D)).
NORMALIZATION_2D = 6.0 * np.sqrt(IMPULSES_COUNT * 0.5 * 0.25)
NORMALIZATION_3D = 6.0 * np.sqrt(IMPULSES_COUNT * 0.5 / (4.0 * np.sqrt(2.0)))


def _at(x, sel):
    """A per-point value at the points `sel`; a constant (0-d, or one direction) stays itself."""
    return x[sel] if np.ndim(x) and np.shape(x)[0] > 1 else x


def _kernel(position, frequency_vector):
    """Cycles' compute_{2,3}d_gabor_kernel as a phasor (cos, sin): a unit Gaussian windowed by
    a Hann window, modulated along the frequency vector (components)."""
    d2 = sum(x * x for x in position)
    envelope = np.exp(-np.pi * d2) * (0.5 + 0.5 * np.cos(np.pi * d2))
    angle = 2.0 * np.pi * sum(x * f for x, f in zip(position, frequency_vector))
    return envelope * np.cos(angle), envelope * np.sin(angle)


def _cell_draws(cells, i: int):
    """What impulse i of each cell (d components, float32) draws: kernel centre (d
    components), orientation hashes (1 in 2D, 2 in 3D), weight hash."""
    seeds = [np.float32(3 * i + k) for k in range(3)]
    if len(cells) == 2:
        return (H.hash_float_to_float2(*cells, seeds[1]), (H.hash_float(*cells, seeds[0]),),
                H.hash_float(*cells, seeds[2]))
    return (H.hash_float_to_float3(*cells, seeds[1]), H.hash_float_to_float2(*cells, seeds[0]),
            H.hash_float(*cells, seeds[2]))


def _orientation_3d(base, isotropy, random_angles):
    """Cycles' compute_3d_orientation: the base direction (components) turned by random
    spherical angles (in [0, pi)) times the isotropy; the base itself where isotropy is 0."""
    with np.errstate(all="ignore"):
        inclination = np.arccos(base[2])
        azimuth = np.where(base[1] < 0.0, -1.0, 1.0) * np.arccos(base[0] / np.hypot(base[0], base[1]))
    inclination = inclination + random_angles[0] * np.pi * isotropy
    azimuth = azimuth + random_angles[1] * np.pi * isotropy
    turned = (np.sin(inclination) * np.cos(azimuth), np.sin(inclination) * np.sin(azimuth), np.cos(inclination))
    return tuple(np.where(isotropy == 0.0, b, t) for b, t in zip(base, turned))


def gabor_noise(coord32, frequency, isotropy, orientation):
    """The phasor (x, y) summed over the 3^d cells around each point of float32 coordinates
    (d components (N,)); orientation: an angle (2D) or a unit vector's components (3D); each
    parameter per point (N,) or constant."""
    d, n = len(coord32), len(coord32[0])
    cell = [np.floor(c) for c in coord32]
    local = [c.astype(np.float64) - k for c, k in zip(coord32, cell)]
    cells, owner = np.unique(np.stack(cell, axis=1), axis=0, return_inverse=True)
    owner = owner.reshape(-1)
    phasor_x, phasor_y = np.zeros(n), np.zeros(n)
    for offset in itertools.product((-1, 0, 1), repeat=d):
        position = [x - o for x, o in zip(local, offset)]
        neighbours = tuple(cells[:, a] + np.float32(offset[a]) for a in range(d))  # float32, as Cycles
        for i in range(IMPULSES_COUNT):
            center, angles, weight = _cell_draws(neighbours, i)
            to_point = [x - np.take(c, owner) for x, c in zip(position, center)]
            reached = np.flatnonzero(sum(x * x for x in to_point) < 1.0)
            if reached.size == 0:
                continue
            to_point = [x[reached] for x in to_point]
            cell_of = owner[reached]
            iso = _at(isotropy, reached)
            if d == 2:
                angle = _at(orientation, reached) + (np.take(angles[0], cell_of) - 0.5) * np.pi * iso
                direction = (np.cos(angle), np.sin(angle))
            else:
                base = tuple(_at(o, reached) for o in orientation)
                direction = _orientation_3d(base, iso, [np.take(a, cell_of) for a in angles])
            f = _at(frequency, reached)
            x, y = _kernel(to_point, [f * c for c in direction])
            sign = np.where(np.take(weight, cell_of) < 0.5, -1.0, 1.0)
            phasor_x[reached] += sign * x
            phasor_y[reached] += sign * y
    return phasor_x, phasor_y


def _f64(x) -> np.ndarray:
    """A float32 input as the float64 of the very value Cycles reads."""
    return np.asarray(x, np.float32).astype(np.float64)


@node("ShaderNodeTexGabor", "Texture", reads=texture_mapping.unlinked_reads("generated"))
def gabor_texture(node, inputs, state):
    """Cycles' svm_node_tex_gabor: Value (the phasor's sine part), Phase and Intensity, each
    mapped to [0, 1] by six standard deviations."""
    vector = texture_mapping.coordinate(node, inputs, state)
    scale = np.asarray(inputs["Scale"], np.float32)
    coord = np.asarray(triple(vector), np.float32) * scale[..., None]
    three_d = node.prop("gabor_type", "2D") == "3D"
    d = 3 if three_d else 2
    frequency = np.maximum(0.001, _f64(inputs["Frequency"]))
    isotropy = 1.0 - np.clip(_f64(inputs["Anisotropy"]), 0.0, 1.0)
    if three_d:
        o = _f64(triple(inputs["Orientation 3D"]))
        with np.errstate(all="ignore"):
            o = o / np.sqrt(np.sum(o * o, axis=-1, keepdims=True))
        orientation = tuple(o[..., a] for a in range(3))
    else:
        orientation = _f64(inputs["Orientation 2D"])
    # () where every input is constant, else (N,): the coordinates go per point if anything is
    parameters = (frequency, isotropy) + (orientation if three_d else (orientation,))
    shape = np.broadcast_shapes(coord.shape[:-1], *(np.shape(v) for v in parameters))
    coord = np.broadcast_to(coord, shape + (3,)).reshape(-1, 3)
    coord32 = tuple(np.ascontiguousarray(coord[:, a]) for a in range(d))
    with np.errstate(all="ignore"):
        x, y = gabor_noise(coord32, frequency, isotropy, orientation)
    norm = NORMALIZATION_3D if three_d else NORMALIZATION_2D
    return {"Value": lambda: scalar((y / norm * 0.5 + 0.5).reshape(shape)),
            "Phase": lambda: scalar(((np.arctan2(y, x) + np.pi) / (2.0 * np.pi)).reshape(shape)),
            "Intensity": lambda: scalar((np.hypot(x, y) / norm).reshape(shape))}


NODES = (gabor_texture,)
