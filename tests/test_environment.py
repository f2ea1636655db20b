"""Environment map light, without Blender: the sampler's chi-square fits on synthetic
maps, pdf/eval consistency, the constant light-sampling weight inside a pixel, the direction
-> pixel convention, what a world builds, light selection and MIS in the path tracer.

Statistical tests are seeded; the chi-square cases share one family-wise level of 0.01 (Sidak
over CHI2_CASES), the Monte Carlo checks use 4 sigma.
"""
import numpy as np
import pytest
from scipy import stats as st

from ember.engine.accel import Accel
from ember.engine.errors import EmberError
from ember.engine.lights.environment import EnvironmentMap, world_light
from ember.engine.lights.light_set import LightSet
from ember.engine.scene import LIGHT_POINT, LIGHT_SUN, Lights, Materials, Mesh, Scene, World
from ember.engine.session import RenderSession

from core_scenes import perspective, quads_mesh, settings
from stats import ChiSquareTest, Mapped, Sphere, sidak_alpha

N = 200_000
H, W = 16, 32


def _u(seed, n=N):
    return np.random.default_rng(seed).random((n, 2))


def rot_x(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def hot_pixel_map(row, col, hot=1e3, background=1.0, h=H, w=W):
    img = np.full((h, w, 3), background, np.float32)
    img[row, col] = (hot, 0.5 * hot, 0.25 * hot)
    return img


def sun_sky_map(h=H, w=W):
    """Sky brighter towards the horizon, dark ground, a 2 x 2-pixel sun of 1e5 x the sky."""
    theta = (np.arange(h) + 0.5) / h * np.pi
    sky = np.where(np.cos(theta) > 0, 1.0 + (1.0 - np.cos(theta)) ** 2, 0.05)
    img = np.repeat(sky[:, None, None], w, axis=1) * np.array([0.5, 0.7, 1.0])
    img[3:5, 11:13] = 1e5
    return img.astype(np.float32)


def random_map(seed, h=H, w=W):
    return (np.random.default_rng(seed).random((h, w, 3)) ** 4 + 1e-3).astype(np.float32)


# ----------------------------------------------------------------------------------------------
# Chi-square of the sampler: env-space directions on the pixel grid against the claimed pdf(d).
# Equirectangular pixels are cells of (cos theta, phi) (d omega = dcos dphi), so the pdf,
# constant per pixel, is integrated exactly.

PIXEL_GRID = (np.cos(np.linspace(np.pi, 0.0, H + 1)), W)  # ascending cos theta = pixel row edges


def _equirect_fit(env, seed):
    def sampler(u):
        s = env.sample(u)
        assert s.valid.all() and np.all(s.pdf > 0)
        return s.wi

    # Rigid maps only: the frame's rows are the env axes in world space.
    return ChiSquareTest(Sphere(frame=env.env_from_world), sampler, env.pdf, PIXEL_GRID, N, seed=seed)


def _ball_fit(env, seed, n_cells=16):
    """Mirror ball: the ball image coordinates (x, y); equal-area (d omega = 16 dx dy) inside
    the ball, nothing outside (high-order quadrature for the rim). Corner samples are rejected."""
    def coordinates(e):
        div = 2.0 * np.sqrt(np.maximum(0.5 * (1.0 - e[:, 1]), 0.0))
        return 0.5 * (e[:, 0] / div + 1.0), 0.5 * (1.0 - e[:, 2] / div)

    def points(x, y):
        X, Z = 2.0 * x - 1.0, 1.0 - 2.0 * y
        r2 = X * X + Z * Z
        inside = r2 < 1.0
        c = np.sqrt(np.maximum(1.0 - r2, 0.0))
        d = np.where(inside[:, None], np.stack([2 * c * X, 2 * r2 - 1, 2 * c * Z], axis=-1), [0.0, 1.0, 0.0])
        return d, np.where(inside, 16.0, 0.0)

    def sampler(u):
        s = env.sample(u)
        return s.wi, s.valid

    return ChiSquareTest(Mapped(((0, 1), (0, 1)), coordinates, points), sampler, env.pdf, n_cells, N, seed=seed,
                         order=32)


CHI2_CASES = {
    "constant": lambda: _equirect_fit(EnvironmentMap(np.ones((H, W, 3), np.float32)), 1),
    "random": lambda: _equirect_fit(EnvironmentMap(random_map(0), (1.0, 0.5, 2.0)), 2),
    "hot_pixel": lambda: _equirect_fit(EnvironmentMap(hot_pixel_map(6, 9)), 3),
    "sun_1e5_sky": lambda: _equirect_fit(EnvironmentMap(sun_sky_map()), 4),
    "hot_pixel_north_pole_row": lambda: _equirect_fit(EnvironmentMap(hot_pixel_map(0, 5)), 5),
    "hot_pixel_south_pole_row": lambda: _equirect_fit(EnvironmentMap(hot_pixel_map(H - 1, 20)), 6),
    "hot_pixel_seam_u0": lambda: _equirect_fit(EnvironmentMap(hot_pixel_map(7, 0)), 7),
    "hot_pixel_seam_u1": lambda: _equirect_fit(EnvironmentMap(hot_pixel_map(9, W - 1)), 8),
    "rotated": lambda: _equirect_fit(EnvironmentMap(sun_sky_map(), env_from_world=rot_z(0.7) @ rot_x(1.1)), 9),
    "mis_compensated_random": lambda: _equirect_fit(EnvironmentMap(random_map(5), compensate=True), 12),
    "mirror_ball_random": lambda: _ball_fit(EnvironmentMap(random_map(3, 16, 16), projection="MIRROR_BALL"), 10),
    "mirror_ball_hot_pixel": lambda: _ball_fit(
        EnvironmentMap(hot_pixel_map(4, 11, h=16, w=16), projection="MIRROR_BALL"), 11),
}


@pytest.mark.parametrize("name", list(CHI2_CASES))
def test_chi2_environment_sampler(name):
    CHI2_CASES[name]().check(n_tests=len(CHI2_CASES))


# ----------------------------------------------------------------------------------------------
# Consistency of sample / pdf / eval

SCALE = rot_x(0.4) @ np.diag([1.0, 2.5, 0.6])  # a Mapping node with non-uniform scale
MAPS = {
    "equirect": dict(image=random_map(1)),
    "equirect_1x1": dict(image=np.array([[[0.3, 0.2, 0.1]]], np.float32)),
    "equirect_rotated": dict(image=sun_sky_map(), env_from_world=rot_z(2.0) @ rot_x(-0.3)),
    "equirect_scaled": dict(image=random_map(2), env_from_world=SCALE),
    "mirror_ball": dict(image=random_map(3, 16, 16), projection="MIRROR_BALL"),
    "mirror_ball_scaled": dict(image=random_map(4, 9, 9), projection="MIRROR_BALL", env_from_world=SCALE),
}


@pytest.mark.parametrize("name", list(MAPS))
def test_pdf_and_eval_agree_with_sample(name):
    env = EnvironmentMap(**MAPS[name])
    s = env.sample(_u(20, 20_000))
    wi, Le, pdf, valid = s.wi, s.Le, s.pdf, s.valid
    assert np.allclose(np.linalg.norm(wi, axis=1), 1.0, rtol=0, atol=1e-12)
    assert np.all(np.isfinite(pdf)) and np.all((pdf > 0) == valid)
    np.testing.assert_allclose(env.pdf(wi[valid]), pdf[valid], rtol=1e-12, atol=0)
    np.testing.assert_array_equal(env.eval(wi[valid]), Le[valid])


@pytest.mark.parametrize("name", list(MAPS))
def test_light_sampling_estimates_are_unbiased(name):
    """E[g(w) / pdf(w)] over valid samples equals the integral of g over the sphere: g = 1
    gives 4 pi (the pdf is a density with full support, Jacobian of the mapping included),
    g = max(z, 0) gives pi."""
    env = EnvironmentMap(**MAPS[name])
    n = 400_000
    s = env.sample(_u(21, n))
    wi, pdf, valid = s.wi, s.pdf, s.valid
    inv = np.divide(1.0, pdf, out=np.zeros(n), where=valid)
    for g, exact in ((np.ones(n), 4.0 * np.pi), (np.maximum(wi[:, 2], 0.0), np.pi)):
        x = g * inv
        assert abs(x.mean() - exact) < 4.0 * x.std() / np.sqrt(n) + 1e-12 * exact, f"{x.mean()} vs {exact}"


@pytest.mark.parametrize("row", [0, 5, H - 1])
def test_light_sampling_weight_is_constant_inside_a_hot_pixel(row):
    """Single hot pixel on black: every sample falls in it, and L / pdf equals its radiance
    times its exact solid angle (2 pi / W)(cos theta_r - cos theta_r+1) for every sample,
    even in the pole rows where sin theta varies most across the pixel."""
    env = EnvironmentMap(hot_pixel_map(row, 7, hot=5.0, background=0.0))
    s = env.sample(_u(22, 50_000))
    wi, weight = s.wi, s.Le / s.pdf[:, None]
    solid_angle = 2.0 * np.pi / W * (np.cos(row * np.pi / H) - np.cos((row + 1) * np.pi / H))
    np.testing.assert_allclose(weight, np.broadcast_to([5.0, 2.5, 1.25], weight.shape) * solid_angle, rtol=1e-9)
    theta = np.arccos(np.clip(wi[:, 2], -1, 1))
    assert theta.min() < (row + 0.05) * np.pi / H and theta.max() > (row + 0.95) * np.pi / H  # fills the row


def test_sun_sky_table_balances_the_light_sampling_weight():
    """Luminance x solid angle tables make L_lum / pdf the same for every pixel (up to the
    float32 table): the sampler's ideal for a 1e5 : 1 sun."""
    env = EnvironmentMap(sun_sky_map())
    s = env.sample(_u(23, 20_000))
    lum = s.Le @ np.array([0.2126729, 0.7151522, 0.0721750])
    ratio = lum / s.pdf
    assert ratio.max() / ratio.min() < 1 + 1e-6


def test_direction_to_pixel_follows_cycles():
    """u = 0.5 - atan2(y, x) / 2 pi, v = 1 - theta / pi, rows top-down: +X is the centre of the
    image, +Y a quarter to the left, -Y a quarter to the right, -X at the seam, +Z the top row.
    Mirror ball (seen from -y): -Y at the centre, +X right, +Z top, +Y on the rim."""
    h, w = 8, 16
    img = np.arange(h * w * 3, dtype=np.float32).reshape(h, w, 3)
    env = EnvironmentMap(img)
    eps = 1e-3
    cases = [((1, eps, eps), (h // 2 - 1, w // 2 - 1)), ((1, -eps, -eps), (h // 2, w // 2)),
             ((0, 1, eps), (h // 2 - 1, w // 4)), ((0, -1, eps), (h // 2 - 1, 3 * w // 4)),
             ((-1, eps, eps), (h // 2 - 1, 0)), ((-1, -eps, eps), (h // 2 - 1, w - 1)),
             ((eps, 0, 1), (0, w // 2)), ((eps, 0, -1), (h - 1, w // 2))]
    for d, (r, c) in cases:
        d = np.array([d], float) / np.linalg.norm(d)
        np.testing.assert_array_equal(env.eval(d)[0], img[r, c])
    ball = EnvironmentMap(np.ascontiguousarray(img[:, :8]), projection="MIRROR_BALL")  # 8 x 8
    for d, (r, c) in [((eps, -1, eps), (3, 4)), ((1, eps, eps), (3, 6)), ((eps, eps, 1), (1, 4))]:
        d = np.array([d], float) / np.linalg.norm(d)
        np.testing.assert_array_equal(ball.eval(d)[0], img[r, c])


def test_mis_compensation_keeps_only_what_stands_out():
    """Compensated table: max(luminance - mean, 0) x solid angle. Pixels at or below the
    solid-angle mean luminance get pdf 0 (left to BSDF sampling); the sun keeps all samples of
    a sun + uniform sky map; a nearly flat map is not compensated."""
    img = np.ones((H, W, 3), np.float32)
    img[4, 10] = 1e3
    env = EnvironmentMap(img, compensate=True)
    assert env.compensated
    pdf = env.sample(_u(24, 1000)).pdf
    np.testing.assert_allclose(pdf, pdf[0])  # all in the sun pixel
    sky = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    assert np.all(env.pdf(sky) == 0) and np.all(EnvironmentMap(img).pdf(sky) > 0)
    flat = np.ones((H, W, 3), np.float32)
    flat[3, 3] = 1.005
    assert not EnvironmentMap(flat, compensate=True).compensated


# ----------------------------------------------------------------------------------------------
# What a world builds (model only what the scene needs)

def test_world_light_builds_only_what_is_needed():
    assert world_light(World(color=np.zeros(3)))[1] is None
    const, env = world_light(World(color=np.array([0.5, 0.5, 0.5])))
    assert env is None and np.allclose(const, 0.5)
    black, env = world_light(World(color=np.ones(3), image=np.zeros((8, 16, 3), np.float32)))
    assert env is None and not black.any()  # a black map is no light at all
    off, env = world_light(World(color=np.zeros(3), image=random_map(0)))
    assert env is None and not off.any()  # strength 0
    one, env = world_light(World(color=np.array([2.0, 2.0, 2.0]), image=np.full((1, 1, 3), 0.25, np.float32)))
    assert env is None and np.allclose(one, 0.5)  # a 1 x 1 map is a constant world
    flat, env = world_light(World(color=np.ones(3), image=np.full((64, 128, 3), (0.1, 0.2, 0.3), np.float32)))
    assert env is None and np.allclose(flat, (0.1, 0.2, 0.3))
    _, env = world_light(World(color=np.ones(3), image=random_map(0)))
    assert isinstance(env, EnvironmentMap)
    bad = random_map(0)
    bad[3, 4, 1] = np.nan
    with pytest.raises(EmberError, match="NaN"):
        world_light(World(color=np.ones(3), image=bad))
    with pytest.raises(EmberError, match="singular"):
        EnvironmentMap(random_map(0), env_from_world=np.diag([1.0, 0.0, 1.0]))


def test_power_integral_is_the_integral_of_radiance():
    """Equirectangular pixels are weighted by their exact solid angle: a constant map
    integrates to exactly 4 pi L."""
    env = EnvironmentMap(np.full((7, 13, 3), 0.5, np.float32), scale=(1.0, 2.0, 4.0))
    np.testing.assert_allclose(env.power_integral, 4 * np.pi * 0.5 * np.array([1.0, 2.0, 4.0]), rtol=1e-6)


def test_scene_save_load_round_trips_the_world(tmp_path):
    base = Scene(Mesh.empty(), Materials.make([]), Lights.make([]), World(), perspective((0, 0, 0), (1, 0, 0)), settings())
    for world in (World(color=np.array([0.1, 0.2, 0.3]), visible=False),
                  World(color=np.ones(3), image=random_map(0), projection="MIRROR_BALL",
                        env_from_world=rot_z(0.3))):
        base.replace(world=world).save(tmp_path / "s.npz")
        w = Scene.load(tmp_path / "s.npz").world
        assert w.visible == world.visible and w.projection == world.projection
        np.testing.assert_array_equal(w.color, world.color)
        np.testing.assert_array_equal(w.env_from_world, world.env_from_world)
        assert (w.image is None) == (world.image is None)
        if world.image is not None:
            assert w.image.dtype == np.float32
            np.testing.assert_array_equal(w.image, world.image)


# ----------------------------------------------------------------------------------------------
# In the light set and the path tracer

def test_environment_in_light_selection_and_mis_weights():
    """The environment is the last light, chosen by power pi R^2 x integral of L (pbrt-v4);
    its NEE pdf includes that pmf, and escaped rays are weighted by the balance heuristic
    against exactly that pdf."""
    mesh = quads_mesh([[[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]], [0])
    accel = Accel(mesh)
    lights = Lights.make([dict(kind=LIGHT_POINT, position=(0, 0, 2), Le=(3.0, 3.0, 3.0))])
    world = World(color=np.array([1.0, 1.0, 1.0]), image=sun_sky_map())
    ls = LightSet(lights, mesh, Materials.make([]), world, accel, accel.scene_radius)
    assert ls.env.compensated  # under MIS; environment sampling alone needs the complete table
    assert not LightSet(lights, mesh, Materials.make([]), world, accel, accel.scene_radius, "light").env.compensated
    env_power = np.pi * accel.scene_radius**2 * ls.env.power_integral.mean()
    point_power = 4 * np.pi * 3.0
    assert ls.env_index == 1
    np.testing.assert_allclose(ls.env_pmf, env_power / (env_power + point_power), rtol=1e-12)
    n = 4000
    rng = np.random.default_rng(5)
    p = np.zeros((n, 3))
    s = ls.sample(p, rng.random(n), rng.random((n, 2)))
    from_env = ~s.delta
    assert 0 < from_env.sum() < n and not s.finite[from_env].any()
    np.testing.assert_allclose(s.pdf[from_env], ls.env_pmf * ls.env.pdf(s.wi[from_env]), rtol=1e-12)
    np.testing.assert_allclose(s.Le[from_env], ls.env.eval(s.wi[from_env]))
    d = s.wi[from_env]
    pdf_bsdf = rng.random(len(d))
    escaped = ls.escaped(d, pdf_bsdf, np.ones(len(d), bool), np.zeros(len(d), bool))
    w = pdf_bsdf / (pdf_bsdf + s.pdf[from_env])
    np.testing.assert_allclose(escaped, ls.env.eval(d) * w[:, None], rtol=1e-12)
    unweighted = ls.escaped(d, pdf_bsdf, np.zeros(len(d), bool), np.zeros(len(d), bool))
    np.testing.assert_allclose(unweighted, ls.env.eval(d))


def _plane_under_environment(image, strategy, env_from_world=np.eye(3), projection="EQUIRECTANGULAR",
                             sun=None, albedo=0.6, samples=128):
    mesh = quads_mesh([[[-60, -60, 0], [60, -60, 0], [60, 60, 0], [-60, 60, 0]]], [0])
    world = World(color=np.ones(3), image=image, projection=projection, env_from_world=env_from_world)
    lights = Lights.make([sun] if sun else [])
    return Scene(mesh, Materials.make([dict(base_color=(albedo,) * 3)]), lights, world,
                 perspective((0, 0, 4), (0, 0.001, 0), 30),
                 settings(samples=samples, width=12, height=12, strategy=strategy, max_depth=4, threads=1))


def _irradiance_on_plane(env, k=16):
    """E = integral of L(d) max(d_z, 0) over the sphere, per map pixel (L is constant on it) by
    a k x k midpoint rule in coordinates where the pixel is a rectangle of uniform solid angle
    density ((phi, cos theta) for equirectangular, (x, y) for the equal-area mirror ball), so
    only the smooth max(d_z, 0) is approximated (error ~1e-5; the pixel edges are exact)."""
    H, W = env.shape
    s = (np.arange(k) + 0.5) / k
    if env.projection == "EQUIRECTANGULAR":
        z_edges = np.cos(np.arange(H + 1) * np.pi / H)
        z = (z_edges[:-1, None] + (z_edges[1:] - z_edges[:-1])[:, None] * s).ravel()  # (H k,)
        phi = np.pi * (1 - 2 * (np.arange(W)[:, None] + s).ravel() / W)  # (W k,)
        Z, P = np.meshgrid(z, phi, indexing="ij")
        S = np.sqrt(1 - Z**2)
        e = np.stack([S * np.cos(P), S * np.sin(P), Z], axis=-1)
        d_omega = np.repeat((2 * np.pi / (W * k)) * (z_edges[:-1] - z_edges[1:]) / k, k)[:, None]
        inside = np.ones(Z.shape, bool)
    else:
        y = ((np.arange(H)[:, None] + s) / H).ravel()
        x = ((np.arange(W)[:, None] + s) / W).ravel()
        Y, X = np.meshgrid(y, x, indexing="ij")
        bx, bz = 2 * X - 1, 1 - 2 * Y
        r2 = bx**2 + bz**2
        inside = r2 < 1
        c = np.sqrt(np.maximum(1 - r2, 0))
        e = np.stack([2 * c * bx, 2 * r2 - 1, 2 * c * bz], axis=-1)
        d_omega = 16.0 / (H * W * k * k)
    g = np.maximum((e @ env.world_from_env.T)[..., 2], 0.0) * d_omega * inside
    per_pixel = g.reshape(H, k, W, k).sum(axis=(1, 3))
    return np.einsum("hw,hwc->c", per_pixel, env.image.astype(np.float64)) * env.scale


def smooth_random_map(seed, h=H, w=W):
    return (0.2 + np.random.default_rng(seed).random((h, w, 3))).astype(np.float32)


SUN_TILT, SUN_HALF_ANGLE, SUN_LE = np.radians(40.0), np.radians(3.0), 300.0
SUN_LAMP = dict(kind=LIGHT_SUN, frame=rot_x(SUN_TILT).T, sun_half_angle=SUN_HALF_ANGLE, Le=(SUN_LE,) * 3)
RENDER_CASES = {
    "equirect_sun_sky": dict(image=sun_sky_map() * np.float32(2e-3) + np.float32(0.3)),  # sun 150 x sky
    "equirect_rotated": dict(image=smooth_random_map(6), env_from_world=rot_x(0.6) @ rot_z(1.0)),
    "mirror_ball": dict(image=smooth_random_map(7, 16, 16), projection="MIRROR_BALL"),
    "equirect_and_sun_lamp": dict(image=smooth_random_map(8), sun=SUN_LAMP),  # two escaped-ray lights
}


@pytest.mark.parametrize("case", list(RENDER_CASES))
def test_diffuse_plane_under_environment_all_strategies(case):
    """A diffuse plane of albedo rho lit by the environment alone has radiance rho E / pi
    everywhere (nothing else is in view or in the upper hemisphere). BSDF sampling alone,
    environment sampling alone and MIS must all converge to it: a wrong pdf, pmf or MIS weight
    biases at least one of them. z-test of the image mean (per-pixel tests are unreliable for
    BSDF sampling of a small sun at this sample count), Sidak-corrected over cases, strategies
    and channels."""
    kw = RENDER_CASES[case]
    E = _irradiance_on_plane(EnvironmentMap(**{k: v for k, v in kw.items() if k != "sun"}))
    if "sun" in kw:  # a cap of half-angle a, tilted t: projected solid angle pi sin^2 a cos t
        E = E + SUN_LE * np.pi * np.sin(SUN_HALF_ANGLE) ** 2 * np.cos(SUN_TILT)
    expected = 0.6 * E / np.pi
    crit = st.norm.ppf(1 - sidak_alpha(0.01, len(RENDER_CASES) * 3 * 3) / 2)
    for strategy in ("mis", "light", "bsdf"):
        session = RenderSession(_plane_under_environment(strategy=strategy, **kw))
        stats = session.run()
        mean, var = session.film.mean(), session.film.variance_of_mean()
        assert stats.nonfinite == 0
        image_se = np.sqrt(var.sum(axis=(0, 1))) / (mean.shape[0] * mean.shape[1])
        z = np.abs(mean.mean(axis=(0, 1)) - expected) / np.sqrt(image_se**2 + (1e-5 * expected) ** 2)
        assert z.max() < crit, f"{strategy}: |z| {z} >= {crit:.2f}"


def test_camera_sees_the_environment_unless_hidden():
    """Escaped camera rays see L(d) with weight 1: a narrow camera looking along +X sees the
    centre pixel of the map; World.visible False (camera visibility off or film transparent)
    renders the background black."""
    img = random_map(8, 8, 16)
    theta, phi = 3.5 / 8 * np.pi, np.pi * (1 - 2 * 7.5 / 16)  # centre of pixel (row 3, col 7)
    target = (np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta))
    view = dict(camera=perspective((0, 0, 0), target, 1.0), settings=settings(samples=4, width=4, height=4))
    base = Scene(Mesh.empty(), Materials.make([]), Lights.make([]), World(), **view)
    for visible in (True, False):
        scene = base.replace(world=World(color=np.array([1.0, 2.0, 0.5]), image=img, visible=visible))
        session = RenderSession(scene)
        session.run()
        expected = img[3, 7] * np.array([1.0, 2.0, 0.5]) if visible else np.zeros(3)
        np.testing.assert_allclose(session.film.mean(), np.broadcast_to(expected, (4, 4, 3)), rtol=1e-6)
