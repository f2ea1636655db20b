"""Ember headless render.

    python render.py scene.blend --output out.png [options]      (bpy module)
    blender -b scene.blend -P render.py -- --output out.exr [options]
    python render.py scene.blend --frames 1-250 --output frames/shot_####.exr
    python render.py merge part*.exr --output frame.exr           (no Blender needed)

Options (each defaults to the scene's own setting):
    --output PATH        .png: 8-bit RGBA through the scene's colour management (view
                         transform, look, compositor) - what Blender would save;
                         .exr: linear float32 RGBA, straight from the film.
                         Default: <blend name>.png in the current directory.
                         '#' characters are the frame number, zero-padded to their count
                         (the last run of them in the file name, as Blender's output path);
                         with --frames and no '#', four are put before the extension.
    --frames SPEC        frames to render, one file each: 5, 1-250, 1,3,10-12, or all (the
                         scene's frame range and step). Default: the scene's current frame.
    --preset NAME        preview or final: Ember's sampling presets (applied before the other
                         options, which then override single values)
    --resolution WxH     frame size in pixels (resolution percentage becomes 100 %)
    --border X0,Y0,X1,Y1 render only this region (Blender's render border: fractions of the
                         frame, y from the bottom), uncropped: tiles that `merge` puts together
    --threads N          CPU threads, one worker process each (1: all in this process). Default:
                         Render Properties > Performance > Threads; Auto-detect uses every CPU
                         the process may run on (its affinity: taskset, cgroups); `blender -t N`
                         is honoured as Blender's own override
    --reference REF.exr  print relMSE (eps 1e-2) against this linear image (R, G, B
                         channels, the render's size) as passes complete and at the end
    --no-progress        no progress on stderr (a bar on a terminal; without one, e.g. in a
                         farm's log, one line every few seconds)
Every Ember setting with a flag in engine/settings.py is an option too, checked against its
declared range or choices (--samples N, --integrator NAME, --max-depth N, --photons N,
--icache-a A, --diffuse-bounces N, --adaptive on|off, ...): `render.py --help` lists them by
subsystem, README's settings table with their defaults and ranges.

Merge: `render.py merge PART.exr ... --output OUT.exr` combines EXRs that render.py wrote of
one frame - disjoint sample ranges (--sample-offset), tiles (--border) or both - weighting each
pixel by the samples each part took there (read from the parts' metadata), every channel:
colour, alpha and, in multilayer files, every pass. The merge of any
split equals the render of all the samples at once to float32 rounding. Parts of different
scenes or settings (the metadata's scene digest), of different seeds, with overlapping sample
ranges, cropped, or stopped early (time limit, noise target, Ctrl-C: unequal sample counts) are
refused with one line (exit 2), as are parts with malformed metadata.

The .blend is only read: settings are changed on the loaded copy in memory and nothing
is saved. The image is written to a hidden temporary file beside the output, checked, and
renamed into place: a failed write (full disk, permission) exits 1 and leaves a previous
file at that path untouched. Exit codes: 0 done, 1 render failed (also: the Ember engine could not be loaded or
registered - render.py never renders with another engine), 2 bad input (file, option, scene),
130 interrupted (Ctrl-C), 143 terminated (SIGTERM, also to the whole process group): one
line, the render stops within about a second (a second signal stops at once) and the output
is the previous file or, for a signal as the write ended, the complete new one; a signal once
the file is in place is too late to stop anything (exit 0).

Design: the render goes through bpy.ops.render.render with the EMBER engine, the same
path as F12 in Blender (engine/blender/final.py: export, progressive result writes,
border, view layers, error reports, compositor), so the CLI exercises and tests the
product rather than a parallel path. It follows the render through final.listeners
(progress bar, stop on Ctrl-C, the film for EXR output).
"""
from __future__ import annotations

import argparse
import functools
import os
import pathlib
import shutil
import signal
import sys
import math
import re
import tempfile
import time

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED, EXIT_TERMINATED = 0, 1, 2, 130, 143
HERE = pathlib.Path(__file__).resolve().parent
IN_BLENDER = "bpy" in sys.modules  # Blender's own interpreter has bpy loaded before -P runs
BLEND_MAGIC = (b"BLENDER", b"\x28\xb5\x2f\xfd", b"\x1f\x8b")  # plain, zstd, gzip


class UsageError(Exception):
    """Bad input: printed as one line, exit code 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise UsageError(message)


def _int_in(minimum, maximum):
    """argparse type: a whole number in minimum..maximum (options that are no Ember setting)."""
    def parse(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a whole number (got {text!r})")
        problem = _declared().range_problem(value, minimum, maximum)
        if problem:
            raise argparse.ArgumentTypeError(problem)
        return value
    return parse


def _declared():
    """engine/settings.py, the settings' declarations (plain Python: cheap before bpy)."""
    _load_ember()
    from ember.engine import settings
    return settings


def _setting_type(declared, s):
    """argparse type of a declared setting: its text read (on|off, numbers, choices in any
    case) and checked against its range or choices and Blender's 32-bit limits."""
    def parse(text):
        try:
            value = declared.from_text(s, text)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e))
        problem = declared.problem(s, value, blender=True)
        if problem:
            raise argparse.ArgumentTypeError(problem)
        return value
    return parse


def _setting_help(declared, s) -> str:
    """--help's text of a declared setting: its description, range, unit and integrators."""
    text = s.description
    if s.kind in (int, float):
        text += f"; {declared.range_text(s)}" + (f" {declared.UNITS[s.unit]}" if s.unit else "")
    if s.honoured_by:
        text += f" [{', '.join(s.honoured_by)}]"
    return text.replace("%", "%%")


def add_setting_options(parser, declared, groups) -> None:
    """One option per declared setting with a flag, in an argument group per subsystem;
    its value lands in args.<setting name> (None: not given)."""
    for g in groups:
        flagged = [s for s in g.settings if s.flag]
        if not flagged:
            continue
        section = parser.add_argument_group(f"{g.label} settings")
        for s in flagged:
            section.add_argument(s.flag, dest=s.name, type=_setting_type(declared, s), metavar=_metavar(s),
                                 help=_setting_help(declared, s))


