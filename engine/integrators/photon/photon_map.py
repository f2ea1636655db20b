"""Photon maps: compact photon storage, k-nearest search, density estimates, radiance photons.

A photon is stored where it hit a surface: position x_p (world), incident direction w_p (unit,
pointing back toward where the photon came from), flux Phi_p (W, RGB) and the surface normal n_p
on the side it arrived from. Estimates follow Jensen (2001) as seed 001 states them:

    L_r(x, wo) ~ sum_p f_r(x, wo, w_p) Phi_p W(d_p / r) / (N_e * c * pi r^2)

over the photons near x (k nearest within r_max), r = the distance to the k-th photon (or r_max
when fewer are found), N_e = photon PATHS emitted (never the stored count), W a kernel with
int_disc W = c pi r^2. Irradiance E is the same sum with f_r = 1.

The same radius can be chosen per photon instead (`set_photon_radii`, `radiance_scattered`:
the sample-point form, each photon's flux spread over the disc of its own k-th neighbour): its
integral over a surface is the flux the photons carry, where the per-point radius above adds
light beside a sharp caustic (a dark point's disc reaches into it). The caustic map uses it.

The k-th photon fixes r and so lies on the boundary of the disc: Jensen's sum includes it, which
biases a uniform density by k / (k - 1) (pi r_k^2 lambda is Gamma(k) distributed, E[1/Gamma(k)] =
1/(k-1)). Here it is left out: given r, the other k - 1 photons are uniform in the disc, so the
estimate is exactly unbiased on a locally uniform density for every kernel (the "(k-1)/(pi r^2)"
form). With fewer than k photons inside r_max, all of them count and r = r_max (a Poisson count).

Wrong-side photons are rejected as Mitsuba 0.6 does (src/librender/photonmap.cpp): a photon
counts only if n_p . n > 0.1 and w_p . n > 0, so light on the back of a thin wall never leaks.

Storage (`PhotonMap.pack`): float32 position (12 B), octahedral int16 w_p and n_p (4 B each,
Cigolle et al. 2014, "A Survey of Efficient Representations for Independent Unit Vectors"),
float32 flux (12 B): 32 B per photon. The search structure is pykdtree's (float32 points used in
place, uint32 permutation and its nodes: a fraction of the packed photon); scipy's cKDTree is the
fallback where pykdtree is missing but SciPy is there (it copies the points as float64, which
nearly doubles a photon's memory). The add-on ships pykdtree only.

Radiance photons (Christensen 1999, "Faster Photon Map Global Illumination"; pbrt-v2
integrators/photonmap.cpp): the irradiance at every j-th photon, computed once from the map, so a
final-gather ray needs one nearest-neighbour lookup (with a normal check) instead of a k-NN
estimate; the caller multiplies by the diffuse reflectance / pi.

Measured in bench/results/photon/code_choices.md: the memory of both search structures; the
Morton order of the stored photons, which speeds up the index build and the queries; a
radiance-photon lookup, many times faster than the full estimate with the same error against
the truth.

Every query is vectorised over N points, processed in chunks so that the N x k temporaries stay
under ~25 MB, on ONE thread (queries run inside worker processes, one per core).
"""
from __future__ import annotations

import ctypes
import glob
import os

import numpy as np

from ...errors import EmberError
from ...settings import DECLARED
from ...vec import dot, take

KERNELS = DECLARED["photon_kernel"].values
CONE_K = 1.1                 # Jensen's cone filter constant (k >= 1)
COS_NORMAL_MIN = 0.1         # photon normal . query normal must exceed this (Mitsuba 0.6)
_SNORM16 = 32767.0
# Candidate (point, photon) pairs per chunk: ~200 B of temporaries each -> ~25 MB at most.
# Bigger chunks gain nothing and start to miss the cache (bench/results/photon/code_choices.md).
_CHUNK_PAIRS = 1 << 17


# ----------------------------------------------------------------------------------------------
# Octahedral unit-vector encoding (Cigolle et al. 2014 section 3.1; Meyer et al. 2010)

def _sign_nonzero(x):
    return np.where(x >= 0, np.float32(1.0), np.float32(-1.0))


