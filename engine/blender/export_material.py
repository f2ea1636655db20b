"""Materials -> one global table (Materials): shader nodes as lobes, textures, Phong.

The active Material Output (target ALL or CYCLES) Surface link is converted the way Cycles
builds its closures (blender/blender intern/cycles/kernel/svm/closure.h):

  Diffuse BSDF       Color -> diffuse (Roughness > 0: Cycles' energy-preserving Oren-Nayar)
  Glossy BSDF        Color, Roughness -> microfacet reflection with F = Color (no Fresnel, as
                     Cycles): Multiscatter GGX (Cycles' energy factor on GGX,
                     engine/bsdf/multiscatter.py), GGX, Beckmann, Ashikhmin-Shirley
  Metallic BSDF      Base Color (F0), Edge Tint (F82), Roughness -> GGX conductor (F82 tint);
                     Physical Conductor (IOR / Extinction), anisotropy, thin film: the node
                     evaluator (engine/nodes/shaders.py)
  Glass BSDF         Color, Roughness, IOR -> dielectric, exact Fresnel, sharp at roughness 0
  Refraction BSDF    the node evaluator (refraction only)
  Transparent BSDF   Color -> straight pass-through
  Emission           Color x Strength -> emission (two-sided, as Cycles' mesh emission)
  Mix Shader / Add Shader   weighted sums (a linked Fac: its default value, approximated)
  Principled BSDF    as Cycles 4+: metallic F82 conductor (F0 = Base Color, F82 = Specular
                     Tint); transmission dielectric (tint sqrt(Base Color)); dielectric
                     specular (exact Fresnel of IOR, Specular IOR Level, Specular Tint) over a
                     diffuse base weighted by 1 - the specular layer's albedo; Emission Color x
                     Strength; Alpha as stochastic transparency; Normal. Coat, sheen,
                     subsurface (-> the diffuse base), diffuse roughness are approximated
                     (ignored); anisotropy, thin film and Specular Tint on transmission go
                     through the node evaluator
  other shader nodes the nearest supported closure: diffuse of their Color input

Inputs may be constants, RGB / Value nodes, or Image Texture nodes (Color or Alpha output)
fed by UVs: nothing (UV), Texture Coordinate UV, UV Map (the active render map) or a Mapping
node (Point / Texture, constant inputs) on those. Normal inputs take a Normal Map node (tangent
space) on an image. Any other input node: the socket's own value (approximated). Each material
reports once which nodes it approximated. Socket values are scene-linear already.

With scene.ember.glossy_as_phong, Glossy, Metallic and Principled reflection become Ember's
Phong lobe (roughness r -> Beckmann alpha = r^2 -> n = 2 / alpha^2 - 2, Mitsuba's mapping).
material.ember.model == 'PHONG' replaces the node tree with a Phong material.
"""
from __future__ import annotations

import numpy as np

from ..scene import (DIST_GGX, DISTRIBUTIONS, EXT_CLIP, EXT_EXTEND, EXT_MIRROR, EXT_REPEAT, FRESNEL_DIELECTRIC,
                     FRESNEL_F82, FRESNEL_NONE, INTERP_CLOSEST, INTERP_LINEAR, LOBE_DIELECTRIC, LOBE_DIFFUSE,
                     LOBE_MICROFACET, LOBE_OREN_NAYAR, LOBE_PHONG, LOBE_TRANSPARENT, MAT_DIFFUSE, MAT_EMISSION_ONLY,
                     MAT_NODES, MAT_PHONG, TEX_ALPHA, TEX_COLOR, Materials)
from ..nodes.bump import bump_from_displacement
from ..nodes.default_surface import default_surface
from ..nodes.hits import provides
from ..nodes.material import compiled_material, with_phong
from ..textures import LUMINANCE
from .export_nodes import export_graph
from .export_volume import medium_of
from .sockets import follow_link, follow_socket  # noqa: F401 (others import them from here)

GREY = (0.8, 0.8, 0.8)
DEFAULT_NAME = "default"
CUTOFF = 1e-5  # Cycles' CLOSURE_WEIGHT_CUTOFF: lobes lighter than this are left out
MAX_PHONG_EXPONENT = 1e6  # Phong stays accurate up to here (engine/bsdf/phong.py)
_EXTENSIONS = {"REPEAT": EXT_REPEAT, "EXTEND": EXT_EXTEND, "CLIP": EXT_CLIP, "MIRROR": EXT_MIRROR}
_IDENTITY_UV = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
_LINEAR_SPACES = {"Non-Color", "Linear Rec.709", "Linear", "Raw", "Linear CIE-XYZ E", "Generic Data"}


