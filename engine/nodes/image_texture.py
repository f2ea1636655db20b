"""Image Texture: an image read at a texture coordinate, projected flat, on a box, a sphere or
a tube (svm/image.h svm_node_tex_image and svm_node_tex_image_box; util/math_float3.h
map_to_sphere and map_to_tube).

The coordinate is the Vector, or the active UV map where it is unlinked (Cycles'
LINK_TEXTURE_UV), through the node's own mapping (texture_mapping.py). Flat reads (x, y);
Sphere and Tube first take the coordinate from the [0, 1] cube to [-1, 1] and read latitude
and longitude about z. Box reads the image three times, on the planes facing x, y and z, mixed
by the object-space shading normal (svm_node_tex_image_box): single faces where the normal is
near an axis, two or three blended where Blend widens the seams. The image is interpolated
and extended as the node says (engine/nodes/image.py), its tile chosen for UDIM images; where
the Alpha output is linked, the colour of an associated image is divided by alpha, as Cycles
compiles the node. Projections run in float32, the kernel's precision, since Closest picks its
texel from them.
"""
from __future__ import annotations

import numpy as np

from . import image, texture_mapping
from .base import components, node, triple

F32 = np.float32
_INTERPOLATION = {"Closest": "CLOSEST", "Linear": "LINEAR", "Cubic": "CUBIC", "Smart": "SMART"}
_1_PI = F32(1.0 / np.pi)  # M_1_PI_F
_1_2PI = F32(0.5 / np.pi)  # M_1_2PI_F


def _reads(node, outputs) -> tuple:
    socket = node.input("Vector")
    fields = () if socket is not None and socket.link is not None else ("uv",)
    if node.prop("projection", "FLAT") == "BOX":
        fields += ("N", "world_from_object")
    return fields


def remap_square(co):
    """texco_remap_square: the [0, 1] cube to [-1, 1]."""
    return (co.astype(F32) - F32(0.5)) * F32(2.0)


def map_to_sphere(co):
    """(u, v) of points about the origin: u the longitude (u = 1/2 toward +y, growing toward -x),
    v the latitude from the -z pole (0) to +z (1); the origin maps to (0, 0), the z axis to u 0."""
    x, y, z = components(co.astype(F32))
    length2 = x * x + y * y + z * z
    on_axis = (x == 0.0) & (y == 0.0)
    u = F32(0.5) - np.arctan2(x, y) * _1_2PI
    u = np.where(on_axis, F32(0.0), u)
    with np.errstate(divide="ignore", invalid="ignore"):
        cos_theta = np.clip(z / np.sqrt(length2), F32(-1.0), F32(1.0))
    v = F32(1.0) - np.arccos(cos_theta) * _1_PI
    some = length2 > 0.0
    return np.where(some, u, F32(0.0)), np.where(some, v, F32(0.0))


def map_to_tube(co):
    """(u, v) of points about the z axis: u the angle about it as map_to_sphere's, v = (z + 1) / 2;
    the axis maps to (0, 0)."""
    x, y, z = components(co.astype(F32))
    length = np.sqrt(x * x + y * y)
    some = length > 0.0
    safe = np.where(some, length, F32(1.0))
    u = (F32(1.0) - np.arctan2(x / safe, y / safe) * _1_PI) * F32(0.5)
    v = (z + F32(1.0)) * F32(0.5)
    return np.where(some, u, F32(0.0)), np.where(some, v, F32(0.0))