def _metavar(s) -> str:
    if s.kind is bool:
        return "on|off"
    if s.kind is str:
        return "|".join(s.values) or "NAME"
    return {"s": "S", "m": "M"}.get(s.unit, "N" if s.kind is int else "X")


def _resolution(text):
    parts = text.lower().split("x")
    try:
        w, h = (int(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT such as 640x480, got {text!r}")
    if w < 1 or h < 1 or w > 65536 or h > 65536:
        raise argparse.ArgumentTypeError(f"width and height must be 1..65536, got {text!r}")
    return w, h


def _border(text):
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 4 or not all(0 <= v <= 1 for v in values):
        raise argparse.ArgumentTypeError(f"expected four fractions X0,Y0,X1,Y1 in 0..1, got {text!r}")
    x0, y0, x1, y1 = values
    if not (x0 < x1 and y0 < y1):
        raise argparse.ArgumentTypeError(f"the border's X0 < X1 and Y0 < Y1 must hold, got {text!r}")
    return values


def build_parser(blend_required: bool) -> argparse.ArgumentParser:
    declared = _declared()
    p = _Parser(prog="render.py", description="Render a .blend with Ember, headless.",
                epilog="Options left out keep the scene's own settings.")
    p.add_argument("blend", nargs=None if blend_required else "?", help="the .blend file to render")
    p.add_argument("-o", "--output", help="output image, .png or .exr (default: <blend name>.png)")
    p.add_argument("--resolution", type=_resolution, help="WIDTHxHEIGHT in pixels")
    p.add_argument("--border", type=_border, help="render border X0,Y0,X1,Y1 (fractions, y up), uncropped")
    p.add_argument("--threads", type=_int_in(1, 1024),
                   help="CPU threads (worker processes); default: the scene's setting, Auto-detect = "
                        "the CPUs this process may use (affinity)")
    p.add_argument("--frames", help="frames to render: 5, 1-250, 1,3,10-12 or all (one file each)")
    p.add_argument("--preset", choices=("preview", "final"), help="Ember's sampling preset, before the other options")
    p.add_argument("--reference", help="linear EXR to print relMSE against while rendering")
    p.add_argument("--no-progress", action="store_true",
                   help="no progress (a bar on a terminal, else a log line every few seconds)")
    p.add_argument("--scheduler", help="render on Dask: tcp://HOST:PORT of a scheduler, or local:N workers")
    p.add_argument("--chunk-samples", type=_int_in(1, declared.INT_MAX),
                   help="with --scheduler: at most this many samples per task (frames split, then merged)")
    p.add_argument("--send-blend", action="store_true",
                   help="with --scheduler: send the .blend's bytes, its external images packed into it, to "
                        "the workers (else they read its path)")
    p.add_argument("--missing-textures", choices=("warn", "error"),
                   help="an image file the scene uses that is missing: a warning and magenta (as Cycles; the "
                        "default) or an error (exit 2; the default of --scheduler's tasks)")
    add_setting_options(p, declared, declared.GROUPS)
    return p


def _exists(path: pathlib.Path, what: str, kind: str = "file") -> bool:
    """Whether `path` exists as a file (or "dir"); a directory on the way that may not be
    searched is bad input (one line), not a PermissionError traceback."""
    try:
        return path.is_dir() if kind == "dir" else path.is_file()
    except PermissionError:
        raise UsageError(f"cannot open {what} {path}: permission denied (a directory on its path "
                         "may not be searched)") from None


def _check_blend(path: pathlib.Path) -> None:
    if not _exists(path, ".blend"):
        if path.exists():
            raise UsageError(f"not a file: {path}")
        raise UsageError(f"file not found: {path}")
    try:
        with open(path, "rb") as fh:
            head = fh.read(7)
    except OSError as e:
        raise UsageError(f"cannot read {path}: {e.strerror or e}")
    if not head.startswith(BLEND_MAGIC):
        raise UsageError(f"not a .blend file: {path}")


def _check_output(path: pathlib.Path) -> str:
    kind = path.suffix.lower()
    if kind not in (".png", ".exr"):
        raise UsageError(f"output must end in .png or .exr, got {str(path)!r}")
    parent = path.parent if str(path.parent) else pathlib.Path(".")
    if _exists(path, "output", "dir"):
        raise UsageError(f"output path is a directory: {path}")
    if not _exists(parent, "output directory", "dir"):
        raise UsageError(f"output directory does not exist: {parent}")
    _check_writable(path)
    return kind


def _check_writable(path: pathlib.Path) -> None:
    """The image is written beside `path` under a longer temporary name and renamed into
    place: the directory must take that file. Really try it (permission bits say little for
    root or read-only file systems; the name may be too long only with the temporary's
    additions)."""
    if path.exists() and not os.access(path, os.W_OK):
        raise UsageError(f"output path is not writable: {path}")
    _load_ember()
    from ember.engine import imageio
    try:
        imageio.check_writable(path)
    except imageio.OutputError as e:
        raise UsageError(str(e).replace("could not write", "cannot write", 1)) from None


class _Follower:
    """A final.listeners entry: progress (a bar on a terminal, log lines without one),
    Ctrl-C stop, the film, the scene's digest and errors."""

    LOG_EVERY = 5.0  # seconds between progress lines in a log (no terminal)

    def __init__(self, show_progress: bool, reference=None, log: bool = False, frame=None):
        self.show_progress = show_progress
        self.reference = reference  # _Reference or None
        self.log, self.frame = log, frame
        self.last_log = time.perf_counter()
        self.bar = None
        self.bar_layer = None
        self.layers = {}  # layer -> (stats, image, border)
        self.digests = {}  # layer -> engine.scene.scene_digest of what was rendered
        self.errors = []  # (message, user_error)
        self.passes = {}  # layer -> {pass name: (H, W, C) image} (enabled passes besides Combined)

    # final.RenderListener interface -------------------------------------------------
    def should_stop(self):
        return STOP.requested

    def on_export(self, layer, text):
        if self.show_progress and self.bar is None:
            sys.stderr.write(f"\r{layer}: export: {text[:60]:<60}")
            sys.stderr.flush()

    def on_scene(self, layer, scene):
        from ember.engine.scene import scene_digest
        self.digests[layer] = scene_digest(scene)

    def on_progress(self, layer, progress):
        error = self.reference.update(progress, self.bar is None) if self.reference else None
        if self.log and time.perf_counter() - self.last_log >= self.LOG_EVERY:
            self.last_log = time.perf_counter()
            print(log_line(self.frame, layer, progress), file=sys.stderr, flush=True)
        if not self.show_progress:
            return
        limit = getattr(progress, "time_limit", 0.0)
        if self.bar is None or self.bar_layer != layer:
            self._close_bar()
            from tqdm import tqdm
            sys.stderr.write("\r" + " " * 80 + "\r")
            cols = shutil.get_terminal_size((80, 24)).columns
            if limit > 0:  # the bar is the share of the time limit (Blender's progress bar too)
                self.bar = tqdm(total=limit, desc=layer, file=sys.stderr, ncols=max(40, min(cols, 120)), leave=True,
                                bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.1f}/{total:.1f} s{postfix}")
            else:
                self.bar = tqdm(total=progress.samples_target, desc=layer, unit="spp", file=sys.stderr,
                                ncols=max(40, min(cols, 120)), leave=True)
            self.bar_layer = layer
        postfix = f"{progress.rays_per_second / 1e6:.2f} M rays/s"
        if limit > 0:
            self.bar.n = min(max(progress.fraction * limit, 0.0), limit)
            postfix = f"{progress.samples_done}/{progress.samples_target} spp, {postfix}"
        else:
            self.bar.n = progress.samples_done
        if getattr(progress, "stage", "pixels") != "pixels":
            postfix = f"{progress.stage}, {postfix}"
        if error is not None:
            postfix += f", relMSE {error:.3e}"
        self.bar.set_postfix_str(postfix, refresh=False)
        self.bar.refresh()

    def on_run_done(self, layer, stats):
        if self.bar is not None and not stats.cancelled:
            self.bar.n = self.bar.total  # done (as Blender's bar): all samples, or the limit reached
        self._close_bar()  # before the summary line, which would otherwise run into the bar

    def on_layer_done(self, layer, stats, image, border):
        self._close_bar()
        self.layers[layer] = (stats, image, border)

    def on_error(self, layer, message, user_error):
        self._close_bar()
        self.errors.append((message, user_error))

    def on_layer_passes(self, layer, passes, metadata):
        self.passes[layer] = passes

    # -------------------------------------------------------------------------------
    def _close_bar(self):
        if self.bar is not None:
            self.bar.close()
            self.bar = None



class _Stop:
    """SIGINT (Ctrl-C) and SIGTERM: one line on stderr, then stop within about a second.

    Mostly (`soft`) the request is a flag: checked between the phases (bpy import, file
    load, add-on registration: a KeyboardInterrupt inside Blender's own start-up code
    crashed it) and polled by the render loop (export and sampling stop at their next
    check, ~0.25 s; worker processes are killed). While the image is written the signal
    raises KeyboardInterrupt at once, which removes the half-written temporary. Python runs signal handlers only between bytecodes, so a
    watcher thread woken by the C-level handler (signal.set_wakeup_fd) ends the process
    GRACE seconds after the first signal if it is still running (a long build or file load
    in C), and at once after a second one. No output file is written after a stop."""

    GRACE = 0.7  # seconds: more than the render loop needs to stop (it polls every update)

    def __init__(self):
        self.requested = False
        self.signum = None
        self.soft = True  # Blender's own Python (bpy import, add-on loading) must not be interrupted
        self.output = None  # the output path, whose temporaries an abort removes
        self._printed = False
        self.holding = False  # the output is complete: a signal is noted, not announced (hold)
        self.held = None

    @property
    def code(self) -> int:
        return EXIT_TERMINATED if self.signum == signal.SIGTERM else EXIT_INTERRUPTED

    def install(self) -> None:
        import threading
        r, w = os.pipe()
        os.set_blocking(w, False)
        signal.set_wakeup_fd(w, warn_on_full_buffer=False)
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, self)
        threading.Thread(target=self._watch, args=(r,), daemon=True, name="render.py-stop").start()

    def check(self) -> None:
        """Between phases: stop if a signal came."""
        if self.requested:
            raise KeyboardInterrupt

    def hold(self) -> None:
        """The output is complete (its summary line, the exit follow): a signal from here is
        too late to change it and is only noted, so that an interrupted render never also
        reports success."""
        self.holding = True

    def release(self) -> None:
        """Another frame follows: a signal noted while holding stops it."""
        self.holding = False
        if self.held is not None:
            signum, self.held = self.held, None
            self(signum, None)

    def _say(self) -> None:
        if not self._printed:
            self._printed = True
            sys.stderr.write(("\n" if sys.stderr.isatty() else "") + "Interrupted.\n")
            sys.stderr.flush()

    def __call__(self, signum, frame):
        """The Python-level handler (main thread)."""
        if self.holding:
            self.held = self.held or signum
            return
        if self.requested and self.signum is not None and self._printed:
            return  # the watcher counts repeated signals
        self.requested, self.signum = True, signum
        self._say()
        if not self.soft:
            raise KeyboardInterrupt

    def _watch(self, fd: int) -> None:
        import time as _time
        deadline = None
        while True:
            try:
                data = os.read(fd, 64)
            except OSError:
                return
            if not data:
                return
            if self.holding:
                self.held = self.held or data[0]
                continue
            if self.signum is None:
                self.signum = data[0]
            self.requested = True
            if deadline is not None or len(data) > 1:  # a second signal: stop now
                self.abort()
            deadline = _time.monotonic() + self.GRACE
            import threading
            timer = threading.Timer(self.GRACE, self.abort)
            timer.daemon = True
            timer.start()

    def abort(self) -> None:
        """End the process now, without leaving a temporary output file or a shared-memory
        segment behind."""
        self._say()
        shared = sys.modules.get("ember.engine.parallel.shared")  # no import here: another thread may hold its lock
        if shared is not None:
            try:
                shared.unlink_all()
            except Exception:
                pass
        if self.output is not None:
            try:
                from ember.engine import imageio
                imageio.remove_stale_temporaries(self.output, include_own=True)
            except Exception:
                pass
        try:
            sys.stdout.flush()
        except Exception:
            pass
        os._exit(self.code)


STOP = _Stop()


class _Reference:
    """relMSE of the film against a reference image while the render runs (engine.metrics)."""

    PRINT_EVERY = 2.0  # seconds between progress lines, besides power-of-two sample counts

    def __init__(self, path: pathlib.Path, metrics, imageio):
        self.path, self.metrics = path, metrics
        try:
            self.image = imageio.read_rgb(path).astype(float)
        except KeyError:
            raise UsageError(f"reference {path} has no R, G, B channels")
        except (OSError, RuntimeError, ValueError) as e:
            raise UsageError(f"cannot read reference {path}: {e}")
        self.last_print = -float("inf")
        self.printed_n = 0
        self.last = None

    def check_size(self, width: int, height: int) -> None:
        h, w = self.image.shape[:2]
        if (w, h) != (width, height):
            raise UsageError(f"reference {self.path} is {w}x{h} but the render is {width}x{height}")

    def error(self, image) -> float:
        """relMSE over the rendered pixels (alpha > 0) of an (H, W, 4) film image."""
        return self.metrics.rel_mse(image[..., :3], self.image, image[..., 3] > 0)

    def update(self, progress, print_line: bool):
        """relMSE after each completed pass (every pixel then has a sample); prints a line when
        the sample count passes a power of two and at least every PRINT_EVERY seconds."""
        if not progress.pass_completed:
            return self.last
        self.last = self.error(progress.film.image())
        n = progress.samples_done
        now = time.perf_counter()
        if print_line and (n.bit_length() > self.printed_n.bit_length()
                           or now - self.last_print >= self.PRINT_EVERY):
            print(f"relMSE {self.last:.4e} (eps {self.metrics.EPS:g}) at {n} samples, "
                  f"{progress.elapsed:.2f} s", flush=True)
            self.last_print, self.printed_n = now, n
        return self.last


def _apply_settings(scene, args) -> None:
    """Command-line overrides onto the in-memory scene (never saved)."""
    declared = _declared()
    ember = scene.ember
    if args.preset is not None:
        from ember.ui.presets import apply_preset
        apply_preset(ember, args.preset.upper())
    for s in declared.DECLARED.values():
        value = getattr(args, s.name, None) if s.flag else None
        if value is None:
            continue
        if s.kind is str:  # the property's items: the integrator's are only known here
            ids = [i.identifier for i in type(ember).bl_rna.properties[s.bpy_prop].enum_items]
            problem = declared.problem(s, value, choices=tuple(i.lower() for i in ids))
            if problem:
                raise UsageError(f"argument {s.flag}: {problem}")
            value = value.upper()
        setattr(ember, s.bpy_prop, value)
    if args.border is not None:
        r = scene.render
        r.use_border, r.use_crop_to_border = True, False
        r.border_min_x, r.border_min_y, r.border_max_x, r.border_max_y = args.border
    if args.threads is not None:  # Blender's own setting, which `blender -t N` overrides the same way
        scene.render.threads_mode = 'FIXED'
        scene.render.threads = args.threads
    if args.resolution is not None:
        (scene.render.resolution_x, scene.render.resolution_y,
         scene.render.resolution_percentage) = blender_resolution(*args.resolution)


def log_line(frame, layer: str, progress) -> str:
    """One progress line for a log: frame, samples, elapsed, estimated remaining, rays/s."""
    where = f"frame {frame} | " if frame is not None else ""
    stage = getattr(progress, "stage", "pixels")
    remaining = ""
    if 0 < progress.fraction < 1:
        remaining = f" | ~{progress.elapsed * (1 - progress.fraction) / progress.fraction:.0f} s left"
    return (f"Ember: {where}{layer} | {stage if stage != 'pixels' else 'sample'} "
            f"{progress.samples_done}/{progress.samples_target} | {progress.elapsed:.1f} s{remaining} | "
            f"{_fmt_rate(progress.rays_per_second)}")


def exr_metadata(stats, digest: str, border, frame: int, layer: str) -> dict:
    """What an Ember EXR records about its render (render.py merge reads it back)."""
    s = stats.settings
    offset = getattr(s, "sample_offset", 0)
    return {
        "ember/engine": "Ember", "ember/version": _version(), "ember/integrator": s.integrator,
        "ember/samples": int(stats.samples), "ember/seed": int(s.seed), "ember/pattern": s.pattern,
        "ember/sampleOffset": int(offset), "ember/sampleRange": f"[{offset}, {offset + stats.samples})",
        "ember/renderSeconds": float(stats.elapsed), "ember/stoppedBy": stats.stopped_by or "done",
        "ember/border": list(border), "ember/frame": int(frame), "ember/viewLayer": layer,
        "ember/sceneDigest": digest,
        **({"ember/auto": stats.auto[0]} if getattr(stats, "auto", ()) else {}),
    }


def blender_resolution(width: int, height: int) -> tuple[int, int, int]:
    """(resolution_x, resolution_y, resolution_percentage) giving a width x height frame.
    Blender clamps resolution_x/y to 4..65536 (a 1x1 request became 4x4) but applies the
    percentage after: size = resolution * percentage // 100, so small sizes take a small
    percentage, e.g. 1x1 = 100x100 at 1 %."""
    for pct in range(100, 0, -1):
        rx, ry = -(-100 * width // pct), -(-100 * height // pct)  # smallest with rx * pct // 100 == w
        if 4 <= rx <= 65536 and 4 <= ry <= 65536 and rx * pct // 100 == width and ry * pct // 100 == height:
            return rx, ry, pct
    raise UsageError(f"--resolution {width}x{height} cannot be expressed in Blender's render settings")


def _set_png_format(scene) -> None:
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):  # 5.0+: file_format lists depend on media_type
        settings.media_type = 'IMAGE'
    settings.file_format = 'PNG'
    settings.color_mode = 'RGBA'
    settings.color_depth = '8'


def _fmt_rate(r: float) -> str:
    return f"{r / 1e6:.2f} M rays/s" if r >= 1e5 else f"{r / 1e3:.1f} k rays/s"


def _clean_blender_error(text: str) -> str:
    text = str(text).strip().splitlines()[-1] if str(text).strip() else "render failed"
    return text[len("Error: "):] if text.startswith("Error: ") else text


class EngineMissing(Exception):
    """The Ember engine could not be loaded or registered: one line, exit code 1. render.py
    never lets Blender fall back to another engine (a farm would get EEVEE frames)."""


def _load_ember():
    if str(HERE) not in sys.path:
        sys.path.insert(0, str(HERE))
    from _bootstrap import load_ember
    return load_ember()


def _register_ember():
    """Load and register the add-on; EngineMissing if either fails."""
    try:
        ember = _load_ember()
        ember.register()
        from ember.engine.blender import registration
        registration.check_runtime()
    except Exception as e:  # any failure: missing wheel, bad install, registration error
        detail = f"{type(e).__name__}: {e}".strip().splitlines()[0][:200]
        raise EngineMissing(f"the Ember engine is not available: the add-on failed to load ({detail})")
    return ember


def _require_ember(scene) -> None:
    """Select EMBER on the scene and check that Blender really has it."""
    try:
        scene.render.engine = 'EMBER'
    except (TypeError, ValueError, AttributeError):
        pass
    if scene.render.engine != 'EMBER':
        raise EngineMissing("the Ember engine is not available: the render engine 'EMBER' is not registered "
                            f"(the scene would render with {scene.render.engine})")


def parse_frames(spec: str, scene_range: tuple[int, int, int]) -> list[int]:
    """'5', '1-250', '1,3,10-12' or 'all' (scene_range = (start, end, step)) -> frames in the
    order given, repeats dropped."""
    text = spec.strip().lower()
    if text == "all":
        start, end, step = scene_range
        frames = list(range(start, end + 1, max(step, 1)))
    else:
        frames = []
        for part in text.split(","):
            m = re.fullmatch(r"\s*(-?\d+)\s*(?:-\s*(-?\d+)\s*)?", part)
            if m is None:
                raise UsageError(f"--frames: expected frames such as 5, 1-250, 1,3,10-12 or all, got {spec!r}")
            a = int(m.group(1))
            b = int(m.group(2)) if m.group(2) is not None else a
            if b < a:
                raise UsageError(f"--frames: range {part.strip()!r} ends before it starts")
            frames.extend(range(a, b + 1))
    if not frames:
        raise UsageError(f"--frames {spec!r}: no frames (scene range {scene_range[0]}-{scene_range[1]})")
    if len(frames) > 1_000_000:
        raise UsageError(f"--frames {spec!r}: more than a million frames")
    return list(dict.fromkeys(frames))


def frame_path(path: pathlib.Path, frame: int, numbered: bool) -> pathlib.Path:
    """The output path of `frame`: the last run of '#' in the file name becomes the frame
    number zero-padded to its length (Blender's rule); without '#', `numbered` puts four
    digits before the extension (out.png -> out0001.png)."""
    name = path.name
    runs = list(re.finditer(r"#+", name))
    if runs:
        m = runs[-1]
        name = name[:m.start()] + f"{frame:0{len(m.group())}d}" + name[m.end():]
    elif numbered:
        name = f"{path.stem}{frame:04d}{path.suffix}"
    return path.with_name(name)


def missing_images() -> list[tuple[str, str]]:
    """(name, absolute path) of the images some datablock uses whose file is not there (not
    packed, not generated); a sequence or UDIM set counts as missing when its directory is."""
    import bpy
    out = []
    for image in bpy.data.images:
        if image.users == 0 or image.packed_file is not None or image.source not in ('FILE', 'SEQUENCE', 'TILED'):
            continue
        path = bpy.path.abspath(image.filepath, library=image.library)
        there = os.path.isdir(os.path.dirname(path)) if image.source != 'FILE' else os.path.isfile(path)
        if not there:
            out.append((image.name, path))
    return out


def _missing_text(missing) -> str:
    text = ", ".join(f"'{name}' ({path})" for name, path in missing[:3])
    return text + (f" and {len(missing) - 3} more" if len(missing) > 3 else "")


def _packed_blend_bytes() -> bytes:
    """The loaded .blend with its external images packed into it, as bytes: what --send-blend
    sends, so that textures on (relative) paths travel with the job. The file on disk is left
    as it is (a copy is saved)."""
    import bpy
    for image in bpy.data.images:
        if image.users and image.packed_file is None and image.source == 'FILE' and \
                os.path.isfile(bpy.path.abspath(image.filepath, library=image.library)):
            image.pack()
    with tempfile.TemporaryDirectory(prefix="ember-send-") as tmp:
        copy = pathlib.Path(tmp) / "scene.blend"
        # Other paths stay as written (relative ones to the original's directory, as the bytes
        # of the file itself would have them).
        bpy.ops.wm.save_as_mainfile(filepath=str(copy), copy=True, check_existing=False, relative_remap=False)
        return copy.read_bytes()


def _load_writers() -> None:
    """Import what writing a frame imports (OpenEXR's binding, the passes table, the version's
    TOML reader) while a signal is only a flag."""
    import importlib
    from ember.engine import imageio
    importlib.import_module("ember.engine.passes")
    imageio.load_exr_binding()
    _version()


@functools.lru_cache(maxsize=None)
def _version() -> str:
    """The add-on's version (blender_manifest.toml)."""
    try:
        import tomllib
        with open(HERE / "blender_manifest.toml", "rb") as fh:
            return str(tomllib.load(fh).get("version", "unknown"))
    except (OSError, ValueError):
        return "unknown"


def _save_multilayer_exr(imageio, output, layer: str, passes: dict, crop, header: dict) -> None:
    """Every pass into one EXR, channels named as Blender's multilayer files name them."""
    from ember.engine.passes import BY_NAME
    channels = {}
    for name, image in passes.items():
        for i, letter in enumerate(BY_NAME[name].chan_id):
            channels[f"{layer}.{name}.{letter}"] = image[crop][..., i]
    shape = next(iter(channels.values())).shape
    imageio.write_atomically(output, lambda tmp: imageio.write_exr(tmp, channels, header),
                             lambda tmp: imageio.check_exr(tmp, shape))


def run(argv: list[str]) -> int:
    if argv and argv[0] == "merge":
        return run_merge(argv[1:])
    t_start = time.perf_counter()
    args = build_parser(blend_required=not IN_BLENDER).parse_args(argv)

    if args.blend is not None:
        blend = pathlib.Path(args.blend)
        _check_blend(blend)
    else:
        blend = None
    stem = blend.stem if blend is not None else "render"
    output = pathlib.Path(args.output) if args.output else pathlib.Path(f"{stem}.png")
    kind = _check_output(output)
    reference = None
    if args.reference is not None:
        ref_path = pathlib.Path(args.reference)
        if not _exists(ref_path, "reference"):
            raise UsageError(f"reference not found: {ref_path}")
        if ref_path.suffix.lower() != ".exr":
            raise UsageError(f"reference must be a linear .exr, got {str(ref_path)!r}")
        _load_ember()
        from ember.engine import imageio, metrics
        reference = _Reference(ref_path, metrics, imageio)

    STOP.check()
    import bpy  # after the cheap checks: importing the bpy module takes a moment
    STOP.check()

    if blend is not None:
        try:
            bpy.ops.wm.open_mainfile(filepath=str(blend.resolve()), load_ui=False)
        except RuntimeError as e:
            raise UsageError(f"cannot open {blend}: {_clean_blender_error(e)}")
    elif not bpy.data.filepath:
        raise UsageError("no .blend loaded: use  blender -b scene.blend -P render.py -- [options]")
    else:
        blend = pathlib.Path(bpy.data.filepath)

    STOP.check()
    _register_ember()
    STOP.check()

    scene = bpy.context.scene
    _require_ember(scene)
    _apply_settings(scene, args)
    if args.missing_textures == "error" or (args.scheduler is not None and args.missing_textures is None):
        missing = missing_images()
        if missing:
            raise UsageError(f"image file(s) missing: {_missing_text(missing)} (or allow them: --missing-textures warn)")
    if scene.camera is None:
        raise UsageError(f"the scene '{scene.name}' has no active camera: add one or set Scene > Camera")
    if kind == ".png":
        _set_png_format(scene)
    w, h = scene.render.resolution_x * scene.render.resolution_percentage // 100, \
        scene.render.resolution_y * scene.render.resolution_percentage // 100
    if reference is not None:
        reference.check_size(w, h)
    frames = None
    if args.frames is not None:
        frames = parse_frames(args.frames, (scene.frame_start, scene.frame_end, scene.frame_step))
        _check_writable(frame_path(output, max(frames, key=lambda f: len(str(f))), True))  # the longest name
        scene.render.use_persistent_data = True  # workers and Embree scenes stay from frame to frame
    if args.scheduler is not None:
        return _run_farm(args, argv, blend, output, kind, scene, frames, t_start)
    job = _Job(blend, kind, reference, show_progress=not args.no_progress, t_start=t_start,
               numbered=frames is not None)
    if frames is None:
        return job.render_frame(scene, scene.frame_current, frame_path(output, scene.frame_current, False))
    for i, frame in enumerate(frames):
        STOP.release()  # a signal during the last frame's summary stops this one
        STOP.check()
        scene.frame_set(frame)
        _require_ember(scene)  # a frame-change handler could have switched it
        code = job.render_frame(scene, frame, frame_path(output, frame, True), f" ({i + 1}/{len(frames)})")
        if code != EXIT_OK:
            return code
    if len(frames) > 1:
        print(f"Ember: {len(frames)} frames in {time.perf_counter() - t_start:.2f} s", flush=True)
    return EXIT_OK


# Options the farm sets per task (or that only the caller uses); the rest go to every task.
_FARM_OWN = {"-o", "--output", "--frames", "--samples", "--sample-offset", "--scheduler", "--chunk-samples",
             "--send-blend", "--reference", "--no-progress"}


def task_options(argv: list[str]) -> list[str]:
    """The render options of `argv` that every farm task repeats: all but the .blend, the
    output, the frames, the sample range and the farm's own."""
    flags = {o for a in build_parser(False)._actions if a.nargs == 0 for o in a.option_strings}
    out, i = [], 0
    while i < len(argv):
        token = argv[i]
        name = token.split("=", 1)[0]
        takes_value = token.startswith("-") and name not in flags and "=" not in token
        if token.startswith("-") and name not in _FARM_OWN:
            out += argv[i:i + 1 + takes_value]
        i += 1 + takes_value if token.startswith("-") else 1  # a bare word is the .blend
    return out


def _run_farm(args, argv, blend, output, kind, scene, frames, t_start) -> int:
    """--scheduler: frames and sample ranges as Dask tasks (engine/parallel/farm.py); each
    frame is merged and written as soon as its parts are in."""
    from ember.engine import imageio
    from ember.engine.merge import MergeError, Part, merge_channels
    from ember.engine.parallel import farm

    if kind != ".exr":
        raise UsageError("--scheduler writes .exr frames (partial renders merge in linear float)")
    if args.reference is not None:
        raise UsageError("--reference does not apply with --scheduler")
    numbered = frames is not None
    frames = frames if numbered else [scene.frame_current]
    tasks = farm.plan(frames, scene.ember.samples, scene.ember.sample_offset, args.chunk_samples or 0)
    options = task_options(argv)
    if str(scene.ember.integrator) == "AUTO" and len(tasks) > len(frames):
        options += _auto_for_parts(scene)
    if args.scheduler.startswith("local:"):
        try:
            n = int(args.scheduler.split(":", 1)[1])
        except ValueError:
            n = 0
        if n < 1:
            raise UsageError(f"--scheduler local:N needs a number of workers >= 1, got {args.scheduler!r}")
        if args.threads is None:  # the local workers share this machine's CPUs
            from ember.engine.parallel.workers import available_cores
            options += ["--threads", str(max(available_cores() // n, 1))]
    elif not args.scheduler.startswith(("tcp://", "tls://")):
        raise UsageError(f"--scheduler expects tcp://HOST:PORT or local:N, got {args.scheduler!r}")
    if args.missing_textures is None:  # a frame without its textures is no frame on a farm
        options += ["--missing-textures", "error"]
    blend_bytes = _packed_blend_bytes() if args.send_blend else None
    where = str(blend.resolve())
    print(f"Ember: {blend.name}: {len(tasks)} tasks ({len(frames)} frames) on {args.scheduler}", flush=True)
    expected = {f: sum(t.frame == f for t in tasks) for f in frames}
    parts = {f: [] for f in frames}
    try:
        client, cluster = farm.connect(args.scheduler)
    except (OSError, TimeoutError) as e:
        raise EngineMissing(f"cannot reach the Dask scheduler {args.scheduler}: {e}")
    except farm.RenderTaskError as e:
        raise EngineMissing(str(e))
    t_farm = time.perf_counter()

    warned = set()

    def on_task(done, total, task, result):
        print(f"Ember: task {done}/{total}: {task.describe()} done, {time.perf_counter() - t_farm:.1f} s",
              flush=True)
        for line in result.get("warnings", ()):  # each once, as a local render shows it
            if line not in warned:
                warned.add(line)
                print(f"{line} ({task.describe()})", flush=True)

    try:
        futures = farm.submit(client, tasks, str(HERE / "render.py"), None if args.send_blend else where,
                              blend_bytes, options)
        for task, result in farm.gather(futures, on_task):
            STOP.check()
            parts[task.frame].append(result["exr"])
            if len(parts[task.frame]) == expected[task.frame]:
                path = frame_path(output, task.frame, numbered)
                _write_farm_frame(path, parts.pop(task.frame), imageio, Part, merge_channels)
                print(f"Ember: {blend.name} frame {task.frame} -> {path}: {expected[task.frame]} part(s)", flush=True)
    except farm.RenderTaskError as e:
        print(f"render.py: error: {e}", file=sys.stderr)
        return EXIT_FAILED
    except (MergeError, imageio.OutputError) as e:
        print(f"render.py: error: {e}", file=sys.stderr)
        return EXIT_FAILED
    except Exception as e:  # Dask's own: KilledWorker (a task whose workers kept dying), lost scheduler
        print(f"render.py: error: the farm failed ({type(e).__name__}: {str(e).splitlines()[0][:200] if str(e) else ''})",
              file=sys.stderr)
        return EXIT_FAILED
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    print(f"Ember: {len(frames)} frames in {time.perf_counter() - t_start:.2f} s on {args.scheduler}", flush=True)
    return EXIT_OK


def _auto_for_parts(scene) -> list[str]:
    """Options that give every part of a frame split into sample ranges the integrator and
    parameters `auto` chooses once, here, for a render of sample ranges (each part deciding
    alone, the part at offset 0 could take one that cannot be split and the others another)."""
    import bpy
    from ember.engine.blender.export import export_scene
    from ember.engine import choice

    exported, _ = export_scene(bpy.context.evaluated_depsgraph_get())
    s = exported.settings
    resolved = choice.resolve(exported.replace(settings=s.replace(sample_offset=max(s.sample_offset, 1))))
    print(f"Ember: {resolved.lines[0]} (once, for every part)", flush=True)
    declared = _declared()
    out = ["--integrator", resolved.scene.settings.integrator]
    for name, value in resolved.choice.settings.items():
        out += [declared.DECLARED[name].flag, declared.to_text(declared.DECLARED[name], value)]
    return out


def _write_farm_frame(path, datas, imageio, Part, merge_channels) -> None:
    """One part: its bytes as they are; several: merged (engine/merge.py), every channel."""
    if len(datas) == 1:
        def write(tmp):
            with open(tmp, "wb") as fh:
                fh.write(datas[0])
        imageio.write_atomically(path, write, imageio.check_exr)
        return
    with tempfile.TemporaryDirectory(prefix="ember-merge-") as tmp:
        parts = []
        for i, data in enumerate(datas):
            part = pathlib.Path(tmp) / f"part{i}.exr"
            part.write_bytes(data)
            channels, header = imageio.read_exr(part)
            parts.append(Part.from_exr(f"{path.name} part {i}", channels, header))
    _save_merged(imageio, path, *merge_channels(parts))


def _save_merged(imageio, path, channels: dict, header: dict) -> None:
    """A merge's channels (RGBA, or a multilayer file's every pass) through a checked write."""
    shape = next(iter(channels.values())).shape
    imageio.write_atomically(path, lambda tmp: imageio.write_exr(tmp, channels, header),
                             lambda tmp: imageio.check_exr(tmp, shape))


class _Job:
    """Renders frames of the loaded scene one at a time and writes each file."""

    def __init__(self, blend, kind, reference, show_progress, t_start, numbered):
        self.blend, self.kind, self.reference = blend, kind, reference
        self.show_progress, self.t_start, self.numbered = show_progress, t_start, numbered

    def render_frame(self, scene, frame: int, output: pathlib.Path, count: str = "") -> int:
        import bpy
        from ember.engine.blender import final
        t_frame = time.perf_counter()
        tty = sys.stderr.isatty()
        follower = _Follower(show_progress=self.show_progress and tty, reference=self.reference,
                             log=self.show_progress and not tty, frame=frame if self.numbered else None)
        final.listeners.append(follower)
        blender_error = None
        STOP.output = output
        STOP.check()
        try:
            bpy.ops.render.render(write_still=False)
        except RuntimeError as e:  # ERROR reports (ours and Blender's own) raise here
            blender_error = _clean_blender_error(e)
        finally:
            follower._close_bar()
            final.listeners.remove(follower)
        STOP.check()
        _load_writers()  # an import a signal interrupts fails for good (pybind11: ImportError)
        STOP.soft = False  # from here a signal interrupts the write at once ...
        try:
            STOP.check()  # ... and one that came just before stops it too
            code, summary = self._write(scene, frame, output, follower, blender_error, t_frame, count)
        finally:
            STOP.soft = True
        STOP.hold()  # the file is in place: a signal from here is noted (run() releases it)
        STOP.check()  # one before: the file is whole, but the render stops
        if summary:
            print(summary, flush=True)
        return code

    def _write(self, scene, frame, output, follower, blender_error, t_frame, count) -> tuple[int, str]:
        """Write the frame's file: (exit code, the summary line to print once it is in place)."""
        import bpy
        if follower.errors:
            message, user_error = follower.errors[0]
            print(f"render.py: error: {message}", file=sys.stderr)
            return (EXIT_USAGE if user_error else EXIT_FAILED), ""
        if blender_error is not None:  # Blender refused before our engine ran (e.g. too small)
            print(f"render.py: error: {blender_error}", file=sys.stderr)
            return EXIT_USAGE, ""
        if not follower.layers:
            print("render.py: error: nothing was rendered by Ember (no enabled view layer?)", file=sys.stderr)
            return EXIT_FAILED, ""
        w = scene.render.resolution_x * scene.render.resolution_percentage // 100
        h = scene.render.resolution_y * scene.render.resolution_percentage // 100

        # The view layer shown in the Render Result: the window's active one if rendered.
        active = bpy.context.view_layer.name if bpy.context.view_layer else None
        layer = active if active in follower.layers else next(iter(follower.layers))
        stats, image, border = follower.layers[layer]
        from ember.engine import imageio
        imageio.remove_stale_temporaries(output)  # left by a render killed while writing
        try:
            if self.kind == ".exr":
                if image is None:
                    raise imageio.OutputError(f"could not write {output}: nothing was rendered")
                header = exr_metadata(stats, follower.digests.get(layer, ""), border, frame, layer)
                crop = (slice(None), slice(None))
                if scene.render.use_border and scene.render.use_crop_to_border:
                    x0, y0, x1, y1 = border
                    crop = (slice(y0, y1), slice(x0, x1))
                    header["ember/crop"] = [x0, y0, x1, y1]
                passes = follower.passes.get(layer)
                if passes:  # every enabled pass, named as Blender's multilayer files: <layer>.<pass>.<channel>
                    _save_multilayer_exr(imageio, output, layer, {"Combined": image, **passes}, crop, header)
                else:
                    imageio.save_rgba_exr(output, image[crop], header)
            else:
                result = bpy.data.images["Render Result"]

                def save_png(tmp):
                    result.save_render(filepath=str(pathlib.Path(tmp).resolve()), scene=scene)

                size = None
                if image is not None:  # the PNG is the film's size, or the border's when cropped
                    size = (image.shape[1], image.shape[0])
                    if scene.render.use_border and scene.render.use_crop_to_border:
                        x0, y0, x1, y1 = border
                        size = (x1 - x0, y1 - y0)
                imageio.write_atomically(output, save_png, lambda tmp: imageio.check_png(tmp, size))
        except imageio.OutputError as e:
            print(f"render.py: error: {e}", file=sys.stderr)
            return EXIT_FAILED, ""
        if len(follower.layers) > 1 and self.kind == ".exr":
            print(f"note: {len(follower.layers)} view layers rendered; {output} holds '{layer}'",
                  file=sys.stderr)

        samples = min(s.samples for s, _, _ in follower.layers.values())
        rays = sum(s.rays for s, _, _ in follower.layers.values())
        render_s = sum(s.elapsed for s, _, _ in follower.layers.values())
        extra = ""
        if stats.noise is not None and math.isfinite(stats.noise):
            extra += f", noise {stats.noise:.4f}"
        if stats.stopped_by in ("time limit", "noise target"):
            extra += f", stopped at the {stats.stopped_by}"
        if self.reference is not None:
            full = follower.layers[layer][1]  # the full-frame image, before any crop
            extra += f", relMSE {self.reference.error(full):.4e} (eps {self.reference.metrics.EPS:g})"
        nonfinite = sum(int(getattr(s, "nonfinite", 0)) for s, _, _ in follower.layers.values())
        where = f" frame {frame}{count}" if self.numbered else ""
        b = stats.builds
        total = time.perf_counter() - (t_frame if self.numbered else self.t_start)
        return EXIT_OK, (f"Ember: {self.blend.name}{where} -> {output}: {w}x{h}, {samples} samples, "
                         f"render {render_s:.2f} s, total {total:.2f} s, "
                         f"{_fmt_rate(rays / max(render_s, 1e-9))}, {stats.processes} worker processes "
                         f"({b.get('workers', 0)} started, {b.get('embree', 0)} Embree and "
                         f"{b.get('lights', 0)} light builds), {nonfinite} non-finite samples{extra}")



def run_merge(argv: list[str]) -> int:
    p = _Parser(prog="render.py merge", description="Merge partial Ember EXRs of one frame.")
    p.add_argument("parts", nargs="+", help="EXRs written by render.py (sample ranges, tiles)")
    p.add_argument("-o", "--output", required=True, help="the merged .exr")
    args = p.parse_args(argv)
    output = pathlib.Path(args.output)
    if _check_output(output) != ".exr":
        raise UsageError(f"merge writes an .exr, got {str(output)!r}")
    _load_ember()
    from ember.engine import imageio
    from ember.engine.merge import MergeError, Part, merge_channels
    parts = []
    for name in args.parts:
        path = pathlib.Path(name)
        if not _exists(path, "part"):
            raise UsageError(f"part not found: {path}")
        try:
            channels, header = imageio.read_exr(path)
        except (OSError, RuntimeError, ValueError) as e:
            raise UsageError(f"cannot read {path}: {e}")
        try:
            parts.append(Part.from_exr(path.name, channels, header))
        except MergeError as e:
            raise UsageError(str(e))
    try:
        channels, header = merge_channels(parts)
    except MergeError as e:
        raise UsageError(str(e))
    imageio.remove_stale_temporaries(output)
    try:
        _save_merged(imageio, output, channels, header)
    except imageio.OutputError as e:
        print(f"render.py: error: {e}", file=sys.stderr)
        return EXIT_FAILED
    h, w = next(iter(channels.values())).shape
    print(f"Ember: merged {len(parts)} parts -> {output}: {w}x{h}, "
          f"samples {header['ember/sampleRange']}", flush=True)
    return EXIT_OK


def main() -> int:
    argv = sys.argv[sys.argv.index("--") + 1:] if IN_BLENDER and "--" in sys.argv else \
        ([] if IN_BLENDER else sys.argv[1:])
    STOP.install()
    try:
        code = run(argv)
        STOP.hold()  # done: a signal from here is too late to stop anything
        STOP.check()  # one the last phase did not poll (a merge, the farm's last frame)
        return code
    except UsageError as e:
        print(f"render.py: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except EngineMissing as e:
        print(f"render.py: error: {e}", file=sys.stderr)
        return EXIT_FAILED
    except PermissionError as e:  # an input the checks above did not open themselves
        print(f"render.py: error: cannot read {e.filename or ''}: permission denied", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        if not STOP.requested:  # raised by Python itself (no handler yet)
            print("Interrupted.", file=sys.stderr)
        return STOP.code


if __name__ == "__main__":
    code = main()
    for _sig in (signal.SIGINT, signal.SIGTERM):  # the exit code is decided (interpreter shutdown
        signal.signal(_sig, signal.SIG_IGN)       # restores default handlers, which would kill it)
    sys.stdout.flush()
    sys.stderr.flush()
    sys.exit(code)
