"""The light tree (engine/lights/light_tree.py behind LightSet): the lights it chooses follow the
pmf it reports (chi-square), that pmf sums to 1 and is what the emitter-hit MIS weights read
(pdf of a sample == pmf x the light's own pdf, for the same shading point), it is 0 only
where a light cannot shine, and renders with it agree with power selection (z-tests) with less
noise in a many-lights scene."""
import numpy as np
import pytest

from ember.engine.accel import Accel
from ember.engine.lights import light_set, shapes
from ember.engine.lights.light_set import LightSet
from ember.engine.scene import (LIGHT_DISK, LIGHT_POINT, LIGHT_RECT, LIGHT_SPOT, LIGHT_SUN, MAT_DIFFUSE,
                                MAT_EMISSION_ONLY, Lights, Materials, World)
from ember.engine.session import RenderSession

from core_scenes import many_lights, quads_mesh
from stats import ChiSquareTest, Discrete, sidak_alpha, z_test_p_values

ALPHA = 0.01
POINTS = np.array([[0.3, 0.2, 0.0], [-6.0, 4.0, 0.0], [7.5, -7.5, 2.0]])


def _frame_down(tilt):
    z = np.array([tilt, 0.2 * tilt, 1.0])
    z /= np.linalg.norm(z)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z])  # -z (the emitting side, the spot axis) points down


def mixed_light_set():
    """A floor, 120 small emissive squares (240 triangles) of varied power, and analytic lights
    of every finite kind plus a sun, with the tree forced on (threshold 1)."""
    rng = np.random.default_rng(3)
    quads = [[[-20, -20, 0], [20, -20, 0], [20, 20, 0], [-20, 20, 0]]]
    mats = [dict(kind=MAT_DIFFUSE, base_color=(0.5,) * 3)]
    for x, y in rng.uniform(-10, 10, (120, 2)):
        s, h = 0.1, rng.uniform(0.2, 3.0)
        quads.append([[x - s, y - s, h], [x - s, y + s, h + 0.05], [x + s, y + s, h], [x + s, y - s, h - 0.05]])
        mats.append(dict(kind=MAT_EMISSION_ONLY, emission=(10 ** rng.uniform(0, 3),) * 3))
    mesh = quads_mesh(quads, list(range(len(quads))))
    lights = Lights.make([
        dict(kind=LIGHT_POINT, position=(1, 2, 1), Le=(5.0,) * 3),
        dict(kind=LIGHT_POINT, position=(-3, 1, 1.5), radius=0.2, soft=False, Le=(40.0,) * 3),
        dict(kind=LIGHT_POINT, position=(4, -4, 1.0), radius=0.3, soft=True, Le=(30.0,) * 3),
        dict(kind=LIGHT_SPOT, position=(0, 5, 3), frame=_frame_down(0.3), Le=(200.0,) * 3,
             spot_cos_half=np.cos(0.4), spot_smooth=0.1),
        dict(kind=LIGHT_RECT, position=(-5, -5, 2.5), frame=_frame_down(0.5), size=(0.5, 0.3), Le=(20.0,) * 3),
        dict(kind=LIGHT_DISK, position=(6, 6, 2.0), frame=_frame_down(-0.4), size=(0.4, 0.4), Le=(25.0,) * 3),
        dict(kind=LIGHT_SUN, frame=_frame_down(0.2), sun_half_angle=0.05, Le=(3.0,) * 3),
    ])
    accel = Accel(mesh)
    return LightSet(lights, mesh, Materials.make(mats), World(), accel, accel.scene_radius, tree_min_lights=1)


@pytest.fixture(scope="module")
def ls():
    return mixed_light_set()


def test_the_tree_is_used_from_the_threshold_on():
    sc = many_lights(40, "point")
    accel = Accel(sc.mesh)
    make = lambda k: LightSet(sc.lights, sc.mesh, sc.materials, sc.world, accel, accel.scene_radius, tree_min_lights=k)
    assert make(41).tree is None and make(40).tree is not None
    assert light_set.TREE_MIN_LIGHTS > 8 and make(None).tree is not None  # 40 lights: the tree


