"""Light-path controls, depth of field and ray visibility against Cycles references of the same
.blend (scenes/build_light_paths.py: one control changed per scene, 32x32, 16 runs x 1024
spp), through Blender as tests/test_reference.py does: per-pixel z-test, relMSE against its
expectation from the honest (between-seed) variances, and the image and quadrant means.
Each scene differs visibly from the same scene without its control (the test's power: see
test_controls_change_the_image)."""
import numpy as np
import pytest
from scipy import stats as st

from test_reference import ROOT, EPS, addon, pooled_checks, rel_mse, render_seeds  # noqa: F401
from stats import sidak_alpha, z_test_images

from ember.engine import imageio

pytestmark = pytest.mark.blender
SCENES = ["lp_diffuse", "lp_glossy", "lp_transmission", "lp_caustics", "dof_round", "dof_blades",
          "vis_camera", "vis_diffuse", "vis_shadow", "vis_holdout", "vis_meshlight", "vis_glossy",
          "vis_transmission", "vis_lights", "vis_world"]
SAMPLES = 512
# The lights scene has pixels lit by small, bright lights whose variance estimate is unreliable
# below ~1000 spp (tests/test_reference.py; bench/results/full/code_choices.md).
SAMPLES_OF = {"vis_lights": 1024}


def _reference(name):
    ch, _ = imageio.read_exr(ROOT / "tests" / "data" / f"{name}_cycles.exr")
    ref = np.stack([ch["R"], ch["G"], ch["B"]], axis=-1).astype(np.float64)
    ref_var = np.stack([ch["var.R"], ch["var.G"], ch["var.B"]], axis=-1).astype(np.float64)
    return ref, ref_var


def compare(name, mean, var, honest):
    """Failures (list of str) of Ember's render against the Cycles reference of `name`."""
    ref, ref_var = _reference(name)
    bad = []
    accepted = z_test_images(mean, var, ref, ref_var, alpha=0.01)
    if accepted < 0.9975:
        bad.append(f"only {accepted:.2%} of pixels agree")
    expected = float(np.mean((honest + ref_var) / (ref**2 + EPS)))
    measured = rel_mse(mean, ref)
    if not measured < 1.5 * expected:
        bad.append(f"relMSE {measured:.3g} vs {expected:.3g} expected from noise")
    checks = pooled_checks(mean, honest, ref, ref_var)
    crit = st.norm.isf(sidak_alpha(0.01, len(checks)) / 2)
    bad += [f"{region}: {d:+.2%} (se {se:.2%})" for region, d, se, tol in checks if abs(d) > tol + crit * se]
    return bad


@pytest.mark.parametrize("name", SCENES)
def test_matches_cycles_reference(name):
    ref, _ = _reference(name)
    mean, var, honest = render_seeds(ROOT / "scenes" / f"{name}.blend", ref.shape[1], ref.shape[0],
                                     SAMPLES_OF.get(name, SAMPLES))
    assert np.all(np.isfinite(mean))
    bad = compare(name, mean, var, honest)
    assert not bad, f"{name}: " + "; ".join(bad)
