"""Worlds and lights through the node evaluator.

Without Blender: the world program's table against its samples (chi-square over the sphere,
cells on the table's pixels), the light-sampling estimate of the world's integral against the
integral computed apart, the radiance of a diffuse plane under a program world against
quadrature for every strategy, the path state a world's Light Path reads (through a stub
node), what a world builds, and a World's graph through save / load and the worker handover.
With Blender (marked blender): Ember's renders of a white diffuse sphere under worlds Cycles
renders differently from a constant (the default Sky Texture, a Mix Shader of two backgrounds,
an Environment Texture through Mapping, a procedural gradient) and lit by lights whose node
trees fold to constants (Blackbody, Emission strength), against Cycles' renders of the same
scenes in the same run.

Mutation checks live in the tests themselves: a table pdf off by 3 % must fail the chi-square
(test_chi2_notices_a_three_percent_pdf_error), a light strength in the wrong unit must fail the
render comparison (test_lights_match_cycles's mutation case).
"""
import zlib

import numpy as np
import pytest

from ember.engine.accel import Accel
from ember.engine.lights import world as world_mod
from ember.engine.lights.light_set import LightSet
from ember.engine.lights.world import Background, WorldMap, map_size, world_emitters
from ember.engine.nodes import light_path as lp, registry, state as state_mod
from ember.engine.nodes.hits import RayState
from ember.engine.nodes.graph import Graph, Input, Link, Node
from ember.engine.scene import Lights, Materials, Scene, World, scene_from_plain, to_plain
from ember.engine.session import RenderSession

from core_scenes import perspective, quads_mesh, settings
from stats import ChiSquareTest, Sphere

# ---- graphs by hand -----------------------------------------------------------------------------


def _node(kind, label, inputs=(), outputs=(), **props):
    return Node(kind, label, tuple(sorted(props.items())), tuple(inputs), tuple(outputs))


def _colour(value=(0.0, 0.0, 0.0), link=None):
    return Input("Color", "rgba", tuple(value), link)


def _world(*nodes, surface: int, socket="Background") -> Graph:
    """A Graph of `nodes` whose Surface is output `socket` of node `surface`."""
    return Graph(tuple(nodes), (("surface", Input("Surface", "shader", 0.0, Link(surface, socket, "shader"))),))


def _background(i, label="Background", colour=(0.8, 0.8, 0.8), link=None, strength=1.0):
    return _node("ShaderNodeBackground", label, [_colour(colour, link), Input("Strength", "value", strength)],
                 [("Background", "shader")])


def sky_graph(**props) -> Graph:
    """Sky Texture (Blender's defaults unless given) -> Background."""
    sky = _node("ShaderNodeTexSky", "Sky Texture", [Input("Vector", "vector", (0.0, 0.0, 0.0))],
                [("Color", "rgba")], **props)
    return _world(sky, _background(1, link=Link(0, "Color", "rgba")), surface=1)


def gradient_graph(kind="LINEAR") -> Graph:
    """Gradient Texture of the direction (Generated) -> Background: dark at -x, bright at +x."""
    grad = _node("ShaderNodeTexGradient", "Gradient", [Input("Vector", "vector", (0.0, 0.0, 0.0))],
                 [("Fac", "value"), ("Color", "rgba")], gradient_type=kind)
    return _world(grad, _background(1, link=Link(0, "Color", "rgba"), strength=2.0), surface=1)


def mix_graph() -> Graph:
    """Mix Shader of a gradient background and a constant one, by a quadratic-sphere gradient."""
    grad = _node("ShaderNodeTexGradient", "Gradient", [Input("Vector", "vector", (0.0, 0.0, 0.0))],
                 [("Fac", "value"), ("Color", "rgba")], gradient_type="LINEAR")
    fac = _node("ShaderNodeTexGradient", "Fac", [Input("Vector", "vector", (0.0, 0.0, 0.0))],
                [("Fac", "value"), ("Color", "rgba")], gradient_type="QUADRATIC_SPHERE")
    a = _background(2, "A", link=Link(0, "Color", "rgba"), strength=3.0)
    b = _background(3, "B", colour=(0.1, 0.3, 0.9), strength=0.5)
    mix = _node("ShaderNodeMixShader", "Mix", [Input("Fac", "value", 0.5, Link(1, "Fac", "value")),
                                               Input("Shader", "shader", 0.0, Link(2, "Background", "shader")),
                                               Input("Shader_001", "shader", 0.0, Link(3, "Background", "shader"))],
                [("Shader", "shader")])
    return _world(grad, fac, a, b, mix, surface=4, socket="Shader")


BIG_SUN = dict(sun_size=0.25, sun_intensity=0.02, sun_elevation=0.5, sun_rotation=1.0)  # resolvable by quadrature
GRAPHS = {"sky": lambda: sky_graph(), "sky_big_sun": lambda: sky_graph(**BIG_SUN), "gradient": gradient_graph,
          "mix": mix_graph}


