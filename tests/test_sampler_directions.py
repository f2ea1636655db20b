"""Directional checks of every sampler the path tracer calls, through the objects it calls them
on (not only the warps underneath): chi-square of the directions that `LambertClosure.sample`
and `Closure.sample` (one lobe kind at a time, in tilted shading frames) draw, against an
independently written density; the closure's mixture pdf checked without its own `_mixture`
(rebuilt from the lobe modules and the lobe shares, integrated over the sphere, matched to the
fraction of samples it keeps); and next-event estimation through `LightSet.sample` (directions
of each light kind against the density a ray hit reports, irradiance of several lights at once
against quadrature, and the selection pmf against the lights' powers).

A furnace test cannot see a sampler that draws the wrong directions when the weight it returns
hides it (uniform directions with the weight of cosine sampling integrate a constant exactly);
these can. Seeded; chi-square cases share a family-wise level of 0.01 (Sidak), z-tests too.
"""
import numpy as np
import pytest

from ember.engine.accel import Accel
from ember.engine.bsdf import closure as closure_mod
from ember.engine.bsdf import fast_path
from ember.engine.bsdf import phong
from ember.engine.lights.light_set import LightSet
from ember.engine.scene import (FRESNEL_NONE, LIGHT_DISK, LIGHT_POINT, LIGHT_RECT, LIGHT_SPOT, LOBE_DIELECTRIC,
                                LOBE_DIFFUSE, LOBE_MICROFACET, LOBE_PHONG, MAT_DIFFUSE, MAT_EMISSION_ONLY,
                                MAT_NODES, Lights, Materials, Mesh, Scene, World)

from core_scenes import perspective, quads_mesh, settings
from stats import ChiSquareTest, Cone, Sphere

N = 200_000
TILT = np.array([0.35, -0.5, 0.79])
TILT = TILT / np.linalg.norm(TILT)  # the shading normal of every closure below


def _frame(n):
    """An orthonormal frame (t, b, n) built here, not by sampling.frame_from_z."""
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t = np.cross(a, n)
    t /= np.linalg.norm(t)
    return t, np.cross(n, t), n


def _direction(cos_t, phi, n):
    t, b, n = _frame(n)
    s = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    return (s * np.cos(phi))[..., None] * t + (s * np.sin(phi))[..., None] * b + cos_t[..., None] * n


def _fit(n, sampler, density, seed):
    """Chi-square test over the sphere in 40 x 40 cells of (cos, phi) around n; density per
    solid angle; u (N, 3) (direction, lobe choice)."""
    return ChiSquareTest(Sphere(frame=np.stack(_frame(n))), sampler, density, 40, N, seed=seed, sample_dim=3,
                         refine=True)


# ----------------------------------------------------------------------------------------------
# Closures on a tilted surface

def _closure(lobes, wo_local, n=N, inside=False):
    """A Closure at n points of a quad whose normal is TILT, wo given in the (t, b, n) frame of
    _frame(TILT); from below the quad (inside an object) when inside."""
    t, b, nn = _frame(TILT)
    corners = np.array([-t - b, t - b, t + b, -t + b], np.float64)
    v = corners.astype(np.float32)
    tris = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    normals = np.tile(TILT.astype(np.float32), (2, 3, 1))
    mesh = Mesh(v, tris, normals, np.zeros(2, np.int32), uvs=np.zeros((2, 3, 2), np.float32))
    mats = Materials.make([dict(kind=MAT_NODES, lobes=lobes)])
    scene = Scene(mesh, mats, Lights.make([]), World(), perspective((0, 0, 3), (0, 0, 0)), settings())
    wo_local = np.asarray(wo_local, np.float64) / np.linalg.norm(wo_local)
    wo = wo_local[0] * t + wo_local[1] * b + wo_local[2] * nn
    if inside:
        wo = wo - 2 * (wo @ nn) * nn
    side = 1.0 if wo @ nn > 0 else -1.0
    ng = np.tile(nn * side, (n, 1))
    return closure_mod.Closure(scene, np.zeros(n, np.int32), ng.copy(), ng, np.tile(wo, (n, 1)),
                               np.zeros(n, np.int64), np.tile([0.2, 0.3, 0.5], (n, 1))), wo, nn * side


