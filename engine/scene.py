"""Scene: everything a render needs, as NumPy arrays. Knows nothing of Blender.

World space is Blender's (right-handed, Z up, metres). Colours are linear RGB in the
file's working space. Radiometric units follow Cycles (see ../shared/reference/blender.md):
radiance in W/(m^2 sr), intensity in W/sr, irradiance in W/m^2.

Everything is a frozen dataclass of arrays so a Scene is picklable and can be saved to
.npz (`save`) and replayed (`load`) without Blender.
"""
from __future__ import annotations

import dataclasses
import weakref
from dataclasses import dataclass, field, fields

import numpy as np

from .errors import EmberError
from .settings import SAMPLING_ONLY, Settings  # generated from the declarations (engine/settings.py)

# Material kinds: how a material was defined (for messages and tests). What is shaded is its
# lobes (below); shading runs once per lobe kind present in the scene.
MAT_DIFFUSE = 0  # one Lambertian lobe, albedo = base_color
MAT_EMISSION_ONLY = 1  # black BSDF (pure emitter, e.g. an Emission shader)
MAT_PHONG = 2  # one physically plausible Phong lobe (seed 000)
MAT_NODES = 3  # lobes converted from a shader node tree

# Lobe kinds. A material's BSDF is the sum of its lobes, each scaled by its weight.
LOBE_DIFFUSE = 0  # Lambertian: colour / pi
LOBE_PHONG = 1  # kd = colour, ks = tint, exponent n
LOBE_MICROFACET = 2  # GGX reflection, alpha = roughness^2; a perfect mirror when smooth
LOBE_DIELECTRIC = 3  # GGX (or smooth) reflection + refraction with the exact Fresnel of ior
LOBE_TRANSPARENT = 4  # straight pass-through (alpha, Transparent BSDF)
LOBE_OREN_NAYAR = 5  # rough diffuse: Cycles' energy-preserving Oren-Nayar, sigma = roughness
LOBE_SHEEN = 6  # Cycles' microfiber sheen (an LTC lobe) or, with DIST_VELVET, the Ashikhmin velvet
LOBE_TRANSLUCENT = 7  # Lambertian transmission: colour / pi on the far side
LOBE_TOON = 8  # Cycles' Toon: size, smooth, the component in lobe_distribution (TOON_*)
LOBE_KINDS = 9
TOON_DIFFUSE, TOON_GLOSSY = 0, 1  # the Toon cone's axis: the normal, wo's mirror direction

# Fresnel of LOBE_MICROFACET (Cycles' models).
FRESNEL_NONE = 0  # F = colour (Glossy BSDF)
FRESNEL_F82 = 1  # conductor: F0 = colour, F82 tint = tint (Principled metallic, Metallic BSDF)
FRESNEL_DIELECTRIC = 2  # exact Fresnel of ior remapped to F0 = F0(ior) tint .. 1 (Principled)
FRESNEL_CONDUCTOR = 3  # exact conductor Fresnel of n = colour, k = tint (Metallic BSDF, Physical Conductor)
FRESNEL_COAT = 4  # Principled coat: exact Fresnel of ior times colour (the coat weight); tint: Coat Tint
# LOBE_DIELECTRIC: FRESNEL_NONE reflects F x tint (Glass); FRESNEL_DIELECTRIC reflects the exact
# Fresnel remapped to F0 = F0(ior) tint .. 1, untinted (Principled transmission's Specular Tint).

# Microfacet distribution of LOBE_MICROFACET and LOBE_DIELECTRIC (the nodes' `distribution`).
DIST_GGX = 0  # single-scattering GGX
DIST_MULTI_GGX = 1  # GGX with Cycles' energy compensation (engine/bsdf/multiscatter.py)
DIST_BECKMANN = 2  # Beckmann (engine/bsdf/beckmann.py): microfacet lobes only
DIST_ASHIKHMIN_SHIRLEY = 3  # Ashikhmin-Shirley (engine/bsdf/ashikhmin_shirley.py): microfacet lobes only
DIST_VELVET = 4  # Sheen BSDF's Ashikhmin velvet (sheen lobes; any other value: microfiber)
DISTRIBUTIONS = {"GGX": DIST_GGX, "MULTI_GGX": DIST_MULTI_GGX, "BECKMANN": DIST_BECKMANN,
                 "ASHIKHMIN_SHIRLEY": DIST_ASHIKHMIN_SHIRLEY, "ASHIKHMIN": DIST_VELVET}

