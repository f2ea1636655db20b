"""The lobe table (engine/bsdf/lobes/): every lobe answers the whole interface; each lobe's
samples, pdf and eval agree (chi-square of its own samples against its own pdf, in its local
frame: glass seen from inside and the Fresnel models included); delta lobes' weights and
pmfs; the facts the photon tracer and the scene analysis ask of lobes; and the closure keeps
no switch on lobe kinds (the table does the dispatch). The formulas underneath are tested in
test_bsdf_models.py, the mixture in test_materials.py and test_sampler_directions.py.
Seeded; the chi-square cases share a family-wise level of 0.01 (Sidak)."""
import ast
import inspect
import pathlib

import numpy as np
import pytest

from ember.engine.bsdf import fresnel, lobes
from ember.engine.bsdf.lobes import base, inputs
from ember.engine.scene import (DIST_ASHIKHMIN_SHIRLEY, DIST_BECKMANN, DIST_MULTI_GGX, FRESNEL_DIELECTRIC,
                                FRESNEL_F82, FRESNEL_NONE, LOBE_DIELECTRIC, LOBE_DIFFUSE, LOBE_KINDS, LOBE_MICROFACET, LOBE_OREN_NAYAR, LOBE_PHONG,
                                LOBE_TOON, LOBE_TRANSLUCENT, LOBE_TRANSPARENT, MAT_NODES, RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMIT,
                                Materials)

from stats import ChiSquareTest, Sphere, integrate

ROOT = pathlib.Path(__file__).resolve().parents[1]
N_CHI2 = 100_000

# name: (lobe as Materials.make takes it, wo's polar angle in degrees, seen from inside the object)
CASES = {
    "diffuse": (dict(kind=LOBE_DIFFUSE, color=(0.6, 0.5, 0.4)), 40, False),
    "phong_n30": (dict(kind=LOBE_PHONG, color=(0.3, 0.2, 0.1), tint=(0.4, 0.5, 0.6), exponent=30.0), 50, False),
    "ggx_plain_r0.4": (dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_NONE, color=(0.8, 0.7, 0.6), roughness=0.4), 30,
                       False),
    "ggx_f82_r0.3": (dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_F82, color=(0.9, 0.6, 0.3), tint=(0.8, 0.9, 1.0),
                          roughness=0.3), 70, False),
    "ggx_specular_r0.6": (dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_DIELECTRIC, ior=1.45, tint=(1.0, 0.9, 0.8),
                               roughness=0.6), 60, False),
    "mirror": (dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_F82, color=(0.9, 0.6, 0.3), roughness=0.0), 45, False),
    "glass_rough_outside": (dict(kind=LOBE_DIELECTRIC, color=(0.9, 0.8, 0.7), tint=(1.0, 1.0, 0.9), roughness=0.5,
                                 ior=1.5), 35, False),
    "glass_rough_inside": (dict(kind=LOBE_DIELECTRIC, color=(0.9, 0.8, 0.7), tint=(1.0, 1.0, 0.9), roughness=0.5,
                                ior=1.5), 25, True),
    "glass_smooth_outside": (dict(kind=LOBE_DIELECTRIC, color=(0.9, 0.8, 0.7), tint=(1.0, 1.0, 0.9), roughness=0.0,
                                  ior=1.5), 35, False),
    "glass_smooth_inside": (dict(kind=LOBE_DIELECTRIC, color=(0.9, 0.8, 0.7), tint=(1.0, 1.0, 0.9), roughness=0.0,
                                 ior=1.5), 55, True),
    "transparent": (dict(kind=LOBE_TRANSPARENT, color=(0.5, 0.6, 0.7)), 20, False),
    "multi_ggx_f82_r0.7": (dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_F82, color=(0.9, 0.6, 0.3), tint=(0.8, 0.9, 1.0),
                                roughness=0.7, distribution=DIST_MULTI_GGX), 50, False),
    "multi_ggx_specular_r0.5": (dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_DIELECTRIC, ior=1.45, tint=(1.0, 0.9, 0.8),
                                     roughness=0.5, distribution=DIST_MULTI_GGX), 40, False),
    "multi_glass_rough_inside": (dict(kind=LOBE_DIELECTRIC, color=(0.9, 0.8, 0.7), tint=(1.0, 1.0, 0.9), roughness=0.6,
                                      ior=1.5, distribution=DIST_MULTI_GGX), 30, True),
    "oren_nayar_r0.8": (dict(kind=LOBE_OREN_NAYAR, color=(0.6, 0.5, 0.4), roughness=0.8), 60, False),
    "beckmann_plain_r0.5": (dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_NONE, color=(0.8, 0.7, 0.6), roughness=0.5,
                                 distribution=DIST_BECKMANN), 40, False),
    "beckmann_f82_r0.35": (dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_F82, color=(0.9, 0.6, 0.3), roughness=0.35,
                               distribution=DIST_BECKMANN), 70, False),
    "ashikhmin_shirley_r0.45": (dict(kind=LOBE_MICROFACET, fresnel=FRESNEL_NONE, color=(0.8, 0.7, 0.6), roughness=0.45,
                                     distribution=DIST_ASHIKHMIN_SHIRLEY), 50, False),
    "translucent": (dict(kind=LOBE_TRANSLUCENT, color=(0.6, 0.7, 0.4)), 50, False),
    "toon_diffuse_s0.4": (dict(kind=LOBE_TOON, color=(0.7, 0.6, 0.5), roughness=0.4, exponent=0.190334), 30, False),  # edge at cos 0.6: a cell edge
    # (the Glossy Toon's cone is about the mirror direction: tests/test_toon_translucent.py)
    "toon_diffuse_wide": (dict(kind=LOBE_TOON, color=(0.7, 0.6, 0.5), roughness=0.8, exponent=0.5), 70, False),
}
DELTA = {"mirror", "glass_smooth_outside", "glass_smooth_inside", "transparent"}
SMOOTH = [name for name in CASES if name not in DELTA]


