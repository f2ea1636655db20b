"""Every bad input answered: scenes and options Ember cannot render as asked
get one clear line (CLI exit 2, Blender ERROR report), features it ignores get one warning per
feature naming the datablocks, and the cases it can render (a world without objects, lights of
zero power, a 1x1 frame) render. Core checks run without bpy; the rest through render.py."""
from __future__ import annotations

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
    import os
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
    ("SIGINT", True, 130, 2.5), ("SIGTERM", False, 143, 2.5), ("SIGTERM", False, 143, 0.2),
    ("SIGINT", True, 130, 0.2),  # workers ignore SIGINT before their first import
])
def test_signal_during_sampling_stops_fast_one_line_no_file_no_workers(bad_scenes, sig, group, code, wait):
    """wait 2.5: while sampling; wait 0.2: while the worker processes start."""
    import signal
    out_path = bad_scenes / "long.exr"
    proc = _start(bad_scenes, "world_only.blend", "-o", out_path, *LONG)
    _after_export(proc, wait)
    workers = _children(proc.pid)
    seconds, out, err = _signal_and_wait(proc, getattr(signal, sig), group)
    assert proc.returncode == code, err
    assert err.strip().splitlines() == ["Interrupted."], err  # no worker tracebacks either
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
