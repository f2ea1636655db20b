"""Checks of a Scene before rendering: settings in range, light values Ember can render,
memory enough for the film, the batches and the scene; something that emits light.

One place for them, so the CLI, F12 and tests give the same message for the same problem.
"""
from __future__ import annotations

import math
import os

import numpy as np

from . import passes as passes_mod
from . import settings as declared
from .errors import EmberError
from .integrators import REGISTRY, choices, honours
from .integrators.path import ITEM_BATCHES
from .passes import NAMES as PASS_NAMES
from .scene import RAY_ALL, RAY_CAMERA, Scene
from .volumes import Media


def validate(scene: Scene) -> None:
    problems = settings_problems(scene.settings) + lens_problems(scene.camera)
    if problems:
        raise EmberError("Invalid render settings: " + "; ".join(problems))
    check_light_values(scene)
    check_memory(scene)


def settings_problems(s) -> list[str]:
    """Each declared setting within its range or among its choices (engine/settings.py), and
    what a range cannot say: the border inside the frame, a sample offset the integrator
    allows, passes Ember has."""
    problems = [f"{d.name.replace('_', ' ')} {p}" for d in declared.FIELDS
                if (p := declared.problem(d, getattr(s, d.name), choices(d) if d.kind is str else None))]
    x0, y0, x1, y1 = s.border
    if not (0 <= x0 < x1 <= s.width and 0 <= y0 < y1 <= s.height):
        problems.append(f"render border {tuple(s.border)} is empty or outside the {s.width}x{s.height} frame "
                        "(enlarge the render region or disable it)")
    problems += sample_offset_problems(s)
    if s.integrator == "icache" and s.icache_gather == "path" and s.gather_rays < 1:
        problems.append("gather rays must be at least 1 for the irradiance cache's path-traced gathering "
                        f"(got {s.gather_rays})")
    unknown = sorted(set(s.passes) - set(PASS_NAMES))
    if unknown:
        problems.append(f"unknown render pass(es) {', '.join(unknown)} (use some of {', '.join(PASS_NAMES)})")
    return problems


# Integrators that render negative lights as Cycles does (negative radiance; the light set
# already chooses lights by |power|). They need to keep negative contributions (the path
# tracer drops emission and light samples that are not > 0); until one is listed here,
# negative lights are refused for it rather than silently dropped.
NEGATIVE_LIGHT_INTEGRATORS: frozenset = frozenset({"path", "auto"})  # auto then chooses path


def _names(names, limit=5) -> str:
    unique = list(dict.fromkeys(names))
    text = ", ".join(f"'{n}'" for n in unique[:limit])
    return text + (f" and {len(unique) - limit} more" if len(unique) > limit else "")


def _light_names(scene: Scene, rows) -> list:
    names = scene.lights.names
    return [names[i] if i < len(names) else f"light {i}" for i in rows]


def _used_material_names(scene: Scene, bad: np.ndarray) -> list:
    """Names of materials flagged in bad (M,) that some triangle uses."""
    used = np.zeros(len(bad), bool)
    used[np.unique(scene.mesh.material)] = True
    names = scene.materials.names
    return [names[i] if i < len(names) else f"material {i}" for i in np.flatnonzero(bad & used)]


def check_light_values(scene: Scene) -> None:
    """Refuse NaN/Inf light strengths and emission (they would make every pixel NaN) and
    negative ones for integrators not in NEGATIVE_LIGHT_INTEGRATORS."""
    Le, emission, world = scene.lights.Le, scene.materials.emission, scene.world
    problems = []
    bad = ~np.all(np.isfinite(Le), axis=-1)
    if bad.any():
        problems.append(f"light(s) {_names(_light_names(scene, np.flatnonzero(bad)))} have a NaN or infinite strength")
    bad_m = _used_material_names(scene, ~np.all(np.isfinite(emission), axis=-1))
    if bad_m:
        problems.append(f"material(s) {_names(bad_m)} have a NaN or infinite emission")
    if not np.all(np.isfinite(world.color)):
        problems.append("the world colour or strength is NaN or infinite")
    if problems:
        raise EmberError("Cannot render: " + "; ".join(problems) + ".")
    if scene.settings.integrator in NEGATIVE_LIGHT_INTEGRATORS:
        return
    neg = _light_names(scene, np.flatnonzero(np.any(Le < 0, axis=-1)))
    neg_m = _used_material_names(scene, np.any(emission < 0, axis=-1))
    what = []
    if neg:
        what.append(f"light(s) {_names(neg)}")
    if neg_m:
        what.append(f"emissive material(s) {_names(neg_m)}")
    if np.any(world.color < 0) or (world.image is not None and np.min(world.image) < 0):
        what.append("the world")
    if what:
        raise EmberError("Negative light is not supported yet: " + " and ".join(what)
                         + " emit negative power; use a positive strength and colour.")


