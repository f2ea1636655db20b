"""Ray-query robustness (algorithms.md section 2, hard case 1; pbrt-v4 Triangle.Reintersect)."""
import numpy as np
import pytest

from ember.engine.accel import Accel, offset_origin
from ember.engine.scene import Mesh


def _soup(tris):
    tris = np.asarray(tris, np.float64)
    v = tris.reshape(-1, 3).astype(np.float32)
    t = np.arange(len(v), dtype=np.int32).reshape(-1, 3)
    n = np.zeros((len(t), 3, 3), np.float32)
    return Mesh(v, t, n, np.zeros(len(t), np.int32))


def _random_dirs(rng, n):
    d = rng.normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_spawned_rays_never_rehit_their_triangle():
    """1000 random triangles with log-uniform coordinates in [1e-4, 1e4] x random sign; from
    a random point on each, 200 random directions leaving the side they point to must not
    hit the triangle they leave (0 self-hits allowed), with the self-primitive skip the
    integrator uses."""
    rng = np.random.default_rng(7)
    self_hits = 0
    for _ in range(1000 // 50):
        scale = 10.0 ** rng.uniform(-4, 4, size=(50, 1, 1))
        tris = (rng.uniform(-1, 1, size=(50, 3, 3)) * scale) + rng.uniform(-1, 1, (50, 1, 3)) * scale * 10.0 ** rng.uniform(-1, 1, (50, 1, 1))
        accel = Accel(_soup(tris))
        k = 200
        prim = np.repeat(np.arange(50), k)
        u = rng.random((50 * k, 2))
        su = np.sqrt(u[:, 0])
        b1, b2 = su * (1 - u[:, 1]), su * u[:, 1]
        p = accel.v0[prim] + b1[:, None] * accel.e1[prim] + b2[:, None] * accel.e2[prim]
        d = _random_dirs(rng, len(prim))
        side = np.sign(np.einsum("ij,ij->i", d, accel.ng[prim]))[:, None]
        ok = accel.area[prim] > 0
        o = offset_origin(p, accel.ng[prim] * side)
        hit = accel.intersect(o[ok], d[ok], skip_prim=prim[ok])
        self_hits += int(np.sum(hit.prim == prim[ok]))
    assert self_hits == 0


def test_rays_leaving_a_mesh_never_hit_its_coplanar_neighbours():
    """A finely triangulated plane (shared edges, fan vertices) far from and near the origin:
    rays leaving points on it - many right on the shared edges - never hit the plane again."""
    rng = np.random.default_rng(5)
    for offset in (0.0, 1e2, 1e4):
        n = 40
        g = np.linspace(-1, 1, n + 1)
        X, Y = np.meshgrid(g, g)
        v = np.stack([X, Y, np.zeros_like(X)], -1).reshape(-1, 3) * 3.0 + offset
        i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
        a, b, c, d_ = i, i + 1, i + n + 2, i + n + 1
        tris = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d_], -1).reshape(-1, 3)])
        mesh = Mesh(v.astype(np.float32), tris.astype(np.int32), np.zeros((len(tris), 3, 3), np.float32),
                    np.zeros(len(tris), np.int32))
        accel = Accel(mesh)
        k = 200_000
        prim = rng.integers(0, len(tris), k)
        u = rng.random((k, 2))
        u[: k // 2, 1] = 0.0  # half the points exactly on an edge of their triangle
        su = np.sqrt(u[:, 0])
        b1, b2 = su * (1 - u[:, 1]), su * u[:, 1]
        p = accel.v0[prim] + b1[:, None] * accel.e1[prim] + b2[:, None] * accel.e2[prim]
        d = _random_dirs(rng, k)
        up = np.sign(d[:, 2])[:, None] * np.array([0, 0, 1.0])
        hit = accel.intersect(offset_origin(p, up), d, skip_prim=prim)
        assert np.sum(hit.prim >= 0) == 0, offset


def test_shadow_rays_stop_short_of_the_target_surface():
    """Shadow rays from a floor to points on a parallel quad above never report the quad itself."""
    quad = [[[-1, -1, 1], [1, -1, 1], [1, 1, 1]], [[-1, -1, 1], [1, 1, 1], [-1, 1, 1]]]
    floor = [[[-5, -5, 0], [5, -5, 0], [5, 5, 0]], [[-5, -5, 0], [5, 5, 0], [-5, 5, 0]]]
    accel = Accel(_soup(quad + floor))
    rng = np.random.default_rng(1)
    n = 20000
    p = np.column_stack([rng.uniform(-4, 4, n), rng.uniform(-4, 4, n), np.zeros(n)])
    target = np.column_stack([rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), np.ones(n)])
    blocked = accel.occluded(offset_origin(p, np.tile([0, 0, 1.0], (n, 1))), target=target)
    assert blocked.sum() == 0


