"""Light sampling of textured emitters (engine/lights/emission_maps.py): points drawn where the
emission shines, with the pdf they claim (chi-square), the pdf a ray hitting the emitter reads
the same as the light sample's (MIS), and next-event estimates of the light a checker-textured
emitter sends to a point unbiased against a uniform estimator and less noisy than it."""
import dataclasses

import numpy as np
import pytest
from scipy import stats as st

from ember.engine.lights.emission_maps import FLOOR, EmissionMaps
from ember.engine.textures import LUMINANCE

from stats import ChiSquareTest, Discrete


def _checker(t, b):
    """Radiance at barycentrics b (N,3): a 3 x 3 checker of 10 and 0.1 over (u, v), brighter on
    triangle 1 (of two)."""
    u, v = b[:, 1], b[:, 2]
    on = (np.floor(3 * u) + np.floor(3 * v)) % 2 == 0
    Le = np.where(on, 10.0, 0.1) * np.where(t == 1, 2.0, 1.0)
    return np.repeat(Le[:, None], 3, axis=1)


@pytest.mark.parametrize("budget", [2 * 16 * 16, 2 * 5 * 5])
def test_points_follow_the_table_with_the_pdf_they_claim(budget):
    """The sub-triangle of each point drawn, against the table's pmf (chi-square); the density
    each sample claims is the table's where it fell. Inside a sub-triangle the point is uniform
    (sampling.sample_uniform_triangle, tested on its own)."""
    maps = EmissionMaps(2, _checker, budget=budget)
    s = maps.pmf.shape[1]
    for t in (0, 1):
        def sampler(u, t=t):
            b, density = maps.sample(np.full(len(u), t), u)
            assert np.all(b >= -1e-12) and np.allclose(b.sum(axis=1), 1.0)
            np.testing.assert_allclose(density, maps.pdf_in_triangle(np.full(len(u), t), b), rtol=1e-9)
            return maps.sub_triangle(b)

        ChiSquareTest(Discrete(s), sampler, lambda j, t=t: maps.pmf[t, j], n_samples=200_000, seed=t,
                      name=f"emission map, triangle {t}").run(n_tests=4).check()


def test_bright_texels_get_the_samples_and_dark_ones_keep_a_floor():
    maps = EmissionMaps(2, _checker, budget=2 * 12 * 12)
    assert maps.k == 12
    lum = np.array([10.0, 0.1])
    # A sub-triangle's share is its luminance over the triangle's total, the dark ones raised
    # to FLOOR x the mean.
    p = maps.pmf[0]
    assert np.isclose(p.sum(), 1.0)
    bright, dark = p.max(), p.min()
    mean = (lum[0] + lum[1]) / 2  # half the sub-triangles' centres on each colour, about
    assert bright / dark == pytest.approx(lum[0] / max(lum[1], FLOOR * mean), rel=0.25)
    # The triangles' means (what chooses between them) from the same centres.
    np.testing.assert_allclose(maps.mean[1] / maps.mean[0], 2.0, rtol=1e-12)
    assert maps.mean[0, 0] == pytest.approx(10.0 * 5 / 9 + 0.1 * 4 / 9, rel=0.02)  # 5/9 of the triangle is bright


def test_a_dark_triangle_is_sampled_uniformly():
    maps = EmissionMaps(1, lambda t, b: np.zeros((len(t), 3)), budget=16)
    np.testing.assert_allclose(maps.pmf, 1.0 / maps.pmf.shape[1])


# ---- in a scene: the light set, a path tracer's MIS and the estimate --------------------------

def _emitter_scene():
    bpy = pytest.importorskip("bpy")
    import ember
    from ember.engine.blender.export import export_scene
    ember.register()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=3, location=(0, 0, 2.0))
    lamp = bpy.context.active_object
    mat = bpy.data.materials.new("Lamp")
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = 5.0
    chk = nt.nodes.new("ShaderNodeTexChecker")
    chk.inputs["Scale"].default_value = 3.0
    chk.inputs["Color1"].default_value = (1, 0.9, 0.2, 1)
    chk.inputs["Color2"].default_value = (0.002, 0.005, 0.06, 1)
    nt.links.new(chk.outputs["Color"], em.inputs["Color"])
    nt.links.new(em.outputs[0], out.inputs["Surface"])
    lamp.data.materials.append(mat)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (0, 0, -3)
    sc.collection.objects.link(cam)
    sc.camera = cam
    try:
        scene, _ = export_scene(bpy.context.evaluated_depsgraph_get())
    finally:
        ember.unregister()
    return scene


