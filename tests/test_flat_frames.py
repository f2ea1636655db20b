"""The per-triangle frame table of flat-shaded meshes (engine/integrators/surface.py): a hit
reads its shading frame from the table, and it must be bit for bit what shading_frame and
frame_from_z compute at the hit, or images would change."""
import numpy as np

from ember.engine.accel import Accel
from ember.engine.integrators import surface
from ember.engine.sampling import frame_from_z
from ember.engine.scene import Mesh


def _flat_mesh(gen, n=300):
    """Random triangles far from the origin, each with one corner normal for all three corners:
    mostly near its geometric normal, some flipped below the surface, one zero (both replaced
    by the geometric normal)."""
    v = gen.normal(size=(3 * n, 3)) + 1e4
    ng = np.cross(v[1::3] - v[::3], v[2::3] - v[::3])
    ng /= np.linalg.norm(ng, axis=1, keepdims=True)
    normal = ng + 0.3 * gen.normal(size=(n, 3))
    normal[:20] = -ng[:20] + 0.1 * gen.normal(size=(20, 3))  # below the surface
    normal[20] = 0.0  # degenerate
    normal *= gen.uniform(0.5, 2.0, (n, 1))  # not unit: shading_frame normalises
    normals = np.repeat(normal[:, None], 3, axis=1).astype(np.float32)
    return Mesh(v.astype(np.float32), np.arange(3 * n, dtype=np.int32).reshape(n, 3), normals,
                np.zeros(n, np.int32))


def test_table_rows_equal_the_frames_computed_at_each_hit():
    gen = np.random.default_rng(3)
    mesh = _flat_mesh(gen)
    accel = Accel(mesh)
    flat = surface.flat_normals(mesh)
    table = surface.flat_frames(mesh, flat, accel.ng)
    prim = gen.integers(0, mesh.n_triangles, 5000)
    wo = gen.normal(size=(5000, 3))
    wo[:10] = np.cross(accel.ng[prim[:10]], gen.normal(size=(10, 3)))  # grazing: dot(ng, wo) ~ 0
    ng = accel.ng[prim]
    ng_f, ns = surface.shading_frame(mesh, flat, prim, None, ng, wo)
    t, b = frame_from_z(ns)
    rows = surface.flat_frame_rows(table, prim, ng, wo)
    for got, want in zip(rows, (ng_f, ns, t, b)):
        assert np.array_equal(got, want)
    assert np.any(np.all(ns == ng_f, axis=1)) and not np.all(ns == ng_f)  # both kinds of rows were checked


def test_no_table_for_smooth_or_big_meshes():
    gen = np.random.default_rng(4)
    mesh = _flat_mesh(gen, 30)
    accel = Accel(mesh)
    assert surface.flat_frames(mesh, None, accel.ng) is None
    big = np.zeros((surface.FLAT_FRAMES_MAX + 1, 3))
    assert surface.flat_frames(mesh, big, big) is None
