"""Photon emission: engine/lights/emission.py.

- Chi-square fits of origins and directions of every light kind against PhotonEmitter.pdf
  (one family-wise level of 0.01, Sidak over CHI2_CASES).
- The flux of every photon is Le |cos| / (P pdf_pos pdf_dir) with Le and cos evaluated here
  independently; the power of every kind matches its formula; mean(flux) equals total_power
  (z-test with the sample variance) and lights are chosen in proportion to their power.
- Agreement with next-event estimation: the photons' irradiance on disk receivers (flux crossing
  the disk from its front / (N pi rho^2)) equals the mean irradiance over the same disk from
  LightSet.sample (no occlusion), per receiver and channel, z-tests Sidak-corrected over all.
  Deliberate bugs (a 3 % flux scale, a linear spot ramp, uniform instead of cosine directions
  with the cosine flux, the one-sided triangle, a soft light as sphere) must make it fail:
  test_nee_agreement_has_power.
Random numbers from numpy's seeded generator.
"""
import numpy as np
import pytest
from scipy import stats as st

from ember.engine import sampling
from ember.engine.accel import Accel
from ember.engine.lights import emission, shapes
from ember.engine.lights.emission import PhotonEmitter, _ramp_inverse, sample_spot_cos, spot_mass
from ember.engine.lights.light_set import LightSet
from ember.engine.scene import (LIGHT_DISK, LIGHT_POINT, LIGHT_RECT, LIGHT_SPOT, LIGHT_SUN, MAT_DIFFUSE, Lights,
                                Materials, Mesh, World)

from stats import Box, ChiSquareTest, Cone, Discrete, Disk, Mapped, Sphere, integrate, sidak_alpha

CENTER = np.zeros(3)
R_SCENE = 2.0
N_CHI2 = 200_000


def rot(axis, angle):
    """Rotation matrix (3,3) about a unit axis."""
    a = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def frame_rows(m):
    """Lights.frame rows (world x, y, z axes of the light) from a rotation matrix."""
    return m.T.copy()


TILT = frame_rows(rot((1, 2, 0.5), 0.7))  # a light tilted away from the world axes


def light_set(rows=(), world=None, quads=None, Le_tri=(1.0, 0.7, 0.4), strategy="mis"):
    """LightSet of analytic `rows`, an optional emissive quad mesh (Q,4,3), a World."""
    if quads is not None:
        quads = np.asarray(quads, np.float64)
        v = quads.reshape(-1, 3)
        tris = np.concatenate([[[4 * q, 4 * q + 1, 4 * q + 2], [4 * q, 4 * q + 2, 4 * q + 3]] for q in range(len(quads))])
        mesh = Mesh(v.astype(np.float32), tris.astype(np.int32), np.zeros((len(tris), 3, 3), np.float32),
                    np.zeros(len(tris), np.int32))
        mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(0.5,) * 3, emission=Le_tri)])
    else:
        mesh, mats = Mesh.empty(), Materials.make([])
    return LightSet(Lights.make(list(rows)), mesh, mats, world or World(), Accel(mesh), R_SCENE, strategy)


def emitter(ls):
    return PhotonEmitter(ls, CENTER, R_SCENE)


def shoot(em, n, seed):
    rng = np.random.default_rng(seed)
    return em.sample(rng.random(n), rng.random((n, 2)), rng.random((n, 2)))


def sky_map(h=16, w=32):
    """Sky brighter towards the horizon, dark ground, a 2 x 2-pixel sun of 1e3 x the sky."""
    theta = (np.arange(h) + 0.5) / h * np.pi
    sky = np.where(np.cos(theta) > 0, 1.0 + (1.0 - np.cos(theta)) ** 2, 0.05)
    img = np.repeat(sky[:, None, None], w, axis=1) * np.array([0.5, 0.7, 1.0])
    img[3:5, 11:13] = 1e3
    return img.astype(np.float32)


SPOT_HALF = np.radians(40.0)
SPOT = dict(kind=LIGHT_SPOT, spot_cos_half=np.cos(SPOT_HALF), spot_smooth=0.4 * (1 - np.cos(SPOT_HALF)))
QUAD = [[[-0.5, -0.4, 0.3], [0.6, -0.4, 0.1], [0.6, 0.5, 0.2], [-0.5, 0.5, 0.4]]]