def box_weights(n, blend):
    """The weights (N, 3) of the planes facing x, y and z for object-space normals n (N, 3),
    as svm_node_tex_image_box splits the triangle of |n| / (|x| + |y| + |z|) into seven zones:
    corners of one plane, seams of two blended over `blend`, a middle of three."""
    a = np.abs(n)
    a = a / np.sum(a, axis=-1, keepdims=True)
    x, y, z = a[:, 0], a[:, 1], a[:, 2]
    limit = 0.5 * (1.0 + blend)
    w = np.zeros_like(a)
    only_x = (x > limit * (x + y)) & (x > limit * (x + z))
    only_y = ~only_x & (y > limit * (x + y)) & (y > limit * (y + z))
    only_z = ~only_x & ~only_y & (z > limit * (x + z)) & (z > limit * (y + z))
    rest = ~(only_x | only_y | only_z)
    w[only_x, 0] = w[only_y, 1] = w[only_z, 2] = 1.0
    if blend <= 0.0:  # no blending: a point in no corner reads the x plane
        w[rest, 0] = 1.0
        return w
    xy = rest & (z < (1.0 - limit) * (y + x))
    yz = rest & ~xy & (x < (1.0 - limit) * (y + z))
    xz = rest & ~xy & ~yz & (y < (1.0 - limit) * (x + z))
    middle = rest & ~(xy | yz | xz)

    def seam(p, q):
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.clip((p / (p + q) - 0.5 * (1.0 - blend)) / blend, 0.0, 1.0)
    s = seam(x[xy], y[xy])
    w[xy, 0], w[xy, 1] = s, 1.0 - s
    s = seam(y[yz], z[yz])
    w[yz, 1], w[yz, 2] = s, 1.0 - s
    s = seam(x[xz], z[xz])
    w[xz, 0], w[xz, 2] = s, 1.0 - s
    w[middle] = ((2.0 - limit) * a[middle] + (limit - 1.0)) / (2.0 * limit - 1.0)
    return w


def _box(co, n, texels, interpolation, extension, blend, unassociate):
    """svm_node_tex_image_box: the three planes' lookups, each where its weight is not 0, at
    coordinates turned so that no plane reads the image mirrored."""
    w = box_weights(n, blend)
    x, y, z = components(co)
    planes = (
        (np.where(n[:, 0] < 0.0, 1.0 - y, y), z),
        (np.where(n[:, 1] > 0.0, 1.0 - x, x), z),
        (np.where(n[:, 2] > 0.0, 1.0 - y, y), x),
    )
    out = np.zeros((len(co), 4))
    for k, (u, v) in enumerate(planes):
        at = np.flatnonzero(w[:, k] > 0.0)
        if len(at):
            out[at] += w[at, k:k + 1] * image.sample(texels, u[at], v[at], interpolation, extension, unassociate)
    return out


def _object_normal(state):
    """object_inverse_normal_transform: the shading normal in object space (M^T n, normalised)."""
    m = np.broadcast_to(state.world_from_object, (state.n, 4, 4))[:, :3, :3]
    n = np.einsum("nji,nj->ni", m, np.broadcast_to(state.N, (state.n, 3)))
    length = np.linalg.norm(n, axis=-1, keepdims=True)
    return np.where(length > 0.0, n / np.where(length > 0.0, length, 1.0), 0.0)


def texture(co, texels, projection: str, interpolation: str, extension: str, blend: float = 0.0,
            unassociate: bool = False, normal=None) -> np.ndarray:
    """RGBA (N, 4) of the image (Texels, Tiles or None) at mapped coordinates co (N, 3);
    `normal`: object-space shading normals (N, 3), for BOX."""
    interpolation = _INTERPOLATION.get(interpolation, "LINEAR")
    if projection == "BOX":
        if isinstance(texels, image.Tiles):
            texels = texels.first()
        return _box(co, normal, texels, interpolation, extension, blend, unassociate)
    if projection == "SPHERE":
        u, v = map_to_sphere(remap_square(co))
    elif projection == "TUBE":
        u, v = map_to_tube(remap_square(co))
    else:
        u, v = co[:, 0], co[:, 1]
    return image.sample_tiles(texels, u, v, interpolation, extension, unassociate)


@node("ShaderNodeTexImage", "Texture", reads=_reads, uses_links=True)
def image_texture(node, inputs, state, used):
    co = triple(texture_mapping.coordinate(node, inputs, state, "uv"))
    projection = node.prop("projection", "FLAT")
    normal = _object_normal(state) if projection == "BOX" else None
    points = co.reshape(-1, 3) if normal is None else np.broadcast_to(co, normal.shape)
    rgba = texture(points, node.prop("image"), projection, node.prop("interpolation", "Linear"),
                   node.prop("extension", "REPEAT"), float(node.prop("projection_blend", 0.0)),
                   "Alpha" in used, normal)
    if co.ndim == 1 and normal is None:  # a constant coordinate: constant outputs
        rgba = rgba[0]
    return {"Color": rgba[..., :3], "Alpha": rgba[..., 3]}


NODES = (image_texture,)
