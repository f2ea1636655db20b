"""The benchmark's scenes: .blend files in scenes/, each built by a script there.

A scene whose file is missing is skipped with a note (other scripts' scenes join when they
land), so the list may name files that do not exist yet. `reference` says how its ground
truth is made (bench/references.py): "cycles" renders `reference_blend` (default: the scene
itself) with Cycles; "mitsuba" adds Mitsuba 3's particle tracer (bench/mitsuba_reference.py).
"""
from __future__ import annotations

import pathlib
from dataclasses import dataclass

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCENES_DIR = ROOT / "scenes"


@dataclass(frozen=True)
class BenchScene:
    name: str
    file: str  # in scenes/
    built_by: str  # the script that writes `file`
    quick: bool = False  # part of --quick
    reference: str = "cycles"  # "cycles" or "mitsuba"
    reference_blend: str = ""  # rendered for the reference instead of `file`
    ref_runs: int = 16  # Cycles reference: independent runs x samples per run
    ref_samples: int = 256
    note: str = ""

    @property
    def path(self) -> pathlib.Path:
        return SCENES_DIR / self.file

    @property
    def reference_path(self) -> pathlib.Path:
        return SCENES_DIR / (self.reference_blend or self.file)


SCENES = (
    BenchScene("cornell_box", "cornell_box.blend", "scenes/build.py", quick=True, ref_samples=1024,
               note="diffuse; measured Cornell geometry, Mitsuba 3 colours"),
    BenchScene("cornell_glossy", "cornell_glossy.blend", "scenes/build_materials.py",
               note="microfacet boxes, mirror sphere"),
    BenchScene("veach_mis", "veach_mis.blend", "scenes/build_materials.py", quick=True,
               note="Veach's MIS plates (Bitterli's port)"),
    BenchScene("hdri", "hdri.blend", "scenes/build_world.py", quick=True,
               note="objects under a procedural HDRI with a small bright sun"),
    BenchScene("caustic", "caustic.blend", "scenes/build_bench.py", reference="mitsuba",
               note="glass sphere on a diffuse floor, 3 cm spherical emitter"),
    BenchScene("caustic_point", "caustic_point.blend", "scenes/build_bench.py", reference="mitsuba",
               note="the caustic scene lit by a radius-0 point light of the emitter's power"),
    BenchScene("interior", "interior.blend", "scenes/build_bench.py", quick=True, ref_samples=1024,
               note="room lit through a window by sun and sky"),
    BenchScene("hard_tiny_light", "hard_tiny_light.blend", "scenes/build_bench.py",
               note="1 cm light at the Cornell light's power"),
    BenchScene("hard_light_near_wall", "hard_light_near_wall.blend", "scenes/build_bench.py",
               ref_samples=1024, note="area light edge 5 mm from a wall"),
    BenchScene("hard_degenerate", "hard_degenerate.blend", "scenes/build_bench.py",
               reference_blend="hard_degenerate_clean.blend",
               note="zero-area (one emissive) and duplicated triangles; reference without them"),
    BenchScene("hard_phong", "hard_phong.blend", "scenes/build_bench.py", ref_samples=1024,
               note="near-mirror floor: Beckmann alpha 0.01, the lobe of Phong n = 19998"),
    BenchScene("hard_far_origin", "hard_far_origin.blend", "scenes/build_bench.py",
               note="Cornell box 1e4 m from the origin"),
    BenchScene("hard_grazing", "hard_grazing.blend", "scenes/build_bench.py",
               note="camera 25 cm above a checkerboard, 4 degrees down"),
    BenchScene("procedural", "procedural.blend", "scenes/build_procedural.py", ref_samples=1024,
               note="five procedural materials of 27-33 nodes (noise, Voronoi, ramps, bump) under an HDRI"),
)


def available(names=None, quick=False):
    """(scenes to run, notes on those skipped). names: subset by name (None = all, or the
    quick ones with quick=True)."""
    chosen = [s for s in SCENES if (s.name in names if names else (s.quick or not quick))]
    unknown = sorted(set(names or ()) - {s.name for s in SCENES})
    notes = [f"unknown scene '{n}' (known: {', '.join(s.name for s in SCENES)})" for n in unknown]
    run = []
    for s in chosen:
        if s.path.is_file():
            run.append(s)
        else:
            notes.append(f"{s.name}: skipped, scenes/{s.file} not found (built by {s.built_by})")
    return run, notes


def by_name(name: str) -> BenchScene:
    for s in SCENES:
        if s.name == name:
            return s
    raise KeyError(name)
