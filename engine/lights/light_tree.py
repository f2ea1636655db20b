"""A light tree: choose one of many lights by its estimated contribution at a shading point.

Binary tree over light bounds (Conty Estevez and Kulla 2018, "Importance Sampling of Many
Lights with Adaptive Tree Splitting"; Cycles' intern/cycles/scene/light_tree.cpp and
kernel/light/tree.h; pbrt-v4's BVHLightSampler). Every node holds the axis-aligned box of its
lights, their power phi and an orientation cone: axis w, theta_o bounding the lights' normals
about w, theta_e the spread of emission about a normal (pi/2 for area lights; theta_o = pi for
emitters that shine every way: points, two-sided triangles). The importance of a node at a
point p (pbrt-v4 LightBounds::Importance, without the receiver's normal, which the LightSet
interface does not carry) is

    I = phi cos(theta') / max(d^2, r^2),   theta' = max(0, theta_w - theta_o - theta_b),

d the distance from p to the box centre, r the radius of the box's bounding sphere, theta_w
the angle between w and the direction centre -> p, theta_b the half-angle the bounding sphere
subtends at p (pi when p is inside it); I = 0 when theta' >= theta_e (no light of the node can
face p). The bounds are conservative, so I = 0 only where no light of the node emits towards p.

Choosing a light: from the root, a child with probability I_child / (I_left + I_right), the
uniform rescaled into the chosen branch; one light per leaf, so the pmf of a light is the
product of the branch probabilities on its path. All shading points descend together, one
level per step (wavefront), and the pmf of given lights at given points walks each light's
path upwards one level per step. Build: median split of the light centroids along the longest
axis of their bounds (balanced: depth ceil(log2 n)).
"""
from __future__ import annotations

import numpy as np

from ..vec import dot

ONE_MINUS_EPSILON = 1.0 - 2.0**-53


def _cone_union(wa, ta, wb, tb):
    """Smallest cone (axis, half-angle) holding cones (wa, ta) and (wb, tb) (pbrt-v4
    DirectionCone Union: the new half-angle is the mean of the two extreme angles)."""
    if ta >= np.pi or tb >= np.pi:
        return wa, np.pi
    td = float(np.arccos(np.clip(wa @ wb, -1.0, 1.0)))
    if min(td + tb, np.pi) <= ta:
        return wa, ta
    if min(td + ta, np.pi) <= tb:
        return wb, tb
    to = 0.5 * (ta + td + tb)
    k = np.cross(wa, wb)
    k_len = np.linalg.norm(k)
    if to >= np.pi or k_len < 1e-12:
        return wa, np.pi
    k = k / k_len
    tr = to - ta  # rotate wa towards wb by tr (Rodrigues; k is perpendicular to wa)
    w = wa * np.cos(tr) + np.cross(k, wa) * np.sin(tr)
    return w / np.linalg.norm(w), to