# ---- memory -------------------------------------------------------------------------------
# Bytes per film pixel in the render process: running sums and squares, count, the noise
# snapshot, the layout's pixel indices, the transient (H, W, 4) images and float64 means made
# when the film is shown or saved, and Blender's render result (measured:
# bench/memory_per_pixel.py, bench/results/reliability/memory.md).
FILM_BYTES_PER_PIXEL = 400
# Per pixel and channel of each render pass (and a transparent film's alpha): its float64 sum,
# the float32 image and its copy in the render result (measured as above).
PASS_BYTES_PER_CHANNEL = 20
# Per pixel in every tracing process: the layout's pixel indices (three int64 arrays) and the
# coordinate grids they are made from.
LAYOUT_BYTES_PER_PIXEL = 40
# Per ray of a batch in a tracing process: ray, hit, throughput and shading state arrays
# (float64 (N,3) each) and NumPy temporaries of one bounce.
BATCH_BYTES_PER_PATH = 2000
# Per path of a work item, live or not: its camera ray, radiance, random-number keys and pixel
# indices (the path tracer's items hold several batches, engine/integrators/path.py ITEM_BATCHES).
ITEM_BYTES_PER_PATH = 160
# Per triangle in a tracing process: the Mesh arrays, the Accel's float64 copies, Embree's BVH.
SCENE_BYTES_PER_TRIANGLE = 400
PROCESS_BYTES = 150 << 20  # an interpreter with NumPy and Embree loaded
GIB = float(1 << 30)
CGROUP_ROOT = "/sys/fs/cgroup"


def available_memory() -> int | None:
    """Bytes this process may still allocate: MemAvailable of /proc/meminfo, or less where
    a cgroup (a container, a farm's job slot) limits memory below it. None where neither is
    known."""
    avail = None
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    avail = int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    limited = cgroup_available()
    if limited is not None:
        avail = limited if avail is None else min(avail, limited)
    return avail


def _read_int(path: str) -> int | None:
    try:
        with open(path) as fh:
            text = fh.read().strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None  # cgroup v2 writes "max" for no limit


def cgroup_available(proc_cgroup: str = "/proc/self/cgroup", root: str = CGROUP_ROOT) -> int | None:
    """Limit minus usage (less reclaimable page cache) of the tightest memory cgroup on this
    process's path to the root: v2 (memory.max, memory.current) or v1 (memory.limit_in_bytes,
    memory.usage_in_bytes); None without a limit."""
    try:
        with open(proc_cgroup) as fh:
            lines = fh.read().splitlines()
    except OSError:
        return None
    places = []  # (directory holding the controller's files, limit file, usage file)
    for line in lines:
        _, controllers, path = (line.split(":", 2) + ["", ""])[:3]
        if controllers == "":
            places.append((root, path, "memory.max", "memory.current"))
        elif "memory" in controllers.split(","):
            places.append((os.path.join(root, "memory"), path, "memory.limit_in_bytes", "memory.usage_in_bytes"))
    best = None
    for base, path, limit_name, usage_name in places:
        parts = [p for p in path.split("/") if p]
        for depth in range(len(parts), -1, -1):  # a container sees its own cgroup as the root
            directory = os.path.join(base, *parts[:depth])
            limit = _read_int(os.path.join(directory, limit_name))
            if limit is None or limit >= 1 << 60:  # v1's "no limit" is a huge number
                continue
            usage = (_read_int(os.path.join(directory, usage_name)) or 0) - _inactive_file(directory)
            left = max(limit - max(usage, 0), 0)
            best = left if best is None else min(best, left)
    return best