def encode_octahedral(v: np.ndarray) -> np.ndarray:
    """Unit vectors v (N,3) -> (N,2) int16 octahedral snorm codes (angular error below 1e-4 rad)."""
    v = np.asarray(v, dtype=np.float64)
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    l1 = np.abs(x) + np.abs(y) + np.abs(z)
    l1 = np.where(l1 > 0, l1, 1.0)
    u, w = x / l1, y / l1
    lower = z < 0  # fold the lower hemisphere over the diagonals
    u, w = (np.where(lower, (1.0 - np.abs(w)) * _sign_nonzero(u), u),
            np.where(lower, (1.0 - np.abs(u)) * _sign_nonzero(w), w))
    out = np.empty((len(v), 2), np.int16)
    out[:, 0] = np.rint(np.clip(u, -1.0, 1.0) * _SNORM16)
    out[:, 1] = np.rint(np.clip(w, -1.0, 1.0) * _SNORM16)
    return out


def decode_octahedral(e: np.ndarray) -> np.ndarray:
    """(N,2) int16 octahedral codes -> unit vectors (N,3) float32."""
    u = e[:, 0].astype(np.float32) * np.float32(1.0 / _SNORM16)
    w = e[:, 1].astype(np.float32) * np.float32(1.0 / _SNORM16)
    z = np.float32(1.0) - np.abs(u) - np.abs(w)
    lower = z < 0
    u, w = (np.where(lower, (np.float32(1.0) - np.abs(w)) * _sign_nonzero(u), u),
            np.where(lower, (np.float32(1.0) - np.abs(u)) * _sign_nonzero(w), w))
    inv = np.float32(1.0) / np.sqrt(u * u + w * w + z * z)  # |(u, w, z)| >= 1/sqrt(3): never 0
    out = np.empty((len(e), 3), np.float32)
    out[:, 0], out[:, 1], out[:, 2] = u * inv, w * inv, z * inv
    return out


def _spread_bits(v):
    """10-bit integers (uint32) -> their bits at every third position (Morton 'part1by2')."""
    v = (v | (v << 16)) & np.uint32(0x030000FF)
    v = (v | (v << 8)) & np.uint32(0x0300F00F)
    v = (v | (v << 4)) & np.uint32(0x030C30C3)
    return (v | (v << 2)) & np.uint32(0x09249249)


def morton_order(p: np.ndarray) -> np.ndarray:
    """Permutation (M,) that sorts points p (M,3) along a Z-order curve (1024^3 cubic cells over
    their bounding cube). Photons adjacent in space then sit together in memory, so the gathers of a k-NN
    query hit the cache, which makes estimates on a large map much faster (and the index build
    too)."""
    if len(p) == 0:
        return np.zeros(0, np.int64)
    lo = p.min(axis=0)
    extent = float(np.max(p.max(axis=0) - lo))
    scale = 1023.0 / extent if extent > 0 else 0.0  # cubic cells: the curve is isotropic
    code = np.zeros(len(p), np.uint32)
    for axis in range(3):
        cell = ((p[:, axis] - lo[axis]) * scale).astype(np.uint32)
        code |= _spread_bits(cell) << np.uint32(axis)
    return np.argsort(code, kind="stable")


# ----------------------------------------------------------------------------------------------
# Kernels: weight W(t) of t = d^2 / r^2 in [0, 1) and c = int_disc W / (pi r^2)

def _kernel(kernel: str):
    """(W, c) for a kernel name. The Mitsuba/pbrt-v2 'Simpson' kernel (1 - t)^2 (a biweight) is
    what the brief and those renderers call Epanechnikov here; c = 1/3 gives their 3/(pi r^2)."""
    if kernel == "uniform":
        return None, 1.0
    if kernel == "cone":  # Jensen 2001 eq. 7.7: W = 1 - d/(k r), c = 1 - 2/(3k)
        return (lambda t: 1.0 - np.sqrt(t) / CONE_K), 1.0 - 2.0 / (3.0 * CONE_K)
    if kernel in ("epanechnikov", "simpson"):
        return (lambda t: (1.0 - t) ** 2), 1.0 / 3.0
    raise ValueError(f"unknown kernel {kernel!r}; expected one of {KERNELS}")


# ----------------------------------------------------------------------------------------------
# The search structure