# --- node helpers (shared with lights and world) ------------------------------------------
def find_output(tree, bl_idname: str):
    """The output node Cycles uses: the active one among targets ALL/CYCLES, else the
    first such node, else None."""
    outs = [n for n in tree.nodes if n.bl_idname == bl_idname
            and getattr(n, "target", "ALL") in ("ALL", "CYCLES")]
    for n in outs:
        if getattr(n, "is_active_output", False):
            return n
    return outs[0] if outs else None


def rgb(socket) -> tuple:
    return tuple(float(c) for c in socket.default_value[:3])


def f0_from_ior(eta: float) -> float:
    return ((eta - 1.0) / (eta + 1.0)) ** 2


def ior_from_f0(f0: float) -> float:
    r = np.sqrt(min(max(f0, 0.0), 0.999999))
    return float((1.0 + r) / (1.0 - r))


def phong_exponent(roughness: float) -> float:
    """Blender roughness -> Phong n = 2 / alpha^2 - 2 with Beckmann alpha = roughness^2,
    at most MAX_PHONG_EXPONENT (a mirror)."""
    alpha2 = max(float(roughness), 0.0) ** 4
    if alpha2 * (MAX_PHONG_EXPONENT + 2.0) <= 2.0:
        return MAX_PHONG_EXPONENT
    return 2.0 / alpha2 - 2.0


# --- images and texture slots -----------------------------------------------------------
class _Textures:
    """Images (read once per datablock) and texture slots shared by all materials."""

    def __init__(self):
        self.images: list[dict] = []
        self.slots: list[dict] = []
        self._image_index: dict[int, int] = {}
        self._slot_index: dict[tuple, int] = {}

    def image(self, img, note) -> int | None:
        key = img.as_pointer()
        if key in self._image_index:
            return self._image_index[key]
        w, h = (int(v) for v in img.size)
        if w * h == 0:
            note(f"image '{img.name}' has no pixels (missing file?)")
            return None
        texels = np.empty(w * h * img.channels, np.float32)
        img.pixels.foreach_get(texels)
        texels = texels.reshape(h, w, img.channels)
        space = img.colorspace_settings.name
        srgb = False
        if space == "sRGB":
            if img.is_float:  # Cycles converts float images to linear when it loads them
                texels[:, :, :3] = _srgb_to_linear(texels[:, :, :3])
            else:
                srgb = True  # bytes: interpolated as stored, decoded after (textures.py)
        elif space not in _LINEAR_SPACES:
            note(f"image '{img.name}' colour space '{space}' read as linear")
        self._image_index[key] = len(self.images)
        self.images.append(dict(texels=texels, srgb=srgb, name=img.name))
        return self._image_index[key]

    def slot(self, image: int, output: int, extension: int, interpolation: int, transform) -> int:
        key = (image, output, extension, interpolation, tuple(np.round(np.ravel(transform), 12)))
        if key not in self._slot_index:
            self._slot_index[key] = len(self.slots)
            self.slots.append(dict(image=image, output=output, extension=extension,
                                   interpolation=interpolation, transform=np.array(transform)))
        return self._slot_index[key]


def _srgb_to_linear(c):
    return np.where(c < 0.04045, np.maximum(c, 0.0) / 12.92, ((np.maximum(c, 0.04045) + 0.055) / 1.055) ** 2.4)


