"""Property-based tests (hypothesis) of the sampling routines, the BSDFs and the light samplers
over random and extreme inputs: uniforms at 0, 1 and denormals, unit vectors off by a few ulps,
grazing and below-the-surface directions, roughness 0 and 1, Phong exponent 1e6, IOR near 1,
tiny and huge lights. Properties: outputs finite, pdfs non-negative, weights bounded, and the
pdf a sampler reports equal to the pdf its evaluation function gives at the sample.

Each example is a batch of rows, so a modest example count covers many inputs; examples are
derandomised (the same on every run and in CI) and no database is written. The properties must
hold with and without flush-to-zero: once a test has rendered through Blender, the process
computes with denormals flushed (as Ember does inside Blender), so the same examples run both
ways depending on which tests ran before.
"""
import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ember.engine import sampling
from ember.engine.accel import Accel
from ember.engine.bsdf import closure as closure_mod
from ember.engine.bsdf import fast_path
from ember.engine.bsdf import dielectric, microfacet, phong
from ember.engine.lights import shapes
from ember.engine.lights.environment import EnvironmentMap
from ember.engine.lights.light_set import LightSet
from ember.engine.scene import (FRESNEL_DIELECTRIC, FRESNEL_F82, FRESNEL_NONE, LIGHT_DISK, LIGHT_POINT, LIGHT_RECT,
                                LIGHT_SPOT, LIGHT_SUN, LOBE_DIELECTRIC, LOBE_DIFFUSE, LOBE_MICROFACET, LOBE_PHONG,
                                LOBE_TRANSPARENT, MAT_DIFFUSE, MAT_NODES, Lights, Materials, Mesh, Scene, World)

from core_scenes import perspective, quads_mesh, settings as scene_settings

FUZZ = settings(max_examples=40, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
ROWS = 16
TINY = 5e-324  # the smallest denormal

# ----------------------------------------------------------------------------------------------
# Strategies

unit_interval = st.one_of(st.sampled_from([0.0, TINY, 1e-300, 1e-16, 0.5, 1.0 - 2**-53, 1.0]),
                          st.floats(0.0, 1.0, allow_nan=False))
u2 = st.lists(st.tuples(unit_interval, unit_interval), min_size=ROWS, max_size=ROWS).map(
    lambda r: np.array(r, np.float64))
u1 = st.lists(unit_interval, min_size=ROWS, max_size=ROWS).map(lambda r: np.array(r, np.float64))


@st.composite
def directions(draw, rows=ROWS, upper=False):
    """Unit vectors (rows, 3), some grazing (cos 0, +-1e-12, 1e-300), some exactly on an axis,
    each scaled by 1 + k eps (|k| <= 4): unit only up to rounding, as a normalised float is."""
    out = []
    for _ in range(rows):
        cos_t = draw(st.one_of(st.sampled_from([0.0, 1e-300, 1e-12, -1e-12, 1.0, -1.0, 0.5, 1 - 1e-15]),
                               st.floats(-1.0, 1.0)))
        if upper:
            cos_t = abs(cos_t)
        phi = draw(st.floats(0.0, 2 * np.pi))
        k = draw(st.integers(-4, 4))
        s = np.sqrt(max(0.0, 1.0 - cos_t * cos_t))
        out.append(np.array([s * np.cos(phi), s * np.sin(phi), cos_t]) * (1.0 + k * 2.2e-16))
    return np.array(out)


def _finite(*arrays):
    return all(np.all(np.isfinite(a)) for a in arrays)


# ----------------------------------------------------------------------------------------------
# sampling.py

@FUZZ
@given(u=u2)
def test_direction_warps_are_unit_finite_and_in_their_support(u):
    with np.errstate(divide="raise", invalid="raise", over="raise"):
        for warp, lower in ((sampling.sample_uniform_sphere, -1.0), (sampling.sample_uniform_hemisphere, 0.0),
                            (sampling.sample_cosine_hemisphere, 0.0)):
            d = warp(u)
            assert _finite(d)
            np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
            assert np.all(d[:, 2] >= lower)
        d = sampling.sample_cosine_hemisphere(u)
        p = sampling.pdf_cosine_hemisphere(d[:, 2])
        assert _finite(p) and np.all(p >= 0)
        disk = sampling.sample_concentric_disk(u)
        assert _finite(disk) and np.all(np.sum(disk * disk, 1) <= 1.0 + 1e-12)
        b = sampling.sample_uniform_triangle(u)
        assert np.all(b >= 0.0) and np.allclose(b.sum(1), 1.0, atol=1e-15)


@FUZZ
@given(u=u2, sin2=st.one_of(st.sampled_from([0.0, TINY, 1e-300, 1e-20, 1e-8, 0.5, 1.0 - 1e-16, 1.0]),
                            st.floats(0.0, 1.0)))
def test_sphere_cone_samples_stay_in_the_cone_with_a_finite_pdf(u, sin2):
    d, omc_max = sampling.sample_sphere_cone(u, sin2)
    pdf = sampling.pdf_sphere_cone(omc_max)
    assert _finite(d, omc_max, pdf) and np.all(pdf >= 0)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    one_minus_cos = 0.5 * np.sum((d - [0, 0, 1.0]) ** 2, axis=1)  # chord form, no cancellation
    assert np.all(one_minus_cos <= omc_max * (1 + 1e-9) + 1e-300)


@FUZZ
@given(n=directions())
def test_frames_are_orthonormal_for_unit_vectors_off_by_rounding(n):
    t, b = sampling.frame_from_z(n)
    assert _finite(t, b)
    nn = n / np.linalg.norm(n, axis=1, keepdims=True)
    for x, y in ((t, b), (t, nn), (b, nn)):
        assert np.all(np.abs(np.sum(x * y, 1)) < 1e-12)
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(b, axis=1), 1.0, atol=1e-12)
    v = sampling.to_world(sampling.to_local(nn, t, b, n), t, b, n)
    np.testing.assert_allclose(v, nn, atol=1e-12)