# One scene per light kind (single emitter, or two of a kind), used by every test below.
SCENES = {
    "rect": lambda: light_set([dict(kind=LIGHT_RECT, position=(0, 0, 1), size=(0.5, 0.3), Le=(1.0, 0.8, 0.6))]),
    "ellipse": lambda: light_set([dict(kind=LIGHT_DISK, position=(0.2, 0, 1), frame=TILT, size=(0.6, 0.25),
                                       Le=(2.0, 2.0, 1.0))]),
    "triangles": lambda: light_set(quads=QUAD),
    "point": lambda: light_set([dict(kind=LIGHT_POINT, position=(0.1, 0, 0.2), Le=(3.0, 2.0, 1.0))]),
    "spot": lambda: light_set([dict(SPOT, position=(0, 0, 1), Le=(3.0, 3.0, 2.0))]),
    "spot_sphere": lambda: light_set([dict(SPOT, position=(0, 0, 1), radius=0.3, Le=(2.0, 2.0, 2.0))]),
    "spot_soft": lambda: light_set([dict(SPOT, position=(0, 0, 1), radius=0.02, soft=True, Le=(2e3, 2e3, 2e3),
                                         frame=TILT)]),
    "sphere": lambda: light_set([dict(kind=LIGHT_POINT, position=(0, 0, 0), radius=0.4, Le=(1.0, 1.5, 2.0))]),
    "soft": lambda: light_set([dict(kind=LIGHT_POINT, position=(0, 0, 0), radius=0.02, soft=True,
                                    Le=(2e3, 2e3, 2e3))]),
    "sun": lambda: light_set([dict(kind=LIGHT_SUN, frame=TILT, sun_half_angle=0.15, Le=(1.0, 0.9, 0.8))]),
    "sun_delta": lambda: light_set([dict(kind=LIGHT_SUN, frame=TILT, Le=(1.0, 0.9, 0.8))]),
    "environment": lambda: light_set(world=World(color=np.array([1.0, 0.8, 0.6]), image=sky_map())),
    "world": lambda: light_set(world=World(color=np.array([0.3, 0.4, 0.5]))),
}


# ----------------------------------------------------------------------------------------------
# Chi-square of origins and directions: N_CHI2 photons each, u (N, 5) split as shoot() does.

def _frame(z):
    z = _unit(z)
    t, b = sampling.frame_from_z(z.reshape(1, 3))
    return t[0], b[0], z


def _photons(ls, em=None):
    """A sampler of photons as rows (o, d) (N, 6)."""
    em = em or emitter(ls)

    def sampler(u):
        e = em.sample(u[:, 0], u[:, 1:3], u[:, 3:5])
        return np.concatenate([e.o, e.d], axis=1)
    return sampler


def _directions(em, sign=1.0):
    """A sampler of photon directions d (or -d, towards the emitter, for sign -1)."""
    return lambda u: sign * em.sample(u[:, 0], u[:, 1:3], u[:, 3:5]).d


def _chi2(domain, sampler, pdf, resolution, seed):
    return ChiSquareTest(domain, sampler, pdf, resolution, N_CHI2, seed=seed, sample_dim=5)


def _pdf_dir(em, light, sign=1.0):
    """pdf_dir of directions sign * d from emitter `light` (origins at 0: only d matters)."""
    return lambda d: em.pdf(np.full(len(d), light), np.zeros_like(d), sign * d).dir


def _dir_fit(em, seed, axis, light=0, mu_edges=20, n_phi=16):
    """(cos, phi) about axis of the directions d; the pdf is per solid angle (d omega = dcos dphi)."""
    return _chi2(Sphere(axis=axis), _directions(em), _pdf_dir(em, light), (mu_edges, n_phi), seed)


def case_rect_pos():
    ls = SCENES["rect"]()
    em = emitter(ls)
    c = ls.lights.position[0]

    def sampler(u):
        q = em.sample(u[:, 0], u[:, 1:3], u[:, 3:5]).o - c
        assert np.abs(q[:, 2]).max() < 1e-12
        return q[:, :2]

    def pdf(xy):
        o = c + np.concatenate([xy, np.zeros((len(xy), 1))], axis=1)
        return em.pdf(np.zeros(len(o), int), o, np.tile([0, 0, -1.0], (len(o), 1))).pos

    return _chi2(Box((-0.5, 0.5), (-0.3, 0.3)), sampler, pdf, (10, 8), 1)


def case_rect_dir():
    em = emitter(SCENES["rect"]())
    return _dir_fit(em, 2, (0, 0, -1))


def case_ellipse_pos():
    """Origins on the ellipse (semi-axes hx, hy along the frame), as (rho^2, angle): uniform."""
    ls = SCENES["ellipse"]()
    em = emitter(ls)
    f, c = ls.lights.frame[0], ls.lights.position[0]
    hx, hy = ls.lights.size[0]

    def sampler(u):
        o = em.sample(u[:, 0], u[:, 1:3], u[:, 3:5]).o
        assert np.abs((o - c) @ f[2]).max() < 1e-12
        return o

    def pdf(o):
        return em.pdf(np.zeros(len(o), int), o, np.tile(-f[2], (len(o), 1))).pos

    return _chi2(Disk(c, hx * f[0], hy * f[1]), sampler, pdf, (10, 12), 3)


def case_ellipse_dir():
    ls = SCENES["ellipse"]()
    return _dir_fit(emitter(ls), 4, -ls.lights.frame[0, 2])