def _lambert_density(n):
    return lambda d: np.maximum(d @ n, 0.0) / np.pi


def case_lambert_closure():
    def sampler(u):
        ns = np.tile(TILT, (len(u), 1))
        s = fast_path.LambertClosure(np.full((len(u), 3), 0.7), ns, ns.copy()).sample(u[:, :2], u[:, 2])
        assert s.valid.all() and not s.delta.any()
        np.testing.assert_allclose(s.pdf, np.maximum(s.wi @ TILT, 0) / np.pi, rtol=1e-9)  # its pdf is cos / pi
        np.testing.assert_allclose(s.weight, 0.7)  # and its weight that of cosine sampling
        return s.wi

    return _fit(TILT, sampler, _lambert_density(TILT), 1)


def _closure_case(lobes, wo_local, seed, inside=False, density=None):
    def sampler(u):
        c, _, _ = _closure(lobes, wo_local, n=len(u), inside=inside)
        s = c.sample(u[:, :2], u[:, 2])
        assert not s.delta.any() and np.all(np.isfinite(s.weight)) and np.all(np.isfinite(s.pdf))
        return s.wi, s.valid

    if density is None:
        def density(d):
            return _closure(lobes, wo_local, n=len(d), inside=inside)[0].eval(d, np.arange(len(d)))[1]
    return _fit(_closure(lobes, wo_local, n=1, inside=inside)[2], sampler, density, seed)


def _diffuse_density():
    t, b, n = _frame(TILT)
    return lambda d: np.maximum(d @ n, 0.0) / np.pi


CLOSURE_CASES = {
    "lambert_closure": case_lambert_closure,
    # The general closure with one diffuse lobe, against cos / pi written here.
    "closure_diffuse": lambda: _closure_case([dict(kind=LOBE_DIFFUSE, color=(0.5, 0.5, 0.5))], [0.4, 0.2, 0.8], 2,
                                             density=_diffuse_density()),
    "closure_ggx_r0.5_30deg": lambda: _closure_case(
        [dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_NONE, color=(0.9, 0.9, 0.9), roughness=0.5)],
        [np.sin(0.52), 0.0, np.cos(0.52)], 3),
    "closure_ggx_r0.8_75deg": lambda: _closure_case(
        [dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_NONE, color=(0.9, 0.9, 0.9), roughness=0.8)],
        [np.sin(1.31), 0.0, np.cos(1.31)], 4),
    "closure_rough_glass_outside": lambda: _closure_case(
        [dict(kind=LOBE_DIELECTRIC, color=(1, 1, 1), tint=(1, 1, 1), roughness=0.6, ior=1.5)],
        [0.5, 0.1, 0.8], 5),
    "closure_rough_glass_inside": lambda: _closure_case(
        [dict(kind=LOBE_DIELECTRIC, color=(1, 1, 1), tint=(1, 1, 1), roughness=0.6, ior=1.5)],
        [0.3, 0.1, 0.9], 6, inside=True),
    "closure_phong_n20": lambda: _closure_case(
        [dict(kind=LOBE_PHONG, color=(0.3, 0.3, 0.3), tint=(0.5, 0.5, 0.5), exponent=20.0)], [0.5, -0.2, 0.7], 7),
}


@pytest.mark.parametrize("name", list(CLOSURE_CASES))
def test_closure_samplers_chi2(name):
    CLOSURE_CASES[name]().check(n_tests=len(CLOSURE_CASES))


# ----------------------------------------------------------------------------------------------
# The mixture pdf, without the closure's own _mixture

TWO_LOBES = [dict(kind=LOBE_DIFFUSE, color=(0.6, 0.4, 0.2), weight=(0.7, 0.7, 0.7)),
             dict(kind=LOBE_PHONG, color=(0.1, 0.1, 0.1), tint=(0.5, 0.6, 0.7), exponent=30.0, weight=(0.5,) * 3)]


