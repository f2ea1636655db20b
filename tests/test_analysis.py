"""Scene analysis (engine/choice/analysis.py) classifies hand-built scenes: an exterior under an
environment map, a glass caustic under a point light, a closed diffuse interior, a glossy
scene and a scene without light."""
import numpy as np

from ember.engine.choice.analysis import ENCLOSED, analyse
from ember.engine.scene import (LIGHT_POINT, LIGHT_RECT, LIGHT_SUN, LOBE_DIELECTRIC, LOBE_MICROFACET, MAT_DIFFUSE, Lights,
                                Materials, Mesh, Scene, World)

from core_scenes import box_quads, perspective, quads_mesh, settings, uv_sphere

FLOOR = [[[-10, -10, 0], [10, -10, 0], [10, 10, 0], [-10, 10, 0]]]
DIFFUSE = dict(kind=MAT_DIFFUSE, base_color=(0.8,) * 3)


def _with_sphere(quads, quad_mats, center, radius, sphere_mat):
    """quads_mesh plus a uv sphere of material sphere_mat."""
    base = quads_mesh(quads, quad_mats)
    v, t, n = uv_sphere(center, radius, 16, 32)
    return Mesh(np.concatenate([base.vertices, v]), np.concatenate([base.triangles, t + len(base.vertices)]),
                np.concatenate([base.normals, n]),
                np.concatenate([base.material, np.full(len(t), sphere_mat, np.int32)]))


def exterior_under_environment():
    h, w = 16, 32
    sky = np.ones((h, w, 3), np.float32) * np.linspace(2.0, 0.2, h, dtype=np.float32)[:, None, None]
    mesh = quads_mesh(FLOOR + list(box_quads((-1, -1, 0), (1, 1, 2))), [0] * 7)
    return Scene(mesh, Materials.make([DIFFUSE]), Lights.make([]), World(color=np.ones(3), image=sky),
                 perspective((0, -8, 3), (0, 0, 1), 50), settings())


def glass_caustic_under_point_light(glass=True):
    lobes = [dict(kind=LOBE_DIELECTRIC, roughness=0.0, ior=1.5)] if glass else [dict(color=(0.8,) * 3)]
    mats = Materials.make([DIFFUSE, dict(name="glass", lobes=lobes)])
    mesh = _with_sphere(FLOOR, [0], (0, 0, 1.0), 0.6, 1)
    lights = Lights.make([dict(kind=LIGHT_POINT, position=(0, 0, 2.2), Le=(50.0,) * 3)])
    return Scene(mesh, mats, lights, World(), perspective((0, -4, 3), (0, 0, 0.5), 50), settings())


def closed_interior(material=DIFFUSE):
    """A closed 4 m room lit by a small rectangle under its ceiling; camera inside."""
    mesh = quads_mesh(box_quads((-2, -2, 0), (2, 2, 4)), [0] * 6)
    frame = np.eye(3)  # emits along -z: down
    lights = Lights.make([dict(kind=LIGHT_RECT, position=(0, 0, 3.9), frame=frame, size=(0.25, 0.25), Le=(50.0,) * 3)])
    return Scene(mesh, Materials.make([material]), lights, World(), perspective((0, -1.5, 1.5), (0, 2, 1.2), 70),
                 settings())


def hot_spot_room(sun=False):
    """The closed room with its light 5 mm from a wall, tilted 60 degrees at it: the wall's hot
    spot lights the room (indirect noise ~22); with a sun outside the closed room, the same."""
    t = np.radians(60.0)
    z, x = np.array([np.sin(t), 0.0, np.cos(t)]), np.array([np.cos(t), 0.0, -np.sin(t)])
    rect = dict(kind=LIGHT_RECT, position=(-2 + 0.125 + 0.005, 0, 3.9), frame=np.array([x, np.cross(z, x), z]),
                size=(0.25, 0.25), Le=(50.0,) * 3)
    sun_light = dict(kind=LIGHT_SUN, frame=np.eye(3), sun_half_angle=0.005, Le=(1.0,) * 3)
    return closed_interior().replace(lights=Lights.make([rect] + ([sun_light] if sun else [])))


def glossy_scene():
    return closed_interior(dict(lobes=[dict(kind=LOBE_MICROFACET, roughness=0.5, color=(0.9,) * 3)]))


def no_light():
    return closed_interior().replace(lights=Lights.make([]))