# --- one material's node tree -----------------------------------------------------------
class _Converter:
    """Converts one node tree into lobes, emission and a normal map, noting approximations."""

    def __init__(self, mat, textures: _Textures, phong: bool):
        self.mat = mat
        self.textures = textures
        self.phong = phong
        self.lobes: list[dict] = []
        self.emission = np.zeros(3)
        self.normal = None  # (slot, strength)
        self.notes: list[str] = []
        self.base_color = None

    def note(self, text: str) -> None:
        if text not in self.notes:
            self.notes.append(text)

    # inputs ---------------------------------------------------------------------------------
    def color(self, node, name):
        """(constant colour (3,), texture slot or -1) of input `name`."""
        sock = node.inputs[name]
        src, out = follow_socket(sock)
        if src is None:
            return np.array(rgb(sock)), -1
        if src.bl_idname == "ShaderNodeRGB":
            return np.array(rgb(src.outputs[0])), -1
        if src.bl_idname == "ShaderNodeValue":
            return np.full(3, float(src.outputs[0].default_value)), -1
        if src.bl_idname == "ShaderNodeTexImage":
            slot = self.image_slot(src, out)
            if slot is not None:
                return np.array(rgb(sock)), slot
            return np.array([1.0, 0.0, 1.0]), -1  # Cycles' missing-texture pink
        self.note(f"'{src.name}' ({src.bl_label}) on {node.name}.{name} (used the input's own value)")
        return np.array(rgb(sock)), -1

    def value(self, node, name):
        """(constant, texture slot or -1) of a float input `name`."""
        sock = node.inputs[name]
        src, out = follow_socket(sock)
        if src is None:
            return float(sock.default_value), -1
        if src.bl_idname == "ShaderNodeValue":
            return float(src.outputs[0].default_value), -1
        if src.bl_idname == "ShaderNodeRGB":
            return float(np.dot(rgb(src.outputs[0]), LUMINANCE)), -1
        if src.bl_idname == "ShaderNodeTexImage":
            slot = self.image_slot(src, out)
            if slot is not None:
                return float(sock.default_value), slot
        else:
            self.note(f"'{src.name}' ({src.bl_label}) on {node.name}.{name} (used the input's own value)")
        return float(sock.default_value), -1

    def constant(self, node, name) -> float:
        """A float input used as a constant (a linked one is approximated by its own value)."""
        v, slot = self.value(node, name)
        if slot >= 0:
            self.note(f"texture on {node.name}.{name} (used the input's own value)")
        return v

    def image_slot(self, tex, out) -> int | None:
        img = tex.image
        if img is None:
            self.note(f"'{tex.name}' has no image (pink, as Cycles)")
            return None
        image = self.textures.image(img, self.note)
        if image is None:
            return None
        if tex.projection != "FLAT":
            self.note(f"'{tex.name}' projection {tex.projection} (used flat)")
        interp = INTERP_CLOSEST if tex.interpolation == "Closest" else INTERP_LINEAR
        if tex.interpolation not in ("Closest", "Linear"):
            self.note(f"'{tex.name}' {tex.interpolation} interpolation (used linear)")
        transform = self.uv_transform(tex)
        output = TEX_ALPHA if out is not None and out.name == "Alpha" else TEX_COLOR
        return self.textures.slot(image, output, _EXTENSIONS.get(tex.extension, EXT_REPEAT), interp, transform)

    def uv_transform(self, tex) -> np.ndarray:
        """(2,3) affine map from mesh UV to the image's lookup UV."""
        src, out = follow_socket(tex.inputs["Vector"])
        if src is not None and src.bl_idname == "ShaderNodeMapping":
            self.check_uv_source(*follow_socket(src.inputs["Vector"]), node=src)
            return self.mapping(src)
        if src is not None:
            self.check_uv_source(src, out, node=tex)
        return _IDENTITY_UV

    def check_uv_source(self, src, out, node) -> None:
        """Note texture coordinates other than the active render UV map (used instead)."""
        if src is None:
            if node.bl_idname == "ShaderNodeMapping":  # an unlinked Mapping vector is (0, 0, 0)
                self.note(f"'{node.name}' without input coordinates (used UV)")
        elif src.bl_idname == "ShaderNodeUVMap":
            if src.uv_map:
                self.note(f"'{src.name}' UV map '{src.uv_map}' (used the active render UV map)")
        elif not (src.bl_idname == "ShaderNodeTexCoord" and out is not None and out.name == "UV"):
            self.note(f"'{src.name}' ({src.bl_label}) as texture coordinates (used UV)")

    def mapping(self, node) -> np.ndarray:
        """Mapping node (Point or Texture, constant inputs) restricted to z = 0 -> (2,3)."""
        kind = node.vector_type
        if kind not in ("POINT", "TEXTURE"):
            self.note(f"'{node.name}' mapping type {kind} (ignored)")
            return _IDENTITY_UV
        for name in ("Location", "Rotation", "Scale"):
            if node.inputs[name].is_linked:
                self.note(f"'{node.name}' linked {name} (used its own value)")
        loc = np.array(node.inputs["Location"].default_value[:3], np.float64)
        rot = np.array(node.inputs["Rotation"].default_value[:3], np.float64)
        scale = np.array(node.inputs["Scale"].default_value[:3], np.float64)
        cx, cy, cz = np.cos(rot)
        sx, sy, sz = np.sin(rot)
        # Euler XYZ: R = Rz Ry Rx (Blender's convention for the Mapping node).
        Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
        Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
        Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
        M = np.eye(4)
        if kind == "POINT":  # out = R (S in) + L
            M[:3, :3] = Rz @ Ry @ Rx @ np.diag(scale)
            M[:3, 3] = loc
        else:  # TEXTURE: the inverse of POINT
            A = Rz @ Ry @ Rx @ np.diag(scale)
            try:
                Ainv = np.linalg.inv(A)
            except np.linalg.LinAlgError:
                self.note(f"'{node.name}' singular texture mapping (ignored)")
                return _IDENTITY_UV
            M[:3, :3] = Ainv
            M[:3, 3] = -Ainv @ loc
        return np.array([[M[0, 0], M[0, 1], M[0, 3]], [M[1, 0], M[1, 1], M[1, 3]]])

    def normal_input(self, node, name="Normal"):
        """Record a Normal Map feeding `name` (one per material)."""
        if name not in node.inputs:
            return
        src, _ = follow_socket(node.inputs[name])
        if src is None:
            return
        if src.bl_idname != "ShaderNodeNormalMap":
            self.note(f"'{src.name}' ({src.bl_label}) on {node.name}.{name} (ignored)")
            return
        if src.space != "TANGENT":
            self.note(f"'{src.name}' {src.space} space (ignored)")
            return
        if src.uv_map:  # the tangents of the render UV map only here (the node evaluator reads any)
            self.note(f"'{src.name}' on UV map '{src.uv_map}' (read as the render UV map)")
        color, slot = self.color(src, "Color")
        if slot < 0:  # a constant colour still tilts the normal: only the node evaluator has it
            self.note(f"'{src.name}' without an image (ignored)")
            return
        strength = self.constant(src, "Strength")
        if self.normal is not None and self.normal != (slot, strength):
            self.note("several normal maps (used the first)")
            return
        self.normal = (slot, strength)

    # closures -------------------------------------------------------------------------------
    def add(self, w, **lobe) -> int:
        """Append a lobe with weight w (3,) unless negligible; its index or -1."""
        w = np.asarray(w, np.float64)
        if w.max() <= CUTOFF:
            return -1
        self.lobes.append(dict(lobe, weight=tuple(w)))
        return len(self.lobes) - 1

    def shader(self, node, w, depth=0):
        """Add the closure of `node` (a shader node) with weight w (3,)."""
        if node is None or w.max() <= 0:
            return
        if node.mute:
            self.note(f"'{node.name}' is muted (black)")
            return
        if depth > 64:
            self.note("shader nodes nested too deep")
            return
        kind = node.bl_idname
        if kind == "ShaderNodeMixShader":
            fac = float(np.clip(self.constant(node, "Fac"), 0.0, 1.0))
            self.shader(follow_link(node.inputs[1]), w * (1.0 - fac), depth + 1)
            self.shader(follow_link(node.inputs[2]), w * fac, depth + 1)
        elif kind == "ShaderNodeAddShader":
            self.shader(follow_link(node.inputs[0]), w, depth + 1)
            self.shader(follow_link(node.inputs[1]), w, depth + 1)
        elif kind == "ShaderNodeBsdfDiffuse":
            color, tex = self.color(node, "Color")
            self.normal_input(node)
            self.base_color = color if self.base_color is None else self.base_color
            self.add(w, color=tuple(color), color_tex=tex, **self.diffuse_roughness(node, "Roughness"))
        elif kind in ("ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic"):
            self.glossy(node, w)
        elif kind == "ShaderNodeBsdfMetallic":
            self.metallic(node, w)
        elif kind in ("ShaderNodeBsdfGlass", "ShaderNodeBsdfRefraction"):
            if kind == "ShaderNodeBsdfRefraction":
                self.note(f"'{node.name}' Refraction BSDF (rendered as Glass: adds the Fresnel reflection)")
            dist = self.distribution(node, reflection=False)
            if self._set(node, "Thin Film Thickness"):
                self.note(f"'{node.name}' thin film (ignored)")
            color, tex = self.color(node, "Color")
            rough, rtex = self.value(node, "Roughness")
            ior = max(self.constant(node, "IOR"), 1e-5)
            self.normal_input(node)
            self.add(w, kind=LOBE_DIELECTRIC, color=tuple(color), color_tex=tex, tint_is_color=True,
                     roughness=rough, roughness_tex=rtex, ior=ior, distribution=dist)
        elif kind == "ShaderNodeBsdfTransparent":
            color, tex = self.color(node, "Color")
            self.add(w, kind=LOBE_TRANSPARENT, color=tuple(color), color_tex=tex)
        elif kind == "ShaderNodeEmission":
            color, tex = self.color(node, "Color")
            if tex >= 0:
                self.note(f"texture on '{node.name}' emission (used the input's own value)")
            self.emission += w * color * self.constant(node, "Strength")
        elif kind == "ShaderNodeBsdfPrincipled":
            self.principled(node, w)
        elif kind == "ShaderNodeHoldout":
            self.note(f"'{node.name}' Holdout (black)")
        else:
            self.note(f"'{node.name}' ({node.bl_label}) (rendered as diffuse)")
            if "Color" in node.inputs:
                color, tex = self.color(node, "Color")
            else:
                color, tex = np.array(GREY), -1
            self.add(w, kind=LOBE_DIFFUSE, color=tuple(color), color_tex=tex)

    def distribution(self, node, reflection: bool = True) -> int:
        """The node's DIST_*: Multiscatter GGX, GGX, and Beckmann or Ashikhmin-Shirley on a
        reflection lobe; the others are rendered as GGX."""
        dist = getattr(node, "distribution", "GGX")
        if dist == "SHARP":
            return DIST_GGX
        if dist not in DISTRIBUTIONS or (dist in ("BECKMANN", "ASHIKHMIN_SHIRLEY") and not reflection):
            self.note(f"'{node.name}' {dist} distribution (rendered as GGX)")
            return DIST_GGX
        return DISTRIBUTIONS[dist]

    def diffuse_roughness(self, node, name: str) -> dict:
        """The lobe kind and roughness of a diffuse from its roughness input: Oren-Nayar where
        it has one (Cycles takes Lambert below 1e-5), else Lambert."""
        if name not in node.inputs:
            return dict(kind=LOBE_DIFFUSE)
        rough, rtex = self.value(node, name)
        if rtex < 0 and rough < 1e-5:
            return dict(kind=LOBE_DIFFUSE)
        return dict(kind=LOBE_OREN_NAYAR, roughness=float(np.clip(rough, 0.0, 1.0)), roughness_tex=rtex)

    def glossy(self, node, w):
        dist = self.distribution(node)
        color, tex = self.color(node, "Color")
        rough, rtex = self.value(node, "Roughness")
        if "Anisotropy" in node.inputs and (node.inputs["Anisotropy"].is_linked or node.inputs["Anisotropy"].default_value != 0):
            self.note(f"'{node.name}' anisotropy (rendered isotropic)")
        self.normal_input(node)
        if self.phong:
            self.phong_lobe(node, w, kd=np.zeros(3), ks=color, ks_tex=tex, rough=rough, rtex=rtex)
        else:
            self.add(w, kind=LOBE_MICROFACET, fresnel=FRESNEL_NONE, color=tuple(color), color_tex=tex,
                     roughness=rough, roughness_tex=rtex, distribution=dist)

    def _set(self, node, name: str) -> bool:
        sock = node.inputs.get(name)
        return sock is not None and (sock.is_linked or float(sock.default_value) != 0.0)

    def metallic(self, node, w):
        dist = self.distribution(node)
        rough, rtex = self.value(node, "Roughness")
        for label, key in (("anisotropy", "Anisotropy"), ("thin film", "Thin Film Thickness")):
            if self._set(node, key):
                self.note(f"'{node.name}' {label} (ignored)")
        self.normal_input(node)
        if getattr(node, "fresnel_type", "F82") == "F82":
            f0, tex = self.color(node, "Base Color")
            tint, ttex = self.color(node, "Edge Tint")
            if ttex >= 0:
                self.note(f"texture on '{node.name}' Edge Tint (used the input's own value)")
        else:
            self.note(f"'{node.name}' physical conductor (rendered as F82 with its normal-incidence colour)")
            n, _ = self.color(node, "IOR")
            k, _ = self.color(node, "Extinction")
            f0, tex = ((n - 1) ** 2 + k ** 2) / np.maximum((n + 1) ** 2 + k ** 2, 1e-12), -1
            tint = np.ones(3)
        f0 = np.clip(f0, 0.0, 1.0)
        if self.phong:
            self.phong_lobe(node, w, kd=np.zeros(3), ks=f0, ks_tex=tex, rough=rough, rtex=rtex)
        else:
            self.add(w, kind=LOBE_MICROFACET, fresnel=FRESNEL_F82, color=tuple(f0), color_tex=tex,
                     tint=tuple(np.clip(tint, 0.0, 1.0)), roughness=rough, roughness_tex=rtex, distribution=dist)

    def phong_lobe(self, node, w, kd, ks, ks_tex, rough, rtex, kd_tex=-1):
        """Phong lobe: kd may be textured (colour), ks only constant; kd + ks <= 1 enforced."""
        if rtex >= 0:
            self.note(f"texture on '{node.name}' roughness (Phong exponent from its own value)")
        if ks_tex >= 0:
            self.note(f"texture on '{node.name}' specular colour (Phong: used the input's own value)")
        kd, ks = np.clip(kd, 0.0, None), np.clip(ks, 0.0, None)
        scale = max(float((kd + ks).max()), 1.0)
        if scale > 1.0:
            self.note(f"'{node.name}' Phong kd + ks > 1 (scaled down to conserve energy)")
        self.add(w, kind=LOBE_PHONG, color=tuple(kd / scale), color_tex=kd_tex, tint=tuple(ks / scale),
                 exponent=phong_exponent(rough))

    def principled(self, node, w):
        """Cycles' Principled BSDF (svm/closure.h), top layer first."""
        dist = self.distribution(node)
        for label, key, default in (("coat", "Coat Weight", 0.0), ("sheen", "Sheen Weight", 0.0),
                                    ("subsurface", "Subsurface Weight", 0.0),
                                    ("anisotropy", "Anisotropic", 0.0),
                                    ("thin film", "Thin Film Thickness", 0.0)):
            sock = node.inputs.get(key)
            if sock is not None and (sock.is_linked or float(sock.default_value) != default):
                self.note(f"'{node.name}' {label} (ignored)")
        base, btex = self.color(node, "Base Color")
        self.base_color = base if self.base_color is None else self.base_color
        rough, rtex = self.value(node, "Roughness")
        metallic = float(np.clip(self.constant(node, "Metallic"), 0.0, 1.0))
        transmission = float(np.clip(self.constant(node, "Transmission Weight"), 0.0, 1.0))
        ior = max(self.constant(node, "IOR"), 1e-5)
        level = max(self.constant(node, "Specular IOR Level"), 0.0)
        spec_tint, stex = self.color(node, "Specular Tint")
        if stex >= 0:
            self.note(f"texture on '{node.name}' Specular Tint (used the input's own value)")
        spec_tint = np.maximum(spec_tint, 0.0)
        self.normal_input(node)
        alpha, atex = self.value(node, "Alpha")
        alpha = float(np.clip(alpha, 0.0, 1.0))
        opacity = dict(opacity_tex=atex) if atex >= 0 else {}
        if atex >= 0:
            self.add(w, kind=LOBE_TRANSPARENT, color=(1.0, 1.0, 1.0), opacity_tex=atex, opacity_invert=True)
        elif alpha < 1.0:
            self.add(w * (1.0 - alpha), kind=LOBE_TRANSPARENT, color=(1.0, 1.0, 1.0))
            w = w * alpha
        ecolor, etex = self.color(node, "Emission Color")
        if etex >= 0:
            self.note(f"texture on '{node.name}' Emission Color (used the input's own value)")
        # A constant Emission Strength not above the cutoff emits nothing in Cycles, a negative
        # one included (engine/nodes/shaders.py _emits).
        self.emission += w * ecolor * max(self.constant(node, "Emission Strength"), 0.0)
        if atex >= 0 and self.emission.max() > 0:
            self.note(f"'{node.name}' emission under a textured Alpha (emitted in full)")
        common = dict(roughness=rough, roughness_tex=rtex, distribution=dist, **opacity)
        eta = ior
        f0 = f0_from_ior(ior)
        if level != 0.5:  # Specular IOR Level rescales F0 and the IOR with it
            f0 *= 2.0 * level
            eta = ior_from_f0(f0) if f0 > 0 else 1.0
            eta = 1.0 / eta if ior < 1.0 else eta
        if self.phong:
            ks = metallic * np.clip(base, 0, 1) + (1 - metallic) * (1 - transmission) * f0 * spec_tint
            kd = (1 - metallic) * (1 - transmission) * base * (1 - f0)
            if btex >= 0:
                self.note(f"'{node.name}' textured base colour under Phong (specular used its own value)")
            self.phong_lobe(node, w, kd=kd, ks=ks, ks_tex=-1, rough=rough, rtex=rtex,
                            kd_tex=btex if metallic < 1 else -1)
            if transmission > CUTOFF and metallic < 1:
                self.add(w * (1 - metallic) * transmission, kind=LOBE_DIELECTRIC, color=tuple(base),
                         color_tex=btex, color_sqrt=True, ior=ior, **common)
            return
        if metallic > CUTOFF:
            self.add(w * metallic, kind=LOBE_MICROFACET, fresnel=FRESNEL_F82, color=tuple(np.clip(base, 0, 1)),
                     color_tex=btex, tint=tuple(np.minimum(spec_tint, 1.0)), **common)
        w = w * (1.0 - metallic)
        if transmission > CUTOFF:
            if not np.allclose(spec_tint, 1.0):
                self.note(f"'{node.name}' Specular Tint on transmission (ignored)")
            self.add(w * transmission, kind=LOBE_DIELECTRIC, color=tuple(base), color_tex=btex, color_sqrt=True,
                     ior=ior, **common)
        w = w * (1.0 - transmission)
        top = -1
        if eta != 1.0:
            top = self.add(w, kind=LOBE_MICROFACET, fresnel=FRESNEL_DIELECTRIC, ior=eta,
                           tint=tuple(spec_tint), **common)
        self.add(w, color=tuple(base), color_tex=btex, layer=top, **self.diffuse_roughness(node, "Diffuse Roughness"),
                 **opacity)