def test_clustered_lights_keep_power_selection():
    """An emissive sphere of 960 triangles, small in its scene: every triangle is about as far
    from every receiver, so no tree (TREE_MIN_SPREAD); the same sphere filling the scene gets one."""
    from core_scenes import uv_sphere
    from ember.engine.scene import Mesh

    def light_set_of(radius):
        floor = quads_mesh([[[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]]], [0])
        v, t, n = uv_sphere((0, 0, 2), radius, 16, 32)
        mesh = Mesh(np.concatenate([floor.vertices, v]), np.concatenate([floor.triangles, t + 4]),
                    np.concatenate([floor.normals, n]), np.concatenate([floor.material, np.ones(len(t), np.int32)]))
        mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(0.5,) * 3), dict(kind=MAT_EMISSION_ONLY, emission=(5.0,) * 3)])
        accel = Accel(mesh)
        return LightSet(Lights.make([]), mesh, mats, World(), accel, accel.scene_radius)
    small, large = light_set_of(0.2), light_set_of(4.0)
    assert len(small.tri_prim) > light_set.TREE_MIN_LIGHTS and small.tree is None
    assert large.tree is not None


def test_pmf_sums_to_one_at_every_point(ls):
    assert ls.tree is not None and 0 < ls.p_infinite < 1
    for p in POINTS:
        pmf = ls.pmf(np.arange(ls.count), np.tile(p, (ls.count, 1)))
        assert abs(pmf.sum() - 1.0) < 1e-9
        assert (pmf > 0).sum() > 100  # not degenerate


def test_chosen_lights_follow_the_pmf(ls):
    """Chi-square of the chosen light indices against the pmf at three shading points."""
    n = 200_000
    for i, p in enumerate(POINTS):
        pts = np.tile(p, (n, 1))

        def sampler(u):
            index, pmf = ls._choose(pts, u[:, 0])
            # What the sampler reports is the pmf of what it chose, at the same point.
            np.testing.assert_allclose(pmf, ls.pmf(index, pts), rtol=1e-12)
            return index

        ChiSquareTest(Discrete(ls.count), sampler, lambda k: ls.pmf(k, np.tile(p, (len(k), 1))), n_samples=n,
                      seed=[11, i], sample_dim=1, name=f"point {p}").check(ALPHA, n_tests=len(POINTS))


def test_sample_pdf_is_what_a_hit_reports(ls):
    """The pdf of every light sample equals the pdf the emitter-hit side computes for the same
    point on the light from the same shading point: pdf_triangle_hit for triangles, pmf(i, p)
    x hit_analytic's pdf_dir for hittable analytic lights (the MIS weights' two sides)."""
    rng = np.random.default_rng(5)
    n = 40_000
    p = np.column_stack([rng.uniform(-10, 10, (n, 2)), rng.uniform(0.0, 1.0, n)])
    s = ls.sample(p, rng.random(n), rng.random((n, 2)))
    tri = np.flatnonzero(s.valid & (s.target_prim >= 0))
    assert len(tri) > 1000
    v = s.target[tri] - p[tri]
    t = np.linalg.norm(v, axis=1)
    cos = np.abs(np.sum(s.wi[tri] * ls.tri_ng[ls.light_of_prim[s.target_prim[tri]] - ls.n_analytic], axis=1))
    np.testing.assert_allclose(ls.pdf_triangle_hit(s.target_prim[tri], p[tri], t, cos, None), s.pdf[tri], rtol=1e-6)
    checked = 0
    for i in ls.hittable.tolist():
        h = shapes.hit_analytic(int(ls.lights.kind[i]), ls.lights, i, p, s.wi, np.full(n, np.inf))
        mine = np.flatnonzero(s.valid & h.hit & (s.target_prim < 0) & s.finite)
        mine = mine[np.linalg.norm(s.target[mine] - ls.lights.position[i], axis=1) < 1.0]
        np.testing.assert_allclose(ls.pmf(np.full(len(mine), i), p[mine]) * h.pdf[mine], s.pdf[mine], rtol=1e-6)
        checked += len(mine)
    assert checked > 100
    # emission_along weighs what the rays find with that same pmf, at the rays' origins.
    pdf_bsdf = np.full(n, 0.3)
    found = ls.emission_along(p, s.wi, np.full(n, np.inf), pdf_bsdf, np.ones(n, bool), np.zeros(n, bool))
    expect = np.zeros((n, 3))
    for i in ls.hittable.tolist():
        h = shapes.hit_analytic(int(ls.lights.kind[i]), ls.lights, i, p, s.wi, np.full(n, np.inf))
        r = np.flatnonzero(h.hit)
        w = pdf_bsdf[r] / (pdf_bsdf[r] + ls.pmf(np.full(len(r), i), p[r]) * h.pdf[r])
        expect[r] += (h.gain[r] * w)[:, None] * ls.lights.Le[i]
    assert np.count_nonzero(expect[:, 0]) > 100
    np.testing.assert_allclose(found, expect, rtol=1e-9)