def _independent_mixture(wo_l, wi_l):
    """f (M,3) and pdf (M,) of TWO_LOBES at local directions, from the lobe formulas: shares
    proportional to the mean of weight x albedo estimate (Lambert: colour; Phong: kd + ks)."""
    m = len(wi_l)
    a_d = 0.7 * np.array([0.6, 0.4, 0.2]).mean()
    a_p = 0.5 * (np.array([0.1, 0.1, 0.1]) + np.array([0.5, 0.6, 0.7])).mean()
    P_d, P_p = a_d / (a_d + a_p), a_p / (a_d + a_p)
    kd, ks, n = np.full((m, 3), 0.1), np.tile([0.5, 0.6, 0.7], (m, 1)), np.full(m, 30.0)
    wo = np.broadcast_to(wo_l, (m, 3))
    cos = wi_l[:, 2]
    f = 0.7 * np.array([0.6, 0.4, 0.2]) / np.pi * (cos > 0)[:, None] + 0.5 * phong.eval(kd, ks, n, wo, wi_l)
    pdf = P_d * np.maximum(cos, 0.0) / np.pi + P_p * phong.pdf(kd, ks, n, wo, wi_l)
    return f, pdf


def test_mixture_pdf_and_weight_against_independent_formulas():
    wo_local = np.array([0.5, -0.2, 0.7]) / np.linalg.norm([0.5, -0.2, 0.7])
    c, wo, n = _closure(TWO_LOBES, wo_local, n=20_000)
    rng = np.random.default_rng(11)
    s = c.sample(rng.random((20_000, 2)), rng.random(20_000))
    t, b, nn = _frame(TILT)
    wi_l = np.stack([s.wi @ t, s.wi @ b, s.wi @ nn], axis=1)
    f, pdf = _independent_mixture(wo_local, wi_l)
    ok = s.valid
    assert ok.mean() > 0.8
    np.testing.assert_allclose(s.pdf[ok], pdf[ok], rtol=1e-9)
    np.testing.assert_allclose(s.weight[ok], f[ok] * wi_l[ok, 2:3] / pdf[ok, None], rtol=1e-9)


def test_mixture_pdf_integrates_to_the_fraction_of_kept_samples():
    """int pdf d omega over the sphere = P(a sample is kept) (no delta lobes): the pdf eval()
    reports, integrated by quadrature, against the fraction of valid samples of sample()."""
    wo_local = [0.8, 0.1, 0.35]  # fairly grazing: the Phong lobe loses samples under the surface
    c, wo, n = _closure(TWO_LOBES, wo_local, n=N)
    rng = np.random.default_rng(12)
    kept = c.sample(rng.random((N, 2)), rng.random(N)).valid.mean()
    # Quadrature over (cos theta, phi) around the normal: the pdf is 0 below, smooth above except
    # the Phong lobe's peak, resolved by 400 x 800 Gauss points.
    x, w = np.polynomial.legendre.leggauss(400)
    ct, wc = 0.5 * (x + 1.0), 0.5 * w
    x, w = np.polynomial.legendre.leggauss(800)
    ph, wp = np.pi * (x + 1.0), np.pi * w
    C, P = np.meshgrid(ct, ph, indexing="ij")
    d = _direction(C.ravel(), P.ravel(), n)
    grid, _, _ = _closure(TWO_LOBES, wo_local, n=len(d))
    integral = float(grid.eval(d, np.arange(len(d)))[1] @ np.outer(wc, wp).ravel())
    se = np.sqrt(kept * (1 - kept) / N)
    assert abs(integral - kept) < 4 * se + 1e-4, (integral, kept)


# ----------------------------------------------------------------------------------------------
# Next-event estimation through LightSet

P0 = np.array([0.1, -0.2, 0.0])  # the shading point
N0 = np.array([0.0, 0.0, 1.0])


def _light_set(lights, mesh=None, mats=None):
    if mesh is None:
        mesh = quads_mesh([[[-20, -20, -5], [20, -20, -5], [20, 20, -5], [-20, 20, -5]]], [0])
        mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(0.5,) * 3)])
    accel = Accel(mesh)
    return LightSet(lights, mesh, mats, World(), accel, accel.scene_radius)


def _down(z_axis=(0.0, 0.0, 1.0)):
    """A light frame (rows x, y, z) whose -z points down when z_axis = +z."""
    z = np.asarray(z_axis, float) / np.linalg.norm(z_axis)
    t, b, _ = _frame(z)
    return np.stack([t, b, z])


