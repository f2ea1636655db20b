"""Irradiance-cache storage and interpolation (engine/integrators/irradiance/cache.py, octree.py).

References are written here: fields whose interpolation is exact (constant, linear along the
surface, linear in the normal), weights at hand-computed distances, brute force over all pairs
for the octree, the all-pairs closure min_j (R_j + |p_i - p_j|) for neighbour clamping.

Deliberate bugs these tests catch (checked by patching the modules one at a time, 26 of 26):
octree balls one level too fine (edge >= s instead of 2 s), stored in one cell instead of all
the cells their box meets, the query's +1 offset dropped, a chunk boundary off by one, a
distance filter twice too loose; extrapolation without the translational or the rotational
gradient; Ward's eps without its floor or with (1 - n . n_i) unsquare-rooted, Tabellion's kappa
= 1 / a or its 10-degree constant at 12 degrees; the front test on n_i or n alone, its sign
flipped, without tolerance; no division by the weight sum; neighbour clamping one way only,
ignoring radius_min, or missing the centres inside the new records' balls; spread_subset
without the conflict step, conflicts at spacing / 4 or on min(spacing) instead of max, the cell
candidate or the priority by input order instead of key, a coarser grid; a wrong radius_min
default.
"""
import numpy as np
import pytest
from scipy.spatial.distance import cdist

from ember.engine.integrators.irradiance import cache as C
from ember.engine.integrators.irradiance import octree as O

Z = np.array([0.0, 0.0, 1.0])


def _plane_records(n, rng, E=None, radius=None, channels=3):
    """n records on the plane z = 0 (normal +z) in the unit square, zero gradients."""
    p = np.column_stack([rng.random((n, 2)), np.zeros(n)])
    E = np.tile([1.0, 0.5, 2.0], (n, 1)) if E is None else E
    R = rng.uniform(0.3, 1.0, n) if radius is None else radius
    zero = np.zeros((n, channels, 3))
    return C.Records(p, np.tile(Z, (n, 1)), E, R, zero, zero.copy())


def _plane_points(n, rng):
    return np.column_stack([rng.random((n, 2)), np.zeros(n)]), np.tile(Z, (n, 1))


def _record(p, n=Z, E=(1.0, 1.0, 1.0), R=1.0, grad_r=None, grad_t=None, R_min=0.0):
    g = np.zeros((1, 3, 3))
    return C.Records(np.atleast_2d(p), np.atleast_2d(n), np.atleast_2d(E), np.atleast_1d(R),
                     g if grad_r is None else np.asarray(grad_r)[None],
                     g if grad_t is None else np.asarray(grad_t)[None],
                     radius_min=np.atleast_1d(R_min))


# ----------------------------------------------------------------------------------------------
# Interpolation of fields it must reproduce exactly

@pytest.mark.parametrize("weight", C.WEIGHTS)
def test_constant_field_is_exact_wherever_covered(weight):
    rng = np.random.default_rng(1)
    E0 = np.array([0.7, 1.3, 0.2])
    cache = C.RecordOctree(_plane_records(60, rng, E=np.tile(E0, (60, 1))), 0.2, weight)
    p, n = _plane_points(4000, rng)
    E, wsum, count = cache.interpolate(p, n)
    covered = count > 0
    assert 0.3 < covered.mean() < 1.0                    # some covered, some not
    assert np.all(wsum[covered] > 0) and np.all(wsum[~covered] == 0)
    assert np.abs(E[covered] - E0).max() < 1e-12
    assert np.all(E[~covered] == 0.0)


