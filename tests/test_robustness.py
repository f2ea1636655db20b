"""Every bad input answered: scenes and options Ember cannot render as asked
get one clear line (CLI exit 2, Blender ERROR report), features it ignores get one warning per
feature naming the datablocks, and the cases it can render (a world without objects, lights of
zero power, a 1x1 frame) render. Core checks run without bpy; the rest through render.py."""
from __future__ import annotations

import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

from ember.engine import validation
from ember.engine.errors import EmberError
from ember.engine.scene import LIGHT_POINT, LIGHT_SUN, Lights, Materials, Mesh, Scene, World, MAT_DIFFUSE
from ember.engine.session import RenderSession

from core_scenes import furnace_box, perspective, settings

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
import render as render_cli  # noqa: E402  (only its pure helpers are used here)


# ---- core: no bpy -------------------------------------------------------------------------------
def _world_only(color=(0.2, 0.4, 0.6), lights=(), **kw):
    return Scene(Mesh.empty(), Materials.make([]), Lights.make(list(lights)), World(color=np.array(color)),
                 perspective((0, -3, 0), (0, 0, 0), 40), settings(**kw))


def _render(scene):
    session = RenderSession(scene)
    stats = session.run()
    return session, stats, session.film.mean()


def test_world_without_objects_renders_the_world_exactly():
    session, stats, img = _render(_world_only(samples=2))
    assert stats.nonfinite == 0
    assert np.array_equal(img, np.broadcast_to([0.2, 0.4, 0.6], img.shape))


def test_zero_power_lights_render_without_crash():
    """A sun in a scene without geometry has zero power for light selection (pbrt's
    pi r^2 E with r = 0): nothing is light-sampled, and the render goes on (it was an
    AttributeError in light_set.py)."""
    sun = dict(kind=LIGHT_SUN, Le=(3.0, 3.0, 3.0), sun_half_angle=0.01, frame=np.eye(3), name="sun")
    session, stats, img = _render(_world_only(color=(0.1, 0.1, 0.1), lights=[sun], samples=2))
    assert stats.nonfinite == 0 and np.all(np.isfinite(img))
    assert np.allclose(img, 0.1)  # the sun is behind the camera's view
    # Zero-strength light beside geometry: black image, a warning, no crash.
    scene = furnace_box(Le=0.0, samples=2)
    session, stats, img = _render(scene)
    assert not validation.has_light(scene) and session.warnings
    assert stats.nonfinite == 0 and np.all(img == 0)


def test_light_choice_by_absolute_power():
    """Selection pmf proportional to |power| (Cycles picks negative lights by magnitude)."""
    from ember.engine.accel import Accel
    from ember.engine.lights.light_set import LightSet
    scene = furnace_box(Le=0.0)
    lights = Lights.make([dict(kind=LIGHT_POINT, position=(0, 0, 0), Le=(2.0,) * 3, name="a"),
                          dict(kind=LIGHT_POINT, position=(0, 0.5, 0), Le=(-6.0,) * 3, name="b")])
    accel = Accel(scene.mesh)
    ls = LightSet(lights, scene.mesh, scene.materials, scene.world, accel, accel.scene_radius)
    assert np.allclose(ls.pmf(np.array([0, 1])), [0.25, 0.75])
    s = ls.sample(np.zeros((4, 3)), np.array([0.1, 0.2, 0.9, 0.95]), np.full((4, 2), 0.5))
    assert np.all(s.valid) and np.all(s.Le[2:] < 0) and np.all(s.Le[:2] > 0)


def test_negative_and_nonfinite_light_refused_with_names():
    base = furnace_box(Le=0.0)
    neg_light = Scene(base.mesh, base.materials, Lights.make([dict(kind=LIGHT_POINT, Le=(-1.0,) * 3, name="Lamp")]),
                      base.world, base.camera, base.settings)
    neg_emit = furnace_box(Le=-1.0)
    nan_light = Scene(base.mesh, base.materials, Lights.make([dict(kind=LIGHT_POINT, Le=(np.nan, 1, 1), name="Bad")]),
                      base.world, base.camera, base.settings)
    if base.settings.integrator in validation.NEGATIVE_LIGHT_INTEGRATORS:
        pytest.skip("negative lights are rendered")
    with pytest.raises(EmberError, match="Negative light.*'Lamp'"):
        validation.validate(neg_light)
    with pytest.raises(EmberError, match="Negative light.*emissive material"):
        validation.validate(neg_emit)
    with pytest.raises(EmberError, match="'Bad' have a NaN or infinite strength"):
        validation.validate(nan_light)


def _two_lights_room(signs, seed, kind="point", samples=64):
    """A closed room (albedo 0.5) lit by point light A (sign sA) and B (sign sB), B a point
    light or a 0.6 m emissive panel under the ceiling (present, black, when sB = 0)."""
    from core_scenes import box_quads, quads_mesh
    base = furnace_box(Le=0.0, samples=samples, seed=seed, pattern="random", width=24, height=24)
    sa, sb = signs
    rows = [dict(kind=LIGHT_POINT, position=(0.4, 0.3, 0.5), Le=(3.0 * sa,) * 3, name="A")] if sa else []
    panel = [[[-0.7, -0.3, 0.8], [-0.7, 0.3, 0.8], [-0.1, 0.3, 0.8], [-0.1, -0.3, 0.8]]]
    mesh = quads_mesh(np.concatenate([box_quads((-1, -1, -1), (1, 1, 1)), panel]), [0] * 6 + [1])
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(0.5,) * 3, name="wall"),
                           dict(kind=MAT_DIFFUSE, base_color=(0.5,) * 3, name="panel",
                                emission=(3.0 * sb if kind == "emissive" else 0.0,) * 3)])
    if kind == "point" and sb:
        rows.append(dict(kind=LIGHT_POINT, position=(-0.5, 0.2, -0.3), Le=(2.0 * sb,) * 3, name="B"))
    return Scene(mesh, mats, Lights.make(rows), base.world, base.camera, base.settings)