RECT = dict(kind=LIGHT_RECT, position=(0.5, 0.3, 1.5), frame=_down((0.2, -0.1, 1.0)), size=(0.4, 0.25),
            Le=(3.0, 3.0, 3.0))
DISK = dict(kind=LIGHT_DISK, position=(-0.8, 0.2, 1.2), frame=_down((-0.3, 0.0, 1.0)), size=(0.3, 0.3),
            Le=(2.0, 2.0, 2.0))
SPHERE = dict(kind=LIGHT_POINT, position=(0.2, 1.0, 1.0), radius=0.3, soft=False, Le=(5.0, 5.0, 5.0))
SOFT = dict(kind=LIGHT_POINT, position=(-0.4, -1.0, 0.9), radius=0.25, soft=True, Le=(4.0, 4.0, 4.0))
SOFT_SPOT = dict(kind=LIGHT_SPOT, position=(0.0, 0.0, 1.4), frame=_down(), radius=0.2, soft=True, Le=(6.0,) * 3,
                 spot_cos_half=np.cos(np.radians(50)), spot_smooth=0.1)


def _hit_density(ls, i):
    """Density per solid angle at P0 of directions toward analytic light i: the pdf_dir a ray
    hit reports, times the light's selection pmf (0 where the ray misses the light)."""
    from ember.engine.lights import shapes

    def density(d):
        o = np.broadcast_to(P0, d.shape)
        h = shapes.hit_analytic(int(ls.lights.kind[i]), ls.lights, i, o, d, np.full(len(d), np.inf))
        return np.where(h.hit, h.pdf, 0.0) * ls.pmf(np.array([i]))[0]
    return density


def _cone_around(lights, i, dist):
    """1 - cos of the half-angle of a cone from P0 around the direction to light i's centre
    (at distance dist) that holds the light: the silhouette itself for a sphere and for a soft
    light (a disk facing P0), so that it lies on the grid's edge; for a rect or a disk, the
    cone of a ball around it, 5 % wider."""
    kind, (hx, hy), r = int(lights.kind[i]), lights.size[i], lights.radius[i]
    if kind in (LIGHT_RECT, LIGHT_DISK):
        sin2, widen = (np.hypot(hx, hy) if kind == LIGHT_RECT else max(hx, hy)) ** 2 / dist**2, 1.05
    else:
        sin2, widen = r * r / (dist**2 + r * r if lights.soft[i] else dist**2), 1.0
    return widen * sin2 / (1.0 + np.sqrt(1.0 - sin2))


def _light_cone_fit(ls, i, seed, cells=24):
    """Chi-square test of NEE directions toward light i, in coordinates around the direction to
    its centre: s = (1 - cos) / (1 - cos_max) over [0, 1] and the azimuth, so the light fills
    the grid. The samples of other lights are rejected: the density is light i's pmf x its pdf."""
    from ember.engine.lights import shapes
    axis = np.asarray(ls.lights.position[i]) - P0
    dist = np.linalg.norm(axis)
    axis /= dist

    def sampler(u):
        p = np.tile(P0, (len(u), 1))
        s = ls.sample(p, u[:, 0], u[:, 1:])
        hit = shapes.hit_analytic(int(ls.lights.kind[i]), ls.lights, i, p, s.wi, np.full(len(u), np.inf)).hit
        assert (s.valid & ~hit & ((s.wi @ axis) > 0.99)).sum() == 0
        return s.wi, s.valid & hit  # the samples of light i (the lights do not overlap as seen from P0)

    return ChiSquareTest(Cone(_cone_around(ls.lights, i, dist), axis=axis), sampler, _hit_density(ls, i), cells, N,
                         seed=seed, sample_dim=3, refine=True)  # the silhouettes of rects and disks cut cells