def case_triangle_pos():
    """Origins on the first of the quad's two triangles, in barycentrics (s = b1 + b2, w = b2 / s)
    (dA = 2 A s ds dw); photons of the other triangle are rejected, so the density is its
    selection pmf x pdf_pos."""
    ls = SCENES["triangles"]()
    em = emitter(ls)
    light = ls.n_analytic
    v0, E = ls.tri_v0[0], np.stack([ls.tri_e1[0], ls.tri_e2[0]], axis=1)  # (3,2)
    to_b12 = np.linalg.pinv(E)

    def sampler(u):
        e = em.sample(u[:, 0], u[:, 1:3], u[:, 3:5])
        first = e.prim == ls.tri_prim[0]
        assert np.all(e.prim[e.valid] >= 0) and 0.2 < first.mean() < 0.8
        q = e.o[first] - v0
        assert np.abs(q - (q @ to_b12.T) @ E.T).max() < 1e-9  # in the triangle's plane
        return e.o, first

    def coordinates(o):
        b12 = (o - v0) @ to_b12.T
        s_ = b12.sum(axis=1)
        return s_, b12[:, 1] / s_

    def points(s_, w):
        o = v0 + np.multiply.outer(s_ * (1.0 - w), E[:, 0]) + np.multiply.outer(s_ * w, E[:, 1])
        return o, 2.0 * ls.tri_area[0] * s_

    def pdf(o):
        k = np.full(len(o), light)
        return em.pmf(k) * em.pdf(k, o, np.tile(ls.tri_ng[0], (len(o), 1))).pos

    return _chi2(Mapped(((0, 1), (0, 1)), coordinates, points), sampler, pdf, 10, 5)


def case_triangle_dir():
    """Both sides, |cos| / 2 pi about the geometric normal."""
    ls = SCENES["triangles"]()
    return _dir_fit(emitter(ls), 6, ls.tri_ng[0], light=ls.n_analytic)


def case_point_dir():
    return _dir_fit(emitter(SCENES["point"]()), 7, (0, 0, 1))


def _spot_mu_edges(cos_half, smooth):
    return np.concatenate([[-1.0, cos_half - 0.05], np.linspace(cos_half, min(cos_half + smooth, 1.0), 12)[:-1],
                           np.linspace(min(cos_half + smooth, 1.0), 1.0, 6)])


def _spot_dir_case(name, seed):
    ls = SCENES[name]()
    a = ls.lights
    return _dir_fit(emitter(ls), seed, -a.frame[0, 2], mu_edges=_spot_mu_edges(a.spot_cos_half[0], a.spot_smooth[0]))


def case_spot_dir_clipped_ramp():
    """cos_half + smooth > 1: the ramp is cut at the axis (att < 1 everywhere)."""
    ls = light_set([dict(kind=LIGHT_SPOT, position=(0, 0, 0), spot_cos_half=0.8, spot_smooth=0.5, Le=(1, 1, 1))])
    return _dir_fit(emitter(ls), 9, (0, 0, -1), mu_edges=np.concatenate([[-1.0, 0.7], np.linspace(0.8, 1.0, 16)]))


def case_spot_dir_hard_edge():
    ls = light_set([dict(kind=LIGHT_SPOT, position=(0, 0, 0), spot_cos_half=0.3, spot_smooth=0.0, Le=(1, 1, 1))])
    return _dir_fit(emitter(ls), 10, (0, 0, -1), mu_edges=np.concatenate([[-1.0, 0.2], np.linspace(0.3, 1.0, 15)]))


D0 = np.array([0.0, 0.0, 1.0])  # the direction paired with the points a pdf_pos is evaluated at


def _photon_pos_pdf(em):
    return lambda od: em.pdf(np.zeros(len(od), int), od[:, :3], od[:, 3:]).pos


def _sphere_pos_case(name, seed):
    """Origin normal n = (o - c) / r in the frame of d: (cos(n, d), phi), density r^2 pdf_pos
    (pdf_pos depends on cos(n, d) alone: it is evaluated with d = D0)."""
    ls = SCENES[name]()
    c, r = ls.lights.position[0], ls.lights.radius[0]
    photons = _photons(ls)

    def sampler(u):
        od = photons(u)
        assert np.abs(np.linalg.norm(od[:, :3] - c, axis=1) - r).max() < 1e-9 * r  # on the sphere
        return od

    def coordinates(od):
        n, d = (od[:, :3] - c) / r, od[:, 3:]
        t, b = sampling.frame_from_z(d)
        return (np.clip(np.einsum("ij,ij->i", n, d), -1.0, 1.0),
                np.mod(np.arctan2(np.einsum("ij,ij->i", n, b), np.einsum("ij,ij->i", n, t)), 2 * np.pi))

    about_d0 = Sphere(axis=D0)

    def points(mu, phi):
        n, _ = about_d0.points(mu, phi)
        return np.concatenate([c + r * n, np.broadcast_to(D0, n.shape)], axis=1), np.full(len(mu), r * r)

    domain = Mapped(((-1, 1), (0, 2 * np.pi)), coordinates, points, periodic=(False, True))
    return _chi2(domain, sampler, _photon_pos_pdf(emitter(ls)), (20, 8), seed)


