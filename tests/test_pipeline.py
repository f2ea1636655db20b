"""Pipelines: render.py as a farm runs it - frames, a missing engine, threads,
logs, metadata, split frames and their merge - on a tiny animated scene in a subprocess."""
from __future__ import annotations

import importlib.util
import os
import pathlib
import subprocess
import sys
import textwrap

import numpy as np
import pytest

pytestmark = pytest.mark.blender

ROOT = pathlib.Path(__file__).resolve().parents[1]
RENDER = ROOT / "render.py"

# A plane under a point light whose power is keyframed 100 W (frame 1) -> 900 W (frame 3).
BUILD = textwrap.dedent('''
    import sys, bpy, mathutils
    out = sys.argv[-1]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.resolution_x, sc.render.resolution_y = 24, 16
    sc.render.resolution_percentage = 100
    me = bpy.data.meshes.new("plane")
    me.from_pydata([(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], [], [(0, 1, 2, 3)])
    me.update()
    sc.collection.objects.link(bpy.data.objects.new("plane", me))
    box = bpy.data.meshes.new("box")
    box.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0), (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)],
                    [], [(4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)])
    box.update()
    sc.collection.objects.link(bpy.data.objects.new("box", box))
    ld = bpy.data.lights.new("lamp", 'POINT')
    lo = bpy.data.objects.new("lamp", ld)
    lo.location = (1, -1, 3)
    sc.collection.objects.link(lo)
    for frame, energy in ((1, 100.0), (3, 900.0)):
        ld.energy = energy
        ld.keyframe_insert("energy", frame=frame)
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    cam.location = (0, -5, 4)
    sc.collection.objects.link(cam)
    cam.rotation_euler = (mathutils.Vector((0, 0, 0)) - cam.location).to_track_quat('-Z', 'Y').to_euler()
    sc.camera = cam
    sc.frame_start, sc.frame_end, sc.frame_current = 1, 3, 2
    sys.path.insert(0, sys.argv[-2])
    from _bootstrap import load_ember
    load_ember().register()
    sc.ember.batch_size = 1024  # several items per frame, so that worker processes would pay off
    bpy.ops.wm.save_as_mainfile(filepath=out + "/anim.blend")
''')