def _sun_fit(seed, half_angle=0.2, cells=24):
    """A sun of half angle 0.2 rad tilted off +z: NEE directions against the density sun_hit
    reports for escaped rays, in (1 - cos) / (1 - cos_max) and azimuth around the sun's axis."""
    from ember.engine.lights import shapes
    z = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])
    sun = dict(kind=2, frame=_down(z), sun_half_angle=half_angle, Le=(2.0, 2.0, 2.0))
    ls = _light_set(Lights.make([sun]))

    def sampler(u):
        s = ls.sample(np.tile(P0, (len(u), 1)), u[:, 0], u[:, 1:])
        assert s.valid.all() and not s.finite.any()
        return s.wi

    def density(d):
        h = shapes.sun_hit(ls.lights, 0, d)
        return np.where(h.hit, h.pdf, 0.0)

    return ChiSquareTest(Cone(1.0 - np.cos(half_angle), axis=z), sampler, density, cells, N, seed=seed, sample_dim=3)


LIGHT_CASES = {
    "sun_with_angle": lambda: _sun_fit(28),
    "rect": lambda: _light_cone_fit(_light_set(Lights.make([RECT])), 0, 21),
    "disk": lambda: _light_cone_fit(_light_set(Lights.make([DISK])), 0, 22),
    "sphere": lambda: _light_cone_fit(_light_set(Lights.make([SPHERE])), 0, 23),
    "soft_point": lambda: _light_cone_fit(_light_set(Lights.make([SOFT])), 0, 24),
    "soft_spot": lambda: _light_cone_fit(_light_set(Lights.make([SOFT_SPOT])), 0, 25),
    # With several lights the selection pmf scales each light's share of the samples.
    "rect_among_three": lambda: _light_cone_fit(_light_set(Lights.make([DISK, RECT, SPHERE])), 1, 26),
    "sphere_among_three": lambda: _light_cone_fit(_light_set(Lights.make([DISK, RECT, SPHERE])), 2, 27),
}


@pytest.mark.parametrize("name", list(LIGHT_CASES))
def test_light_sampler_directions_chi2(name):
    LIGHT_CASES[name]().check(n_tests=len(LIGHT_CASES))


def _area_irradiance(center, frame, half, disk, Le, k=200):
    """Irradiance at P0 (normal N0) of a one-sided planar emitter by Gauss quadrature over its
    area: int Le cos_p cos_l / d^2 dA."""
    x, w = np.polynomial.legendre.leggauss(k)
    if disk:  # polar coordinates r in [0, 1], phi in [0, 2 pi): dA = hx hy r dr dphi
        r, wr = 0.5 * (x + 1.0), 0.5 * w
        ph, wph = np.pi * (x + 1.0), np.pi * w
        R, PH = np.meshgrid(r, ph, indexing="ij")
        u, v = half[0] * R * np.cos(PH), half[1] * R * np.sin(PH)
        wa = np.outer(wr, wph) * half[0] * half[1] * R
    else:
        U, V = np.meshgrid(half[0] * x, half[1] * x, indexing="ij")
        u, v = U, V
        wa = np.outer(w, w) * half[0] * half[1]
    y = center + u[..., None] * frame[0] + v[..., None] * frame[1]
    dv = y - P0
    d2 = np.sum(dv * dv, -1)
    wi = dv / np.sqrt(d2)[..., None]
    cos_p = np.maximum(wi @ N0, 0.0)
    cos_l = np.maximum(wi @ frame[2], 0.0)  # it emits along -z: towards P0 when wi.z > 0
    return float(np.sum(Le * cos_p * cos_l / d2 * wa))


def _sphere_irradiance(center, r, Le):
    """pi L (r / d)^2 cos(angle to the centre): exact for a sphere wholly above the horizon."""
    d = np.asarray(center) - P0
    dist = np.linalg.norm(d)
    return np.pi * Le * (r / dist) ** 2 * (d @ N0) / dist


