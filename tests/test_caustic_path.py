"""Path tracing + caustic map (engine/integrators/photon/caustic_path.py): it splits the light
at the first diffuse point between the caustic map (L S+ D) and the path tracer without
overlap or gap, so where the caustic map is nearly exact (a smooth caustic under a flat glass
slab, a small radius) it agrees with the unbiased path tracer (counting the slab's light
twice or not at all is far outside the tolerance); without specular surfaces it is the path
tracer."""
import numpy as np

from core_scenes import box_quads, perspective, quads_mesh, settings
from ember.engine.scene import LIGHT_RECT, LOBE_DIELECTRIC, MAT_DIFFUSE, Lights, Materials, Scene, World
from ember.engine.session import RenderSession

REGION = (slice(12, 20), slice(8, 16))  # floor under the slab's middle


def slab_under_a_large_light(glass=True):
    """A diffuse floor under a 2 cm glass slab (1.2 m square) and a 4 m square light 2 m up,
    seen from the side between them: under the slab's middle half the light comes through
    the glass, a smooth caustic."""
    floor = [[[-4, -4, 0], [4, -4, 0], [4, 4, 0], [-4, 4, 0]]]
    slab = box_quads((-0.6, -0.6, 0.5), (0.6, 0.6, 0.52))
    mesh = quads_mesh(np.concatenate([floor, slab]), [0] + [1] * 6)
    lobes = [dict(kind=LOBE_DIELECTRIC, roughness=0.0, ior=1.5)] if glass else [dict(color=(0.5,) * 3)]
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(0.7,) * 3), dict(name="slab", lobes=lobes)])
    lights = Lights.make([dict(kind=LIGHT_RECT, position=(0, 0, 2.0), frame=np.eye(3), size=(4.0, 4.0),
                               Le=(1.0,) * 3)])
    return Scene(mesh, mats, lights, World(), perspective((0, -2.0, 0.25), (0, 0, 0), 20), settings(width=24, height=24))


def _render(scene, **kw):
    s = scene.settings.replace(threads=1, **kw)
    session = RenderSession(scene.replace(settings=s))
    session.run()
    return session.film


def _region(film):
    """Mean of the region and the variance of that mean (pixels' passes as independent samples)."""
    m = film.mean()[REGION].mean(axis=-1)
    v = film.variance_of_mean()[REGION].mean(axis=-1)
    return m.mean(), v.sum() / m.size**2


def test_glass_slab_caustic_agrees_with_the_path_tracer():
    scene = slab_under_a_large_light()
    ref, ref_var = _region(_render(scene, integrator="path", samples=256, seed=1))
    # The caustic map's noise is fixed within a render: its variance from independent renders.
    runs = [_region(_render(scene, integrator="path_caustic", samples=8, seed=10 + k, caustic_photons=100000,
                            caustic_radius=0.02))[0] for k in range(6)]
    mean, var = np.mean(runs), np.var(runs, ddof=1) / len(runs)
    z = (mean - ref) / np.sqrt(var + ref_var)
    assert abs(z) < 3.3, (mean, ref, z)
    assert abs(mean / ref - 1) < 0.05  # and the test has the precision to see a few per cent


def test_without_specular_surfaces_it_is_the_path_tracer():
    scene = slab_under_a_large_light(glass=False)
    a, va = _region(_render(scene, integrator="path", samples=64, seed=1))
    b, vb = _region(_render(scene, integrator="path_caustic", samples=64, seed=2))
    assert abs(a - b) < 3.3 * np.sqrt(va + vb)
