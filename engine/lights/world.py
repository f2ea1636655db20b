"""The world's shader as a light: its node program evaluated at escaped rays, importance
sampled from a table of the program's values over the sphere (Cycles' background light).

Background: the world's Surface program (engine/nodes/program.py) over directions, with the
shading state Cycles' shader_setup_from_background gives a background (geom/shader_data.h):
  P = Generated = Object = d, N = Ng = I = -d (Texture Coordinate's Normal and Reflection read
  -d), UV zero, no object (identity transforms), ray_length FLT_MAX; Camera and Window as
  svm/tex_coord.h computes them for OBJECT_NONE: the point camera position + d (perspective).
The path state (what Light Path reads) per ray: a RayState (engine/nodes/hits.py), the flags
of the ray that escaped with PATH_RAY_EMISSION added and its bounce counts (integrator/
shade_background.h integrator_eval_background_shader); a light sample of the world reads
PATH_RAY_EMISSION and the path's counts (light/sample.h light_sample_shader_eval).

WorldMap: the importance table (Cycles' scene/light.cpp device_update_background). The
program is evaluated at the centres of an equirectangular grid of W x H pixels (the state of a
light sample: PATH_RAY_EMISSION, no bounce) and sampled as EnvironmentMap samples an image:
a pixel chosen by luminance x solid angle, a direction uniform in solid angle inside it. The
radiance a sample carries is the program's own value at its direction, not the table's: the
table only shapes the pdf, which is the table's exactly (EnvironmentMap.pdf), so MIS with BSDF
sampling stays unbiased whatever the table misses between its centres. With MIS compensation
(strategy "mis") pixels below the table's mean get pdf 0 and are BSDF sampling's alone;
without it (strategy "light", which has nothing else) every pixel keeps at least
FLOOR x the mean, so no direction where the world shines has pdf 0.

Resolution (map_size): the World's map_resolution when set (Cycles' Manual), else the width of
the widest Environment Texture image the program reads (one table pixel per texel, as Cycles'
automatic rule; a mirror ball's image of width w resolves its centre at w / 4 pixels per
radian, twice its width in an equirectangular table), at least 512 x 256 with a Sky Texture sun
guided apart (below: the sky itself is smooth), else Cycles' default 1024 x 512 (0.35 degree
pixels: procedurals, gradients, skies without a sun); capped at MAX_WIDTH. Height: half the
width. Cost: one program evaluation per pixel (1024 x 512: 0.5 M directions, bench/results/
world/notes.md has the times), the table 16 bytes per pixel (sampling.Distribution2D) plus
the float32 values (12 bytes) kept to build the uncompensated table photons need.

Sun guiding (Cycles' use_sun_guiding): a Sky Texture of the scattering types with its sun disc
on, whose Vector is unlinked or Texture Coordinate's Generated (the disc is then where the sky
node puts it), is sampled apart: a cone of the disc's half-angle about the sun's direction,
and the table is built with that node's disc off (Cycles' PATH_RAY_IMPORTANCE_BAKE), so it
holds the sky alone. The sun disc is a fraction of a degree: a table of any affordable
resolution resolves it in a pixel or two, whose centres may miss it. The pdf is the mixture
  p(d) = p_map pdf_map(d) + sum_k p_k pdf_cone_k(d),
p_k proportional to each sun's power (the disc's radiance over its cone, measured with the
disc on minus off), at most SUN_SHARE_MAX together (Cycles gives the sun 4 / 5, the map 1 / 5).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .. import panorama, sampling
from ..camera import cycles_frame
from ..nodes import atmosphere
from ..nodes.closures import closures
from ..nodes.graph import Graph
from ..nodes.hits import EMISSION_RAY, PATH_FIELDS, PathFields, RayState
from ..nodes.program import compile
from ..nodes.sky import _DEFAULTS as SKY_DEFAULTS, scattering_sun_direction
from ..nodes.state import ShadingState
from ..textures import LUMINANCE
from .environment import EnvironmentMap, EnvironmentSample

_FLT_MAX = float(np.finfo(np.float32).max)

MAX_WIDTH = 2048  # 2 M evaluations, ~60 MB per process (Cycles goes to 4096 for several suns)
DEFAULT_WIDTH = 1024  # Cycles' default
SUN_WIDTH = 512  # Cycles' least with a sun guided apart
FLOOR = 1e-3  # uncompensated tables: the least a pixel weighs, x the mean
SUN_SHARE_MAX = 0.8  # Cycles' sun_weight / (sun_weight + map_weight)
SUN_SHARE_MIN = 0.05  # a guided sun is never left with fewer light samples than this
_CHUNK = 1 << 16  # directions per program run while building the table
_SUN_PROBES = 1024  # directions in a sun's cone measuring its power


# Fields a point off any mesh and object has as zeros (Cycles' OBJECT_NONE and PRIM_NONE:
# no barycentrics, differentials or object properties), with their trailing shapes.
NO_OBJECT = {"barycentric": (2,), "triangle": (3, 3), "dPdu": (3,), "dPdv": (3,), "smooth": (), "vertex_normal": (3,),
             "N_du": (3,), "N_dv": (3,), "uv_du": (3,), "uv_dv": (3,), "generated_du": (3,), "generated_dv": (3,),
             "dP": (), "object_color": (3,), "object_alpha": (), "object_index": (), "object_random": (),
             "material_index": ()}


class ZeroFields:
    """A state source's NO_OBJECT fields, zero for its len(self) points."""

    def __getattr__(self, name):
        if name in NO_OBJECT:
            return lambda: np.zeros((len(self),) + NO_OBJECT[name], bool if name == "smooth" else np.float64)
        raise AttributeError(name)