def test_far_from_origin_gives_same_hits():
    """A scene translated by 1e4 returns the same primitives and distances (to float32 precision)."""
    rng = np.random.default_rng(3)
    tris = rng.uniform(-1, 1, size=(200, 3, 3))
    n = 5000
    o = rng.uniform(-3, 3, size=(n, 3))
    d = _random_dirs(rng, n)
    a = Accel(_soup(tris)).intersect(o.astype(np.float32), d)
    shift = np.array([1e4, -1e4, 1e4])
    b = Accel(_soup(tris + shift)).intersect((o + shift).astype(np.float32), d)
    agree = (a.prim == b.prim)
    # float32 spacing at 1e4 is ~1e-3: only rays grazing an edge may change primitive.
    assert agree.mean() > 0.995
    both = agree & (a.prim >= 0)
    assert np.max(np.abs(a.t[both] - b.t[both])) < 1e-2


def test_degenerate_triangles_give_no_nan():
    tris = [[[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 0, 0], [0, 0, 0], [0, 0, 0]], [[0, 0, 0], [1, 0, 0], [0, 1, 0]]]
    accel = Accel(_soup(tris))
    assert np.all(np.isfinite(accel.ng)) and accel.area[0] == 0 and accel.area[1] == 0
    n = 1000
    o = np.column_stack([np.random.default_rng(0).uniform(0, 1, (n, 2)) * 0.5, np.ones(n)])
    hit = accel.intersect(o.astype(np.float32), np.tile([0, 0, -1.0], (n, 1)))
    assert np.all(hit.prim == 2) and np.all(np.isfinite(hit.p))


def test_empty_scene_misses_everything():
    accel = Accel(Mesh.empty())
    hit = accel.intersect(np.zeros((4, 3), np.float32), np.tile([0, 0, 1.0], (4, 1)))
    assert np.all(hit.prim == -1) and not accel.occluded(np.zeros((4, 3)), target=np.ones((4, 3))).any()


def test_freed_numpy_memory_stays_in_the_heap():
    """glibc accepts the thresholds that keep batch temporaries out of mmap (Linux CI)."""
    import sys
    from ember.engine.allocator import keep_freed_memory
    if not sys.platform.startswith("linux"):
        pytest.skip("glibc only")
    assert keep_freed_memory() is True


def test_a_ray_leaving_its_triangle_from_the_surface_finds_what_lies_beyond():
    """An origin exactly on its triangle (no offset, as photons leaving an emissive triangle)
    first re-hits it at t = 0; the re-trace must still find the wall 2 m away. (Embree writes
    hit distances into the tfar array it is given: the re-trace once read t = 0 from it as its
    range and lost every such ray.)"""
    quads = np.array([[(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)],
                      [(-1, -1, 2), (1, -1, 2), (1, 1, 2), (-1, 1, 2)]], float)
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    accel = Accel(_soup(tris))
    rng = np.random.default_rng(3)
    n = 1000
    p = np.column_stack([rng.uniform(-0.5, 0.5, n), rng.uniform(-0.5, 0.5, n), np.zeros(n)])
    prim = np.where(p[:, 1] < p[:, 0], 0, 2)  # which of the floor's two triangles holds p
    d = np.tile([0.0, 0.0, 1.0], (n, 1))
    hit = accel.intersect(p.astype(np.float32), d, skip_prim=prim)
    assert np.all(hit.prim >= 0) and np.allclose(hit.t, 2.0, atol=1e-5)


def test_subset_view_skips_hidden_triangles_and_reports_full_indices():
    """Accel.subset (ray visibility): a ray passes through the triangles the view leaves out,
    hits report their index in the full mesh, shadow rays too, and rays and Embree time are
    counted on the full Accel."""
    quads = [[(-1, -1, z), (1, -1, z), (1, 1, z), (-1, 1, z)] for z in (1.0, 2.0, 3.0)]
    v = np.array(quads, np.float32).reshape(-1, 3)
    t = np.array([[4 * q, 4 * q + 1, 4 * q + 2] for q in range(3)] + [[4 * q, 4 * q + 2, 4 * q + 3] for q in range(3)],
                 np.int32)
    mesh = Mesh(v, t, np.zeros((6, 3, 3), np.float32), np.zeros(6, np.int32))
    full = Accel(mesh)
    view = full.subset(np.array([1, 4]), mesh)  # the quad at z = 2 only
    o = np.zeros((2, 3), np.float32)
    d = np.array([[0.1, 0.2, 1.0], [-0.3, -0.1, 1.0]])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    assert set(full.intersect(o, d).prim.tolist()) <= {0, 3}
    hit = view.intersect(o, d)
    assert set(hit.prim.tolist()) <= {1, 4}
    np.testing.assert_allclose(hit.p[:, 2], 2.0, atol=1e-6)
    assert view.occluded(o, np.array([[0.0, 0.0, 1.5], [0.0, 0.0, 2.5]])).tolist() == [False, True]
    empty = full.subset(np.array([], np.int64), mesh)
    assert (empty.intersect(o, d).prim == -1).all()
    assert full.rays >= 6  # the views' rays are counted here


