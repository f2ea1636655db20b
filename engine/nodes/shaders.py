"""Shader nodes: BSDFs as closures of Ember's lobes (engine/bsdf/lobes/), as Cycles builds its
closures from them (svm/closure.h), and what Ember approximates.

A BSDF node makes closures whose kind is a lobe's ("diffuse", "microfacet", ...), whose weight
is its mixture weight and whose params are the lobe's inputs, per point or constant:
  color, tint (3), roughness (Blender's, alpha = roughness^2; Oren-Nayar's sigma), ior, exponent
  (Phong), fresnel ("none", "f82", "dielectric", "conductor", "coat": the microfacet lobe's
  model; on glass "dielectric" makes tint the Fresnel's F0 tint), distribution ("GGX",
  "MULTI_GGX", "BECKMANN", "ASHIKHMIN_SHIRLEY": the node's microfacet distribution; "ASHIKHMIN":
  the sheen lobe's velvet), normal (3, unnormalised world direction where the node's Normal is
  linked), layer (the tag of the closure this one lies under: it keeps 1 - that lobe's albedo,
  and what that lobe keeps: Cycles' closure layering), aspect and tangent (anisotropy, per
  point: alpha_x = alpha / aspect along the world direction tangent), film_thickness and
  film_ior (a thin film on the Fresnel), refract_only (Refraction BSDF).
Every closure has a tag unique within its node (the node's label and its part), so layers
survive Mix and Add Shader. A closure of constant weight at most CUTOFF is left out, as Cycles
leaves out closures lighter than CLOSURE_WEIGHT_CUTOFF.

`phong` (a prop the export sets on every BSDF node when the scene's Render Glossy with Phong
is on) shades Glossy, Metallic and Principled reflection with the seed's Phong lobe, exponent
n = 2 / alpha^2 - 2 with Beckmann alpha = roughness^2 (Mitsuba's mapping).
"""
from __future__ import annotations

import numpy as np

from .base import column, node, scalar, triple
from .closures import Closure
from .geometry import surface_tangent

CUTOFF = 1e-5  # Cycles' CLOSURE_WEIGHT_CUTOFF
MAX_PHONG_EXPONENT = 1e6  # Phong stays accurate up to here (engine/bsdf/phong.py)
ONES = np.ones(3)


def _closure(kind: str, weight, tag: str, **params) -> tuple:
    """(Closure,) unless its weight is a constant at most CUTOFF."""
    weight = triple(weight)
    if weight.ndim == 1 and weight.max() <= CUTOFF:
        return ()
    return (Closure(kind, weight, params, tag),)


def _normal(node, inputs) -> dict:
    """{"normal": the Normal input} where the node's Normal is linked, else {} (the shading
    normal stays the interpolated one)."""
    socket = node.input("Normal")
    return {"normal": triple(inputs["Normal"])} if socket is not None and socket.link is not None else {}


def f0_from_ior(eta):
    return ((eta - 1.0) / (eta + 1.0)) ** 2


def ior_from_f0(f0):
    r = np.sqrt(np.clip(f0, 0.0, 0.999999))
    return (1.0 + r) / (1.0 - r)


def phong_exponent(roughness):
    """Blender roughness -> Phong n = 2 / alpha^2 - 2 with Beckmann alpha = roughness^2, at most
    MAX_PHONG_EXPONENT (a mirror)."""
    alpha2 = np.maximum(scalar(roughness), 0.0) ** 4
    mirror = alpha2 * (MAX_PHONG_EXPONENT + 2.0) <= 2.0
    return np.where(mirror, MAX_PHONG_EXPONENT, 2.0 / np.where(mirror, 1.0, alpha2) - 2.0)


def _phong(weight, tag, kd, ks, roughness, **params) -> tuple:
    """The Phong lobe with kd + ks <= 1 per channel (scaled down where it is more)."""
    kd, ks = np.maximum(triple(kd), 0.0), np.maximum(triple(ks), 0.0)
    s = np.maximum(np.max(kd + ks, axis=-1), 1.0)
    return _closure("phong", weight, tag, color=kd / column(s), tint=ks / column(s),
                    exponent=phong_exponent(roughness), **params)