class _Directions(ZeroFields, PathFields):
    """The shading state source of N background points (see the module docstring): d (N,3)
    unit directions, ray a RayState of the rays, camera a scene Camera or None."""

    def __init__(self, d, ray: RayState, camera=None):
        self._d, self.ray, self._camera = d, ray, camera

    def __len__(self):
        return len(self._d)

    def P(self):
        return self._d

    def generated(self):
        return self._d

    def object(self):
        return self._d

    def N(self):
        return -self._d

    Ng = I = N

    def backfacing(self):
        return np.zeros(len(self._d), bool)

    def uv(self):
        return np.zeros_like(self._d)

    instancer_generated = instancer_uv = uv

    def ray_length(self):
        return np.full(len(self._d), _FLT_MAX)

    def world_from_object(self):
        return np.broadcast_to(np.eye(4), (len(self._d), 4, 4))

    object_from_world = world_from_object

    def world_from_camera(self):
        return camera_frame(self._camera)

    def camera_from_world(self):
        return np.linalg.inv(camera_frame(self._camera))

    def camera(self):
        """svm_texco_camera for OBJECT_NONE: the point camera position + d in camera space,
        which is d in the camera's axes."""
        return self._d @ camera_frame(self._camera)[:3, :3]

    def window(self):
        """camera_world_to_ndc of the point camera position + d (perspective), or d itself
        (orthographic): (0, 0) bottom left of the view, (1, 1) top right, z 0."""
        cam = self._camera
        m = camera_frame(cam)
        if cam is None:
            left, right, bottom, top = -1.0, 1.0, -1.0, 1.0
        else:
            left, right, bottom, top = (float(v) for v in cam.window)
        if cam is not None and cam.panorama:  # where the projection shows the direction (m: its frame)
            u, v = panorama.from_direction(cam, self._d @ m[:3, :3])
            return np.stack([u, v, np.zeros(len(u))], axis=1)
        if cam is not None and cam.ortho:
            c = (self._d - m[:3, 3]) @ m[:3, :3]
            depth = np.ones(len(c))
        else:
            c = self._d @ m[:3, :3]
            depth = np.where(c[:, 2] != 0, c[:, 2], 1.0)
        x = (c[:, 0] / depth - left) / (right - left)
        y = (c[:, 1] / depth - bottom) / (top - bottom)
        return np.stack([x, y, np.zeros(len(c))], axis=1)


def camera_frame(camera) -> np.ndarray:
    """Cycles' camera-to-world (4,4) of a scene Camera (z forward, no scale), identity without
    one (engine/nodes/hits.py has the same for surface hits)."""
    return np.eye(4) if camera is None else cycles_frame(camera)


