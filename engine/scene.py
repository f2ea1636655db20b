"""Scene: everything a render needs, as NumPy arrays. Knows nothing of Blender.

World space is Blender's (right-handed, Z up, metres). Colours are linear RGB in the
file's working space. Radiometric units follow Cycles (see ../shared/reference/blender.md):
radiance in W/(m^2 sr), intensity in W/sr, irradiance in W/m^2.

Everything is a frozen dataclass of arrays so a Scene is picklable and can be saved to
.npz (`save`) and replayed (`load`) without Blender.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field, fields

import numpy as np

# Material kinds (shading runs once per kind present in the scene).
MAT_DIFFUSE = 0  # Lambertian, albedo = base_color
MAT_EMISSION_ONLY = 1  # black BSDF (pure emitter, e.g. an Emission shader)

# Light kinds. Point and spot are spheres of `radius` (delta when radius == 0).
LIGHT_POINT = 0
LIGHT_SPOT = 1
LIGHT_SUN = 2
LIGHT_RECT = 3
LIGHT_DISK = 4  # disk or ellipse

FILTERS = ("BOX", "GAUSSIAN", "BLACKMAN_HARRIS")
INTEGRATORS = ("path",)
# Direct-light strategies: both combined by MIS (default), or one alone (for studies and the
# strategy-agreement tests; each alone is unbiased too, where it can reach the light).
STRATEGIES = ("mis", "bsdf", "light")


def _f64(a, shape_tail=()):
    a = np.ascontiguousarray(a, dtype=np.float64)
    return a.reshape((-1,) + shape_tail) if shape_tail else a


@dataclass(frozen=True)
class Mesh:
    """All mesh instances flattened into one world-space triangle soup.

    vertices (V,3) float32 world positions; triangles (T,3) int32 vertex indices;
    normals (T,3,3) float32 world-space corner (shading) normals, unit length;
    material (T,) int32 index into Materials.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray
    material: np.ndarray

    @staticmethod
    def empty() -> "Mesh":
        return Mesh(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32),
                    np.zeros((0, 3, 3), np.float32), np.zeros(0, np.int32))

    @property
    def n_triangles(self) -> int:
        return len(self.triangles)


@dataclass(frozen=True)
class Materials:
    """Per-material tables, (M,) or (M,3).

    kind: MAT_* per material; base_color (M,3) albedo in [0,1];
    emission (M,3) emitted radiance W/(m^2 sr) (colour x strength, as Cycles); emission
    of meshes is two-sided like Cycles'. names: for messages.
    """

    kind: np.ndarray
    base_color: np.ndarray
    emission: np.ndarray
    names: tuple = ()

    @staticmethod
    def make(rows: list[dict]) -> "Materials":
        """rows: dicts with kind, base_color, emission, name. Empty -> one grey diffuse."""
        if not rows:
            rows = [dict(kind=MAT_DIFFUSE, base_color=(0.8, 0.8, 0.8), emission=(0, 0, 0), name="default")]
        return Materials(
            kind=np.array([r.get("kind", MAT_DIFFUSE) for r in rows], np.int32),
            base_color=np.array([r.get("base_color", (0.8, 0.8, 0.8)) for r in rows], np.float64).reshape(-1, 3),
            emission=np.array([r.get("emission", (0, 0, 0)) for r in rows], np.float64).reshape(-1, 3),
            names=tuple(r.get("name", f"material{i}") for i, r in enumerate(rows)),
        )


@dataclass(frozen=True)
class Lights:
    """Analytic lights (emissive triangles are found from Materials at build time).

    kind (L,) LIGHT_*; position (L,3) centre; frame (L,3,3) rows = the light object's
    world x, y, z axes (unit); area lights and spots emit along -z, the sun shines along -z.
    size (L,2): RECT half-extents along x, y; DISK semi-axes along x, y.
    radius (L,): POINT/SPOT sphere radius (0 = delta light).
    Le (L,3): POINT/SPOT with radius > 0, RECT, DISK, SUN with angle > 0: radiance
    W/(m^2 sr); POINT/SPOT with radius 0: intensity W/sr; SUN with angle 0: irradiance W/m^2.
    spot_cos_half (L,), spot_smooth (L,): Cycles' smoothstep((cos - cos_half)/smooth).
    sun_half_angle (L,) radians.
    visible (L,) bool: seen by camera rays (Cycles' visible_camera).
    """

    kind: np.ndarray
    position: np.ndarray
    frame: np.ndarray
    size: np.ndarray
    radius: np.ndarray
    Le: np.ndarray
    spot_cos_half: np.ndarray
    spot_smooth: np.ndarray
    sun_half_angle: np.ndarray
    visible: np.ndarray
    names: tuple = ()

    @staticmethod
    def make(rows: list[dict]) -> "Lights":
        """rows: dicts with the fields above (scalars/tuples); missing ones get defaults."""
        n = len(rows)
        g = lambda k, d: [r.get(k, d) for r in rows]
        eye = np.eye(3)
        return Lights(
            kind=np.array(g("kind", LIGHT_POINT), np.int32).reshape(n),
            position=_f64(g("position", (0, 0, 0)), (3,)),
            frame=np.array(g("frame", eye), np.float64).reshape(n, 3, 3),
            size=_f64(g("size", (0, 0)), (2,)),
            radius=np.array(g("radius", 0.0), np.float64).reshape(n),
            Le=_f64(g("Le", (0, 0, 0)), (3,)),
            spot_cos_half=np.array(g("spot_cos_half", -1.0), np.float64).reshape(n),
            spot_smooth=np.array(g("spot_smooth", 0.0), np.float64).reshape(n),
            sun_half_angle=np.array(g("sun_half_angle", 0.0), np.float64).reshape(n),
            visible=np.array(g("visible", True), bool).reshape(n),
            names=tuple(g("name", "light")),
        )

    def __len__(self) -> int:
        return len(self.kind)


