"""Point/spot lights of radius r, as a sphere and with Blender's Soft Falloff (a disk facing the
shading point): light sampling and ray hits describe the same emitter, and match the exact
irradiance where it is known."""
import numpy as np
import pytest
from scipy import stats as st

from ember.engine import sampling
from ember.engine.lights import shapes
from ember.engine.scene import LIGHT_POINT, Lights
from ember.engine.vec import dot

N = 400_000
R, LE = 0.9, 2.0


def _light(soft):
    return Lights.make([dict(kind=LIGHT_POINT, position=(0, 0, 0), radius=R, Le=(LE,) * 3, soft=soft)])


def _irradiance_by_light_sampling(lights, p, n, rng):
    p = np.broadcast_to(p, (N, 3)).copy()
    s = shapes.sample_analytic(LIGHT_POINT, lights, np.zeros(N, int), p, rng.random((N, 2)))
    f = np.divide(s.Le[:, 0] * np.maximum(s.wi @ n, 0.0), s.pdf, out=np.zeros(N), where=s.pdf > 0)
    return f.mean(), f.std() / np.sqrt(N)


def _irradiance_by_cosine_rays(lights, p, n, rng):
    """E = pi E_cos[L]: directions from the cosine-weighted hemisphere around n, lights hit by rays."""
    t, b = sampling.frame_from_z(n[None])
    d = sampling.to_world(sampling.sample_cosine_hemisphere(rng.random((N, 2))), t, b, n[None])
    h = shapes.hit_analytic(LIGHT_POINT, lights, 0, np.broadcast_to(p, (N, 3)), d, np.full(N, np.inf))
    f = np.pi * np.where(h.hit, h.gain * lights.Le[0, 0], 0.0)
    return f.mean(), f.std() / np.sqrt(N), h.hit, h.pdf, d


def _exact_on_axis(soft, dist):
    """Receiver facing the light's centre: sphere pi L (r/d)^2; facing disk pi L r^2/(d^2 + r^2)."""
    return np.pi * LE * R * R / (dist * dist + (R * R if soft else 0.0))


@pytest.mark.parametrize("soft", [False, True])
@pytest.mark.parametrize("where", ["on_axis", "oblique"])
def test_light_sampling_and_ray_hits_agree(soft, where):
    rng = np.random.default_rng(7 + soft)
    lights = _light(soft)
    if where == "on_axis":
        p, n = np.array([0.0, 0.0, -1.2]), np.array([0.0, 0.0, 1.0])
    else:  # tilted receiver, partly below its horizon
        p = np.array([1.1, 0.3, -0.4])
        n = np.array([-0.2, 0.9, 0.4]) / np.linalg.norm([-0.2, 0.9, 0.4])
    e_light, se_light = _irradiance_by_light_sampling(lights, p, n, rng)
    e_rays, se_rays, _, _, _ = _irradiance_by_cosine_rays(lights, p, n, rng)
    z = (e_light - e_rays) / np.hypot(se_light, se_rays)
    assert abs(z) < st.norm.ppf(1 - 0.001 / 2), (e_light, e_rays)
    if where == "on_axis":
        exact = _exact_on_axis(soft, 1.2)
        assert abs(e_light - exact) < st.norm.ppf(1 - 0.001 / 2) * se_light, (e_light, exact)


def test_soft_falloff_is_darker_than_the_sphere_close_to_a_large_light():
    """The two models differ by what the test above can see (here 0.36 vs 0.5625 pi L)."""
    assert _exact_on_axis(True, 1.2) < 0.7 * _exact_on_axis(False, 1.2)


@pytest.mark.parametrize("soft", [False, True])
def test_hit_pdf_is_the_density_of_light_sampling(soft):
    """For directions that hit the light, pdf_dir integrates to 1 over them: the cosine-hemisphere
    estimate of the integral of pdf_dir over the hit set (all hits lie in the upper hemisphere of
    a receiver facing the light) is 1."""
    rng = np.random.default_rng(3)
    p, n = np.array([0.0, 0.0, -1.5]), np.array([0.0, 0.0, 1.0])
    _, _, hit, pdf_dir, d = _irradiance_by_cosine_rays(_light(soft), p, n, rng)
    cos = d @ n
    g = np.where(hit, pdf_dir / np.maximum(cos / np.pi, 1e-300), 0.0)  # pdf_dir / pdf_cosine
    z = (g.mean() - 1.0) / (g.std() / np.sqrt(N))
    assert abs(z) < st.norm.ppf(1 - 0.001 / 2), g.mean()


def test_soft_light_sampled_points_lie_on_the_disk_facing_the_point():
    rng = np.random.default_rng(5)
    lights = _light(True)
    p = np.array([[0.3, -2.0, 0.5]] * 1000)
    s = shapes.sample_analytic(LIGHT_POINT, lights, np.zeros(1000, int), p, rng.random((1000, 2)))
    pdf, target = s.pdf, s.target
    n_disk = p[0] / np.linalg.norm(p[0])
    assert np.abs(target @ n_disk).max() < 1e-12  # in the plane through the centre facing p
    assert np.linalg.norm(target, axis=1).max() <= R * (1 + 1e-12)
    assert np.all(pdf > 0) and np.all(np.isfinite(pdf))
    assert np.all(dot(target - p, target - p) > 0)