def test_exterior_under_an_environment_is_open_and_lit_by_the_environment():
    a = analyse(exterior_under_environment(), pilot_rays=1024)
    assert a.light_kinds == ("environment",) and a.count("environment") == 1
    assert dict(a.light_power)["environment"] == 1.0
    assert a.escape_share > 0.3 and not a.enclosed
    assert not a.caustics_possible and np.isnan(a.caustic_share)
    assert a.diffuse_share == 1.0
    assert a.environment_texels == 16 * 32
    assert "open" in a.summary and "no caustics: no specular surface" in a.summary


def test_glass_under_a_point_light_makes_caustics():
    a = analyse(glass_caustic_under_point_light(), pilot_rays=1024)
    assert a.count("delta") == 1 and a.light_kinds == ("point",)
    assert a.caustics_possible and a.specular_share > 0.0
    # The sphere subtends (1 - cos 30 deg) / 2 = 6.7 % of the light's sphere; about half the
    # light reaches the floor, so some 10 % of it comes through the glass.
    assert 0.04 < a.caustic_share < 0.25
    assert a.pilot_photons > 0 and "caustics possible" in a.summary
    b = analyse(glass_caustic_under_point_light(glass=False), pilot_rays=1024)
    assert not b.caustics_possible and np.isnan(b.caustic_share) and b.pilot_photons == 0
    assert any("no caustic pilot: no specular surface" in s for s in b.skipped)


def test_closed_diffuse_interior_is_enclosed_with_strong_indirect_light():
    a = analyse(closed_interior(), pilot_rays=1024)
    assert a.escape_share == 0.0 and a.camera_escape_share == 0.0 and a.enclosed
    assert a.count("small") == 1  # 0.5 m light in a room of radius 3.5 m
    assert a.diffuse_share == 1.0 and a.glossy_share == 0.0
    # Albedo 0.8 all round: the indirect light is several times the direct, and smooth: a
    # path sample's indirect light varies little (E[I^2] / E[L]^2 is ~0.5; its floor, by
    # Cauchy-Schwarz, (E[I] / E[L])^2 = (r / (1 + r))^2, is ~0.46).
    r = a.indirect_ratio
    assert r > 1.5 and (r / (1 + r)) ** 2 <= a.indirect_noise < 1.0
    assert "enclosed" in a.summary


def test_a_hot_spot_makes_indirect_light_noisy():
    # The same room with its light 5 mm from a wall and turned at it: most light reaches the
    # room from the wall's hot spot, which few bounce rays find.
    a = analyse(hot_spot_room(), pilot_rays=4096)
    assert a.indirect_ratio > 5 and a.indirect_noise > 15


def test_glossy_scene_is_glossy():
    a = analyse(glossy_scene(), pilot_rays=1024)
    assert a.glossy_share == 1.0 and a.diffuse_share == 0.0 and a.specular_share == 0.0
    assert not a.caustics_possible


def test_scene_without_light_runs_no_light_pilots():
    a = analyse(no_light(), pilot_rays=256)
    assert not a.has_light and a.light_counts == () and a.light_kinds == ()
    assert np.isnan(a.indirect_ratio) and np.isnan(a.caustic_share)
    assert "no indirect-light pilot: the scene has no light" in a.skipped
    assert a.enclosed  # the probes still run


def test_light_sizes_are_classified_relative_to_the_scene():
    from ember.engine.scene import LIGHT_SUN
    scene = closed_interior()
    rows = [dict(kind=LIGHT_POINT, position=(0, 0, 2), Le=(1.0,) * 3),  # delta
            dict(kind=LIGHT_POINT, position=(0, 0, 2), radius=0.02, Le=(1.0,) * 3),  # tiny: 0.04 m / 3.5 m
            dict(kind=LIGHT_RECT, position=(0, 0, 3.9), frame=np.eye(3), size=(2.0, 2.0), Le=(1.0,) * 3),  # large
            dict(kind=LIGHT_SUN, frame=np.eye(3), sun_half_angle=0.01, Le=(1.0,) * 3)]
    a = analyse(scene.replace(lights=Lights.make(rows)), pilot_rays=64, pilot_photons=64)
    assert dict(a.light_counts) == {"delta": 1, "tiny": 1, "large": 1, "distant": 1}
    assert abs(sum(p for _, p in a.light_power) - 1.0) < 1e-9


def test_the_analysis_is_reproducible():
    a, b = analyse(glass_caustic_under_point_light(), pilot_rays=256), analyse(glass_caustic_under_point_light(), pilot_rays=256)
    assert (a.caustic_share, a.escape_share, a.indirect_ratio) == (b.caustic_share, b.escape_share, b.indirect_ratio)
    assert ENCLOSED < 0.5
