"""Light-path controls and the thin lens against analytic answers (no Blender): bounce limits
per ray type, transparent passes, sample clamping (Cycles' film_clamp_light) and depth of
field. The same controls are compared with Cycles in tests/test_light_paths.py."""
import numpy as np
import pytest

from ember.engine import camera as camera_mod
from ember.engine.rng import Sampler
from ember.engine.scene import (LIGHT_POINT, LOBE_TRANSPARENT, MAT_DIFFUSE, MAT_EMISSION_ONLY, Camera, Lights,
                               Materials, Scene, World)
from ember.engine.session import RenderSession

from core_scenes import furnace_box, look_at, perspective, quads_mesh, settings, sphere_with_point_light


def render(scene):
    session = RenderSession(scene)
    session.run()
    return session.film.mean(), session.film.variance_of_mean()


def _image_mean_z(mean, var, exact):
    return (mean.mean() - exact) / (np.sqrt(var.sum()) / var.size)


# ---- bounce limits ----------------------------------------------------------------------
@pytest.mark.parametrize("limits,terms", [(dict(diffuse_bounces=2), 3), (dict(max_depth=3), 4),
                                          (dict(diffuse_bounces=1, max_depth=5), 2),
                                          (dict(glossy_bounces=1, transmission_bounces=1), None)])
def test_furnace_with_bounce_limits_sums_that_many_bounces(limits, terms):
    """Every wall emits Le and reflects albedo a: a path that may scatter k times sees
    Le (1 + a + ... + a^k). Glossy and transmission limits do not touch diffuse paths."""
    a = 0.5
    mean, var = render(furnace_box(albedo=a, Le=1.0, samples=64, **limits))
    exact = 1.0 / (1.0 - a) if terms is None else sum(a**k for k in range(terms))
    assert abs(_image_mean_z(mean, var, exact)) < 4.0


def _transparent_stack(layers, **kw):
    """The camera looks through `layers` fully transparent sheets at a diffuse wall lit by a
    point light between the last sheet and the wall."""
    quads = [[[-5, y, -5], [-5, y, 5], [5, y, 5], [5, y, -5]] for y in 1.0 + 0.5 * np.arange(layers + 1)]
    mesh = quads_mesh(quads, [0] * layers + [1])
    mats = Materials.make([dict(lobes=[dict(kind=LOBE_TRANSPARENT, color=(1.0, 1.0, 1.0))]),
                           dict(kind=MAT_DIFFUSE, base_color=(0.5, 0.5, 0.5))])
    wall = 1.0 + 0.5 * layers
    lights = Lights.make([dict(kind=LIGHT_POINT, position=(0, wall - 0.25, 0), Le=(1.0, 1.0, 1.0))])
    return Scene(mesh, mats, lights, World(), perspective((0, 0, 0), (0, 1, 0), 30), settings(samples=2, **kw))


def test_transparent_passes_have_their_own_limit():
    """Three transparent sheets before a lit wall. As in Cycles (transparent_max_bounce is not
    + 1), the surface after the T-th pass only adds its emission: the wall is lit with 4
    transparent bounces, whatever Max Bounces (passes do not count toward it; nothing else is
    in the scene, so Max Bounces 1 gives the whole image), and black with 3."""
    lit, _ = render(_transparent_stack(3, transparent_bounces=4, max_depth=1))
    assert lit.min() > 0
    full, _ = render(_transparent_stack(3, transparent_bounces=4, max_depth=64))
    assert np.array_equal(lit, full)
    blocked, _ = render(_transparent_stack(3, transparent_bounces=3, max_depth=64))
    assert np.all(blocked == 0)


# ---- clamping ---------------------------------------------------------------------------
def _firefly_scene(radius=0.02, **kw):
    """A unit sphere lit by a small, very bright sphere light at its centre: BSDF-sampled hits
    of the light and the light's reflection are rare and large."""
    return sphere_with_point_light(radius=radius, intensity=np.pi, **dict(dict(samples=1, width=16, height=16), **kw))