def _inactive_file(directory: str) -> int:
    """Page cache the kernel reclaims before it would kill (memory.stat's inactive_file, v1's
    total_inactive_file): usage that is no working set, as `docker stats` counts it."""
    try:
        with open(os.path.join(directory, "memory.stat")) as fh:
            for line in fh:
                key, _, value = line.partition(" ")
                if key in ("inactive_file", "total_inactive_file") and value.strip().isdigit():
                    return int(value)
    except OSError:
        pass
    return 0


def film_channels(s) -> int:
    """Channels the film keeps besides Combined: every pass a render accumulates, and alpha."""
    from .passes import BY_NAME, needed
    return sum(BY_NAME[n].channels for n in needed(s.passes)) + int(bool(s.film_transparent))


def memory_estimate(scene: Scene, processes: int | None = None) -> dict:
    """Peak memory (bytes) a render of `scene` needs, by part: film (render process: pixels,
    passes), batches (rays in flight: gather rays multiply them), scene (each per tracing
    process), published (photon maps, irradiance records) and the total. processes: tracing
    processes (default: one per core, the most the session starts)."""
    s = scene.settings
    if processes is None:
        processes = s.threads if getattr(s, "threads", 0) else (os.cpu_count() or 1)
    processes = max(int(processes), 1)
    pixels = int(s.width) * int(s.height)
    film = (FILM_BYTES_PER_PIXEL + PASS_BYTES_PER_CHANNEL * film_channels(s)) * pixels
    x0, y0, x1, y1 = s.border
    total = max(int(s.samples), 1) * max((x1 - x0) * (y1 - y0), 1)
    integrator = REGISTRY.get(s.integrator)
    rays = integrator.batch_rays(scene, total) if integrator is not None else min(int(s.batch_size), total)
    item = min(ITEM_BATCHES * int(s.batch_size), total)
    batches = BATCH_BYTES_PER_PATH * rays + ITEM_BYTES_PER_PATH * item  # (path tracer's items: the most)
    image = scene.world.image
    texels = scene.materials.image_texels
    scene_bytes = (SCENE_BYTES_PER_TRIANGLE * scene.mesh.n_triangles + LAYOUT_BYTES_PER_PIXEL * pixels
                   + (4 * image.nbytes if image is not None else 0)  # the image and its tables
                   + (texels.nbytes if texels is not None else 0))
    published = integrator.memory_estimate(scene) if integrator is not None else 0
    per_process = batches + scene_bytes + PROCESS_BYTES + published  # every worker maps the published data
    total = film + processes * per_process + published  # ... and the render process reduces it
    return dict(film=film, batches=batches, scene=scene_bytes, published=published, processes=processes,
                total=total)


def check_memory(scene: Scene, available: int | None = None) -> None:
    """Refuse a render whose memory estimate exceeds the memory available (before anything
    large is allocated), naming the estimate and what to change."""
    if available is None:
        available = available_memory()
    if available is None:
        return
    est = memory_estimate(scene)
    if est["total"] <= available:
        return
    s = scene.settings
    raise EmberError(
        f"Not enough memory: a {s.width}x{s.height} render needs about {est['total'] / GIB:.1f} GiB "
        f"(film and passes {est['film'] / GIB:.1f} GiB, {est['processes']} process(es) x "
        f"{(est['batches'] + est['scene'] + est['published'] + PROCESS_BYTES) / GIB:.2f} GiB: rays in flight "
        f"{est['batches'] / GIB:.2f}, scene {est['scene'] / GIB:.2f}, photon maps and records "
        f"{est['published'] / GIB:.2f}) but {available / GIB:.1f} GiB are available; lower the resolution, the "
        f"passes, the batch size, the gather rays or the photon counts.")