@dataclass(frozen=True)
class World:
    """Background: constant radiance `color` (3,) W/(m^2 sr), seen by camera rays if visible."""

    color: np.ndarray = field(default_factory=lambda: np.zeros(3))
    visible: bool = True


@dataclass(frozen=True)
class Camera:
    """Pinhole or orthographic camera.

    world_from_camera (4,4): camera looks down its -z axis, +y up, +x right.
    window (4,) = (left, right, bottom, top) of the image rectangle in camera space at
    z = -1 (perspective) or of the view volume (orthographic, metres); includes sensor fit
    and lens shift. clip_start/clip_end along the view axis.
    """

    world_from_camera: np.ndarray
    window: np.ndarray
    ortho: bool = False
    clip_start: float = 0.1
    clip_end: float = 1000.0


@dataclass(frozen=True)
class Settings:
    """Render settings. Pixel rows count from the top of the image in the core.

    width/height: full frame in pixels (resolution_percentage applied).
    border (x0, y0, x1, y1): the pixel rectangle to render, half-open, top-left origin.
    """

    width: int = 64
    height: int = 64
    border: tuple = None
    samples: int = 16
    max_depth: int = 64
    rr_depth: int = 3
    seed: int = 0
    time_limit: float = 0.0  # seconds, 0 = none
    batch_size: int = 1 << 16
    filter: str = "BLACKMAN_HARRIS"
    filter_width: float = 1.5  # pixels
    integrator: str = "path"
    strategy: str = "mis"
    noise_target: float = 0.0  # stop when Film.noise() falls below it (0 = off)
    threads: int = 0  # 0 = all cores

    def __post_init__(self):
        if self.border is None:
            object.__setattr__(self, "border", (0, 0, self.width, self.height))

    def replace(self, **kw) -> "Settings":
        return dataclasses.replace(self, **kw)


@dataclass(frozen=True)
class Scene:
    mesh: Mesh
    materials: Materials
    lights: Lights
    world: World
    camera: Camera
    settings: Settings

    def replace(self, **kw) -> "Scene":
        return dataclasses.replace(self, **kw)

    # --- .npz round trip (replay a Blender export without Blender) ---------------------
    def save(self, path) -> None:
        flat = {}
        for part in fields(self):
            obj = getattr(self, part.name)
            for f in fields(obj):
                v = getattr(obj, f.name)
                flat[f"{part.name}.{f.name}"] = np.asarray(v if v is not None else np.nan, dtype=object if isinstance(v, (tuple, str)) else None)
        np.savez_compressed(path, **flat)

    @staticmethod
    def load(path) -> "Scene":
        data = np.load(path, allow_pickle=True)
        parts = {}
        for part in fields(Scene):
            cls = {"mesh": Mesh, "materials": Materials, "lights": Lights, "world": World,
                   "camera": Camera, "settings": Settings}[part.name]
            kw = {}
            for f in fields(cls):
                v = data[f"{part.name}.{f.name}"]
                if v.dtype == object:
                    v = v.item() if v.shape == () else tuple(v.tolist())
                elif v.shape == () and cls in (Settings, Camera, World):
                    v = v.item()
                kw[f.name] = v
            parts[part.name] = cls(**kw)
        return Scene(**parts)


# --- plain-data form (worker processes): dicts of arrays, no class references ---------------
def to_plain(obj):
    """A dataclass tree as nested dicts of arrays/scalars/tuples (picklable anywhere)."""
    if dataclasses.is_dataclass(obj):
        return {f.name: to_plain(getattr(obj, f.name)) for f in fields(obj)}
    return obj


def scene_from_plain(data: dict) -> "Scene":
    parts = {"mesh": Mesh, "materials": Materials, "lights": Lights, "world": World,
             "camera": Camera, "settings": Settings}
    return Scene(**{name: cls(**data[name]) for name, cls in parts.items()})
