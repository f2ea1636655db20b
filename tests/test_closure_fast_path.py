"""The Lambert fast path gives exactly what the general lobe-table closure gives."""
import numpy as np

from ember.engine.bsdf.closure import Closure
from ember.engine.bsdf.fast_path import LambertClosure, make_closure, plain_lambert_albedo
from ember.engine.scene import MAT_DIFFUSE, MAT_EMISSION_ONLY, Materials

from core_scenes import furnace_box


def _points(n, rng):
    ns = rng.normal(size=(n, 3))
    ns /= np.linalg.norm(ns, axis=1, keepdims=True)
    ng = ns + 0.2 * rng.normal(size=(n, 3))
    ng /= np.linalg.norm(ng, axis=1, keepdims=True)
    ng *= np.sign(np.einsum("ij,ij->i", ng, ns))[:, None]
    wo = ng + rng.normal(size=(n, 3))
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    flip = np.einsum("ij,ij->i", wo, ng) < 0
    wo[flip] *= -1
    return ns, ng, wo


def test_lambert_fast_path_equals_general_closure():
    rng = np.random.default_rng(4)
    scene = furnace_box()
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(0.2, 0.5, 0.9)),
                           dict(kind=MAT_DIFFUSE, base_color=(0.7, 0.7, 0.1))])
    scene = scene.replace(materials=mats)
    n = 5000
    mat = rng.integers(0, 2, n)
    ns, ng, wo = _points(n, rng)
    prim, bary = np.zeros(n, np.int64), np.full((n, 3), 1 / 3)
    fast = make_closure(scene, plain_lambert_albedo(mats), mat, ns, ng, wo, prim, bary)
    slow = Closure(scene, mat, ns, ng, wo, prim, bary)
    assert isinstance(fast, LambertClosure)
    u, u_lobe = rng.random((n, 2)), rng.random(n)
    a, b = fast.sample(u, u_lobe), slow.sample(u, u_lobe)
    assert np.array_equal(a.valid, b.valid)
    v = a.valid
    assert np.allclose(a.wi[v], b.wi[v], rtol=0, atol=1e-12)
    assert np.allclose(a.weight[v], b.weight[v], rtol=1e-12) and np.allclose(a.pdf[v], b.pdf[v], rtol=1e-12)
    assert np.allclose(fast.reflectance, slow.reflectance) and np.array_equal(fast.has_smooth, slow.has_smooth)
    wi = rng.normal(size=(n, 3))
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    rows = np.arange(n)
    (f1, p1), (f2, p2) = fast.eval(wi, rows), slow.eval(wi, rows)
    assert np.allclose(f1, f2, rtol=1e-12, atol=0) and np.allclose(p1, p2, rtol=1e-12, atol=0)


def test_textured_or_layered_materials_take_the_general_path():
    image = dict(texels=np.full((2, 2, 4), 0.5, np.float32), name="n")
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(0.5, 0.5, 0.5)),
                           dict(kind=MAT_DIFFUSE, base_color=(0.5, 0.5, 0.5), normal_tex=0),
                           dict(kind=MAT_EMISSION_ONLY, emission=(1, 1, 1))],
                          slots=[dict(image=0)], images=[image])
    albedo = plain_lambert_albedo(mats)
    assert np.array_equal(albedo[0], [0.5, 0.5, 0.5]) and np.isnan(albedo[1]).all()
    assert np.array_equal(albedo[2], [0, 0, 0])  # a pure emitter is black


def test_plain_points_of_a_mixed_batch_get_the_fast_paths_numbers():
    """A batch where some points are glossy: the plain Lambertian points still get exactly
    LambertClosure's numbers (the general closure's differ by rounding), so a path's value
    does not depend on what the other paths of its batch hit (batch size, regeneration)."""
    from ember.engine.scene import LOBE_MICROFACET

    rng = np.random.default_rng(5)
    scene = furnace_box()
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(0.7, 0.7, 0.7)),
                           dict(lobes=[dict(kind=LOBE_MICROFACET, roughness=0.3, color=(0.9, 0.9, 0.9))])])
    scene = scene.replace(materials=mats)
    n = 4000
    mat = rng.integers(0, 2, n)
    ns, ng, wo = _points(n, rng)
    prim, bary = np.zeros(n, np.int64), np.full((n, 3), 1 / 3)
    albedo = plain_lambert_albedo(mats)
    mixed = make_closure(scene, albedo, mat, ns, ng, wo, prim, bary)
    p = np.flatnonzero(mat == 0)
    alone = make_closure(scene, albedo, mat[p], ns[p], ng[p], wo[p], prim[p], bary[p])
    assert isinstance(alone, LambertClosure) and not isinstance(mixed, LambertClosure)
    u, u_lobe = rng.random((n, 2)), rng.random(n)
    a, b = mixed.sample(u, u_lobe), alone.sample(u[p], u_lobe[p])
    for name in ("wi", "weight", "pdf", "valid", "delta", "label"):
        assert np.array_equal(getattr(a, name)[p], getattr(b, name)), name
    assert np.array_equal(mixed.reflectance[p], alone.reflectance)
    assert np.array_equal(mixed.has_smooth[p], alone.has_smooth)
    wi = rng.normal(size=(n, 3))
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    (f1, p1), (f2, p2) = mixed.eval(wi, np.arange(n)), alone.eval(wi[p], np.arange(len(p)))
    assert np.array_equal(f1[p], f2) and np.array_equal(p1[p], p2)
    assert np.array_equal(mixed.eval_by_class(wi, np.arange(n))[p], alone.eval_by_class(wi[p], np.arange(len(p))))
    # the glossy points are the general closure's
    g = np.flatnonzero(mat == 1)
    general = Closure(scene, mat, ns, ng, wo, prim, bary)
    assert np.array_equal(a.weight[g], general.sample(u, u_lobe).weight[g])