def test_clamp_bounds_every_direct_contribution():
    """Direct light only (Max Bounces 1): camera emission, one light sample and one BSDF hit,
    each clamped to a mean RGB of c, so no 1-spp pixel exceeds 3c; unclamped ones do."""
    c = 0.05
    free, _ = render(_firefly_scene(max_depth=1))
    clamped, _ = render(_firefly_scene(max_depth=1, clamp_direct=c))
    assert free.mean(axis=2).max() > 10 * c  # the test has power
    assert clamped.mean(axis=2).max() <= 3 * c * (1 + 1e-12)
    # A clamped light sample keeps a mean RGB of c (Cycles compares R+G+B with 3c), not less.
    assert clamped.mean(axis=2).max() >= c * (1 - 1e-9)
    # Indirect clamping leaves direct light alone, light found by BSDF sampling included
    # (a large light: many BSDF hits).
    free, _ = render(_firefly_scene(radius=0.3, max_depth=1, samples=4))
    indirect_only, _ = render(_firefly_scene(radius=0.3, max_depth=1, samples=4, clamp_indirect=c))
    assert free.max() > 3 * c
    assert np.array_equal(indirect_only, free)


def test_clamp_bounds_every_indirect_contribution():
    """Max Bounces 3 adds four indirect contributions (light samples at the 2nd and 3rd
    vertex, emission found by the 2nd and 3rd BSDF ray) to the direct ones, which are the same
    random paths as at Max Bounces 1: each indirect one is clamped to a mean RGB of c."""
    c = 0.02
    direct, _ = render(_firefly_scene(max_depth=1))
    free, _ = render(_firefly_scene(max_depth=3))
    clamped, _ = render(_firefly_scene(max_depth=3, clamp_indirect=c))
    assert (free - direct).mean(axis=2).max() > 10 * c
    assert (clamped - direct).mean(axis=2).max() <= 4 * c + 1e-9
    assert (clamped - direct).min() >= -1e-9


def test_clamp_that_never_binds_changes_nothing():
    free, _ = render(_firefly_scene(max_depth=3, samples=4))
    huge, _ = render(_firefly_scene(max_depth=3, samples=4, clamp_direct=1e30, clamp_indirect=1e30))
    assert np.array_equal(free, huge)


# ---- thin lens --------------------------------------------------------------------------
def _lens_camera(**kw):
    m = look_at((0, 0, 0), (0, 1, 0))
    return Camera(world_from_camera=m, window=np.array([-0.2, 0.2, -0.2, 0.2]), clip_start=0.1, clip_end=100.0,
                  **kw)


@pytest.mark.parametrize("blades,ratio", [(0, 1.0), (5, 1.0), (0, 2.0), (6, 0.5)])
def test_rays_of_a_pixel_meet_on_the_plane_of_focus(blades, ratio):
    """Whatever the lens sample, a pixel's rays pass through the point its pinhole ray meets
    the plane of focus, start on the aperture (pushed to the near clip along the ray), and
    cover the aperture's shape: a disk or a regular polygon of the given radius, x / ratio."""
    cam = _lens_camera(aperture_radius=0.1, focus_distance=3.0, blades=blades, blade_rotation=0.3, aperture_ratio=ratio)
    s = settings(width=8, height=8, filter="BOX")
    n = 4096
    px, py = np.full(n, 5), np.full(n, 2)
    sampler = Sampler(3, np.arange(n), np.zeros(n, np.int64), "random")
    u_f = sampler.get(0, None, 2)
    o, d, tmax = camera_mod.generate_rays(cam, s, px, py, u_f, sampler.get(camera_mod.LENS_GROUP, None, 2))
    o0, d0, _ = camera_mod.generate_rays(cam, s, px, py, u_f)
    # World y is the view axis (camera -z): the focus plane is y = 3.
    focus = o + d * ((3.0 - o[:, 1]) / d[:, 1])[:, None]
    pinhole = o0 + d0 * ((3.0 - o0[:, 1]) / d0[:, 1])[:, None]
    assert np.allclose(focus, pinhole, atol=1e-12)
    # Back on the lens plane y = 0: camera x = world x, camera y = world z.
    lens = o - d * (o[:, 1] / d[:, 1])[:, None]
    x, y = lens[:, 0] * ratio, lens[:, 2]
    r, phi = np.hypot(x, y), np.arctan2(y, x)
    if blades:
        # Inside the polygon with corners at rotation + (2k+1) pi / blades, radius 0.1
        # (Cycles' regular_polygon_sample: edge normals at rotation + 2k pi / blades).
        half = np.pi / blades
        sector = np.mod(phi - 0.3 + half, 2 * half) - half  # angle to the nearest edge's normal
        assert np.all(r * np.cos(sector) <= 0.1 * np.cos(half) + 1e-12)
        area = blades * 0.1**2 * np.sin(half) * np.cos(half)
    else:
        assert np.all(r <= 0.1 + 1e-12)
        area = np.pi * 0.1**2
    # Uniform: the fraction within half the radius is a quarter (any star-shaped aperture).
    inner = np.mean(r <= 0.05 * (np.cos(half) / np.cos(sector) if blades else 1.0))
    assert abs(inner - 0.25) < 4 * np.sqrt(0.25 * 0.75 / n)
    assert area > 0
    # Clipped where the pinhole ray is: the same distance to the far clip.
    assert np.allclose(tmax, camera_mod.generate_rays(cam, s, px, py, u_f)[2])