# Values spanning up to 1e306: a cell 1e-308 of the table's mean would get a pdf that underflows
# to 0 (a probability of 1e-308, accepted).
# No denormals: flushed to zero under Blender, a denormal cell's pdf becomes 0.
table_values = st.one_of(st.sampled_from([0.0, 1e-300, 1.0, 1e6]), st.floats(0.0, 1e6, allow_subnormal=False))


@FUZZ
@given(f=st.lists(table_values, min_size=1, max_size=40), u=u1)
def test_distribution1d_samples_have_positive_consistent_pdfs(f, u):
    f = np.array(f)
    if not np.isfinite(np.sum(f)):
        return  # tables summing to Inf are refused (tested in test_sampling)
    d = sampling.Distribution1D(f)
    x, pdf, index = d.sample_continuous(u)
    assert _finite(x, pdf) and np.all((x >= 0) & (x < 1)) and np.all(pdf > 0)
    np.testing.assert_array_equal(d.pdf(x), pdf)
    i, pmf, rest = d.sample_discrete(u)
    assert np.all(pmf > 0) and np.all((rest >= 0) & (rest < 1))
    assert abs(d.pmf(np.arange(d.n)).sum() - 1.0) < 1e-12


@FUZZ
@given(f=st.lists(st.lists(table_values, min_size=3, max_size=3), min_size=1, max_size=6), u=u2)
def test_distribution2d_samples_have_positive_consistent_pdfs(f, u):
    f = np.array(f)
    if not np.isfinite(np.sum(f)):
        return
    d = sampling.Distribution2D(f)
    uv, pdf, (row, col) = d.sample(u)
    assert _finite(uv, pdf) and np.all((uv >= 0) & (uv < 1)) and np.all(pdf > 0)
    np.testing.assert_array_equal(d.pdf(uv), pdf)
    if f.sum() > 0:
        assert np.all(d.func[row, col] > 0)  # zero cells are never chosen


@FUZZ
@given(u=u2, kind=st.sampled_from(sampling.PIXEL_FILTER_KINDS), width=st.floats(0.01, 10.0))
def test_pixel_filter_offsets_stay_in_the_support(u, kind, width):
    off = sampling.sample_pixel_filter(kind, width, u)
    assert _finite(off) and np.all(np.abs(off) <= sampling.pixel_filter_radius(kind, width) * (1 + 1e-12))


# ----------------------------------------------------------------------------------------------
# BSDF models

phong_exponent = st.one_of(st.sampled_from([0.0, 1.0, 1e6, 1e-300]), st.floats(0.0, 1e6))
reflectance = st.floats(0.0, 1.0)


