"""Irradiance-cache records from one stratified hemisphere gather: directions, E, R, gradients.

Every function is pure, works on NumPy arrays and is vectorised over R records at once (loops
run only over the M rows or N columns of the cell grid, never over records or rays). Nothing
here traces rays or draws random numbers: the caller passes uniforms `u`, traces the directions
of `cell_directions` (after turning them into world space with `sampling.to_world` and the
record's frame), and passes back the radiance `L` and hit distance `r` of every gather ray.

Cell grid (Ward & Heckbert 1992; Mitsuba 0.6 src/librender/irrcache.cpp `HemisphereSampler`).
The hemisphere above a record (local frame: z = the record's normal n_i, x = t, y = b) is split
into M rows of equal *projected* solid angle and N columns of equal azimuth. Row j (0 <= j < M,
j = 0 around the normal) spans sin^2(theta) in [j/M, (j+1)/M]; column k (0 <= k < N) spans
phi in [2 pi k / N, 2 pi (k+1) / N]. Each cell has projected solid angle pi / (M N), so one
direction per cell, uniform in projected solid angle inside it, is a stratified sample of the
cosine density cos(theta) / pi (per unit solid angle). Names of angles used below:

    theta_{j-}, theta_{j+}, theta_j :  sin^2 = j/M, (j+1)/M, (j+0.5)/M   (row start, end, centre)
    phi_{k-}, phi_k                  :  2 pi k / N, 2 pi (k+0.5) / N       (column start, centre)

Array conventions: L (R, M, N, C) radiance arriving at the record along each cell's direction
(W m^-2 sr^-1 per channel, C = 3 for RGB; emission of lights excluded by the caller when direct
light is computed separately); r (R, M, N) hit distance of each gather ray (scene units,
np.inf for rays that escaped). Irradiance E (R, C) is in W m^-2. Gradients are (R, C, 3): for
each record and channel one 3-vector, in the record's local frame unless converted with
`gradient_to_world`; their z components are 0 (both gradients live in the tangent plane).
The rotational gradient is in W m^-2 per radian, the translational one in W m^-2 per unit
length.

Accuracy (tests/test_irradiance_records.py checks it against closed forms; the errors per grid
size are in bench/results/icache/code_choices.md): both gradients are biased low on a finite
grid and converge as M, N grow. The rotational gradient converges slowest for light reaching
the horizon (tan(theta_j) at the row centre underweights the last row, about -0.55 / sqrt(M)).
For the translational gradient an edge near the normal is the worst case, because an edge
between two row boundaries is weighted by sin(theta) interpolated linearly in sin^2(theta),
which undershoots the concave sqrt near theta = 0.

Sources (formulas read, code written here): G. Ward, F. Rubinstein, R. Clear, "A Ray Tracing
Solution for Diffuse Interreflection", SIGGRAPH 1988 (records, harmonic-mean radius);
G. Ward, P. Heckbert, "Irradiance Gradients", Eurographics Rendering Workshop 1992 (rotational
gradient, cell layout); J. Krivanek, P. Gautron, G. Ward, H. W. Jensen, E. Tabellion,
P. H. Christensen, "Practical Global Illumination with Irradiance Caching", SIGGRAPH 2008
course (improved translational gradient, after Krivanek et al. 2005, "Improved Radiance
Gradient Computation", SCCG). The formulas are those of ../shared/reference/algorithms.md
section 1.4; note that Mitsuba 0.6's loop skips the j = 1 row of the translational gradient's
first sum, which the formula includes and so does this module.
"""
import numpy as np

ONE_MINUS_EPSILON = float(np.nextafter(1.0, 0.0))


# ----------------------------------------------------------------------------------------------
# The grid

def _check_grid(M, N):
    M, N = int(M), int(N)
    if M < 1 or N < 1:
        raise ValueError(f"the cell grid needs M >= 1 and N >= 1, got M={M}, N={N}")
    return M, N


def _grid_of(a, M, N, name):
    """Check that a's axes 1 and 2 are the (M, N) grid."""
    a = np.asarray(a, dtype=np.float64)
    M, N = _check_grid(M, N)
    if a.ndim < 3 or a.shape[1:3] != (M, N):
        raise ValueError(f"{name} must have shape (R, {M}, {N}, ...), got {a.shape}")
    return a