def _lobe_and_params(name, k):
    """(lobe, its parameters at k rows of one material lobe, wo (k,3), material table)."""
    spec, theta, inside = CASES[name]
    m = Materials.make([dict(kind=MAT_NODES, lobes=[spec])])
    lobe = lobes.LOBES[spec["kind"]]
    p = lobe.parameters(m, np.zeros(k, np.int64), np.arange(k), inputs.Sources(None), np.full(k, inside))
    t = np.radians(theta)
    wo = np.tile([np.sin(t) * np.cos(1.0), np.sin(t) * np.sin(1.0), np.cos(t)], (k, 1))  # azimuth 1 rad
    return lobe, p, wo, m


# ----------------------------------------------------------------------------------------------
# The table

def _names(path):
    tree = ast.parse(path.read_text(), filename=str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Name):
            yield node.id
        elif isinstance(node, ast.Attribute):
            yield node.attr
        elif isinstance(node, ast.alias):
            yield node.asname or node.name


@pytest.mark.parametrize("path", ["engine/bsdf/closure.py", "engine/integrators/photon/tracing.py",
                                  "engine/choice/analysis.py"])
def test_no_switch_on_lobe_kinds_outside_the_lobes(path):
    """The closure, the photon tracer and the scene analysis name no LOBE_* or FRESNEL_* kind:
    what differs between lobes is asked of the lobe table."""
    named = sorted({n for n in _names(ROOT / path) if n.startswith(("LOBE_", "FRESNEL_"))})
    assert named == [], f"{path} switches on {named}"


def test_closure_reaches_no_lobe_formula():
    """The closure imports the lobe table, not the lobes' formula modules."""
    tree = ast.parse((ROOT / "engine/bsdf/closure.py").read_text())
    imported = {a.name for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and node.level
                for a in node.names} | {node.module for node in ast.walk(tree)
                                        if isinstance(node, ast.ImportFrom) and node.level and node.module}
    assert not imported & {"diffuse", "phong", "microfacet", "dielectric", "fresnel", "layering"}, imported


