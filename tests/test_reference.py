"""Ember through Blender (bpy.ops.render.render, engine EMBER) against Cycles references of
the same .blend (design.md test layer 4). References: scenes/reference.py, committed as
float EXR with the variance of their mean. Compared per pixel by a two-sided z-test
(Sidak-corrected, Mitsuba 3's acceptance of >= 99.75 % of pixels) and by relMSE, whose
expectation for an unbiased render is known from the variances.

1024 samples per pixel: pixels at the image border and next to the directly seen disk light
get their value from rare filter-tail samples; below ~1000 samples their estimated variance
is unreliable and the per-pixel normal approximation fails (the acceptance rates per sample
count are in bench/results/full/code_choices.md).

Honest variances under Sobol: the default sampling pattern stratifies each pixel's samples, so
their sample variance overstates the error of the pixel mean, several times over in variance on
these scenes (bench/results/full/code_choices.md). The samples are therefore split over SEEDS
independent renders; the spread of their means is an honest (if 3-dof) per-pixel variance, and
summed over pixels - relMSE's expectation, image and region means - it has thousands of degrees
of freedom. The per-pixel z-test keeps the within-pixel variance: a conservative screen for
outlier pixels, not what gives the test its power. The pooled tests are: the image mean and the
four quadrant means, each within a stated modelling tolerance (TOL_IMAGE, TOL_REGION:
tessellation, float32 tables and Cycles' own approximations, with the measured Ember / Cycles
ratios well inside) plus the Sidak-corrected noise band; a 2 % scale error exceeds both on
every scene (tests/mutations/run.py applies it)."""
import os
import pathlib
import tempfile

import numpy as np
import pytest

os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))
bpy = pytest.importorskip("bpy")

import ember  # noqa: E402
from ember.engine import imageio  # noqa: E402
from ember.engine.blender import final  # noqa: E402

from scipy import stats as st  # noqa: E402

from stats import sidak_alpha, z_test_images  # noqa: E402

pytestmark = pytest.mark.blender
ROOT = pathlib.Path(__file__).resolve().parents[1]
EPS = 1e-2  # relMSE stabiliser for [0,1]-scaled images (algorithms.md section 3)
SEEDS = 4  # independent renders, samples / SEEDS each
TOL_IMAGE = 0.005  # modelling tolerance of the image mean, relative
TOL_REGION = 0.01  # of each quadrant's mean


@pytest.fixture(scope="module", autouse=True)
def addon():
    ember.register()
    yield
    ember.unregister()


class _Film:
    def on_progress(self, layer, progress):
        self.film = progress.film


def render_with_ember(blend, width, height, samples, seed=1):
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    sc = bpy.context.scene
    sc.render.engine = "EMBER"
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = width, height, 100
    sc.ember.samples = samples
    sc.ember.seed = seed
    sc.ember.integrator = 'PATH'  # the unbiased one these z-tests are for (the default, auto, may choose another)
    grab = _Film()
    final.listeners.append(grab)
    try:
        bpy.ops.render.render()
    finally:
        final.listeners.remove(grab)
    return grab.film.mean(), grab.film.variance_of_mean()


def render_seeds(blend, width, height, samples):
    """SEEDS independent renders of samples / SEEDS each: (mean (H,W,3) of all samples,
    within-pixel variance of that mean (H,W,3), between-seed variance of that mean (H,W,3))."""
    runs = [render_with_ember(blend, width, height, samples // SEEDS, seed=1 + k) for k in range(SEEDS)]
    means = np.stack([m for m, _ in runs])
    within = np.stack([v for _, v in runs]).mean(axis=0) / SEEDS
    between = means.var(axis=0, ddof=1) / SEEDS
    return means.mean(axis=0), within, between


def pooled_checks(mean, var, ref, ref_var):
    """[(region, relative difference, its standard error, tolerance)] for the image mean and
    the four quadrant means; var, ref_var: honest variances of each pixel's mean."""
    h, w = ref.shape[:2]
    regions = {"image": (slice(None), slice(None))}
    for i, rows in enumerate((slice(0, h // 2), slice(h // 2, h))):
        for j, cols in enumerate((slice(0, w // 2), slice(w // 2, w))):
            regions[f"quadrant {'tb'[i]}{'lr'[j]}"] = (rows, cols)
    out = []
    for name, sl in regions.items():
        r = ref[sl].mean()
        if r <= 1e-4:
            continue  # a black region: the per-pixel test covers it
        n = ref[sl].size
        se = np.sqrt(var[sl].sum() + ref_var[sl].sum()) / n
        out.append((name, (mean[sl].mean() - r) / r, se / r, TOL_IMAGE if name == "image" else TOL_REGION))
    return out


def rel_mse(x, ref):
    return float(np.mean((x - ref) ** 2 / (ref**2 + EPS)))


@pytest.mark.parametrize("name,samples", [("cornell_box", 1024), ("lights", 1024), ("hdri", 1024),
                                          ("env_marker", 256),
                                          # materials (scenes/build_materials.py); the glossy box
                                          # (32x32) needs ~1000 spp: its mirror caustics are skewed
                                          ("cornell_glossy", 1024), ("glass_sphere", 512),
                                          ("textured_plane", 256)])
def test_matches_cycles_reference(name, samples):
    ref_path = ROOT / "tests" / "data" / f"{name}_cycles.exr"
    ch, header = imageio.read_exr(ref_path)
    ref = np.stack([ch["R"], ch["G"], ch["B"]], axis=-1).astype(np.float64)
    ref_var = np.stack([ch["var.R"], ch["var.G"], ch["var.B"]], axis=-1).astype(np.float64)
    h, w = ref.shape[:2]
    mean, var, honest = render_seeds(ROOT / "scenes" / f"{name}.blend", w, h, samples)
    assert np.all(np.isfinite(mean))
    accepted = z_test_images(mean, var, ref, ref_var, alpha=0.01)
    assert accepted >= 0.9975, f"{name}: only {accepted:.4%} of pixels agree with Cycles"
    # An unbiased render's expected relMSE is mean((var_ember + var_ref) / (ref^2 + eps)) with
    # honest variances (renders land close to it); a systematic difference (units, orientation,
    # a missing light path) adds its square on top.
    expected = float(np.mean((honest + ref_var) / (ref**2 + EPS)))
    measured = rel_mse(mean, ref)
    assert measured < 1.5 * expected, f"{name}: relMSE {measured:.3g} vs {expected:.3g} expected from noise"
    # Image and quadrant means: within the modelling tolerance plus the noise band.
    checks = pooled_checks(mean, honest, ref, ref_var)
    crit = st.norm.isf(sidak_alpha(0.01, len(checks)) / 2)
    bad = [f"{region}: {d:+.2%} (se {se:.2%})" for region, d, se, tol in checks if abs(d) > tol + crit * se]
    assert not bad, f"{name}: mean differs from Cycles: " + "; ".join(bad)
    # The image band must be narrow enough to see a 2 % error.
    assert all(tol + crit * se < 0.015 for region, _, se, tol in checks if region == "image"), checks