def _env(tmp, **extra):
    env = dict(os.environ)
    env["BLENDER_USER_RESOURCES"] = str(tmp / "blender_user")
    env["TMPDIR"] = str(tmp)
    env.pop("PYTHONPATH", None)
    env.update(extra)
    return env


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    pytest.importorskip("bpy")
    d = tmp_path_factory.mktemp("pipeline")
    proc = subprocess.run([sys.executable, "-c", BUILD, str(ROOT), str(d)], env=_env(d), capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return d


def run(scenes, *args, env=None, timeout=180):
    proc = subprocess.run([sys.executable, str(RENDER), *map(str, args)], cwd=scenes, env=env or _env(scenes),
                          capture_output=True, text=True, timeout=timeout)
    return proc.returncode, proc.stdout, proc.stderr


def read(path):
    from ember.engine import imageio
    ch, header = imageio.read_exr(path)
    return np.stack([ch[c] for c in "RGBA"], axis=-1), header


def _render_py():
    spec = importlib.util.spec_from_file_location("render_py_under_test", RENDER)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# --- 5. fail loudly ----------------------------------------------------------------------------

def test_missing_engine_fails_loudly(scenes, tmp_path):
    """An add-on that cannot load (its Embree wheel missing) exits 1 with one clear line and
    writes nothing - never a render by another engine."""
    fake = tmp_path / "fake" / "embreex"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text('raise ImportError("simulated: no embreex wheel")\n')
    code, out, err = run(scenes, "anim.blend", "-o", "missing.png", env=_env(scenes, PYTHONPATH=str(fake.parent)))
    assert code == 1, (out, err)
    assert "Traceback" not in err
    line = [l for l in err.splitlines() if l.startswith("render.py: error:")]
    assert len(line) == 1 and "Ember engine is not available" in line[0] and "embreex" in line[0], err
    assert not (scenes / "missing.png").exists()


def test_unregistered_engine_is_refused():
    """A scene whose render.engine cannot become EMBER (not registered) is refused."""
    rp = _render_py()

    class Render:
        def __init__(self):
            self._engine = "BLENDER_EEVEE_NEXT"

        @property
        def engine(self):
            return self._engine

        @engine.setter
        def engine(self, value):
            raise TypeError(f"enum {value!r} not found")

    class Scene:
        render = Render()

    with pytest.raises(rp.EngineMissing, match="'EMBER' is not registered.*BLENDER_EEVEE_NEXT"):
        rp._require_ember(Scene())


# --- 1. frames ---------------------------------------------------------------------------------

def test_frame_specs_and_paths():
    rp = _render_py()
    assert rp.parse_frames("1-3", (1, 250, 1)) == [1, 2, 3]
    assert rp.parse_frames("1,3,10-12,3", (1, 250, 1)) == [1, 3, 10, 11, 12]
    assert rp.parse_frames("all", (5, 11, 3)) == [5, 8, 11]
    assert rp.parse_frames("-2--1", (1, 2, 1)) == [-2, -1]
    for bad in ("1-", "a", "3-1", "1,,2"):
        with pytest.raises(rp.UsageError, match="--frames"):
            rp.parse_frames(bad, (1, 250, 1))
    P = pathlib.Path
    assert rp.frame_path(P("out/shot_####.exr"), 7, True) == P("out/shot_0007.exr")
    assert rp.frame_path(P("a##/b_#_##.png"), 123, True) == P("a##/b_#_123.png")  # the last run, in the name
    assert rp.frame_path(P("out.png"), 7, True) == P("out0007.png")
    assert rp.frame_path(P("out.png"), 7, False) == P("out.png")


def test_frames_write_one_file_each(scenes):
    code, out, err = run(scenes, "anim.blend", "--frames", "1-3", "--samples", "4", "-o", "anim_##.exr")
    assert code == 0, err
    lines = [l for l in out.splitlines() if l.startswith("Ember: anim.blend frame")]
    assert [l.split(" -> ")[0][-5:] for l in lines] == ["(1/3)", "(2/3)", "(3/3)"]
    means = []
    for frame in (1, 2, 3):
        img, header = read(scenes / f"anim_{frame:02d}.exr")
        assert header["ember/frame"] == frame and header["ember/samples"] == 4
        means.append(float(img[..., :3].mean()))
    # The light's power is keyframed 100 -> 500 -> 900 W: the image scales with it.
    assert means[1] / means[0] == pytest.approx(5.0, rel=1e-4)
    assert means[2] / means[0] == pytest.approx(9.0, rel=1e-4)


def test_animation_through_blender(scenes):
    """`blender -b anim.blend -a`: Blender's own animation render calls Ember per frame."""
    script = textwrap.dedent(f'''
        import sys, bpy
        sys.path.insert(0, {str(ROOT)!r})
        from _bootstrap import load_ember
        load_ember().register()
        bpy.ops.wm.open_mainfile(filepath={str(scenes / "anim.blend")!r})
        sc = bpy.context.scene
        sc.render.engine = 'EMBER'
        sc.ember.samples = 2
        sc.render.image_settings.file_format = 'OPEN_EXR'
        sc.render.filepath = {str(scenes / "blender_a_")!r}
        sc.frame_end = 2
        bpy.ops.render.render(animation=True)
    ''')
    proc = subprocess.run([sys.executable, "-c", script], cwd=scenes, env=_env(scenes), capture_output=True,
                          text=True, timeout=180)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.count("Ember done: 2 samples") == 2, proc.stdout
    files = sorted(p.name for p in scenes.glob("blender_a_*.exr"))
    assert files == ["blender_a_0001.exr", "blender_a_0002.exr"]


# --- 3. threads --------------------------------------------------------------------------------

def _processes(out):
    line = [l for l in out.splitlines() if l.startswith("Ember: anim.blend")][-1]
    return int(line.split(" worker processes")[0].rsplit(" ", 1)[1])


def test_render_threads_setting():
    from ember.engine.blender.export_settings import render_threads
    from ember.engine.parallel.workers import available_cores

    class R:
        def __init__(self, mode, threads):
            self.threads_mode, self.threads = mode, threads

    assert render_threads(R("FIXED", 3)) == 3  # as asked, like Cycles
    assert render_threads(R("AUTO", 1)) == 1  # `blender -t 1`
    assert render_threads(R("AUTO", 4096)) == available_cores()  # Auto-detect: the affinity mask


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="needs Linux CPU affinity")
def test_threads_and_affinity(scenes):
    """--threads 1 and a process pinned to one CPU start no worker process; --threads 2 starts two."""
    args = ("anim.blend", "--samples", "16", "-o", "threads.exr")
    code, out, err = run(scenes, *args, "--threads", "1")
    assert code == 0, err
    assert _processes(out) == 0
    code, out, err = run(scenes, *args, "--threads", "2")
    assert code == 0, err
    assert _processes(out) == 2
    pinned = subprocess.run([sys.executable, str(RENDER), *args], cwd=scenes, env=_env(scenes), capture_output=True,
                            text=True, timeout=180, preexec_fn=lambda: os.sched_setaffinity(0, {min(os.sched_getaffinity(0))}))
    assert pinned.returncode == 0, pinned.stderr
    assert _processes(pinned.stdout) == 0