def _disk_across(ls, seed, center, radius):
    """Origins on disks of the given radius perpendicular to each photon's d, centred at
    center(d) (N,3): (rho^2 / radius^2, angle) in the frame of d; uniform, pdf_pos constant."""
    photons = _photons(ls)

    def offsets(od):
        d = od[:, 3:]
        q = od[:, :3] - center(d)
        t, b = sampling.frame_from_z(d)
        return np.einsum("ij,ij->i", q, t), np.einsum("ij,ij->i", q, b), np.einsum("ij,ij->i", q, d)

    def sampler(u):
        od = photons(u)
        assert np.abs(offsets(od)[2]).max() < 1e-9
        return od

    def coordinates(od):
        x, y, _ = offsets(od)
        return (x * x + y * y) / radius**2, np.mod(np.arctan2(y, x), 2 * np.pi)

    across_d0 = Disk(center(D0[None])[0], radius * _frame(D0)[0], radius * _frame(D0)[1])

    def points(rho2, phi):
        o, jacobian = across_d0.points(rho2, phi)
        return np.concatenate([o, np.broadcast_to(D0, o.shape)], axis=1), jacobian

    domain = Mapped(((0, 1), (0, 2 * np.pi)), coordinates, points, periodic=(False, True))
    return _chi2(domain, sampler, _photon_pos_pdf(emitter(ls)), (10, 12), seed)


def _beam_pos_case(name, seed):
    """Origins on the disk of radius R perpendicular to wi = -d, centred R along wi."""
    return _disk_across(SCENES[name](), seed, lambda d: CENTER - R_SCENE * d, R_SCENE)


def case_soft_pos():
    """Soft falloff: origins on the disk through the centre perpendicular to d, uniform."""
    ls = SCENES["spot_soft"]()
    c, r = ls.lights.position[0], ls.lights.radius[0]
    return _disk_across(ls, 12, lambda d: np.broadcast_to(c, d.shape), r)


def case_sun_dir():
    """wi = -d in the cone: ((1 - cos) / (1 - cos half) over [0, 1.05], phi), uniform inside."""
    ls = SCENES["sun"]()
    em = emitter(ls)
    cone = Cone(shapes.one_minus_cos(0.15), axis=ls.lights.frame[0, 2], extent=1.05)
    return _chi2(cone, _directions(em, -1.0), _pdf_dir(em, 0, -1.0), (21, 8), 13)


ENV_GRID = (np.cos(np.linspace(np.pi, 0, 17)), 32)  # the sky map's pixels: (cos theta, phi) cells


def case_environment_dir():
    """-d on the env pixel grid; the scene's table is MIS-compensated, the photons' must not be."""
    ls = SCENES["environment"]()
    assert ls.env.compensated
    em = emitter(ls)
    return _chi2(Sphere(), _directions(em, -1.0), _pdf_dir(em, 0, -1.0), ENV_GRID, 15)


def case_world_dir():
    return _dir_fit(emitter(SCENES["world"]()), 17, (0.3, 0.2, 1))


CHI2_CASES = {
    "rect_pos": case_rect_pos,
    "rect_dir": case_rect_dir,
    "ellipse_pos": case_ellipse_pos,
    "ellipse_dir": case_ellipse_dir,
    "triangle_pos": case_triangle_pos,
    "triangle_dir_two_sided": case_triangle_dir,
    "point_dir": case_point_dir,
    "spot_dir": lambda: _spot_dir_case("spot", 8),
    "spot_sphere_dir": lambda: _spot_dir_case("spot_sphere", 18),
    "spot_soft_dir": lambda: _spot_dir_case("spot_soft", 19),
    "spot_dir_clipped_ramp": case_spot_dir_clipped_ramp,
    "spot_dir_hard_edge": case_spot_dir_hard_edge,
    "sphere_pos": lambda: _sphere_pos_case("sphere", 11),
    "spot_sphere_pos": lambda: _sphere_pos_case("spot_sphere", 20),
    "soft_pos": case_soft_pos,
    "sun_dir": case_sun_dir,
    "sun_pos": lambda: _beam_pos_case("sun", 14),
    "sun_delta_pos": lambda: _beam_pos_case("sun_delta", 21),
    "environment_dir": case_environment_dir,
    "environment_pos": lambda: _beam_pos_case("environment", 16),
    "world_dir": case_world_dir,
}


@pytest.mark.parametrize("name", list(CHI2_CASES))
def test_chi2_emission(name):
    CHI2_CASES[name]().check(n_tests=len(CHI2_CASES))


def test_environment_photons_reach_every_pixel():
    """The scene's compensated table is 0 in dim pixels; the photons' table is not."""
    em = emitter(SCENES["environment"]())
    assert integrate(Sphere(), _pdf_dir(em, 0, -1.0), ENV_GRID).min() > 0


def test_chi2_has_power_against_a_linear_spot_ramp(monkeypatch):
    """Directions drawn from a linear ramp (density (mu - cos_half) / smooth on the ramp) while the
    pdf claims Cycles' smoothstep: the spot's direction fit rejects."""
    monkeypatch.setattr(emission, "sample_spot_cos", _linear_ramp_cos)
    assert _spot_dir_case("spot", 8).run().p_value < 1e-6


# ----------------------------------------------------------------------------------------------
# Flux of each photon, power of each kind, selection