@pytest.mark.parametrize("kind", ["point", "emissive"])
def test_negative_light_subtracts_exactly_what_the_positive_one_adds(kind):
    """Cycles' negative lights: I(A, -B) = I(A) - I(B). Independent renders; z-test of the
    image and of 4x4-pixel blocks with the sum of the three variances."""
    if "path" not in validation.NEGATIVE_LIGHT_INTEGRATORS:
        pytest.skip("negative lights are refused until the path tracer keeps negative contributions")
    from scipy import stats as scipy_stats
    from stats import sidak_alpha
    m_a, v_a = _render_mv(_two_lights_room((1, 0), 1, kind))
    m_b, v_b = _render_mv(_two_lights_room((0, 1), 2, kind))
    m_ab, v_ab = _render_mv(_two_lights_room((1, -1), 3, kind))
    d, v = m_ab - (m_a - m_b), v_ab + v_a + v_b
    blocks = lambda a: a.reshape(6, 4, 6, 4, 3).sum(axis=(1, 3))  # noqa: E731
    z = np.concatenate([(d.sum(axis=(0, 1)) / np.sqrt(v.sum(axis=(0, 1)))).ravel(),
                        (blocks(d) / np.sqrt(blocks(v))).ravel()])
    z_max = scipy_stats.norm.isf(sidak_alpha(0.01, z.size) / 2)
    assert np.all(np.abs(z) < z_max), np.abs(z).max()
    assert m_b.mean() > 0.1 * m_a.mean()  # B's share is large enough to matter


def _render_mv(scene):
    session = RenderSession(scene)
    stats = session.run()
    assert stats.nonfinite == 0
    return session.film.mean(), session.film.variance_of_mean()


def test_memory_estimate_refuses_huge_frames_and_names_the_estimate():
    small = furnace_box(width=64, height=64)
    huge = furnace_box(width=65536, height=65536)
    validation.check_memory(small, available=8 << 30)
    with pytest.raises(EmberError, match=r"65536x65536 render needs about [0-9.]+ GiB .* but 8\.0 GiB are available"):
        validation.check_memory(huge, available=8 << 30)
    with pytest.raises(EmberError, match="needs at least"):
        validation.check_frame_memory(65536, 65536, available=8 << 30)
    validation.check_frame_memory(4096, 4096, available=8 << 30)
    est = validation.memory_estimate(furnace_box(width=2048, height=1024), processes=2)
    est2 = validation.memory_estimate(furnace_box(width=2048, height=2048), processes=2)
    assert est2["film"] == 2 * est["film"] and est2["batches"] == est["batches"]
    assert est["total"] == est["film"] + 2 * (est["batches"] + est["scene"] + validation.PROCESS_BYTES)


def test_available_memory_reads_proc_meminfo():
    avail = validation.available_memory()
    if not pathlib.Path("/proc/meminfo").exists():
        assert avail is None
    else:
        assert avail is not None and avail > 1 << 20