# --- 4. logs and metadata ----------------------------------------------------------------------

def test_log_lines_without_a_terminal(capsys):
    """No TTY: one line per LOG_EVERY seconds with frame, samples, elapsed, remaining, rays/s."""
    rp = _render_py()
    from types import SimpleNamespace
    follower = rp._Follower(show_progress=False, log=True, frame=12)
    progress = SimpleNamespace(samples_done=8, samples_target=32, fraction=0.25, elapsed=3.0,
                               rays_per_second=2.5e6, stage="pixels")
    follower.on_progress("ViewLayer", progress)  # too soon after the start: nothing
    assert capsys.readouterr().err == ""
    follower.last_log -= follower.LOG_EVERY
    follower.on_progress("ViewLayer", progress)
    follower.on_progress("ViewLayer", progress)  # again too soon
    lines = capsys.readouterr().err.splitlines()
    assert lines == ["Ember: frame 12 | ViewLayer | sample 8/32 | 3.0 s | ~9 s left | 2.50 M rays/s"]


def test_exr_metadata(scenes):
    code, out, err = run(scenes, "anim.blend", "--samples", "3", "--seed", "7", "-o", "meta.exr")
    assert code == 0, err
    assert err.strip() == "" or "Ember:" not in err  # a short render logs no progress line
    _, h = read(scenes / "meta.exr")
    assert (h["ember/engine"], h["ember/integrator"], h["ember/samples"], h["ember/seed"]) == ("Ember", "path", 3, 7)
    assert h["ember/sampleRange"] == "[0, 3)" and h["ember/frame"] == 2 and h["ember/version"] != "unknown"
    assert 0 < h["ember/renderSeconds"] < 60 and len(h["ember/sceneDigest"]) == 40


# --- 6. split frames that merge exactly --------------------------------------------------------

F32_ULP = 2.0 ** -23


def _merge(scenes, *parts, out="merged.exr"):
    return run(scenes, "merge", *parts, "-o", out)


@pytest.mark.parametrize("integrator", ["path", "photon"])
def test_sample_ranges_merge_into_the_full_render(scenes, integrator):
    """[0, 32) + [32, 64) merged = the 64-sample render to float32 rounding (2 ulp: the parts'
    means and the merge are each rounded once)."""
    common = ("anim.blend", "--seed", "3", "--integrator", integrator, "--photons", "2000", "--caustic-photons", "0",
              "--gather-rays", "2")
    tag = integrator
    for args, out in (((), f"{tag}_full.exr"), (("--samples", "32"), f"{tag}_a.exr"),
                      (("--samples", "32", "--sample-offset", "32"), f"{tag}_b.exr")):
        samples = () if args else ("--samples", "64")
        code, _, err = run(scenes, *common, *samples, *args, "-o", out)
        assert code == 0, err
    code, out, err = _merge(scenes, f"{tag}_a.exr", f"{tag}_b.exr", out=f"{tag}_merged.exr")
    assert code == 0, err
    full, _ = read(scenes / f"{tag}_full.exr")
    merged, header = read(scenes / f"{tag}_merged.exr")
    part, _ = read(scenes / f"{tag}_a.exr")
    assert header["ember/sampleRange"] == "[0, 64)" and header["ember/samples"] == 64
    np.testing.assert_allclose(merged, full, rtol=2 * F32_ULP, atol=0)
    assert np.abs(part - full).max() > 1e3 * F32_ULP * np.abs(full).max()  # the parts differ from the whole