@pytest.mark.parametrize("weight", C.WEIGHTS)
def test_linear_field_is_exact_with_gradients_only(weight):
    """E(p) = E0 + g . (p - p0) along the plane: each record extrapolates to the true value."""
    rng = np.random.default_rng(2)
    E0, p0 = np.array([5.0, 3.0, 4.0]), np.array([0.5, 0.5, 0.0])
    g = np.array([[1.0, -2.0, 0.0], [0.5, 0.5, 0.0], [-1.0, 0.0, 0.0]])      # (C, 3)
    rec = _plane_records(80, rng)
    E_true = lambda q: E0 + (q - p0) @ g.T                                     # noqa: E731
    rec = C.Records(rec.position, rec.normal, E_true(rec.position), rec.radius, rec.grad_r,
                    np.tile(g, (80, 1, 1)))
    cache = C.RecordOctree(rec, 0.3, weight)
    p, n = _plane_points(3000, rng)
    E, _, count = cache.interpolate(p, n)
    covered = count > 0
    assert covered.mean() > 0.5
    assert np.abs(E[covered] - E_true(p[covered])).max() < 1e-9
    E_plain, _, count_plain = cache.interpolate(p, n, gradients=False)
    assert np.array_equal(count_plain, count)
    assert np.abs(E_plain[covered] - E_true(p[covered])).max() > 0.05       # far off without them


@pytest.mark.parametrize("weight", C.WEIGHTS)
def test_rotational_gradient_reproduces_a_field_linear_in_the_normal(weight):
    """E(n) = e0 + b . n with b in the records' tangent plane: grad_r = n_i x b (rotating n by
    delta about u changes E by b . (delta u x n) = delta u . (n x b)); then
    E_i + (n_i x n) . (n_i x b) = e0 + b . n exactly (Lagrange's identity, n_i . b = 0)."""
    rng = np.random.default_rng(3)
    e0 = np.array([2.0, 1.0, 3.0])
    b = np.array([[0.8, -0.3, 0.0], [0.1, 0.4, 0.0], [-0.5, 0.2, 0.0]])     # (C, 3), b_z = 0
    rec = _plane_records(50, rng)
    grad_r = np.tile(np.cross(Z, b), (50, 1, 1))
    rec = C.Records(rec.position, rec.normal, np.tile(e0 + b @ Z, (50, 1)), rec.radius, grad_r,
                    rec.grad_t)
    cache = C.RecordOctree(rec, 0.3, weight)
    p, _ = _plane_points(2000, rng)
    tilt = rng.uniform(0.0, 0.05, len(p))                                 # radians, within support
    phi = rng.uniform(0.0, 2 * np.pi, len(p))
    n = np.column_stack([np.sin(tilt) * np.cos(phi), np.sin(tilt) * np.sin(phi), np.cos(tilt)])
    E, _, count = cache.interpolate(p, n)
    covered = count > 0
    assert covered.mean() > 0.5
    E_true = e0 + n @ b.T
    assert np.abs(E[covered] - E_true[covered]).max() < 1e-12
    E_plain, _, _ = cache.interpolate(p, n, gradients=False)
    assert np.abs(E_plain[covered] - E_true[covered]).max() > 0.02         # ~ 0.05 |b|


# ----------------------------------------------------------------------------------------------
# The octree against brute force

def _random_balls(rng, R):
    c = rng.random((R, 3))
    s = 0.3 * 10.0 ** rng.uniform(-3.0, 0.0, R)                       # 3 orders of magnitude
    return c, s


def _pairs(rows, cols):
    return set(zip(rows.tolist(), cols.tolist()))


def test_octree_candidates_equal_brute_force(monkeypatch):
    rng = np.random.default_rng(4)
    c, s = _random_balls(rng, 1500)
    q = np.concatenate([rng.random((2000, 3)) * 1.4 - 0.2,                # also outside the root
                        c[:300] + rng.normal(0.0, 1.0, (300, 3)) * s[:300, None]])
    tree = O.BallOctree(c, s)
    assert len(tree.levels) >= 8
    dist = cdist(q, c)
    brute = _pairs(*np.nonzero(dist <= s[None]))
    assert len(brute) > 3000
    rows, balls, d = tree.candidates(q)
    assert len(rows) == len(brute) and _pairs(rows, balls) == brute
    assert np.allclose(d, dist[rows, balls], rtol=1e-14, atol=0)
    monkeypatch.setattr(O, "MAX_PAIRS", 100)                            # many small chunks
    monkeypatch.setattr(O, "BLOCK_POINTS", 100)
    rows2, balls2, _ = tree.candidates(q)
    assert np.array_equal(rows2, rows) and np.array_equal(balls2, balls)
    r = 10.0 ** rng.uniform(-3.0, -1.0, len(q))
    rows, balls = tree.overlapping(q, r)
    assert _pairs(rows, balls) == _pairs(*np.nonzero(dist <= s[None] + r[:, None]))