@pytest.fixture(scope="module")
def lights():
    from ember.engine.accel import Accel
    from ember.engine.lights.light_set import LightSet
    from ember.engine.nodes.material import MaterialPrograms, SurfaceEmission
    scene = _emitter_scene()
    accel = Accel(scene.mesh)
    programs = MaterialPrograms.of(scene.materials)
    ls = LightSet(scene.lights, scene.mesh, scene.materials, scene.world, accel, accel.scene_radius,
                  surface_emission=SurfaceEmission(scene, programs))
    assert ls.maps is not None
    return ls, accel


def test_a_ray_hitting_the_emitter_reads_the_light_samples_pdf(lights):
    ls, accel = lights
    rng = np.random.default_rng(3)
    n = 4000
    p = np.column_stack([rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), np.zeros(n)])
    s = ls.sample(p, rng.random(n), rng.random((n, 2)))
    hit = accel.intersect(p, s.wi)
    assert np.all(hit.prim == s.target_prim)
    cos = np.abs(np.sum(s.wi * hit.ng, axis=1))
    np.testing.assert_allclose(ls.pdf_triangle_hit(hit.prim, p, hit.t, cos, hit.b), s.pdf, rtol=1e-6)


def _estimates(ls, uniform: bool, n: int, seed: int):
    """Next-event estimates (N,) of the luminance irradiance at the origin, facing up."""
    rng = np.random.default_rng(seed)
    p = np.zeros((n, 3))
    s = _uniform_sample(ls, p, rng) if uniform else ls.sample(p, rng.random(n), rng.random((n, 2)))
    cos = np.maximum(s.wi[:, 2], 0.0)
    return np.where(s.valid, (s.Le @ LUMINANCE) * cos / np.where(s.valid, s.pdf, 1.0), 0.0)


def _uniform_sample(ls, p, rng):
    """Light samples with the emitter's triangles sampled uniformly (as before the maps)."""
    varying = ls.tri_varying
    ls.tri_varying = np.zeros_like(varying)
    try:
        s = ls.sample(p, rng.random(len(p)), rng.random((len(p), 2)))
        t = ls.light_of_prim[s.target_prim] - ls.n_analytic
        b = ls.barycentrics(t, s.target)
        Le = ls.triangle_emission(t, b, s.target, -s.wi)
    finally:
        ls.tri_varying = varying
    return dataclasses.replace(s, Le=Le)


def test_the_estimate_is_unbiased_and_less_noisy_than_uniform(lights):
    ls, _ = lights
    n = 200_000
    a = _estimates(ls, False, n, 1)
    b = _estimates(ls, True, n, 2)
    z = (a.mean() - b.mean()) / np.sqrt(a.var() / n + b.var() / n)
    assert abs(z) < st.norm.ppf(1 - 0.005), (a.mean(), b.mean(), z)
    assert a.var() < 0.5 * b.var(), (a.var(), b.var())


def test_photons_leave_where_the_emitter_shines_with_its_power(lights):
    """Photon emission draws origins from the same maps: their mean flux is the emitter's power
    (2 pi x the integral of its radiance over its area, both faces), against a dense uniform
    quadrature of the program, and the photons' flux varies less than it would uniformly."""
    from ember.engine.lights.emission import PhotonEmitter
    ls, accel = lights
    emitter = PhotonEmitter(ls, np.zeros(3), accel.scene_radius)
    rng = np.random.default_rng(7)
    n = 200_000
    photons = emitter.sample(rng.random(n), rng.random((n, 2)), rng.random((n, 2)))
    flux = photons.flux @ LUMINANCE
    t = rng.integers(0, len(ls.tri_prim), n)
    b = rng.dirichlet([1.0, 1.0, 1.0], n)
    y = ls.tri_v0[t] + ls.tri_e1[t] * b[:, 1:2] + ls.tri_e2[t] * b[:, 2:3]
    Le = ls.triangle_emission(t, b, y, ls.tri_ng[t]) @ LUMINANCE
    uniform = 2.0 * np.pi * ls.tri_area.sum() * Le  # the same power, origins uniform by area
    z = (flux.mean() - uniform.mean()) / np.sqrt(flux.var() / n + uniform.var() / n)
    assert abs(z) < st.norm.ppf(1 - 0.005), (flux.mean(), uniform.mean(), z)
    assert flux.var() < 0.5 * uniform.var()
    # The density the emitter claims for its photons' origins is the maps'.
    pdf = emitter.pdf(photons.light[:1000], photons.o[:1000], photons.d[:1000]).pos
    rows = ls.light_of_prim[photons.prim[:1000]] - ls.n_analytic
    expected = ls.maps.pdf_in_triangle(ls.map_row[rows], ls.barycentrics(rows, photons.o[:1000])) / ls.tri_area[rows]
    np.testing.assert_allclose(pdf, expected, rtol=1e-9)
