"""Ray differentials as Cycles' SVM uses them, and the shading state a Bump node's offset
evaluations read.

Cycles keeps a ray's differential compact, a radius dP (util/differential.h): where two axes are
needed it takes dP along make_orthonormals(Ng) (differential_from_compact), and it solves for
the barycentric differentials du, dv of the hit (differential_dudv) so that any attribute moves
with the point: f(x) = f + dx (du.dx (f1 - f0) + dv.dx (f2 - f0)).

A Bump node evaluates its Height three times, at the point and at the point moved by
filter_width * dPdx and filter_width * dPdy (svm/attribute.h svm_node_bump_P_dx, the *_bump_dx
node variants). Cycles' compiler copies the Height subgraph twice and marks the copies; the
copies of the nodes that have bump variants (Geometry, Texture Coordinate, UV Map, Attribute,
Color Attribute, Wireframe) read the moved point. Ember's compiler copies the subgraph likewise
(program.py) and runs the copies on an OffsetState: the same batch seen from the moved point.
What moves: P, the barycentric (u, v), uv, generated and every named attribute (by their
derivatives), object, camera and window (the moved P taken to those spaces) and the normal
Texture Coordinate reads (re-interpolated). On a back face Cycles has negated dPdu and dPdv
before solving for du, dv: P moves along dPdx as on a front face, but the barycentrics and
attributes move the other way; the state's fields are Cycles' (dPdu, dPdv negated there), and
this follows. What stays: N, Ng, I, the flags, the transforms, the
ray and path data, and whatever a node reads from `state.unshifted` (Camera Data, Tangent and
Geometry's Tangent read the unmoved point, as their Cycles nodes have no bump variant).
"""
from __future__ import annotations

import numpy as np

from .base import column
from .state import Attribute, ShadingState
from .vector_math import normalize, safe_normalize, transform_point

AXES = ("dx", "dy")


def make_orthonormals(n):
    """Cycles' make_orthonormals (util/math_float3.h): a = normalize((1,1,1) x N), or
    normalize((-1,1,1) x N) where N's components are all equal; b = N x a."""
    x, y, z = n[..., 0], n[..., 1], n[..., 2]
    equal = (x == y) & (x == z)
    a = np.stack([z - y, np.where(equal, x + z, x - z), np.where(equal, -y - x, y - x)], axis=-1)
    a = normalize(a)
    return a, np.cross(n, a)


def from_compact(ng, dp):
    """differential_from_compact(Ng, dP): the radius dP along Ng's two orthonormals, (dx, dy)."""
    a, b = make_orthonormals(ng)
    return column(dp) * a, column(dp) * b


def dudv(dpdu, dpdv, dp_dx, dp_dy, ng):
    """differential_dudv: (du.dx, du.dy, dv.dx, dv.dy) solving dP = dPdu du + dPdv dv by
    Cramer's rule in the plane of Ng's two largest components (a zero determinant gives 0)."""
    an = np.abs(ng)
    xn, yn, zn = an[..., 0], an[..., 1], an[..., 2]
    project = (zn < xn) | (zn < yn)
    use_y = project & ((yn < xn) | (yn < zn))  # x is replaced by y, then y by z

    def plane(v):
        first = np.where(use_y, v[..., 1], v[..., 0])
        second = np.where(project, v[..., 2], v[..., 1])
        return first, second

    (ux, uy), (vx, vy) = plane(dpdu), plane(dpdv)
    (xx, xy), (yx, yy) = plane(dp_dx), plane(dp_dy)
    det = ux * vy - vx * uy
    with np.errstate(divide="ignore"):
        inv = np.where(det != 0.0, 1.0 / np.where(det != 0.0, det, 1.0), 0.0)
    return ((xx * vy - xy * vx) * inv, (yx * vy - yy * vx) * inv,
            (xy * ux - xx * uy) * inv, (yy * ux - yx * uy) * inv)


def barycentric_differentials(state):
    """sd->du, sd->dv from the compact dP (differential_dudv_compact): ((du.dx, dv.dx),
    (du.dy, dv.dy)), each (N,)."""
    dx, dy = from_compact(state.Ng, state.dP)
    dudx, dudy, dvdx, dvdy = dudv(state.dPdu, state.dPdv, dx, dy, state.Ng)
    return (dudx, dvdx), (dudy, dvdy)


