"""Nodes that trace rays (engine/nodes/rays.py), without Blender: Ambient Occlusion at points
of a floor beside a wall against its analytic value, Bevel beside a box's edge (it turns the
normal toward the edge, for sharp paths only), and a material using both rendered the same
whatever the batches and workers.

AO beside a wall: a point on a floor (normal +z) at distance h from a wall (x = h, high and wide
enough to catch every ray shorter than the AO distance D). Cosine-distributed directions project
to points uniform on the unit disk (Malley), and a direction meets the wall within D where its
x component exceeds h / D: the occluded share is the disk's segment beyond a = h / D,
(acos a - a sqrt(1 - a^2)) / pi. Inside turns the rays under the floor, where a wall below it
plays the same part; Only Local counts the wall only when it is part of the floor's object.
Each estimate is a mean over many points (independent numbers per point: each its own pixel),
tested by a z-test on its standard error; a 3 % error is many standard errors."""
import numpy as np
import pytest

from ember.engine.accel import Accel
from ember.engine.nodes import light_path
from ember.engine.nodes.graph import Graph, Input, Link, Node
from ember.engine.nodes.hits import RayState, SurfaceHits
from ember.engine.nodes.program import compile
from ember.engine.nodes.rays import SceneRays, ShaderRays
from ember.engine.rng import Sampler
from ember.engine.scene import LOBE_MICROFACET, MAT_DIFFUSE, Camera, Lights, Materials, Mesh, Scene, World

from core_scenes import box_quads, quads_mesh, settings

POINTS = 20000
Z = 4.5  # standard errors allowed: a few tests, each far from failing by chance
H = 0.3


def _occluded_share(a: float) -> float:
    return (np.arccos(a) - a * np.sqrt(1.0 - a * a)) / np.pi


def _wall_scene(below: bool, one_object: bool, distance: float):
    """A floor (z = 0, x, y in [-4, 4]) and a wall at x = H spanning what rays of length
    `distance` can reach, above the floor or below it; the floor is object 0, the wall object 1
    or (one_object) part of object 0."""
    r = distance + 1.0
    z0, z1 = (-r, 0.0) if below else (0.0, r)
    floor = [[-4, -4, 0], [4, -4, 0], [4, 4, 0], [-4, 4, 0]]
    wall = [[H, -r, z0], [H, r, z0], [H, r, z1], [H, -r, z1]]
    mesh = quads_mesh([floor, wall], [0, 0])
    objects = np.array([0, 4]) if one_object else np.array([0, 2, 4])
    eye = np.eye(4)[None].repeat(len(objects) - 1, axis=0)
    mesh = Mesh(mesh.vertices, mesh.triangles, mesh.normals, mesh.material, objects=objects, object_matrix=eye,
                object_texspace=np.tile([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]], (len(objects) - 1, 1, 1)))
    mats = Materials.make([dict()])
    cam = Camera(world_from_camera=np.eye(4), window=np.array([-1.0, 1.0, -1.0, 1.0]))
    return Scene(mesh, mats, Lights.make([]), World(), cam, settings())


def _floor_hits(scene, seed: int = 7) -> SurfaceHits:
    """POINTS hits on the floor along the line x = 0, y in [-1, 1] (the wall is the same
    everywhere along it), each with the numbers of its own pixel."""
    n = POINTS
    y = np.linspace(-1.0, 1.0, n)
    p = np.stack([np.zeros(n), y, np.zeros(n)], axis=1)
    up = np.tile([0.0, 0.0, 1.0], (n, 1))
    prim = np.where(y < 0.0, 0, 1).astype(np.int64)  # the floor's two triangles split along its diagonal
    accel = Accel(scene.mesh)
    sampler = Sampler(seed, np.arange(n), np.zeros(n, np.int64))
    rays = ShaderRays(SceneRays(accel, accel, scene.mesh), prim, sampler, np.arange(n), 0)
    bary = np.full((n, 3), 1.0 / 3.0)
    return SurfaceHits(scene, prim, bary, p, up, up, up, ray=RayState(light_path.CAMERA, rays=rays))


