"""Make the references bench/run.py measures error against, one EXR per scene.

    python bench/references.py [--only NAME ...] [--force] [--resolution 64]

Cycles (scenes/reference.py: CPU, unbiased settings, the scene's own pixel filter, mean and
variance of independent runs, samples/time/version in the header) renders each scene of
bench/scenes.py at the bench resolution, `ref_runs` x `ref_samples` samples; scenes whose
`reference` is "mitsuba" are then finished by bench/mitsuba_reference.py. Existing files are
kept unless --force. Runs one render at a time.
"""
from __future__ import annotations

import argparse
import os
import pathlib
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_bur_"))
from bench.scenes import ROOT, available  # noqa: E402

RESOLUTION = 64


def reference_path(scene, resolution=RESOLUTION):
    if scene.name == "cornell_box" and resolution == 64:  # the test suite's, 16 x 1024 spp
        return ROOT / "tests" / "data" / "cornell_box_cycles.exr"
    return ROOT / "bench" / "references" / f"{scene.name}_{resolution}.exr"


def cycles_reference(scene, out, resolution, blend=None):
    cmd = [sys.executable, str(ROOT / "scenes" / "reference.py"), str(blend or scene.reference_path),
           "--out", str(out), "--resolution", f"{resolution}x{resolution}",
           "--runs", str(scene.ref_runs), "--samples", str(scene.ref_samples)]
    subprocess.run(cmd, check=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", action="append", help="scene name (repeatable)")
    ap.add_argument("--force", action="store_true", help="re-render existing references")
    ap.add_argument("--resolution", type=int, default=RESOLUTION)
    args = ap.parse_args(argv)
    scenes, notes = available(args.only)
    for n in notes:
        print("note:", n)
    for s in scenes:
        out = reference_path(s, args.resolution)
        if out.exists() and not args.force:
            print(f"{s.name}: {out.relative_to(ROOT)} exists")
            continue
        out.parent.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        if s.reference == "mitsuba":
            try:
                import mitsuba  # noqa: F401
            except ImportError:
                print(f"{s.name}: skipped: its reference needs Mitsuba 3 (pip install mitsuba, see bench/README.md)")
                continue
            from _bootstrap import load_ember
            load_ember()
            from bench import mitsuba_reference
            mitsuba_reference.make(s, out, args.resolution)
        else:
            cycles_reference(s, out, args.resolution)
        print(f"{s.name}: {out.relative_to(ROOT)} in {time.perf_counter() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    main()