def test_the_table_is_indexed_by_kind_and_every_lobe_is_complete():
    assert len(lobes.LOBES) == LOBE_KINDS
    for kind, lobe in enumerate(lobes.LOBES):
        assert isinstance(lobe, base.SurfaceLobe) and lobe.kind == kind
        assert not inspect.isabstract(type(lobe)), type(lobe).__abstractmethods__
        assert lobe.reflection_class in (0, 1, 2) and lobe.transmission_class in (0, 1, 2)
        assert lobes.RAYS[kind] == lobe.rays and lobes.STRAIGHT[kind] == lobe.straight
        assert lobes.REFLECTION_CLASS[kind] == lobe.reflection_class
        assert lobes.TRANSMISSION_CLASS[kind] == lobe.transmission_class
        assert lobes.NEEDS_SIDE[kind] == lobe.needs_side
    for phase in lobes.PHASE_FUNCTIONS:
        assert isinstance(phase, base.Lobe) and not inspect.isabstract(type(phase))
    # Cycles' light visibility and render passes: glass is glossy and transmission.
    assert lobes.RAYS[LOBE_DIELECTRIC] == RAY_GLOSSY | RAY_TRANSMIT
    assert lobes.RAYS[LOBE_PHONG] == RAY_DIFFUSE | RAY_GLOSSY and lobes.RAYS[LOBE_TRANSPARENT] == 0
    assert (lobes.LOBES[LOBE_DIELECTRIC].reflection_class, lobes.LOBES[LOBE_DIELECTRIC].transmission_class) == (1, 2)


@pytest.mark.parametrize("name", list(CASES))
def test_every_lobe_answers_the_whole_interface(name):
    k = 64
    lobe, p, wo, m = _lobe_and_params(name, k)
    rng = np.random.default_rng(7)
    assert len(p) == k and p.color.shape == (k, 3) and p.delta.dtype == bool
    np.testing.assert_array_equal(lobe.is_delta(p), p.delta)
    assert p.delta.all() == (name in DELTA)
    albedo = lobe.albedo(p, wo)
    assert albedo.shape == (k, 3) and np.all((albedo >= 0) & (albedo <= 1))
    s = lobe.sample(p, wo, rng.random((k, 2)), rng.random(k))
    assert s.wi.shape == (k, 3) and s.pdf.shape == (k,)
    np.testing.assert_array_equal(np.broadcast_to(s.delta, (k,)), p.delta)
    np.testing.assert_allclose(np.linalg.norm(s.wi, axis=1), 1.0, rtol=1e-12)
    assert np.all(np.broadcast_to(s.label, (k,)) >= 0) and np.all(s.pdf >= 0)
    assert (s.weight is not None) == np.any(s.delta)
    if s.eta2 is not None:
        assert s.eta2.shape == (k,)
    if not p.delta.any() or name == "transparent":  # eval and pdf: rows that are not a Dirac
        f, pdf = lobe.eval(p, wo, s.wi)
        assert f.shape == (k, 3) and pdf.shape == (k,) and np.all(f >= 0) and np.all(np.isfinite(f))
        np.testing.assert_array_equal(lobe.pdf(p, wo, s.wi), pdf)
    under = lobe.layer_weight(p, wo)
    assert under.shape == (k,) and np.all((under >= 0) & (under <= 1))
    weight = np.full((k, 3), 0.5)
    parts = lobe.albedo_parts(p, wo, weight, weight * albedo)
    assert all(c in (0, 1, 2) and v.shape == (k, 3) for c, v in parts)
    np.testing.assert_allclose(sum(v for _, v in parts), weight * albedo, rtol=1e-12)
    lobe_ids = np.zeros(3, np.int64)
    assert lobe.stores_photons(m, lobe_ids, 0.3).dtype == bool
    shares = lobe.analysis_albedo(m, lobe_ids, m.lobe_color[lobe_ids], 0.3)
    assert set(shares) <= set(base.ANALYSIS_CLASSES) and all(v.shape == (3,) for v in shares.values())
    # Caustics toggles and Filter Glossy change the record in place (or leave the lobe out).
    whole = lobe.drop_caustics(p, np.ones(k, bool), np.zeros(k, bool))
    assert whole is None or (whole.dtype == bool and whole.shape == (k,))
    lobe.blur(p, np.full(k, 0.5))
    np.testing.assert_array_equal(lobe.is_delta(p), p.delta)
    if hasattr(p, "alpha"):  # GGX lobes: alpha at least Filter Glossy's, no mirror left
        assert np.all(p.alpha >= 0.5) and not p.delta.any()


def test_rows_of_a_record_are_gathered_as_read():
    lobe, p, wo, m = _lobe_and_params("glass_rough_inside", 5)
    rows = p.take(np.array([4, 0, 0]))
    assert len(rows) == 3 and "alpha" not in rows.__dict__
    np.testing.assert_array_equal(rows.alpha, p.alpha[[4, 0, 0]])
    np.testing.assert_array_equal(rows.take(np.array([1])).inside, p.inside[[0]])