class Background:
    """The world's Surface program over directions. graph: its Graph; scale (3,): World.color,
    the factor its radiance is multiplied by; camera: the scene's Camera (Camera and Window
    coordinates), or None."""

    def __init__(self, graph: Graph, scale=(1.0, 1.0, 1.0), camera=None):
        self.graph = graph
        self.program = compile(graph, {"surface": "shader"})
        self.scale = np.asarray(scale, np.float64).reshape(3)
        self.camera = camera
        reads = self.program.reads
        self.reads_path = reads & PATH_FIELDS  # what Light Path reads of the rays' paths
        self.reads_camera = bool(reads & {"camera", "window", "world_from_camera", "camera_from_world"})

    @property
    def warnings(self) -> tuple:
        return self.program.warnings

    def radiance(self, d: np.ndarray, ray: RayState = EMISSION_RAY) -> np.ndarray:
        """Radiance (N,3) W/(m^2 sr) arriving along -d from unit world directions d (N,3):
        the background and emission closures of the program (Cycles' surface_shader_background
        sums both), for rays of the paths `ray` (default: a light sample before any bounce).
        Non-finite values are 0."""
        n = len(d)
        if n == 0:
            return np.zeros((0, 3))
        state = ShadingState(n, source=_Directions(d, ray, self.camera))
        total = np.zeros((n, 3))
        for c in closures(self.program.run(state)["surface"]):
            if c.kind in ("background", "emission"):
                total = total + c.weight
        total = total * self.scale
        return np.where(np.isfinite(total), total, 0.0)


# ---- the table ----------------------------------------------------------------------------------

def _linked_from_generated(graph: Graph, socket) -> bool:
    """The Vector is unlinked (the sky node reads the direction) or Texture Coordinate's
    Generated (the direction in a world): Cycles' condition for guiding the sun."""
    if socket is None or socket.link is None:
        return True
    src = graph.nodes[socket.link.node]
    return src.kind == "ShaderNodeTexCoord" and socket.link.socket == "Generated" and not src.prop("from_instancer")


def guided_suns(graph: Graph) -> list:
    """[(node index, unit direction (3,), half-angle)] of the Sky Textures whose sun disc is
    sampled apart (see the module docstring), as the node draws its disc (engine/nodes/sky.py)."""
    suns = []
    for i, node in enumerate(graph.nodes):
        if node.kind != "ShaderNodeTexSky":
            continue
        prop = {key: node.prop(key, default) for key, default in SKY_DEFAULTS.items()}
        if prop["sky_type"] not in ("SINGLE_SCATTERING", "MULTIPLE_SCATTERING") or not prop["sun_disc"]:
            continue
        if not _linked_from_generated(graph, node.input("Vector")):
            continue
        elevation, rotation = atmosphere.wrap_sun(prop["sun_elevation"], prop["sun_rotation"])
        size = max(float(prop["sun_size"]), float(np.float32(0.0005)))  # Cycles' get_sun_size
        suns.append((i, scattering_sun_direction(elevation, rotation), 0.5 * size))
    return suns


def without_discs(graph: Graph, nodes) -> Graph:
    """The graph with the sun discs of Sky Texture nodes `nodes` (indices) off."""
    if not nodes:
        return graph
    out = list(graph.nodes)
    for i in nodes:
        out[i] = replace(out[i], props=tuple(sorted(dict(out[i].props, sun_disc=False).items())))
    return replace(graph, nodes=tuple(out))


def map_size(graph: Graph, manual: int = 0, guided: bool = False) -> tuple:
    """(width, height) of the importance table (the module docstring's rule)."""
    if manual > 0:
        width = int(manual)
    else:
        width = 0
        for node in graph.nodes:
            if node.kind != "ShaderNodeTexEnvironment":
                continue
            texels = node.prop("image")
            first = getattr(texels, "first", None)
            texels = first() if callable(first) else texels
            if texels is None or not hasattr(texels, "size"):
                continue
            w = int(texels.size[0])
            width = max(width, 2 * w if node.prop("projection") == "MIRROR_BALL" else w)
        if guided:
            width = max(width, SUN_WIDTH)
        if width == 0:
            width = DEFAULT_WIDTH
    width = int(min(max(width, 2), MAX_WIDTH))
    width += width % 2
    return width, width // 2


def pixel_centres(width: int, height: int, rows=slice(None)) -> np.ndarray:
    """(R*W, 3) unit directions of the centres of table rows `rows` (EnvironmentMap's
    equirectangular convention: row 0 at +z, u = 1/2 - atan2(y, x) / 2 pi)."""
    r = np.arange(height)[rows]
    theta = (r + 0.5) * (np.pi / height)
    phi = np.pi * (1.0 - 2.0 * (np.arange(width) + 0.5) / width)
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    d = np.stack([st * np.cos(phi)[None, :], st * np.sin(phi)[None, :], np.broadcast_to(ct, (len(r), width))], axis=-1)
    return d.reshape(-1, 3)