def _linked_or_set(node, name: str, default: float) -> bool:
    socket = node.input(name)
    return socket is not None and (socket.link is not None or float(np.max(socket.value)) != default)


_BECKMANN = ("ShaderNodeBsdfAnisotropic", "ShaderNodeBsdfGlossy", "ShaderNodeBsdfMetallic", "ShaderNodeBsdfGlass",
             "ShaderNodeBsdfRefraction")
_ASHIKHMIN_SHIRLEY = ("ShaderNodeBsdfAnisotropic", "ShaderNodeBsdfGlossy")


def _emits(node, inputs) -> bool:
    """Whether a Principled BSDF emits: Cycles' shader graph drops its emission where the
    Emission Strength or Color is unlinked and not above the cutoff (a negative constant
    strength emits nothing), and evaluates linked ones as they come, negative too (checked by
    baking with bpy's Cycles: tests/test_nodes_math.py)."""
    for name in ("Emission Strength", "Emission Color"):
        socket = node.input(name)
        if (socket is None or socket.link is None) and not np.max(inputs[name]) > CUTOFF:
            return False
    return True


def _distribution(node) -> str:
    """The node's distribution as a lobe parameter: Multiscatter GGX, GGX, Beckmann (Glossy,
    Metallic, Glass, Refraction) and Ashikhmin-Shirley (Glossy) where Blender offers them."""
    dist = node.prop("distribution", "GGX")
    if (dist == "MULTI_GGX" or (dist == "BECKMANN" and node.kind in _BECKMANN)
            or (dist == "ASHIKHMIN_SHIRLEY" and node.kind in _ASHIKHMIN_SHIRLEY)):
        return dist
    return "GGX"


def _distribution_notes(node) -> list:
    dist = node.prop("distribution", "GGX")
    return [] if dist in ("SHARP", _distribution(node)) else [f"{dist} distribution rendered as GGX"]


def _diffuse(weight, tag, color, roughness, **params) -> tuple:
    """Lambert, or Cycles' Oren-Nayar where the roughness varies or is at least 1e-5."""
    if np.ndim(roughness) or float(roughness) >= 1e-5:
        return _closure("oren_nayar", weight, tag, color=color, roughness=np.clip(roughness, 0.0, 1.0), **params)
    return _closure("diffuse", weight, tag, color=color, **params)


@node("ShaderNodeBsdfDiffuse", "Shader")
def diffuse(node, inputs, state):
    return {"BSDF": _diffuse(ONES, node.label, triple(inputs["Color"]), scalar(inputs["Roughness"]),
                             **_normal(node, inputs))}


# Anisotropy (svm/closure.h): the Glossy BSDF's Anisotropy a in [-0.99, 0.99] gives alpha_x =
# alpha (1 - a), alpha_y = alpha / (1 - a) for a >= 0, alpha / (1 + a) and alpha (1 + a) below;
# the Metallic and Principled BSDFs' a in [0, 1] gives alpha_x = alpha / s, alpha_y = alpha s
# with s = sqrt(1 - 0.9 a). The lobe takes the aspect s of alpha_x = alpha / s, alpha_y = alpha
# s, and the tangent: the Tangent input, or where it is unlinked Cycles' default (its shader
# graph links the Geometry node's Tangent: the radial tangent about the object's Z through the
# generated coordinates), turned about the normal by Rotation x 2 pi.

def _aspect_glossy(a):
    a = np.clip(a, -0.99, 0.99)
    return np.where(np.abs(a) <= 1e-4, 1.0, np.where(a < 0.0, 1.0 + a, 1.0 / (1.0 - np.where(a < 0.0, 0.0, a))))


def _aspect_principled(a):
    return np.sqrt(1.0 - 0.9 * np.clip(a, 0.0, 1.0))