def test_pinhole_rays_do_not_draw_lens_numbers():
    """No aperture: camera_rays asks for the filter's numbers only (images unchanged)."""
    calls = []

    class Spy:
        def get(self, dim, rows=None, k=1):
            calls.append(dim)
            return np.full((3, k), 0.5)

    camera_mod.camera_rays(_lens_camera(), settings(width=4, height=4), np.arange(3), np.arange(3), Spy())
    assert calls == [0]
    camera_mod.camera_rays(_lens_camera(aperture_radius=0.1), settings(width=4, height=4), np.arange(3),
                           np.arange(3), Spy())
    assert calls == [0, camera_mod.LENS_GROUP, 0]


def _disk_step(x):
    """Fraction of a unit disk centred at x (in radii) on the side t < 0 of a straight edge."""
    x = np.clip(x, -1.0, 1.0)
    return (np.arccos(x) - x * np.sqrt(1.0 - x * x)) / np.pi


def test_defocused_edge_is_the_circle_of_confusion():
    """A camera focused at 2 m looks at an emitting half-plane 4 m away, edge through the view
    axis: each pixel sees the edge through a disk of radius R = A (z - f) / f on the plane
    (A the aperture radius), so a column at x sees the lit fraction of that disk; averaged over
    the pixel (box filter) it matches per column within the noise."""
    A, f, z, W = 0.2, 2.0, 4.0, 32
    half = 0.25  # window half-width at z = -1
    quad = [[[0, z, -5], [0, z, 5], [5, z, 5], [5, z, -5]]]  # x >= 0, facing -y
    mesh = quads_mesh(quad, [0])
    mats = Materials.make([dict(kind=MAT_EMISSION_ONLY, base_color=(0, 0, 0), emission=(1.0, 1.0, 1.0))])
    cam = Camera(world_from_camera=look_at((0, 0, 0), (0, 1, 0)), window=np.array([-half, half, -half, half]),
                 clip_start=0.01, clip_end=100.0, aperture_radius=A, focus_distance=f)
    scene = Scene(mesh, mats, Lights.make([]), World(), cam,
                  settings(width=W, height=4, samples=256, filter="BOX", filter_width=1.0))
    mean, var = render(scene)
    col, col_var = mean[..., 0].mean(axis=0), var[..., 0].sum(axis=0) / (4 * 4)
    R = A * (z - f) / f  # on the plane
    pixel = 2 * half * z / W  # pixel width on the plane
    x_edges = (np.arange(W + 1) - W / 2) * pixel
    t = np.linspace(0, 1, 2001)
    expected = np.array([_disk_step(-(x0 + (x1 - x0) * t) / R).mean() for x0, x1 in zip(x_edges[:-1], x_edges[1:])])
    assert 2 * R / pixel > 3  # the blur spans several pixels: a wrong radius shows
    z_cols = (col - expected) / np.sqrt(np.maximum(col_var, 1e-12))
    partial = (expected > 0.02) & (expected < 0.98)
    assert np.all(np.abs(z_cols[partial]) < 4.5), z_cols[partial]
    assert np.allclose(col[~partial], expected[~partial], atol=0.03)