@FUZZ
@given(wo=directions(), u=u2, u_lobe=u1, n=phong_exponent, kd=reflectance, ks=reflectance)
def test_phong_sample_is_finite_bounded_and_consistent(wo, u, u_lobe, n, kd, ks):
    if kd + ks > 1.0:
        kd, ks = kd / (kd + ks), ks / (kd + ks)
    m = len(wo)
    kd_, ks_, n_ = np.full((m, 3), kd), np.full((m, 3), ks), np.full(m, n)
    with np.errstate(divide="raise", invalid="raise", over="raise"):
        wi, weight, pdf = phong.sample(kd_, ks_, n_, wo, u, u_lobe)
        f = phong.eval(kd_, ks_, n_, wo, wi)
        p2 = phong.pdf(kd_, ks_, n_, wo, wi)
    assert _finite(wi, weight, pdf, f, p2)
    assert np.all(pdf >= 0) and np.all(weight >= 0) and np.all(f >= 0)
    # f cos / mixture pdf <= kd / P_d + ks (n + 2) / ((n + 1) P_s) <= 2 (kd + ks) (n + 2) / (n + 1)
    assert np.all(weight <= 4.0 * (kd + ks) + 1e-12)
    np.testing.assert_allclose(p2, pdf, rtol=1e-9, atol=0)
    assert np.all(weight[pdf == 0] == 0)


def test_ggx_eval_is_zero_not_nan_for_underflowing_cosines():
    """Found by the fuzzer: wo 1e-300 above the horizon made 4 cos_o cos_i underflow to 0 and
    G2 0, so f was 0 / 0 = NaN."""
    wo = np.array([[1.0, 0.0, 1e-300], [0.6, 0.0, 0.8]])
    wi = np.array([[-1.0, 0.0, 4e-291], [-0.6, 0.0, 0.8]])
    f = microfacet.eval_reflection(np.full(2, 1.5e-5), wo, wi, np.ones((2, 3)))
    assert np.all(np.isfinite(f)) and np.all(f[0] == 0.0) and np.all(f[1] > 0.0)


alpha_values = st.one_of(st.sampled_from([1.5e-5, 1e-4, 1e-3, 1.0]), st.floats(1.5e-5, 1.0))


@FUZZ
@given(wo=directions(), u=u2, alpha=alpha_values)
def test_ggx_reflection_sample_is_finite_bounded_and_consistent(wo, u, alpha):
    m = len(wo)
    a = np.full(m, alpha)
    wi, h, pdf = microfacet.sample_reflection(a, wo, u)
    f = microfacet.eval_reflection(a, wo, wi, np.ones((m, 3)))
    p2 = microfacet.pdf_reflection(a, wo, wi)
    assert _finite(wi, h, pdf, f, p2) and np.all(pdf >= 0) and np.all(f >= 0)
    # eval and pdf(wo, wi) rebuild h from wo + wi, which cancels for nearly opposite grazing
    # directions (|cos| = 1e-12: the pdf 30 % off, at 1e10; cos 1e-27: f cos / pdf = 4): the
    # weight bound and the consistency are checked where both cosines are >= 1e-6.
    ok = (pdf > 0) & (np.abs(wo[:, 2]) >= 1e-6) & (np.abs(wi[:, 2]) >= 1e-6)
    ok &= np.all((u > 1e-9) & (u < 1.0 - 1e-9), axis=1)  # see the dielectric test below
    weight = f[ok, 0] * wi[ok, 2] / pdf[ok]
    assert np.all(weight <= 1.0 + 1e-9)  # G2 / G1 <= 1 with F = 1
    np.testing.assert_allclose(p2[ok], pdf[ok], rtol=1e-4)


ior_values = st.one_of(st.sampled_from([1.0001, 1.001, 1.0 / 1.001, 1.5, 1 / 1.5, 2.4, 4.0]), st.floats(0.25, 4.0))