def position_differentials(state):
    """(dPdx(sd), dPdy(sd)): dPdu du + dPdv dv along each axis (svm/util.h dPdx)."""
    out = []
    for du, dv in barycentric_differentials(state):
        out.append(state.dPdu * column(du) + state.dPdv * column(dv))
    return tuple(out)


# What an offset evaluation needs beyond the fields a node reads.
_MOVE = ("dP", "dPdu", "dPdv", "Ng")
_OFFSET_READS = {"P": ("P",) + _MOVE, "barycentric": ("barycentric",) + _MOVE,
                 "uv": ("uv", "uv_du", "uv_dv") + _MOVE,
                 "generated": ("generated", "generated_du", "generated_dv") + _MOVE,
                 "object": ("P", "object_from_world") + _MOVE, "camera": ("P", "camera_from_world") + _MOVE,
                 "window": ("P", "ndc_from_world") + _MOVE, "texcoord_normal": ("N", "N_du", "N_dv") + _MOVE}


def offset_reads(fields) -> set:
    """The fields an offset evaluation of a node reading `fields` needs."""
    out = set()
    for f in fields:
        out.update(_OFFSET_READS.get(f, (f,)))
        if f.startswith("attribute:"):
            out.update(_MOVE)
    return out


class OffsetState:
    """`base` seen from the point moved by `width` times its differential along `axis` ("dx" or
    "dy"), as Cycles' bump variants of its nodes read it (module docstring)."""

    def __init__(self, base: ShadingState, axis: str, width: float):
        self.base = base
        self.n = base.n
        self.axis = AXES.index(axis)
        self.width = float(width)
        self._moved: dict = {}
        self._attributes: dict = {}

    @property
    def unshifted(self) -> ShadingState:
        return self.base

    def _steps(self):
        """(du, dv) of the move: the barycentric differentials along the axis times the width."""
        if "steps" not in self._moved:
            # Both axes come from one solve: the other axis' offset state reuses it.
            both = self.base.__dict__.get("_barycentric_differentials")
            if both is None:
                both = self.base.__dict__["_barycentric_differentials"] = barycentric_differentials(self.base)
            du, dv = both[self.axis]
            self._moved["steps"] = (du * self.width, dv * self.width)
        return self._moved["steps"]

    def _along(self, value, f_du, f_dv):
        du, dv = self._steps()
        return value + f_du * column(du) + f_dv * column(dv)

    def _make(self, name):
        b = self.base
        if name == "P":  # dPdx(sd) = dPdu du.dx + dPdv dv.dx, times the width
            du, dv = self._steps()
            return b.P + b.dPdu * column(du) + b.dPdv * column(dv)
        if name == "barycentric":
            du, dv = self._steps()
            return b.barycentric + np.stack([du, dv], axis=-1)
        if name in ("uv", "generated"):
            return self._along(getattr(b, name), getattr(b, name + "_du"), getattr(b, name + "_dv"))
        if name == "object":
            return transform_point(b.object_from_world, self.P)
        if name == "camera":
            return transform_point(b.camera_from_world, self.P)
        if name == "window":  # camera_world_to_ndc of the moved point, z 0
            m = np.asarray(b.ndc_from_world, np.float64)
            h = self.P @ m[:3, :3].T + m[:3, 3]
            w = self.P @ m[3, :3] + m[3, 3]
            with np.errstate(all="ignore"):
                ndc = h / column(np.where(w != 0.0, w, 1.0))
            return np.stack([ndc[..., 0], ndc[..., 1], np.zeros_like(ndc[..., 0])], axis=-1)
        if name == "texcoord_normal":
            return safe_normalize(self._along(b.N, b.N_du, b.N_dv))
        return None

    def __getattr__(self, name: str):
        if name.startswith("_"):
            raise AttributeError(name)
        if name not in self._moved:
            value = self._make(name)
            if value is None:
                return getattr(self.base, name)
            self._moved[name] = value
        return self._moved[name]

    def attribute(self, name: str):
        if name not in self._attributes:
            a = self.base.attribute(name)
            if a is not None and a.du is not None and np.ndim(a.value) == 2:
                a = Attribute(a.type, self._along(a.value, a.du, a.dv), a.du, a.dv)
            self._attributes[name] = a
        return self._attributes[name]

