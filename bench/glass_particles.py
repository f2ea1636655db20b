"""An independent particle tracer of the caustic bench scenes (a glass sphere on a floor).

No Ember code: plain NumPy on the scene's numbers. The glass sphere is the scene's own
flat-faceted icosphere, which is convex, so a ray meets it where it crosses the facet planes
(t_enter = the largest plane crossing of the planes the ray enters, t_exit the smallest of
those it leaves): exact for the facets, one (N,3) x (3,F) product per query. Smooth
dielectric with Fresnel's exact unpolarised reflectance at both interfaces, total internal
reflection, any number of internal bounces (reflect or refract chosen with probability F,
which keeps every photon's flux). Floor (4 x 4 m, z = 0) and back wall (y = 2 m) are
Lambertian with albedo RHO (Russian roulette with the albedo). The world is black.

Light: a radius-0 point light (uniform directions, flux 4 pi I), a sphere light of radius r
(origin uniform on the sphere, direction cosine-weighted outward, flux 4 pi^2 r^2 L) or the
emissive icosphere (its facets' area A, radiance L outward: origin uniform on the facets,
direction cosine-weighted, flux pi A L). The emitter itself does not block photons (it
intercepts a small fraction, ~ (r / 2 m)^2, of the light bouncing back up).

What it returns (per channel-free unit of flux: multiply by the channel's I or L):
  - the flux that reaches the floor through the glass (the first diffuse hit after one or
    more glass interactions, at least one of them a refraction), and the flux the sphere
    reflects onto the floor without entering it, with standard errors (through_se, and
    floor_se of their sum: what a caustic photon map stores on the floor);
  - per-pixel floor irradiance for a camera, split into direct light, L S+ D (light whose
    every bounce so far was on the glass) and the rest, from the photons' floor hits binned
    by the pixel whose footprint they fall in (footprint area from the pixel's corners
    projected onto the floor): the pixel's floor radiance is RHO / pi x E.
"""
from __future__ import annotations

import numpy as np

RHO = 0.8                  # floor and wall albedo (scenes/build_bench.py "Grey")
IOR = 1.5
FLOOR_HALF = 2.0           # floor: |x|, |y| <= 2, z = 0
WALL_Y, WALL_TOP = 2.0, 2.5
EPS = 1e-7


class Sphere:
    """A convex polyhedron from its triangles (F,3,3): outward unit normals n (F,3), plane
    offsets h (F,) with n.x = h on facet plane, bounding centre c and radius r."""

    def __init__(self, tris: np.ndarray):
        tris = np.asarray(tris, np.float64)
        self.c = tris.reshape(-1, 3).mean(axis=0)
        n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
        n /= np.linalg.norm(n, axis=1)[:, None]
        flip = np.einsum("ij,ij->i", n, tris[:, 0] - self.c) < 0
        n[flip] *= -1
        self.n, self.h = n, np.einsum("ij,ij->i", n, tris[:, 0])
        self.r = float(np.linalg.norm(tris.reshape(-1, 3) - self.c, axis=1).max())

    def enter(self, o, d):
        """(t (N,), facet (N,)) where rays from outside enter; t = inf where they miss."""
        t = np.full(len(o), np.inf)
        facet = np.zeros(len(o), np.int64)
        oc = o - self.c
        b = np.einsum("ij,ij->i", oc, d)
        near = (b * b - (np.einsum("ij,ij->i", oc, oc) - self.r * self.r) > 0) & (b < 0)
        rows = np.flatnonzero(near)
        for s in range(0, len(rows), 4096):
            r = rows[s:s + 4096]
            dn = d[r] @ self.n.T
            tp = (self.h[None] - o[r] @ self.n.T) / np.where(dn != 0, dn, 1e-300)
            t_in = np.where(dn < 0, tp, -np.inf)
            t_out = np.where(dn > 0, tp, np.inf)
            k = np.argmax(t_in, axis=1)
            a, z = t_in[np.arange(len(r)), k], t_out.min(axis=1)
            hit = (a < z) & (a > EPS)
            t[r[hit]], facet[r[hit]] = a[hit], k[hit]
        return t, facet

    def exit(self, o, d):
        """(t (N,), facet (N,)) where rays from inside leave."""
        t, facet = np.zeros(len(o)), np.zeros(len(o), np.int64)
        for s in range(0, len(o), 4096):
            dn = d[s:s + 4096] @ self.n.T
            tp = (self.h[None] - o[s:s + 4096] @ self.n.T) / np.where(dn != 0, dn, 1e-300)
            t_out = np.where((dn > 0) & (tp > -EPS), tp, np.inf)
            k = np.argmin(t_out, axis=1)
            t[s:s + 4096], facet[s:s + 4096] = t_out[np.arange(len(k)), k], k
        return t, facet


