"""PathState (engine/integrators/path_state.py): a wavefront's per-path arrays compact and
extend together; arrays that are None stay None, one depth for all paths stays a scalar."""
import numpy as np

from ember.engine.accel import Hit
from ember.engine.integrators.path_state import Bounces, PathState


def _paths(n=5, per_path=False):
    rng = np.random.default_rng(1)
    o64 = rng.random((n, 3))
    paths = PathState.rays(o64, o64.astype(np.float32), rng.random((n, 3)), None, np.arange(n) + 10,
                           beta=rng.random((n, 3)), pdf_prev=rng.random(n), no_mis=rng.random(n) < 0.5)
    paths.depth = np.arange(n) if per_path else 2
    paths.bounces = Bounces.start(n, 8, per_path=per_path)
    return paths


def test_take_keeps_the_rows_of_every_array_and_leaves_none_and_scalars_alone():
    paths = _paths()
    rows = np.array([3, 0, 4])
    kept = paths.take(rows)
    for name in ("idx", "o64", "o32", "d", "skip", "beta", "pdf_prev", "no_mis"):
        assert np.array_equal(getattr(kept, name), getattr(paths, name)[rows]), name
    assert kept.tmax is None and kept.specular is None and kept.p is None
    assert kept.depth == 2 and np.ndim(kept.bounces.total) == 0 and kept.bounces.counts is None


def test_join_appends_paths_and_gives_unlimited_rays_tmax_inf():
    a, b = _paths(3, per_path=True), _paths(2, per_path=True)
    b.tmax = np.array([1.0, 2.0])
    b.idx = np.array([7, 8])
    ab = a.join(b)
    assert ab.idx.tolist() == [0, 1, 2, 7, 8]
    assert ab.tmax.tolist() == [np.inf, np.inf, np.inf, 1.0, 2.0]
    assert np.array_equal(ab.beta, np.concatenate([a.beta, b.beta]))
    assert ab.depth.tolist() == [0, 1, 2, 0, 1] and len(ab.bounces.total) == 5


def test_arrive_spends_the_rays_and_sets_the_vertices_of_the_hits_only():
    paths = _paths()
    rows12 = np.tile(np.arange(12.0), (2, 1))  # two triangles: v0, e1, e2, ng
    prim = np.array([1, -1, 0, 1, -1])
    hit = Hit(prim, np.arange(5.0), np.full(5, 0.25), np.full(5, 0.5), rows12)
    hits = np.flatnonzero(prim >= 0)
    at = paths.arrive(hit, hits, material=np.array([4, 6]), bary=False)
    assert at.idx.tolist() == [0, 2, 3] and at.prim.tolist() == [1, 0, 1] and at.mat.tolist() == [6, 4, 6]
    assert np.array_equal(at.p, hit.take(hits).p) and np.array_equal(at.d, paths.d[hits])
    for name in ("o64", "o32", "tmax", "skip", "pdf_prev", "no_mis", "bary"):
        assert getattr(at, name) is None, name


def test_leave_puts_the_kept_paths_on_their_next_rays_one_bounce_deeper():
    paths = _paths()
    paths.prim, paths.p = np.arange(5) + 20, np.random.default_rng(2).random((5, 3))
    paths.ng = np.tile([0, 0, 1.0], (5, 1))
    rows = np.array([1, 4])
    wi = np.tile([0, 0, 1.0], (2, 1))
    nxt = paths.leave(rows, wi, np.ones((2, 3)), reflects=True)
    assert nxt.idx.tolist() == [1, 4] and nxt.skip.tolist() == [21, 24] and nxt.depth == 3
    assert np.array_equal(nxt.o64, paths.p[rows]) and np.all(nxt.o32[:, 2] > nxt.o64[:, 2].astype(np.float32))
    assert nxt.pdf_prev is None and nxt.p is None and len(nxt.bounces.last.shape) == 0