def evaluate_table(background: Background, width: int, height: int) -> np.ndarray:
    """(H, W, 3) float32 radiance at the pixel centres, a light sample's (PATH_RAY_EMISSION),
    in chunks of about _CHUNK directions."""
    out = np.empty((height, width, 3), np.float32)
    step = max(1, _CHUNK // width)
    for r0 in range(0, height, step):
        rows = slice(r0, min(r0 + step, height))
        out[rows] = background.radiance(pixel_centres(width, height, rows)).reshape(-1, width, 3)
    return out


class _Sun:
    """A cone of directions sampled apart: axis (3,), half-angle, share of the light samples."""

    def __init__(self, axis, half, power):
        self.axis = np.asarray(axis, np.float64) / np.linalg.norm(axis)
        self.half = float(half)
        self.omc = float(2.0 * np.sin(0.5 * self.half) ** 2)
        self.pdf_inside = 1.0 / (2.0 * np.pi * self.omc)
        self.power = np.asarray(power, np.float64)  # (3,) integral of its radiance over the cone
        self.share = 0.0
        self.t, self.b = (v[0] for v in sampling.frame_from_z(self.axis[None]))

    def pdf(self, d):
        chord2 = np.einsum("ij,ij->i", d - self.axis, d - self.axis)
        return np.where(0.5 * chord2 <= self.omc, self.pdf_inside, 0.0)

    def sample(self, u):
        local, _ = sampling.sample_sphere_cone(u, np.sin(self.half) ** 2)
        return sampling.to_world(local, self.t, self.b, self.axis)


def _sun_power(background: Background, table: Background, sun: _Sun) -> np.ndarray:
    """(3,) what a sun disc adds to the sphere's radiance integral: the radiance with the disc
    on minus off, averaged over stratified directions in its cone, x the cone's solid angle."""
    k = int(np.sqrt(_SUN_PROBES))
    g = (np.stack(np.meshgrid(np.arange(k), np.arange(k)), -1).reshape(-1, 2) + 0.5) / k
    d = sun.sample(g)
    added = np.abs(background.radiance(d) - table.radiance(d)).mean(axis=0)
    return added * 2.0 * np.pi * sun.omc


class WorldMap:
    """The world's light: the Background's program sampled by its table (and guided suns).
    Interface of EnvironmentMap: eval, pdf, sample, power_integral, compensated, nbytes.

    background: the Background; size (W, H) of the table (map_size); compensate: MIS
    compensation of the table (strategy "mis"); values, suns: a table already evaluated and
    its guided suns (uncompensated() builds its twin without evaluating again)."""

    def __init__(self, background: Background, size, compensate=False, values=None, suns=None):
        self.background = background
        width, height = size
        if values is None:
            guided = guided_suns(background.graph)
            table = Background(without_discs(background.graph, [i for i, _, _ in guided]), background.scale,
                               background.camera) if guided else background
            values = evaluate_table(table, width, height)
            suns = [_Sun(axis, half, _sun_power(background, table, _Sun(axis, half, 0.0))) for _, axis, half in guided]
        self.values = values
        self.suns = [s for s in (suns or []) if float(s.power @ LUMINANCE) > 0]
        image = values
        if not compensate:  # no pixel left at pdf 0 (see the module docstring)
            lum = values.reshape(-1, 3) @ LUMINANCE.astype(np.float32)
            floor = FLOOR * float(np.mean(np.abs(lum))) if lum.size else 0.0
            image = values if floor == 0.0 else np.abs(values) + np.float32(floor)
        self.map = EnvironmentMap(image, compensate=compensate)
        self.compensated = self.map.compensated
        self.shape = self.map.shape
        self.map_integral = _integral(values, self.map)
        sun_total = sum((s.power for s in self.suns), np.zeros(3))
        self.power_integral = self.map_integral + sun_total
        self._shares(float(self.map_integral @ LUMINANCE), [float(s.power @ LUMINANCE) for s in self.suns])

    def _shares(self, map_power: float, sun_powers: list) -> None:
        """p_map and each sun's p_k: by power, the suns together within [SUN_SHARE_MIN,
        SUN_SHARE_MAX] (each at least SUN_SHARE_MIN / K)."""
        if not self.suns:
            self.p_map = 1.0
            return
        total = map_power + sum(sun_powers)
        suns = np.array(sun_powers) / total if total > 0 else np.full(len(sun_powers), 1.0 / len(sun_powers))
        suns = np.maximum(suns, SUN_SHARE_MIN / len(suns))
        together = float(np.clip(suns.sum(), SUN_SHARE_MIN, SUN_SHARE_MAX))
        suns = suns * (together / suns.sum())
        for s, p in zip(self.suns, suns):
            s.share = float(p)
        self.p_map = 1.0 - together

    def uncompensated(self) -> "WorldMap":
        """The same light with the uncompensated table (photon emission)."""
        if not self.compensated:
            return self
        return WorldMap(self.background, (self.shape[1], self.shape[0]), False, self.values, self.suns)

    def eval(self, d, ray: RayState = EMISSION_RAY) -> np.ndarray:
        """The program's radiance (N,3) at unit world directions d (N,3), a light sample's."""
        return self.background.radiance(d, ray)

    def pdf(self, d) -> np.ndarray:
        """Solid-angle pdf (N,) with which sample() draws the unit directions d (N,3)."""
        d = np.asarray(d, np.float64)
        pdf = self.p_map * self.map.pdf(d) if self.p_map > 0 else np.zeros(len(d))
        for s in self.suns:
            pdf = pdf + s.share * s.pdf(d)
        return pdf

    def sample(self, u, ray: RayState = EMISSION_RAY) -> EnvironmentSample:
        """Directions from u (N,2) in [0, 1)^2: a component chosen by u[:, 0] (rescaled), the
        table's direction or a sun's cone; the program's radiance there (for a light sample of
        the paths `ray`) and the mixture's pdf."""
        u = np.asarray(u, np.float64)
        n = len(u)
        if not self.suns:
            wi = self.map.sample(u).wi
        else:
            edges = np.cumsum([self.p_map] + [s.share for s in self.suns])
            which = np.minimum(np.searchsorted(edges, u[:, 0], side="right"), len(edges) - 1)
            lo = np.concatenate([[0.0], edges[:-1]])[which]
            width = np.concatenate([[self.p_map], [s.share for s in self.suns]])[which]
            v = np.column_stack([np.clip((u[:, 0] - lo) / np.where(width > 0, width, 1.0), 0.0,
                                         sampling.ONE_MINUS_EPSILON), u[:, 1]])
            wi = np.empty((n, 3))
            for k in range(len(edges)):
                rows = np.flatnonzero(which == k)
                if len(rows):
                    wi[rows] = self.map.sample(v[rows]).wi if k == 0 else self.suns[k - 1].sample(v[rows])
        pdf = self.pdf(wi)
        valid = (pdf > 0) & np.isfinite(pdf)
        Le = self.background.radiance(wi, ray)
        return EnvironmentSample(wi, np.where(valid[:, None], Le, 0.0), np.where(valid, pdf, 0.0), valid)

    @property
    def nbytes(self) -> int:
        return self.map.nbytes + self.values.nbytes


def _integral(values, env: EnvironmentMap) -> np.ndarray:
    """(3,) the integral over the sphere of the table's values (each pixel x its solid angle)."""
    H, W = values.shape[:2]
    dz = env._dz  # the rows' cos theta extents
    return (2.0 * np.pi / W) * (dz @ values.astype(np.float64).sum(axis=1))


def world_emitters(world, compensate=False, camera=None):
    """What a World lights with: (constant radiance (3,), Background or None, sampled light or
    None). A constant world is a constant (no table); an image world (World.image) an
    EnvironmentMap (environment.world_light); a graph world (World.graph) its Background, and
    a WorldMap unless its table is constant (BSDF sampling covers a constant) or the world
    asks for no importance sampling (World.map_resolution < 0)."""
    graph = world.graph[0] if getattr(world, "graph", ()) else None
    if graph is None:
        from .environment import world_light
        constant, env = world_light(world, compensate)
        return constant, None, env
    background = Background(graph, world.color, camera)
    if not np.any(background.scale != 0):
        return np.zeros(3), None, None
    manual = int(getattr(world, "map_resolution", 0))
    if manual < 0:
        return np.zeros(3), background, None
    guided = bool(guided_suns(graph))
    env = WorldMap(background, map_size(graph, manual, guided), compensate)
    if not env.suns and np.all(env.values == env.values[0, 0]):
        # A constant table (a world varying by Light Path alone): nothing to guide; photons
        # leave it with that radiance, escaped rays still evaluate the program.
        return env.values[0, 0].astype(np.float64), background, None
    return np.zeros(3), background, env
