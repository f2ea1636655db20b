"""Local features against exact values, rendered through the core without Blender: a spot
light's cone and its smoothstep blend on a diffuse floor (region z-tests on the blend ring, the
cone's inside and the dark outside), and the camera's orientation (a marker in the upper-left of
the view must land in the upper-left of the image).

The spot floor is lit only directly (one plane under a black world: nothing reflects back), so
the exact pixel value is the direct-light formula averaged over the pixel's footprint (the box
filter spreads samples uniformly over it); independent samples (pattern "random") make the
per-pixel sample variance honest, and a region's mean has the variance of the sum of its pixels.
"""
import numpy as np
import pytest
from scipy import stats as st

from ember.engine.scene import (LIGHT_SPOT, MAT_DIFFUSE, MAT_EMISSION_ONLY, Camera, Lights, Materials,
                                Scene, World)
from ember.engine.session import RenderSession

from core_scenes import perspective, quads_mesh, settings
from stats import sidak_alpha

ALBEDO = 0.6
HEIGHT = 2.0  # the spot hangs this far above the floor, pointing straight down
INTENSITY = 30.0  # W/sr (a delta spot: Le is the intensity)
COS_HALF = np.cos(np.radians(30.0))  # cone half angle 30 degrees
SMOOTH = 0.08  # Cycles' spot_smooth: the blend spans cos in [COS_HALF, COS_HALF + SMOOTH]
EXTENT = 1.6  # the orthographic camera sees [-EXTENT, EXTENT]^2 of the floor
RES = 48


def _spot_scene(samples, seed=3):
    floor = quads_mesh([[[-10, -10, 0], [10, -10, 0], [10, 10, 0], [-10, 10, 0]]], [0])
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(ALBEDO,) * 3)])
    # frame rows = the light's x, y, z axes; a spot shines along its -z: z = +z points it down.
    lights = Lights.make([dict(kind=LIGHT_SPOT, position=(0.3, -0.2, HEIGHT), frame=np.eye(3), radius=0.0,
                               Le=(INTENSITY,) * 3, spot_cos_half=COS_HALF, spot_smooth=SMOOTH)])
    m = np.eye(4)
    m[:3, 3] = (0.0, 0.0, 5.0)  # looking down -z from above; +y is up in the image
    cam = Camera(world_from_camera=m, window=np.array([-EXTENT, EXTENT, -EXTENT, EXTENT]), ortho=True)
    s = settings(width=RES, height=RES, samples=samples, seed=seed, pattern="random", filter="BOX",
                 filter_width=1.0, max_depth=4)
    return Scene(floor, mats, lights, World(), cam, s)


def _smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _exact_floor_radiance(x, y):
    """Radiance leaving the floor at (x, y) towards the camera: rho / pi * I * att * cos / d^2."""
    dx, dy, dz = x - 0.3, y + 0.2, -HEIGHT
    d2 = dx * dx + dy * dy + dz * dz
    cos_axis = HEIGHT / np.sqrt(d2)  # angle between the spot's axis (down) and the lit point
    att = _smoothstep((cos_axis - COS_HALF) / SMOOTH)
    return ALBEDO / np.pi * INTENSITY * att * cos_axis / d2


def _exact_pixels(order=12):
    """(RES, RES) pixel means of the exact radiance over each pixel's square (Gauss-Legendre)."""
    t, w = np.polynomial.legendre.leggauss(order)
    t, w = 0.5 * (t + 1.0), 0.5 * w
    size = 2.0 * EXTENT / RES
    col = np.arange(RES)[:, None] + t[None, :]  # (RES, order) positions inside each pixel
    xs = -EXTENT + size * col  # pixel columns left to right
    ys = EXTENT - size * col  # pixel rows from the top
    X = xs[None, None, :, :]
    Y = ys[:, :, None, None]
    values = _exact_floor_radiance(X, Y)  # (row, i, col, j)
    return np.einsum("aibj,i,j->ab", values, w, w)


@pytest.fixture(scope="module")
def spot_render():
    session = RenderSession(_spot_scene(samples=256))
    stats = session.run()
    assert stats.nonfinite == 0
    mean = session.film.mean().mean(axis=2)  # grey light and floor: channels equal
    var = session.film.variance_of_mean().mean(axis=2)
    return mean, var


