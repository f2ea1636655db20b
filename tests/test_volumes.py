"""Homogeneous media in the path tracer (engine/volumes.py, engine/integrators/media.py).

- The coefficients of Volume Absorption, Volume Scatter and Principled Volume as Cycles'
  kernel computes them (svm/closure.h), written out here from its formulas.
- A slab of absorbing, emitting medium in front of a uniform background: exactly
  W exp(-sigma_t h) + E (1 - exp(-sigma_t h)) / sigma_t (the attenuation-only path).
- A furnace: a sphere of chromatic medium (scattering, absorption, emission E = sigma_a W)
  in a uniform world W, all scattering orders: the radiance is W everywhere (the RTE's
  equilibrium), which checks distance sampling with the channel MIS, the collision
  estimator of emission, light and phase sampling with MIS and shadow transmittance.
- Agreement with Cycles (region t-test) on a cube of Volume Scatter lit by a sun over a
  floor, a sphere of Volume Absorption in front of a bright background, the same under glass,
  the cube as an emitting Principled Volume with four volume bounces, and the cube lit by
  an area light inside it (light and phase samples combined by MIS across its boundary),
  seen by the camera through the fog or hidden from camera rays.
"""
import numpy as np
import pytest
from scipy import stats as st

from ember.engine import volumes
from ember.engine.scene import LOBE_TRANSPARENT, MAT_NODES, Lights, Materials, Mesh, Scene, World
from ember.engine.session import RenderSession

from core_scenes import box_quads, perspective, quads_mesh, settings, uv_sphere
from stats import sidak_alpha

W = np.array([0.8, 1.0, 1.2])  # the world's radiance


def _volume_row(coef: volumes.Coefficients) -> dict:
    return dict(kind=MAT_NODES, base_color=(0, 0, 0), emission=(0, 0, 0), name="medium",
                lobes=[dict(kind=LOBE_TRANSPARENT, weight=(1, 1, 1), color=(1, 1, 1))], volume=coef.as_row())


def _render(scene):
    session = RenderSession(scene)
    session.run()
    return session.film.mean(), session.film.variance_of_mean()


# -- coefficients ---------------------------------------------------------------------------
def test_principled_volume_coefficients_as_cycles():
    color, density, absorption_color = np.array([0.7, 0.4, 0.1]), 2.5, np.array([0.09, 0.25, 0.64])
    m = volumes.principled_volume(color, density, 0.3, absorption_color, 4.0, (1.0, 0.5, 0.25))
    # svm_node_principled_volume: the absorption colour enters through its square root.
    assert np.allclose(m.sigma_s, color * density)
    assert np.allclose(m.sigma_a, (1 - color) * (1 - np.sqrt(absorption_color)) * density)
    assert np.allclose(m.sigma_a, [0.3 * 0.7, 0.6 * 0.5, 0.9 * 0.2] * np.array(density))
    assert np.allclose(m.emission, [4.0, 2.0, 1.0]) and m.g == 0.3
    dark = volumes.principled_volume(color, -1.0, 0.0, absorption_color, 0.0, (1, 1, 1))
    assert not dark.sigma_s.any() and not dark.sigma_a.any() and not dark.emission.any()


def test_absorption_and_scatter_coefficients_as_cycles():
    a = volumes.volume_absorption((0.2, 0.5, 0.8), 1.5)
    assert np.allclose(a.sigma_a, [1.2, 0.75, 0.3]) and not a.sigma_s.any()
    s = volumes.volume_scatter((0.9, 0.8, 0.6), 1.2, -0.4)
    assert np.allclose(s.sigma_s, [1.08, 0.96, 0.72]) and not s.sigma_a.any() and s.g == -0.4
    both = a + s
    assert np.allclose(both.sigma_s + both.sigma_a, [2.28, 1.71, 1.02]) and both.g == pytest.approx(-0.4)


