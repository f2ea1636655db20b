"""A light tree: choose one of many lights by its estimated contribution at a shading point.

Binary tree over light bounds (Conty Estevez and Kulla 2018, "Importance Sampling of Many
Lights with Adaptive Tree Splitting"; Cycles' intern/cycles/scene/light_tree.cpp and
kernel/light/tree.h; pbrt-v4's BVHLightSampler). Every node holds the axis-aligned box of its
lights, their power phi and an orientation cone: axis w, theta_o bounding the lights' normals
about w, theta_e the spread of emission about a normal (pi/2 for area lights; theta_o = pi for
points, which shine every way), and whether a light of the node is two-sided (emissive
triangles: normals in the cone or its mirror image, theta_w then measured from +-w). The
importance of a node at a point p (pbrt-v4 LightBounds::Importance, without the receiver's
normal, which the LightSet interface does not carry) is

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
    theta_o, theta_e (n,) radians; two_sided (n,) bool (see the module docstring).
    """

    def __init__(self, lo, hi, phi, axis, theta_o, theta_e, two_sided):
        n = len(phi)
        self.n_lights = n
        nodes_lo, nodes_hi, nodes_phi, nodes_axis, nodes_to, nodes_te, nodes_2 = [], [], [], [], [], [], []
        left, right, light = [], [], []
        centroid = 0.5 * (lo + hi)

        def new_node():
            for a in (nodes_lo, nodes_hi, nodes_phi, nodes_axis, nodes_to, nodes_te, nodes_2, left, right, light):
                a.append(None)
            return len(left) - 1

        def build(ids):
            k = new_node()
            if len(ids) == 1:
                i = int(ids[0])
                nodes_lo[k], nodes_hi[k], nodes_phi[k] = lo[i], hi[i], phi[i]
                nodes_axis[k], nodes_to[k], nodes_te[k], nodes_2[k] = axis[i], theta_o[i], theta_e[i], two_sided[i]
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
            wa, wb = nodes_axis[a], nodes_axis[b]
            if (nodes_2[a] or nodes_2[b]) and wa @ wb < 0:  # a two-sided cone may be mirrored
                wb = -wb if nodes_2[b] else wb
                wa = -wa if not nodes_2[b] else wa
            nodes_axis[k], nodes_to[k] = _cone_union(wa, nodes_to[a], wb, nodes_to[b])
            nodes_te[k] = max(nodes_te[a], nodes_te[b])
            nodes_2[k] = nodes_2[a] or nodes_2[b]
            left[k], right[k], light[k] = a, b, -1
            return k

        build(np.arange(n))
        lo_n, hi_n = np.array(nodes_lo, np.float64), np.array(nodes_hi, np.float64)
        theta_o_n = np.array(nodes_to, np.float64)
        # One row per node field, one gather per importance call; float32 (the importance only
        # steers the choice: the pmf is the product of the probabilities actually used).
        self.fields = np.ascontiguousarray(np.vstack([
            (0.5 * (lo_n + hi_n)).T, np.array(nodes_axis, np.float64).T,
            0.5 * np.linalg.norm(hi_n - lo_n, axis=1), np.array(nodes_phi, np.float64),
            np.cos(theta_o_n), np.sin(theta_o_n), np.cos(np.array(nodes_te, np.float64)),
            np.array(nodes_2, np.float64)]), np.float32)
        # Every node shines every way (points only): the cone terms are 1.
        self.omni = bool(np.all(theta_o_n >= np.pi))
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

    def importance(self, node, px, py, pz):
        """Importance (M,) float32 of nodes node (M,) at points (px, py, pz) (M,) float32 each
        (module docstring)."""
        cx, cy, cz, wx, wy, wz, r, phi, cos_o, sin_o, cos_e, two_sided = np.take(self.fields, node, axis=1)
        vx, vy, vz = px - cx, py - cy, pz - cz
        d2 = vx * vx + vy * vy + vz * vz
        denom = np.maximum(np.maximum(d2, r * r), np.float32(1e-30))
        if self.omni:
            return phi / denom
        d = np.sqrt(d2)
        cos_w = (vx * wx + vy * wy + vz * wz) / np.maximum(d, np.float32(1e-30))
        np.abs(cos_w, out=cos_w, where=two_sided > 0)
        sin_w = np.sqrt(np.maximum(1.0 - cos_w * cos_w, 0.0, dtype=np.float32))
        sin_b = np.minimum(r / np.maximum(d, np.float32(1e-30)), 1.0, dtype=np.float32)
        cos_b = np.sqrt(1.0 - sin_b * sin_b, dtype=np.float32)
        # theta_x = max(0, theta_w - theta_o), then theta' = max(0, theta_x - theta_b), by the
        # cosine and sine of a difference (no arccos); inside the bounding sphere theta_b = pi.
        beyond = cos_w < cos_o
        cos_x = np.where(beyond, cos_w * cos_o + sin_w * sin_o, np.float32(1.0))
        sin_x = np.where(beyond, sin_w * cos_o - cos_w * sin_o, np.float32(0.0))
        cos_p = np.where((cos_x < cos_b) & (d > r), cos_x * cos_b + sin_x * sin_b, np.float32(1.0))
        return np.where(cos_p > cos_e, phi * cos_p / denom, np.float32(0.0))

    def _branch(self, node, p):
        """Probability (M,) of each child of nodes node (M,) at p (3 columns): (p_left, p_right)."""
        il = self.importance(self.left[node], *p).astype(np.float64)
        ir = self.importance(self.right[node], *p).astype(np.float64)
        total = il + ir
        pl = np.divide(il, total, out=np.zeros_like(total), where=total > 0)
        pr = np.divide(ir, total, out=np.zeros_like(total), where=total > 0)
        return pl, pr

    def sample(self, p, u):
        """One light per point: index (N,) int64 into the tree's lights and its pmf (N,) (0 where
        no light of the tree can reach p), from points p (N,3) float64 and uniforms u (N,).
        The live points descend together, compacted as they reach a leaf."""
        n = len(p)
        leaf = np.zeros(n, np.int64)
        pmf = np.zeros(n)
        rows = np.arange(n)  # the live points, with their node, pmf, uniform and position
        node, pmf_l, u_l = np.zeros(n, np.int64), np.ones(n), np.asarray(u, np.float64).copy()
        p_l = [np.ascontiguousarray(p[:, k], np.float32) for k in range(3)]
        while len(rows):
            done = (self.left[node] < 0) | (pmf_l == 0)
            if done.any():
                leaf[rows[done]], pmf[rows[done]] = node[done], pmf_l[done]
                go = np.flatnonzero(~done)
                rows, node, pmf_l, u_l = rows[go], node[go], pmf_l[go], u_l[go]
                p_l = [c[go] for c in p_l]
                if not len(rows):
                    break
            pl, pr = self._branch(node, p_l)
            go_left = u_l < pl
            chosen = np.where(go_left, pl, pr)
            u_l = np.minimum(np.where(go_left, u_l, u_l - pl) / np.where(chosen > 0, chosen, 1.0), ONE_MINUS_EPSILON)
            pmf_l *= chosen
            node = np.where(go_left, self.left[node], self.right[node])
        # Points where every branch had importance 0 stopped early: pmf 0, some light below.
        stuck = self.left[leaf] >= 0
        while stuck.any():
            leaf[stuck] = self.left[leaf[stuck]]
            stuck = self.left[leaf] >= 0
        return self.light[leaf], pmf

    def pmf(self, light, p):
        """Probability (N,) that `sample` at points p (N,3) chooses lights light (N,): the
        product of the branch probabilities on the light's path, walked upwards."""
        node = self.leaf[light]
        p = [np.ascontiguousarray(p[:, k], np.float32) for k in range(3)]
        pmf = np.ones(len(node))
        live = np.flatnonzero(self.parent[node] >= 0)
        while len(live):
            child = node[live]
            up = self.parent[child]
            pl, pr = self._branch(up, [c[live] for c in p])
            pmf[live] *= np.where(self.left[up] == child, pl, pr)
            node[live] = up
            live = live[self.parent[up] >= 0]
        return pmf
