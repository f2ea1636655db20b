"""The caustic under a glass sphere (scenes/caustic.blend: a small emissive sphere, L S+ D E)
against Mitsuba 3's particle tracer (bench/references/caustic_64.exr, bench/mitsuba_reference.py).

The caustic's energy (the mean over the caustic region, bench/regions.py) within
3 % of the reference. A path tracer reaches the light through the glass only by rare
BSDF-sampled rays: at 64 samples its caustic is a few fireflies, far off in the region's
relMSE, which shows the region's metrics tell a caustic from noise. The margins of these
tests are in bench/results/photon/code_choices.md.
"""
import pathlib

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from bench import regions  # noqa: E402
from ember.engine import imageio  # noqa: E402
from ember.engine.session import RenderSession  # noqa: E402

pytestmark = pytest.mark.blender
ROOT = pathlib.Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def caustic():
    from ember.engine.blender.export import export_scene

    bpy.ops.wm.open_mainfile(filepath=str(ROOT / "scenes" / "caustic.blend"), load_ui=False)
    scene = export_scene(bpy.context.evaluated_depsgraph_get())[0]
    ch, _ = imageio.read_exr(ROOT / "bench" / "references" / "caustic_64.exr")
    reference = np.stack([ch[c] for c in "RGB"], -1).astype(np.float64)
    settings = scene.settings.replace(width=64, height=64, border=(0, 0, 64, 64))
    mask = regions.bright_region(reference, regions.CAUSTIC_SEEDS["caustic"])
    assert mask.sum() >= 10
    return scene.replace(settings=settings), reference, mask


def _render(scene, **kw):
    session = RenderSession(scene.replace(settings=scene.settings.replace(**kw)))
    stats = session.run()
    assert stats.nonfinite == 0
    return session.film.mean()


@pytest.mark.parametrize("integrator, kw", [
    ("photon", dict(samples=16)),
    ("ppm", dict(samples=32, photons=100_000)),
])
def test_caustic_energy_matches_the_particle_tracer(caustic, integrator, kw):
    scene, reference, mask = caustic
    image = _render(scene, integrator=integrator, seed=1, **kw)
    m = regions.region_metrics(image, reference, mask)
    assert abs(m["mean_ratio"] - 1.0) < 0.03, m
    assert m["relmse"] < 0.05, m  # a few times what either integrator gives


def test_a_path_tracer_finds_the_caustic_only_as_fireflies(caustic):
    scene, reference, mask = caustic
    m = regions.region_metrics(_render(scene, integrator="path", samples=64, seed=1), reference, mask)
    assert m["relmse"] > 1.0, m  # many times the photon maps' error, which take fewer samples


@pytest.mark.slow
def test_ppm_error_keeps_falling_with_passes(caustic):
    """The log-log slope of relMSE against passes between 16 and 256 is steeper than
    -0.5 (a fixed-radius photon map would flatten out at its bias)."""
    scene, reference, mask = caustic
    from bench.metrics import rel_mse

    errors = {}

    def update(progress):
        if progress.pass_completed and progress.samples_done in (16, 256):
            errors[progress.samples_done] = rel_mse(progress.film.mean(), reference)

    session = RenderSession(scene.replace(settings=scene.settings.replace(integrator="ppm", samples=256,
                                                                          photons=100_000, seed=3)))
    session.run(on_update=update)
    slope = np.log(errors[256] / errors[16]) / np.log(256 / 16)
    print(f"ppm relMSE {errors[16]:.4e} at 16 passes, {errors[256]:.4e} at 256: slope {slope:.3f}")
    assert slope < -0.5, (errors, slope)