def _ao_graph(distance: float, samples: int, inside=False, only_local=False, normal=None):
    props = tuple(sorted(dict(samples=samples, inside=inside, only_local=only_local).items()))
    inputs = (Input("Color", "rgba", (0.5, 0.8, 1.0)), Input("Distance", "value", distance),
              Input("Normal", "vector", (0.0, 0.0, 0.0)))
    nodes = [Node("ShaderNodeAmbientOcclusion", "AO", props, inputs, (("Color", "rgba"), ("AO", "value")))]
    if normal is not None:  # a linked Normal: a constant vector through a Normal node's output
        nodes.insert(0, Node("ShaderNodeCombineXYZ", "N", (), tuple(Input(c, "value", v) for c, v in zip("XYZ", normal)),
                             (("Vector", "vector"),)))
        ao = nodes[1]
        nodes[1] = Node(ao.kind, ao.label, ao.props, ao.inputs[:2] + (Input("Normal", "vector", (0.0, 0.0, 0.0),
                                                                            Link(0, "Vector", "vector")),), ao.outputs)
    k = len(nodes) - 1
    outputs = (("ao", Input("ao", "value", 0.0, Link(k, "AO", "value"))),
               ("color", Input("color", "rgba", (0.0, 0.0, 0.0), Link(k, "Color", "rgba"))))
    return Graph(tuple(nodes), outputs)


def _ao(graph, hits):
    out = compile(graph, {"ao": "value", "color": "rgba"}).run(hits.state())
    return np.broadcast_to(out["ao"], (hits.state().n,)), out["color"]


def _z(values, expected):
    se = values.std(ddof=1) / np.sqrt(len(values))
    return (values.mean() - expected) / max(se, 1e-12)


@pytest.mark.parametrize("below, inside", [(False, False), (True, True)])
def test_ambient_occlusion_beside_a_wall_is_the_disk_segment(below, inside):
    distance, samples = 1.0, 4
    scene = _wall_scene(below, one_object=False, distance=distance)
    ao, color = _ao(_ao_graph(distance, samples, inside=inside), _floor_hits(scene))
    expected = 1.0 - _occluded_share(H / distance)
    assert abs(_z(ao, expected)) < Z, (ao.mean(), expected)
    assert abs(_z(ao, 0.97 * expected)) > Z  # power: a 3 % error is seen
    np.testing.assert_allclose(color, ao[:, None] * np.array([0.5, 0.8, 1.0]))
    # Each point's estimate is a share of its samples.
    assert set(np.unique(ao * samples)) <= set(range(samples + 1))


def test_ambient_occlusion_reads_its_distance():
    """A shorter distance meets less of the wall; one beyond the wall's distance none of it."""
    scene = _wall_scene(False, one_object=False, distance=2.0)
    hits = _floor_hits(scene)
    for distance in (0.5, 2.0):
        ao, _ = _ao(_ao_graph(distance, 2), hits)
        assert abs(_z(ao, 1.0 - _occluded_share(H / distance))) < Z
    for distance in (0.25, 0.0, -1.0):  # no ray reaches the wall; none traced at all
        assert np.all(_ao(_ao_graph(distance, 2), hits)[0] == 1.0)


def test_ambient_occlusion_rays_leave_the_other_side_only_inside():
    """The wall below the floor occludes only rays sent inside; the wall above only rays sent
    outside."""
    scene = _wall_scene(True, one_object=False, distance=1.0)
    assert np.all(_ao(_ao_graph(1.0, 4, inside=False), _floor_hits(scene))[0] == 1.0)
    scene = _wall_scene(False, one_object=False, distance=1.0)
    assert np.all(_ao(_ao_graph(1.0, 4, inside=True), _floor_hits(scene))[0] == 1.0)