def _group(warn, what: str, name: str) -> None:
    """One warning line per unsupported feature listing the datablocks (export.Warnings)."""
    group = getattr(warn, "group", None)
    if group is not None:
        group(what, name)
    else:
        warn(f"{what}: '{name}'.")


def material_row(mat, textures: _Textures, warn, phong: bool = False) -> dict:
    """One Materials row for a bpy Material (evaluated or original). Warns at most once."""
    name = mat.name
    settings = getattr(mat, "ember", None)
    if settings is not None and getattr(settings, "model", "NODES") == "PHONG":
        kd, ks = np.array(settings.diffuse_color[:3]), np.array(settings.specular_color[:3])
        scale = max(float((kd + ks).max()), 1.0)
        if scale > 1.0:
            warn(f"Material '{name}': Phong diffuse + specular colour exceeds 1; scaled down to conserve energy.")
        return dict(kind=MAT_PHONG, base_color=tuple(kd / scale), emission=(0, 0, 0), name=name,
                    phong=(tuple(kd / scale), tuple(ks / scale), float(settings.exponent)))
    tree = mat.node_tree
    if tree is None:
        return dict(kind=MAT_DIFFUSE, base_color=tuple(mat.diffuse_color[:3]), emission=(0, 0, 0), name=name)
    out = find_output(tree, "ShaderNodeOutputMaterial")
    if out is None:
        warn(f"Material '{name}': it has no Material Output node; rendered as grey diffuse.")
        return dict(kind=MAT_DIFFUSE, base_color=GREY, emission=(0, 0, 0), name=name)
    surface = follow_link(out.inputs["Surface"])
    volume_socket = out.inputs.get("Volume")
    if volume_socket is None or follow_link(volume_socket) is None:
        return _surface_row(mat, out, surface, textures, warn, phong)
    if surface is None:  # Cycles: a volume-only material has a transparent boundary
        row = dict(kind=MAT_NODES, base_color=(0.0, 0.0, 0.0), emission=(0, 0, 0), name=name,
                   lobes=[dict(kind=LOBE_TRANSPARENT, weight=(1.0, 1.0, 1.0), color=(1.0, 1.0, 1.0))])
    else:
        row = _surface_row(mat, out, surface, textures, warn, phong)
    notes = []
    medium = medium_of(volume_socket, notes.append)
    if notes:
        warn(f"Material '{name}': volume approximated " + "; ".join(notes) + ".")
    if medium is not None:
        row["volume"] = medium.as_row()
    return row