def emitted_radiance_cos(ls, e):
    """Le(o, d) |cos| (N,3) of the photons, evaluated from the scene's lights independently of
    emission.py (the conventions of shapes.py / light_set.py)."""
    n_an = ls.n_analytic
    out = np.zeros((len(e.d), 3))
    a = ls.lights
    idx = e.light
    an = idx < n_an
    if an.any():
        i = idx[an]
        d, o = e.d[an], e.o[an]
        kind = a.kind[i]
        Le = a.Le[i].copy()
        cos = np.ones(len(i))
        area = (kind == LIGHT_RECT) | (kind == LIGHT_DISK)
        cos = np.where(area, np.maximum(-np.einsum("ij,ij->i", d, a.frame[i, 2]), 0), cos)
        ps = (kind == LIGHT_POINT) | (kind == LIGHT_SPOT)
        sphere = ps & (a.radius[i] > 0) & ~a.soft[i]
        nrm = (o - a.position[i]) / np.maximum(a.radius[i], 1e-300)[:, None]
        cos = np.where(sphere, np.einsum("ij,ij->i", nrm, d), cos)
        att = np.where(kind == LIGHT_SPOT, shapes.spot_attenuation(a, i, d), 1.0)
        out[an] = Le * (att * cos)[:, None]
    tri = (idx >= n_an) & (idx < n_an + len(ls.tri_prim))
    if tri.any():
        t = idx[tri] - n_an
        out[tri] = ls.tri_Le[t] * np.abs(np.einsum("ij,ij->i", e.d[tri], ls.tri_ng[t]))[:, None]
    env = idx == ls.env_index
    if ls.env is not None and env.any():
        out[env] = ls.env.eval(-e.d[env])
    world = idx == ls.count
    if world.any():
        out[world] = ls.world
    return out


@pytest.mark.parametrize("name", list(SCENES) + ["mixed"])
def test_flux_is_le_cos_over_the_pdfs(name):
    """flux = Le |cos| / (P(light) pdf_pos pdf_dir) photon by photon, with Le and cos from the
    light's conventions and the pdfs from PhotonEmitter.pdf; the flux of a grey uniform emitter is
    the same for every photon (= total_power)."""
    ls = mixed_scene() if name == "mixed" else SCENES[name]()
    em = emitter(ls)
    e = shoot(em, 20_000, 30)
    assert e.valid.mean() > 0.999
    pdf = em.pdf(e.light, e.o, e.d)
    expect = emitted_radiance_cos(ls, e) / (em.pmf(e.light) * pdf.pos * pdf.dir)[:, None]
    v = e.valid
    np.testing.assert_allclose(e.flux[v], expect[v], rtol=1e-9, atol=0)
    if name not in ("environment", "triangles", "mixed"):  # one emitter of uniform Le
        np.testing.assert_allclose(e.flux[v], np.broadcast_to(em.total_power, e.flux[v].shape), rtol=1e-9)


def expected_power(name, ls):
    """Each kind's power from its textbook formula (W, RGB)."""
    a = ls.lights
    Le = a.Le[0] if len(a) else None
    if name == "rect":
        return np.pi * (4 * 0.5 * 0.3) * Le
    if name == "ellipse":
        return np.pi * (np.pi * 0.6 * 0.25) * Le
    if name == "triangles":
        return 2 * np.pi * (ls.tri_area[:, None] * ls.tri_Le).sum(axis=0)
    if name == "point":
        return 4 * np.pi * Le
    if name in ("spot", "spot_sphere", "spot_soft"):
        # integral of the attenuation over the sphere by quadrature in mu (independent of spot_mass)
        mu, w = np.polynomial.legendre.leggauss(200)
        lo, hi = a.spot_cos_half[0], 1.0
        x = np.clip((0.5 * (mu + 1) * (hi - lo) + lo - lo) / a.spot_smooth[0], 0, 1)
        cone = 2 * np.pi * np.sum(w * 0.5 * (hi - lo) * (3 * x * x - 2 * x**3))
        r = a.radius[0]
        return cone * (np.pi * r * r if r > 0 else 1.0) * Le
    if name in ("sphere", "soft"):
        r = a.radius[0]
        return 4 * np.pi * np.pi * r * r * Le  # Lambertian sphere: pi Le x 4 pi r^2
    if name == "sun":
        return np.pi * R_SCENE**2 * 2 * np.pi * (1 - np.cos(0.15)) * Le
    if name == "sun_delta":
        return np.pi * R_SCENE**2 * Le
    if name == "environment":
        return np.pi * R_SCENE**2 * ls.env.power_integral
    if name == "world":
        return 4 * np.pi * np.pi * R_SCENE**2 * ls.world


@pytest.mark.parametrize("name", list(SCENES))
def test_power_of_each_kind(name):
    ls = SCENES[name]()
    em = emitter(ls)
    np.testing.assert_allclose(em.total_power, expected_power(name, ls), rtol=1e-6)


def mixed_scene():
    rows = [dict(kind=LIGHT_RECT, position=(0, 0, 1), size=(0.5, 0.3), Le=(1.0, 0.8, 0.6)),
            dict(kind=LIGHT_POINT, position=(0.3, 0, 0), Le=(0.5, 0.5, 0.2)),
            dict(SPOT, position=(0, 0, 1), Le=(1.0, 2.0, 1.0)),
            dict(kind=LIGHT_POINT, position=(0, 0, 0.5), radius=0.1, Le=(20.0, 20.0, 20.0)),
            dict(kind=LIGHT_POINT, position=(0, 0.5, 0.5), radius=0.1, soft=True, Le=(10.0, 10.0, 5.0)),
            dict(kind=LIGHT_SUN, frame=TILT, sun_half_angle=0.1, Le=(10.0, 10.0, 10.0)),
            dict(kind=LIGHT_DISK, position=(0, 0, 1), size=(0.2, 0.2), Le=(0.0, 0.0, 0.0)),  # black
            dict(kind=LIGHT_POINT, position=(0, 0, 0), Le=(-1.0, -1.0, -1.0))]  # negative: not emitted
    return light_set(rows, world=World(color=np.array([0.004, 0.004, 0.004]), image=sky_map()), quads=QUAD)