_ANISOTROPY = {"ShaderNodeBsdfAnisotropic": ("Anisotropy", "Rotation", _aspect_glossy),
               "ShaderNodeBsdfMetallic": ("Anisotropy", "Rotation", _aspect_principled),
               "ShaderNodeBsdfPrincipled": ("Anisotropic", "Anisotropic Rotation", _aspect_principled)}


def _anisotropic(node) -> bool:
    """The node may be anisotropic somewhere: its anisotropy is linked or set."""
    name = _ANISOTROPY[node.kind][0]
    return not node.prop("phong", False) and _linked_or_set(node, name, 0.0)


def _anisotropy_reads(node, outputs):
    """The state an anisotropic node reads: the normal, and the default tangent's inputs."""
    if not _anisotropic(node):
        return ()
    socket = node.input("Tangent")
    return ("N",) if socket is not None and socket.link is not None else ("N", "generated", "object_from_world")


def _anisotropy(node, inputs, state, normal: dict) -> dict:
    """{"aspect": (N,), "tangent": (N,3)} per point, or {} where the node is isotropic."""
    if not _anisotropic(node):
        return {}
    name, rotation, aspect_of = _ANISOTROPY[node.kind]
    base = state.unshifted
    n = base.N
    if "normal" in normal:
        n = np.broadcast_to(normal["normal"], (state.n, 3))
        n = n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-300)
    socket = node.input("Tangent")
    if socket is not None and socket.link is not None:
        t = np.broadcast_to(triple(inputs["Tangent"]), (state.n, 3))
    else:
        t = surface_tangent(base.generated, base.N, base.object_from_world)
    angle = column(np.broadcast_to(2.0 * np.pi * scalar(inputs[rotation]), (state.n,)))
    # Rodrigues' rotation about n, as Cycles' rotate_around_axis.
    t = t * np.cos(angle) + np.cross(n, t) * np.sin(angle) + n * (np.sum(n * t, axis=-1, keepdims=True)
                                                                  * (1.0 - np.cos(angle)))
    return {"aspect": np.broadcast_to(aspect_of(scalar(inputs[name])), (state.n,)).copy(), "tangent": t}


def _glossy_notes(node) -> list:
    notes = _distribution_notes(node)
    if _anisotropic(node) and node.prop("distribution", "GGX") == "ASHIKHMIN_SHIRLEY":
        notes.append("anisotropy of Ashikhmin-Shirley rendered isotropic")
    return notes


@node("ShaderNodeBsdfAnisotropic", "Shader", notes=_glossy_notes, reads=_anisotropy_reads)
def glossy(node, inputs, state):
    color, rough, normal = triple(inputs["Color"]), scalar(inputs["Roughness"]), _normal(node, inputs)
    if node.prop("phong", False):
        return {"BSDF": _phong(ONES, node.label, np.zeros(3), color, rough, **normal)}
    return {"BSDF": _closure("microfacet", ONES, node.label, fresnel="none", color=color, roughness=rough,
                             distribution=_distribution(node), **normal, **_anisotropy(node, inputs, state, normal))}


def _film(inputs, thickness: str, ior: str) -> dict:
    """A thin film's parameters where its thickness may exceed Cycles' cutoff (0.1 nm)."""
    d = np.maximum(scalar(inputs[thickness]), 0.0)
    if not np.ndim(d) and float(d) <= 0.1:
        return {}
    return {"film_thickness": d, "film_ior": np.maximum(scalar(inputs[ior]), 1e-5)}


