"""Final render driver: F12 and bpy.ops.render.render (and so render.py) come through here.

Blender calls render(engine, depsgraph) once per enabled view layer. Per layer:
1. begin one render result for the layer (border-sized when render border is on);
2. export the depsgraph to an engine.scene.Scene, polling engine.test_break and showing
   "Export: ..." in the status bar;
3. RenderSession.run: its worker threads touch only NumPy/Embree; on_update and
   should_stop come back on this (Blender's render) thread, where every bpy and engine.*
   call stays. The film goes to the result after each completed pass and at least every
   REFRESH_SECONDS, progress and stats at every update (~0.25 s); Esc (test_break) stops
   the run within about a second and the partial image is kept;
4. end the result, print the summary line.

Every exception is caught (Blender would only print it and report success): EmberError
-> its message as an ERROR report + error_set; anything else -> a short message the same
way, the traceback to the console. Cancelled (Esc during export) ends quietly.
The user's scene is only read, never written.

`listeners` lets an in-process caller (render.py) follow a render that runs inside
bpy.ops.render.render: objects with any of the methods of RenderListener.
"""
from __future__ import annotations

import time
import traceback

from ..errors import Cancelled, EmberError
from ..passes import needed
from ..session import RenderSession
from ..validation import check_frame_memory
from .export import export_scene
from .result import ResultWriter, blender_border

REFRESH_SECONDS = 2.0  # film -> render result at least this often between passes
# Preview renders (bl_use_preview): few samples, traced in this process (a worker pool's
# start-up would cost more than the thumbnail), no passes (measured in
# bench/results/viewport/report.md).
PREVIEW_OVERRIDES = dict(samples=16, threads=1, passes=(), max_depth=8)


class RenderListener:
    """The optional methods a listener may have (all called on Blender's render thread)."""

    def should_stop(self) -> bool:  # stop like Esc (render.py's Ctrl-C)
        return False

    def on_export(self, layer: str, text: str) -> None:
        pass

    def on_scene(self, layer: str, scene) -> None:
        """The exported engine.scene.Scene, before the render starts."""

    def on_progress(self, layer: str, progress) -> None:
        pass

    def on_run_done(self, layer: str, stats) -> None:
        """The layer's sampling has ended; its summary line is printed next."""

    def on_layer_done(self, layer: str, stats, image, border: tuple) -> None:
        """image: (H, W, 4) float32 full frame, row 0 = top, zero outside border
        (x0, y0, x1, y1; top-left origin, half-open), or None if nothing was rendered."""

    def on_error(self, layer: str, message: str, user_error: bool) -> None:
        pass


listeners: list = []


def _notify(method: str, *args):
    for listener in list(listeners):
        fn = getattr(listener, method, None)
        if fn is not None:
            fn(*args)


def _listener_stop() -> bool:
    return any(getattr(l, "should_stop", lambda: False)() for l in list(listeners))


def _report_once(engine, kind: str, message: str) -> None:
    """Report a message once per render job (render() runs once per view layer on the same
    engine instance)."""
    try:
        seen = engine._ember_reported
    except AttributeError:
        seen = set()
        try:
            engine._ember_reported = seen
        except (AttributeError, TypeError):
            pass
    if (kind, message) in seen:
        return
    seen.add((kind, message))
    engine.report({kind}, message)


def _fail(engine, layer: str, message: str, user_error: bool) -> None:
    print(f"Ember: {layer}: error: {message}", flush=True)
    _notify("on_error", layer, message, user_error)
    try:
        engine.error_set(message)
    finally:
        _report_once(engine, 'ERROR', message)


def _fmt_rate(rays_per_second) -> str:
    r = float(rays_per_second or 0.0)
    if r >= 1e6:
        return f"{r / 1e6:.1f} M rays/s"
    if r >= 1e3:
        return f"{r / 1e3:.1f} k rays/s"
    return f"{r:.0f} rays/s"