@FUZZ
@given(wo=directions(), u=u2, u_lobe=u1, alpha=alpha_values, eta=ior_values)
def test_dielectric_samples_are_finite_bounded_and_consistent(wo, u, u_lobe, alpha, eta):
    m = len(wo)
    if abs(eta - 1.0) < dielectric.INDEX_MATCHED_TOLERANCE:
        return
    a = np.full(m, alpha)
    wi, weight, pdf = dielectric.sample_rough(a, eta, wo, u, u_lobe)
    f = dielectric.eval_rough(a, eta, wo, wi)
    p2 = dielectric.pdf_rough(a, eta, wo, wi)
    assert _finite(wi, weight, pdf, f, p2) and np.all(pdf >= 0) and np.all(weight >= 0) and np.all(f >= 0)
    # G2 / G1 <= 1, divided by eta_rel^2 on refraction: at most max(1, eta^2, 1 / eta^2).
    bound = max(1.0, eta * eta, 1.0 / (eta * eta)) * (1 + 1e-9)
    assert np.all(weight <= bound)
    # As for GGX, and not for u on the square's edge: the visible-normal map sends u0 = 0 to a
    # microfacet on the horizon, whose h cannot be rebuilt from wo and wi (under flush-to-zero
    # its h.z is a rounding residue: the sampled pdf 5e3, the rebuilt one 0).
    ok = (pdf > 0) & (np.abs(wo[:, 2]) >= 1e-6) & (np.abs(wi[:, 2]) >= 1e-6)
    ok &= np.all((u > 1e-9) & (u < 1.0 - 1e-9), axis=1)
    np.testing.assert_allclose(p2[ok], pdf[ok], rtol=1e-4)
    wi_s, w_s, pmf_s, _ = dielectric.sample_smooth(eta, wo, u_lobe)
    assert _finite(wi_s, w_s, pmf_s) and np.all((pmf_s >= 0) & (pmf_s <= 1)) and np.all(w_s <= bound)


# ----------------------------------------------------------------------------------------------
# The closure, as the integrator builds it

lobe_strategy = st.one_of(
    st.builds(lambda c: dict(kind=LOBE_DIFFUSE, color=(c, c, c)), reflectance),
    st.builds(lambda c, r, fr, ior: dict(kind=LOBE_MICROFACET, color=(c, 0.5 * c, c), roughness=r, fresnel=fr,
                                         ior=ior, tint=(1, 1, 1)),
              reflectance, st.one_of(st.sampled_from([0.0, 1e-3, 1.0]), st.floats(0.0, 1.0)),
              st.sampled_from([FRESNEL_NONE, FRESNEL_DIELECTRIC, FRESNEL_F82]), st.floats(1.0001, 3.0)),
    st.builds(lambda r, ior: dict(kind=LOBE_DIELECTRIC, color=(1, 1, 1), tint=(1, 1, 1), roughness=r, ior=ior),
              st.one_of(st.sampled_from([0.0, 1.0]), st.floats(0.0, 1.0)), st.sampled_from([1.0, 1.00005, 1.0001,
                                                                                           1.33, 1.5, 2.4])),
    st.builds(lambda kd, ks, n: dict(kind=LOBE_PHONG, color=(kd,) * 3, tint=(ks,) * 3, exponent=n),
              st.floats(0.0, 0.5), st.floats(0.0, 0.5), phong_exponent.filter(lambda n: n >= 1.0)),
    st.builds(lambda c: dict(kind=LOBE_TRANSPARENT, color=(c, c, c)), reflectance),
)


def _closure(lobes, wo, normal):
    """A Closure at len(wo) points of a quad with the (unit up to rounding) normal."""
    n = normal / np.linalg.norm(normal)
    t, b = sampling.frame_from_z(n[None])
    t, b = t[0], b[0]
    v = np.array([-t - b, t - b, t + b, -t + b], np.float32)
    tris = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    mesh = Mesh(v, tris, np.tile(n.astype(np.float32), (2, 3, 1)), np.zeros(2, np.int32),
                uvs=np.zeros((2, 3, 2), np.float32))
    mats = Materials.make([dict(kind=MAT_NODES, lobes=lobes)])
    scene = Scene(mesh, mats, Lights.make([]), World(), perspective((0, 0, 3), (0, 0, 0)), scene_settings())
    k = len(wo)
    side = np.where(wo @ n >= 0, 1.0, -1.0)[:, None]
    ng = np.tile(normal, (k, 1)) * side  # the normal as given, off by rounding
    return closure_mod.Closure(scene, np.zeros(k, np.int32), ng.copy(), ng, wo, np.zeros(k, np.int64),
                               np.tile([0.2, 0.3, 0.5], (k, 1)))


@FUZZ
@given(lobes=st.lists(lobe_strategy, min_size=1, max_size=3), wo=directions(), normal=directions(rows=1),
       u=u2, u_lobe=u1)