def _surface_row(mat, out, surface, textures: _Textures, warn, phong: bool) -> dict:
    """The Materials row of the material's Surface shader (see material_row)."""
    name = mat.name
    conv = _Converter(mat, textures, phong)
    conv.shader(surface, np.ones(3))
    displaced = follow_link(out.inputs["Displacement"]) is not None
    if conv.notes or displaced:  # what the lobe conversion approximates (or ignores), the node evaluator may not
        row = _node_row(mat, out, phong, warn)
        if row is not None:
            return row
    if displaced:
        conv.note("displacement (ignored)")
    if conv.notes:
        warn(f"Material '{name}': approximated " + "; ".join(conv.notes) + ".")
    row = dict(kind=MAT_NODES, base_color=tuple(conv.base_color if conv.base_color is not None else (0, 0, 0)),
               emission=tuple(conv.emission), name=name, lobes=conv.lobes)
    if conv.normal is not None:
        row["normal_tex"], row["normal_strength"] = conv.normal
    if not conv.lobes:
        row["kind"] = MAT_EMISSION_ONLY  # no BSDF: black, like Cycles without a surface shader
    elif _is_plain_diffuse(conv.lobes) and conv.normal is None:
        row["kind"] = MAT_DIFFUSE
    return row


def _node_row(mat, out, phong: bool, warn) -> dict | None:
    """The material through the node evaluator (engine/nodes/): its lobes, and its graph where
    they vary over the surface; None where the evaluator would approximate more than the
    conversion above (a node it cannot build, or one that reads what the renderer does not give
    a program yet: engine/nodes/hits.py provides)."""
    notes = []
    sockets = {"surface": out.inputs["Surface"]}
    # Displacement: as Cycles' Bump Only (a shading normal from the height, material.py), and
    # in object space for Displacement and Bump, whose moving of the mesh Ember leaves out.
    method = getattr(mat, "displacement_method", "BUMP")
    displaced = follow_link(out.inputs["Displacement"]) is not None
    if displaced and method != "DISPLACEMENT":
        sockets["displacement"] = out.inputs["Displacement"]
    graph = export_graph(sockets, notes.append)
    if "displacement" in sockets:
        graph = bump_from_displacement(graph, object_space=method == "BOTH")
    if displaced and method != "BUMP":
        notes.append("displacement of the mesh (ignored" + ("; its bump is rendered)" if method == "BOTH" else ")"))
    return graph_row(graph, mat.name, phong, warn, notes)