@node("ShaderNodeBsdfMetallic", "Shader", notes=_distribution_notes, reads=_anisotropy_reads)
def metallic(node, inputs, state):
    """Cycles' Metallic BSDF: F82 tint (Base Color, Edge Tint) or the physical conductor of
    complex index IOR + i Extinction; thin film and anisotropy on either."""
    rough, normal = scalar(inputs["Roughness"]), _normal(node, inputs)
    if node.prop("fresnel_type", "F82") == "F82":
        color, tint, model = np.clip(triple(inputs["Base Color"]), 0.0, 1.0), np.clip(triple(inputs["Edge Tint"]), 0, 1), "f82"
    else:
        color, tint, model = np.maximum(triple(inputs["IOR"]), 0.0), np.maximum(triple(inputs["Extinction"]), 0.0), \
            "conductor"
    if node.prop("phong", False):
        f0 = color if model == "f82" else ((color - 1) ** 2 + tint ** 2) / np.maximum((color + 1) ** 2 + tint ** 2, 1e-12)
        return {"BSDF": _phong(ONES, node.label, np.zeros(3), f0, rough, **normal)}
    film = _film(inputs, "Thin Film Thickness", "Thin Film IOR") if "Thin Film Thickness" in inputs else {}
    return {"BSDF": _closure("microfacet", ONES, node.label, fresnel=model, color=color, tint=tint,
                             roughness=rough, distribution=_distribution(node), **normal, **film,
                             **_anisotropy(node, inputs, state, normal))}


@node("ShaderNodeBsdfGlass", "Shader", notes=_distribution_notes)
def glass(node, inputs, state):
    """Cycles' Glass BSDF: reflection and refraction tinted by Color, a thin film on its Fresnel."""
    color = triple(inputs["Color"])
    film = _film(inputs, "Thin Film Thickness", "Thin Film IOR") if "Thin Film Thickness" in inputs else {}
    return {"BSDF": _closure("dielectric", ONES, node.label, color=color, tint=color,
                             roughness=scalar(inputs["Roughness"]), ior=np.maximum(scalar(inputs["IOR"]), 1e-5),
                             distribution=_distribution(node), **_normal(node, inputs), **film)}


@node("ShaderNodeBsdfRefraction", "Shader", notes=_distribution_notes)
def refraction(node, inputs, state):
    """Cycles' Refraction BSDF: the refraction of a dielectric interface alone, without its
    Fresnel factor (none under total internal reflection)."""
    color = triple(inputs["Color"])
    return {"BSDF": _closure("dielectric", ONES, node.label, color=color, tint=np.zeros(3), refract_only=True,
                             roughness=scalar(inputs["Roughness"]), ior=np.maximum(scalar(inputs["IOR"]), 1e-5),
                             distribution=_distribution(node), **_normal(node, inputs))}


@node("ShaderNodeBsdfTransparent", "Shader")
def transparent(node, inputs, state):
    return {"BSDF": _closure("transparent", ONES, node.label, color=triple(inputs["Color"]))}


@node("ShaderNodeHoldout", "Shader")
def holdout(node, inputs, state):
    """No light (its share renders black) and a hole in the alpha of camera rays (Materials.holdout)."""
    return {"Holdout": (Closure("holdout", ONES, {}, node.label),)}


_PRINCIPLED_IGNORED = (("subsurface", "Subsurface Weight", 0.0),)


def _principled_notes(node) -> list:
    notes = _distribution_notes(node)
    notes += [f"{label} ignored" for label, name, default in _PRINCIPLED_IGNORED if _linked_or_set(node, name, default)]
    layered = _linked_or_set(node, "Coat Weight", 0.0) or _linked_or_set(node, "Sheen Weight", 0.0)
    if layered and node.prop("phong", False):
        notes.append("coat and sheen ignored with Phong")
    if _linked_or_set(node, "Coat Weight", 0.0) and node.input("Coat Normal") is not None \
            and node.input("Coat Normal").link is not None:
        notes.append("Coat Normal ignored (the coat shades with Normal)")
    if layered and _linked_or_set(node, "Emission Strength", 0.0):
        notes.append("emission not dimmed by the coat and sheen")
    return notes


