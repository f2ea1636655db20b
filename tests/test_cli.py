"""render.py as users run it: `python render.py scene.blend [options]` in a subprocess,
on small scenes saved into a temporary directory. Exit codes, one-line errors, outputs."""
from __future__ import annotations

import os
import pathlib
import struct
import subprocess
import sys
import textwrap
import zlib

import numpy as np
import pytest

pytestmark = pytest.mark.blender

ROOT = pathlib.Path(__file__).resolve().parents[1]
RENDER = ROOT / "render.py"

BUILD = textwrap.dedent('''
    import sys, bpy, mathutils
    out = sys.argv[-1]

    def scene(name, camera=True, geometry=True):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        sc = bpy.context.scene
        sc.render.resolution_x, sc.render.resolution_y = 24, 16
        sc.render.resolution_percentage = 100
        if geometry:
            me = bpy.data.meshes.new("plane")
            me.from_pydata([(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], [], [(0, 1, 2, 3)])
            me.update()
            sc.collection.objects.link(bpy.data.objects.new("plane", me))
            ld = bpy.data.lights.new("lamp", 'POINT')
            ld.energy = 500.0
            lo = bpy.data.objects.new("lamp", ld)
            lo.location = (1, -1, 3)
            sc.collection.objects.link(lo)
        if camera:
            cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
            cam.location = (0, -5, 4)
            sc.collection.objects.link(cam)
            cam.rotation_euler = (mathutils.Vector((0, 0, 0)) - cam.location).to_track_quat('-Z', 'Y').to_euler()
            sc.camera = cam
        bpy.ops.wm.save_as_mainfile(filepath=out + "/" + name + ".blend")

    scene("ok")
    scene("nocam", camera=False)
    scene("empty", geometry=False)
''')