def test_tiles_and_ranges_merge_into_the_full_render(scenes):
    """Four parts: the left half in two sample ranges, the right half (a render border) whole."""
    common = ("anim.blend", "--seed", "5")
    jobs = [(("--samples", "64"), "t_full.exr"),
            (("--samples", "16", "--border", "0,0,0.5,1"), "t_l0.exr"),
            (("--samples", "48", "--sample-offset", "16", "--border", "0,0,0.5,1"), "t_l1.exr"),
            (("--samples", "64", "--border", "0.5,0,1,1"), "t_r.exr")]
    for args, out in jobs:
        code, _, err = run(scenes, *common, *args, "-o", out)
        assert code == 0, err
    code, _, err = _merge(scenes, "t_l0.exr", "t_r.exr", "t_l1.exr", out="t_merged.exr")
    assert code == 0, err
    full, _ = read(scenes / "t_full.exr")
    merged, header = read(scenes / "t_merged.exr")
    assert header["ember/border"] == "[0, 0, 24, 16]" and header["ember/samples"] == 64
    np.testing.assert_allclose(merged, full, rtol=2 * F32_ULP, atol=0)


def test_merge_refuses_parts_that_do_not_belong_together(scenes):
    common = ("anim.blend", "--samples", "4")
    for args, out in ((("--seed", "1", "--frames", "2-3"), "r_#.exr"),  # frames 2 and 3: other light power
                      (("--seed", "2", "--sample-offset", "4"), "r_seed.exr"),
                      (("--seed", "1", "--sample-offset", "2"), "r_overlap.exr")):
        code, _, err = run(scenes, *common, *args, "-o", out)
        assert code == 0, err
    for parts, words in ((("r_2.exr", "r_seed.exr"), ["seed 2", "seed 1"]),
                         (("r_2.exr", "r_3.exr"), ["different scenes"]),
                         (("r_2.exr", "r_overlap.exr"), ["same samples"]),
                         (("r_2.exr", "anim.blend"), ["cannot read"])):
        code, _, err = _merge(scenes, *parts, out="refused.exr")
        assert code == 2, err
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("render.py: error:"), err
        assert all(w in lines[0] for w in words), (words, lines[0])
        assert not (scenes / "refused.exr").exists()


def test_ppm_refuses_a_sample_offset(scenes):
    code, _, err = run(scenes, "anim.blend", "--integrator", "ppm", "--samples", "2", "--sample-offset", "2",
                       "-o", "ppm.exr")
    assert code == 2
    assert "sample offset does not apply to the 'ppm' integrator" in err.lower() and "Traceback" not in err


# --- 2. persistent data ------------------------------------------------------------------------

def _builds(out):
    """[(processes, started, Embree builds, light builds)] per frame line."""
    import re
    rows = []
    for line in out.splitlines():
        m = re.search(r"(\d+) worker processes \((\d+) started, (\d+) Embree and (\d+) light builds\)", line)
        if m and line.startswith("Ember: anim.blend"):
            rows.append(tuple(int(g) for g in m.groups()))
    return rows