def stats_text(progress) -> str:
    """'Sample 12/64 | 3.2 s | 1.1 M rays/s' (+ noise when the session estimates it)."""
    stage = getattr(progress, "stage", "pixels")
    where = "" if stage == "pixels" else f"{stage.capitalize()} | "  # e.g. "Photons | " while tracing them
    text = (f"{where}Sample {progress.samples_done}/{progress.samples_target} | "
            f"{progress.elapsed:.1f} s | {_fmt_rate(progress.rays_per_second)}")
    noise = getattr(progress, "noise", None)
    if noise is not None and noise == noise and noise != float("inf"):
        text += f" | noise {noise:.3g}"
    return text


class _ExportProgress:
    """progress callback for export_scene: shows 'Export: ...' in Blender's status bar.
    Accepts what an exporter is likely to pass: a text, (i, n) counts, a fraction."""

    def __init__(self, engine, layer: str):
        self.engine, self.layer = engine, layer

    def __call__(self, *args, **kwargs):
        words, numbers = [], []
        for a in list(args) + list(kwargs.values()):
            if isinstance(a, str):
                words.append(a)
            elif isinstance(a, (int, float)) and not isinstance(a, bool):
                numbers.append(a)
        text = " ".join(words).strip()
        if text.lower().startswith("export:"):
            text = text[len("export:"):].strip()
        text = text or "working"
        if len(numbers) >= 2 and numbers[1]:
            text += f" ({int(numbers[0])}/{int(numbers[1])})"
        elif len(numbers) == 1 and 0.0 <= numbers[0] <= 1.0:
            text += f" ({100.0 * numbers[0]:.0f}%)"
        self.engine.update_stats("Ember", f"Export: {text}")
        _notify("on_export", self.layer, text)


class _Loop:
    """on_update / should_stop for RenderSession.run, on Blender's render thread."""

    def __init__(self, engine, writer: ResultWriter, prefix: str):
        self.engine, self.writer, self.prefix = engine, writer, prefix
        self.last_write = time.monotonic()
        self.film = None
        self.stopped = False

    def should_stop(self) -> bool:
        if self.engine.test_break() or _listener_stop():
            self.stopped = True
        return self.stopped

    def on_update(self, progress) -> None:
        self.film = progress.film
        now = time.monotonic()
        if progress.pass_completed or now - self.last_write >= REFRESH_SECONDS:
            self.writer.write(progress.film.image())
            self.last_write = now
        # The share of the samples done, or of the time limit if that ends the render sooner.
        self.engine.update_progress(min(max(float(progress.fraction), 0.0), 1.0))
        self.engine.update_stats("", self.prefix + stats_text(progress))
        _notify("on_progress", self.writer.layer, progress)


def _version() -> str:
    """The add-on's version, from its manifest."""
    import pathlib
    import tomllib
    try:
        return tomllib.loads((pathlib.Path(__file__).resolve().parents[2] / "blender_manifest.toml").read_text())["version"]
    except (OSError, KeyError, ValueError):
        return "unknown"


def metadata(settings, stats) -> dict:
    """The render's facts for Blender's image header (stamp fields, so its multilayer EXR
    carries them), under the keys render.py's EXR uses. The integrator is the one that
    rendered (what `auto` chose; "ember/auto" then holds its reasons)."""
    rendered = getattr(stats, "settings", None) or settings
    out = {"ember/engine": "Ember", "ember/version": _version(), "ember/integrator": rendered.integrator,
           "ember/samples": str(stats.samples), "ember/seed": str(settings.seed),
           "ember/renderSeconds": f"{stats.elapsed:.3f}"}
    if getattr(stats, "auto", ()):
        out["ember/auto"] = stats.auto[0]
    return out


def _layer_prefix(depsgraph, layer: str) -> str:
    try:
        n = sum(1 for vl in depsgraph.scene.view_layers if vl.use)
    except Exception:
        n = 1
    return f"{layer} | " if n > 1 else ""


def _persistent(engine, scene) -> bool:
    """Keep workers and Embree scenes for the next render: Blender's Persistent Data, and
    every frame of an animation render but its last."""
    if scene.render.use_persistent_data:
        return True
    if getattr(engine, "is_animation", False):
        return scene.frame_current + max(scene.frame_step, 1) <= scene.frame_end
    return False