@pytest.mark.parametrize("w, h", [(1, 1), (3, 2), (1000, 2), (640, 480), (4, 4), (65536, 65536), (2, 700)])
def test_small_resolutions_through_the_percentage(w, h):
    rx, ry, pct = render_cli.blender_resolution(w, h)
    assert 4 <= rx <= 65536 and 4 <= ry <= 65536 and 1 <= pct <= 100
    assert (rx * pct // 100, ry * pct // 100) == (w, h)


# ---- through render.py ----------------------------------------------------------------------
BUILD = r'''
import sys, warnings, bpy, mathutils, math
warnings.simplefilter("ignore", DeprecationWarning)
out = sys.argv[-1]

def base(name, geometry=True, light=True, world=None):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.resolution_x, sc.render.resolution_y = 16, 12
    sc.render.resolution_percentage = 100
    if world is not None:
        w = bpy.data.worlds.new("Sky")
        w.use_nodes = True
        bg = w.node_tree.nodes["Background"]
        bg.inputs["Color"].default_value = (*world, 1.0)
        sc.world = w
    if geometry:
        me = bpy.data.meshes.new("plane")
        me.from_pydata([(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], [], [(0, 1, 2, 3)])
        me.update()
        sc.collection.objects.link(bpy.data.objects.new("plane", me))
    if light:
        ld = bpy.data.lights.new("lamp", 'POINT')
        ld.energy = 500.0
        lo = bpy.data.objects.new("lamp", ld)
        lo.location = (1, -1, 3)
        sc.collection.objects.link(lo)
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    cam.location = (0, -5, 4)
    sc.collection.objects.link(cam)
    cam.rotation_euler = (mathutils.Vector((0, 0, 0)) - cam.location).to_track_quat('-Z', 'Y').to_euler()
    sc.camera = cam
    return sc

def save(name):
    bpy.ops.wm.save_as_mainfile(filepath=out + "/" + name + ".blend")

base("world_only", geometry=False, light=False, world=(0.2, 0.4, 0.6)); save("world_only")
sc = base("sun_only", geometry=False, light=False)
sd = bpy.data.lights.new("sun", 'SUN'); sd.energy = 3.0
so = bpy.data.objects.new("sun", sd); sc.collection.objects.link(so); save("sun_only")
sc = base("negative_light")
nd = bpy.data.lights.new("neg", 'POINT'); nd.energy = -200.0
no = bpy.data.objects.new("neg", nd); no.location = (-1, 1, 2); sc.collection.objects.link(no); save("negative_light")
sc = base("only_negative", light=False)
nd = bpy.data.lights.new("neg", 'POINT'); nd.energy = -200.0
no = bpy.data.objects.new("neg", nd); no.location = (-1, 1, 2); sc.collection.objects.link(no); save("only_negative")
sc = base("zero_light", light=False)
zd = bpy.data.lights.new("zero", 'POINT'); zd.energy = 0.0
zo = bpy.data.objects.new("zero", zd); sc.collection.objects.link(zo); save("zero_light")
# volume material on a cube + world volume
sc = base("volumes", world=(0.1, 0.1, 0.1))
m = bpy.data.materials.new("Smoke"); m.use_nodes = True
nt = m.node_tree; nt.nodes.remove(nt.nodes["Principled BSDF"])
vol = nt.nodes.new("ShaderNodeVolumePrincipled")
nt.links.new(vol.outputs[0], nt.nodes["Material Output"].inputs["Volume"])
me = bpy.data.meshes.new("cube")
v = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (0, 2)]
me.from_pydata(v, [], [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
me.update(); me.materials.append(m)
for i in range(2):
    ob = bpy.data.objects.new(f"smoke{i}", me); ob.location.x = 2 * i; sc.collection.objects.link(ob)
wv = sc.world.node_tree.nodes.new("ShaderNodeVolumeScatter")
sc.world.node_tree.links.new(wv.outputs[0], sc.world.node_tree.nodes["World Output"].inputs["Volume"])
save("volumes")
# NaN vertices
sc = base("nan_vertices")
me = bpy.data.meshes.new("bad")
me.from_pydata([(0, 0, 1), (1, 0, 1), (0, 1, 1), (float("nan"), 0, 1), (float("inf"), 1, 1)], [], [(0, 1, 2), (0, 3, 2), (1, 4, 2)])
me.update()
sc.collection.objects.link(bpy.data.objects.new("broken", me)); save("nan_vertices")
# motion blur on
sc = base("motion_blur"); sc.render.use_motion_blur = True; save("motion_blur")
# a transparent film with passes: its parts merge channel by channel
sc = base("passes"); sc.render.film_transparent = True
vl = sc.view_layers[0]
vl.use_pass_z = vl.use_pass_normal = vl.use_pass_diffuse_direct = vl.use_pass_emit = True
save("passes")
# a negative Principled Emission Strength (Cycles emits nothing)
sc = base("negative_emission")
m = bpy.data.materials.new("Glow"); m.use_nodes = True
p = m.node_tree.nodes["Principled BSDF"]
p.inputs["Emission Strength"].default_value = -5.0; p.inputs["Emission Color"].default_value = (1, 1, 1, 1)
sc.objects["plane"].data.materials.append(m); save("negative_emission")
# an image texture on a path relative to the .blend
import os
os.makedirs(out + "/tex", exist_ok=True)
img = bpy.data.images.new("checker", 4, 4)
img.pixels = [float((i // 4 + i // 16) % 2) for i in range(64)]
img.filepath_raw = out + "/tex/checker.png"; img.file_format = 'PNG'; img.save()
sc = base("textured")
m = bpy.data.materials.new("Tex"); m.use_nodes = True
t = m.node_tree.nodes.new("ShaderNodeTexImage"); t.image = bpy.data.images.load(out + "/tex/checker.png")
m.node_tree.links.new(t.outputs[0], m.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
sc.objects["plane"].data.materials.append(m)
bpy.ops.wm.save_as_mainfile(filepath=out + "/textured.blend", relative_remap=True)
'''


@pytest.fixture(scope="module")
def bad_scenes(tmp_path_factory):
    pytest.importorskip("bpy")
    from test_cli import _env
    d = tmp_path_factory.mktemp("robust")
    proc = subprocess.run([sys.executable, "-c", BUILD, str(d)], env=_env(d), capture_output=True, text=True,
                          timeout=180)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return d


def _cli(d, *args):
    from test_cli import run
    return run(d, *args, "--no-progress")


def _exr(path):
    from ember.engine import imageio
    ch, _ = imageio.read_exr(path)
    return np.stack([ch[c] for c in "RGBA"], axis=-1)


def _warnings(out):
    return [l for l in out.splitlines() if l.startswith("Warning: ")]


@pytest.mark.blender
@pytest.mark.parametrize("args, words", [
    (["--samples", "99999999999"], ["--samples", "at most 2147483647"]),
    (["--seed", "3000000000"], ["--seed", "at most"]),
    (["--max-depth", "100000"], ["--max-depth", "at most 1024"]),
    (["--time-limit", "1e39"], ["--time-limit"]),
    (["--resolution", "70000x10"], ["--resolution", "1..65536"]),
    (["--resolution", "1x65536"], ["--resolution", "1x65536"]),
    (["--resolution", "65536x65536"], ["not enough memory", "GiB"]),
    (["--integrator", "photon", "--gather-rays", "2147483647"], ["not enough memory", "rays in flight", "gather rays"]),
])
def test_out_of_range_options_exit_2_with_one_line(bad_scenes, args, words):
    from test_cli import _one_clear_line
    code, out, err = _cli(bad_scenes, "world_only.blend", "-o", "x.exr", *args)
    assert code == 2, (out, err)
    _one_clear_line(err, *words)
    assert not (bad_scenes / "x.exr").exists()


@pytest.mark.blender
@pytest.mark.parametrize("name, words", [
    ("negative_light", ["negative light", "'neg'"]),
    ("only_negative", ["negative light", "'neg'"]),
])
def test_bad_scenes_exit_2_with_one_line(bad_scenes, name, words):
    from test_cli import _one_clear_line
    if "path" in validation.NEGATIVE_LIGHT_INTEGRATORS:
        pytest.skip("negative lights are rendered")
    code, out, err = _cli(bad_scenes, f"{name}.blend", "-o", "x.exr")
    assert code == 2, (out, err)
    _one_clear_line(err, *words)
    assert not (bad_scenes / "x.exr").exists()


@pytest.mark.blender
def test_one_by_one_frame(bad_scenes):
    code, out, err = _cli(bad_scenes, "world_only.blend", "-o", "one.exr", "--resolution", "1x1", "--samples", "1")
    assert code == 0, err
    img = _exr(bad_scenes / "one.exr")
    assert img.shape == (1, 1, 4) and np.allclose(img[0, 0], [0.2, 0.4, 0.6, 1.0])
    assert "1x1" in out.splitlines()[-1] and "0 non-finite samples" in out.splitlines()[-1]


@pytest.mark.blender
@pytest.mark.parametrize("name, expect", [
    ("world_only", "world"), ("sun_only", "black"), ("zero_light", "black")])
def test_renderable_edge_scenes(bad_scenes, name, expect):
    code, out, err = _cli(bad_scenes, f"{name}.blend", "-o", f"{name}.exr", "--samples", "2")
    assert code == 0, (out, err)
    assert "Traceback" not in err and err.strip() == ""
    img = _exr(bad_scenes / f"{name}.exr")
    assert np.all(np.isfinite(img))
    if expect == "world":
        assert np.allclose(img[..., :3], [0.2, 0.4, 0.6])
    else:
        assert np.all(img[..., :3] == 0)
    if name == "zero_light":
        assert _warnings(out) == ["Warning: The scene has no lights, no emissive materials and a black world: "
                                  "the image will be black."]


@pytest.mark.blender
@pytest.mark.parametrize("name, expected", [
    ("volumes", ["Warning: World 'Sky': world volume shaders are not supported and are ignored."]),
    ("nan_vertices", ["Warning: Triangles with NaN or infinite vertex coordinates were dropped: 'broken'."]),
    ("motion_blur", ["Warning: Motion blur is not supported yet: the image is rendered without it."]),
])
def test_unsupported_features_warned_once_per_datablock(bad_scenes, name, expected):
    code, out, err = _cli(bad_scenes, f"{name}.blend", "-o", f"{name}.exr", "--samples", "2")
    assert code == 0, (out, err)
    assert err.strip() == "", err  # no NumPy warnings or tracebacks
    assert sorted(_warnings(out)) == sorted(expected)
    assert "zero-area" not in out
    img = _exr(bad_scenes / f"{name}.exr")
    assert np.all(np.isfinite(img))


@pytest.mark.blender
def test_volume_only_object_is_transparent(bad_scenes):
    """Two cubes with a volume-only material: Cycles renders their boundary transparent,
    so the image equals the scene without them (same seed, same paths where they are not)."""
    code, out, err = _cli(bad_scenes, "volumes.blend", "-o", "vol.exr", "--samples", "2", "--seed", "3")
    assert code == 0, err
    img = _exr(bad_scenes / "vol.exr")
    # The world (0.1) is seen through the cubes: no pixel is the opaque black a closed
    # emission-less box would give.
    assert img[..., :3].min() > 0.0


# ---- interruption ---------------------------------------------------------
LONG = ["--samples", "100000", "--resolution", "200x200", "--no-progress"]


def _children(pid):
    out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(pid)], capture_output=True, text=True).stdout
    return [int(x) for x in out.split()]


