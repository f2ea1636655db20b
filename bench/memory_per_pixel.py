"""Peak memory per pixel of a render through render.py, the figures behind engine/validation.py's
FILM_BYTES_PER_PIXEL and PASS_BYTES_PER_CHANNEL, and the irradiance cache's records per pixel
(RECORDS_PER_PIXEL). One process (--threads 1): its peak resident size at two resolutions;
the difference over the difference in pixels is what a pixel costs.

    .venv/bin/python bench/memory_per_pixel.py   -> bench/results/reliability/memory.md
"""
from __future__ import annotations

import os
import pathlib
import re
import subprocess
import sys
import tempfile
import textwrap

ROOT = pathlib.Path(__file__).resolve().parents[1]
OUT = ROOT / "bench" / "results" / "reliability" / "memory.md"
SIZES = (200, 1400)

BUILD = textwrap.dedent('''
    import sys, bpy, mathutils
    out = sys.argv[-1]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    me = bpy.data.meshes.new("plane")
    me.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    me.update()
    sc.collection.objects.link(bpy.data.objects.new("plane", me))
    ld = bpy.data.lights.new("lamp", 'POINT'); ld.energy = 500.0
    lo = bpy.data.objects.new("lamp", ld); lo.location = (1, -1, 3); sc.collection.objects.link(lo)
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam")); cam.location = (0, -5, 4)
    sc.collection.objects.link(cam)
    cam.rotation_euler = (mathutils.Vector((0, 0, 0)) - cam.location).to_track_quat('-Z', 'Y').to_euler()
    sc.camera = cam
    bpy.ops.wm.save_as_mainfile(filepath=out + "/plain.blend")
    vl = sc.view_layers[0]
    vl.use_pass_z = vl.use_pass_normal = vl.use_pass_diffuse_direct = vl.use_pass_emit = True
    sc.render.film_transparent = True
    bpy.ops.wm.save_as_mainfile(filepath=out + "/passes.blend")
''')
PASS_CHANNELS = 1 + 3 + 3 + 3 + 3 + 1  # Depth, Normal, Diffuse Direct and Color, Emission; alpha


def peak(d: pathlib.Path, blend: str, size: int) -> int:
    proc = subprocess.Popen([sys.executable, str(ROOT / "render.py"), str(d / blend), "-o", str(d / "m.exr"),
                             "--resolution", f"{size}x{size}", "--samples", "1", "--threads", "1",
                             "--integrator", "path", "--no-progress"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    assert status == 0, blend
    return usage.ru_maxrss * 1024


def per_pixel(d, blend) -> float:
    a, b = (peak(d, blend, n) for n in SIZES)
    return (b - a) / (SIZES[1] ** 2 - SIZES[0] ** 2)


def records_per_pixel(size: int) -> float:
    proc = subprocess.run([sys.executable, str(ROOT / "render.py"), str(ROOT / "scenes" / "cornell_box.blend"),
                           "-o", str(pathlib.Path(tempfile.gettempdir()) / "ember_records.exr"),
                           "--integrator", "icache", "--samples", "2", "--resolution", f"{size}x{size}",
                           "--no-progress"], capture_output=True, text=True)
    m = re.search(r"(\d+) records", proc.stdout)
    return int(m.group(1)) / size ** 2


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        d = pathlib.Path(tmp)
        subprocess.run([sys.executable, "-c", BUILD, str(d)], check=True, capture_output=True)
        plain, passes = per_pixel(d, "plain.blend"), per_pixel(d, "passes.blend")
    records = {n: records_per_pixel(n) for n in (100, 200)}
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(
        "# Memory per pixel (bench/memory_per_pixel.py)\n\n"
        f"Peak resident size of `render.py --threads 1 --samples 1 --integrator path`, {SIZES[0]}^2 vs "
        f"{SIZES[1]}^2 pixels, difference per pixel:\n\n"
        "| render | bytes per pixel | engine/validation.py |\n|---|---|---|\n"
        f"| Combined only | {plain:.0f} | FILM_BYTES_PER_PIXEL = 400 |\n"
        f"| + {PASS_CHANNELS} pass channels (Depth, Normal, Diffuse Direct and Color, Emission, alpha) | "
        f"{passes:.0f} ({(passes - plain) / PASS_CHANNELS:.1f} per channel) | PASS_BYTES_PER_CHANNEL = 20 |\n\n"
        "Irradiance cache records per pixel (cornell_box.blend, 2 samples): "
        + ", ".join(f"{n}x{n}: {r:.3f}" for n, r in records.items())
        + " (RECORDS_PER_PIXEL = 0.125 bounds them).\n")
    print(OUT.read_text())


if __name__ == "__main__":
    main()