def test_other_integrators_warn_about_path_only_controls():
    """Photon mapping uses Max Bounces alone and the whole scene for every ray: it says so."""
    import dataclasses

    scene = furnace_box(integrator="photon", diffuse_bounces=3, clamp_indirect=2.0)
    assert len(RenderSession(scene).warnings) == 1
    hidden = dataclasses.replace(scene.mesh, visibility=np.full(scene.mesh.n_triangles, 30, np.uint8))
    warnings = RenderSession(scene.replace(mesh=hidden)).warnings
    assert any("diffuse bounces, clamp indirect" in w for w in warnings)
    assert any("ray visibility" in w for w in warnings)
    assert RenderSession(furnace_box(diffuse_bounces=3, clamp_indirect=2.0)).warnings == []


def test_filter_glossy_blurs_mirrors_after_rough_bounces_only():
    """Cycles' Filter Glossy: a mirror seen by camera rays (no rough bounce yet) is untouched;
    after a bounce of pdf p the closure's GGX alpha is at least sqrt(1 - p / k) / 2."""
    from ember.engine.bsdf.closure import Closure
    from ember.engine.integrators.path_options import ClosureOptions
    from ember.engine.integrators.path_state import Bounces
    from ember.engine.scene import LOBE_MICROFACET

    mats = Materials.make([dict(lobes=[dict(kind=LOBE_MICROFACET, roughness=0.0, color=(1.0, 1.0, 1.0))])])
    n = 3
    up = np.tile([0.0, 0.0, 1.0], (n, 1))
    b = Bounces.start(n, 64, min_pdf=True)
    b.min_pdf = np.array([np.inf, 0.5, 4.0])
    min_alpha = ClosureOptions(True, True, filter_glossy=2.0).blur(b)
    np.testing.assert_allclose(min_alpha, [0.0, 0.5 * np.sqrt(0.75), 0.0])
    scene = furnace_box().replace(materials=mats)
    c = Closure(scene, np.zeros(n, np.int32), up, up, up, np.zeros(n, np.int64), np.full((n, 3), 1 / 3), min_alpha=min_alpha)
    assert c.pair_delta.tolist() == [True, False, True]
    (glossy,) = c.groups  # the microfacet lobe's pairs
    np.testing.assert_allclose(glossy.p.alpha[1], 0.5 * np.sqrt(0.75))
    assert ClosureOptions(True, True, filter_glossy=0.0).blur(b) is None


def test_holdout_is_black_and_transparent_camera_hidden_objects_are_not_seen():
    """Camera rays see a holdout as a hole (black, alpha 0 on a transparent film, as Cycles);
    an object hidden from camera rays is looked through (the emitter behind it is seen)."""
    import dataclasses

    from ember.engine.scene import HOLDOUT, RAY_ALL, RAY_CAMERA

    front = [[-5, 1, -5], [-5, 1, 5], [5, 1, 5], [5, 1, -5]]
    back = [[-5, 2, -5], [-5, 2, 5], [5, 2, 5], [5, 2, -5]]
    mesh = quads_mesh([front, back], [0, 1])
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(0.5, 0.5, 0.5)),
                           dict(kind=MAT_EMISSION_ONLY, base_color=(0, 0, 0), emission=(1.0, 1.0, 1.0))])
    scene = Scene(mesh, mats, Lights.make([]), World(), perspective((0, 0, 0), (0, 1, 0), 30),
                  settings(samples=2, film_transparent=True))
    vis = np.array([RAY_ALL | HOLDOUT] * 2 + [RAY_ALL] * 2, np.uint8)  # the front sheet a holdout
    session = RenderSession(scene.replace(mesh=dataclasses.replace(mesh, visibility=vis)))
    session.run()
    rgba = session.film.image()
    assert np.all(rgba[..., :3] == 0) and np.all(rgba[..., 3] == 0)
    vis = np.array([RAY_ALL & ~RAY_CAMERA] * 2 + [RAY_ALL] * 2, np.uint8)  # the front sheet hidden from the camera
    session = RenderSession(scene.replace(mesh=dataclasses.replace(mesh, visibility=vis)))
    session.run()
    rgba = session.film.image()
    assert np.allclose(rgba[..., :3], 1.0) and np.all(rgba[..., 3] == 1)
