"""Transparent shadows without Blender: a half-transparent card (Transparent lobe of weight 0.5
beside a diffuse one) between a floor and a large area light. Light sampling alone (its shadow
rays pass the card with transmittance 0.5), BSDF sampling alone (paths pass it by sampling the
transparent lobe) and their MIS combination are three unbiased estimators of one image: they
agree only if a transparent pass keeps the MIS state of the vertex before it (the light's pdf
seen from there, Cycles' mis_ray_pdf and ray origin)."""
import numpy as np

from ember.engine.scene import LIGHT_RECT, LOBE_DIFFUSE, LOBE_TRANSPARENT, MAT_DIFFUSE, MAT_NODES, Lights, Materials, Scene, World
from ember.engine.session import RenderSession

from core_scenes import perspective, quads_mesh, settings


def _scene(strategy):
    floor = [[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]]
    card = [[-0.6, -0.6, 0.5], [0.6, -0.6, 0.5], [0.6, 0.6, 0.5], [-0.6, 0.6, 0.5]]
    mesh = quads_mesh([floor, card], [0, 1])
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(0.8,) * 3),
                           dict(kind=MAT_NODES, lobes=[dict(kind=LOBE_TRANSPARENT, weight=(0.5,) * 3, color=(1.0,) * 3),
                                                       dict(kind=LOBE_DIFFUSE, weight=(0.5,) * 3, color=(0.5,) * 3)])])
    lights = Lights.make([dict(kind=LIGHT_RECT, position=(0, 0, 1.2), size=(0.8, 0.8), Le=(3.0,) * 3,
                               visible=False)])  # emits down, its frame's -z
    camera = perspective((0, -0.01, 3.0), (0, 0, 0), 30)
    return Scene(mesh, mats, lights, World(), camera,
                 settings(width=8, height=8, samples=256, strategy=strategy, max_depth=2, diffuse_bounces=2, threads=1))


def _render(strategy):
    session = RenderSession(_scene(strategy))
    session.run()
    mean, var = session.film.mean(), session.film.variance_of_mean()
    return mean.mean(), float(np.sqrt(var.mean(axis=2).sum()) / var[..., 0].size)


def test_strategies_agree_through_a_transparent_card():
    m_mis, se_mis = _render("mis")
    for strategy in ("light", "bsdf"):
        m, se = _render(strategy)
        assert abs(m - m_mis) < 4 * np.hypot(se, se_mis), (strategy, m / m_mis)
    assert se_mis < 0.005 * m_mis  # the comparison resolves 2 % differences