def test_closure_samples_are_finite_bounded_and_match_eval(lobes, wo, normal, u, u_lobe):
    normal = normal[0]
    if abs(np.linalg.norm(normal) - 1) > 1e-12:
        return
    c = _closure(lobes, wo, normal)
    s = c.sample(u, u_lobe)
    assert _finite(s.wi, s.weight, s.pdf) and np.all(s.pdf >= 0) and np.all(s.weight >= 0)
    np.testing.assert_allclose(np.linalg.norm(s.wi, axis=1), 1.0, atol=1e-9)
    # Weights: each lobe's own weight is at most ~1 (x 1 / eta^2 <= 1 / 1.0001^-2 from inside
    # glass up to eta^2 = 5.8) and its share of the selection is at least 1e-3 of its weight.
    assert np.all(s.weight <= 6.0 / closure_mod._MIN_ESTIMATE)
    smooth = s.valid & ~s.delta
    rows = np.flatnonzero(smooth)
    if len(rows):
        f, pdf = c.eval(s.wi[rows], rows)
        assert _finite(f, pdf)
        np.testing.assert_allclose(pdf, s.pdf[rows], rtol=1e-6)
        cos = np.abs(s.wi[rows] @ (c.ns[rows].T)).diagonal() if len(rows) < 2 else np.abs(np.sum(s.wi[rows] * c.ns[rows], 1))
        np.testing.assert_allclose(s.weight[rows], f * cos[:, None] / pdf[:, None], rtol=1e-6, atol=1e-12)


@FUZZ
@given(wo=directions(), normal=directions(rows=1), u=u2)
def test_lambert_closure_is_finite_and_matches_its_pdf(wo, normal, u):
    ns = np.tile(normal[0], (len(wo), 1))
    c = fast_path.LambertClosure(np.full((len(wo), 3), 0.8), ns, ns.copy())
    s = c.sample(u, np.zeros(len(wo)))
    assert _finite(s.wi, s.weight, s.pdf) and np.all(s.pdf >= 0) and np.all(s.weight <= 0.8)
    rows = np.flatnonzero(s.valid)
    f, pdf = c.eval(s.wi[rows], rows)
    # eval recomputes the cosine from the world direction: rounding ~1e-16 absolute.
    np.testing.assert_allclose(pdf, s.pdf[rows], rtol=1e-9, atol=1e-15)


# ----------------------------------------------------------------------------------------------
# Light samplers

def _light_row(draw):
    kind = draw(st.sampled_from([LIGHT_POINT, LIGHT_SPOT, LIGHT_SUN, LIGHT_RECT, LIGHT_DISK]))
    size = draw(st.one_of(st.sampled_from([0.0, 1e-6, 1e-3, 50.0]), st.floats(0.0, 5.0)))
    pos = draw(st.tuples(*[st.floats(-3, 3)] * 3))
    z = draw(directions(rows=1))[0]
    t, b = sampling.frame_from_z(z[None] / np.linalg.norm(z))
    frame = np.stack([t[0], b[0], z / np.linalg.norm(z)])
    le = draw(st.one_of(st.sampled_from([1e-30, 1.0, 1e6]), st.floats(1e-3, 100.0)))
    row = dict(kind=kind, position=pos, frame=frame, Le=(le, le, le))
    if kind in (LIGHT_POINT, LIGHT_SPOT):
        row.update(radius=size, soft=draw(st.booleans()))
        if kind == LIGHT_SPOT:
            row.update(spot_cos_half=draw(st.floats(-1.0, 0.999)), spot_smooth=draw(st.floats(0.0, 1.0)))
    elif kind == LIGHT_SUN:
        row.update(sun_half_angle=draw(st.sampled_from([0.0, 1e-6, 0.01, 0.5])))
    else:
        row.update(size=(max(size, 1e-9), max(0.5 * size, 1e-9)))
    return row


@st.composite
def light_lists(draw):
    return [_light_row(draw) for _ in range(draw(st.integers(1, 3)))]


_MESH = quads_mesh([[[-2, -2, -4], [2, -2, -4], [2, 2, -4], [-2, 2, -4]]], [0])
_ACCEL = Accel(_MESH)
_MATS = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(0.5,) * 3)])


@FUZZ
@given(rows=light_lists(), p=st.lists(st.tuples(*[st.one_of(st.floats(-4, 4), st.sampled_from([0.0, 1e4, -1e6]))] * 3),
                                      min_size=ROWS, max_size=ROWS), u=u2, u_sel=u1)