def _omp_set_num_threads():
    """omp_set_num_threads of the OpenMP runtime pykdtree's wheel bundles, or None.

    pykdtree parallelises queries with OpenMP; the workers already use every core, so each
    query runs on one thread. The setting is per calling thread, hence applied before each query.
    """
    import pykdtree

    root = os.path.dirname(pykdtree.__file__)
    # Linux wheels bundle libgomp beside the package, macOS ones libomp inside it; Windows uses
    # the system's vcomp140 (loaded already: CDLL returns the same library)
    candidates = sorted(glob.glob(root + ".libs/*omp*")) + sorted(glob.glob(os.path.join(root, ".dylibs", "*omp*")))
    if os.name == "nt":
        candidates.append("vcomp140.dll")
    for path in candidates:
        try:
            return ctypes.CDLL(path).omp_set_num_threads
        except (OSError, AttributeError):
            continue
    return None


class _Index:
    """k-nearest search over float32 points (M,3), used in place (never written to).

    query(q (n,3), k, bound) -> (d2 (n,k) squared distances, idx (n,k) int), sorted by
    distance; neighbours beyond `bound` (or missing) have d2 = inf and idx = M.
    """

    def __init__(self, points: np.ndarray, leafsize: int = 16):
        self.m = len(points)
        self.leafsize = leafsize
        try:
            from pykdtree.kdtree import KDTree
        except ImportError:  # the fallback where the wheel is missing (tested); the add-on ships no SciPy
            try:
                from scipy.spatial import cKDTree
            except ImportError:
                raise EmberError("Photon mapping needs the pykdtree package, which did not load (on Apple "
                                 "silicon its wheel needs macOS 14 or later); the path tracer needs no kd-tree.")

            self.kind = "cKDTree"
            self._tree = cKDTree(points, leafsize=leafsize, balanced_tree=False, compact_nodes=False)
            self._threads = None
        else:
            self.kind = "pykdtree"
            self._tree = KDTree(points, leafsize=leafsize) if self.m else None
            self._threads = _omp_set_num_threads()

    @property
    def nbytes(self) -> int:
        """Memory of the structure beyond the points: the permutation plus the nodes, estimated
        with half-full leaves and 48 B per malloc'ed node (pykdtree, leafsize 16: 16 B per point,
        a little above malloc's own count)."""
        nodes = 2 * (2 * self.m // self.leafsize + 1)
        if self.kind == "pykdtree":
            return 4 * self.m + 48 * nodes
        return 32 * self.m + 72 * nodes  # cKDTree: float64 copy + intp indices + nodes

    def query(self, q: np.ndarray, k: int, bound: float):
        n = len(q)
        if self.m == 0 or k == 0:
            return np.full((n, k), np.inf, np.float32), np.full((n, k), self.m, np.int64)
        if self.kind == "pykdtree":
            if self._threads is not None:
                self._threads(1)
            d2, idx = self._tree.query(np.ascontiguousarray(q, dtype=np.float32), k=k,
                                       distance_upper_bound=float(bound), sqr_dists=True)
        else:
            d, idx = self._tree.query(q, k=k, distance_upper_bound=float(bound), workers=1)
            d2 = d * d
        return d2.reshape(n, k), idx.reshape(n, k)


def _per_point(r, n: int) -> np.ndarray:
    """r (scalar or (n,)) as an (n,) float64 array."""
    r = np.asarray(r, dtype=np.float64)
    return np.broadcast_to(r, (n,)) if r.ndim == 0 else r.reshape(n)


def _chunks(n: int, k: int):
    step = max(1, _CHUNK_PAIRS // max(k, 1))
    for s in range(0, n, step):
        yield s, min(n, s + step)


# ----------------------------------------------------------------------------------------------
# Photon map

class _Points:
    """What photon maps and radiance photons share: packed arrays (`arrays`), positions (M,3),
    octahedral normals (`_normal`) and a k-nearest index over the positions (`_index`)."""

    def __len__(self) -> int:
        return len(self.position)

    @property
    def nbytes(self) -> int:
        """Bytes held: the packed arrays plus the search structure."""
        return sum(a.nbytes for a in self.arrays.values()) + self._index.nbytes

    def normal(self, rows) -> np.ndarray:
        """Unit normals (K,3) float32 of points `rows`."""
        return decode_octahedral(take(self._normal, rows))


class PhotonMap(_Points):
    """Photons stored at surface hits, with a k-nearest index over their positions.

    position (M,3) world; wi (M,3) unit, toward where the photon came from; flux (M,3) W per
    photon (estimates divide by n_emitted); normal (M,3) unit surface normal on the side the
    photon arrived from; n_emitted: number of photon PATHS emitted. The inputs are only read.
    `arrays` holds the packed arrays (see `pack`) to publish to other processes.
    """

    def __init__(self, position, wi, flux, normal, n_emitted: int):
        self._install(self.pack(position, wi, flux, normal), n_emitted)

    @staticmethod
    def pack(position, wi, flux, normal) -> dict[str, np.ndarray]:
        """Compact arrays, 32 B per photon, in Morton order (`morton_order`; photons are a set,
        their order carries nothing): position (M,3) float32, wi and normal (M,2) int16
        octahedral, flux (M,3) float32."""
        position = np.asarray(position).reshape(-1, 3)
        order = morton_order(position)
        return {
            "position": take(position, order).astype(np.float32, copy=False),
            "wi": encode_octahedral(take(np.asarray(wi).reshape(-1, 3), order)),
            "normal": encode_octahedral(take(np.asarray(normal).reshape(-1, 3), order)),
            "flux": take(np.asarray(flux).reshape(-1, 3), order).astype(np.float32, copy=False),
        }

    @classmethod
    def from_packed(cls, arrays: dict, n_emitted: int) -> "PhotonMap":
        """A map over arrays made by `pack` (e.g. read-only views of shared memory); builds the
        index in this process and copies nothing."""
        self = cls.__new__(cls)
        self._install(arrays, n_emitted)
        return self

    def _install(self, arrays: dict, n_emitted: int) -> None:
        p, wi, nrm, flux = arrays["position"], arrays["wi"], arrays["normal"], arrays["flux"]
        m = len(p)
        if not (p.dtype == np.float32 and p.shape == (m, 3) and flux.dtype == np.float32
                and flux.shape == (m, 3) and wi.dtype == nrm.dtype == np.int16
                and wi.shape == nrm.shape == (m, 2)):
            raise ValueError("photon arrays must be packed by PhotonMap.pack")
        if n_emitted <= 0 and m > 0:
            raise ValueError("n_emitted must be positive")
        self.arrays = {"position": p, "wi": wi, "normal": nrm, "flux": flux}
        self.position, self._wi, self._normal, self.flux = p, wi, nrm, flux
        self.n_emitted = int(n_emitted)
        self._index = _Index(p)

    def wi(self, rows) -> np.ndarray:
        """Unit incident directions (K,3) float32 of photons `rows`."""
        return decode_octahedral(take(self._wi, rows))

    # -- queries -------------------------------------------------------------------------------

    def _accept(self, j, nq):
        """Mask (K,) of photons j seen from query normals nq (K,3), and their wi (K,3)."""
        wi = self.wi(j)
        ok = (dot(self.normal(j), nq) > COS_NORMAL_MIN) & (dot(wi, nq) > 0.0)
        return ok, wi

    def radiance(self, p, n, f, k: int, r_max, kernel: str = "uniform", min_count: int = 8, accept=None):
        """Reflected radiance L (N,3) [W m^-2 sr^-1] at points p (N,3) with unit normals n (N,3)
        on the side being shaded (photons count only if they arrived on that side).

        f(rows (K,), wi (K,3)) -> (K,3): the BSDF value f_r(wo, wi) [1/sr] at query points
        `rows` (indices into p) for photon directions wi (the caller binds wo); f=None gives the
        irradiance E [W m^-2]. k >= 2 nearest photons within r_max (scalar or (N,) [m]);
        kernel in KERNELS; L = 0 where fewer than min_count photons are accepted.
        accept(rows (K,), j (K,)) -> (K,) bool, optional: a further test of photons j for query
        points `rows` (e.g. visibility, so light does not leak through thin walls).
        Returns (L (N,3) float64, r (N,) float64 radius used [m]).
        """
        if k < 2:
            raise ValueError("k must be at least 2 (the k-th photon only sets the radius)")
        weight, c = _kernel(kernel)
        p = np.asarray(p).reshape(-1, 3)
        n = np.asarray(n).reshape(-1, 3)
        N = len(p)
        r_max = _per_point(r_max, N)
        L = np.zeros((N, 3))
        r_out = r_max.copy()
        if len(self) == 0:
            return L, r_out
        k_query = min(k, len(self))
        for s, e in _chunks(N, k_query):
            r2_max = r_max[s:e] ** 2
            d2, idx = self._index.query(p[s:e], k_query, np.sqrt(r2_max.max()) * (1 + 1e-6))
            inside = d2 < r2_max[:, None]
            # k found inside r_max: the k-th sets r and sits on the boundary (module docstring)
            full = inside[:, -1] if k_query == k else np.zeros(e - s, bool)
            r2 = np.where(full, d2[:, -1], r2_max)
            inside[:, -1] &= ~full
            rows, cols = np.nonzero(inside)
            j = idx[rows, cols]
            ok, wi = self._accept(j, take(n, rows + s))
            if accept is not None and ok.any():
                ok[ok] = accept(rows[ok] + s, j[ok])
            rows, cols, j, wi = rows[ok], cols[ok], j[ok], wi[ok]
            count = np.bincount(rows, minlength=e - s)
            r2_row = r2[rows]
            # W / (c pi r^2); r2 = 0 only if k photons coincide with x: no estimate there
            norm = np.divide(1.0, c * np.pi * r2_row, out=np.zeros(len(rows)), where=r2_row > 0)
            if weight is not None:
                norm *= weight(d2[rows, cols] / np.where(r2_row > 0, r2_row, 1.0))
            contrib = take(self.flux, j).astype(np.float64)
            if f is not None:
                contrib *= f(rows + s, wi)
            for ch in range(3):
                L[s:e, ch] = np.bincount(rows, weights=contrib[:, ch] * norm, minlength=e - s)
            L[s:e][count < min_count] = 0.0
            r_out[s:e] = np.sqrt(r2)
        if self.n_emitted > 0:
            L /= self.n_emitted
        return L, r_out

    def irradiance(self, p, n, k: int, r_max, kernel: str = "uniform", min_count: int = 8, accept=None):
        """Irradiance E (N,3) [W m^-2] from photons arriving on the side of n; see `radiance`.
        Returns (E (N,3), r (N,))."""
        return self.radiance(p, n, None, k, r_max, kernel, min_count, accept)

    def set_photon_radii(self, k: int, r_max: float) -> None:
        """Give every photon its own kernel radius for `radiance_scattered`: the distance to
        its k-th nearest other photon, at most r_max (one k-nearest query per photon)."""
        m = len(self)
        self.radius2 = np.full(m, r_max * r_max, np.float32)
        k_query = min(k + 1, m)  # the photon itself is its own nearest
        if k_query < 2:
            return
        for s, e in _chunks(m, k_query):
            d2, _ = self._index.query(self.position[s:e], k_query, r_max * (1 + 1e-6))
            self.radius2[s:e] = np.minimum(d2[:, -1], r_max * r_max) if k_query == k + 1 else r_max * r_max

    def radiance_scattered(self, p, n, f, kernel: str = "uniform", accept=None):
        """Reflected radiance L (N,3) at points p (N,3) with normals n (N,3) from photons that
        each spread their flux over their own disc (`set_photon_radii`): the sample-point
        form of the adaptive estimate, sum_p f Phi_p W(d_p / h_p) / (N_e c pi h_p^2) over the
        photons whose disc holds x. Each photon's weights integrate to its flux over the
        surface, so the estimate keeps the light the photons carry; the k-nearest form
        (`radiance`) adds light next to a sharp caustic, where a dark point's radius reaches
        into it. Unbiased on a locally uniform density like the k-nearest form. f, accept as
        in `radiance`."""
        weight, c = _kernel(kernel)
        p = np.asarray(p).reshape(-1, 3)
        n = np.asarray(n).reshape(-1, 3)
        N = len(p)
        L = np.zeros((N, 3))
        if len(self) == 0 or N == 0:
            return L
        r_max = float(np.sqrt(self.radius2.max()))
        pending = np.arange(N)
        k = 32
        # k-nearest with k growing x4 until no point has all k inside r_max
        while len(pending):
            k = min(k, len(self))
            unsaturated = []
            for s, e in _chunks(len(pending), k):
                q = pending[s:e]
                d2, idx = self._index.query(take(p, q), k, r_max * (1 + 1e-6))
                found = np.isfinite(d2)
                done = ~found[:, -1] | (k == len(self))
                rows, cols = np.nonzero(found & done[:, None])
                j = idx[rows, cols]
                h2 = self.radius2[j].astype(np.float64)
                d2_in = d2[rows, cols].astype(np.float64)
                inside = d2_in < h2
                rows, j, h2, d2_in = rows[inside], j[inside], h2[inside], d2_in[inside]
                g = q[rows]
                ok, wi = self._accept(j, take(n, g))
                if accept is not None and ok.any():
                    ok[ok] = accept(g[ok], j[ok])
                g, j, wi, h2, d2_in = g[ok], j[ok], wi[ok], h2[ok], d2_in[ok]
                norm = np.divide(1.0, c * np.pi * h2, out=np.zeros(len(g)), where=h2 > 0)
                if weight is not None:
                    norm *= weight(d2_in / np.where(h2 > 0, h2, 1.0))
                contrib = take(self.flux, j).astype(np.float64)
                if f is not None:
                    contrib *= f(g, wi)
                for ch in range(3):
                    L[:, ch] += np.bincount(g, weights=contrib[:, ch] * norm, minlength=N)
                unsaturated.append(q[~done])
            pending = np.concatenate(unsaturated) if unsaturated else pending[:0]
            k *= 4
        return L / self.n_emitted

    def gather_radius(self, p, n, r, f=None, accept=None):
        """All accepted photons within a fixed radius r (N,) [m] of each point (progressive
        photon mapping). f as in `radiance`, f=None for flux alone.

        Returns (sum_f_flux (N,3) = sum f Phi_p [W/sr or W], NOT divided by n_emitted or pi r^2;
        count (N,) int64 of accepted photons). Wrong-side photons and photons with f = 0 are not
        counted, so they do not shrink a PPM radius (Mitsuba issue #145).
        """
        p = np.asarray(p).reshape(-1, 3)
        n = np.asarray(n).reshape(-1, 3)
        N = len(p)
        r2 = _per_point(r, N) ** 2
        total = np.zeros((N, 3))
        count = np.zeros(N, np.int64)
        pending = np.arange(N)
        k = 32
        # k-nearest with k growing x4 until no point has all k inside its radius
        while len(pending) and len(self):
            k = min(k, len(self))
            unsaturated = []
            for s, e in _chunks(len(pending), k):
                q = pending[s:e]
                r2_q = r2[q]
                d2, idx = self._index.query(take(p, q), k, np.sqrt(r2_q.max()) * (1 + 1e-6))
                inside = d2 < r2_q[:, None]
                done = ~inside[:, -1] | (k == len(self))
                inside &= done[:, None]
                rows, cols = np.nonzero(inside)
                j = idx[rows, cols]
                g = q[rows]
                ok, wi = self._accept(j, take(n, g))
                if accept is not None and ok.any():
                    ok[ok] = accept(g[ok], j[ok])
                g, j, wi = g[ok], j[ok], wi[ok]
                contrib = take(self.flux, j).astype(np.float64)
                if f is not None:
                    contrib *= f(g, wi)
                    nonzero = np.any(contrib != 0.0, axis=1)
                    g, contrib = g[nonzero], contrib[nonzero]
                for ch in range(3):
                    total[:, ch] += np.bincount(g, weights=contrib[:, ch], minlength=N)
                count += np.bincount(g, minlength=N)
                unsaturated.append(q[~done])
            pending = np.concatenate(unsaturated) if unsaturated else pending[:0]
            k *= 4
        return total, count


# ----------------------------------------------------------------------------------------------
# Radiance photons

class RadiancePhotons(_Points):
    """Irradiance precomputed at a subset of photons (Christensen 1999).

    position (R,3) world, normal (R,3) unit, E (R,3) [W m^-2]: the irradiance estimate from the
    photon map at each radiance photon. `lookup` answers with the E of the nearest radiance
    photon whose normal agrees with the query normal: one nearest-neighbour query per point.
    """

    LOOKUP_K = 8            # candidates examined for an agreeing normal
    COS_NORMAL_MIN = 0.5    # radiance photon normal . query normal must exceed this

    def __init__(self, position, normal, E):
        self._install(self.pack(position, normal, E))

    @staticmethod
    def rows(n_photons: int, stride: int = 4, offset: int = 0) -> np.ndarray:
        """Photon indices that become radiance photons: every stride-th (pbrt-v2 uses 1/8)."""
        return np.arange(offset % max(stride, 1), n_photons, max(stride, 1))

    @classmethod
    def build(cls, photon_map: PhotonMap, k: int, r_max, stride: int = 4, kernel: str = "uniform",
              min_count: int = 8, rows=None) -> "RadiancePhotons":
        """Radiance photons at photon_map's photons `rows` (default every stride-th), each with
        the irradiance estimate of the map at its position and normal (one k-NN estimate each;
        to spread the work over processes, estimate slices of rows and use the constructor)."""
        if rows is None:
            rows = cls.rows(len(photon_map), stride)
        position = take(photon_map.position, rows)
        normal = photon_map.normal(rows)
        E, _ = photon_map.irradiance(position, normal, k, r_max, kernel, min_count)
        return cls(position, normal, E)

    @staticmethod
    def pack(position, normal, E) -> dict[str, np.ndarray]:
        """position (R,3) float32, normal (R,2) int16 octahedral, E (R,3) float32: 28 B each,
        in Morton order as PhotonMap.pack."""
        position = np.asarray(position).reshape(-1, 3)
        order = morton_order(position)
        return {
            "position": take(position, order).astype(np.float32, copy=False),
            "normal": encode_octahedral(take(np.asarray(normal).reshape(-1, 3), order)),
            "E": take(np.asarray(E).reshape(-1, 3), order).astype(np.float32, copy=False),
        }

    @classmethod
    def from_packed(cls, arrays: dict) -> "RadiancePhotons":
        self = cls.__new__(cls)
        self._install(arrays)
        return self

    def _install(self, arrays: dict) -> None:
        p, nrm, E = arrays["position"], arrays["normal"], arrays["E"]
        m = len(p)
        if not (p.dtype == E.dtype == np.float32 and p.shape == E.shape == (m, 3)
                and nrm.dtype == np.int16 and nrm.shape == (m, 2)):
            raise ValueError("radiance photon arrays must be packed by RadiancePhotons.pack")
        self.arrays = {"position": p, "normal": nrm, "E": E}
        self.position, self._normal, self.E = p, nrm, E
        self._index = _Index(p)


    def lookup(self, p, n, r_max=np.inf, return_found: bool = False, accept=None):
        """Irradiance E (N,3) [W m^-2] at points p (N,3) with unit normals n (N,3): the E of the
        nearest radiance photon within r_max [m] (scalar or (N,)) whose normal agrees with n;
        0 where none does. One query of the LOOKUP_K nearest per point; the rare point whose
        candidates all disagree (a corner) is asked again with 4x as many. accept(rows (K,),
        j (K,)) -> (K,) bool, optional: a further test of the chosen candidate (visibility);
        a refused one passes the choice to the next candidate. With return_found, also the
        (N,) bool mask of points that found one."""
        p = np.asarray(p).reshape(-1, 3)
        n = np.asarray(n).reshape(-1, 3)
        N = len(p)
        out = np.zeros((N, 3))
        found = np.zeros(N, bool)
        r2_max = _per_point(r_max, N) ** 2
        pending = np.arange(N) if len(self) else np.zeros(0, np.int64)
        k = self.LOOKUP_K
        while len(pending):
            k = min(k, len(self))
            unresolved = []
            for s, e in _chunks(len(pending), k):
                q = pending[s:e]
                d2, idx = self._index.query(take(p, q), k, np.sqrt(r2_max[q].max()))
                inside = d2 < r2_max[q, None]
                rows, cols = np.nonzero(inside)
                j = idx[rows, cols]
                agree = dot(decode_octahedral(take(self._normal, j)), take(n, q[rows])) > self.COS_NORMAL_MIN
                valid = np.zeros(inside.shape, bool)
                valid[rows[agree], cols[agree]] = True
                first = np.argmax(valid, axis=1)  # the nearest agreeing candidate
                hit = valid[np.arange(e - s), first]
                check = np.flatnonzero(hit) if accept is not None else []
                while len(check):  # test the choices; a refused one hands on to the next
                    refused = check[~accept(q[check], idx[check, first[check]])]
                    valid[refused, first[refused]] = False
                    first[refused] = np.argmax(valid[refused], axis=1)
                    hit[refused] = valid[refused, first[refused]]
                    inside[refused, -1] = False  # refused candidates are no reason to ask again
                    check = refused[hit[refused]]
                out[q[hit]] = take(self.E, idx[np.arange(e - s), first][hit])
                found[q[hit]] = True
                unresolved.append(q[~hit & inside[:, -1]])  # all k inside: more may be within r_max
            pending = np.concatenate(unresolved) if k < len(self) else pending[:0]
            k *= 4
        return (out, found) if return_found else out