# Image texture lookups (Cycles' Image Texture node).
EXT_REPEAT, EXT_EXTEND, EXT_CLIP, EXT_MIRROR = 0, 1, 2, 3
INTERP_LINEAR, INTERP_CLOSEST = 0, 1
TEX_COLOR, TEX_ALPHA = 0, 1  # which output of the node feeds the input

# Light kinds. Point and spot are spheres of `radius` (delta when radius == 0).
LIGHT_POINT = 0
LIGHT_SPOT = 1
LIGHT_SUN = 2
LIGHT_RECT = 3
LIGHT_DISK = 4  # disk or ellipse

# Ray visibility (Cycles' object, light and world visibility): bit set = seen by that kind
# of ray. A ray is a camera ray until its first non-transparent bounce, then a diffuse,
# glossy or transmission ray by that bounce's kind; shadow rays are light samples' rays.
# HOLDOUT marks triangles that camera rays see as a hole (Cycles' Holdout object).
RAY_CAMERA, RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMIT, RAY_SHADOW = 1, 2, 4, 8, 16
RAY_ALL = 31
HOLDOUT = 32

# Light and shadow linking (Cycles' light sets): an emitter's 64-bit masks of the receiver and
# blocker sets it is linked to; LINK_ALL: every set (no linking).
LINK_ALL = 0xFFFFFFFFFFFFFFFF

# Cycles' attribute types (Mesh.attributes' type codes index this).
ATTRIBUTE_TYPES = ("float", "float2", "float3", "float4", "rgba")


def _f64(a, shape_tail=()):
    a = np.ascontiguousarray(a, dtype=np.float64)
    return a.reshape((-1,) + shape_tail) if shape_tail else a