def test_nee_irradiance_of_several_lights_matches_quadrature():
    """E[Le cos / pdf] over LightSet.sample with a rect, a disk, a sphere and an emissive
    triangle at once equals the sum of their irradiances computed without any sampler: a wrong
    selection pmf, a wrong area-to-solid-angle factor or a lost light shows."""
    tri_v = np.array([[-0.3, 0.9, 1.3], [0.4, 1.2, 1.6], [-0.1, 0.5, 1.8]])
    floor = np.array([[-20, -20, -5], [20, -20, -5], [20, 20, -5]])
    v = np.concatenate([floor, tri_v]).astype(np.float32)
    tris = np.array([[0, 1, 2], [3, 4, 5]], np.int32)
    nrm = np.cross(tri_v[1] - tri_v[0], tri_v[2] - tri_v[0])
    nrm /= np.linalg.norm(nrm)
    normals = np.stack([np.tile([0, 0, 1.0], (3, 1)), np.tile(nrm, (3, 1))]).astype(np.float32)
    mesh = Mesh(v, tris, normals, np.array([0, 1], np.int32))
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(0.5,) * 3),
                           dict(kind=MAT_EMISSION_ONLY, base_color=(0, 0, 0), emission=(1.5, 1.5, 1.5))])
    ls = _light_set(Lights.make([RECT, DISK, SPHERE]), mesh, mats)
    n = 400_000
    rng = np.random.default_rng(31)
    s = ls.sample(np.tile(P0, (n, 1)), rng.random(n), rng.random((n, 2)))
    x = np.divide(s.Le[:, 0] * np.maximum(s.wi @ N0, 0.0), s.pdf, out=np.zeros(n), where=s.valid)
    est, se = x.mean(), x.std() / np.sqrt(n)
    rect = Lights.make([RECT])
    exact = _area_irradiance(np.array(RECT["position"]), rect.frame[0], RECT["size"], False, 3.0)
    disk = Lights.make([DISK])
    exact += _area_irradiance(np.array(DISK["position"]), disk.frame[0], DISK["size"], True, 2.0)
    exact += _sphere_irradiance(SPHERE["position"], 0.3, 5.0)
    # The triangle is two-sided: |cos_l|; quadrature over its area by a fine subdivision.
    k = 400
    a, b = np.meshgrid((np.arange(k) + 0.5) / k, (np.arange(k) + 0.5) / k, indexing="ij")
    keep = a + b < 1.0
    y = tri_v[0] + a[keep, None] * (tri_v[1] - tri_v[0]) + b[keep, None] * (tri_v[2] - tri_v[0])
    area = 0.5 * np.linalg.norm(np.cross(tri_v[1] - tri_v[0], tri_v[2] - tri_v[0]))
    dv = y - P0
    d2 = np.sum(dv * dv, -1)
    wi = dv / np.sqrt(d2)[:, None]
    exact += float(np.sum(1.5 * np.maximum(wi @ N0, 0) * np.abs(wi @ nrm) / d2) * area / keep.sum())
    assert abs(est - exact) < 4 * se + 2e-4 * exact, (est, exact, se)


def test_selection_pmf_is_proportional_to_power():
    """pmf of each light = its power (written here: pi A Le for one-sided area lights, 4 pi^2
    r^2 Le for spheres) over the total; the samples of each light carry exactly that pmf."""
    ls = _light_set(Lights.make([DISK, RECT, SPHERE]))
    power = np.array([np.pi * np.pi * 0.3 * 0.3 * 2.0, np.pi * 4 * 0.4 * 0.25 * 3.0,
                      4 * np.pi * np.pi * 0.3 * 0.3 * 5.0])
    pmf = power / power.sum()
    np.testing.assert_allclose(ls.pmf(np.arange(3)), pmf, rtol=1e-12)
    n = 100_000
    rng = np.random.default_rng(32)
    s = ls.sample(np.tile(P0, (n, 1)), rng.random(n), rng.random((n, 2)))
    from ember.engine.lights import shapes
    for i in range(3):
        rows = np.flatnonzero(s.valid & (np.argmax(np.stack([s.wi @ (np.asarray(ls.lights.position[j]) - P0)
                                                             / np.linalg.norm(np.asarray(ls.lights.position[j]) - P0)
                                                             for j in range(3)]), axis=0) == i))
        h = shapes.hit_analytic(int(ls.lights.kind[i]), ls.lights, i, np.tile(P0, (len(rows), 1)),
                                s.wi[rows], np.full(len(rows), np.inf))
        assert h.hit.all()
        np.testing.assert_allclose(s.pdf[rows], pmf[i] * h.pdf, rtol=1e-6)