def row_angles(M):
    """Sines and cosines of the row angles of an M-row grid, float64.

    Returns (sin_lo, cos_lo, sin_c, cos_c), each (M + 1,) for the row boundaries theta_{j-}
    (sin^2 = j/M, j = 0..M; the last entry is the horizon) and (M,) for the row centres theta_j
    (sin^2 = (j + 0.5)/M). Cosines come from (M - j)/M, not from 1 - sin^2, so they are exact
    near the horizon.
    """
    M = _check_grid(M, 1)[0]
    j = np.arange(M + 1, dtype=np.float64)
    sin_lo, cos_lo = np.sqrt(j / M), np.sqrt((M - j) / M)
    jc = j[:-1] + 0.5
    sin_c, cos_c = np.sqrt(jc / M), np.sqrt((M - jc) / M)
    return sin_lo, cos_lo, sin_c, cos_c


def column_angles(N):
    """Azimuths (phi_{k-}, phi_k), each (N,): column starts 2 pi k / N and centres 2 pi (k+.5)/N."""
    N = _check_grid(1, N)[1]
    k = np.arange(N, dtype=np.float64)
    return 2.0 * np.pi * k / N, 2.0 * np.pi * (k + 0.5) / N


def _tangent(phi):
    """(N, 3) unit vectors in the tangent plane (z = 0) at azimuths phi (N,)."""
    return np.stack([np.cos(phi), np.sin(phi), np.zeros_like(phi)], axis=-1)


# ----------------------------------------------------------------------------------------------
# Directions and irradiance

def cell_directions(M, N, u):
    """One direction per cell of the M x N grid, for R records: (R, M, N, 3) float64, local frame.

    u: (R, M, N, 2) uniforms in [0, 1) (clamped into it). In cell (j, k):
    sin^2(theta) = (j + u0) / M and phi = 2 pi (k + u1) / N, so each direction is uniform in
    projected solid angle over its cell, and the M N directions of a record together are a
    stratified sample of the cosine density cos(theta) / pi per unit solid angle. The frame is
    the record's: z = its normal (turn into world space with `sampling.to_world(d, t, b, n)`).
    cos(theta) is computed as sqrt((M - j - u0) / M), so it stays > 0 even in the last row.
    """
    M, N = _check_grid(M, N)
    u = np.asarray(u, dtype=np.float64)
    if u.ndim != 4 or u.shape[1:] != (M, N, 2):
        raise ValueError(f"u must have shape (R, {M}, {N}, 2), got {u.shape}")
    u = np.clip(u, 0.0, ONE_MINUS_EPSILON)
    j = np.arange(M, dtype=np.float64)[:, None]
    k = np.arange(N, dtype=np.float64)[None, :]
    sin_theta = np.sqrt((j + u[..., 0]) / M)
    cos_theta = np.sqrt(((M - j) - u[..., 0]) / M)
    phi = (2.0 * np.pi / N) * (k + u[..., 1])
    return np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), cos_theta], axis=-1)


def irradiance(L):
    """Irradiance E (R, C) in W m^-2 from the radiance L (R, M, N, C) of one gather per record.

    E = pi / (M N) sum_{j,k} L_{j,k}: the cosine-weighted stratified estimate of
    int_H L(w) cos(theta) dw (Ward et al. 1988; Mitsuba 0.6 `HemisphereSampler::process`).
    A constant radiance L gives pi L exactly.
    """
    L = np.asarray(L, dtype=np.float64)
    if L.ndim != 4:
        raise ValueError(f"L must have shape (R, M, N, C), got {L.shape}")
    M, N = L.shape[1], L.shape[2]
    return (np.pi / (M * N)) * L.sum(axis=(1, 2))