def _objects(rng, sizes, shift=None):
    """A soup of objects (random triangles in a unit cube each, objects side by side along x;
    `shift` moves object i by shift[i]) with Mesh.objects set."""
    tris = []
    for i, n in enumerate(sizes):
        t = rng.uniform(0, 1, (n, 3, 3)) + [1.5 * i, 0, 0]
        if shift is not None:
            t = t + shift[i]
        tris.append(t)
    mesh = _soup(np.concatenate(tris))
    import dataclasses
    return dataclasses.replace(mesh, objects=np.cumsum([0] + list(sizes)))


def test_big_objects_get_scenes_of_their_own_kept_when_others_move(monkeypatch):
    """With split (persistent data), an object of BLOCK_MIN triangles or more is an Embree
    scene of its own: closest hits, occlusion and the per-triangle rows equal one scene over
    everything; moving another object rebuilds only that object's block, and the result
    equals a fresh build of the moved scene."""
    from ember.engine import accel as accel_mod

    monkeypatch.setattr(accel_mod, "BLOCK_MIN", 300)
    rng = np.random.default_rng(3)
    sizes = [40, 400, 30, 350]
    mesh = _objects(rng, sizes)
    assert accel_mod.blocks(mesh) == [(0, 40), (40, 440), (440, 470), (470, 820)]
    o = rng.uniform([-1, -1, -1], [7, 2, 2], (4000, 3))
    d = _random_dirs(rng, 4000)
    target = rng.uniform([-1, -1, -1], [7, 2, 2], (4000, 3))

    def same(a, b):
        ha, hb = a.intersect(o.astype(np.float32), d), b.intersect(o.astype(np.float32), d)
        assert (ha.prim >= 0).sum() > 300
        np.testing.assert_array_equal(ha.prim, hb.prim)
        np.testing.assert_array_equal(ha.p, hb.p)
        np.testing.assert_array_equal(a.occluded(o, target), b.occluded(o, target))
        np.testing.assert_array_equal(a.rows, b.rows)

    built = accel_mod.BUILT[0]
    split = Accel(mesh, split=True)
    assert accel_mod.BUILT[0] - built == 4
    same(split, Accel(mesh))
    moved = _objects(np.random.default_rng(3), sizes, shift=[[0, 0, 0], [0, 0, 0], [0, 0.3, 0], [0, 0, 0]])
    built = accel_mod.BUILT[0]
    again = Accel(moved, split, split=True)
    assert accel_mod.BUILT[0] - built == 1  # the moved small object's block only
    same(again, Accel(moved, split=True))
    same(again, Accel(moved))


def test_hits_kept_before_their_points_are_built_equal_the_kept_rows():
    """Hit.take (the path tracer drops escaped rays first) gives bit for bit the rows of the
    full-width points, barycentrics and normals, which are rebuilt per row from the triangle."""
    rng = np.random.default_rng(8)
    tris = rng.uniform(-1, 1, size=(200, 3, 3)) + 1e4
    o = (rng.uniform(-0.5, 0.5, size=(4000, 3)) + 1e4).astype(np.float32)  # among the triangles
    hit = Accel(_soup(tris)).intersect(o, _random_dirs(rng, 4000), None, np.full(4000, -1))
    keep = np.flatnonzero(hit.prim >= 0)
    assert 0.2 * len(o) < len(keep) < len(o)  # misses to drop, hits to keep
    kept = hit.take(keep)
    assert np.array_equal(kept.prim, hit.prim[keep]) and np.array_equal(kept.t, hit.t[keep])
    for name in ("p", "b", "ng"):
        assert np.array_equal(getattr(kept, name), getattr(hit, name)[keep]), name
    assert np.all(np.isinf(hit.t[hit.prim < 0]))