# ----------------------------------------------------------------------------------------------
# Sample, pdf and eval of each lobe agree

@pytest.mark.parametrize("name", SMOOTH)
def test_sample_pdf_is_the_lobes_pdf_and_evals(name):
    k = 20_000
    lobe, p, wo, _ = _lobe_and_params(name, k)
    rng = np.random.default_rng(11)
    s = lobe.sample(p, wo, rng.random((k, 2)), rng.random(k))
    kept = s.pdf > 0
    assert kept.mean() > 0.5 and not np.any(s.delta)
    q = p.take(np.flatnonzero(kept))
    f, pdf = lobe.eval(q, wo[kept], s.wi[kept])
    np.testing.assert_allclose(s.pdf[kept], pdf, rtol=1e-6)
    assert np.all(pdf > 0) and np.all(f.max(axis=1) > 0)


def _chi2(name, seed) -> ChiSquareTest:
    """The lobe's own samples against its own pdf over the sphere about the local z, in (cos
    theta, phi) cells; samples the lobe drops (pdf 0) form the rejected cell."""
    lobe, p, wo, _ = _lobe_and_params(name, N_CHI2)

    def sampler(u):
        s = lobe.sample(p, wo, u[:, :2], u[:, 2])
        return s.wi, s.pdf > 0

    def pdf(d):
        lobe_d, q, wo_d, _ = _lobe_and_params(name, len(d))
        return lobe_d.pdf(q, wo_d, d)

    return ChiSquareTest(Sphere(), sampler, pdf, resolution=(40, 30), n_samples=N_CHI2, seed=seed,
                         sample_dim=3, order=6, name=name)


@pytest.mark.parametrize("name", SMOOTH)
def test_lobe_samples_follow_its_pdf_chi2(name):
    """Pearson's statistic over the cells, and the number of samples the lobe drops against the
    share its pdf leaves out (ChiSquareTest tests both)."""
    _chi2(name, SMOOTH.index(name)).check(n_tests=len(SMOOTH))


@pytest.mark.parametrize("name", SMOOTH)
def test_lobe_pdf_integrates_to_the_share_it_keeps(name):
    """The pdf over the sphere (fine cells: narrow lobes at grazing angles) equals the share of
    samples the lobe keeps, within 4 binomial standard deviations: sees a pdf off by a
    constant factor, to which the chi-square over many cells is nearly blind."""
    test = _chi2(name, 100 + SMOOTH.index(name))
    _, kept = test.draw()
    share = kept.mean()
    integral = integrate(Sphere(), test.pdf, (160, 120), order=6).sum()
    assert abs(integral - share) < 4 * np.sqrt(share * (1 - share) / N_CHI2) + 1e-4, (integral, share)


@pytest.mark.parametrize("name", sorted(DELTA))
def test_delta_samples_carry_their_discrete_weight(name):
    """Mirror: F at wo (its albedo); transparency: straight through with its colour; smooth
    glass: reflect with pmf F (tint), refract with pmf 1 - F (colour / eta_rel^2): the
    expected weight is F tint + (1 - F) colour / eta_rel^2."""
    k = 4096
    lobe, p, wo, _ = _lobe_and_params(name, k)
    u_branch = (np.arange(k) + 0.5) / k
    s = lobe.sample(p, wo, np.full((k, 2), 0.5), u_branch)
    assert np.all(s.delta)
    if name == "transparent":
        np.testing.assert_array_equal(s.wi, -wo)
        np.testing.assert_array_equal(s.weight, lobe.albedo(p, wo))
        assert np.all(s.pdf == 1) and np.all(s.label == base.LABEL_TRANSPARENT)
    elif name == "mirror":
        np.testing.assert_allclose(s.wi, wo * [-1, -1, 1])
        np.testing.assert_array_equal(s.weight, lobe.albedo(p, wo))
        assert np.all(s.pdf == 1) and np.all(s.label == base.LABEL_GLOSSY)
    else:
        inside = CASES[name][2]
        eta_rel = 1 / 1.5 if inside else 1.5
        F = fresnel.dielectric(wo[0, 2], eta_rel)
        refracted = s.wi[:, 2] < 0
        np.testing.assert_allclose(refracted.mean(), 1 - F, atol=1.5 / k)
        np.testing.assert_allclose(s.pdf, np.where(refracted, 1 - F, F), rtol=1e-12)
        np.testing.assert_array_equal(s.label, np.where(refracted, base.LABEL_TRANSMIT, base.LABEL_GLOSSY))
        np.testing.assert_allclose(s.eta2, eta_rel ** 2, rtol=1e-12)
        expected = F * p.tint[0] + (1 - F) * p.color[0] / eta_rel ** 2
        np.testing.assert_allclose(s.weight.mean(axis=0), expected, rtol=2e-3)
        # Snell in the mirrored frame: sin_t = sin_o / eta_rel.
        sin_o = np.hypot(wo[0, 0], wo[0, 1])
        np.testing.assert_allclose(np.hypot(s.wi[refracted, 0], s.wi[refracted, 1]), sin_o / eta_rel, rtol=1e-9)