def test_mean_flux_is_total_power_and_lights_are_chosen_by_power():
    ls = mixed_scene()
    em = emitter(ls)
    assert em.count == ls.count and em.world_index == -1
    assert list(em.emitted) == [True] * 6 + [False, False] + [True] * (ls.count - 8)
    np.testing.assert_allclose(em.total_power, em.power[em.emitted].sum(axis=0))
    n = 1_000_000
    e = shoot(em, n, 40)
    mean, se = e.flux.mean(axis=0), e.flux.std(axis=0) / np.sqrt(n)
    z = (mean - em.total_power) / se
    assert np.all(np.abs(z) < st.norm.ppf(1 - sidak_alpha(0.01, 3) / 2)), (mean, em.total_power, z)
    assert not np.isin(e.light, [6, 7]).any()
    w = np.where(em.emitted, em.power.mean(axis=1), 0.0)
    ChiSquareTest(Discrete(em.count), None, lambda k: w[k] / w.sum()).fit(e.light).check()
    # Per emitter: the photons of light l carry its power (mean over all photons of flux [light == l]).
    for light in np.flatnonzero(em.emitted):
        f = np.where((e.light == light)[:, None], e.flux, 0.0)
        z = (f.mean(axis=0) - em.power[light]) / np.maximum(f.std(axis=0) / np.sqrt(n), 1e-12)
        assert np.all(np.abs(z) < st.norm.ppf(1 - sidak_alpha(0.01, 3 * em.emitted.sum()) / 2)), (light, z)


def test_per_emitter_flux_detects_a_three_percent_selection_error():
    """The per-emitter check above has power: light 0 chosen 3 % more often than the pmf its
    photons' flux is divided by."""
    em = emitter(mixed_scene())
    n = 1_000_000
    old_pmf = em.pmf(np.arange(em.count))
    func = np.array(em.select.func)
    func[0] *= 1.03
    em.select = sampling.Distribution1D(func)
    e = shoot(em, n, 40)
    flux = e.flux * (em.pmf(e.light) / old_pmf[e.light])[:, None]
    f = np.where((e.light == 0)[:, None], flux, 0.0)
    z = (f.mean(axis=0) - em.power[0]) / (f.std(axis=0) / np.sqrt(n))
    assert np.all(np.abs(z) > st.norm.ppf(1 - sidak_alpha(0.01, 3 * em.emitted.sum()) / 2)), z


def test_constant_world_is_an_extra_emitter():
    ls = light_set([dict(kind=LIGHT_POINT, position=(0, 0, 0), Le=(1.0, 1.0, 1.0))],
                   world=World(color=np.array([0.2, 0.2, 0.2])))
    em = emitter(ls)
    assert ls.count == 1 and em.count == 2 and em.world_index == 1
    e = shoot(em, 10_000, 41)
    assert set(np.unique(e.light)) == {0, 1}


def test_nothing_emits():
    for ls in (light_set(), light_set([dict(kind=LIGHT_POINT, Le=(-1.0, -1.0, -1.0)),
                                       dict(kind=LIGHT_RECT, size=(1, 1), Le=(0, 0, 0))])):
        em = emitter(ls)
        assert em.empty and np.all(em.total_power == 0)
        e = shoot(em, 100, 1)
        assert not e.valid.any() and np.all(e.flux == 0) and np.all(np.isfinite(e.o))


def test_spot_cone_sampler_inverts_its_cdf():
    """sample_spot_cos maps u to mu with P(mu' >= mu) = u: the attenuation's CDF from the axis,
    integrated here in closed form (flat cap, then 1/2 - (x^3 - x^4 / 2) of the ramp)."""
    x = np.linspace(0, 1, 10001)
    np.testing.assert_allclose(_ramp_inverse(x**3 - 0.5 * x**4), x, atol=1e-12)
    for cos_half, smooth in ((0.6, 0.25), (0.9, 0.3), (-0.2, 0.0)):
        cos_start, x_max, mass = spot_mass(cos_half, smooth)
        u = np.linspace(0, 1, 2001)[:-1]
        mu = sample_spot_cos(u, np.full(u.shape, cos_half), np.full(u.shape, smooth))
        F = lambda x: x**3 - 0.5 * x**4
        xm = np.clip((mu - cos_half) / smooth, 0, 1) if smooth > 0 else np.ones_like(mu)
        above = (1 - np.maximum(mu, cos_start)) + np.where(mu < cos_start, smooth * (F(x_max) - F(xm)), 0.0)
        np.testing.assert_allclose(above / mass, u, atol=1e-12)


# ----------------------------------------------------------------------------------------------
# Agreement with next-event estimation: irradiance on disk receivers

N_PHOTONS = 1_000_000
M_NEE = 200_000