@node("ShaderNodeBsdfPrincipled", "Shader", notes=_principled_notes, reads=_anisotropy_reads)
def principled(node, inputs, state):
    """Cycles' Principled BSDF (svm/closure.h), top layer first: transparency (1 - Alpha);
    then, of what Alpha keeps, sheen and coat (_sheen_and_coat) and under them metallic (an
    F82 conductor: F0 = Base Color, F82 tint = Specular Tint), transmission (glass whose
    refraction is tinted sqrt(Base Color), its Fresnel's F0 tinted by Specular Tint) of what
    metallic leaves, and a dielectric specular layer (Fresnel of the IOR rescaled by Specular
    IOR Level, tinted by Specular Tint) over a diffuse base of the rest; Emission Color x
    Strength. Anisotropy on the metal and the specular (Cycles' glass is isotropic), a thin
    film on all three. Cycles 5.0 leaves the base's IOR as it is under a coat (svm and osl
    alike), and so does Ember."""
    label = node.label
    base = triple(inputs["Base Color"])
    rough = scalar(inputs["Roughness"])
    metal = np.clip(scalar(inputs["Metallic"]), 0.0, 1.0)
    transmission = np.clip(scalar(inputs["Transmission Weight"]), 0.0, 1.0)
    ior = np.maximum(scalar(inputs["IOR"]), 1e-5)
    level = np.maximum(scalar(inputs["Specular IOR Level"]), 0.0)
    spec_tint = np.maximum(triple(inputs["Specular Tint"]), 0.0)
    alpha = np.clip(scalar(inputs["Alpha"]), 0.0, 1.0)
    normal = _normal(node, inputs)
    dist = _distribution(node)
    film = _film(inputs, "Thin Film Thickness", "Thin Film IOR")
    aniso = _anisotropy(node, inputs, state, normal)
    w = ONES
    out = _closure("transparent", w * column(1.0 - alpha), label + "/alpha", color=ONES)
    w = w * column(alpha)
    emission = _closure("emission", w * triple(inputs["Emission Color"]) * column(inputs["Emission Strength"]),
                        label + "/emission") if _emits(node, inputs) else ()
    f0 = f0_from_ior(ior)
    rescaled = level != 0.5  # Specular IOR Level rescales F0 and the IOR with it
    f0 = np.where(rescaled, f0 * 2.0 * level, f0)
    eta = np.where(rescaled, np.where(f0 > 0, ior_from_f0(f0), 1.0), ior)
    eta = np.where(rescaled & (ior < 1.0), 1.0 / eta, eta)
    if node.prop("phong", False):
        ks = column(metal) * np.clip(base, 0, 1) + column((1 - metal) * (1 - transmission) * f0) * spec_tint
        kd = column((1 - metal) * (1 - transmission)) * base * column(1 - f0)
        out += _phong(w, label + "/phong", kd, ks, rough, **normal)
        out += _closure("dielectric", w * column((1 - metal) * transmission), label + "/transmission",
                        color=np.sqrt(np.clip(base, 0.0, 1.0)), tint=ONES, roughness=rough, ior=ior, **normal)
        return {"BSDF": out + emission}
    layers = _sheen_and_coat(inputs, w, label, normal)
    out += layers
    under = {"layer": layers[-1].tag} if layers else {}
    out += _closure("microfacet", w * column(metal), label + "/metallic", fresnel="f82", color=np.clip(base, 0, 1),
                    tint=np.minimum(spec_tint, 1.0), roughness=rough, distribution=dist, **under, **normal, **film,
                    **aniso)
    w = w * column(1.0 - metal)
    out += _closure("dielectric", w * column(transmission), label + "/transmission",
                    color=np.sqrt(np.clip(base, 0.0, 1.0)), tint=spec_tint, fresnel="dielectric", roughness=rough,
                    ior=ior, distribution=dist, **under, **normal, **film)
    w = w * column(1.0 - transmission)
    top = ()
    if np.ndim(eta) or eta != 1.0 or film:
        top = _closure("microfacet", w, label + "/specular", fresnel="dielectric", tint=spec_tint,
                       roughness=rough, ior=eta, distribution=dist, **under, **normal, **film, **aniso)
    layer = {"layer": top[0].tag} if top else under
    out += top + _diffuse(w, label + "/base", base, scalar(inputs["Diffuse Roughness"]) if "Diffuse Roughness" in inputs
                          else 0.0, **layer, **normal)
    return {"BSDF": out + emission}