def graph_row(graph, name: str, phong: bool, warn, notes=()) -> dict | None:
    """The Materials row of a node graph (see _node_row), or None where the evaluator cannot
    render it; notes: what the export already approximated. A varying emission's table value
    is its mean over probe points (engine/nodes/material.py): what says the material emits."""
    notes = list(notes)
    if phong:
        graph = with_phong(graph)
    try:
        compiled = compiled_material(graph)  # shared with earlier exports of the same graph
    except (ValueError, KeyError, TypeError, IndexError) as exc:
        notes.append(f"node graph not evaluated ({exc})")
        compiled = None
    if compiled is None or any("not supported" in n for n in compiled.notes):
        return None
    if not all(provides(field) for field in compiled.program.reads):  # the renderer cannot run it yet
        return None
    notes = list(compiled.notes) + notes
    if notes:
        warn(f"Material '{name}': approximated " + "; ".join(notes) + ".")
    base = next((lobe.get("color") for lobe in compiled.lobes if lobe["kind"] in (LOBE_DIFFUSE, LOBE_OREN_NAYAR)),
                (0.0, 0.0, 0.0))
    row = dict(kind=MAT_NODES, base_color=tuple(base), emission=tuple(compiled.emission_mean), name=name,
               lobes=[dict(lobe) for lobe in compiled.lobes], graph=None if compiled.constant else graph,
               holdout=compiled.holdout)
    if not compiled.constant:
        row["reads"] = compiled.reads
    if not compiled.lobes:
        row["kind"] = MAT_EMISSION_ONLY
    return row