def _unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


def _spot_receivers(ls, dist=1.5):
    """On the axis, in the ramp at x = 1/4 and x = 3/4 (small disks facing the light), and a
    tilted one."""
    a = ls.lights
    c, axis = a.position[0], -a.frame[0, 2]
    t, b, _ = _frame(axis)
    out = [(c + dist * axis, -axis, 0.3)]
    for x in (0.25, 0.75):
        mu = a.spot_cos_half[0] + x * a.spot_smooth[0]
        w = np.sqrt(1 - mu * mu) * _unit(t + 0.3 * b) + mu * axis
        out.append((c + dist * w, -w, 0.04))
    out.append((c + 1.2 * axis + 0.5 * t, _unit(-axis + 0.6 * t + 0.2 * b), 0.3))
    return out


ABOVE = [((0, 0, 0), (0, 0, 1), 0.5), ((0.9, 0.3, 0.4), _unit((-1, -0.2, 0.6)), 0.4),
         ((-0.3, 0.9, 0.85), _unit((0.2, -1, 0.1)), 0.3), ((0.5, -0.6, -0.4), _unit((-0.3, 0.5, 1)), 0.4)]
AROUND = [((0, 0, -1.0), (0, 0, 1), 0.5), ((0.7, 0.3, 0.3), _unit((-1, -0.3, -0.2)), 0.3),
          ((-0.2, 1.1, -0.5), _unit((0.3, -1, 0.9)), 0.4), ((1.0, 0.0, 0.1), (0, 0, 1), 0.4)]  # last: horizon
AROUND_SMALL = AROUND[:3] + [((0.6, -0.9, 0.2), _unit((-0.6, 0.9, -0.5)), 0.3)]  # tiny lights: no horizon case
INSIDE = [((0, 0, 0), (0, 0, 1), 0.5), ((0.8, 0.5, -0.5), _unit((1, 0, 0.2)), 0.4),
          ((-1, 0.3, 0.4), _unit((-0.5, -1, 0.3)), 0.4), ((0.2, -0.9, 0.3), TILT[2], 0.3),
          ((0.3, 0.3, -0.6), _unit(np.cross(TILT[2], (1, 0, 0)) + 0.1 * TILT[2]), 0.4)]
BOTH_SIDES = [((0, 0, 1.2), (0, 0, -1), 0.5), ((0.2, 0, -0.8), (0, 0, 1), 0.5),
              ((1.2, 0.2, 0.5), _unit((-1, 0, -0.2)), 0.4)]
RECEIVERS = {"rect": ABOVE, "ellipse": ABOVE, "triangles": BOTH_SIDES, "point": AROUND_SMALL, "sphere": AROUND,
             "soft": AROUND_SMALL, "sun": INSIDE, "sun_delta": INSIDE, "environment": INSIDE, "world": INSIDE}


def receivers(name, ls):
    return _spot_receivers(ls) if name.startswith("spot") else RECEIVERS[name]


def photon_irradiance(e, rec):
    """Mean irradiance (3,) over the disk receiver and the variance of that mean: flux of the
    photons crossing it from its front side / (N pi rho^2)."""
    c, n, rho = (np.asarray(rec[0], np.float64), np.asarray(rec[1], np.float64), rec[2])
    dn = e.d @ n
    t = np.divide((c - e.o) @ n, dn, out=np.full(len(dn), -1.0), where=dn < 0)
    rows = np.flatnonzero(t > 0)  # travelling against n, disk plane ahead
    q = e.o[rows] + e.d[rows] * t[rows, None] - c
    rows = rows[np.einsum("ij,ij->i", q, q) <= rho * rho]
    x = e.flux[rows] / (np.pi * rho * rho)
    n_all = len(e.d)
    mean = x.sum(axis=0) / n_all
    return mean, ((x * x).sum(axis=0) / n_all - mean * mean) / n_all


def nee_irradiance(name, ls, rec, seed):
    """Mean irradiance over the disk by light sampling (uniform points on the disk), no occlusion,
    and the variance of the mean. The constant world is not light-sampled: pi L exactly."""
    if name == "world":
        return np.pi * ls.world, np.zeros(3)
    if name == "environment":  # the compensated table is only valid under MIS: sample the plain one
        ls = light_set(world=World(color=np.array([1.0, 0.8, 0.6]), image=sky_map()), strategy="light")
    c, n, rho = (np.asarray(rec[0], np.float64), np.asarray(rec[1], np.float64), rec[2])
    rng = np.random.default_rng(seed)
    t, b, _ = _frame(n)
    xy = sampling.sample_concentric_disk(rng.random((M_NEE, 2))) * rho
    p = c + xy[:, :1] * t + xy[:, 1:] * b
    s = ls.sample(p, rng.random(M_NEE), rng.random((M_NEE, 2)))
    f = np.where(s.valid[:, None], s.Le * (np.maximum(s.wi @ n, 0.0) / np.where(s.valid, s.pdf, 1.0))[:, None], 0.0)
    return f.mean(axis=0), f.var(axis=0) / M_NEE


N_NEE_TESTS = 3 * sum(4 if k.startswith("spot") else len(RECEIVERS[k]) for k in SCENES)
NEE_ALPHA = sidak_alpha(0.01, N_NEE_TESTS)