def unit(n, seed):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def sphere_integral(background: Background, width=2048, weight=None) -> np.ndarray:
    """(3,) integral of the program's radiance over the sphere (x weight(d) if given) by the
    midpoint rule on a fine (cos theta, phi) grid, apart from the table."""
    height = width // 2
    cos_t = 1.0 - (np.arange(height) + 0.5) * (2.0 / height)
    phi = (np.arange(width) + 0.5) * (2.0 * np.pi / width)
    sin_t = np.sqrt(1.0 - cos_t**2)
    d = np.stack([np.outer(sin_t, np.cos(phi)), np.outer(sin_t, np.sin(phi)), np.repeat(cos_t[:, None], width, 1)],
                 axis=-1).reshape(-1, 3)
    step = 1 << 18
    L = np.concatenate([background.radiance(d[k:k + step]) for k in range(0, len(d), step)])
    if weight is not None:
        L = L * weight(d)[:, None]
    return L.sum(axis=0) * (2.0 / height) * (2.0 * np.pi / width)


# ---- the table against its samples --------------------------------------------------------------

N_CHI2 = 400_000
TABLE = 64  # table width for the chi-square cases: cells on its pixels integrate its pdf exactly


def _fit(env: WorldMap, seed, pdf=None):
    """The chi-square of the table's sampler: cells on its pixels (rows of cos theta, columns of
    phi: a frame whose azimuth is atan2(y, x) has them at k 2 pi / W), where its pdf is
    constant, and, around each guided sun, a fine grid of 48 x 48 cells over the cone's
    (cos theta, phi) box, so the cone's rim cuts only small cells."""
    h, w = env.shape
    rows, cols = [np.cos(np.linspace(np.pi, 0.0, h + 1))], [np.linspace(0.0, 2.0 * np.pi, w + 1)]
    for sun in env.suns:
        theta, phi = np.arccos(sun.axis[2]), np.mod(np.arctan2(sun.axis[1], sun.axis[0]), 2.0 * np.pi)
        rows.append(np.cos(np.linspace(theta + 1.2 * sun.half, theta - 1.2 * sun.half, 49)))
        wide = 1.2 * sun.half / np.sin(theta)
        cols.append(np.linspace(phi - wide, phi + wide, 49))
    edges = tuple(_merged(e, lo, hi) for e, (lo, hi) in zip((rows, cols), ((-1.0, 1.0), (0.0, 2.0 * np.pi))))

    def sampler(u):
        s = env.sample(u)
        assert s.valid.all()
        return s.wi

    return ChiSquareTest(Sphere(frame=np.eye(3)), sampler, pdf or env.pdf, edges, N_CHI2, seed=seed, order=6)


def _merged(parts, lo, hi):
    """Sorted edges of `parts` within [lo, hi], ends exactly lo and hi, none closer than 1e-9."""
    e = np.unique(np.clip(np.concatenate(parts), lo, hi))
    e = e[np.concatenate([[True], np.diff(e) > 1e-9])]
    e[0], e[-1] = lo, hi
    return e


CHI2 = [(name, compensate) for name in GRAPHS if name != "sky" for compensate in (False, True)]


@pytest.mark.parametrize("name,compensate", CHI2)
def test_chi2_world_table(name, compensate):
    env = WorldMap(Background(GRAPHS[name]()), map_size(GRAPHS[name](), TABLE), compensate)
    if name == "sky_big_sun":
        assert env.suns and 0.0 < env.p_map < 1.0
    _fit(env, seed=zlib.crc32(name.encode()) % 1000 + compensate).check(n_tests=len(CHI2))  # not hash(): salted per process


def test_chi2_notices_a_three_percent_pdf_error():
    """The mutation: the claimed pdf 3 % high above the horizon and low enough below that it
    still integrates to 1; the chi-square must reject it (and accept the true one)."""
    env = WorldMap(Background(gradient_graph()), map_size(gradient_graph(), TABLE), False)
    up = world_mod.pixel_centres(64, 32)[:, 2] > 0
    top = float(np.sum(env.pdf(world_mod.pixel_centres(64, 32))[up]))
    rest = float(np.sum(env.pdf(world_mod.pixel_centres(64, 32))[~up]))
    low = 1.0 - 0.03 * top / rest

    def wrong(d):
        return env.pdf(d) * np.where(d[:, 2] > 0, 1.03, low)

    assert _fit(env, 7).run().passed
    assert not _fit(env, 7, wrong).run().passed


def test_sun_is_sampled_apart_and_its_disc_left_out_of_the_table():
    graph = sky_graph()
    guided = world_mod.guided_suns(graph)
    assert len(guided) == 1
    _, axis, half = guided[0]
    np.testing.assert_allclose(axis, [0.0, np.cos(0.2617993950843811), np.sin(0.2617993950843811)], atol=1e-6)
    assert np.isclose(half, 0.5 * 0.009512044489383698)
    env = WorldMap(Background(graph), map_size(graph, 0, True), False)
    assert env.shape == (256, 512) and 0.5 < env.suns[0].share <= world_mod.SUN_SHARE_MAX
    # The table is the sky alone: no pixel near the sun holds the disc's radiance.
    sun_radiance = Background(graph).radiance(axis[None])[0]
    assert env.values.max() < 1e-3 * sun_radiance.max()
    # A linked vector other than Generated: not guided (as Cycles).
    sky = graph.nodes[0]
    mapped = _node("ShaderNodeMapping", "Mapping", [Input("Vector", "vector", (0.0, 0.0, 0.0))], [("Vector", "vector")])
    linked = Graph((mapped, Node(sky.kind, sky.label, sky.props, (Input("Vector", "vector", (0.0, 0.0, 0.0),
                                                                         Link(0, "Vector", "vector")),), sky.outputs),
                    _background(2, link=Link(1, "Color", "rgba"))), graph.outputs)
    assert not world_mod.guided_suns(replace_surface(linked, 2))