def _sheen_and_coat(inputs, w, label: str, normal: dict) -> tuple:
    """The Principled BSDF's top layers, top first (svm/closure.h): a microfiber sheen of colour
    Sheen Weight x Sheen Tint, then a coat (Multiscatter GGX, the exact dielectric Fresnel of
    Coat IOR >= 1 times Coat Weight), each lying under the one above it; the lobes under them
    keep what they leave (the coat's Coat Tint included). Both have the closure weight w: the
    Sheen and Coat Weights are in their colours, where their albedos (and so the layering) see
    them, as in Cycles' closure weights."""
    sheen_w = np.maximum(scalar(inputs["Sheen Weight"]), 0.0)
    coat_w = np.maximum(scalar(inputs["Coat Weight"]), 0.0)
    out = ()
    if np.ndim(sheen_w) or sheen_w > CUTOFF:
        out += _closure("sheen", w, label + "/sheen", color=column(sheen_w) * np.maximum(triple(inputs["Sheen Tint"]), 0.0),
                        roughness=np.clip(scalar(inputs["Sheen Roughness"]), 0.0, 1.0), **normal)
    if np.ndim(coat_w) or coat_w > CUTOFF:
        under = {"layer": out[-1].tag} if out else {}
        out += _closure("microfacet", w, label + "/coat", fresnel="coat", color=column(coat_w) * ONES,
                        tint=np.maximum(triple(inputs["Coat Tint"]), 0.0),
                        roughness=np.clip(scalar(inputs["Coat Roughness"]), 0.0, 1.0),
                        ior=np.maximum(scalar(inputs["Coat IOR"]), 1.0), distribution="MULTI_GGX", **under, **normal)
    return out


@node("ShaderNodeBsdfSheen", "Shader")
def sheen(node, inputs, state):
    """Cycles' Sheen BSDF: microfiber (an LTC lobe scaled by its albedo) or Ashikhmin velvet."""
    velvet = {"distribution": "ASHIKHMIN"} if node.prop("distribution", "MICROFIBER") == "ASHIKHMIN" else {}
    return {"BSDF": _closure("sheen", triple(inputs["Color"]), node.label, color=ONES,
                             roughness=np.clip(scalar(inputs["Roughness"]), 0.0, 1.0), **velvet,
                             **_normal(node, inputs))}


@node("ShaderNodeBsdfTranslucent", "Shader")
def translucent(node, inputs, state):
    return {"BSDF": _closure("translucent", ONES, node.label, color=triple(inputs["Color"]), **_normal(node, inputs))}


@node("ShaderNodeBsdfToon", "Shader")
def toon(node, inputs, state):
    """Cycles' Toon: Size and Smooth as fractions of pi/2 (engine/bsdf/lobes/toon.py)."""
    return {"BSDF": _closure("toon", ONES, node.label, color=triple(inputs["Color"]),
                             roughness=np.clip(scalar(inputs["Size"]), 0.0, 1.0),
                             exponent=np.clip(scalar(inputs["Smooth"]), 0.0, 1.0),
                             component=node.prop("component", "DIFFUSE"), **_normal(node, inputs))}


# Shaders Ember does not build yet: the diffuse of their Color (grey without one), with a note.
_APPROXIMATED = ("ShaderNodeBsdfHair",
                 "ShaderNodeBsdfHairPrincipled", "ShaderNodeSubsurfaceScattering", "ShaderNodeBsdfRayPortal",
                 "ShaderNodeEeveeSpecular")


def _as_diffuse(node, inputs, state):
    color = triple(inputs["Color"]) if "Color" in inputs else np.full(3, 0.8)
    out = node.outputs[0][0] if node.outputs else "BSDF"
    return {out: _closure("diffuse", ONES, node.label, color=color, **_normal(node, inputs))}


APPROXIMATED = tuple(node(kind, "Shader", notes=lambda node: ["rendered as diffuse"])(_as_diffuse)
                     for kind in _APPROXIMATED)

NODES = (diffuse, glossy, metallic, glass, refraction, transparent, holdout, principled, sheen, translucent,
         toon) + APPROXIMATED