@dataclass(frozen=True)
class Mesh:
    """All mesh instances flattened into one world-space triangle soup.

    vertices (V,3) float32 world positions; triangles (T,3) int32 vertex indices;
    normals (T,3,3) float32 world-space corner (shading) normals, unit length;
    material (T,) int32 index into Materials; uvs (T,3,2) float32 corner texture
    coordinates of the active render UV map (zeros without one, as Cycles);
    visibility (T,) uint8 RAY_* bits (+ HOLDOUT) of each triangle's object, or None: every
    triangle seen by every ray, no holdout.
    objects (B+1,) int64 triangle offsets of the exported objects (each triangle range uses
    its own vertices), or None: engine/accel.py gives big objects an Embree scene of their
    own, kept when only other objects change.
    object_matrix (B,4,4) float64 world_from_object of each object (column vectors, in the
    render's world: shifted with the vertices, see recentred); object_texspace (B,2,3) its
    texture space (location, size) in object space: Generated maps location - size ..
    location + size to [0, 1]^3. None with `objects`.

    What node programs read beyond that (engine/nodes/hits.py), each None unless a material
    of the scene reads it (engine/blender/export.py decides):
    attributes: {name: (values, types)} the mesh attributes programs read by Cycles' names
    (engine/nodes/state.py), aligned with the triangles: values (T,3,c) float32 per corner in
    the triangles' corner order (a face's or triangle's value on all three corners where
    some mesh has the attribute per corner) or (T,c) per triangle; types (B,) int8 per object
    (one row for all triangles without `objects`): the Cycles type of the object's attribute,
    an index into ATTRIBUTE_TYPES, -1 where its mesh has none.
    object_attributes: {name: (B,4) float64} Object and Instancer attributes (custom
    properties) by Cycles' prefixed names. object_info (B,6) float64: the object's Color
    (RGBA), Pass Index and Cycles' random number; instancer (B,5) float64: the instancer's
    generated coordinates (3) and UV (2) at an instance (zeros for other objects);
    material_pass_index (M,) float64: each material's Pass Index.

    terminator (B,2) float32 per object (with `objects`): Cycles' shadow terminator Geometry
    Offset and Shading Offset (Object Properties > Shading), as Blender shows them; None: both 0.
    link_sets (B,2) uint8 per object: its receiver set and blocker set (light and shadow
    linking, 0: in no linking collection); link_membership (B,2) uint64: as an emitter (an
    emissive object), the masks of receiver sets it lights and blocker sets that shadow it
    (LINK_ALL: all); both None without linking.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray
    material: np.ndarray
    uvs: np.ndarray = None
    visibility: np.ndarray = None
    objects: np.ndarray = None
    object_matrix: np.ndarray = None
    object_texspace: np.ndarray = None
    attributes: dict = None
    object_attributes: dict = None
    object_info: np.ndarray = None
    instancer: np.ndarray = None
    material_pass_index: np.ndarray = None
    terminator: np.ndarray = None
    link_sets: np.ndarray = None
    link_membership: np.ndarray = None

    def __post_init__(self):
        if self.uvs is None:
            object.__setattr__(self, "uvs", np.zeros((len(self.triangles), 3, 2), np.float32))

    @staticmethod
    def empty() -> "Mesh":
        return Mesh(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32),
                    np.zeros((0, 3, 3), np.float32), np.zeros(0, np.int32))

    @property
    def n_triangles(self) -> int:
        return len(self.triangles)


_LOBE_DEFAULTS = dict(kind=LOBE_DIFFUSE, weight=(1.0, 1.0, 1.0), color=(0.8, 0.8, 0.8), color_tex=-1,
                      color_sqrt=False, tint=(1.0, 1.0, 1.0), tint_is_color=False, roughness=0.5,
                      roughness_tex=-1, ior=1.5, fresnel=FRESNEL_NONE, distribution=DIST_GGX, exponent=1.0, layer=-1,
                      opacity_tex=-1, opacity_invert=False, film_thickness=0.0, film_ior=1.33, refract_only=False)
_SLOT_DEFAULTS = dict(image=0, output=TEX_COLOR, extension=EXT_REPEAT, interpolation=INTERP_LINEAR,
                      transform=((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)))


@dataclass(frozen=True)
class Materials:
    """Per-material tables (M rows), their lobes (K rows) and textures.

    Materials: kind (M,) MAT_*; base_color (M,3) representative albedo (viewport, messages);
    emission (M,3) emitted radiance W/(m^2 sr) (colour x strength, as Cycles), two-sided;
    holdout (M,) the mean over RGB of its Holdout closures' weight (Cycles' holdout: camera
    rays' alpha loses it there);
    normal_tex (M,) texture slot of a tangent-space normal map (-1 none) and
    normal_strength (M,); names.

    Lobes, sorted by material: the BSDF of material m is the sum of its lobes
    lobe_weight * lobe(colour, ...). lobe_material (K,), lobe_kind (K,) LOBE_*;
    lobe_weight (K,3) constant factor (mix factors, metallic / transmission split, alpha);
    lobe_color (K,3) the colour input (diffuse albedo, Glossy colour, conductor F0, glass
    transmission tint, Phong kd), replaced by texture slot lobe_color_tex (-1 none), taken as
    sqrt(clamp(colour)) where lobe_color_sqrt (Principled transmission);
    lobe_tint (K,3): FRESNEL_DIELECTRIC specular tint, FRESNEL_F82 edge tint, dielectric
    reflection tint (the colour itself where lobe_tint_is_color), Phong ks;
    lobe_roughness (K,) Blender roughness (alpha = roughness^2), from slot lobe_roughness_tex;
    lobe_ior (K,) (n_inside / n_outside); lobe_fresnel (K,) FRESNEL_*; lobe_distribution (K,)
    DIST_* of microfacet and dielectric lobes; lobe_exponent (K,)
    Phong n; lobe_layer (K,) the lobe this one lies under (it is scaled by 1 - that lobe's
    albedo, Cycles' closure layering; -1 none); lobe_opacity_tex (K,) slot whose scalar
    value multiplies the weight (1 - value where lobe_opacity_invert): textured alpha;
    lobe_film_thickness (K,) nm and lobe_film_ior (K,): a thin film on a microfacet or glass
    lobe's Fresnel (engine/bsdf/thin_film.py; none below 0.1 nm); lobe_refract_only (K,) bool:
    a dielectric lobe without its reflection (the Refraction BSDF).

    Texture slots (S): tex_image (S,) image index, tex_output (S,) TEX_COLOR / TEX_ALPHA,
    tex_extension (S,) EXT_*, tex_interpolation (S,) INTERP_*, tex_transform (S,2,3) affine
    map from mesh UV to image UV (Mapping node). A scalar read from a colour is its luminance.

    Images (I), all texels in one array: image_texels (P,4) float32 RGBA rows bottom-up,
    image i has image_size[i] = (width, height) texels from image_offset[i]; image_srgb (I,)
    bool: texels are sRGB-encoded bytes / 255, decoded after interpolation (as Cycles);
    image_names.

    Volumes (engine/volumes.py): volume_sigma_s, volume_sigma_a, volume_emission (M,3) the
    homogeneous medium a closed mesh of the material bounds (all zero: none), per unit length;
    volume_g (M,) its Henyey-Greenstein mean cosine. Rows take them from a `volume` dict.

    graphs: per material, its shader node graph (engine/nodes/graph.py) where parameters vary
    over the surface (textures, procedurals, Fresnel mixes), else None; empty: none at all.
    Such a material's lobes are its graph's closures in order (engine/nodes/material.py), with
    their values at the probe point in the table; a node program gives them per point.
    """

    kind: np.ndarray
    base_color: np.ndarray
    emission: np.ndarray
    names: tuple = ()
    normal_tex: np.ndarray = None
    normal_strength: np.ndarray = None
    lobe_material: np.ndarray = None
    lobe_kind: np.ndarray = None
    lobe_weight: np.ndarray = None
    lobe_color: np.ndarray = None
    lobe_color_tex: np.ndarray = None
    lobe_color_sqrt: np.ndarray = None
    lobe_tint: np.ndarray = None
    lobe_tint_is_color: np.ndarray = None
    lobe_roughness: np.ndarray = None
    lobe_roughness_tex: np.ndarray = None
    lobe_ior: np.ndarray = None
    lobe_fresnel: np.ndarray = None
    lobe_distribution: np.ndarray = None
    lobe_exponent: np.ndarray = None
    lobe_layer: np.ndarray = None
    lobe_opacity_tex: np.ndarray = None
    lobe_opacity_invert: np.ndarray = None
    lobe_film_thickness: np.ndarray = None
    lobe_film_ior: np.ndarray = None
    lobe_refract_only: np.ndarray = None
    tex_image: np.ndarray = None
    tex_output: np.ndarray = None
    tex_extension: np.ndarray = None
    tex_interpolation: np.ndarray = None
    tex_transform: np.ndarray = None
    image_texels: np.ndarray = None
    image_size: np.ndarray = None
    image_offset: np.ndarray = None
    image_srgb: np.ndarray = None
    image_names: tuple = ()
    graphs: tuple = ()
    holdout: np.ndarray = None
    volume_sigma_s: np.ndarray = None
    volume_sigma_a: np.ndarray = None
    volume_emission: np.ndarray = None
    volume_g: np.ndarray = None

    def __post_init__(self):
        if self.holdout is None:
            object.__setattr__(self, "holdout", np.zeros(len(self.kind)))
        # Tables built without lobes (kind + base_color only) get them from their kind.
        if self.lobe_kind is None:
            rows = [dict(kind=int(k), base_color=c) for k, c in zip(self.kind, self.base_color)]
            full = Materials.make(rows)
            for f in fields(Materials):
                if getattr(self, f.name) is None:
                    object.__setattr__(self, f.name, getattr(full, f.name))

    @property
    def n_lobes(self) -> int:
        return len(self.lobe_kind)

    @staticmethod
    def make(rows: list[dict], slots: list[dict] = (), images: list[dict] = ()) -> "Materials":
        """Build the tables from plain Python values.

        rows: dicts with kind, base_color, emission, name, normal_tex, normal_strength and
        `lobes`, a list of dicts with the lobe_* fields above without the prefix (missing ones
        get defaults; `layer` counts among the material's own lobes). Without `lobes` a row's kind decides: MAT_DIFFUSE -> one diffuse lobe
        of base_color; MAT_PHONG -> one Phong lobe from `phong` = (kd, ks, n);
        MAT_EMISSION_ONLY -> none. Empty rows -> one grey diffuse material.
        slots: dicts with image, output, extension, interpolation, transform.
        images: dicts with texels (H,W,4) (or (H,W,C)) bottom row first, srgb, name.
        Raises EmberError for texture references out of range.
        """
        if not rows:
            rows = [dict(kind=MAT_DIFFUSE, base_color=(0.8, 0.8, 0.8), emission=(0, 0, 0), name="default")]
        lobes = []
        for m, r in enumerate(rows):
            first = len(lobes)
            for lobe in _row_lobes(r):
                lobe = dict(_LOBE_DEFAULTS, **lobe, material=m)
                lobe["layer"] = first + lobe["layer"] if lobe["layer"] >= 0 else -1
                lobes.append(lobe)
        col = lambda k, dtype: np.array([lb[k] for lb in lobes], dtype)
        vec = lambda k: np.array([lb[k] for lb in lobes], np.float64).reshape(-1, 3)
        vol = lambda k: np.array([r.get("volume", {}).get(k, (0.0, 0.0, 0.0)) for r in rows], np.float64).reshape(-1, 3)
        slots = [dict(_SLOT_DEFAULTS, **s) for s in slots]
        texels, sizes, offsets, offset = [], [], [], 0
        for im in images:
            t = _rgba(im["texels"])
            texels.append(t.reshape(-1, 4))
            sizes.append((t.shape[1], t.shape[0]))
            offsets.append(offset)
            offset += t.shape[0] * t.shape[1]
        mats = Materials(
            kind=np.array([r.get("kind", MAT_DIFFUSE) for r in rows], np.int32),
            base_color=np.array([r.get("base_color", (0.8, 0.8, 0.8)) for r in rows], np.float64).reshape(-1, 3),
            emission=np.array([r.get("emission", (0, 0, 0)) for r in rows], np.float64).reshape(-1, 3),
            names=tuple(r.get("name", f"material{i}") for i, r in enumerate(rows)),
            normal_tex=np.array([r.get("normal_tex", -1) for r in rows], np.int32),
            normal_strength=np.array([r.get("normal_strength", 1.0) for r in rows], np.float64),
            lobe_material=col("material", np.int32),
            lobe_kind=col("kind", np.int32),
            lobe_weight=vec("weight"),
            lobe_color=vec("color"),
            lobe_color_tex=col("color_tex", np.int32),
            lobe_color_sqrt=col("color_sqrt", bool),
            lobe_tint=vec("tint"),
            lobe_tint_is_color=col("tint_is_color", bool),
            lobe_roughness=col("roughness", np.float64),
            lobe_roughness_tex=col("roughness_tex", np.int32),
            lobe_ior=col("ior", np.float64),
            lobe_fresnel=col("fresnel", np.int32),
            lobe_distribution=col("distribution", np.int32),
            lobe_exponent=col("exponent", np.float64),
            lobe_layer=col("layer", np.int32),
            lobe_opacity_tex=col("opacity_tex", np.int32),
            lobe_opacity_invert=col("opacity_invert", bool),
            lobe_film_thickness=col("film_thickness", np.float64),
            lobe_film_ior=col("film_ior", np.float64),
            lobe_refract_only=col("refract_only", bool),
            tex_image=np.array([s["image"] for s in slots], np.int32),
            tex_output=np.array([s["output"] for s in slots], np.int32),
            tex_extension=np.array([s["extension"] for s in slots], np.int32),
            tex_interpolation=np.array([s["interpolation"] for s in slots], np.int32),
            tex_transform=np.array([s["transform"] for s in slots], np.float64).reshape(-1, 2, 3),
            image_texels=np.concatenate(texels) if texels else np.zeros((0, 4), np.float32),
            image_size=np.array(sizes, np.int32).reshape(-1, 2),
            image_offset=np.array(offsets, np.int64),
            image_srgb=np.array([bool(im.get("srgb", False)) for im in images], bool),
            image_names=tuple(im.get("name", f"image{i}") for i, im in enumerate(images)),
            graphs=tuple(r.get("graph") for r in rows) if any(r.get("graph") is not None for r in rows) else (),
            holdout=np.array([r.get("holdout", 0.0) for r in rows], np.float64),
            volume_sigma_s=vol("sigma_s"), volume_sigma_a=vol("sigma_a"), volume_emission=vol("emission"),
            volume_g=np.array([r.get("volume", {}).get("g", 0.0) for r in rows], np.float64),
        )
        mats.check()
        return mats

    def check(self) -> None:
        """Raise EmberError if a lobe, material or slot refers to something that is not there."""
        n_slots, n_images, n_lobes = len(self.tex_image), len(self.image_size), self.n_lobes
        refs = [("normal map", self.normal_tex), ("colour", self.lobe_color_tex),
                ("roughness", self.lobe_roughness_tex), ("opacity", self.lobe_opacity_tex)]
        for what, idx in refs:
            if np.any(idx >= n_slots) or np.any(idx < -1):
                raise EmberError(f"A material's {what} texture refers to a missing texture slot.")
        if np.any(self.tex_image >= n_images) or np.any(self.tex_image < 0):
            raise EmberError("A texture slot refers to a missing image.")
        if np.any(self.lobe_layer >= n_lobes) or np.any(self.lobe_material >= len(self.kind)):
            raise EmberError("A material lobe refers to a missing lobe or material.")
        if n_lobes and np.any(np.diff(self.lobe_material) < 0):
            raise EmberError("Material lobes must be sorted by material.")


def _row_lobes(row: dict) -> list:
    if "lobes" in row:
        return list(row["lobes"])
    kind = row.get("kind", MAT_DIFFUSE)
    if kind == MAT_DIFFUSE:
        return [dict(kind=LOBE_DIFFUSE, color=tuple(row.get("base_color", (0.8, 0.8, 0.8))))]
    if kind == MAT_PHONG:
        if "phong" not in row:
            raise EmberError(f"Phong material '{row.get('name', '')}' needs phong = (kd, ks, n).")
        kd, ks, n = row["phong"]
        return [dict(kind=LOBE_PHONG, color=tuple(kd), tint=tuple(ks), exponent=float(n))]
    return []


def _rgba(texels) -> np.ndarray:
    """(H,W,C) with C in 1..4 -> (H,W,4) float32 (grey to RGB, alpha 1 where missing)."""
    t = np.asarray(texels, np.float32)
    if t.ndim == 2:
        t = t[:, :, None]
    h, w, c = t.shape
    out = np.ones((h, w, 4), np.float32)
    if c in (1, 2):
        out[:, :, :3] = t[:, :, :1]
        if c == 2:
            out[:, :, 3] = t[:, :, 1]
    else:
        out[:, :, :c] = t[:, :, :4]
    return out


@dataclass(frozen=True)
class Lights:
    """Analytic lights (emissive triangles are found from Materials at build time).

    kind (L,) LIGHT_*; position (L,3) centre; frame (L,3,3) rows = the light object's
    world x, y, z axes (unit); area lights and spots emit along -z, the sun shines along -z.
    size (L,2): RECT half-extents along x, y; DISK semi-axes along x, y.
    radius (L,): POINT/SPOT sphere radius (0 = delta light).
    soft (L,) bool: POINT/SPOT with Blender's "Soft Falloff" (its default): instead of a
    sphere, a disk of `radius` that faces the shading point (Cycles' point.h, is_sphere off).
    Le (L,3): POINT/SPOT with radius > 0, RECT, DISK, SUN with angle > 0: radiance
    W/(m^2 sr); POINT/SPOT with radius 0: intensity W/sr; SUN with angle 0: irradiance W/m^2.
    spot_cos_half (L,), spot_smooth (L,): Cycles' smoothstep((cos - cos_half)/smooth).
    sun_half_angle (L,) radians.
    visible (L,) bool: seen by camera rays (Cycles' visible_camera).
    ray_visibility (L,) uint8 RAY_* bits: the ray kinds that see the light (camera: as
    `visible`) and the BSDF lobes it lights (diffuse, glossy, transmission; Cycles' light
    object visibility).
    graphs: per light, its shader's node graph (engine/nodes/graph.py) where its emission
    varies over the light's samples (Light Falloff, IES, a texture of the direction), else
    None; empty: none at all. Le is then the light's radiance for a shader of emission 1,
    which engine/lights/light_shader.py multiplies by the program's value per sample and hit.
    matrix (L,3,3): the light object's world matrix's linear part (columns its x, y, z axes,
    scale included); with `position`, the object transform a light's shader reads.
    links (L,2) uint64: the masks of the receiver sets each light lights and of the blocker
    sets that shadow it (light and shadow linking; Mesh.link_sets), or None: all of them.
    """

    kind: np.ndarray
    position: np.ndarray
    frame: np.ndarray
    size: np.ndarray
    radius: np.ndarray
    soft: np.ndarray
    Le: np.ndarray
    spot_cos_half: np.ndarray
    spot_smooth: np.ndarray
    sun_half_angle: np.ndarray
    visible: np.ndarray
    names: tuple = ()
    ray_visibility: np.ndarray = None
    graphs: tuple = ()
    matrix: np.ndarray = None
    links: np.ndarray = None

    def __post_init__(self):
        if self.ray_visibility is None:
            vis = np.where(np.asarray(self.visible, bool), RAY_ALL, RAY_ALL & ~RAY_CAMERA).astype(np.uint8)
            object.__setattr__(self, "ray_visibility", vis.reshape(len(self.kind)))
        if self.matrix is None:
            object.__setattr__(self, "matrix", np.transpose(np.asarray(self.frame, np.float64), (0, 2, 1)))

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
            soft=np.array(g("soft", False), bool).reshape(n),
            Le=_f64(g("Le", (0, 0, 0)), (3,)),
            spot_cos_half=np.array(g("spot_cos_half", -1.0), np.float64).reshape(n),
            spot_smooth=np.array(g("spot_smooth", 0.0), np.float64).reshape(n),
            sun_half_angle=np.array(g("sun_half_angle", 0.0), np.float64).reshape(n),
            visible=np.array(g("visible", True), bool).reshape(n),
            names=tuple(g("name", "light")),
            ray_visibility=np.array([r.get("ray_visibility", RAY_ALL if r.get("visible", True) else RAY_ALL & ~RAY_CAMERA)
                                     for r in rows], np.uint8).reshape(n),
            graphs=tuple(r.get("graph") for r in rows) if any(r.get("graph") is not None for r in rows) else (),
            matrix=np.array([r["matrix"] if "matrix" in r else np.transpose(r.get("frame", eye)) for r in rows],
                            np.float64).reshape(n, 3, 3),
            links=np.array([r.get("links", (LINK_ALL, LINK_ALL)) for r in rows], np.uint64).reshape(n, 2)
            if any("links" in r for r in rows) else None,
        )

    def __len__(self) -> int:
        return len(self.kind)


ENV_PROJECTIONS = ("EQUIRECTANGULAR", "MIRROR_BALL")  # Cycles' Environment Texture projections


@dataclass(frozen=True)
class World:
    """Background radiance L(d) arriving along escaped rays of world direction d.

    color (3,): without an image or a graph the constant radiance W/(m^2 sr); with an image
    the factor it is multiplied by (Background colour x strength); with a graph the factor
    its radiance is multiplied by (1).
    image (H,W,3) float32 linear RGB, rows top-down (row 0 = the top of the picture), or None.
    graph: (Graph,), the world's Surface node graph (engine/nodes/graph.py) where it varies
    and is not an image the fast path reads (engine/lights/world.py evaluates it), else ().
    map_resolution: the width of a graph world's importance table (Cycles' Manual sampling;
    height = width / 2), 0 automatic (world.map_size), negative: no importance sampling
    (Cycles' sampling method None: only BSDF sampling finds the world).
    projection: one of ENV_PROJECTIONS; Cycles' mapping of directions to the image
    (engine/lights/environment.py).
    env_from_world (3,3): the image is looked up at direction env_from_world @ d (normalised),
    as Cycles' Mapping node transforms the lookup vector (rotation, scale).
    visible: seen by camera rays (Cycles' camera ray visibility and film transparency).
    ray_visibility: RAY_* bits of the ray kinds that see the world and the lobes it lights
    (its camera bit is ignored: `visible` says that).
    """

    color: np.ndarray = field(default_factory=lambda: np.zeros(3))
    visible: bool = True
    image: np.ndarray = None
    projection: str = "EQUIRECTANGULAR"
    env_from_world: np.ndarray = field(default_factory=lambda: np.eye(3))
    ray_visibility: int = RAY_ALL
    graph: tuple = ()
    map_resolution: int = 0


@dataclass(frozen=True)
class Camera:
    """Pinhole, orthographic or panoramic camera.

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
    # Thin lens (Cycles' camera.h): rays start on the aperture and meet the pinhole ray on the
    # plane focus_distance along the view axis. aperture_radius (m, 0 = pinhole) is Blender's
    # lens / (2 f-stop) (1 / (2 f-stop) for orthographic cameras); blades >= 3 make a regular
    # polygon inscribed in that radius, turned by blade_rotation (radians); aperture_ratio > 1
    # squeezes the aperture horizontally (anamorphic bokeh).
    aperture_radius: float = 0.0
    focus_distance: float = 10.0
    blades: int = 0
    blade_rotation: float = 0.0
    aperture_ratio: float = 1.0
    # Panoramic projection (engine/panorama.py): "" none, else one of its PANORAMAS, window then
    # (0, 1, 0, 1) (the image's (u, v)); its parameters in Cycles' units (see engine/panorama.py).
    panorama: str = ""
    fisheye_fov: float = np.pi
    fisheye_lens: float = 10.5
    sensor: tuple = (36.0, 24.0)
    pano_range: tuple = (-np.pi, np.pi, -0.5 * np.pi, 0.5 * np.pi)
    polynomial: tuple = (0.0, -0.02, 0.0, 0.0, 0.0)


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
                key = f"{part.name}.{f.name}"
                if key not in data.files and f.default is not dataclasses.MISSING:
                    continue  # saved before the field existed: its default
                v = data[key]
                if f.default is None and v.shape == () and v.dtype.kind == "f" and np.isnan(v):
                    v = None  # saved as NaN (an optional array that was absent)
                elif v.dtype == object:
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


def digest(value) -> str:
    """SHA-1 of a plain value (to_plain: nested dicts, tuples, arrays, scalars)."""
    import hashlib

    h = hashlib.sha1()

    def feed(key, value):
        h.update(key.encode())
        if isinstance(value, dict):
            for k in sorted(value):
                feed(f"{key}.{k}", value[k])
        elif isinstance(value, (list, tuple)):
            for i, v in enumerate(value):
                feed(f"{key}[{i}]", v)
        elif isinstance(value, np.ndarray) and value.dtype == object:
            feed(key, value.tolist())
        elif isinstance(value, np.ndarray):
            h.update(f"{value.dtype}{value.shape}".encode())
            h.update(np.ascontiguousarray(value).tobytes())
        elif dataclasses.is_dataclass(value):  # node graphs inside a part: their arrays in full
            feed(f"{key}:{type(value).__name__}", to_plain(value))
        else:
            h.update(repr(value).encode())

    feed("", value)
    return h.hexdigest()


_DIGESTS: dict = {}  # id(part) -> (weak reference to the part, its digest)


def part_digest(part) -> str:
    """digest(to_plain(part)), remembered for as long as the part lives: parts are frozen, and
    a viewport hashes the same 100 MB mesh at every update otherwise."""
    key = id(part)
    known = _DIGESTS.get(key)
    if known is not None and known[0]() is part:
        return known[1]
    value = digest(to_plain(part))
    _DIGESTS[key] = (weakref.ref(part, lambda _, key=key: _DIGESTS.pop(key, None)), value)
    return value


def part_digests(scene: "Scene") -> dict[str, str]:
    """Part name (mesh, materials, lights, world, camera, settings) -> digest: what changed
    between two renders (persistent data rebuilds only that)."""
    return {f.name: part_digest(getattr(scene, f.name)) for f in fields(scene)}


def scene_digest(scene: "Scene") -> str:
    """Digest of the scene's arrays and settings but SAMPLING_ONLY: equal digests mean the
    same image up to which samples of which pixels were taken (the seed is compared apart)."""
    plain = to_plain(scene)
    plain["settings"] = {k: v for k, v in plain["settings"].items() if k not in SAMPLING_ONLY}
    return digest(plain)


def scene_from_plain(data: dict) -> "Scene":
    parts = {"mesh": Mesh, "materials": Materials, "lights": Lights, "world": World,
             "camera": Camera, "settings": Settings}
    return Scene(**{name: cls(**data[name]) for name, cls in parts.items()})


# ---- origin ---------------------------------------------------------------------------------
# Beyond this distance from (0, 0, 0) a scene is rendered about its own centre: float32 (the
# vertices, Embree's rays) has 1 mm steps at 1e4 and 6 cm at 1e6, and ray origins are pushed
# off surfaces by a few of those steps, which moves light by centimetres to metres.
RECENTRE_BEYOND = 1000.0


def scene_origin(points, positions=(), camera=None) -> np.ndarray:
    """The point to render about: the centre of the bounds of `points` (N,3) (the geometry's
    bounding box corners), the lights' positions and the camera, rounded to whole metres (coordinates on a coarser grid stay exact), or 0
    when that centre is within RECENTRE_BEYOND of the world origin."""
    pts = [np.asarray(points, np.float64).reshape(-1, 3)]
    pts += [np.asarray(p, np.float64).reshape(1, 3) for p in positions]
    if camera is not None:
        pts.append(np.asarray(camera.world_from_camera, np.float64)[:3, 3].reshape(1, 3))
    pts = np.concatenate(pts)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) == 0:
        return np.zeros(3)
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    return np.round(centre) if np.max(np.abs(centre)) > RECENTRE_BEYOND else np.zeros(3)


def recentred(scene: Scene, origin=None, mesh_done: bool = False) -> Scene:
    """The same scene with `origin` (default: the centre of its vertices' bounds, see
    scene_origin) moved to (0, 0, 0): vertices, light positions and the camera shift
    together, directions (world, suns, normals) do not, so the image is unchanged but for
    float32 precision, which the shift restores far from the origin. mesh_done: the mesh
    is already shifted (MeshCollector.build did it in float64)."""
    if origin is None:
        v = scene.mesh.vertices
        v = v[np.all(np.isfinite(v), axis=1)] if len(v) else v
        bounds = [v.min(axis=0), v.max(axis=0)] if len(v) else []
        origin = scene_origin(np.array(bounds, np.float64).reshape(-1, 3), scene.lights.position, scene.camera)
    origin = np.asarray(origin, np.float64)
    if not np.any(origin):
        return scene
    mesh = scene.mesh
    if not mesh_done:
        mesh = dataclasses.replace(mesh, vertices=(mesh.vertices.astype(np.float64) - origin).astype(np.float32))
        if mesh.object_matrix is not None:
            matrix = mesh.object_matrix.copy()
            matrix[:, :3, 3] -= origin
            mesh = dataclasses.replace(mesh, object_matrix=matrix)
    lights = dataclasses.replace(scene.lights, position=scene.lights.position - origin)
    m = np.array(scene.camera.world_from_camera, np.float64)
    m[:3, 3] -= origin
    camera = dataclasses.replace(scene.camera, world_from_camera=m)
    settings = scene.settings.replace(origin=tuple(float(v) for v in np.add(scene.settings.origin, origin)))
    return dataclasses.replace(scene, mesh=mesh, lights=lights, camera=camera, settings=settings)