def _render_layer(engine, depsgraph, writer: ResultWriter, layer: str):
    def export_break():
        return bool(engine.test_break() or _listener_stop())

    engine.update_stats("Ember", "Export: starting")
    t0 = time.perf_counter()
    # Frame and border exactly as Blender sized the result (the exporter computes the same
    # from scene.render; passing them keeps film and result in step whatever happens there).
    frame = dict(width=writer.width, height=writer.height, border=writer.border,
                 persistent=_persistent(engine, depsgraph.scene) or None)
    if getattr(engine, "is_preview", False):  # material/light/world thumbnails: quick, in-process
        frame.update(PREVIEW_OVERRIDES)
    scene, warnings = export_scene(depsgraph, overrides=frame, test_break=export_break,
                                   progress=_ExportProgress(engine, layer))
    print(f"Ember: {layer}: exported in {time.perf_counter() - t0:.2f} s", flush=True)
    for w in warnings or ():
        _report_once(engine, 'WARNING', str(w))
    settings = scene.settings
    if export_break():
        return None, None
    _notify("on_scene", layer, scene)

    engine.update_stats("Ember", "Building")
    session = RenderSession(scene)
    for w in getattr(session, "warnings", ()) or ():
        _report_once(engine, 'WARNING', str(w))
    for line in getattr(session, "auto", ()):  # integrator auto: its choice, the analysis, what it left out
        _report_once(engine, 'INFO', f"Ember: {line}")

    loop = _Loop(engine, writer, _layer_prefix(depsgraph, layer))
    stats = session.run(on_update=loop.on_update, should_stop=loop.should_stop)
    image = None
    film = loop.film if loop.film is not None else session.film
    if loop.film is not None:
        image = film.image()
        writer.write(image)
    missing = writer.write_passes(film)
    if missing:
        _report_once(engine, 'WARNING', f"Render passes missing from the result: {', '.join(missing)}")
    writer.stamp(metadata(settings, stats))
    # Listeners (render.py's EXR) get the Color passes that Direct and Indirect are divided by
    # too: parts of a frame merge exactly only with them (engine/merge.py).
    _notify("on_layer_passes", layer, {name: film.pass_image(name) for name in needed(film.passes_wanted)},
            metadata(settings, stats))
    cancelled = bool(getattr(stats, "cancelled", False))
    if not cancelled:
        engine.update_progress(1.0)
    summary = stats.summary()
    engine.update_stats("", loop.prefix + summary)
    _notify("on_run_done", layer, stats)  # a terminal progress bar ends before the summary line
    print(f"{summary} (view layer '{layer}')", flush=True)
    for line in stats.auto[1:]:  # the analysis and what was left out (the choice is in the summary)
        print(f"Ember analysis: {line}", flush=True)
    return stats, image


def render(engine, depsgraph):
    """Render one view layer of depsgraph into engine's result. Returns the RenderStats, or
    None when nothing was rendered (error or cancel during export). Never raises."""
    layer = "ViewLayer"
    writer = None
    stats = image = None
    try:
        layer = depsgraph.view_layer.name
        width, height = int(engine.resolution_x), int(engine.resolution_y)
        check_frame_memory(width, height)  # before Blender allocates a result of that size
        border = blender_border(depsgraph.scene.render, width, height)
        writer = ResultWriter(engine, layer, width, height, border)
        stats, image = _render_layer(engine, depsgraph, writer, layer)
    except Exception as e:
        if isinstance(e, Cancelled):
            engine.update_stats("", "Cancelled")
            print(f"Ember: {layer}: cancelled during export", flush=True)
        elif isinstance(e, EmberError):
            _fail(engine, layer, str(e), user_error=True)
        else:
            traceback.print_exc()
            detail = f"{type(e).__name__}: {e}"
            if len(detail) > 200:
                detail = detail[:197] + "..."
            _fail(engine, layer, f"Ember failed ({detail}); details in the console", user_error=False)
    finally:
        if writer is not None:
            try:
                writer.end()
            except Exception:
                traceback.print_exc()
    if writer is not None and stats is not None:
        _notify("on_layer_done", layer, stats, image, writer.border)
    return stats