def test_ambient_occlusion_only_local_sees_its_own_object():
    expected = 1.0 - _occluded_share(H)
    other = _wall_scene(False, one_object=False, distance=1.0)
    assert np.all(_ao(_ao_graph(1.0, 4, only_local=True), _floor_hits(other))[0] == 1.0)
    own = _wall_scene(False, one_object=True, distance=1.0)
    ao, _ = _ao(_ao_graph(1.0, 4, only_local=True), _floor_hits(own))
    assert abs(_z(ao, expected)) < Z


def test_ambient_occlusion_about_a_linked_normal():
    """A Normal input tilted away from the wall (1 radian toward -x): the rays meet the wall
    where they go toward it (x > H / D) above the floor (the wall stands on it); the floor lets
    the rays below it through, as Cycles' own-triangle skip does. The expected share comes from
    a million directions of the tilted cosine lobe."""
    scene = _wall_scene(False, one_object=False, distance=1.0)
    tilt = np.array([-np.sin(1.0), 0.0, np.cos(1.0)])
    ao = _ao(_ao_graph(1.0, 4, normal=tuple(tilt)), _floor_hits(scene))[0]
    rng = np.random.default_rng(1)
    r, phi = np.sqrt(rng.random(10 ** 6)), 2.0 * np.pi * rng.random(10 ** 6)
    local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1.0 - r * r)], axis=1)
    t = np.array([np.cos(1.0), 0.0, np.sin(1.0)])  # tilt, t and y: a right-handed frame
    d = local[:, :1] * t + local[:, 1:2] * np.array([0.0, 1.0, 0.0]) + local[:, 2:] * tilt
    expected = 1.0 - np.mean((d[:, 0] > H) & (d[:, 2] >= 0.0))
    assert abs(_z(ao, expected)) < Z, (ao.mean(), expected)
    assert abs(_z(ao, 1.0 - _occluded_share(H))) > Z  # not the normal's


def test_ambient_occlusion_is_reproducible_and_seeded():
    scene = _wall_scene(False, one_object=False, distance=1.0)
    a = _ao(_ao_graph(1.0, 4), _floor_hits(scene, seed=3))[0]
    b = _ao(_ao_graph(1.0, 4), _floor_hits(scene, seed=3))[0]
    c = _ao(_ao_graph(1.0, 4), _floor_hits(scene, seed=4))[0]
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_ambient_occlusion_without_ray_queries_is_one():
    """Where the renderer gives no ray queries (a bake, a world shader), Cycles' answer: 1."""
    scene = _wall_scene(False, one_object=False, distance=1.0)
    hits = _floor_hits(scene)
    plain = SurfaceHits(scene, hits.prim, hits.bary, hits.P(), hits.N(), hits.Ng(), hits.I())
    assert np.all(_ao(_ao_graph(1.0, 4), plain)[0] == 1.0)


def _traced_material_graph():
    """A Diffuse BSDF whose colour is an AO's Color and whose normal is a Bevel's."""
    ao = Node("ShaderNodeAmbientOcclusion", "AO", (("inside", False), ("only_local", False), ("samples", 3)),
              (Input("Color", "rgba", (0.8, 0.7, 0.6)), Input("Distance", "value", 0.8),
               Input("Normal", "vector", (0.0, 0.0, 0.0))), (("Color", "rgba"), ("AO", "value")))
    bevel = Node("ShaderNodeBevel", "Bevel", (("samples", 2),),
                 (Input("Radius", "value", 0.2), Input("Normal", "vector", (0.0, 0.0, 0.0))), (("Normal", "vector"),))
    diffuse = Node("ShaderNodeBsdfDiffuse", "Diffuse", (),
                   (Input("Color", "rgba", (0.8, 0.8, 0.8), Link(0, "Color", "rgba")), Input("Roughness", "value", 0.0),
                    Input("Normal", "vector", (0.0, 0.0, 0.0), Link(1, "Normal", "vector"))), (("BSDF", "shader"),))
    return Graph((ao, bevel, diffuse), (("surface", Input("Surface", "shader", 0.0, Link(2, "BSDF", "shader"))),))