def test_total_internal_reflection_inside_smooth_glass():
    spec, _, _ = CASES["glass_smooth_inside"]
    lobe = lobes.LOBES[LOBE_DIELECTRIC]
    m = Materials.make([dict(kind=MAT_NODES, lobes=[spec])])
    p = lobe.parameters(m, np.zeros(8, np.int64), np.arange(8), inputs.Sources(None), np.ones(8, bool))
    t = np.radians(60)  # past the critical angle of 41.8 degrees
    wo = np.tile([np.sin(t), 0.0, np.cos(t)], (8, 1))
    s = lobe.sample(p, wo, np.zeros((8, 2)), np.linspace(0, 0.999, 8))
    assert np.all(s.wi[:, 2] > 0) and np.all(s.pdf == 1)
    np.testing.assert_allclose(s.weight, np.tile(p.tint[0], (8, 1)))


# ----------------------------------------------------------------------------------------------
# What the photon tracer and the scene analysis ask

def _all_kinds():
    return Materials.make([dict(kind=MAT_NODES, lobes=[
        dict(kind=LOBE_DIFFUSE, color=(0.5, 0.5, 0.5), weight=(0.5,) * 3),
        dict(kind=LOBE_PHONG, color=(0.2, 0.2, 0.2), tint=(0.3, 0.3, 0.3), weight=(0.5,) * 3)]),
        dict(kind=MAT_NODES, lobes=[dict(kind=LOBE_PHONG, color=(0, 0, 0), tint=(0.6, 0.6, 0.6))]),
        dict(kind=MAT_NODES, lobes=[dict(kind=LOBE_MICROFACET, roughness=0.2, color=(0.9, 0.9, 0.9))]),
        dict(kind=MAT_NODES, lobes=[dict(kind=LOBE_MICROFACET, roughness=0.3, color=(0.9, 0.9, 0.9))]),
        dict(kind=MAT_NODES, lobes=[dict(kind=LOBE_DIELECTRIC, roughness=0.5, color=(0.2, 0.2, 0.2))]),
        dict(kind=MAT_NODES, lobes=[dict(kind=LOBE_TRANSPARENT, color=(0.4, 0.4, 0.4), weight=(0.8,) * 3)])])


def test_photon_storing_lobes():
    """Diffuse, Phong with a diffuse part, GGX and glass of roughness >= the threshold."""
    m = _all_kinds()
    assert lobes.stores_photons(m, 0.3).tolist() == [True, True, False, False, True, True, False]


def test_analysis_classes_of_lobe_albedos():
    m = _all_kinds()
    a = lobes.analysis_albedo(m, m.lobe_color, 0.3)
    expected = np.array([[0.25, 0, 0, 0],  # diffuse: weight x colour
                         [0.1, 0.15, 0, 0],  # Phong: kd diffuse, ks glossy
                         [0, 0.6, 0, 0],
                         [0, 0, 0.9, 0],  # GGX sharper than 0.3: specular
                         [0, 0.9, 0, 0],
                         [0, 1.0, 0, 0],  # glass: its weight, whatever its colour
                         [0, 0, 0, 0.8]])  # transparency: its weight
    assert base.ANALYSIS_CLASSES == ("diffuse", "glossy", "specular", "transparent")
    np.testing.assert_allclose(a, expected, rtol=1e-12)