def harmonic_radius(r):
    """Validity radius R (R,) of each record: the harmonic mean of its hit distances.

    r: (R, M, N) hit distances of the gather rays (scene units; np.inf or NaN for rays that
    escaped). R = M N / sum_{j,k} 1 / r_{j,k} (Ward et al. 1988), where escaped rays count in
    M N and add 1/r = 0; R = inf when every ray escaped, and R = 0 when a distance is <= 0 (the
    limit of the harmonic mean; a gather ray that hits at distance 0 leaves no valid radius).
    For a record facing an infinite plane at distance d, R tends to 3 d / 2 (E[cos] = 2/3 under
    the cosine density).
    """
    r = np.asarray(r, dtype=np.float64)
    if r.ndim != 3:
        raise ValueError(f"r must have shape (R, M, N), got {r.shape}")
    cells = r.shape[1] * r.shape[2]
    hit = np.isfinite(r) & (r > 0.0)
    inv_sum = np.divide(1.0, r, out=np.zeros(r.shape), where=hit).sum(axis=(1, 2))
    touching = np.any(r <= 0.0, axis=(1, 2))
    radius = np.divide(float(cells), inv_sum, out=np.full(inv_sum.shape, np.inf), where=inv_sum > 0)
    return np.where(touching, 0.0, radius)


# ----------------------------------------------------------------------------------------------
# Gradients

def _inverse_min_distance(ra, rb):
    """1 / min(ra, rb) where that minimum is finite and > 0, else 0 (the term vanishes)."""
    m = np.minimum(ra, rb)
    return np.divide(1.0, m, out=np.zeros(m.shape), where=np.isfinite(m) & (m > 0.0))


def rotational_gradient(L, M, N):
    """Rotational gradient (R, C, 3) of each record's irradiance, local frame, W m^-2 per radian.

    Ward & Heckbert 1992, written for the cosine-stratified grid (algorithms.md section 1.4):

        grad_r E = pi / (M N) sum_k t_k sum_j tan(theta_j) L_{j,k},

    t_k = (-sin phi_k, cos phi_k, 0) the tangent-plane unit vector at azimuth phi_k + pi/2, with
    theta_j, phi_k the cell centres. It estimates int_H L(w) (n x w) dw: rotating the normal by a
    small rotation vector delta changes E by delta . grad_r E, so a record is extrapolated to a
    normal n as E_i + (n_i x n) . grad_r E_i, and tilting n toward a bright direction raises E.
    The z components are 0. L: (R, M, N, C) as for `irradiance`.
    """
    L = _grid_of(L, M, N, "L")
    M, N = L.shape[1], L.shape[2]
    _, _, sin_c, cos_c = row_angles(M)
    _, phi_c = column_angles(N)
    tan_c = sin_c / cos_c
    per_column = np.einsum("j,rjkc->rkc", tan_c, L)               # (R, N, C)
    t = _tangent(phi_c + 0.5 * np.pi)                              # (N, 3)
    return (np.pi / (M * N)) * np.einsum("rkc,kx->rcx", per_column, t)


def translational_gradient(L, r, M, N):
    """Translational gradient (R, C, 3) of each record's irradiance, local frame, W m^-3.

    The improved form of Krivanek et al. (2008 course, after Krivanek et al. 2005), as in
    algorithms.md section 1.4:

        grad_t E = sum_k [ u_k   sum_{j=1}^{M-1} (2 pi / N) sin(theta_{j-}) cos^2(theta_{j-})
                                     (L_{j,k} - L_{j-1,k}) / min(r_{j,k}, r_{j-1,k})
                         + v_k-  sum_{j=0}^{M-1} cos(theta_j) (cos(theta_{j-}) - cos(theta_{j+}))
                                     / sin(theta_j) (L_{j,k} - L_{j,k-1}) / min(r_{j,k}, r_{j,k-1}) ]

    with u_k the tangent unit vector at the column centre phi_k, v_k- the one at phi_{k-} + pi/2
    (perpendicular to the boundary between columns k-1 and k; k - 1 wraps around), theta_j the
    row centre and theta_{j-}, theta_{j+} the row boundaries. The first sum moves the boundaries
    between rows, the second those between columns, each at the speed of the nearer of the two
    surfaces seen on either side. Row j = 1 is included (Mitsuba 0.6's loop skips it). Terms
    whose min(r) is not finite and > 0 (both rays escaped: a distant environment does not move
    with the record) vanish. L: (R, M, N, C); r: (R, M, N). The z components are 0.
    """
    L = _grid_of(L, M, N, "L")
    r = _grid_of(r, M, N, "r")
    if L.ndim != 4 or r.ndim != 3 or r.shape[0] != L.shape[0]:
        raise ValueError(f"L (R, M, N, C) and r (R, M, N) do not match: {L.shape}, {r.shape}")
    M, N = L.shape[1], L.shape[2]
    sin_lo, cos_lo, sin_c, cos_c = row_angles(M)
    phi_lo, phi_c = column_angles(N)

    # Boundaries between rows j-1 and j (j = 1..M-1), moved along u_k.
    w_rows = (2.0 * np.pi / N) * sin_lo[1:M] * cos_lo[1:M] ** 2                        # (M-1,)
    inv_rows = _inverse_min_distance(r[:, 1:], r[:, :-1])                               # (R, M-1, N)
    d_rows = L[:, 1:] - L[:, :-1]                                                       # (R, M-1, N, C)
    per_column_rows = np.einsum("j,rjk,rjkc->rkc", w_rows, inv_rows, d_rows)

    # Boundaries between columns k-1 and k, moved along v_k-. cos(theta_{j-}) - cos(theta_{j+})
    # is written as (1/M) / (cos(theta_{j-}) + cos(theta_{j+})), which does not cancel.
    w_cols = cos_c * (1.0 / M) / (cos_lo[:-1] + cos_lo[1:]) / sin_c                   # (M,)
    inv_cols = _inverse_min_distance(r, np.roll(r, 1, axis=2))                          # (R, M, N)
    d_cols = L - np.roll(L, 1, axis=2)                                                  # (R, M, N, C)
    per_column_cols = np.einsum("j,rjk,rjkc->rkc", w_cols, inv_cols, d_cols)

    u = _tangent(phi_c)
    v = _tangent(phi_lo + 0.5 * np.pi)
    return np.einsum("rkc,kx->rcx", per_column_rows, u) + np.einsum("rkc,kx->rcx", per_column_cols, v)