def test_traced_nodes_render_the_same_whatever_the_batches():
    """Rays traced from inside shaders draw each path's own numbers: batch sizes and worker
    processes do not change the image, bit for bit; and the nodes do darken and bend it."""
    from ember.engine.nodes.material import compile_material
    from ember.engine.session import RenderSession
    from test_batch_independence import open_box

    scene = open_box(diffuse_bounces=2, samples=4)
    graph = _traced_material_graph()
    mp = compile_material(graph)
    rows = [dict(kind=MAT_DIFFUSE, base_color=(0.8, 0.8, 0.8), lobes=mp.lobes, graph=graph, reads=mp.reads)]
    rows += [dict(kind=MAT_DIFFUSE, base_color=(0.7, 0.2, 0.2)),
             dict(lobes=[dict(kind=LOBE_MICROFACET, roughness=0.3, color=(0.9,) * 3)])]
    rest = [dict(kind=MAT_DIFFUSE, base_color=(0.5,) * 3)] * 4
    traced = scene.replace(materials=Materials.make(rows + rest))
    plain = scene.replace(materials=Materials.make([dict(kind=MAT_DIFFUSE, base_color=(0.8, 0.7, 0.6))] + rows[1:] + rest))

    def image(s, **kw):
        session = RenderSession(s.replace(settings=s.settings.replace(**kw)))
        session.run()
        return session.film.mean()

    first = image(traced)
    for kw in (dict(batch_size=56), dict(batch_size=4096), dict(threads=2)):
        assert np.array_equal(first, image(traced, **kw)), kw
    assert first.mean() < 0.97 * image(plain).mean()  # unoccluded, the AO's colour itself


def test_bevel_only_for_sharp_paths():
    """Bevel at points beside a box's edge turns the normal toward the side face on a camera
    ray's hit (min_ray_pdf infinite), and leaves N for a path whose smallest BSDF pdf so far is
    below 8 (a diffuse bounce: Cycles' blurry indirect rays) or with a zero radius."""
    mesh = quads_mesh(box_quads((-0.5, -0.5, -0.5), (0.5, 0.5, 0.5)), [0] * 6)
    scene = Scene(mesh, Materials.make([dict()]), Lights.make([]), World(),
                  Camera(world_from_camera=np.eye(4), window=np.array([-1.0, 1.0, -1.0, 1.0])), settings())
    n = 4000
    x = np.linspace(0.42, 0.49, n)  # on the top face, within the radius of the +x edge
    p = np.stack([x, np.zeros(n), np.full(n, 0.5)], axis=1)
    up = np.tile([0.0, 0.0, 1.0], (n, 1))
    prim = np.full(n, 2, np.int64)  # the top face's first triangle (below its diagonal y = x)
    accel = Accel(mesh)
    rays = ShaderRays(SceneRays(accel, accel, mesh), prim, Sampler(1, np.arange(n), np.zeros(n, np.int64)),
                      np.arange(n), 0)

    def bevel(radius, min_ray_pdf):
        node = Node("ShaderNodeBevel", "Bevel", (("samples", 4),),
                    (Input("Radius", "value", radius), Input("Normal", "vector", (0.0, 0.0, 0.0))),
                    (("Normal", "vector"),))
        graph = Graph((node,), (("n", Input("n", "vector", (0.0, 0.0, 0.0), Link(0, "Normal", "vector"))),))
        ray = RayState(light_path.CAMERA, min_ray_pdf=min_ray_pdf, rays=rays)
        hits = SurfaceHits(scene, prim, np.full((n, 3), 1.0 / 3.0), p, up, up, up, ray=ray)
        return np.broadcast_to(compile(graph, {"n": "vector"}).run(hits.state())["n"], (n, 3))

    sharp = bevel(0.1, np.inf)
    assert sharp[:, 0].mean() > 0.05 and np.all(sharp[:, 0] >= -1e-12)  # toward +x, never away
    assert np.allclose(np.linalg.norm(sharp, axis=1), 1.0)
    assert np.array_equal(bevel(0.1, 1.0), up) and np.array_equal(bevel(0.0, np.inf), up)
    assert not np.array_equal(bevel(0.1, 8.0), up)  # 8 itself still bevels