def replace_surface(graph, node):
    return Graph(graph.nodes, (("surface", Input("Surface", "shader", 0.0, Link(node, "Background", "shader"))),))


@pytest.mark.parametrize("name", list(GRAPHS))
def test_light_sampling_estimates_the_worlds_integral(name):
    """E[L / pdf] over the table's samples is the integral of the program's radiance over the
    sphere (the uncompensated table, 4 sigma): the radiance is the program's, the pdf the
    table's."""
    graph = GRAPHS[name]()
    background = Background(graph)
    env = WorldMap(background, map_size(graph, 256, bool(world_mod.guided_suns(graph))), False)
    s = env.sample(np.random.default_rng(3).random((400_000, 2)))
    f = s.Le / s.pdf[:, None]
    est, se = f.mean(axis=0), f.std(axis=0) / np.sqrt(len(f))
    if name == "sky":  # the real disc is a tenth of a degree: integrate it in its own cone
        sun = env.suns[0]
        inside = lambda d: (0.5 * np.sum((d - sun.axis) ** 2, axis=1) <= sun.omc).astype(float)  # noqa: E731
        ref = sphere_integral(background, 2048, lambda d: 1.0 - inside(d))
        cone = sun.sample(np.random.default_rng(4).random((200_000, 2)))
        ref = ref + background.radiance(cone).mean(axis=0) * 2.0 * np.pi * sun.omc
    else:
        ref = sphere_integral(background, 2048)
    assert np.all(np.abs(est - ref) < 4.0 * se + 2e-3 * ref), (est, ref, se)
    np.testing.assert_allclose(env.power_integral, ref, rtol=0.05)