@pytest.mark.parametrize("weight", C.WEIGHTS)
def test_record_weights_equal_brute_force(weight):
    """The records a point uses, and their weights, against the weight formulas over all pairs."""
    rng = np.random.default_rng(5)
    R, a = 800, 0.25
    c, s = _random_balls(rng, R)
    nrm = rng.normal(size=(R, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    zero = np.zeros((R, 3, 3))
    rec = C.Records(c, nrm, rng.random((R, 3)), s / a, zero, zero)
    near = rng.integers(0, R, 3000)                                    # a point near a record
    q = c[near] + rng.normal(0.0, 0.5, (3000, 3)) * s[near, None]
    n = nrm[near] + rng.normal(0.0, 0.05, (3000, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    rows, recs, w = C.RecordOctree(rec, a, weight).weights(q, n)
    P, Q, Ni, N = c[None], q[:, None], nrm[None], n[:, None]
    if weight == "ward":
        eps = C.ward_error(Q, N, P, Ni, rec.radius[None])
        use, W = eps < a, 1.0 / np.maximum(eps, C.WARD_EPS_MIN)
    else:
        W = C.tabellion_weight(Q, N, P, Ni, rec.radius[None], a)
        use = W > 0
    use &= C.front_offset(Q, N, P, Ni) >= -C.FRONT_TOLERANCE * s[None]
    assert use.sum() > 500
    assert _pairs(rows, recs) == _pairs(*np.nonzero(use))
    assert np.allclose(w, W[rows, recs], rtol=1e-14, atol=0)


# ----------------------------------------------------------------------------------------------
# Weights, thresholds, rejection

@pytest.mark.parametrize("weight", C.WEIGHTS)
def test_records_in_front_are_rejected(weight):
    a, R = 0.2, 1.0
    tol = C.FRONT_TOLERANCE * a * R                                       # 0.01
    p, n = np.array([[0.05, 0.0, 0.0]]), Z[None]
    # h: the record's height above the point's plane (> 0: in front of the point)
    for h, used in [(0.0, True), (-0.1, True), (0.5 * tol, True), (2.0 * tol, False),
                    (0.1, False)]:
        cache = C.RecordOctree(_record([0.0, 0.0, h]), a, weight)
        assert cache.interpolate(p, n)[2][0] == used, (h, used)


def test_ward_threshold_and_weight():
    a, R = 0.2, 2.0
    rec = _record([0.0, 0.0, 0.0], R=R)
    cache = C.RecordOctree(rec, a, "ward")
    d = a * R * np.array([1.0 - 1e-9, 1.0 + 1e-9, 0.5])
    p = np.column_stack([d, np.zeros(3), np.zeros(3)])
    _, wsum, count = cache.interpolate(p, np.tile(Z, (3, 1)))
    assert list(count) == [1, 0, 1]
    assert wsum[0] == pytest.approx(1.0 / a, rel=1e-8) and wsum[2] == pytest.approx(2.0 / a)
    # the normal term alone: sqrt(1 - cos t) just below and above a, at the record itself
    t = np.arccos(1.0 - (a * np.array([1.0 - 1e-6, 1.0 + 1e-6])) ** 2)
    n = np.column_stack([np.sin(t), np.zeros(2), np.cos(t)])
    assert list(cache.interpolate(np.zeros((2, 3)), n)[2]) == [1, 0]
    # at the record: eps = 0, the weight is capped at 1 / WARD_EPS_MIN
    assert cache.interpolate(np.zeros((1, 3)), Z[None])[1][0] == 1.0 / C.WARD_EPS_MIN


def test_tabellion_threshold_and_weight():
    a, R = 0.2, 2.0
    cache = C.RecordOctree(_record([0.0, 0.0, 0.0], R=R), a, "tabellion")
    d = a * R * np.array([1.0 - 1e-9, 1.0 + 1e-9, 0.5, 0.0])
    p = np.column_stack([d, np.zeros(4), np.zeros(4)])
    _, wsum, count = cache.interpolate(p, np.tile(Z, (4, 1)))
    assert list(count) == [1, 0, 1, 1]
    assert np.allclose(wsum, [1e-9, 0.0, 0.5, 1.0], rtol=1e-6, atol=1e-12)    # 1 - d / (a R)
    limit = 2.0 * a * np.sqrt(1.0 - np.cos(np.radians(10.0)))          # normal support
    t = np.arccos(1.0 - (limit * np.array([1.0 - 1e-6, 1.0 + 1e-6])) ** 2)
    n = np.column_stack([np.sin(t), np.zeros(2), np.cos(t)])
    assert list(cache.interpolate(np.zeros((2, 3)), n)[2]) == [1, 0]


@pytest.mark.parametrize("weight", C.WEIGHTS)
def test_interpolation_is_the_weighted_mean(weight):
    """Two records with hand-computed weights at one point."""
    a = 0.3
    rec = _record([0.0, 0.0, 0.0], E=(1.0, 2.0, 3.0), R=1.0).concat(
        _record([0.2, 0.0, 0.0], E=(3.0, 0.0, 1.0), R=2.0))
    p = np.array([[0.05, 0.0, 0.0]])
    E, wsum, count = C.RecordOctree(rec, a, weight).interpolate(p, Z[None])
    d = np.array([0.05, 0.15]) / np.array([1.0, 2.0])                 # |p - p_i| / R_i
    w = 1.0 / d if weight == "ward" else 1.0 - 2.0 * d / (2.0 * a)
    assert count[0] == 2 and wsum[0] == pytest.approx(w.sum(), rel=1e-12)
    expect = (w[0] * np.array([1.0, 2.0, 3.0]) + w[1] * np.array([3.0, 0.0, 1.0])) / w.sum()
    assert np.allclose(E[0], expect, rtol=1e-12)


def test_extrapolated_values_are_clamped_at_zero():
    g = np.array([[-100.0, 0.0, 0.0]] * 3)
    cache = C.RecordOctree(_record([0.0, 0.0, 0.0], E=(1.0, 1.0, 1.0), grad_t=g), 0.2)
    E, _, count = cache.interpolate(np.array([[0.1, 0.0, 0.0]]), Z[None])
    assert count[0] == 1 and np.all(E == 0.0)


def test_bad_input_is_refused_clearly():
    rec = _record([0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="weight"):
        C.RecordOctree(rec, 0.2, "gauss")
    with pytest.raises(ValueError, match="accuracy"):
        C.RecordOctree(rec, 0.0)
    with pytest.raises(ValueError, match="non-finite"):
        _record([0.0, 0.0, 0.0], R=np.inf)
    with pytest.raises(ValueError, match="shape"):
        C.Records(np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 3)), np.zeros(3),
                  np.zeros((2, 3, 3)), np.zeros((2, 3, 3)))
    # non-finite query points are simply not covered
    E, wsum, count = C.RecordOctree(rec, 0.2).interpolate(np.array([[np.nan, 0, 0]]), Z[None])
    assert count[0] == 0 and np.all(E == 0) and wsum[0] == 0


# ----------------------------------------------------------------------------------------------
# Neighbour clamping

def _closure(p, R):
    """min_j (R_j + |p_i - p_j|) over all pairs (brute force)."""
    return (R[None, :] + cdist(p, p)).min(axis=1)


def test_neighbour_clamp_shrinks_a_large_record_next_to_a_small_one():
    big, small = _record([0.0, 0.0, 0.0], R=10.0), _record([2.0, 0.0, 0.0], R=1.0)
    for existing, new in [(big, small), (small, big)]:
        out = C.neighbour_clamp(existing, new)
        R = dict(zip(out.position[:, 0].tolist(), out.radius.tolist()))
        assert R == {0.0: 3.0, 2.0: 1.0}
        assert np.array_equal(out.radius_unclamped, out.radius)
    # the footprint minimum holds the clamped radius up; the unclamped one is kept
    out = C.neighbour_clamp(_record([0.0, 0.0, 0.0], R=10.0, R_min=5.0), small)
    assert out.radius[0] == 5.0 and out.radius_unclamped[0] == 3.0
    assert np.array_equal(out.position, np.array([[0.0, 0, 0], [2.0, 0, 0]]))   # existing first


def test_neighbour_clamp_is_the_closure_idempotent_and_order_independent():
    rng = np.random.default_rng(6)
    n = 300
    rec = _plane_records(n, rng, radius=10.0 ** rng.uniform(-2.5, 0.0, n))
    expect = _closure(rec.position, rec.radius)
    assert np.mean(expect < rec.radius) > 0.3                          # many get clamped
    once = C.neighbour_clamp(C.Records.empty(), rec)
    assert np.allclose(once.radius, expect, rtol=1e-15, atol=0)
    again = C.neighbour_clamp(C.Records.empty(), once)
    assert np.array_equal(again.radius, once.radius)
    assert np.array_equal(C.neighbour_clamp(once, C.Records.empty()).radius, once.radius)
    # shuffled, and added in three batches in another order: the same radius per record
    perm = rng.permutation(n)
    parts = np.array_split(perm, 3)
    out = C.Records.empty()
    for part in parts[::-1]:
        out = C.neighbour_clamp(out, rec.take(part))
    order = np.concatenate(parts[::-1])
    assert np.allclose(out.radius, expect[order], rtol=1e-15, atol=0)
    assert np.array_equal(out.position, rec.position[order])


# ----------------------------------------------------------------------------------------------
# Spreading new records

@pytest.mark.parametrize("varying", [False, True])
def test_spread_subset_spacing_coverage_and_order_independence(varying):
    rng = np.random.default_rng(7)
    N = 4000
    # hit points on two walls of a room, as a batch of failing pixels would give
    p = rng.random((N, 3)) * 4.0
    p[: N // 2, 2] = 0.0
    p[N // 2:, 0] = 0.0
    s = rng.uniform(0.2, 0.5, N) if varying else np.full(N, 0.3)
    key = rng.permutation(N).astype(np.uint64) * np.uint64(2654435761)
    kept = C.spread_subset(p, s if varying else 0.3, key)
    assert np.array_equal(kept, np.unique(kept))
    assert 40 < len(kept) < N // 4
    d = cdist(p[kept], p[kept])
    np.fill_diagonal(d, np.inf)
    assert np.all(d >= 0.5 * np.maximum(s[kept][:, None], s[kept][None]))
    to_kept = cdist(p, p[kept])
    ratio = (to_kept / s[:, None]).min(axis=1)
    assert ratio.max() <= np.sqrt(3.0) + 0.5 + 1e-12                    # the proven bound
    perm = rng.permutation(N)
    kept2 = C.spread_subset(p[perm], s[perm] if varying else 0.3, key[perm])
    assert np.array_equal(np.sort(perm[kept2]), kept)


def test_spread_subset_prefers_small_keys():
    p = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [5.0, 0.0, 0.0]])
    assert list(C.spread_subset(p, 1.0, np.array([2, 1, 3], np.uint64))) == [1, 2]
    assert list(C.spread_subset(p, 1.0, np.array([1, 2, 3], np.uint64))) == [0, 2]
    # two candidates of neighbouring cells that conflict: the smaller key wins
    p = np.array([[0.99, 0.5, 0.5], [1.01, 0.5, 0.5]])
    assert list(C.spread_subset(p, 1.0, np.array([5, 4], np.uint64))) == [1]
    assert list(C.spread_subset(p, 1.0, np.array([4, 5], np.uint64))) == [0]
    with pytest.raises(ValueError, match="spacing"):
        C.spread_subset(p, 0.0, np.arange(2))


# ----------------------------------------------------------------------------------------------
# Publishing

def test_pack_round_trip_on_read_only_views():
    rng = np.random.default_rng(8)
    rec = _plane_records(200, rng)
    rec = C.Records(rec.position, rec.normal, rec.E, rec.radius, rng.normal(size=(200, 3, 3)),
                    rng.normal(size=(200, 3, 3)), radius_unclamped=rec.radius * 2,
                    radius_min=rec.radius / 2)
    packed = rec.pack()
    assert all(v.flags.c_contiguous and v.dtype == np.float64 for v in packed.values())
    shared = {}
    for k, v in packed.items():
        buf = np.empty_like(v)                                         # as in shared memory
        buf[...] = v
        buf.setflags(write=False)
        shared[k] = buf
    back = C.Records.from_packed(shared)
    for k in packed:
        assert shared[k].size == 0 or np.shares_memory(getattr(back, k), shared[k])  # (no coefficients: empty)
        assert np.array_equal(getattr(back, k), getattr(rec, k))
    p, n = _plane_points(500, rng)
    for got, want in zip(C.RecordOctree(back, 0.2).interpolate(p, n),
                         C.RecordOctree(rec, 0.2).interpolate(p, n)):
        assert np.array_equal(got, want)
    out = C.neighbour_clamp(back, _record([0.5, 0.5, 0.0], R=0.01))
    before = rec.concat(_record([0.5, 0.5, 0.0], R=0.01)).radius
    assert len(out) == 201 and np.all(out.radius <= before) and np.any(out.radius < before)


@pytest.mark.parametrize("weight", C.WEIGHTS)
@pytest.mark.parametrize("side", [1.0, -1.0])
def test_front_test_keeps_records_on_a_sphere(weight, side):
    """On a sphere (outside, side = 1, or inside, side = -1) the chord p - p_i is perpendicular
    to n + n_i, so no record is rejected as being in front, however curved the surface."""
    rng = np.random.default_rng(9)
    u = rng.normal(size=(400, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    rec = C.Records(u, side * u, np.ones((400, 3)), np.full(400, 1.0), np.zeros((400, 3, 3)),
                    np.zeros((400, 3, 3)))
    q = rng.normal(size=(2000, 3))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    a = 0.3
    count = C.RecordOctree(rec, a, weight).interpolate(q, side * q)[2]
    if weight == "ward":
        expect = C.ward_error(q[:, None], side * q[:, None], u[None], side * u[None], 1.0) < a
    else:
        expect = C.tabellion_weight(q[:, None], side * q[:, None], u[None], side * u[None], 1.0,
                                    a) > 0
    assert expect.sum() > 1000
    assert np.array_equal(count, expect.sum(axis=1))


def test_interpolation_does_not_depend_on_batching(monkeypatch):
    """Bit-identical results for any split of the query points and any chunk size: each point's
    sum runs over its records in the tree's order (so images do not depend on batch size)."""
    rng = np.random.default_rng(10)
    rec = _plane_records(300, rng, radius=10.0 ** rng.uniform(-1.5, 0.0, 300))
    rec = C.Records(rec.position, rec.normal, rng.random((300, 3)), rec.radius,
                    rng.normal(size=(300, 3, 3)), rng.normal(size=(300, 3, 3)))
    cache = C.RecordOctree(rec, 0.3)
    p, _ = _plane_points(3000, rng)
    n = np.tile(Z, (3000, 1)) + rng.normal(0.0, 0.05, (3000, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    whole = cache.interpolate(p, n)
    assert np.mean(whole[2] > 1) > 0.5
    monkeypatch.setattr(O, "MAX_PAIRS", 50)
    monkeypatch.setattr(O, "BLOCK_POINTS", 333)
    parts = [cache.interpolate(p[k], n[k]) for k in np.array_split(np.arange(3000), 7)]
    for got, want in zip((np.concatenate(x) for x in zip(*parts)), whole):
        assert np.array_equal(got, want)


def test_empty_sets():
    empty = C.Records.empty()
    p, n = np.array([[0.0, 0.0, 0.0]]), Z[None]
    E, wsum, count = C.RecordOctree(empty, 0.2).interpolate(p, n)
    assert E.shape == (1, 3) and np.all(E == 0) and wsum[0] == 0 and count[0] == 0
    E, wsum, count = C.RecordOctree(_record([0.0, 0.0, 0.0]), 0.2).interpolate(np.zeros((0, 3)),
                                                                               np.zeros((0, 3)))
    assert E.shape == (0, 3) and wsum.shape == (0,) and count.dtype == np.int64
    assert len(C.neighbour_clamp(empty, empty)) == 0
    assert len(C.spread_subset(np.zeros((0, 3)), 1.0, np.zeros(0, np.uint64))) == 0
    rows, recs = C.RecordOctree(empty, 0.2).overlapping(p, np.ones(1))
    assert len(rows) == len(recs) == 0
