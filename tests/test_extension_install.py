"""The built extension installs offline and renders.

Builds this platform's zip (`blender_ext.py build --split-platforms`, needs ./wheels from
tools/fetch_wheels.sh; skipped without them), installs it with Blender's own operator into a
temporary user directory, in an interpreter that sees only bpy and NumPy (every other package
must come from the zip's wheels), renders a scene with Ember and reads the image back. The
add-on must not import SciPy, which the zip no longer carries.
"""
from __future__ import annotations

import os
import pathlib
import subprocess
import sys
import textwrap
import tomllib

import pytest

from test_manifest import ROOT, _blender_ext_path

pytestmark = pytest.mark.blender

SCRIPT = textwrap.dedent('''
    import sys
    site, zip_path, out = sys.argv[-3:]
    sys.path.insert(0, site)  # bpy and NumPy only (python -S: no site-packages)
    import bpy
    assert not bpy.app.online_access
    assert bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default",
                                                     enable_on_install=True) == {"FINISHED"}
    assert "bl_ext.user_default.ember" in sys.modules
    sc = bpy.context.scene
    me = bpy.data.meshes.new("plane")
    me.from_pydata([(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], [], [(0, 1, 2, 3)])
    sc.collection.objects.link(bpy.data.objects.new("plane", me))
    lamp = bpy.data.objects.new("lamp", bpy.data.lights.new("lamp", "POINT"))
    lamp.data.energy, lamp.location = 500.0, (0, 0, 3)
    sc.collection.objects.link(lamp)
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    cam.location = (0, 0, 6)
    sc.collection.objects.link(cam)
    sc.camera = cam
    sc.render.engine = "EMBER"
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 16, 16, 100
    sc.ember.samples = 4
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.filepath = out
    bpy.ops.render.render(write_still=True)
    sc.ember.integrator, sc.ember.photons, sc.ember.caustic_photons = "PHOTON", 2000, 0  # the kd-tree's wheel
    bpy.ops.render.render(write_still=False)
    import embreex, OpenEXR, pykdtree, numpy as np
    with OpenEXR.File(out) as f:
        ch = f.channels()
        rgb = ch["RGBA"].pixels if "RGBA" in ch else np.stack([ch[c].pixels for c in "RGB"], -1)
    print("MEAN", float(np.asarray(rgb)[..., :3].mean()))
    print("EMBREEX", embreex.__file__)
    print("PYKDTREE", pykdtree.__file__)
    print("SCIPY", "scipy" in sys.modules)
''')


def _platform() -> str:
    return {"linux": "linux_x64", "win32": "windows_x64"}.get(sys.platform, "")


def test_built_zip_installs_offline_and_renders(tmp_path):
    with open(ROOT / "blender_manifest.toml", "rb") as fh:
        wheels = tomllib.load(fh)["wheels"]
    if not all((ROOT / w).is_file() for w in wheels):
        pytest.skip("./wheels is incomplete: run tools/fetch_wheels.sh")
    if not _platform():
        pytest.skip("checked on Linux and Windows")
    ext = _blender_ext_path()
    dist = tmp_path / "dist"
    dist.mkdir()
    proc = subprocess.run([sys.executable, str(ext), "build", "--source-dir", str(ROOT), "--output-dir", str(dist),
                           "--split-platforms"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    archive = next(dist.glob(f"*-{_platform()}.zip"))
    import numpy
    packages = pathlib.Path(numpy.__file__).parents[1]  # the site-packages holding bpy and NumPy
    site = tmp_path / "site"
    site.mkdir()
    for name in ("bpy", "numpy", "numpy.libs"):
        if (packages / name).exists():
            os.symlink(packages / name, site / name)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    env["BLENDER_USER_RESOURCES"] = str(tmp_path / "user")
    env["TMPDIR"] = str(tmp_path)
    out = tmp_path / "render.exr"
    proc = subprocess.run([sys.executable, "-S", "-c", SCRIPT, str(site), str(archive), str(out)], env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-3000:]
    lines = dict(l.split(" ", 1) for l in proc.stdout.splitlines() if l.split(" ", 1)[0] in ("MEAN", "EMBREEX", "PYKDTREE", "SCIPY"))
    assert float(lines["MEAN"]) > 0.01
    assert lines["EMBREEX"].startswith(str(tmp_path / "user"))  # from the zip's wheels
    assert lines["PYKDTREE"].startswith(str(tmp_path / "user"))
    assert lines["SCIPY"] == "False"
