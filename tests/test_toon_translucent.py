"""The Translucent and Toon lobes (engine/bsdf/lobes/translucent.py, toon.py) beyond the lobe
table's common checks (tests/test_lobes.py): the Glossy Toon's samples against its pdf in the
frame of the mirror direction, the Diffuse Toon's adjoint (light particles), the symmetries
each has (Translucent f reciprocal; Toon Glossy f cos symmetric), the white furnace (the energy
Cycles' intensity profile keeps, by quadrature), and with Blender: a leaf lit from behind and
toon spheres against Cycles' renders of the same scenes. Seeded."""
import numpy as np
import pytest

from ember.engine.bsdf import lobes
from ember.engine.bsdf.lobes import inputs
from ember.engine.scene import LOBE_TOON, LOBE_TRANSLUCENT, MAT_NODES, TOON_GLOSSY, Materials

from stats import ChiSquareTest, Sphere

N_CHI2 = 100_000
# acos(0.9) / (pi / 2): the Glossy cone's edge on a cell edge of the (cos, phi) grid about its axis.
GLOSSY = dict(kind=LOBE_TOON, color=(0.5, 0.6, 0.7), roughness=0.2, exponent=0.0871113, distribution=TOON_GLOSSY)
DIFFUSE = dict(kind=LOBE_TOON, color=(0.7, 0.6, 0.5), roughness=0.3, exponent=0.4)
TRANSLUCENT = dict(kind=LOBE_TRANSLUCENT, color=(0.6, 0.7, 0.4))


def _params(spec, k, adjoint=False):
    m = Materials.make([dict(kind=MAT_NODES, lobes=[spec])])
    lobe = lobes.LOBES[spec["kind"]]
    p = lobe.parameters(m, np.zeros(k, np.int64), np.arange(k), inputs.Sources(None), np.zeros(k, bool))
    p.adjoint = adjoint
    return lobe, p


def _dir(theta_deg, phi=1.0, k=1):
    t = np.radians(theta_deg)
    return np.tile([np.sin(t) * np.cos(phi), np.sin(t) * np.sin(phi), np.cos(t)], (k, 1))


def _unit(n, seed):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


@pytest.mark.parametrize("case", ["glossy", "glossy_adjoint", "diffuse_adjoint"])
def test_toon_samples_follow_its_pdf_chi2(case):
    """Glossy: cells about wo's mirror direction (the cone's edge on a cell edge); the Diffuse
    adjoint (cosine-weighted) over the sphere about the normal."""
    spec = GLOSSY if case.startswith("glossy") else DIFFUSE
    adjoint = case.endswith("adjoint")
    wo = _dir(55.0)
    axis = wo[0] * [-1, -1, 1] if spec is GLOSSY else [0.0, 0.0, 1.0]

    def sampler(u):
        lobe, p = _params(spec, len(u), adjoint)
        s = lobe.sample(p, np.repeat(wo, len(u), 0), u[:, :2], u[:, 2])
        return s.wi, s.pdf > 0

    def pdf(d):
        lobe, p = _params(spec, len(d), adjoint)
        return lobe.pdf(p, np.repeat(wo, len(d), 0), d)

    test = ChiSquareTest(Sphere(axis=axis), sampler, pdf, resolution=(40, 30), n_samples=N_CHI2,
                         seed=["glossy", "glossy_adjoint", "diffuse_adjoint"].index(case), sample_dim=3, order=6,
                         name=case)
    test.check(n_tests=3)


def test_translucent_is_reciprocal_and_glossy_toon_f_cos_is_symmetric():
    """Translucent: f(wo, wi) = f(wi', wo') in the frame flipped to wi's side; Glossy Toon: f
    cos(wi) = f(wi, wo) cos(wo) (Cycles makes f cos a function of the angle between wi and
    wo's mirror direction, which is symmetric); its adjoint is f(wi, wo)."""
    k = 4000
    wo, wi = _unit(k, 1), _unit(k, 2)
    wo[:, 2] = np.abs(wo[:, 2])
    lobe, p = _params(TRANSLUCENT, k)
    below = wi * [1, 1, 1]
    below[:, 2] = -np.abs(wi[:, 2])  # on the far side
    f, _ = lobe.eval(p, wo, below)
    g, _ = lobe.eval(p, below * [1, 1, -1], wo * [1, 1, -1])
    np.testing.assert_allclose(f, g, rtol=1e-12)
    np.testing.assert_allclose(f, np.tile([0.6, 0.7, 0.4], (k, 1)) / np.pi, rtol=1e-12)
    # Glossy Toon: wide cone so that most pairs are inside it.
    wide = dict(GLOSSY, roughness=0.6, exponent=0.4)
    lobe, p = _params(wide, k)
    up = wi * np.sign(wi[:, 2:3])
    f, _ = lobe.eval(p, wo, up)
    g, _ = lobe.eval(p, up, wo)
    assert (f[:, 0] > 0).mean() > 0.3
    np.testing.assert_allclose(f * up[:, 2:3], g * wo[:, 2:3], rtol=1e-9, atol=1e-12)
    _, q = _params(wide, k, adjoint=True)
    np.testing.assert_allclose(lobe.eval(q, wo, up)[0], g, rtol=1e-12)