def test_map_size_rule():
    assert map_size(gradient_graph()) == (world_mod.DEFAULT_WIDTH, world_mod.DEFAULT_WIDTH // 2)
    assert map_size(sky_graph(), 0, True) == (512, 256)
    assert map_size(sky_graph(), 300) == (300, 150)
    assert map_size(sky_graph(), 10 ** 6)[0] == world_mod.MAX_WIDTH
    from ember.engine.nodes.image import Texels
    env = _node("ShaderNodeTexEnvironment", "Env", [Input("Vector", "vector", (0.0, 0.0, 0.0))],
                [("Color", "rgba"), ("Alpha", "value")],
                image=Texels("hdr", np.ones((40, 80, 4), np.float32)), projection="EQUIRECTANGULAR")
    graph = _world(env, _background(1, link=Link(0, "Color", "rgba")), surface=1)
    assert map_size(graph) == (80, 40)
    ball = Graph((replace_prop(env, projection="MIRROR_BALL"),) + graph.nodes[1:], graph.outputs)
    assert map_size(ball) == (160, 80)


def replace_prop(node, **props):
    return Node(node.kind, node.label, tuple(sorted(dict(node.props, **props).items())), node.inputs, node.outputs)


# ---- rendering: a diffuse plane under a program world ------------------------------------------

def plane_scene(world, strategy="mis", samples=64):
    """A white (albedo 0.5) diffuse square facing +z, seen from above: its radiance is
    0.5 / pi x the integral of L cos over the upper hemisphere (nothing else in the scene)."""
    mesh = quads_mesh([[(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]], [0])
    mats = Materials.make([dict(base_color=(0.5, 0.5, 0.5))])
    return Scene(mesh, mats, Lights.make([]), world, perspective((0, 0, 3), (0, 0, 0), 20),
                 settings(samples=samples, width=8, height=8, strategy=strategy, threads=1))


@pytest.mark.parametrize("name", ["sky_big_sun", "mix"])
@pytest.mark.parametrize("strategy", ["mis", "light", "bsdf"])
def test_diffuse_plane_under_program_world(name, strategy):
    graph = GRAPHS[name]()
    world = World(color=np.ones(3), graph=(graph,), map_resolution=128)
    session = RenderSession(plane_scene(world, strategy, samples=256 if strategy == "bsdf" else 64))
    session.run()
    img, var = session.film.mean(), session.film.variance_of_mean()
    up = lambda d: np.maximum(d[:, 2], 0.0)  # noqa: E731
    expected = 0.5 / np.pi * sphere_integral(Background(graph), 1024, up)
    mean, se = img.mean(axis=(0, 1)), np.sqrt(var.sum(axis=(0, 1))) / img[..., 0].size
    assert np.all(np.abs(mean - expected) < 4.5 * se + 0.01 * expected), (mean, expected, se)


def test_world_emitters_build_only_what_is_needed():
    # A program of constant radiance in every direction (Light Path aside): a constant light.
    flat = _world(_node("ShaderNodeTexGradient", "G", [Input("Vector", "vector", (0.0, 0.0, 0.0))],
                        [("Fac", "value"), ("Color", "rgba")], gradient_type="LINEAR"),
                  _background(1, colour=(0.2, 0.3, 0.4)), surface=1)
    constant, background, env = world_emitters(World(color=np.ones(3), graph=(flat,)))
    assert env is None
    constant, background, env = world_emitters(World(color=np.ones(3), graph=(gradient_graph(),)))
    assert isinstance(env, WorldMap) and background is not None and not np.any(constant)
    constant, background, env = world_emitters(World(color=np.ones(3), graph=(gradient_graph(),), map_resolution=-1))
    assert env is None and background is not None
    constant, background, env = world_emitters(World(color=np.zeros(3), graph=(gradient_graph(),)))
    assert env is None and background is None and not np.any(constant)
    # Uncompensated twin for photons: the same values, no new evaluation.
    env = world_emitters(World(color=np.ones(3), graph=(gradient_graph(),)), compensate=True)[2]
    assert env.compensated and not env.uncompensated().compensated and env.uncompensated().values is env.values


def test_world_graph_survives_save_load_and_the_worker_handover(tmp_path):
    world = World(color=np.ones(3), graph=(mix_graph(),), map_resolution=300)
    scene = plane_scene(world)
    scene.save(tmp_path / "s.npz")
    back = Scene.load(tmp_path / "s.npz").world
    assert back.graph == world.graph and back.map_resolution == 300
    plain = scene_from_plain(to_plain(scene)).world
    assert plain.graph == world.graph
    d = unit(100, 1)
    np.testing.assert_array_equal(Background(plain.graph[0]).radiance(d), Background(world.graph[0]).radiance(d))


# ---- Light Path in a world: the path state of escaped rays --------------------------------------

def camera_trick_graph(output="Is Camera Ray") -> Graph:
    """Mix Shader by a Light Path output: 0 -> a blue background of 0.5, 1 -> red of 2."""
    lp = _node("ShaderNodeLightPath", "Light Path", [], [(output, "value")])
    a = _background(1, "Lighting", colour=(0.0, 0.0, 1.0), strength=0.5)
    b = _background(2, "Camera", colour=(1.0, 0.0, 0.0), strength=2.0)
    mix = _node("ShaderNodeMixShader", "Mix", [Input("Fac", "value", 0.0, Link(0, output, "value")),
                                               Input("Shader", "shader", 0.0, Link(1, "Background", "shader")),
                                               Input("Shader_001", "shader", 0.0, Link(2, "Background", "shader"))],
                [("Shader", "shader")])
    return _world(lp, a, b, mix, surface=3, socket="Shader")


def test_escaped_rays_read_their_path_state():
    world = World(color=np.ones(3), graph=(camera_trick_graph(),))
    ls = LightSet(Lights.make([]), *_no_geometry(), world, Accel(_no_geometry()[0]), 1.0)
    assert ls.world_reads == {"path_flag"} and ls.env is None  # lighting: constant blue
    np.testing.assert_allclose(ls.world, [0.0, 0.0, 0.5])  # what photons and the table see
    d = unit(4, 2)
    flags = np.array([lp.CAMERA, lp.REFLECT | lp.DIFFUSE, lp.REFLECT | lp.GLOSSY, lp.CAMERA], np.uint32)
    camera = flags == lp.CAMERA
    L = ls.escaped(d, np.ones(4), np.zeros(4, bool), camera, None, RayState(flags))
    np.testing.assert_allclose(L, [[2, 0, 0], [0, 0, 0.5], [0, 0, 0.5], [2, 0, 0]])
    # Paths untracked (photon gathers): camera rays by `camera`, the others diffuse.
    L = ls.escaped(d, np.ones(4), np.zeros(4, bool), np.array([True, False, False, True]))
    np.testing.assert_allclose(L[:, 0], [2, 0, 0, 2])


def test_escaped_rays_and_light_samples_add_the_emission_flag():
    """Cycles evaluates the background with PATH_RAY_EMISSION added to the ray's flags, and a
    light sample with that flag alone and the path's counts."""
    ray = RayState(np.array([lp.CAMERA, lp.REFLECT | lp.GLOSSY], np.uint32), np.array([0, 3]))
    assert list(ray.escaped().flag) == [lp.CAMERA | lp.EMISSION, lp.REFLECT | lp.GLOSSY | lp.EMISSION]
    assert list(ray.escaped().bounce) == [0, 3]
    sample = ray.for_emission()
    assert sample.flag == lp.EMISSION and list(sample.bounce) == [0, 3]


def test_camera_sees_one_world_and_the_plane_another():
    """The render: background pixels red (2, 0, 0), the plane lit by the blue world only
    (its radiance: albedo 0.5 x 0.5 = 0.25 in blue)."""
    world = World(color=np.ones(3), graph=(camera_trick_graph(),))
    scene = plane_scene(world, samples=16)
    scene = scene.replace(camera=perspective((0, 0, 3), (0, 0, 0), 60))
    session = RenderSession(scene)
    session.run()
    img = session.film.mean()
    corner, centre = img[0, 0], img[4, 4]
    np.testing.assert_allclose(corner, [2.0, 0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(centre, [0.0, 0.0, 0.25], rtol=0.02, atol=1e-6)


def test_ray_depth_reads_the_paths_bounces():
    """Ray Depth in a world: the path's bounces + 1 (PATH_RAY_EMISSION); a RayState handed to
    escaped() gives them, and the tracer keeps the counts when the world reads them."""
    world = World(color=np.ones(3), graph=(camera_trick_graph("Ray Depth"),))
    ls = LightSet(Lights.make([]), *_no_geometry(), world, Accel(_no_geometry()[0]), 1.0)
    assert ls.world_reads == {"bounce", "path_flag"}

    ray = RayState(np.array([lp.CAMERA, lp.REFLECT | lp.DIFFUSE, lp.REFLECT | lp.DIFFUSE], np.uint32),
                   np.array([0, 1, 2]))
    L = ls.escaped(unit(3, 5), np.ones(3), np.zeros(3, bool), np.array([True, False, False]), None, ray)
    # Fac = depth + 1 clamped to [0, 1] by the Mix Shader: 1 everywhere -> red x 2.
    np.testing.assert_allclose(L[:, 0], 2.0)
    L0 = ls.escaped(unit(3, 5), np.ones(3), np.zeros(3, bool), np.zeros(3, bool), None, None)
    np.testing.assert_allclose(L0[:, 0], 2.0)  # no path given: depth 0 + 1


def _no_geometry():
    mesh = quads_mesh([[(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]], [0])
    return mesh, Materials.make([dict(base_color=(0.5, 0.5, 0.5))])


# ---- against Cycles (Blender) -------------------------------------------------------------------
# A white diffuse sphere (and, for the lights, a floor) rendered by Cycles and by Ember's path
# tracer in the same run, each as several independent renders: the spread of their means is an
# honest variance of each pixel's mean (Sobol's within-pixel variance overstates it). Pixels are
# z-tested with the within-pixel variances (a conservative screen for outliers); the image and
# its quadrants' means, with the honest variances, within a modelling tolerance (float32 tables,
# tessellation) plus the Sidak-corrected noise band: what gives the comparison its power.

SIZE = 32
CYCLES_RUNS, EMBER_RUNS = 6, 3
TOL_IMAGE, TOL_REGION = 0.005, 0.015


def _bpy():
    import os
    import tempfile
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))
    return pytest.importorskip("bpy")


def sphere_scene(floor=False):
    """Empty file: a camera at +x looking at a smooth white diffuse sphere of radius 1 at the
    origin (and a 8 x 8 floor under it), SIZE x SIZE pixels; returns the world's node tree."""
    bpy = _bpy()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.resolution_x = sc.render.resolution_y = SIZE
    sc.render.resolution_percentage = 100
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (5.0, 0.0, 0.8)
    cam.rotation_euler = (np.radians(81.0), 0.0, np.radians(90.0))
    sc.collection.objects.link(cam)
    sc.camera = cam
    bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=1.0)
    bpy.ops.object.shade_smooth()
    sphere = bpy.context.active_object
    mat = bpy.data.materials.new("white")
    nt = mat.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    nt.links.new(diffuse.outputs[0], nt.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    sphere.data.materials.append(mat)
    if floor:
        bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0.0, 0.0, -1.0))
        bpy.context.active_object.data.materials.append(mat)
    world = bpy.data.worlds.new("World")
    sc.world = world
    wt = world.node_tree
    for n in list(wt.nodes):
        wt.nodes.remove(n)
    return sc, wt


def _cycles_renders(sc, samples, runs):
    """(mean (H,W,3), within-pixel variance of it (a screen: Cycles gives none, so the
    between-run one), between-run variance of it)."""
    import tempfile
    bpy = _bpy()
    from ember.engine import imageio
    c = sc.cycles
    sc.render.engine = "CYCLES"
    c.device, c.samples, c.use_adaptive_sampling, c.use_denoising = "CPU", samples, False, False
    c.light_sampling_threshold, c.blur_glossy = 0.0, 0.0
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.use_animated_seed = False
    sc.render.film_transparent = False
    sc.render.use_compositing = sc.render.use_sequencer = False
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    sc.render.use_file_extension = False
    images = []
    with tempfile.TemporaryDirectory(prefix="ember_world_") as tmp:
        for k in range(runs):
            c.seed = 100 + k
            sc.render.filepath = f"{tmp}/run{k}.exr"
            bpy.ops.render.render(write_still=True)
            images.append(imageio.read_rgb(sc.render.filepath).astype(np.float64))
    images = np.stack(images)
    between = images.var(axis=0, ddof=1) / runs
    return images.mean(axis=0), between, between


def _ember_renders(samples, runs, **overrides):
    """(mean, within-pixel variance of it, between-run variance of it) of Ember's path tracer."""
    bpy = _bpy()
    from ember.engine.blender.export import export_scene
    means, within = [], []
    for k in range(runs):
        scene, _ = export_scene(bpy.context.evaluated_depsgraph_get(),
                                overrides=dict(samples=samples, seed=1 + k, integrator="path", threads=2, **overrides))
        session = RenderSession(scene)
        session.run()
        means.append(session.film.mean())
        within.append(session.film.variance_of_mean())
    means = np.stack(means)
    return means.mean(axis=0), np.mean(within, axis=0) / runs, means.var(axis=0, ddof=1) / runs


def compare(ember, cycles, name):
    """Failures (a list of str) of Ember's renders against Cycles' (see above)."""
    from scipy import stats as st
    from stats import sidak_alpha, z_test_images
    (e, e_within, e_honest), (c, c_within, c_honest) = ember, cycles
    failures = []
    accepted = z_test_images(e, e_within, c, c_within, alpha=0.01)
    if accepted < 0.99:
        failures.append(f"{name}: only {accepted:.2%} of pixels agree with Cycles")
    h, w = c.shape[:2]
    regions = {"image": (slice(None), slice(None))}
    for i, rows in enumerate((slice(0, h // 2), slice(h // 2, h))):
        for j, cols in enumerate((slice(0, w // 2), slice(w // 2, w))):
            regions[f"quadrant {'tb'[i]}{'lr'[j]}"] = (rows, cols)
    crit = st.norm.isf(sidak_alpha(0.01, len(regions)) / 2)
    for region, sl in regions.items():
        ref = c[sl].mean()
        se = np.sqrt(e_honest[sl].sum() + c_honest[sl].sum()) / c[sl].size / ref
        d = e[sl].mean() / ref - 1.0
        tol = TOL_IMAGE if region == "image" else TOL_REGION
        if abs(d) > tol + crit * se:
            failures.append(f"{name} {region}: {d:+.2%} (se {se:.2%})")
    return failures


def _link(nt, a, b):
    nt.links.new(a, b)


def world_sky(nt):
    """The Sky Texture as Blender adds it (Multiple Scattering, its sun disc on)."""
    sky = nt.nodes.new("ShaderNodeTexSky")
    bg = nt.nodes.new("ShaderNodeBackground")
    _link(nt, sky.outputs["Color"], bg.inputs["Color"])
    _link(nt, bg.outputs[0], nt.nodes.new("ShaderNodeOutputWorld").inputs["Surface"])


def world_mix(nt):
    """Mix Shader (0.35) of a Hosek / Wilkie sky and a constant blue background."""
    sky = nt.nodes.new("ShaderNodeTexSky")
    sky.sky_type = "HOSEK_WILKIE"
    sky.sun_direction = (0.3, 0.5, 0.8)
    a, b = nt.nodes.new("ShaderNodeBackground"), nt.nodes.new("ShaderNodeBackground")
    a.inputs["Strength"].default_value = 0.5
    b.inputs["Color"].default_value = (0.2, 0.3, 0.5, 1.0)
    _link(nt, sky.outputs["Color"], a.inputs["Color"])
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.35
    _link(nt, a.outputs[0], mix.inputs[1])
    _link(nt, b.outputs[0], mix.inputs[2])
    _link(nt, mix.outputs[0], nt.nodes.new("ShaderNodeOutputWorld").inputs["Surface"])


def world_environment(nt):
    """A float image (a smooth sky and a hot spot of 200) read with Linear interpolation in the
    direction turned and moved by a Mapping node (POINT: rotation and a Location)."""
    bpy = _bpy()
    h, w = 32, 64
    v = (np.arange(h) + 0.5) / h
    pixels = np.ones((h, w, 4), np.float32)
    pixels[..., :3] = (0.2 + 0.8 * v[:, None, None]) * np.array([0.4, 0.6, 1.0])
    pixels[22:25, 40:44, :3] = 200.0
    img = bpy.data.images.new("sky", w, h, float_buffer=True)
    img.pixels.foreach_set(pixels.ravel())
    img.pack()
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = img
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.2, 0.7)
    mapping.inputs["Location"].default_value = (0.2, 0.0, 0.1)
    _link(nt, nt.nodes.new("ShaderNodeTexCoord").outputs["Generated"], mapping.inputs["Vector"])
    _link(nt, mapping.outputs["Vector"], env.inputs["Vector"])
    bg = nt.nodes.new("ShaderNodeBackground")
    _link(nt, env.outputs["Color"], bg.inputs["Color"])
    _link(nt, bg.outputs[0], nt.nodes.new("ShaderNodeOutputWorld").inputs["Surface"])


def world_gradient(nt):
    """A procedural sky: Gradient Texture along z (Mapping turns it) through a Color Ramp."""
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, -np.pi / 2, 0.0)
    _link(nt, nt.nodes.new("ShaderNodeTexCoord").outputs["Generated"], mapping.inputs["Vector"])
    grad = nt.nodes.new("ShaderNodeTexGradient")
    _link(nt, mapping.outputs["Vector"], grad.inputs["Vector"])
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.05, 0.05, 0.1, 1.0)
    ramp.color_ramp.elements[1].color = (1.0, 0.8, 0.5, 1.0)
    _link(nt, grad.outputs["Fac"], ramp.inputs["Fac"])
    bg = nt.nodes.new("ShaderNodeBackground")
    bg.inputs["Strength"].default_value = 2.0
    _link(nt, ramp.outputs["Color"], bg.inputs["Color"])
    _link(nt, bg.outputs[0], nt.nodes.new("ShaderNodeOutputWorld").inputs["Surface"])


WORLDS = {"sky": (world_sky, 256), "mix": (world_mix, 128), "environment": (world_environment, 256),
          "gradient": (world_gradient, 128)}


@pytest.mark.blender
@pytest.mark.parametrize("name", list(WORLDS))
def test_worlds_match_cycles(name):
    build, samples = WORLDS[name]
    sc, wt = sphere_scene()
    build(wt)
    from ember.engine.blender.export import export_scene
    scene, warnings = export_scene(_bpy().context.evaluated_depsgraph_get())
    assert scene.world.graph and scene.world.image is None and not warnings, warnings
    cycles = _cycles_renders(sc, 4 * samples, CYCLES_RUNS)
    ember = _ember_renders(samples, EMBER_RUNS)
    failures = compare(ember, cycles, name)
    assert not failures, failures


def lights_scene():
    """The sphere on a floor, a black world, lit by a soft point light whose Emission colour is a
    Blackbody (3500 K) and an area light of Emission strength 3 and colour (1, 0.8, 0.6): both
    shaders fold to constants that multiply the lights' power."""
    bpy = _bpy()
    sc, wt = sphere_scene(floor=True)
    bg = wt.nodes.new("ShaderNodeBackground")
    bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    _link(wt, bg.outputs[0], wt.nodes.new("ShaderNodeOutputWorld").inputs["Surface"])

    def add(kind, name, location, rotation=(0.0, 0.0, 0.0), **props):
        light = bpy.data.lights.new(name, kind)
        for k, v in props.items():
            setattr(light, k, v)
        ob = bpy.data.objects.new(name, light)
        ob.location, ob.rotation_euler = location, rotation
        sc.collection.objects.link(ob)
        light.use_nodes = True
        return light

    point = add("POINT", "Point", (2.0, 2.0, 3.0), energy=400.0, shadow_soft_size=0.3)
    nt = point.node_tree
    black = nt.nodes.new("ShaderNodeBlackbody")
    black.inputs["Temperature"].default_value = 3500.0
    _link(nt, black.outputs["Color"], nt.nodes["Emission"].inputs["Color"])
    area = add("AREA", "Area", (1.5, -2.0, 2.5), (np.radians(50.0), 0.0, np.radians(35.0)), energy=60.0, size=1.0)
    emission = area.node_tree.nodes["Emission"]
    emission.inputs["Strength"].default_value = 3.0
    emission.inputs["Color"].default_value = (1.0, 0.8, 0.6, 1.0)
    return sc


@pytest.mark.blender
def test_lights_match_cycles(monkeypatch):
    """The lights' shaders fold to the constants Cycles multiplies into their strength; the
    mutations - the node strength dropped, or 4 % off - must fail the same comparison."""
    sc = lights_scene()
    from ember.engine.blender import export_light
    from ember.engine.blender.export import export_scene
    scene, warnings = export_scene(_bpy().context.evaluated_depsgraph_get())
    assert not scene.lights.graphs and not warnings, warnings
    cycles = _cycles_renders(sc, 512, CYCLES_RUNS)
    ember = _ember_renders(128, EMBER_RUNS)
    failures = compare(ember, cycles, "lights")
    assert not failures, failures
    shader = export_light.light_shader
    for label, wrong in (("strength dropped", lambda f: f / np.max(f)), ("4 % off", lambda f: 1.04 * f)):
        monkeypatch.setattr(export_light, "light_shader", lambda light, warn, wrong=wrong: (
            wrong(shader(light, warn)[0]), None))
        assert compare(_ember_renders(128, EMBER_RUNS), cycles, label), f"the mutation '{label}' went unnoticed"
    monkeypatch.setattr(export_light, "light_shader", shader)


IES_PROFILE = """IESNA:LM-63-2002
[TEST] a downlight brighter toward one side (type C, two quadrants given)
TILT=NONE
1 1000 1.0 7 3 1 2 0.1 0.1 0.1
1.0 1.0 100
0 30 60 90 120 150 180
0 90 180
1000 900 600 300 100 20 0
1000 950 800 450 150 30 0
1000 700 300 100 40 10 0
"""


def varying_lights_scene():
    """The sphere on its floor under a black world, lit by a soft point light turned by its
    object whose Emission strength is an IES Texture's Fac, and a sun-less area light whose
    strength goes through Light Falloff (Linear): shaders that vary over the light, evaluated
    per light sample and hit."""
    bpy = _bpy()
    sc = lights_scene()
    for ob in list(sc.collection.objects):
        if ob.type == "LIGHT":
            bpy.data.objects.remove(ob)
    light = bpy.data.lights.new("IES", "POINT")
    light.energy, light.shadow_soft_size, light.use_nodes = 8.0, 0.2, True
    ob = bpy.data.objects.new("IES", light)
    ob.location, ob.rotation_euler = (0.8, 0.5, 3.0), (0.35, 0.0, 0.6)
    sc.collection.objects.link(ob)
    nt = light.node_tree
    tex = nt.nodes.new("ShaderNodeTexIES")
    tex.mode = "INTERNAL"
    tex.ies = bpy.data.texts.new("profile.ies")
    tex.ies.write(IES_PROFILE)
    _link(nt, tex.outputs["Fac"], nt.nodes["Emission"].inputs["Strength"])
    area = bpy.data.lights.new("Falloff", "AREA")
    area.energy, area.size, area.use_nodes = 40.0, 1.0, True
    ob = bpy.data.objects.new("Falloff", area)
    ob.location, ob.rotation_euler = (1.5, -2.0, 2.5), (np.radians(50.0), 0.0, np.radians(35.0))
    sc.collection.objects.link(ob)
    falloff = area.node_tree.nodes.new("ShaderNodeLightFalloff")
    falloff.inputs["Strength"].default_value = 0.5
    _link(area.node_tree, falloff.outputs["Linear"], area.node_tree.nodes["Emission"].inputs["Strength"])
    return sc


@pytest.mark.blender
def test_varying_light_shaders_match_cycles():
    sc = varying_lights_scene()
    from ember.engine.blender.export import export_scene
    scene, warnings = export_scene(_bpy().context.evaluated_depsgraph_get())
    assert sum(g is not None for g in scene.lights.graphs) == 2
    assert all("varies over the light" in t for t in warnings), warnings
    cycles = _cycles_renders(sc, 512, CYCLES_RUNS)
    ember = _ember_renders(128, EMBER_RUNS)
    failures = compare(ember, cycles, "varying lights")
    assert not failures, failures


@pytest.mark.blender
def test_light_shaders_fold_as_cycles_multiplies_them():
    """Le of a light = Cycles' strength x eval_fac x the shader's constant emission: a
    Blackbody colour and an Emission strength fold exactly; use_nodes off is an emission of 1;
    a tree without a Light Output emits nothing (Cycles renders it black); an IES Texture
    varies and keeps its graph, its file read from the Text."""
    bpy = _bpy()
    lights_scene()
    from ember.engine.blender import export_light
    from ember.engine.nodes.color import blackbody_rec709
    point = bpy.data.objects["Point"]
    base = np.array(point.data.color) * point.data.energy / (np.pi * 4.0 * np.pi * 0.3**2)  # normalized sphere
    warnings = []
    row = export_light.export_light(point, point.matrix_world, warnings.append)
    np.testing.assert_allclose(row["Le"], base * np.maximum(blackbody_rec709(3500.0), 0.0), rtol=1e-6)
    assert "graph" not in row and not warnings
    area = bpy.data.objects["Area"]
    factor, graph = export_light.light_shader(area.data, warnings.append)
    np.testing.assert_allclose(factor, [3.0, 2.4, 1.8], rtol=1e-6)
    point.data.use_nodes = False
    np.testing.assert_array_equal(export_light.light_shader(point.data, warnings.append)[0], np.ones(3))
    point.data.use_nodes = True
    nt = point.data.node_tree
    nt.nodes.remove(nt.nodes["Light Output"])
    assert export_light.export_light(point, point.matrix_world, warnings.append) is None
    assert warnings and "Light Output" in warnings[-1]
    varying_lights_scene()
    ies_light = bpy.data.objects["IES"]
    factor, graph = export_light.light_shader(ies_light.data, warnings.append)
    ies_node = next(n for n in graph.nodes if n.kind == "ShaderNodeTexIES")
    assert ies_node.prop("ies") == IES_PROFILE and np.all(factor == 1.0)


# ---- IES profiles ------------------------------------------------------------------------------

def test_ies_profile_is_processed_as_cycles_does():
    """Type C from two quadrants mirrored to the full turn (360 degrees = 0), the candela
    scaled by multiplier x ballast factors x 4 pi / 177.83; the table interpolates its own
    values at its angles; TILT=INCLUDE and commas are read; type A or nothing: 100 (Cycles'
    missing profile)."""
    from ember.engine.nodes import ies
    h, v, table = ies.profile(IES_PROFILE)
    np.testing.assert_allclose(np.degrees(h), [0, 90, 180, 270, 360], atol=1e-5)
    np.testing.assert_allclose(np.degrees(v), [0, 30, 60, 90, 120, 150, 180], atol=1e-5)
    np.testing.assert_allclose(table[3], table[1])  # 270 mirrors 90
    np.testing.assert_allclose(table[4], table[0])
    np.testing.assert_allclose(table[1, 2], 800 * ies.CANDELA_TO_WATT, rtol=1e-6)
    hh, vv = np.meshgrid(h[:-1], v[:-1], indexing="ij")
    np.testing.assert_allclose(ies.interpolate((h, v, table), hh.ravel(), vv.ravel()), table[:-1, :-1].ravel(),
                               rtol=1e-6)
    tilted = IES_PROFILE.replace("TILT=NONE\n", "TILT=INCLUDE\n1\n2\n0, 90\n1, 1\n").replace("0 90 180\n", "0,90,180\n")
    np.testing.assert_array_equal(ies.profile(tilted)[2], table)
    type_a = IES_PROFILE.replace("1 1000 1.0 7 3 1 2", "1 1000 1.0 7 3 3 2")
    assert ies.profile(type_a) is None and ies.profile("") is None


def test_ies_texture_reads_the_light_frame_normal():
    """Unlinked, the Vector is N in object space: straight down the object's -z reads v = 0;
    turning the object turns the profile."""
    from ember.engine.nodes import ies
    node = _node("ShaderNodeTexIES", "IES", [Input("Vector", "vector", (0.0, 0.0, 0.0)),
                                             Input("Strength", "value", 2.0)], [("Fac", "value")],
                 ies=IES_PROFILE, mode="INTERNAL")
    down = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    state = ShadingStateFor(N=down, world_from_object=np.broadcast_to(np.eye(4), (2, 4, 4)))
    fac = registry.REGISTRY["ShaderNodeTexIES"].run(node, {"Vector": np.zeros(3), "Strength": np.float64(2.0)},
                                                    state, ("Fac",))["Fac"]
    h, v, table = ies.profile(IES_PROFILE)
    np.testing.assert_allclose(fac[0], 2.0 * table[0, 0], rtol=1e-6)
    # +y in object space: h = atan2(0, 1) + pi (180 degrees), v = 90 degrees.
    np.testing.assert_allclose(fac[1], 2.0 * table[2, 3], rtol=1e-6)
    turn = np.eye(4)
    turn[:3, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]  # 90 degrees about z
    state = ShadingStateFor(N=down, world_from_object=np.broadcast_to(turn, (2, 4, 4)))
    turned = registry.REGISTRY["ShaderNodeTexIES"].run(node, {"Vector": np.zeros(3), "Strength": np.float64(2.0)},
                                                       state, ("Fac",))["Fac"]
    np.testing.assert_allclose(turned[1], 2.0 * table[3, 3], rtol=1e-6)  # world y is object +x: 270 degrees


def ShadingStateFor(**fields):
    n = len(next(iter(fields.values())))
    return state_mod.ShadingState(n, **fields)