def fresnel(cos_i, eta):
    """Unpolarised Fresnel reflectance and cos of the refracted ray; eta = n_t / n_i."""
    sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return np.where(sin2_t >= 1.0, 1.0, 0.5 * (rs * rs + rp * rp)), cos_t


def _frame(n):
    a = np.where(np.abs(n[:, :1]) > 0.9, np.array([[0.0, 1.0, 0.0]]), np.array([[1.0, 0.0, 0.0]]))
    t = np.cross(a, n)
    t /= np.linalg.norm(t, axis=1)[:, None]
    return t, np.cross(n, t)


def cosine_dirs(n, g):
    u1, u2 = g.random(len(n)), g.random(len(n))
    r, phi = np.sqrt(u1), 2 * np.pi * u2
    t, b = _frame(n)
    return (r * np.cos(phi))[:, None] * t + (r * np.sin(phi))[:, None] * b + np.sqrt(1 - u1)[:, None] * n


def _planes(o, d):
    """(t, normal) of the first hit on the floor or the back wall (inf: none)."""
    tf = np.where(d[:, 2] < 0, -o[:, 2] / np.where(d[:, 2] < 0, d[:, 2], -1.0), np.inf)
    pf = o + np.where(np.isfinite(tf), tf, 0)[:, None] * d
    tf = np.where((np.abs(pf[:, 0]) <= FLOOR_HALF) & (np.abs(pf[:, 1]) <= FLOOR_HALF) & (tf > EPS), tf, np.inf)
    tw = np.where(d[:, 1] > 0, (WALL_Y - o[:, 1]) / np.where(d[:, 1] > 0, d[:, 1], 1.0), np.inf)
    pw = o + np.where(np.isfinite(tw), tw, 0)[:, None] * d
    tw = np.where((np.abs(pw[:, 0]) <= FLOOR_HALF) & (pw[:, 2] >= 0) & (pw[:, 2] <= WALL_TOP) & (tw > EPS), tw, np.inf)
    wall = tw < tf
    n = np.where(wall[:, None], np.array([[0.0, -1.0, 0.0]]), np.array([[0.0, 0.0, 1.0]]))
    return np.minimum(tf, tw), n, wall


class Camera:
    """Pixel footprints on the floor: pixel (row from the top, column) -> index, area."""

    def __init__(self, world_from_camera, window, width, sphere: Sphere):
        self.m = np.asarray(world_from_camera, np.float64)
        self.window, self.w = window, width
        left, right, bottom, top = window
        xs = left + np.arange(width + 1) / width * (right - left)
        ys = top - np.arange(width + 1) / width * (top - bottom)
        X, Y = np.meshgrid(xs, ys)
        d = np.stack([X, Y, -np.ones_like(X)], -1) @ self.m[:3, :3].T
        e = self.m[:3, 3]
        t = -e[2] / d[..., 2]
        P = e + t[..., None] * d  # corners on the floor
        a, b, c, q = P[:-1, :-1], P[:-1, 1:], P[1:, 1:], P[1:, :-1]
        self.area = 0.5 * np.abs(np.cross(c - a, q - b)[..., 2])
        self.ok = (t[:-1, :-1] > 0) & (t[1:, 1:] > 0) & (t[:-1, 1:] > 0) & (t[1:, :-1] > 0)

    def pixel(self, p):
        """Pixel index (N,) of floor points p (N,3); -1 outside the image or behind."""
        v = (p - self.m[:3, 3]) @ self.m[:3, :3]  # camera space
        left, right, bottom, top = self.window
        z = -v[:, 2]
        x, y = v[:, 0] / np.where(z > 0, z, 1), v[:, 1] / np.where(z > 0, z, 1)
        col = np.floor((x - left) / (right - left) * self.w).astype(np.int64)
        row = np.floor((top - y) / (top - bottom) * self.w).astype(np.int64)
        ok = (z > 0) & (col >= 0) & (col < self.w) & (row >= 0) & (row < self.w)
        return np.where(ok, row * self.w + col, -1)


def emit_point(pos, n, g):
    """Origins, directions and flux per unit intensity of n photons of a point light."""
    mu = 1 - 2 * g.random(n)
    phi = 2 * np.pi * g.random(n)
    s = np.sqrt(1 - mu * mu)
    d = np.stack([s * np.cos(phi), s * np.sin(phi), mu], 1)
    return np.repeat(np.asarray(pos, np.float64)[None], n, 0), d, 4 * np.pi