# -- analytic scenes -------------------------------------------------------------------------
def test_absorbing_emitting_slab_is_beer_lambert():
    """A 0.5 m slab seen along its normal through a 0.5 degree field of view (cos >= 0.99999)."""
    coef = volumes.Coefficients(np.zeros(3), np.array([0.3, 1.2, 3.0]), np.array([0.5, 0.2, 0.1]))
    h = 0.5
    mesh = quads_mesh(box_quads((-5, -5, 0), (5, 5, h)), [0] * 6)
    scene = Scene(mesh, Materials.make([_volume_row(coef)]), Lights.make([]), World(color=W),
                  perspective((0, 0, 3), (0, 0, 0), 0.5), settings(width=4, height=4, samples=4))
    mean, _ = _render(scene)
    sigma = coef.sigma_a
    T = np.exp(-sigma * h)
    expected = W * T + coef.emission * (1 - T) / sigma
    assert np.allclose(mean.reshape(-1, 3), expected, rtol=1e-4), (mean.reshape(-1, 3)[0], expected)


@pytest.mark.parametrize("nee", [True, False])
def test_furnace_medium_in_a_uniform_world(nee):
    """Scattering, absorbing and emitting (E = sigma_a W) medium in a world W: L = W."""
    sigma_s, sigma_a = np.array([1.5, 0.8, 2.4]), np.array([0.4, 0.9, 0.2])
    coef = volumes.Coefficients(sigma_s, sigma_a, sigma_a * W, 0.5)
    v, t, n = uv_sphere((0, 0, 0), 1.0, 16, 32)
    mesh = Mesh(v, t, n, np.zeros(len(t), np.int32))
    scene = Scene(mesh, Materials.make([_volume_row(coef)]), Lights.make([]), World(color=W),
                  perspective((0, -3.5, 0), (0, 0, 0), 35),
                  settings(width=8, height=8, samples=64, max_depth=256, volume_bounces=256,
                           strategy="mis" if nee else "bsdf"))
    mean, var = _render(scene)
    m, se = mean.mean(axis=(0, 1)), np.sqrt(var.sum(axis=(0, 1))) / (mean.shape[0] * mean.shape[1])
    z = (m - W) / np.maximum(se, 1e-12)
    assert np.all(se > 0) and np.all(se < 0.01 * W)  # the medium is in the picture, and the test has power
    assert np.all(np.abs(z) < st.norm.ppf(1 - sidak_alpha(0.01, 6) / 2)), (m, W, z)


def test_single_scattering_is_darker_than_all_orders():
    """volume_bounces 1 (Cycles' default) leaves out light scattered more than once."""
    coef = volumes.volume_scatter((1, 1, 1), 2.0, 0.0)
    v, t, n = uv_sphere((0, 0, 0), 1.0, 16, 32)
    mesh = Mesh(v, t, n, np.zeros(len(t), np.int32))

    def image(bounces):
        scene = Scene(mesh, Materials.make([_volume_row(coef)]), Lights.make([]), World(color=W),
                      perspective((0, -3.5, 0), (0, 0, 0), 35),
                      settings(width=8, height=8, samples=16, max_depth=64, volume_bounces=bounces))
        return _render(scene)[0].mean()

    assert image(1) < 0.8 * image(64)


# -- Blender: export and Cycles ---------------------------------------------------------------
SEEDS = 8
SAMPLES = 32
CYCLES_SCENES = ("scatter_cube", "absorbing_sphere", "glass_of_ink", "principled_fog", "area_light_in_fog",
                 "hidden_area_light_in_fog")


@pytest.fixture(scope="module")
def addon():
    pytest.importorskip("bpy")
    import ember
    ember.register()
    yield
    ember.unregister()


@pytest.mark.blender
def test_volume_material_export(addon):
    import bpy
    from ember.engine.blender.export_material import material_row
    import volume_scenes
    volume_scenes.scatter_cube(8)
    warnings = []
    row = material_row(bpy.data.materials["fog"], None, warnings.append)
    assert row["lobes"] == [dict(kind=LOBE_TRANSPARENT, weight=(1.0, 1.0, 1.0), color=(1.0, 1.0, 1.0))]
    assert np.allclose(row["volume"]["sigma_s"], np.array([0.9, 0.8, 0.6]) * 1.2)
    assert np.allclose(row["volume"]["sigma_a"], 0) and row["volume"]["g"] == pytest.approx(0.3)
    assert warnings == []
    # A linked density is taken at its own value, with a note.
    nt = bpy.data.materials["fog"].node_tree
    noise = nt.nodes.new("ShaderNodeTexNoise")
    nt.links.new(noise.outputs["Fac"], nt.nodes["Volume Scatter"].inputs["Density"])
    row = material_row(bpy.data.materials["fog"], None, warnings.append)
    assert np.allclose(row["volume"]["sigma_s"], np.array([0.9, 0.8, 0.6]) * 1.2)
    assert len(warnings) == 1 and "Density is linked" in warnings[0]