def _energy(size, smooth):
    """Cycles' toon albedo in closed form: the mean over the sampled cone (half-angle theta_s)
    of the intensity, 1 up to the angle a and 1 - (theta - a) / s after it (f cos = I pdf_c):
    (1 - cos a + cos a - g(theta_s) cos theta_s - (sin theta_s - sin a) / s) / (1 - cos theta_s)."""
    a, s = np.clip(size, 1e-5, 1) * np.pi / 2, np.clip(smooth, 0, 1) * np.pi / 2
    theta_s = min(a + s, np.pi / 2)
    total = 1.0 - np.cos(min(a, theta_s))
    if s > 0 and theta_s > a:  # the fall-off, integrated by parts
        g = 1.0 - (theta_s - a) / s
        total += np.cos(a) - g * np.cos(theta_s) - (np.sin(theta_s) - np.sin(a)) / s
    return total / (1.0 - np.cos(theta_s))


@pytest.mark.parametrize("spec", [TRANSLUCENT, DIFFUSE, dict(DIFFUSE, roughness=0.9, exponent=0.0), GLOSSY,
                                  dict(GLOSSY, roughness=0.5, exponent=0.6)])
def test_white_furnace(spec):
    """The albedo of a white lobe, the mean of f cos / pdf over its samples: 1 for Translucent;
    for Toon the quadrature of its intensity over the cone (Glossy at normal incidence, where no
    part of the cone is under the horizon; at grazing wo it loses what falls under), at most 1;
    5 standard errors."""
    k = 200_000
    spec = dict(spec, color=(1.0, 1.0, 1.0))
    lobe, p = _params(spec, k)
    for theta in (0.0, 35.0, 75.0):
        wo = _dir(theta, k=k)
        s = lobe.sample(p, wo, np.random.default_rng(int(theta)).random((k, 2)), np.zeros(k))
        f, pdf = lobe.eval(p, wo, s.wi)
        w = np.where(s.pdf > 0, f[:, 0] * np.abs(s.wi[:, 2]) / np.where(s.pdf > 0, s.pdf, 1.0), 0.0)
        mean, se = w.mean(), w.std() / np.sqrt(k)
        if spec["kind"] == LOBE_TRANSLUCENT:
            assert abs(mean - 1.0) < 1e-12
        elif spec.get("distribution") != TOON_GLOSSY or theta == 0.0:
            assert abs(mean - _energy(spec["roughness"], spec["exponent"])) < 5 * se + 1e-9, (theta, mean)
        assert mean <= 1.0 + 5 * se


# ---- against Cycles -------------------------------------------------------------------------------

SIZE, SEEDS, EMBER_SAMPLES, CYCLES_SAMPLES, TOL = 32, 4, 64, 256, 0.01


def leaf_scene():
    """A Translucent leaf (a plane) lit from behind by a sun, seen from the front over a dim
    world; a small diffuse card under it shadows part of it and is lit through it."""
    import bpy
    from cycles_scenes import camera, diffuse_floor, new_scene, node_material
    sc = new_scene(SIZE, world=(0.02, 0.02, 0.02))
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(0, 0, 1))
    mat, nt, out = node_material("Leaf")
    t = nt.nodes.new("ShaderNodeBsdfTranslucent")
    t.inputs["Color"].default_value = (0.3, 0.8, 0.2, 1)
    nt.links.new(t.outputs[0], out.inputs["Surface"])
    bpy.context.active_object.data.materials.append(mat)
    bpy.ops.object.light_add(type="SUN", rotation=(np.pi - 0.4, 0.2, 0))  # from below
    bpy.context.active_object.data.energy = 4.0
    diffuse_floor(size=1.0)  # under the leaf, lit through it, shading part of it
    bpy.context.active_object.location = (0.5, 0.3, 0.4)
    camera(sc, (0.0, -2.5, 4.5), (0.5, 0, 0))
    return sc