def check_frame_memory(width: int, height: int, available: int | None = None) -> None:
    """The film part of check_memory, for callers that know only the frame size: F12 calls it
    before Blender allocates its render result, so a frame that cannot fit is refused before
    anything of its size exists."""
    if available is None:
        available = available_memory()
    need = FILM_BYTES_PER_PIXEL * int(width) * int(height) + PROCESS_BYTES  # no passes yet: the least
    if available is not None and need > available:
        raise EmberError(f"Not enough memory: a {width}x{height} render needs at least {need / GIB:.1f} GiB "
                         f"for its image but {available / GIB:.1f} GiB are available; lower the resolution.")


def has_light(scene: Scene) -> bool:
    world = scene.world
    glowing_media = scene.materials.volume_emission is not None and bool(np.any(scene.materials.volume_emission != 0))
    return (len(scene.lights) > 0 or bool(np.any(scene.materials.emission != 0)) or glowing_media
            or bool(np.max(np.abs(world.color)) > 0
                    and (getattr(world, "image", None) is None or np.max(np.abs(world.image)) > 0)))


def sample_offset_problems(s) -> list[str]:
    """A sample offset needs an integrator whose samples are independent of each other."""
    if s.sample_offset and s.integrator in REGISTRY and not honours(declared.DECLARED["sample_offset"], s.integrator,
                                                                        lambda name: getattr(s, name)):
        return [f"a sample offset does not apply to the '{s.integrator}' integrator (each of its passes "
                "depends on the ones before; render its frames whole)"]
    return []


def lens_problems(camera) -> list[str]:
    """What is wrong with the camera's depth of field (empty if nothing)."""
    problems = []
    if not (camera.aperture_radius >= 0 and math.isfinite(camera.aperture_radius)):
        problems.append(f"aperture radius must be a finite number >= 0 (got {camera.aperture_radius})")
    if camera.aperture_radius > 0:
        if not (camera.focus_distance > 0 and math.isfinite(camera.focus_distance)):
            problems.append(f"focus distance must be positive (got {camera.focus_distance})")
        if not (camera.aperture_ratio > 0 and math.isfinite(camera.aperture_ratio)):
            problems.append(f"aperture ratio must be positive (got {camera.aperture_ratio})")
    return problems


# Scene settings only the path tracer honours (the photon integrators trace every ray against
# the whole scene and use Max Bounces alone).
PATH_ONLY = tuple(d for d in declared.FIELDS if d.source == declared.EMBER and d.honoured_by == ("path",))


def path_only_warnings(scene) -> list[str]:
    """Warnings for settings that only the path tracer honours (PATH_ONLY, ray visibility),
    when another integrator renders a scene that uses them."""
    s = scene.settings
    if s.integrator == "path":
        return []
    out = []
    changed = [d.name.replace("_", " ") for d in PATH_ONLY if getattr(s, d.name) != d.default]
    if changed:
        out.append(f"The '{s.integrator}' integrator ignores {', '.join(changed)} (Path Tracing only; "
                   "it uses Max Bounces alone).")
    lobes = RAY_ALL & ~RAY_CAMERA
    if (scene.mesh.visibility is not None or np.any((scene.lights.ray_visibility & lobes) != lobes)
            or (scene.world.ray_visibility & lobes) != lobes):
        out.append(f"The '{s.integrator}' integrator ignores ray visibility and holdouts (Path Tracing only); "
                   "every object is seen by every ray (lights and the world keep their camera visibility).")
    return out


def volume_warnings(scene) -> list[str]:
    """Where a render leaves the materials' volumes out: integrators other than the path
    tracer, and the path tracer with light passes (those count per bounce of a batch at one
    depth, which paths scattering in media leave)."""
    if Media.of(scene.materials) is None:
        return []
    s = scene.settings
    if s.integrator != "path":
        return [f"The '{s.integrator}' integrator renders without volumes (volume shaders: Path Tracing only)."]
    if any(n in passes_mod.LIGHT for n in passes_mod.needed(s.passes)):
        return ["Volumes are left out of renders with light passes (Direct / Indirect / Color) in this version."]
    return []