def test_light_samples_are_finite_with_consistent_pdfs(rows, p, u, u_sel):
    lights = Lights.make(rows)
    ls = LightSet(lights, _MESH, _MATS, World(), _ACCEL, _ACCEL.scene_radius)
    if ls.empty:
        return  # total power 0 (e.g. radius 1e-308): refused by scene validation before a render
    p = np.array(p, np.float64)
    s = ls.sample(p, u_sel, u)
    assert _finite(s.wi, s.Le, s.pdf) and np.all(s.pdf >= 0) and np.all(s.Le >= 0)
    assert np.all(s.pdf[s.valid] > 0)
    # Known, not fixed here (engine/lights is not this suite's to change): a shading point exactly
    # at a delta point light's centre gets a "valid" sample with wi = 0 and Le = I / 1e-300
    # (contributions stay 0, as cos = 0). Such rows are left out of the unit-length check.
    chosen = ls.select.sample_index(u_sel)
    at_centre = ls.delta[chosen] & (np.linalg.norm(p - lights.position[np.minimum(chosen, len(rows) - 1)], axis=1) == 0)
    unit = s.valid & ~at_centre
    np.testing.assert_allclose(np.linalg.norm(s.wi[unit], axis=1), 1.0, atol=1e-9)
    # A light sample of a finite, non-delta analytic light is a point a ray from p along wi
    # hits on that light, with the pdf the hit reports (what MIS uses on the BSDF side).
    for i in range(len(rows)):
        kind = int(lights.kind[i])
        if ls.delta[i] or kind == LIGHT_SUN:
            continue
        target = np.asarray(lights.position[i])
        mine = np.flatnonzero(s.valid & ~s.delta & np.all(np.isclose(s.target, s.target), axis=1))
        mine = [r for r in mine if ls.select.sample_index(np.array([u_sel[r]]))[0] == i]
        if not mine:
            continue
        mine = np.array(mine)
        dist = np.linalg.norm(p[mine] - target, axis=1)
        scale = max(float(np.max(lights.size[i])), float(lights.radius[i]))
        near = (dist > 1e-3) & (dist < 1e3) & (scale > 1e-4)
        if kind in (LIGHT_RECT, LIGHT_DISK):  # not from (nearly) inside the light's own plane
            near &= np.abs(s.wi[mine] @ lights.frame[i, 2]) > 1e-6
        # nor points on the light's rim (u at 0 or 1), which a ray may miss by rounding
        near &= np.all((u[mine] > 1e-9) & (u[mine] < 1.0 - 1e-9), axis=1)
        mine = mine[near]
        if not len(mine):
            continue
        h = shapes.hit_analytic(kind, lights, i, p[mine], s.wi[mine], np.full(len(mine), np.inf))
        ok = h.hit & (h.pdf > 0)
        assert ok.mean() > 0.9, (kind, h.hit, h.pdf)
        np.testing.assert_allclose(s.pdf[mine[ok]], ls.pmf(np.full(ok.sum(), i)) * h.pdf[ok], rtol=1e-5)


@FUZZ
@given(img=st.lists(st.lists(st.one_of(st.sampled_from([0.0, TINY, 1e-30, 1e4]), st.floats(0.0, 10.0)),
                             min_size=4, max_size=4), min_size=2, max_size=4), u=u2,
       projection=st.sampled_from(["EQUIRECTANGULAR", "MIRROR_BALL"]))
def test_environment_samples_are_finite_with_consistent_pdfs(img, u, projection):
    image = np.repeat(np.array(img, np.float32)[:, :, None], 3, axis=2)
    if projection == "MIRROR_BALL":
        image = np.ascontiguousarray(np.resize(image, (4, 4, 3)))
    if not image.max() > 0:
        return
    env = EnvironmentMap(image, projection=projection)
    s = env.sample(u)
    wi, Le, pdf, valid = s.wi, s.Le, s.pdf, s.valid
    assert _finite(wi, Le, pdf) and np.all(pdf >= 0) and np.all(Le >= 0)
    ok = valid & (pdf > 0)
    np.testing.assert_allclose(np.linalg.norm(wi[ok], axis=1), 1.0, atol=1e-9)
    np.testing.assert_allclose(env.pdf(wi[ok]), pdf[ok], rtol=1e-6)
