"""A material's node graph as Ember renders it: its closures become lobes of the material table
(engine/scene.py Materials), and what varies over the surface stays a program run per batch.

compile_material() compiles the graph's Surface once and finds the closures it makes: which
lobes (kind, layering, Fresnel model: fixed by the graph), and for each of their parameters
whether it is a constant or varies from point to point (a texture, a procedural, a Fresnel
mix). The lobes' constants fill the material table as any material's do; a material where
nothing varies renders exactly as one written by hand. A material with varying parameters
keeps its program, and evaluate() gives the values at a batch of shading points: per lobe its
weight and parameters, the emitted radiance, the shading normal where a BSDF's Normal is
linked (Normal Map, Bump).

The closures are found by running the program once on a probe point (every state field at a
plausible value): Mix and Add Shader keep both sides' closures whatever their factors, so the
list of closures is the same at every point and only their values vary.

A graph with an output "normal" (bump.bump_from_displacement: the Material Output's
displacement as Cycles' Bump Only normal) has a second program for it, run first: the surface
program then reads the state with N set to that normal (Cycles' set_normal before the surface
closures), and BSDFs whose Normal is not linked shade with it.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..scene import (DISTRIBUTIONS, FRESNEL_COAT, FRESNEL_CONDUCTOR, FRESNEL_DIELECTRIC, FRESNEL_F82,
                     FRESNEL_NONE, LOBE_DIELECTRIC, LOBE_DIFFUSE, LOBE_MICROFACET, LOBE_OREN_NAYAR, LOBE_PHONG,
                     LOBE_SHEEN, LOBE_TOON, LOBE_TRANSLUCENT, LOBE_TRANSPARENT, TOON_DIFFUSE, TOON_GLOSSY,
                     part_digest)
from . import light_path
from .closures import closures
from .graph import Graph
from .hits import EMISSION_RAY, SurfaceHits
from .program import Program, compile
from .state import ShadingState

LOBE_OF = {"diffuse": LOBE_DIFFUSE, "phong": LOBE_PHONG, "microfacet": LOBE_MICROFACET,
           "dielectric": LOBE_DIELECTRIC, "transparent": LOBE_TRANSPARENT, "oren_nayar": LOBE_OREN_NAYAR,
           "sheen": LOBE_SHEEN, "translucent": LOBE_TRANSLUCENT, "toon": LOBE_TOON}
TOON_COMPONENTS = {"DIFFUSE": TOON_DIFFUSE, "GLOSSY": TOON_GLOSSY}
FRESNEL_OF = {"none": FRESNEL_NONE, "f82": FRESNEL_F82, "dielectric": FRESNEL_DIELECTRIC,
              "conductor": FRESNEL_CONDUCTOR, "coat": FRESNEL_COAT}
# Lobe inputs a closure may carry, and whether each is a colour or vector (3 components).
# aspect and tangent (anisotropy) are per point only: the shader nodes give them the point axis.
PARAMS = {"color": True, "tint": True, "roughness": False, "ior": False, "exponent": False,
          "film_thickness": False, "film_ior": False, "aspect": False, "tangent": True}
# One plausible shading point: what the probe run reads.
_PROBE = dict(P=np.zeros((1, 3)), N=np.array([[0.0, 0.0, 1.0]]), Ng=np.array([[0.0, 0.0, 1.0]]),
              I=np.array([[0.0, 0.0, 1.0]]), backfacing=np.zeros(1, bool), uv=np.full((1, 3), 0.5),
              generated=np.full((1, 3), 0.5), object=np.zeros((1, 3)), camera=np.array([[0.0, 0.0, 1.0]]),
              window=np.full((1, 3), 0.5), ray_length=np.ones(1), instancer_generated=np.zeros((1, 3)),
              instancer_uv=np.zeros((1, 3)), world_from_object=np.eye(4)[None], object_from_world=np.eye(4)[None],
              world_from_camera=np.eye(4), camera_from_world=np.eye(4),
              barycentric=np.full((1, 2), 1.0 / 3.0), triangle=np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]]),
              dPdu=np.array([[1.0, 0.0, 0.0]]), dPdv=np.array([[0.0, 1.0, 0.0]]), smooth=np.ones(1, bool),
              vertex_normal=np.array([[0.0, 0.0, 1.0]]), N_du=np.zeros((1, 3)), N_dv=np.zeros((1, 3)),
              uv_du=np.array([[1.0, 0.0, 0.0]]), uv_dv=np.array([[0.0, 1.0, 0.0]]),
              generated_du=np.array([[1.0, 0.0, 0.0]]), generated_dv=np.array([[0.0, 1.0, 0.0]]),
              dP=np.full(1, 1e-3), ndc_from_world=np.eye(4), object_color=np.ones((1, 3)), object_alpha=np.ones(1),
              object_index=np.zeros(1), object_random=np.full(1, 0.5), material_index=np.zeros(1),
              bounce=np.zeros(1, np.int64), diffuse_bounce=np.zeros(1, np.int64),
              glossy_bounce=np.zeros(1, np.int64), transmission_bounce=np.zeros(1, np.int64),
              transparent_bounce=np.zeros(1, np.int64), portal_bounce=np.zeros(1, np.int64))


PROBES = 16  # points a varying emission's mean is estimated from
# The rays a varying emission is probed for (Light Path): camera, a light sample's, reflected
# diffuse and glossy, transmitted.
_PROBE_FLAGS = (light_path.CAMERA, light_path.EMISSION, light_path.REFLECT | light_path.DIFFUSE,
                light_path.REFLECT | light_path.GLOSSY, light_path.TRANSMIT | light_path.GLOSSY)


def probe_state(n: int = 1, path_flag: int = light_path.CAMERA) -> ShadingState:
    """n probe points: the first the plausible point above, the others spread over the unit
    square of UV and Generated coordinates (and positions) by a 2D Halton sequence, so that a
    texture's mean over them stands for its mean over the surface; path_flag: the rays' Light
    Path flags (default a camera ray's)."""
    fields = {name: np.repeat(value, n, axis=0) if np.ndim(value) and value.shape[0] == 1 else value
              for name, value in _PROBE.items()}
    fields["path_flag"] = np.full(n, path_flag, np.uint32)
    if n > 1:
        k = np.arange(n)
        square = np.stack([_radical_inverse(k, 2), _radical_inverse(k, 3), np.full(n, 0.5)], axis=1)
        fields.update(uv=square, generated=square, P=2.0 * square - 1.0, object=2.0 * square - 1.0)
    return ShadingState(n, **fields)


def _radical_inverse(k: np.ndarray, base: int) -> np.ndarray:
    out, f, k = np.zeros(len(k)), 1.0 / base, k.copy()
    while k.any():
        out += f * (k % base)
        k //= base
        f /= base
    return out


def _varies(value, is_triple: bool) -> bool:
    """Whether a value computed at the probe point is per point (it has the point axis)."""
    return np.ndim(value) == (2 if is_triple else 1)


@dataclass
class MaterialProgram:
    """program: the compiled Surface; lobes: the lobe rows (dicts as Materials.make takes them,
    constants filled in, per-point ones at their probe value); varying[k]: the names of lobe
    k's inputs that vary ("weight" among them); emission: (3,) constant, or None where it
    varies; normal: a BSDF's Normal is linked; notes: what renders differently from Cycles."""

    program: Program
    closures: tuple  # the probe's closures that became lobes, in lobe order
    lobes: list
    varying: list
    emission: np.ndarray | None
    normal: bool
    notes: tuple = field(default_factory=tuple)
    emission_mean: np.ndarray = field(default_factory=lambda: np.zeros(3))  # over PROBES points
    holdout: float = 0.0  # mean over RGB of the Holdout closures' weight (over PROBES points where it varies)
    displacement: Program | None = None  # the bump normal of the Material Output's displacement

    @property
    def constant(self) -> bool:
        return self.emission is not None and not self.normal and not any(self.varying)

    @property
    def reads(self) -> frozenset:
        """The state fields the programs read (engine/nodes/state.py)."""
        return self.program.reads | (self.displacement.reads if self.displacement is not None else frozenset())

    def evaluate(self, state: ShadingState):
        """At the points of `state`: ([{input: (N,...) value} per lobe, with "weight" (N,3)],
        emitted radiance (N,3), shading normal (N,3) or None, the displacement's bump normal
        (N,3) or None: Cycles' sd->N, which a BSDF's own Normal is compared with)."""
        n = state.n
        bumped = None
        if self.displacement is not None:  # set_normal: N is the displacement's bump normal from here on
            bumped = np.broadcast_to(self.displacement.run(state)["normal"], (n, 3))
            state = ShadingState(n, source=_Through(state), N=bumped)
        made = closures(self.program.run(state)["surface"])
        bsdfs = [c for c in made if c.kind in LOBE_OF]
        lobes = []
        for c, names in zip(bsdfs, self.varying):
            values = {"weight": np.broadcast_to(c.weight, (n, 3))}
            for name in names:
                if name != "weight":
                    values[name] = np.broadcast_to(c.params[name], (n, 3) if PARAMS[name] else (n,))
            lobes.append(values)
        emission = np.zeros((n, 3))
        for c in made:
            if c.kind == "emission":
                emission = emission + c.weight
        normal = next((np.broadcast_to(c.params["normal"], (n, 3)) for c in bsdfs if "normal" in c.params), bumped)
        return lobes, emission, normal, bumped


class _Through:
    """A state's fields as the source of another state that overrides some (N): what the first
    has computed is not computed again. The Texture Coordinate normal follows the new state's N."""

    def __init__(self, state: ShadingState):
        self._state = state

    def __getattr__(self, name: str):
        if name.startswith("_") or name in ("N", "texcoord_normal"):
            raise AttributeError(name)
        return lambda: getattr(self._state, name)

    def attribute(self, name: str):
        return self._state.attribute(name)


def compile_material(graph: Graph) -> MaterialProgram:
    """The lobes, emission and program of a material's graph (its output "surface", and
    "normal" where it has one: bump_from_displacement's)."""
    program = compile(graph, {"surface": "shader"})
    socket = graph.output("normal")
    displacement = compile(graph, {"normal": "vector"}) if socket is not None and socket.link is not None else None
    if displacement is not None and not displacement.ops:  # a constant height: the normal unchanged
        displacement = None
    made = closures(program.run(probe_state() if program.ops else None)["surface"])
    bsdfs = [c for c in made if c.kind in LOBE_OF]
    tags = {c.tag: k for k, c in enumerate(bsdfs)}
    lobes, varying = [], []
    for c in bsdfs:
        lobe = dict(kind=LOBE_OF[c.kind], weight=_first(c.weight, True))
        names = ["weight"] if _varies(c.weight, True) else []
        for name, is_triple in PARAMS.items():
            if name in c.params:
                lobe[name] = _first(c.params[name], is_triple)
                if _varies(c.params[name], is_triple):
                    names.append(name)
        if "fresnel" in c.params:
            lobe["fresnel"] = FRESNEL_OF[c.params["fresnel"]]
        if "distribution" in c.params:
            lobe["distribution"] = DISTRIBUTIONS[c.params["distribution"]]
        if "component" in c.params:  # the Toon's, where its lobe keeps it
            lobe["distribution"] = TOON_COMPONENTS[c.params["component"]]
        if "layer" in c.params:
            lobe["layer"] = tags[c.params["layer"]]
        if c.params.get("refract_only"):
            lobe["refract_only"] = True
        lobes.append(lobe)
        varying.append(tuple(names))
    emitters = [c.weight for c in made if c.kind == "emission"]
    emission = None if any(_varies(w, True) for w in emitters) else sum((np.asarray(w) for w in emitters), np.zeros(3))
    normal = any("normal" in c.params for c in bsdfs) or displacement is not None
    warnings = program.warnings + tuple(w for w in (displacement.warnings if displacement is not None else ())
                                        if w not in program.warnings)
    mp = MaterialProgram(program, tuple(bsdfs), lobes, varying, emission, normal, warnings,
                         displacement=displacement)
    holdouts = [c.weight for c in made if c.kind == "holdout"]
    if holdouts:
        if any(_varies(w, True) for w in holdouts):
            state = probe_state(PROBES)
            made_at = closures(program.run(state)["surface"])
            mp.holdout = float(np.mean(sum(np.broadcast_to(c.weight, (PROBES, 3)) for c in made_at
                                           if c.kind == "holdout")))
            mp.notes = mp.notes + ("a Holdout weight that varies over the surface (its mean)",)
        else:
            mp.holdout = float(np.mean(sum(np.asarray(w, np.float64) for w in holdouts)))
    if emission is not None:
        mp.emission_mean = emission
    else:  # the largest mean any kind of ray sees: a surface black to camera rays still lights
        flags = _PROBE_FLAGS if "path_flag" in program.reads else _PROBE_FLAGS[:1]
        means = [mp.evaluate(probe_state(PROBES, flag))[1].mean(axis=0) for flag in flags]
        mp.emission_mean = max(means, key=lambda m: float(np.abs(m).sum()))
    return mp


_PHONG_SHADERS = ("ShaderNodeBsdfAnisotropic", "ShaderNodeBsdfMetallic", "ShaderNodeBsdfPrincipled")


def with_phong(graph: Graph) -> Graph:
    """The graph with its glossy reflection shaded by the seed's Phong lobe (the scene's Render
    Glossy with Phong): the `phong` prop set on its Glossy, Metallic and Principled nodes."""
    nodes = tuple(replace(n, props=tuple(sorted(dict(n.props, phong=True).items())))
                  if n.kind in _PHONG_SHADERS else n for n in graph.nodes)
    return replace(graph, nodes=nodes)


def _first(value, is_triple: bool):
    """A constant as plain numbers; a per-point value at the probe point."""
    a = np.asarray(value, np.float64)
    if is_triple:
        return tuple(float(v) for v in (a[0] if a.ndim == 2 else a))
    return float(a[0] if a.ndim == 1 else a)


class MaterialPrograms:
    """The node programs of a scene's materials (Materials.graphs), compiled once per process,
    and their values at a batch of shading points for the closure."""

    def __init__(self, materials):
        self.compiled = {m: compiled_material(g) for m, g in enumerate(materials.graphs) if g is not None}
        self.has = np.zeros(len(materials.kind), bool)
        self.has[list(self.compiled)] = True
        # Materials whose emitted radiance varies over the surface (evaluated where it is found).
        self.varying_emission = np.zeros(len(materials.kind), bool)
        self.varying_emission[[m for m, mp in self.compiled.items() if mp.emission is None]] = True
        # Every state field some program reads: what the integrators track for them (path flags,
        # bounce counts, ray differentials).
        self.reads = frozenset().union(*(mp.reads for mp in self.compiled.values()))
        self._names = {m: tuple(sorted(r[len("attribute:"):] for r in mp.reads if r.startswith("attribute:")))
                       for m, mp in self.compiled.items()}

    def __bool__(self) -> bool:
        return bool(self.compiled)

    def _batches(self, mat: np.ndarray, hits, which):
        """(material, rows, state) per batch of the points whose materials `which` (M,) bool
        marks: a material's points at once, split where their objects' meshes differ in which
        named attributes the program reads they have (ShadingState.attribute is per batch)."""
        for m in np.unique(mat[which[mat]]):
            m = int(m)
            for rows in hits.split(np.flatnonzero(mat == m), self._names[m]):
                yield self.compiled[m], rows, hits.take(rows).state()

    def pair_values(self, mat: np.ndarray, pair_offset: np.ndarray, n_pairs: int, hits):
        """For the N points of a closure (mat (N,) their materials, pair_offset (N+1,) where each
        point's lobes start in the pair table): ({input: (values (P,...), has (P,) bool)} of
        the pairs whose material's program computes them, normal (K,3) with rows (K,) of the
        points it replaces and their smooth normal (K,3) (the displacement's bump normal where
        there is one, else NaN: the interpolated normal), or (None, None, None)). hits: a
        SurfaceHits of the N points (with the path's record of them, SurfaceHits' ray)."""
        values, normal, normal_rows, smooth = {}, [], [], []
        for mp, rows, state in self._batches(mat, hits, self.has):
            lobes, _, n, bumped = mp.evaluate(state)
            for k, lobe in enumerate(lobes):
                pairs = pair_offset[rows] + k
                for name, v in lobe.items():
                    if name not in values:
                        width = (3,) if name == "weight" or PARAMS.get(name, False) else ()
                        values[name] = (np.zeros((n_pairs,) + width), np.zeros(n_pairs, bool))
                    a, has = values[name]
                    a[pairs], has[pairs] = v, True
            if n is not None:
                normal.append(n)
                normal_rows.append(rows)
                smooth.append(bumped if bumped is not None else np.full((len(rows), 3), np.nan))
        if not normal:
            return values, None, None, None
        return values, np.concatenate(normal), np.concatenate(normal_rows), np.concatenate(smooth)

    def emission(self, mat: np.ndarray, hits) -> np.ndarray | None:
        """(N,3) emitted radiance of N hits where some material's emission varies, else None."""
        if not self.varying_emission[mat].any():
            return None
        out = np.zeros((len(mat), 3))
        for mp, rows, state in self._batches(mat, hits, self.varying_emission):
            out[rows] = mp.evaluate(state)[1]
        return out


    @classmethod
    def of(cls, materials) -> "MaterialPrograms":
        """The programs of `materials`, compiled once per process for the same table."""
        if not materials.graphs:
            return cls(materials)
        key = part_digest(materials)
        if key not in _COMPILED:
            if len(_COMPILED) >= 4:
                _COMPILED.pop(next(iter(_COMPILED)))
            _COMPILED[key] = cls(materials)
        return _COMPILED[key]


_COMPILED: dict = {}  # digest of a material table -> its MaterialPrograms (the last few)
_GRAPHS: dict = {}  # a material's graph -> its MaterialProgram (the last GRAPHS_KEPT)
GRAPHS_KEPT = 256


def compiled_material(graph: Graph) -> MaterialProgram:
    """compile_material(graph), once per process for equal graphs: a viewport edit of one
    material, or another render of the scene, compiles only the graphs that changed. Graphs of
    plain values only: one holding an image's texels (compared by identity, new at every
    export) would never be found again and would keep the texels alive."""
    if not all(_plain(value) for node in graph.nodes for _, value in node.props):
        return compile_material(graph)
    try:
        known = _GRAPHS.get(graph)
    except TypeError:  # an unhashable socket value
        return compile_material(graph)
    if known is None:
        if len(_GRAPHS) >= GRAPHS_KEPT:
            _GRAPHS.pop(next(iter(_GRAPHS)))
        known = _GRAPHS[graph] = compile_material(graph)
    return known


def _plain(value) -> bool:
    if isinstance(value, tuple):
        return all(_plain(v) for v in value)
    return value is None or isinstance(value, (str, int, float, bool))


class SurfaceEmission:
    """The radiance of surfaces whose material's emission varies (textured emitters), at points
    of their triangles: what light sampling and photon emission read (LightSet)."""

    def __init__(self, scene, programs: MaterialPrograms):
        self.scene, self.programs = scene, programs
        self.varying = programs.varying_emission  # (M,) bool per material

    def __call__(self, prim, bary, p, n, wo, ray=None) -> np.ndarray:
        """(K,3) at points p (K,3) (barycentrics bary) of triangles prim (K,), the surface facing
        n (K,3), seen from wo (K,3). ray: the record of the paths whose light samples these are
        (hits.RayState: their bounce counts), else none; either way the shader sees Cycles'
        emission flag and no ray differential, as Cycles evaluates a light's shader for a
        light sample (light_sample_shader_eval, shader_setup_from_sample)."""
        ray = EMISSION_RAY if ray is None else ray.for_emission()
        hits = SurfaceHits(self.scene, prim, bary, p, n, n, wo, ray=ray)
        return self.programs.emission(self.scene.mesh.material[prim], hits)