@pytest.mark.blender
@pytest.mark.parametrize("name", CYCLES_SCENES)
def test_media_match_cycles(addon, name, tmp_path):
    """Region means (image and quadrants) of Ember and Cycles at the same volume bounces
    agree within the noise of independent seeds."""
    from cycles_renders import agree, cycles_image, ember_image
    import volume_scenes
    sc = volume_scenes.SCENES[name](24)
    ember_images = [ember_image(sc, "PATH", SAMPLES, k) for k in range(SEEDS)]
    cycles_images = [cycles_image(sc, SAMPLES, k, tmp_path / f"c{k}.exr") for k in range(SEEDS)]
    agree(ember_images, cycles_images, n_tests=len(CYCLES_SCENES), tol=0.0)


def _fog_sphere(**kw):
    v, t, n = uv_sphere((0, 0, 0), 1.0, 12, 24)
    mesh = Mesh(v, t, n, np.zeros(len(t), np.int32))
    coef = volumes.volume_scatter((0.8, 0.8, 0.8), 1.0, 0.0)
    return Scene(mesh, Materials.make([_volume_row(coef)]), Lights.make([]), World(color=W),
                 perspective((0, -3.5, 0), (0, 0, 0), 35), settings(width=8, height=8, samples=2, **kw))


@pytest.mark.parametrize("kw, says", [(dict(integrator="photon", photons=1000, caustic_photons=1000), "renders without volumes"),
                                      (dict(passes=("Combined", "Diffuse Direct")), "left out of renders with light")])
def test_where_volumes_are_left_out_a_warning_says_so(kw, says):
    session = RenderSession(_fog_sphere(**kw))
    session.run()
    assert any(says in w for w in session.warnings), session.warnings
    assert np.all(np.isfinite(session.film.mean()))


def test_auto_chooses_the_path_tracer_for_volumes():
    session = RenderSession(_fog_sphere(integrator="auto"))
    assert session.scene.settings.integrator == "path"
    assert not any("volume" in w.lower() for w in session.warnings)


def test_camera_inside_a_medium():
    """The slab's camera moved inside it, at half its depth: the attenuation from its near
    clip on (camera rays start there, as Cycles')."""
    coef = volumes.Coefficients(np.zeros(3), np.array([0.3, 1.2, 3.0]), np.array([0.5, 0.2, 0.1]))
    h = 0.5
    mesh = quads_mesh(box_quads((-5, -5, 0), (5, 5, h)), [0] * 6)
    scene = Scene(mesh, Materials.make([_volume_row(coef)]), Lights.make([]), World(color=W),
                  perspective((0, 0, h / 2), (0, 0, -1), 0.5), settings(width=4, height=4, samples=4))
    mean, _ = _render(scene)
    T = np.exp(-coef.sigma_a * (h / 2 - scene.camera.clip_start))
    expected = W * T + coef.emission * (1 - T) / coef.sigma_a
    assert np.allclose(mean.reshape(-1, 3), expected, rtol=1e-4), (mean.reshape(-1, 3)[0], expected)


def test_an_emitting_medium_is_a_light():
    """A glowing medium alone lights the scene: no 'the image will be black' warning."""
    coef = volumes.Coefficients(np.zeros(3), np.full(3, 0.5), np.full(3, 2.0))
    v, t, n = uv_sphere((0, 0, 0), 1.0, 12, 24)
    scene = Scene(Mesh(v, t, n, np.zeros(len(t), np.int32)), Materials.make([_volume_row(coef)]), Lights.make([]),
                  World(), perspective((0, -3.5, 0), (0, 0, 0), 35), settings(width=8, height=8, samples=2))
    session = RenderSession(scene)
    session.run()
    assert not any("black" in w for w in session.warnings), session.warnings
    assert session.film.mean().max() > 0