def nee_p_values(name, em=None, seed=50, bug=None, estimates=None):
    """Two-sided p-values (receivers, 3) of photon vs NEE irradiance for scene `name`; `em` a
    (possibly broken) emitter, `bug` an optional transform of the photons, or the photon
    `estimates` [(mean, var of the mean)] per receiver."""
    ls = SCENES[name]()
    if estimates is None:
        e = shoot(em or emitter(ls), N_PHOTONS, seed)
        if bug is not None:
            bug(ls, e)
        estimates = [photon_irradiance(e, rec) for rec in receivers(name, ls)]
    ps = []
    for j, (m_ph, v_ph) in enumerate(estimates):
        m_nee, v_nee = _nee_cached(name, j)
        var = v_ph + v_nee
        z = np.divide(np.abs(m_ph - m_nee), np.sqrt(var), out=np.where(m_ph == m_nee, 0.0, np.inf), where=var > 0)
        ps.append(2 * st.norm.sf(z))
    return np.array(ps)


_NEE_CACHE = {}
_PHOTON_CACHE = {}


def _nee_cached(name, j):
    if (name, j) not in _NEE_CACHE:
        ls = SCENES[name]()
        _NEE_CACHE[name, j] = nee_irradiance(name, ls, receivers(name, ls)[j], 60 + j)
    return _NEE_CACHE[name, j]


def _photons_cached(name):
    """Photon estimates of the correct emitter per receiver (shared by the agreement test and the
    3 % check, which scales them: the same as shooting with a 3 % larger flux)."""
    if name not in _PHOTON_CACHE:
        ls = SCENES[name]()
        e = shoot(emitter(ls), N_PHOTONS, 50)
        _PHOTON_CACHE[name] = [photon_irradiance(e, rec) for rec in receivers(name, ls)]
    return _PHOTON_CACHE[name]


@pytest.mark.parametrize("name", list(SCENES))
def test_photon_irradiance_agrees_with_nee(name):
    ls = SCENES[name]()
    for j in range(len(receivers(name, ls))):  # every receiver gets light (the test sees something)
        assert _nee_cached(name, j)[0].max() > 0, (name, j)
    p = nee_p_values(name, estimates=_photons_cached(name))
    assert p.min() >= NEE_ALPHA, f"{name}: p = {p.round(5)} (alpha {NEE_ALPHA:.2g})"


def _one_sided_triangles(ls, e):
    """All photons leave the front face, flux unchanged."""
    n = ls.tri_ng[e.light - ls.n_analytic]
    dn = np.einsum("ij,ij->i", e.d, n)
    e.d[:] = e.d - 2 * np.minimum(dn, 0)[:, None] * n


def _linear_ramp_cos(u, cos_half, smooth):
    """A deliberately wrong spot sampler: density (mu - cos_half) / smooth on the ramp (a linear
    ramp integrates to smooth / 2 like the smoothstep, so only the shape is wrong)."""
    cos_start, _, _ = spot_mass(cos_half, smooth)
    mass = (1 - cos_start) + 0.5 * smooth
    p_flat = (1 - cos_start) / mass
    v = np.clip((u - p_flat) / (1 - p_flat), 0, 1)
    return np.where(u < p_flat, 1 - u / p_flat * (1 - cos_start), cos_half + smooth * np.sqrt(1 - v))


@pytest.mark.parametrize("bug", ["flux_3_percent", "linear_spot_ramp", "uniform_not_cosine_rect",
                                 "uniform_not_cosine_triangles", "one_sided_triangles", "compensated_env"])
def test_nee_agreement_has_power(bug, monkeypatch):
    """Each deliberate bug makes the NEE agreement test reject (in every scene it concerns)."""
    if bug == "flux_3_percent":
        names = list(SCENES)
        for name in names:
            scaled = [(1.03 * m, 1.03**2 * v) for m, v in _photons_cached(name)]
            assert nee_p_values(name, estimates=scaled).min() < NEE_ALPHA, name
        return
    if bug == "linear_spot_ramp":  # directions from a linear ramp, flux as for the smoothstep
        monkeypatch.setattr(emission, "sample_spot_cos", _linear_ramp_cos)
        monkeypatch.setattr(emission.PhotonEmitter, "_pdf_spot", lambda self, light, d: np.full(len(d), 1.0 / (
            2 * np.pi * spot_mass(self.lights.lights.spot_cos_half[light], self.lights.lights.spot_smooth[light])[2])))
        p = nee_p_values("spot")
    elif bug.startswith("uniform_not_cosine"):  # directions uniform, flux pi A Le as for cosine
        monkeypatch.setattr(sampling, "sample_cosine_hemisphere", sampling.sample_uniform_hemisphere)
        p = nee_p_values("rect" if bug.endswith("rect") else "triangles")
    elif bug == "one_sided_triangles":
        p = nee_p_values("triangles", bug=_one_sided_triangles)
    else:  # the scene's MIS-compensated table: directions below the map's mean never emit
        ls = SCENES["environment"]()
        em = emitter(ls)
        em.env = ls.env
        p = nee_p_values("environment", em=em)
    assert p.min() < NEE_ALPHA, p