def _gone(pid) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split()[2] == "Z"
    except (FileNotFoundError, ProcessLookupError):
        return True


def _wait_gone(pids, timeout=5.0):
    import time
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if all(_gone(p) for p in pids):
            return True
        time.sleep(0.05)
    return False


def _start(d, *args, script=None):
    from test_cli import RENDER, _env
    cmd = [sys.executable, str(RENDER)] if script is None else [sys.executable, "-c", script]
    return subprocess.Popen(cmd + [str(a) for a in args], cwd=d, env=_env(d), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


def _signal_and_wait(proc, sig, group):
    """Send sig (to the process group, as a terminal's Ctrl-C does, or to the process) and
    return (seconds until it exits, stdout, stderr); bounded by 30 s."""
    import os
    import time
    t0 = time.monotonic()
    (os.killpg if group else os.kill)(proc.pid, sig)
    out, err = proc.communicate(timeout=30)
    return time.monotonic() - t0, out, err


def _after_export(proc, seconds=2.5):
    """Wait until final.py's (flushed) 'exported in' line, then `seconds` more: worker
    processes start well within that, so after 2.5 s they are sampling."""
    for line in proc.stdout:
        if "exported in" in line:
            break
    import time
    time.sleep(seconds)


@pytest.mark.blender
@pytest.mark.parametrize("sig, group, code, wait", [
    ("SIGINT", True, 130, 2.5), ("SIGTERM", False, 143, 0.2),
    ("SIGTERM", True, 143, 2.5),  # timeout, docker stop, a farm manager: the whole process group
    ("SIGINT", True, 130, 0.2),  # workers ignore SIGINT before their first import
])
def test_signal_during_sampling_stops_fast_one_line_no_file_no_workers(bad_scenes, sig, group, code, wait):
    """wait 2.5: while sampling; wait 0.2: while the worker processes start. The workers
    leave the stopping to the render process: none is reported as failed, and the engine's
    destructor raises nothing on the way out."""
    import signal
    out_path = bad_scenes / "long.exr"
    proc = _start(bad_scenes, "world_only.blend", "-o", out_path, *LONG)
    _after_export(proc, wait)
    workers = _children(proc.pid)
    seconds, out, err = _signal_and_wait(proc, getattr(signal, sig), group)
    assert proc.returncode == code, err
    assert err.strip().splitlines() == ["Interrupted."], err  # no worker tracebacks either
    assert "ended unexpectedly" not in out and "Error" not in out, out
    assert seconds < 5.0  # generous: a quiet machine stops within a second
    assert not out_path.exists()
    assert _wait_gone(workers), "worker processes outlived the render"
    assert not [p for p in bad_scenes.iterdir() if p.name.startswith(".long.exr")]


@pytest.mark.blender
@pytest.mark.parametrize("delay", [0.3, 0.9])
def test_signal_while_starting_is_clean(bad_scenes, delay):
    """During bpy import, file load or add-on registration: no crash, one line."""
    import signal
    import time
    proc = _start(bad_scenes, "world_only.blend", "-o", bad_scenes / "early.exr", *LONG)
    time.sleep(delay)
    seconds, out, err = _signal_and_wait(proc, signal.SIGTERM, False)
    assert proc.returncode in (143, 0), err  # 0 only if it finished first (it cannot: 100000 spp)
    assert proc.returncode == 143
    assert err.strip().splitlines() == ["Interrupted."], err
    assert seconds < 5.0
    assert not (bad_scenes / "early.exr").exists()


SLOW_WRITE = """
import os, sys, time
sys.path.insert(0, {root!r})
from _bootstrap import load_ember
load_ember()
from ember.engine import imageio
def slow(path, *args, **kwargs):
    with open(path, "wb") as fh:
        fh.write(b"part of an image")
    open({marker!r}, "w").close()
    time.sleep(30)
imageio.write_rgba_exr = slow
import runpy
sys.argv = [{render!r}] + sys.argv[1:]
runpy.run_path({render!r}, run_name="__main__")
"""


@pytest.mark.blender
def test_signal_during_write_keeps_previous_file(bad_scenes):
    import signal
    import time
    from test_cli import RENDER
    d = bad_scenes / "write"
    d.mkdir(exist_ok=True)
    out_path, marker = d / "w.exr", d / "writing"
    out_path.write_bytes(b"previous good render")
    script = SLOW_WRITE.format(root=str(RENDER.parent), render=str(RENDER), marker=str(marker))
    proc = _start(bad_scenes, "world_only.blend", "-o", out_path, "--samples", "1", "--no-progress", script=script)
    t0 = time.monotonic()
    while not marker.exists() and time.monotonic() - t0 < 60:
        time.sleep(0.05)
    assert marker.exists()
    seconds, out, err = _signal_and_wait(proc, signal.SIGTERM, False)
    assert proc.returncode == 143, err
    assert err.strip().splitlines() == ["Interrupted."], err
    assert seconds < 5.0
    assert out_path.read_bytes() == b"previous good render"
    assert sorted(p.name for p in d.iterdir()) == ["w.exr", "writing"]  # no temporary left


def _kill_while_sampling(bad_scenes):
    """SIGKILL a render while it samples; checks the output and the workers, returns stderr."""
    import signal
    out_path = bad_scenes / "killed.exr"
    out_path.write_bytes(b"previous good render")
    proc = _start(bad_scenes, "world_only.blend", "-o", out_path, *LONG)
    _after_export(proc)
    workers = _children(proc.pid)
    _, out, err = _signal_and_wait(proc, signal.SIGKILL, False)
    assert proc.returncode == -signal.SIGKILL
    assert out_path.read_bytes() == b"previous good render"
    assert _wait_gone(workers), "worker processes outlived a killed render"
    return err


@pytest.mark.blender
def test_sigkill_leaves_previous_file_and_no_workers(bad_scenes):
    _kill_while_sampling(bad_scenes)


@pytest.mark.blender
def test_sigkill_orphaned_workers_exit_quietly(bad_scenes):
    err = _kill_while_sampling(bad_scenes)
    assert "Traceback" not in err, err


@pytest.mark.blender
def test_sigkill_to_the_group_leaves_segments_named_for_the_next_run(bad_scenes):
    """SIGKILL to the process group (its resource tracker dies too): the shared-memory
    segments left are named by their owner's pid, so the next process that creates one
    removes them; no process outlives the render."""
    import signal
    from ember.engine.parallel import shared
    proc = _start(bad_scenes, "world_only.blend", "-o", bad_scenes / "group_killed.exr", *LONG)
    _after_export(proc, 1.0)
    workers = _children(proc.pid)
    assert workers
    _signal_and_wait(proc, signal.SIGKILL, True)
    assert _wait_gone(workers), "worker processes outlived the render"
    left = sorted(n for n in os.listdir(shared.SHM_DIR) if shared.owner(n) == proc.pid)
    assert left, "no segment named for its owner"
    alive = subprocess.Popen([sys.executable, "-c", OWNER, str(ROOT)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                             text=True)  # another render, still running
    try:
        theirs = alive.stdout.readline().strip()
        shared._SWEPT[0] = False
        segment = shared.create(8)  # what the next run's worker pool does first
        try:
            assert not [n for n in os.listdir(shared.SHM_DIR) if shared.owner(n) == proc.pid]
            assert {segment.name, theirs} <= set(os.listdir(shared.SHM_DIR))  # live owners' segments stay
        finally:
            shared.unlink(segment)
    finally:
        alive.communicate("")


OWNER = """
import sys
sys.path.insert(0, sys.argv[1])
from _bootstrap import load_ember
load_ember()
from ember.engine.parallel import shared
segment = shared.create(8)
print(segment.name, flush=True)
sys.stdin.read()
shared.unlink(segment)
"""


WRITE_ENDS = """
import json, os, signal, sys
render_py, report, when = sys.argv[1], sys.argv[2], sys.argv[3]
sys.argv = [render_py] + sys.argv[4:]
source = open(render_py).read().replace('if __name__ == "__main__":', 'patch(globals())\\nif __name__ == "__main__":')

def patch(g):
    write, hold = g["_Job"]._write, type(g["STOP"]).hold
    def _write(self, *args, **kwargs):
        before = set(sys.modules)
        result = write(self, *args, **kwargs)
        json.dump(sorted(set(sys.modules) - before), open(report, "w"))
        if when == "write":
            g["STOP"].soft = True  # the signal lands as the write's finally runs
            os.kill(os.getpid(), signal.SIGINT)
        return result
    def _hold(self):
        hold(self)
        if when == "summary":  # the file is in place, its summary line next
            os.kill(os.getpid(), signal.SIGINT)
    g["_Job"]._write = _write
    type(g["STOP"]).hold = _hold

exec(compile(source, render_py, "exec"), {"__name__": "__main__", "__file__": render_py, "patch": patch})
"""


@pytest.mark.blender
@pytest.mark.parametrize("when", ["write", "summary"])
def test_ctrl_c_as_the_write_ends_is_one_outcome(bad_scenes, when):
    """Ctrl-C as the output write ends: exit 130 and one line, the file complete, no summary;
    once the file is in place and its summary follows, the signal is too late: exit 0 and the
    summary, no "Interrupted." (never both). Nothing is imported while a signal interrupts the
    write (an interrupted import of OpenEXR's binding fails for good)."""
    import json
    from test_cli import RENDER
    out_path, report = bad_scenes / f"ends_{when}.exr", bad_scenes / "imported.json"
    proc = _start(bad_scenes, RENDER, report, when, "world_only.blend", "-o", out_path, "--samples", "1",
                  "--no-progress", script=WRITE_ENDS)
    out, err = proc.communicate(timeout=60)
    if when == "write":
        assert proc.returncode == 130, err
        assert err.strip().splitlines() == ["Interrupted."], err
        assert " -> " not in out, out
    else:
        assert proc.returncode == 0, err
        assert err.strip() == "" and " -> " in out.splitlines()[-1], (out, err)
    assert np.allclose(_exr(out_path)[..., :3], [0.2, 0.4, 0.6])
    assert json.loads(report.read_text()) == []


# ---- merges ----------------------------------------------------------------------------------
def _header(samples=4, offset=0, border=(0, 0, 4, 2), **extra):
    return {"ember/engine": "Ember", "ember/sceneDigest": "d", "ember/stoppedBy": "done",
            "ember/border": str(list(border)), "ember/samples": samples, "ember/sampleOffset": offset,
            "ember/seed": 0, "ember/sampleRange": f"[{offset}, {offset + samples})", **extra}


def test_merge_keeps_alpha_and_every_pass_as_plain_means():
    """Transparent parts: alpha merges like colour. Multilayer parts: every pass, weighted by
    samples; Depth's miss value, Direct/Indirect divided by their Color and the variance of a
    mean go through their plain means, so the merge equals the render of all the samples."""
    from ember.engine.merge import MergeError, Part, merge, merge_channels
    from ember.engine.passes import DEPTH_MISS
    rng = np.random.default_rng(1)
    n = (3, 5)  # samples of the two parts

    def layer(alpha, depth, direct, color, var):
        p = "ViewLayer."
        ch = {f"{p}Combined.{c}": np.full((2, 4), v, np.float32) for c, v in zip("RGBA", (0.5, 0.25, 0.125, alpha))}
        ch[f"{p}Depth.Z"] = depth.astype(np.float32)
        for c in "RGB":
            ch[f"{p}Diffuse Direct.{c}"] = np.divide(direct, color, out=np.zeros_like(direct),
                                                     where=color > 0).astype(np.float32)
            ch[f"{p}Diffuse Color.{c}"] = color.astype(np.float32)
        ch[f"{p}Debug Variance.X"] = var.astype(np.float32)
        return ch

    d = [rng.uniform(1, 2, (2, 4)) for _ in n]
    d[0][0, 0] = 0.0  # every sample of part 0 missed there
    d[1][0, 0] = 0.0
    d[1][1, 1] = 0.0  # part 1 missed, part 0 hit
    direct = [rng.uniform(0, 1, (2, 4)) for _ in n]
    color = [rng.uniform(0.2, 1, (2, 4)) for _ in n]
    var = [rng.uniform(0, 1, (2, 4)) for _ in n]
    alpha = (0.25, 0.75)
    parts = [Part.from_exr(f"p{i}", layer(alpha[i], np.where(d[i] > 0, d[i], DEPTH_MISS), direct[i], color[i], var[i]),
                           _header(n[i], sum(n[:i]))) for i in range(2)]
    merged, header = merge_channels(parts)
    w = np.array(n, float)[:, None, None] / sum(n)
    depth = w[0] * d[0] + w[1] * d[1]
    np.testing.assert_allclose(merged["ViewLayer.Combined.A"], (3 * 0.25 + 5 * 0.75) / 8, rtol=1e-6)
    np.testing.assert_allclose(merged["ViewLayer.Depth.Z"], np.where(depth > 0, depth, DEPTH_MISS), rtol=1e-6)
    mean_direct, mean_color = w[0] * direct[0] + w[1] * direct[1], w[0] * color[0] + w[1] * color[1]
    np.testing.assert_allclose(merged["ViewLayer.Diffuse Direct.G"], mean_direct / mean_color, rtol=1e-5)
    np.testing.assert_allclose(merged["ViewLayer.Debug Variance.X"], w[0] ** 2 * var[0] + w[1] ** 2 * var[1],
                               rtol=1e-5)
    assert header["ember/samples"] == 8 and header["ember/sampleRange"] == "[0, 8)"
    rgba, _ = merge(parts)
    assert rgba.shape == (2, 4, 4) and np.allclose(rgba[..., 3], (3 * 0.25 + 5 * 0.75) / 8)
    plain = [Part.from_exr(f"q{i}", {c: np.full((2, 4), v, np.float32) for c, v in zip("RGBA", (1, 1, 1, alpha[i]))},
                           _header(n[i], sum(n[:i]))) for i in range(2)]
    assert np.allclose(merge(plain)[0][..., 3], (3 * 0.25 + 5 * 0.75) / 8)
    with pytest.raises(MergeError, match="different channels or passes"):
        merge_channels([parts[0], plain[1]])
    lone = {k: v for k, v in layer(1, d[0], direct[0], color[0], var[0]).items() if "Diffuse Color" not in k}
    with pytest.raises(MergeError, match="without Diffuse Color"):
        Part.from_exr("lone", lone, _header())


@pytest.mark.parametrize("change, words", [
    ({"ember/border": "[0, 0, x]"}, "malformed ember/border"),
    ({"ember/border": "[0, 0, 9, 2]"}, "outside its 4x2 image"),
    ({"ember/samples": None}, "no ember/samples"),
    ({"ember/samples": "many"}, "malformed ember/samples"),
    ({"ember/samples": -4}, "ember/samples -4: it must be at least 1"),
    ({"ember/samples": 0}, "it must be at least 1"),
    ({"ember/sampleOffset": "1.5"}, "malformed ember/sampleOffset"),
    ({"ember/sampleOffset": -2}, "ember/sampleOffset -2"),
    ({"ember/seed": "abc"}, "malformed ember/seed"),
])
def test_malformed_merge_metadata_is_one_line(change, words):
    from ember.engine.merge import MergeError, Part
    header = _header()
    for k, v in change.items():
        header.pop(k) if v is None else header.__setitem__(k, v)
    with pytest.raises(MergeError, match=words) as e:
        Part.from_exr("part.exr", {c: np.ones((2, 4), np.float32) for c in "RGBA"}, header)
    assert "\n" not in str(e.value) and str(e.value).startswith("part.exr ")


@pytest.mark.blender
def test_transparent_multilayer_parts_merge_to_the_whole_render(bad_scenes):
    """render.py merge and the farm's frame writer on real parts of a transparent film with
    passes: every channel equals the render of all the samples to float32 rounding; a part
    with malformed metadata is one line, exit 2."""
    from ember.engine import imageio
    from ember.engine.merge import Part, merge_channels
    from test_cli import _one_clear_line, run
    d = bad_scenes
    for name, args in (("whole", ["--samples", "3"]), ("p0", ["--samples", "1"]),
                       ("p1", ["--samples", "2", "--sample-offset", "1"])):
        code, out, err = _cli(d, "passes.blend", "-o", f"{name}.exr", "--seed", "3", "--integrator", "path", *args)
        assert code == 0, err
    code, out, err = run(d, "merge", "p0.exr", "p1.exr", "-o", "merged.exr")
    assert code == 0, err
    whole, _ = imageio.read_exr(d / "whole.exr")
    merged, header = imageio.read_exr(d / "merged.exr")
    assert sorted(merged) == sorted(whole) and "ViewLayer.Combined.A" in whole and "ViewLayer.Depth.Z" in whole
    assert whole["ViewLayer.Combined.A"].min() < 0.9  # transparent past the plane's edge
    for c in whole:
        np.testing.assert_allclose(merged[c], whole[c], rtol=4e-7, atol=1e-7, err_msg=c)
    render_cli._write_farm_frame(d / "farm.exr", [(d / p).read_bytes() for p in ("p0.exr", "p1.exr")],
                                 imageio, Part, merge_channels)
    farm, _ = imageio.read_exr(d / "farm.exr")
    assert all(np.array_equal(farm[c], merged[c]) for c in merged)
    channels, header = imageio.read_exr(d / "p0.exr")
    header = {k: v for k, v in header.items() if k.startswith("ember/")}
    imageio.write_exr(d / "bad_part.exr", channels, {**header, "ember/seed": "abc"})
    code, out, err = run(d, "merge", "bad_part.exr", "p1.exr", "-o", "bad_merge.exr")
    assert code == 2
    _one_clear_line(err, "bad_part.exr", "malformed ember/seed")


# ---- farm textures ---------------------------------------------------------------------------
PACK = """
import sys
sys.argv = ["render.py"]
sys.path.insert(0, {root!r})
import bpy, render
render._load_ember()
bpy.ops.wm.open_mainfile(filepath={blend!r})
open({out!r}, "wb").write(render._packed_blend_bytes())
bpy.ops.wm.open_mainfile(filepath={out!r})  # elsewhere, without tex/ beside it
image = bpy.data.images["checker.png"]
print("packed", image.packed_file is not None, tuple(image.size))
"""


@pytest.mark.blender
def test_farm_textures_travel_or_fail_and_task_warnings_return(bad_scenes, tmp_path):
    """--send-blend sends the .blend with the images it uses packed into it, so a texture on
    a relative path travels with the job. A task on a .blend whose texture is missing returns
    the warning for the caller to show; with --missing-textures error (a farm's default) it
    is one line, exit 2."""
    from ember.engine import imageio
    from ember.engine.parallel import farm
    from test_cli import RENDER, _env, _one_clear_line
    d = bad_scenes
    sent = tmp_path / "sent" / "scene.blend"
    sent.parent.mkdir()
    proc = subprocess.run([sys.executable, "-c", PACK.format(root=str(RENDER.parent), blend=str(d / "textured.blend"),
                                                            out=str(sent))], env=_env(d), capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "packed True (4, 4)" in proc.stdout
    lone = tmp_path / "lone"
    lone.mkdir()
    (lone / "textured.blend").write_bytes((d / "textured.blend").read_bytes())  # its tex/ stays behind
    result = farm.render_task(dict(frame=1, offset=0, samples=1), str(RENDER), str(lone / "textured.blend"), None,
                              ["--threads", "1", "--integrator", "path"])
    assert [w for w in result["warnings"] if "'checker.png' has no pixels" in w and "magenta" in w], result
    (tmp_path / "task.exr").write_bytes(result["exr"])
    rgb = imageio.read_rgb(tmp_path / "task.exr")
    assert rgb[..., 1].sum() < 0.2 * rgb[..., 0].sum()  # magenta (and a white highlight), as Cycles renders it
    code, out, err = _cli(lone, "textured.blend", "-o", "x.exr", "--missing-textures", "error")
    assert code == 2
    _one_clear_line(err, "image file(s) missing", "checker.png", "--missing-textures warn")


# ---- paths ---------------------------------------------------------------------------------
def _denied():
    """A prefix that runs a command without the power to ignore file permissions (root
    has it), or None where no such prefix is needed; skips where none can be had."""
    if os.geteuid() != 0:
        return []
    import shutil
    if shutil.which("setpriv") is None:
        pytest.skip("root without setpriv: file permissions do not apply")
    return ["setpriv", "--bounding-set", "-dac_override,-dac_read_search"]


@pytest.mark.blender
def test_unreadable_paths_are_one_line_exit_2(bad_scenes, tmp_path):
    """A .blend, output, reference or merge part behind a directory that may not be searched,
    or an output directory without write permission: one line, exit 2, before any render."""
    from test_cli import RENDER, _env, _one_clear_line
    d = bad_scenes
    closed, readonly = tmp_path / "closed", tmp_path / "readonly"
    closed.mkdir()
    readonly.mkdir()
    for name in ("world_only.blend",):
        (closed / name).write_bytes((d / name).read_bytes())
    (closed / "part.exr").write_bytes(b"x")
    closed.chmod(0)
    readonly.chmod(0o555)
    try:
        for args, words in (([closed / "world_only.blend", "-o", "x.exr"], [".blend", "permission denied"]),
                            (["world_only.blend", "-o", closed / "x.exr"], ["output", "permission denied"]),
                            (["world_only.blend", "-o", readonly / "x.exr"], ["cannot write", "permission denied"]),
                            (["world_only.blend", "-o", "x.exr", "--reference", closed / "part.exr"],
                             ["reference", "permission denied"]),
                            (["merge", closed / "part.exr", "-o", "x.exr"], ["part", "permission denied"])):
            proc = subprocess.run(_denied() + [sys.executable, str(RENDER), *map(str, args)], cwd=d, env=_env(d),
                                  capture_output=True, text=True, timeout=120)
            assert proc.returncode == 2, (args, proc.stderr)
            _one_clear_line(proc.stderr, *words)
    finally:
        closed.chmod(0o755)
        readonly.chmod(0o755)


@pytest.mark.blender
def test_output_names_are_checked_before_rendering(bad_scenes, tmp_path):
    """Names that fit the file system but not the temporary file written first are refused
    before rendering, for frame numbers too; a non-UTF-8 .exr name is written."""
    from ember.engine import imageio
    from test_cli import _one_clear_line
    d = bad_scenes
    for n in (232, 239):  # too long with any pid (OpenEXR's own check of the final name passes them)
        code, out, err = _cli(d, "world_only.blend", "-o", tmp_path / ("a" * (n - 4) + ".exr"))
        assert code == 2
        _one_clear_line(err, f"{n} bytes", "too long", "temporary")
    # A template whose temporary fits, but not with frame 10000's extra digits (pids as long as ours).
    fits = 255 - len(f".{imageio._TMP_TAG}{os.getpid()}-xxxxxxxx") - 1
    code, out, err = _cli(d, "world_only.blend", "-o", tmp_path / ("b" * (fits - 5) + "#.exr"), "--frames", "1,10000")
    assert code == 2
    _one_clear_line(err, "too long")
    assert not [p for p in tmp_path.iterdir()]  # nothing rendered, nothing left
    name = os.fsdecode(b"caf\xe9.exr")  # Latin-1, not UTF-8
    from test_cli import RENDER, _env
    proc = subprocess.run([sys.executable, str(RENDER), "world_only.blend", "-o", str(tmp_path / name), "--samples", "1",
                           "--no-progress"], cwd=d, env=_env(d), capture_output=True, timeout=180)
    assert proc.returncode == 0, proc.stderr
    assert np.allclose(_exr(tmp_path / name)[..., :3], [0.2, 0.4, 0.6])
    assert os.listdir(os.fsencode(tmp_path)) == [b"caf\xe9.exr"]


# ---- memory ------------------------------------------------------------------------------------
def test_memory_estimate_covers_gather_rays_records_photons_and_passes():
    """Every setting that scales memory raises the estimate: gather rays multiply a batch's
    rays, records (with radiance coefficients) and photons are published, passes add film."""
    base = furnace_box(width=200, height=100)
    est = lambda **kw: validation.memory_estimate(base.replace(settings=base.settings.replace(**kw)), 2)  # noqa: E731
    path = est(integrator="path")
    assert est(integrator="photon", gather_rays=64)["batches"] > 10 * est(integrator="photon", gather_rays=1)["batches"]
    huge = est(integrator="photon", gather_rays=2**31 - 1)
    assert huge["batches"] >= validation.BATCH_BYTES_PER_PATH * 1024 * (2**31 - 1)  # a batch of 1024 paths
    with pytest.raises(EmberError, match="rays in flight .* gather rays"):
        validation.check_memory(base.replace(settings=base.settings.replace(integrator="photon", gather_rays=2**31 - 1)),
                                available=64 << 30)
    assert est(integrator="photon", photons=10**7)["published"] > est(integrator="photon", photons=10**5)["published"]
    icache = est(integrator="icache", icache_radiance=True, icache_radiance_order=8)["published"]
    assert icache > 2 * est(integrator="icache")["published"] > 0
    passes = est(integrator="path", passes=("Depth", "Normal"), film_transparent=True)
    assert passes["film"] - path["film"] == validation.PASS_BYTES_PER_CHANNEL * 5 * 200 * 100


@pytest.mark.parametrize("version", ["v1", "v2"])
def test_available_memory_reads_the_cgroup_limit(tmp_path, version):
    """A container's limit (cgroup v2 memory.max, v1 memory.limit_in_bytes) less its usage,
    the tightest on the way to the root; 'max' and v1's huge number mean no limit."""
    root = tmp_path / "cgroup"
    if version == "v2":
        (tmp_path / "self").write_text("0::/job/task\n")
        limit, usage, base = "memory.max", "memory.current", root
    else:
        (tmp_path / "self").write_text("5:cpu:/x\n4:memory:/job/task\n")
        limit, usage, base = "memory.limit_in_bytes", "memory.usage_in_bytes", root / "memory"
    (base / "job" / "task").mkdir(parents=True)
    (base / limit).write_text("max\n" if version == "v2" else "9223372036854771712\n")
    (base / "job" / limit).write_text(f"{4 << 30}\n")
    (base / "job" / usage).write_text(f"{1 << 30}\n")
    (base / "job" / "task" / limit).write_text(f"{8 << 30}\n")
    assert validation.cgroup_available(str(tmp_path / "self"), str(root)) == 3 << 30
    inactive = "inactive_file" if version == "v2" else "total_inactive_file"
    (base / "job" / "memory.stat").write_text(f"anon 5\n{inactive} {1 << 29}\n")  # page cache: reclaimable
    assert validation.cgroup_available(str(tmp_path / "self"), str(root)) == (3 << 30) + (1 << 29)
    (base / "job" / limit).write_text("max\n" if version == "v2" else "9223372036854771712\n")
    assert validation.cgroup_available(str(tmp_path / "self"), str(root)) == 8 << 30
    (tmp_path / "self").write_text("0::/\n" if version == "v2" else "4:memory:/\n")
    assert validation.cgroup_available(str(tmp_path / "self"), str(root)) is None


# ---- negative light ------------------------------------------------------------------------------
def test_negative_world_is_seen_as_cycles_renders_it():
    """A negative world strength: camera rays see the negative background (Cycles renders it
    so; it was black)."""
    session, stats, img = _render(_world_only(color=(-0.2, -0.4, -0.6), samples=2))
    assert np.array_equal(img, np.broadcast_to([-0.2, -0.4, -0.6], img.shape))


@pytest.mark.blender
def test_negative_principled_emission_emits_nothing(bad_scenes):
    """Cycles renders no emission for a negative Principled Emission Strength (it emitted
    -5 here): the plane is lit by the lamp alone."""
    code, out, err = _cli(bad_scenes, "negative_emission.blend", "-o", "negemit.exr", "--samples", "1", "--seed", "2")
    assert code == 0, err
    img = _exr(bad_scenes / "negemit.exr")
    assert img[..., :3].min() >= 0 and img[..., :3].mean() > 0.01