def _regions():
    """Masks (RES, RES) of the cone's inside, the inner and outer halves of the blend ring and
    the dark outside, from the cosine to the spot's axis at each pixel centre."""
    size = 2.0 * EXTENT / RES
    c = -EXTENT + size * (np.arange(RES) + 0.5)
    X, Y = np.meshgrid(c, c[::-1])
    cos_axis = HEIGHT / np.sqrt((X - 0.3) ** 2 + (Y + 0.2) ** 2 + HEIGHT ** 2)
    x = (cos_axis - COS_HALF) / SMOOTH
    margin = 0.15  # > half a pixel diagonal in x: pixels straddling a region edge stay out
    return {"inside": x > 1 + margin, "ring_inner": (x > 0.5 + margin) & (x < 1 - margin),
            "ring_outer": (x > margin) & (x < 0.5 - margin), "outside": x < -margin}


def test_spot_cone_pixels_match_the_exact_profile(spot_render):
    mean, var = spot_render
    exact = _exact_pixels()
    z = (mean - exact) / np.sqrt(np.maximum(var, 1e-12))
    crit = st.norm.isf(sidak_alpha(0.01, z.size) / 2)
    assert np.abs(z).max() < crit, f"max |z| {np.abs(z).max():.2f} >= {crit:.2f}"


def test_spot_cone_regions_match_the_exact_profile(spot_render):
    """Region means of the blend ring (inner and outer half), the full cone and the outside: a
    linear ramp instead of the smoothstep is ~10 % off in each half of the ring."""
    mean, var = spot_render
    exact = _exact_pixels()
    regions = _regions()
    crit = st.norm.isf(sidak_alpha(0.01, len(regions)) / 2)
    for name, mask in regions.items():
        assert mask.sum() >= 20, (name, mask.sum())
        d = mean[mask].mean() - exact[mask].mean()
        se = np.sqrt(var[mask].sum()) / mask.sum()
        if name == "outside":
            assert np.all(mean[mask] == 0.0), "light outside the spot cone"
            continue
        assert abs(d) < crit * se, f"{name}: {mean[mask].mean():.5g} vs exact {exact[mask].mean():.5g} (se {se:.2g})"
        assert se < 0.01 * exact[mask].mean(), f"{name}: too noisy to see a 3 % error"


# ----------------------------------------------------------------------------------------------
# Camera orientation

def test_marker_in_the_upper_left_of_the_view_is_in_the_upper_left_of_the_image():
    """Camera at -y looking along +y with +z up: the world's -x is the image's left, +z its top.
    An emitter in the upper-left quadrant lights exactly the upper-left pixels (rows from the top,
    as the film stores them); a camera flipped in x or y moves it to another corner."""
    wall = [[[-3, 0.01, -3], [3, 0.01, -3], [3, 0.01, 3], [-3, 0.01, 3]]]
    marker = [[[-2.0, 0.0, 1.0], [-1.0, 0.0, 1.0], [-1.0, 0.0, 2.0], [-2.0, 0.0, 2.0]]]
    mesh = quads_mesh(np.array(wall + marker), [0, 1])
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(0.0, 0.0, 0.0)),
                           dict(kind=MAT_EMISSION_ONLY, base_color=(0, 0, 0), emission=(1.0, 2.0, 3.0))])
    cam = perspective((0.0, -6.0, 0.0), (0.0, 0.0, 0.0), 60)
    scene = Scene(mesh, mats, Lights.make([]), World(), cam, settings(width=24, height=24, samples=4))
    session = RenderSession(scene)
    session.run()
    img = session.film.mean()[..., 0]
    lit = img > 0
    # The marker spans x in [-2, -1], z in [1, 2] at distance 6 with a 60 degree view: its image
    # lies in columns / rows (1 - 2/(6 tan 30)) / 2 * 24 .. (1 - 1/(6 tan 30)) / 2 * 24, i.e.
    # about 1.6 .. 6.8 from the left and from the top.
    t = np.tan(np.radians(30.0))
    lo, hi = (1 - 2 / (6 * t)) / 2 * 24, (1 - 1 / (6 * t)) / 2 * 24
    rows, cols = np.nonzero(lit)
    assert len(rows) > 10
    assert rows.min() >= np.floor(lo) - 1 and rows.max() <= np.ceil(hi) and cols.min() >= np.floor(lo) - 1 \
        and cols.max() <= np.ceil(hi), (rows.min(), rows.max(), cols.min(), cols.max(), lo, hi)
    assert img[int(np.ceil(lo)) + 1, int(np.ceil(lo)) + 1] == pytest.approx(1.0)  # the marker's inside
    assert not lit[12:].any() and not lit[:, 12:].any()