def emit_sphere(centre, radius, n, g):
    """The same for a sphere light (Blender's point light of radius r, Soft Falloff off):
    origin uniform on the sphere, direction cosine-weighted outward, per unit radiance."""
    mu = 1 - 2 * g.random(n)
    phi = 2 * np.pi * g.random(n)
    s = np.sqrt(1 - mu * mu)
    nrm = np.stack([s * np.cos(phi), s * np.sin(phi), mu], 1)
    d = cosine_dirs(nrm, g)
    return np.asarray(centre, np.float64) + radius * nrm + 1e-9 * d, d, np.pi * 4 * np.pi * radius * radius


def _cone(o, target, radius, g):
    """Directions (N,3) uniform in the cone from origins o (N,3) around a sphere (target,
    radius), and the cone's solid angle (N,)."""
    axis = np.asarray(target, np.float64) - o
    dist = np.linalg.norm(axis, axis=1)
    axis /= dist[:, None]
    cos_max = np.sqrt(1 - (radius / dist) ** 2)
    mu = 1 - g.random(len(o)) * (1 - cos_max)
    phi = 2 * np.pi * g.random(len(o))
    t, b = _frame(axis)
    s = np.sqrt(1 - mu * mu)
    d = mu[:, None] * axis + (s * np.cos(phi))[:, None] * t + (s * np.sin(phi))[:, None] * b
    return d, 2 * np.pi * (1 - cos_max)


def aim_point(pos, target, radius):
    """emit(n, g) of a point light whose photons all head for the sphere (target, radius)
    bounding the glass: flux per unit intensity = the cone's solid angle. For the flux
    through the glass only (what misses the sphere is left out)."""
    def emit(n, g):
        o = np.repeat(np.asarray(pos, np.float64)[None], n, 0)
        d, omega = _cone(o, target, radius, g)
        return o, d, omega
    return emit


def aim_sphere_light(centre, r, target, radius):
    """The same for a sphere light of radius r: origin uniform on it (area A), direction
    uniform in the cone; flux per unit radiance A cos+ omega."""
    def emit(n, g):
        mu = 1 - 2 * g.random(n)
        phi = 2 * np.pi * g.random(n)
        s = np.sqrt(1 - mu * mu)
        nrm = np.stack([s * np.cos(phi), s * np.sin(phi), mu], 1)
        o = np.asarray(centre, np.float64) + r * nrm
        d, omega = _cone(o, target, radius, g)
        return o + 1e-9 * d, d, 4 * np.pi * r * r * np.maximum(np.einsum("ij,ij->i", nrm, d), 0.0) * omega
    return emit


def emit_mesh(tris, n, g):
    """The same for a closed emissive mesh (F,3,3), one-sided outward, per unit radiance."""
    tris = np.asarray(tris, np.float64)
    c = tris.reshape(-1, 3).mean(axis=0)
    nrm = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    area = 0.5 * np.linalg.norm(nrm, axis=1)
    nrm /= (2 * area)[:, None]
    nrm *= np.where(np.einsum("ij,ij->i", nrm, tris[:, 0] - c) < 0, -1.0, 1.0)[:, None]
    f = g.choice(len(tris), n, p=area / area.sum())
    u, v = g.random(n), g.random(n)
    su = np.sqrt(u)
    o = ((1 - su)[:, None] * tris[f, 0] + (su * (1 - v))[:, None] * tris[f, 1] + (su * v)[:, None] * tris[f, 2])
    d = cosine_dirs(nrm[f], g)
    return o + 1e-9 * d, d, np.pi * area.sum()