class LightTree:
    """Light tree over n lights (indices 0..n-1 of the arrays given).

    lo, hi (n,3) float64 bounds of each light; phi (n,) power (> 0); axis (n,3) unit;
    theta_o, theta_e (n,) radians (see the module docstring).
    """

    def __init__(self, lo, hi, phi, axis, theta_o, theta_e):
        n = len(phi)
        self.n_lights = n
        nodes_lo, nodes_hi, nodes_phi, nodes_axis, nodes_to, nodes_te = [], [], [], [], [], []
        left, right, light = [], [], []
        centroid = 0.5 * (lo + hi)

        def new_node():
            for a in (nodes_lo, nodes_hi, nodes_phi, nodes_axis, nodes_to, nodes_te, left, right, light):
                a.append(None)
            return len(left) - 1

        def build(ids):
            k = new_node()
            if len(ids) == 1:
                i = int(ids[0])
                nodes_lo[k], nodes_hi[k], nodes_phi[k] = lo[i], hi[i], phi[i]
                nodes_axis[k], nodes_to[k], nodes_te[k] = axis[i], theta_o[i], theta_e[i]
                left[k], right[k], light[k] = -1, -1, i
                return k
            c = centroid[ids]
            dim = int(np.argmax(c.max(axis=0) - c.min(axis=0)))
            half = len(ids) // 2
            order = np.argpartition(c[:, dim], half)
            a, b = build(ids[order[:half]]), build(ids[order[half:]])
            nodes_lo[k] = np.minimum(nodes_lo[a], nodes_lo[b])
            nodes_hi[k] = np.maximum(nodes_hi[a], nodes_hi[b])
            nodes_phi[k] = nodes_phi[a] + nodes_phi[b]
            nodes_axis[k], nodes_to[k] = _cone_union(nodes_axis[a], nodes_to[a], nodes_axis[b], nodes_to[b])
            nodes_te[k] = max(nodes_te[a], nodes_te[b])
            left[k], right[k], light[k] = a, b, -1
            return k

        build(np.arange(n))
        lo_n, hi_n = np.array(nodes_lo, np.float64), np.array(nodes_hi, np.float64)
        self.center = 0.5 * (lo_n + hi_n)
        self.radius = 0.5 * np.linalg.norm(hi_n - lo_n, axis=1)
        self.phi = np.array(nodes_phi, np.float64)
        self.axis = np.array(nodes_axis, np.float64)
        theta_o_n = np.array(nodes_to, np.float64)
        self.cos_o, self.sin_o = np.cos(theta_o_n), np.sin(theta_o_n)
        self.cos_e = np.cos(np.array(nodes_te, np.float64))
        self.left = np.array(left, np.int64)
        self.right = np.array(right, np.int64)
        self.parent = np.full(len(left), -1, np.int64)
        inner = np.flatnonzero(self.left >= 0)
        self.parent[self.left[inner]] = inner
        self.parent[self.right[inner]] = inner
        self.light = np.array(light, np.int64)
        self.leaf = np.zeros(n, np.int64)
        self.leaf[self.light[self.light >= 0]] = np.flatnonzero(self.light >= 0)
        self.n_nodes = len(left)

    def importance(self, node, p):
        """Importance (M,) of nodes node (M,) at points p (M,3) (module docstring)."""
        v = p - self.center[node]
        d2 = dot(v, v)
        d = np.sqrt(d2)
        r = self.radius[node]
        cos_w = np.divide(dot(v, self.axis[node]), d, out=np.ones_like(d), where=d > 0)
        cos_w = np.clip(cos_w, -1.0, 1.0)
        sin_w = np.sqrt(1.0 - cos_w * cos_w)
        inside = d <= r
        sin_b = np.where(inside, 0.0, np.divide(r, d, out=np.zeros_like(d), where=d > 0))
        cos_b = np.where(inside, -1.0, np.sqrt(np.maximum(1.0 - sin_b * sin_b, 0.0)))
        cos_o, sin_o = self.cos_o[node], self.sin_o[node]
        # theta_x = max(0, theta_w - theta_o), then theta' = max(0, theta_x - theta_b), by the
        # cosine and sine of a difference (no arccos).
        beyond = cos_w < cos_o
        cos_x = np.where(beyond, cos_w * cos_o + sin_w * sin_o, 1.0)
        sin_x = np.where(beyond, sin_w * cos_o - cos_w * sin_o, 0.0)
        cos_p = np.where(cos_x < cos_b, cos_x * cos_b + sin_x * sin_b, 1.0)
        denom = np.maximum(np.maximum(d2, r * r), 1e-30)
        return np.where(cos_p > self.cos_e[node], self.phi[node] * cos_p / denom, 0.0)

    def _branch(self, node, p):
        """Probability (M,) of each child of nodes node (M,) at p: (p_left, p_right)."""
        il = self.importance(self.left[node], p)
        ir = self.importance(self.right[node], p)
        total = il + ir
        pl = np.divide(il, total, out=np.zeros_like(total), where=total > 0)
        pr = np.divide(ir, total, out=np.zeros_like(total), where=total > 0)
        return pl, pr

    def sample(self, p, u):
        """One light per point: index (N,) int64 into the tree's lights and its pmf (N,) (0 where
        no light of the tree can reach p), from points p (N,3) float64 and uniforms u (N,)."""
        n = len(p)
        node = np.zeros(n, np.int64)
        pmf = np.ones(n)
        u = np.asarray(u, np.float64).copy()
        live = np.arange(n)
        while len(live):
            live = live[self.left[node[live]] >= 0]
            if not len(live):
                break
            pl, pr = self._branch(node[live], p[live])
            go_left = u[live] < pl
            chosen = np.where(go_left, pl, pr)
            u[live] = np.minimum(np.where(go_left, u[live], u[live] - pl) / np.where(chosen > 0, chosen, 1.0),
                                 ONE_MINUS_EPSILON)
            pmf[live] *= chosen
            node[live] = np.where(go_left, self.left[node[live]], self.right[node[live]])
            live = live[chosen > 0]
        # Points where every branch had importance 0 stopped early: pmf 0, some light.
        stuck = self.left[node] >= 0
        while stuck.any():
            node[stuck] = self.left[node[stuck]]
            stuck = self.left[node] >= 0
        return self.light[node], np.where(np.isfinite(pmf), pmf, 0.0)

    def pmf(self, light, p):
        """Probability (N,) that `sample` at points p (N,3) chooses lights light (N,)."""
        node = self.leaf[light]
        pmf = np.ones(len(node))
        live = np.flatnonzero(self.parent[node] >= 0)
        while len(live):
            child = node[live]
            up = self.parent[child]
            pl, pr = self._branch(up, p[live])
            pmf[live] *= np.where(self.left[up] == child, pl, pr)
            node[live] = up
            live = live[self.parent[up] >= 0]
        return np.where(np.isfinite(pmf), pmf, 0.0)
