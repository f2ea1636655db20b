"""Render passes and film transparency without Blender (engine/passes.py): the light passes
sum to Combined sample by sample, the hit passes are exact on simple geometry, and a
transparent film is the opaque image less the world the camera sees."""
import numpy as np
import pytest

from ember.engine import passes as passes_mod
from ember.engine.scene import (LOBE_DIELECTRIC, LOBE_DIFFUSE, LOBE_MICROFACET, MAT_NODES, Lights, Materials,
                                Mesh, Scene, World)
from ember.engine.session import RenderSession

from core_scenes import perspective, quads_mesh, settings, uv_sphere

LIGHT = [p.name for p in passes_mod.PASSES if p.group in ("light", "color")]


def _scene(**kw):
    """A diffuse floor, a glossy-over-diffuse sphere and a glass sphere under a point light and
    an emissive quad, in a blue world that fills the top of the view."""
    floor = quads_mesh([[(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)]], [0])
    lamp = quads_mesh([[(-2.5, 2, 0.5), (-2.5, 2, 1.5), (-1.5, 2, 1.5), (-1.5, 2, 0.5)]], [3])
    parts = [(floor.vertices, floor.triangles, floor.normals, floor.material),
             (lamp.vertices, lamp.triangles, lamp.normals, lamp.material)]
    for centre, m in (((-0.6, 0, 0.5), 1), ((0.6, 0, 0.5), 2)):
        v, t, n = uv_sphere(centre, 0.5, 16, 32)
        parts.append((v, t, n, np.full(len(t), m, np.int32)))
    offset, tris = 0, []
    for v, t, _, _ in parts:
        tris.append(t + offset)
        offset += len(v)
    mesh = Mesh(np.concatenate([p[0] for p in parts]).astype(np.float32), np.concatenate(tris).astype(np.int32),
                np.concatenate([p[2] for p in parts]).astype(np.float32), np.concatenate([p[3] for p in parts]))
    mats = Materials.make([
        dict(kind=MAT_NODES, lobes=[dict(kind=LOBE_DIFFUSE, color=(0.7, 0.5, 0.3))]),
        dict(kind=MAT_NODES, lobes=[dict(kind=LOBE_MICROFACET, color=(0.9, 0.9, 0.9), roughness=0.3, weight=(0.5,) * 3),
                                    dict(kind=LOBE_DIFFUSE, color=(0.2, 0.6, 0.2), weight=(0.5,) * 3)]),
        dict(kind=MAT_NODES, lobes=[dict(kind=LOBE_DIELECTRIC, color=(1, 1, 1), tint=(1, 1, 1), roughness=0.0,
                                         ior=1.5)]),
        dict(kind=MAT_NODES, lobes=[], emission=(4.0, 4.0, 4.0)),
    ])
    lights = Lights.make([dict(kind=0, position=(1, -1, 2.5), radius=0.1, Le=(30.0,) * 3, soft=True)])
    camera = perspective((0, -4, 1.2), (0, 0, 0.6), 50)
    base = dict(width=24, height=24, samples=4, threads=1, passes=tuple(LIGHT))
    base.update(kw)
    return Scene(mesh, mats, lights, World(color=np.array([0.1, 0.2, 0.4])), camera, settings(**base))


def _render(scene):
    session = RenderSession(scene)
    session.run()
    return session.film


def test_light_passes_sum_to_combined():
    film = _render(_scene())
    combined = film.pass_image("Combined")[..., :3].astype(np.float64)
    total = film.pass_image("Emission") + film.pass_image("Environment")
    for cls in passes_mod.LOBE_CLASSES:
        col = film.pass_image(f"{cls} Color")
        light = film.pass_image(f"{cls} Direct") + film.pass_image(f"{cls} Indirect")
        assert light.max() > 0, cls  # every class lit somewhere: the test sees each term
        total = total + light.astype(np.float64) * col
    for name in ("Emission", "Environment"):
        assert film.pass_image(name).max() > 0, name
    np.testing.assert_allclose(total, combined, rtol=2e-5, atol=1e-6)


def test_passes_cost_nothing_unrequested_and_leave_combined_unchanged():
    plain = _render(_scene(passes=()))
    split = _render(_scene())
    assert plain.pass_sum == {}
    np.testing.assert_array_equal(plain.mean(), split.mean())


def test_hit_passes_on_a_facing_plane_are_exact():
    """A diffuse plane facing the camera at distance 2: Depth 2,
    Normal towards the camera, Position on the plane (world space, after recentring), Albedo
    the base colour - noise-free."""
    plane = quads_mesh([[(4, 2, 0), (10, 2, 0), (10, 2, 6), (4, 2, 6)]], [0])
    mats = Materials.make([dict(kind=MAT_NODES, lobes=[dict(kind=LOBE_DIFFUSE, color=(0.3, 0.6, 0.9))])])
    names = ("Depth", "Position", "Normal", "Denoising Albedo", "Denoising Normal")
    scene = Scene(plane, mats, Lights.make([]), World(color=np.ones(3)), perspective((7, 0, 3), (7, 1, 3), 30),
                  settings(width=8, height=8, samples=3, passes=names, filter="GAUSSIAN", filter_width=1.5))
    film = _render(scene)
    assert film.pass_image("Depth").shape == (8, 8, 1)
    np.testing.assert_allclose(film.pass_image("Depth")[..., 0], 2.0, rtol=1e-6)
    np.testing.assert_allclose(film.pass_image("Position")[..., 1], 2.0, rtol=1e-6)
    assert np.all(np.abs(film.pass_image("Position")[..., 0] - 7.0) < 1.0)
    np.testing.assert_allclose(film.pass_image("Normal"), np.broadcast_to([0, -1, 0], (8, 8, 3)), atol=1e-6)
    # Cycles' camera space (z forward): the normal points back at the camera (-z).
    np.testing.assert_allclose(film.pass_image("Denoising Normal"), np.broadcast_to([0, 0, -1], (8, 8, 3)), atol=1e-6)
    np.testing.assert_allclose(film.pass_image("Denoising Albedo"), np.broadcast_to([0.3, 0.6, 0.9], (8, 8, 3)),
                               rtol=1e-6)
    # The pixel at the view's centre: pixel count and variance debug passes.
    film_debug = _render(scene.replace(settings=scene.settings.replace(passes=("Debug Sample Count",))))
    np.testing.assert_array_equal(film_debug.pass_image("Debug Sample Count"), 1.0)  # Cycles' scale: 3 of 3
    film_debug.count[0] = 1  # a pixel with one sample of three
    assert film_debug.pass_image("Debug Sample Count")[0, 0, 0] == np.float32(1 / 3)