def _env(tmp):
    env = dict(os.environ)
    env["BLENDER_USER_RESOURCES"] = str(tmp / "blender_user")
    env["TMPDIR"] = str(tmp)
    env.pop("PYTHONPATH", None)
    return env


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    pytest.importorskip("bpy")
    d = tmp_path_factory.mktemp("cli")
    proc = subprocess.run([sys.executable, "-c", BUILD, str(d)], env=_env(d), capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    (d / "not_a_blend.blend").write_text("this is not a blend file\n")
    return d


def run(scenes, *args):
    proc = subprocess.run([sys.executable, str(RENDER), *map(str, args)], cwd=scenes, env=_env(scenes),
                          capture_output=True, text=True, timeout=180)
    return proc.returncode, proc.stdout, proc.stderr


def _one_clear_line(stderr, *words):
    lines = [l for l in stderr.strip().splitlines() if l.strip()]
    assert len(lines) == 1, stderr
    assert "Traceback" not in stderr
    assert lines[0].startswith("render.py: error: ")
    for w in words:
        assert w.lower() in lines[0].lower(), (w, lines[0])


@pytest.mark.parametrize("args, words", [
    (["missing.blend"], ["not found", "missing.blend"]),
    (["not_a_blend.blend"], ["not a .blend"]),
    (["ok.blend", "--samples", "-4"], ["--samples", "at least 1"]),
    (["ok.blend", "--samples", "many"], ["--samples"]),
    (["ok.blend", "--resolution", "64by32"], ["--resolution", "WIDTHxHEIGHT"]),
    (["ok.blend", "--resolution", "0x32"], ["--resolution"]),
    (["ok.blend", "--time-limit", "-1"], ["--time-limit"]),
    (["ok.blend", "--max-depth", "-1"], ["--max-depth", "at least 0"]),
    (["ok.blend", "--pattern", "halton"], ["--pattern", "sobol", "random"]),
    (["ok.blend", "--ppm-alpha", "1.5"], ["--ppm-alpha", "at most 0.99"]),
    (["ok.blend", "--photon-k", "1"], ["--photon-k", "at least 2"]),
    (["ok.blend", "--radiance-photons", "maybe"], ["--radiance-photons", "on or off"]),
    (["ok.blend", "--global-radius", "-1"], ["--global-radius"]),
    (["ok.blend", "--diffuse-bounces", "0"], ["--diffuse-bounces", "at least 1"]),
    (["ok.blend", "--clamp-indirect", "-1"], ["--clamp-indirect"]),
    (["ok.blend", "--caustics-refractive", "maybe"], ["--caustics-refractive", "on or off"]),
    (["ok.blend", "-o", "no/such/dir/out.png"], ["output directory does not exist"]),
    (["ok.blend", "-o", "ok.blend/out.png"], ["output directory does not exist"]),
    (["ok.blend", "-o", "out.jpg"], [".png or .exr"]),
    ([], ["blend"]),
])
def test_bad_input_fast(scenes, args, words):
    """Checked before bpy is even imported."""
    code, out, err = run(scenes, *args)
    assert code == 2
    _one_clear_line(err, *words)


@pytest.mark.parametrize("name, args, words", [
    ("nocam.blend", [], ["camera"]),
    ("empty.blend", [], ["nothing to render"]),
    ("ok.blend", ["--integrator", "bidir"], ["integrator", "path", "photon", "ppm"]),
    ("ok.blend", ["--integrator", "photon", "--photon-view", "photons"], ["--photon-view", "global"]),
])
def test_bad_scene_or_option(scenes, name, args, words):
    code, out, err = run(scenes, name, "-o", "x.png", *args)
    assert code == 2, (out, err)
    _one_clear_line(err, *words)
    assert not (scenes / "x.png").exists()


def test_render_exr(scenes):
    blend = scenes / "ok.blend"
    before = blend.read_bytes()
    code, out, err = run(scenes, blend, "--output", "out.exr", "--samples", "3", "--resolution", "20x12",
                         "--seed", "5", "--max-depth", "4", "--time-limit", "60", "--integrator", "PATH")
    assert code == 0, err
    assert blend.read_bytes() == before  # the .blend is never written
    assert not list(scenes.glob("*.blend1"))
    summary = out.strip().splitlines()[-1]
    assert "3 samples" in summary and "rays/s" in summary and " s" in summary and "20x12" in summary
    from ember.engine import imageio
    ch, _ = imageio.read_exr(scenes / "out.exr")
    img = np.stack([ch[c] for c in "RGBA"], axis=-1).astype(np.float32)
    assert img.shape == (12, 20, 4)
    assert np.isfinite(img).all()
    assert (img[..., :3] > 0.01).mean() > 0.3
    assert np.allclose(img[..., 3], 1.0)


def _read_png(path):
    """Minimal PNG reader (8-bit, non-interlaced) -> (H, W, C) uint8."""
    data = pathlib.Path(path).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, ihdr = 8, b"", None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            ihdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    w, h, depth, ctype, _, _, interlace = ihdr
    assert depth == 8 and interlace == 0
    c = {6: 4, 2: 3, 0: 1, 4: 2}[ctype]
    raw = zlib.decompress(idat)
    stride = w * c
    out = np.zeros((h, stride), np.int32)
    prev = np.zeros(stride, np.int32)
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = np.frombuffer(raw, np.uint8, stride, y * (stride + 1) + 1).astype(np.int32)
        cur = np.zeros(stride, np.int32)
        for x in range(stride):
            a = cur[x - c] if x >= c else 0
            b = prev[x]
            cc = prev[x - c] if x >= c else 0
            if f == 0:
                p = 0
            elif f == 1:
                p = a
            elif f == 2:
                p = b
            elif f == 3:
                p = (a + b) // 2
            else:
                pa, pb, pc = abs(b - cc), abs(a - cc), abs(a + b - 2 * cc)
                p = a if pa <= pb and pa <= pc else (b if pb <= pc else cc)
            cur[x] = (line[x] + p) & 255
        out[y], prev = cur, cur
    return out.reshape(h, w, c).astype(np.uint8)


def test_render_png(scenes):
    code, out, err = run(scenes, "ok.blend", "-o", "out.png", "--samples", "2")
    assert code == 0, err
    img = _read_png(scenes / "out.png")
    assert img.shape == (16, 24, 4)  # the scene's own resolution
    assert (img[..., 3] == 255).all()
    assert img[..., :3].max() > 20 and (img[..., :3] > 5).mean() > 0.3
    assert "2 samples" in out.strip().splitlines()[-1]


def test_light_path_options_reach_the_render(scenes):
    """--clamp-direct 0.01 darkens the directly lit plane (each light sample's mean RGB at most
    0.01); the other light-path options are accepted."""
    from ember.engine import imageio

    means = []
    for extra in ([], ["--diffuse-bounces", "1", "--clamp-indirect", "0.5", "--clamp-direct", "0.01",
                       "--caustics-reflective", "off", "--caustics-refractive", "off", "--filter-glossy", "1",
                       "--glossy-bounces", "2", "--transmission-bounces", "3", "--transparent-bounces", "4"]):
        code, out, err = run(scenes, "ok.blend", "-o", "lp.exr", "--samples", "4", "--resolution", "16x12", *extra)
        assert code == 0, err
        ch, _ = imageio.read_exr(scenes / "lp.exr")
        means.append(float(np.mean([ch[c] for c in "RGB"])))
    assert means[1] < 0.05 and means[0] > 0.2, means


@pytest.mark.parametrize("integrator, args, words", [
    ("photon", ["--photons", "3000", "--caustic-photons", "0", "--gather-rays", "2", "--radiance-photons", "off",
                "--photon-k", "10", "--global-radius", "0.5"], ["photons stored", "photons", "pixels"]),
    ("photon", ["--photons", "3000", "--photon-view", "global", "--photon-kernel", "cone"], ["photons stored"]),
    ("photon", ["--photons", "30000", "--photon-view", "positions"], ["photons stored"]),
    ("ppm", ["--photons", "2000", "--ppm-radius", "0.3", "--ppm-alpha", "0.5"], ["2 passes", "mean radius"]),
])
def test_photon_integrators_from_the_command_line(scenes, integrator, args, words):
    """The photon options reach the render (its summary names the stages and the photons)."""
    code, out, err = run(scenes, "ok.blend", "-o", "ph.exr", "--samples", "2", "--resolution", "16x12",
                         "--integrator", integrator, *args)
    assert code == 0, err
    assert all(w in out for w in words), out
    from ember.engine import imageio
    ch, _ = imageio.read_exr(scenes / "ph.exr")
    img = np.stack([ch[c] for c in "RGB"], axis=-1)
    assert np.isfinite(img).all() and img.mean() > 0


def test_multilayer_exr_holds_every_enabled_pass_and_the_metadata(scenes):
    """A .blend whose view layer enables passes: render.py's EXR is Blender's multilayer layout
    (<layer>.<pass>.<channel>) with every enabled pass (and the Color passes Direct and Indirect
    are divided by), and the header names engine, version,
    integrator, samples, seed and time."""
    build = textwrap.dedent('''
        import sys, bpy
        bpy.ops.wm.open_mainfile(filepath=sys.argv[-2])
        vl = bpy.context.scene.view_layers[0]
        vl.use_pass_z = vl.use_pass_normal = vl.use_pass_diffuse_direct = vl.use_pass_emit = True
        bpy.ops.wm.save_as_mainfile(filepath=sys.argv[-1])
    ''')
    proc = subprocess.run([sys.executable, "-c", build, str(scenes / "ok.blend"), str(scenes / "passes.blend")],
                          env=_env(scenes), capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    code, out, err = run(scenes, "passes.blend", "-o", "passes.exr", "--samples", "2", "--seed", "5")
    assert code == 0, err
    from ember.engine import imageio
    channels, header = imageio.read_exr(scenes / "passes.exr")
    # Diffuse Color too: Diffuse Direct is divided by it, and parts merge exactly only with it.
    want = {"Combined": "RGBA", "Depth": "Z", "Normal": "XYZ", "Diffuse Direct": "RGB", "Diffuse Color": "RGB",
            "Emission": "RGB"}
    assert set(channels) == {f"ViewLayer.{p}.{c}" for p, cs in want.items() for c in cs}
    assert channels["ViewLayer.Depth.Z"].shape == (16, 24)
    assert header["ember/engine"] == "Ember" and header["ember/integrator"] == "path"
    assert header["ember/samples"] == 2 and header["ember/seed"] == 5
    assert header["ember/renderSeconds"] > 0 and header["ember/version"]
