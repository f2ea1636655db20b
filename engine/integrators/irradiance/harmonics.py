"""Real spherical harmonics, the basis of radiance records (engine/integrators/irradiance/radiance.py).

Order n means bands l = 0 .. n-1, B = n^2 functions, index b = l (l + 1) + m (-l <= m <= l):

    Y_l^0 = K_l^0 P_l^0(cos theta),
    Y_l^m = sqrt(2) K_l^m P_l^m(cos theta) cos(m phi),      m > 0,
    Y_l^m = sqrt(2) K_l^|m| P_l^|m|(cos theta) sin(|m| phi), m < 0,

K_l^m = sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!), P_l^m the associated Legendre functions without the
Condon-Shortley phase (Sloan, "Stupid spherical harmonics tricks", 2008, whose recurrences these
are). Orthonormal over the sphere: int Y_a Y_b dw = delta_ab.

Why the full sphere and not hemispherical harmonics (Gautron et al. 2004, used by Krivanek et
al. 2005): the coefficients are kept in *world* space, so a record applies to a query point with
another normal without rotating its coefficient vector (the rotation is exact and free); SH are
the basis that is closed under rotation. A record's hemisphere is extended evenly below its
tangent plane (radiance.py), which keeps the function continuous at the horizon.

Truncation (Ramamoorthi and Hanrahan 2002, "Frequency space environment map rendering"): the
SH coefficients of a Phong lobe cos^s fall as about exp(-l^2 / (2 s)) with the band l. Keeping
bands l < n, the first band dropped has weight exp(-n^2 / (2 s)); requiring it <= e^-2 gives
s <= n^2 / 4, the sharpest lobe `max_phong_exponent(n)` the basis serves. (e^-1, s <= n^2 / 2,
proved too loose: on the rough box of tests/test_radiance_cache.py a floor at that threshold
came out visibly too dark or too bright. The clamped cosine's horizon adds its own slowly
decaying bands, so even wide lobes need n >= 6. Measured in bench/results/icache/code_choices.md.)
"""
import numpy as np


def coefficient_count(order: int) -> int:
    order = int(order)
    if order < 1:
        raise ValueError(f"the harmonics order must be >= 1, got {order}")
    return order * order


def max_phong_exponent(order: int) -> float:
    """The sharpest Phong lobe cos^s the basis of this order represents well: s = n^2 / 4."""
    return 0.25 * float(order) ** 2


def min_roughness(order: int) -> float:
    """Blender roughness r (GGX alpha = r^2) of that lobe, by Mitsuba 0.6's equivalence
    alpha = sqrt(2 / (s + 2)) (algorithms.md section 1.2): order 7 -> s 12.25 -> r 0.61."""
    return float(np.sqrt(np.sqrt(2.0 / (max_phong_exponent(order) + 2.0))))


def evaluate(order: int, w) -> np.ndarray:
    """Y_b(w) for unit directions w (..., 3): (..., B) float64 (index b = l (l + 1) + m).

    Computed from x, y, z without trigonometry: sin^m(theta) cos(m phi) and sin^m(theta)
    sin(m phi) are the real and imaginary parts of (x + i y)^m, and P_l^m / sin^m(theta) is a
    polynomial in z (the recurrences in l at fixed m)."""
    B = coefficient_count(order)
    w = np.asarray(w, dtype=np.float64)
    x, y, z = w[..., 0], w[..., 1], w[..., 2]
    out = np.empty(w.shape[:-1] + (B,))
    c, s = np.ones_like(x), np.zeros_like(x)           # Re, Im of (x + i y)^m
    pmm = np.ones_like(z)                               # P_m^m / sin^m = (2m - 1)!!
    for m in range(order):
        if m:
            c, s = c * x - s * y, c * y + s * x
            pmm = pmm * (2 * m - 1)
        p_prev, p = None, pmm                           # P_l^m / sin^m for l = m, m+1, ...
        for l in range(m, order):
            if l == m + 1:
                p_prev, p = p, z * (2 * m + 1) * pmm
            elif l > m + 1:
                p_prev, p = p, ((2 * l - 1) * z * p - (l + m - 1) * p_prev) / (l - m)
            k = np.sqrt((2 * l + 1) / (4 * np.pi) * _factorial_ratio(l, m))
            if m == 0:
                out[..., l * (l + 1)] = k * p
            else:
                out[..., l * (l + 1) + m] = np.sqrt(2.0) * k * p * c
                out[..., l * (l + 1) - m] = np.sqrt(2.0) * k * p * s
    return out


def _factorial_ratio(l: int, m: int) -> float:
    """(l - m)! / (l + m)!"""
    r = 1.0
    for i in range(l - m + 1, l + m + 1):
        r /= i
    return r