def _is_plain_diffuse(lobes) -> bool:
    return (len(lobes) == 1 and lobes[0]["kind"] == LOBE_DIFFUSE and lobes[0].get("color_tex", -1) < 0
            and np.allclose(lobes[0]["weight"], 1.0))


class MaterialTable:
    """Global material table; index(None) is Cycles' default surface (a default Principled BSDF).

    scene: the bpy Scene whose `ember.glossy_as_phong` setting applies (optional)."""

    def __init__(self, warn, scene=None):
        self._warn = warn
        self._rows: list[dict] = []
        self._index: dict[int, int] = {}
        self._default = None
        self._textures = _Textures()
        self._phong = bool(getattr(getattr(scene, "ember", None), "glossy_as_phong", False))

    def index(self, mat) -> int:
        if mat is None:
            if self._default is None:
                self._default = len(self._rows)
                # Cycles' default surface (engine/nodes/default_surface.py)
                self._rows.append(graph_row(default_surface(), DEFAULT_NAME, self._phong, self._warn))
            return self._default
        key = (getattr(mat, "original", None) or mat).as_pointer()
        i = self._index.get(key)
        if i is None:
            i = self._index[key] = len(self._rows)
            self._rows.append(material_row(mat, self._textures, self._warn, self._phong))
        return i

    def __len__(self):
        return len(self._rows)

    def reads(self, i: int) -> frozenset:
        """The state fields material i's node programs read (engine/nodes/state.py; none for a
        material without a program): what the mesh export carries for it."""
        return self._rows[i].get("reads", frozenset())

    def materials(self) -> Materials:
        return Materials.make(self._rows, self._textures.slots, self._textures.images)