def test_depth_where_the_camera_sees_only_the_world_is_cycles_1e10():
    scene = _scene(passes=("Depth",), width=16, height=16)
    depth = _render(scene).pass_image("Depth")[..., 0]
    assert depth[0, 8] == passes_mod.DEPTH_MISS  # the top row looks at the sky
    assert depth[-1, 8] < 10


def test_transparent_film_is_the_opaque_image_less_the_world_seen():
    """Alpha 0 where camera rays see only the world, 1 on objects; the colour is premultiplied:
    opaque = transparent + (1 - alpha) x world, per pixel (the same samples), and the world
    still lights the objects."""
    opaque = _render(_scene(passes=()))
    clear = _render(_scene(passes=(), film_transparent=True))
    rgba = clear.image()
    alpha = rgba[..., 3]
    assert alpha[0, 12] == 0.0 and np.all(rgba[0, 12, :3] == 0)  # sky
    assert alpha[-1, 12] == 1.0  # floor
    assert 0.0 < alpha.min() < 1.0 or np.any((alpha > 0) & (alpha < 1))  # antialiased edges
    world = np.array([0.1, 0.2, 0.4])
    np.testing.assert_allclose(rgba[..., :3] + (1.0 - alpha)[..., None] * world, opaque.image()[..., :3],
                               rtol=1e-5, atol=1e-6)


def test_unknown_pass_is_refused():
    from ember.engine.errors import EmberError
    with pytest.raises(EmberError, match="unknown render pass"):
        RenderSession(_scene(passes=("Diffuse Lighting",)))


def test_one_bounce_is_all_direct_and_colours_are_the_albedos():
    """max_depth 1: light after the first bounce only, so every Indirect pass is 0; the floor's
    Diffuse Color is its base colour and it has no glossy or transmission colour."""
    film = _render(_scene(max_depth=1))
    for cls in passes_mod.LOBE_CLASSES[:2]:
        assert film.pass_image(f"{cls} Direct").max() > 0
    for cls in passes_mod.LOBE_CLASSES:
        assert film.pass_image(f"{cls} Indirect").max() == 0
    floor = film.pass_image("Diffuse Color")[-1, 12]
    np.testing.assert_allclose(floor, [0.7, 0.5, 0.3], rtol=1e-6)
    assert film.pass_image("Glossy Color")[-1, 12].max() == 0


def test_caustics_pass_is_the_caustic_maps_term():
    """`photon`'s Caustics pass is exactly what its caustic debug view shows on the floor (the
    same photon maps, same seed), is non-zero under the glass sphere, and leaves Combined as it
    was without it."""
    kw = dict(integrator="photon", photons=3000, caustic_photons=30000, gather_rays=2, samples=1, width=16,
              height=16)
    with_pass = _render(_scene(**{**kw, "passes": ("Caustics",)}))
    caustic_view = _render(_scene(**{**kw, "passes": (), "photon_view": "caustic"}))
    plain = _render(_scene(**{**kw, "passes": ()}))
    caustics = with_pass.pass_image("Caustics")
    assert caustics.max() > 0
    floor = np.s_[-4:, :]  # the camera sees the floor there, no emitter
    assert caustics[floor].max() > 0
    np.testing.assert_allclose(caustics[floor], caustic_view.mean()[floor], rtol=1e-5, atol=1e-7)
    np.testing.assert_array_equal(with_pass.mean(), plain.mean())


def test_direct_is_the_first_bounce_alone():
    """A second bounce adds Indirect light and leaves every Direct pass exactly as it was
    (the same random numbers drive the first bounce whatever the depth)."""
    one, two = _render(_scene(max_depth=1)), _render(_scene(max_depth=2))
    for cls in passes_mod.LOBE_CLASSES:
        np.testing.assert_array_equal(one.pass_image(f"{cls} Direct"), two.pass_image(f"{cls} Direct"))
    assert two.pass_image("Diffuse Indirect").max() > 0


def test_icache_writes_the_caustics_pass_and_keeps_combined():
    """`icache` shades caustics as `photon` does: its Caustics pass is non-zero on the floor
    under the glass sphere, and turning it on leaves Combined unchanged."""
    kw = dict(integrator="icache", photons=3000, caustic_photons=30000, gather_rays=2, samples=1, width=16,
              height=16, icache_rays=50)
    with_pass = _render(_scene(**{**kw, "passes": ("Caustics",)}))
    plain = _render(_scene(**{**kw, "passes": ()}))
    assert with_pass.pass_image("Caustics")[-4:, :].max() > 0
    np.testing.assert_array_equal(with_pass.mean(), plain.mean())