@pytest.mark.parametrize("threads", [2, 1])
def test_persistent_data_across_frames(scenes, threads):
    """Frames 1-4 in one run: the workers and the Embree scene of frame 1 serve the rest; the
    light tables are rebuilt only while the light's power changes (keyframes 1 -> 3); every
    image equals a fresh render of its frame."""
    code, out, err = run(scenes, "anim.blend", "--frames", "1-4", "--samples", "16", "--threads", threads,
                         "-o", f"persist{threads}_#.exr")
    assert code == 0, err
    workers = threads if threads > 1 else 0
    assert _builds(out) == [(workers, workers, 1, 1), (workers, 0, 0, 1), (workers, 0, 0, 1), (workers, 0, 0, 0)]
    code, out, err = run(scenes, "anim.blend", "--samples", "16", "--threads", threads, "-o", f"fresh{threads}.exr")
    assert code == 0, err
    assert _builds(out) == [(workers, workers, 1, 1)]
    fresh, _ = read(scenes / f"fresh{threads}.exr")
    kept, _ = read(scenes / f"persist{threads}_2.exr")
    np.testing.assert_array_equal(kept, fresh)
    np.testing.assert_array_equal(read(scenes / f"persist{threads}_3.exr")[0], read(scenes / f"persist{threads}_4.exr")[0])


def test_persistent_tracer_rebuilds_only_what_changed():
    """In-process persistent data: camera moves keep Embree and the light tables, a changed
    light keeps Embree, a changed mesh rebuilds both; without persistence nothing is kept."""
    sys.path.insert(0, str(ROOT / "tests"))
    from core_scenes import perspective, sphere_with_point_light
    from ember.engine import tracer as tracer_mod
    from ember.engine.session import RenderSession

    base = sphere_with_point_light(persistent=True, threads=1, samples=2, width=8, height=8)

    def builds(scene):
        stats = RenderSession(scene).run()
        return stats.builds["embree"], stats.builds["lights"], stats.builds["workers"]

    tracer_mod.forget()
    try:
        assert builds(base) == (1, 1, 0)
        assert builds(base.replace(camera=perspective((0, 0.2, 0), (0, 1, 0), 50))) == (0, 0, 0)
        brighter = base.lights.__class__(**{**base.lights.__dict__, "Le": base.lights.Le * 2})
        assert builds(base.replace(lights=brighter)) == (0, 1, 0)
        moved = base.mesh.__class__(**{**base.mesh.__dict__, "vertices": base.mesh.vertices * 0.9})
        assert builds(base.replace(mesh=moved)) == (1, 1, 0)
        plain = base.replace(settings=base.settings.replace(persistent=False))
        assert builds(plain) == (1, 1, 0) and builds(plain) == (1, 1, 0)
    finally:
        tracer_mod.forget()


def test_merge_unit_refusals_and_weights():
    """engine.merge on synthetic parts: per-pixel weights from sample counts and borders, and
    the parts it refuses (stopped early, cropped, a merge with gaps)."""
    from ember.engine.merge import MergeError, Part, merge

    def part(name, value, samples, offset, border, **extra):
        header = {"ember/engine": "Ember", "ember/sceneDigest": "d", "ember/stoppedBy": "done",
                  "ember/border": str(list(border)), "ember/samples": samples, "ember/sampleOffset": offset,
                  "ember/seed": 0, "ember/sampleRange": f"[{offset}, {offset + samples})", **extra}
        ch = {c: np.full((2, 4), value, np.float32) for c in "RGB"}
        return name, ch, header

    a = Part.from_exr(*part("a", 1.0, 1, 0, (0, 0, 4, 2)))
    b = Part.from_exr(*part("b", 4.0, 3, 1, (2, 0, 4, 2)))
    image, header = merge([a, b])
    assert image[0, 0, 0] == 1.0 and image[0, 3, 0] == (1 * 1.0 + 3 * 4.0) / 4  # weights 1 and 3
    assert header["ember/samplesPerPixel"].startswith("1..4")
    for bad, words in ((part("s", 1.0, 4, 0, (0, 0, 4, 2), **{"ember/stoppedBy": "time limit"}), "stopped early"),
                       (part("c", 1.0, 4, 0, (0, 0, 4, 2), **{"ember/crop": "[0, 0, 4, 2]"}), "cropped"),
                       (part("g", 1.0, 4, 0, (0, 0, 4, 2), **{"ember/sampleRange": "[0, 2) [4, 6)"}), "merge its parts"),
                       (("x", {}, {}), "not a render.py EXR")):
        with pytest.raises(MergeError, match=words):
            Part.from_exr(*bad)