def trace(sphere: Sphere, emit, n_photons: int, seed: int, camera: Camera | None = None, batch: int = 1 << 20,
          max_bounces: int = 64, caustic_only: bool = False):
    """Trace n_photons; flux per unit emitter strength. Returns a dict: through (flux onto the
    floor through the glass), reflected (flux the sphere reflects onto the floor), power, and
    with a camera E_direct, E_caustic, E_rest: (W*W,) floor irradiance per pixel footprint.
    caustic_only: photons end at their first diffuse hit (enough for through and reflected)."""
    g = np.random.default_rng(seed)
    out = {"through": 0.0, "reflected": 0.0, "through_sq": 0.0, "floor_sq": 0.0, "power": 0.0, "n": n_photons}
    npx = camera.w * camera.w if camera else 0
    for key in ("E_direct", "E_caustic", "E_rest"):
        out[key] = np.zeros(npx)
    done = 0
    while done < n_photons:
        m = min(batch, n_photons - done)
        done += m
        o, d, power = emit(m, g)
        w = np.broadcast_to(np.asarray(power, np.float64), (m,)) / n_photons
        out["power"] += w.sum()
        inside = np.zeros(m, bool)
        specular = np.ones(m, bool)   # every bounce so far on the glass
        refracted = np.zeros(m, bool)  # entered the glass
        depth = np.zeros(m, np.int64)
        per_photon = np.zeros(m)      # flux through the glass onto the floor, per photon (variance)
        per_photon_floor = np.zeros(m)  # the same plus what the sphere reflects onto the floor
        idx = np.arange(m)
        for _ in range(max_bounces * 2):
            if not len(o):
                break
            t_s = np.full(len(o), np.inf)
            f_s = np.zeros(len(o), np.int64)
            if (~inside).any():
                r = np.flatnonzero(~inside)
                t_s[r], f_s[r] = sphere.enter(o[r], d[r])
            if inside.any():
                r = np.flatnonzero(inside)
                t_s[r], f_s[r] = sphere.exit(o[r], d[r])
            t_p, n_p, _ = _planes(o, d)
            on_glass = t_s < t_p
            on_plane = ~on_glass & np.isfinite(t_p)
            # diffuse hits: record, then reflect (roulette with the albedo)
            r = np.flatnonzero(on_plane)
            p = o[r] + t_p[r, None] * d[r]
            floor = n_p[r, 2] > 0.5
            fl = r[floor]
            caus = specular[fl] & (depth[fl] > 0)
            thr = caus & refracted[fl]
            out["through"] += w[fl][thr].sum()
            out["reflected"] += w[fl][caus & ~refracted[fl]].sum()
            np.add.at(per_photon, idx[fl][thr], w[fl][thr])
            np.add.at(per_photon_floor, idx[fl][caus], w[fl][caus])
            if camera is not None:
                pix = camera.pixel(p[floor])
                good = pix >= 0
                first = depth[fl] == 0
                for key, sel in (("E_direct", first), ("E_caustic", caus), ("E_rest", ~first & ~caus)):
                    k = good & sel
                    out[key] += np.bincount(pix[k], weights=w[fl][k], minlength=npx)
            survive = g.random(len(r)) < (0.0 if caustic_only else RHO)
            rs = r[survive]
            o_new, d_new = p[survive], cosine_dirs(n_p[rs], g)
            # glass hits: Fresnel choice
            q = np.flatnonzero(on_glass)
            pg = o[q] + t_s[q, None] * d[q]
            nf = sphere.n[f_s[q]] * np.where(inside[q], -1.0, 1.0)[:, None]  # facing the ray
            cos_i = -np.einsum("ij,ij->i", d[q], nf)
            eta = np.where(inside[q], 1.0 / IOR, IOR)
            F, cos_t = fresnel(cos_i, eta)
            refl = g.random(len(q)) < F
            dr = d[q] + 2 * cos_i[:, None] * nf
            dt = d[q] / eta[:, None] + (cos_i / eta - cos_t)[:, None] * nf
            dg = np.where(refl[:, None], dr, dt)
            dg /= np.linalg.norm(dg, axis=1)[:, None]
            keep = np.concatenate([rs, q])
            o = np.concatenate([o_new + 1e-9 * d_new, pg + 1e-9 * dg])
            d = np.concatenate([d_new, dg])
            inside = np.concatenate([np.zeros(len(rs), bool), np.where(refl, inside[q], ~inside[q])])
            specular = np.concatenate([np.zeros(len(rs), bool), specular[q]])
            refracted = np.concatenate([refracted[rs], refracted[q] | ~refl])
            depth = np.concatenate([depth[rs], depth[q]]) + 1
            w, idx = w[keep], idx[keep]
        out["through_sq"] += float((per_photon ** 2).sum())
        out["floor_sq"] += float((per_photon_floor ** 2).sum())
    if camera is not None:
        area = np.where(camera.ok.ravel(), camera.area.ravel(), np.inf)
        for key in ("E_direct", "E_caustic", "E_rest"):
            out[key] = out[key] / area
    # standard error of `through`, a sum of n iid per-photon fluxes x_i: sum x^2 - (sum x)^2 / n
    out["through_se"] = float(np.sqrt(max(out["through_sq"] - out["through"] ** 2 / n_photons, 0.0)))
    both = out["through"] + out["reflected"]
    out["floor_se"] = float(np.sqrt(max(out["floor_sq"] - both ** 2 / n_photons, 0.0)))
    return out