def test_pmf_is_zero_only_behind_one_sided_lights(ls):
    """Conservative bounds: the rect and the disk (one-sided, emitting along -z) get pmf 0 only
    at points that are behind them; points in front always get pmf > 0."""
    rng = np.random.default_rng(2)
    n = 20_000
    p = rng.uniform(-12, 12, (n, 3))
    for i in (4, 5):
        pmf = ls.pmf(np.full(n, i), p)
        front = (p - ls.lights.position[i]) @ -ls.lights.frame[i, 2] > 0
        assert np.all(pmf[front] > 0)
        assert np.any(pmf[~front] == 0)  # the cones do prune


# ----------------------------------------------------------------------------------------------
# Renders: tree against power selection

def _render(scene, tree, monkeypatch):
    monkeypatch.setattr(light_set, "TREE_MIN_LIGHTS", 1 if tree else 10**9)
    session = RenderSession(scene)
    session.run()
    assert session.tracer is not None  # in-process: the switch reached the LightSet
    assert (session.tracer.integrator.tracer.lights.tree is not None) == tree
    return session.film.mean(), session.film.variance_of_mean()


def _agree(a, b):
    """Per-pixel z-tests (Sidak) and a pooled z-test of the image means."""
    (ma, va), (mb, vb) = a, b
    p = z_test_p_values(ma.mean(axis=2), va.mean(axis=2), mb.mean(axis=2), vb.mean(axis=2))
    assert p.min() > sidak_alpha(ALPHA, p.size)
    z = (ma.mean() - mb.mean()) / np.sqrt((va.mean(axis=2).sum() + vb.mean(axis=2).sum()) / ma[..., 0].size**2)
    assert abs(z) < 3.0


@pytest.mark.parametrize("kind,radius", [("point", 0.0), ("point", 0.08), ("triangle", 0.0)])
def test_tree_and_power_selection_agree(kind, radius, monkeypatch):
    """Unbiased either way: delta lights (NEE alone), sphere lights and emissive triangles (MIS
    with the emitter-hit pmf at the previous vertex)."""
    n = 200 if radius > 0 else 1000
    scene = many_lights(n, kind, radius=radius, width=16, height=16, samples=64, threads=1)
    _agree(_render(scene, True, monkeypatch), _render(scene, False, monkeypatch))


def test_tree_has_less_error_than_power_selection(monkeypatch):
    """1000 point lights of powers over three decades spread over a floor: at equal samples
    the tree's relMSE against a reference (the tree at 32x the samples) is under half of power
    selection's (bench/results/many_lights/report.md; per-pixel variance estimates are no
    judge here: power selection rarely picks the near, bright light, so at few samples its
    estimate is far too low)."""
    from ember.engine.metrics import rel_mse
    ref, _ = _render(many_lights(1000, "point", width=16, height=16, samples=1024, seed=99, threads=1), True,
                     monkeypatch)
    scene = many_lights(1000, "point", width=16, height=16, samples=32, threads=1)
    (tree, _), (power, _) = _render(scene, True, monkeypatch), _render(scene, False, monkeypatch)
    assert rel_mse(tree, ref) < 0.5 * rel_mse(power, ref)