def record_terms(L, r):
    """(E, R, grad_r, grad_t) of R records from one gather each: L (R, M, N, C), r (R, M, N).

    Shapes (R, C), (R,), (R, C, 3), (R, C, 3); gradients in the records' local frames.
    """
    L = np.asarray(L, dtype=np.float64)
    M, N = L.shape[1], L.shape[2]
    return (irradiance(L), harmonic_radius(r), rotational_gradient(L, M, N),
            translational_gradient(L, r, M, N))


# ----------------------------------------------------------------------------------------------
# Using a record

def gradient_to_world(grad_local, frame):
    """Local-frame gradients (..., C, 3) -> world space (..., C, 3).

    frame: (t, b, n), each (..., 3), the orthonormal frame the record's directions were built in
    (e.g. `sampling.frame_from_z(n_i)` and n_i); the local x, y, z components multiply t, b, n.
    """
    g = np.asarray(grad_local, dtype=np.float64)
    t, b, n = (np.asarray(a, dtype=np.float64) for a in frame)
    axes = np.stack(np.broadcast_arrays(t, b, n), axis=-2)                 # (..., 3 local, 3 world)
    return np.einsum("...cx,...xy->...cy", g, axes)


def extrapolate(E, grad_r, grad_t, p_i, n_i, p, n, frame=None):
    """A record's irradiance moved to a point p with normal n, clamped to >= 0 per channel.

    E_i(p, n) = E_i + (n_i x n) . grad_r E_i + (p - p_i) . grad_t E_i (Ward & Heckbert 1992;
    the clamp as Mitsuba 0.6 `IrradianceCache` does). E: (..., C) W m^-2; grad_r, grad_t:
    (..., C, 3) in world space, or in the record's local frame when frame = (t, b, n) (each
    (..., 3)) is given; p_i, n_i, p, n: (..., 3) world positions and unit normals. All leading
    axes broadcast, so one record can be applied to many points or many records to many points.
    Returns (..., C).
    """
    E = np.asarray(E, dtype=np.float64)
    if frame is not None:
        grad_r = gradient_to_world(grad_r, frame)
        grad_t = gradient_to_world(grad_t, frame)
    grad_r = np.asarray(grad_r, dtype=np.float64)
    grad_t = np.asarray(grad_t, dtype=np.float64)
    n_i, n = np.broadcast_arrays(np.asarray(n_i, dtype=np.float64), np.asarray(n, dtype=np.float64))
    tilt = np.cross(n_i, n)
    shift = np.asarray(p, dtype=np.float64) - np.asarray(p_i, dtype=np.float64)
    value = (E + np.einsum("...cx,...x->...c", grad_r, tilt)
             + np.einsum("...cx,...x->...c", grad_t, shift))
    return np.maximum(value, 0.0)