def toon_scene(components=("DIFFUSE", "GLOSSY")):
    """A Diffuse Toon and a Glossy Toon sphere (those of `components`) on a grey floor under a
    sun and a dim world."""
    import bpy
    from cycles_scenes import camera, diffuse_floor, new_scene, node_material
    sc = new_scene(SIZE, world=(0.1, 0.1, 0.12))
    diffuse_floor()
    for x, component, size, smooth in ((-1.1, "DIFFUSE", 0.5, 0.1), (1.1, "GLOSSY", 0.3, 0.2)):
        if component not in components:
            continue
        bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, location=(x, 0, 1), segments=48, ring_count=24)
        bpy.ops.object.shade_smooth()
        mat, nt, out = node_material(component)
        toon = nt.nodes.new("ShaderNodeBsdfToon")
        toon.component = component
        toon.inputs["Color"].default_value = (0.9, 0.5, 0.2, 1)
        toon.inputs["Size"].default_value, toon.inputs["Smooth"].default_value = size, smooth
        nt.links.new(toon.outputs[0], out.inputs["Surface"])
        bpy.context.active_object.data.materials.append(mat)
    bpy.ops.object.light_add(type="SUN", rotation=(0.6, 0.3, 0.4))
    bpy.context.active_object.data.energy = 3.0
    camera(sc, (0, -6.5, 3.0), (1.2, 0, 0))
    return sc


@pytest.mark.blender
@pytest.mark.parametrize("build", [leaf_scene, toon_scene])
def test_renders_as_cycles(build, tmp_path):
    from cycles_renders import agree, cycles_image, ember_image
    from cycles_scenes import addon
    with addon():
        sc = build()
        cycles = [cycles_image(sc, CYCLES_SAMPLES, 100 + k, tmp_path / f"c{k}.exr") for k in range(SEEDS)]
        ember = [ember_image(sc, "PATH", EMBER_SAMPLES, k) for k in range(SEEDS)]
        agree(ember, cycles, 2, TOL)


def test_toon_components_fill_their_own_passes_and_light_visibility():
    """A material of a Diffuse Toon and a Glossy Toon: the closure files each one's light in
    its own pass class (Diffuse, Glossy) and a light seen by diffuse rays only lights the
    Diffuse Toon (Cycles' closure classes)."""
    from ember.engine.bsdf.closure import Closure
    from ember.engine.scene import Lights, RAY_DIFFUSE, Scene, World
    from core_scenes import perspective, quads_mesh, settings
    wide = dict(roughness=1.0, exponent=0.0)
    mats = Materials.make([dict(kind=MAT_NODES, lobes=[dict(DIFFUSE, **wide), dict(GLOSSY, **wide)])])
    quad = [[-1, 1, -1], [-1, 1, 1], [1, 1, 1], [1, 1, -1]]
    scene = Scene(quads_mesh([quad], [0]), mats, Lights.make([]), World(), perspective((0, 0, 0), (0, 1, 0), 30),
                  settings())
    k = 64
    n = np.tile([0.0, -1.0, 0.0], (k, 1))
    wo = np.tile([0.0, -np.cos(0.3), np.sin(0.3)], (k, 1))
    bsdf = Closure(scene, np.zeros(k, np.int64), n, n, wo, np.zeros(k, np.int64), np.full((k, 3), 1 / 3))
    wi = _unit(k, 5)
    wi[:, 1] = -np.abs(wi[:, 1])
    rows = np.arange(k)
    by_class = bsdf.eval_by_class(wi, rows)
    f_diffuse = _params(dict(DIFFUSE, **wide), k)
    local = np.stack([wi[:, 0], wi[:, 2], -wi[:, 1]], axis=1)  # any frame about n: only angles matter here
    local_wo = np.stack([wo[:, 0], wo[:, 2], -wo[:, 1]], axis=1)
    d = f_diffuse[0].eval(f_diffuse[1], local_wo, local)[0]
    np.testing.assert_allclose(by_class[:, 0], d, rtol=1e-9)
    assert np.all(by_class[:, 2] == 0) and by_class[:, 1].max() > 0
    f, _ = bsdf.eval(wi, rows, np.full(k, RAY_DIFFUSE, np.uint8))
    np.testing.assert_allclose(f, by_class[:, 0], rtol=1e-9)
