"""Colour nodes: Mix (float, vector, colour with every blend mode) and the legacy Mix RGB,
Hue/Saturation/Value, Invert, Gamma, Bright/Contrast, RGB to BW, Separate and Combine Color,
Blackbody, Wavelength and Light Falloff, with Cycles' formulas and guards (util/color.h for the
colour models, svm/color_util.h for the blend modes, the svm/*.h file of each node).

Colours are triples (engine/nodes/base.py); the per-channel branches of Cycles' C code become
np.where over all channels at once.
"""
from __future__ import annotations

import numpy as np

from .base import LUMINANCE, column, components, node, scalar, stack, triple

_FLT_MAX = float(np.finfo(np.float32).max)


def _interp(a, b, t):
    """Cycles' interp: a + t (b - a)."""
    return a + t * (b - a)


# Colour models (util/color.h). Each works on (..., 3) arrays; negative and > 1 components
# go through the same branches as in Cycles (no clamping where Cycles has none).

def rgb_to_hsv(rgb):
    r, g, b = components(triple(rgb))
    cmax = np.maximum(r, np.maximum(g, b))
    cmin = np.minimum(r, np.minimum(g, b))
    delta = cmax - cmin
    with np.errstate(all="ignore"):
        s = np.where(cmax != 0.0, delta / np.where(cmax != 0.0, cmax, 1.0), 0.0)
        chroma = s != 0.0
        d = np.where(chroma, delta, 1.0)
        cr, cg, cb = (cmax - r) / d, (cmax - g) / d, (cmax - b) / d
    h = np.where(r == cmax, cb - cg, np.where(g == cmax, 2.0 + cr - cb, 4.0 + cg - cr)) / 6.0
    h = np.where(h < 0.0, h + 1.0, h)
    return stack(np.where(chroma, h, 0.0), s, cmax)


def hsv_to_rgb(hsv):
    h, s, v = components(triple(hsv))
    h = np.where(h == 1.0, 0.0, h) * 6.0
    i = np.floor(h)
    f = h - i
    p = v * (1.0 - s)
    q = v * (1.0 - s * f)
    t = v * (1.0 - s * (1.0 - f))
    # Sector i picks (r, g, b) among v, t, p, q; any i outside 0..4 (hue outside [0, 1)) takes
    # the last sector, as the C code's final else does.
    conds = [i == 0.0, i == 1.0, i == 2.0, i == 3.0, i == 4.0]
    r = np.select(conds, [v, q, p, p, t], v)
    g = np.select(conds, [t, v, v, q, p], p)
    b = np.select(conds, [p, p, t, v, v], q)
    grey = s == 0.0
    return stack(np.where(grey, v, r), np.where(grey, v, g), np.where(grey, v, b))


def rgb_to_hsl(rgb):
    r, g, b = components(triple(rgb))
    cmax = np.maximum(r, np.maximum(g, b))
    cmin = np.minimum(r, np.minimum(g, b))
    light = np.minimum(1.0, (cmax + cmin) / 2.0)
    grey = cmax == cmin
    delta = np.where(grey, 1.0, cmax - cmin)
    with np.errstate(all="ignore"):
        s = np.where(light > 0.5, delta / (2.0 - cmax - cmin), delta / (cmax + cmin))
        h = np.where(cmax == r, (g - b) / delta + np.where(g < b, 6.0, 0.0),
                     np.where(cmax == g, (b - r) / delta + 2.0, (r - g) / delta + 4.0))
    return stack(np.where(grey, 0.0, h) / 6.0, np.where(grey, 0.0, s), light)


def hsl_to_rgb(hsl):
    h, s, light = components(triple(hsl))
    nr = np.clip(np.abs(h * 6.0 - 3.0) - 1.0, 0.0, 1.0)
    ng = np.clip(2.0 - np.abs(h * 6.0 - 2.0), 0.0, 1.0)
    nb = np.clip(2.0 - np.abs(h * 6.0 - 4.0), 0.0, 1.0)
    chroma = (1.0 - np.abs(2.0 * light - 1.0)) * s
    return stack((nr - 0.5) * chroma + light, (ng - 0.5) * chroma + light, (nb - 0.5) * chroma + light)


# Blend modes (svm/color_util.h svm_mix_*): f(t, a, b) with t a column (N,1) or 0-d.

def _flat(t):
    """A factor column (N,1) back to (N,); 0-d stays."""
    return t[..., 0] if np.ndim(t) else t


def _blend_hue(t, a, b):
    hsv_b = rgb_to_hsv(b)
    hsv = rgb_to_hsv(a)
    hsv = stack(hsv_b[..., 0], hsv[..., 1], hsv[..., 2])
    return np.where(hsv_b[..., 1:2] != 0.0, _interp(a, hsv_to_rgb(hsv), t), a)


def _blend_saturation(t, a, b):
    hsv = rgb_to_hsv(a)
    hsv_b = rgb_to_hsv(b)
    s = (1.0 - _flat(t)) * hsv[..., 1] + _flat(t) * hsv_b[..., 1]
    out = hsv_to_rgb(stack(hsv[..., 0], s, hsv[..., 2]))
    return np.where(hsv[..., 1:2] != 0.0, out, a)


def _blend_value(t, a, b):
    hsv = rgb_to_hsv(a)
    hsv_b = rgb_to_hsv(b)
    return hsv_to_rgb(stack(hsv[..., 0], hsv[..., 1], (1.0 - _flat(t)) * hsv[..., 2] + _flat(t) * hsv_b[..., 2]))


def _blend_color(t, a, b):
    hsv_b = rgb_to_hsv(b)
    hsv = rgb_to_hsv(a)
    out = hsv_to_rgb(stack(hsv_b[..., 0], hsv_b[..., 1], hsv[..., 2]))
    return np.where(hsv_b[..., 1:2] != 0.0, _interp(a, out, t), a)


def _blend_overlay(t, a, b):
    tm = 1.0 - t
    return np.where(a < 0.5, a * (tm + 2.0 * t * b), 1.0 - (tm + 2.0 * t * (1.0 - b)) * (1.0 - a))


def _blend_divide(t, a, b):
    with np.errstate(all="ignore"):
        return np.where(b != 0.0, (1.0 - t) * a + t * a / np.where(b != 0.0, b, 1.0), a)


def _blend_dodge(t, a, b):
    tmp = 1.0 - t * b
    with np.errstate(all="ignore"):
        ratio = a / np.where(tmp > 0.0, tmp, 1.0)
    out = np.where(tmp <= 0.0, 1.0, np.minimum(ratio, 1.0))  # ratio > 1 gives 1
    return np.where(a != 0.0, out, a)


def _blend_burn(t, a, b):
    tmp = (1.0 - t) + t * b
    with np.errstate(all="ignore"):
        out = 1.0 - (1.0 - a) / np.where(tmp > 0.0, tmp, 1.0)
    return np.where(tmp <= 0.0, 0.0, np.clip(out, 0.0, 1.0))


def _blend_screen(t, a, b):
    return 1.0 - ((1.0 - t) + t * (1.0 - b)) * (1.0 - a)


def _blend_soft_light(t, a, b):
    screen = 1.0 - (1.0 - b) * (1.0 - a)
    return (1.0 - t) * a + t * ((1.0 - a) * b * a + a * screen)


BLENDS = {
    "MIX": lambda t, a, b: _interp(a, b, t),
    "DARKEN": lambda t, a, b: _interp(a, np.minimum(a, b), t),
    "MULTIPLY": lambda t, a, b: _interp(a, a * b, t),
    "BURN": _blend_burn,
    "LIGHTEN": lambda t, a, b: _interp(a, np.maximum(a, b), t),
    "SCREEN": _blend_screen,
    "DODGE": _blend_dodge,
    "ADD": lambda t, a, b: _interp(a, a + b, t),
    "OVERLAY": _blend_overlay,
    "SOFT_LIGHT": _blend_soft_light,
    "LINEAR_LIGHT": lambda t, a, b: a + t * (2.0 * b - 1.0),
    "DIFFERENCE": lambda t, a, b: _interp(a, np.abs(a - b), t),
    "EXCLUSION": lambda t, a, b: np.maximum(_interp(a, a + b - 2.0 * a * b, t), 0.0),
    "SUBTRACT": lambda t, a, b: _interp(a, a - b, t),
    "DIVIDE": _blend_divide,
    "HUE": _blend_hue,
    "SATURATION": _blend_saturation,
    "COLOR": _blend_color,
    "VALUE": _blend_value,
}


def blend(mode: str, t, a, b):
    """svm_mix: colours a, b (triples) blended by factor t (a scalar: (N,) or 0-d)."""
    return BLENDS[mode](column(t), triple(a), triple(b))


def _lerp(t, a, b):
    """svm_node_mix_float / _vector: a (1 - t) + b t."""
    return a * (1.0 - t) + b * t


@node("ShaderNodeMix", "Utilities")  # Utilities > Math, and Color as Mix Color
def mix(node, inputs, state):
    """Mix (svm/mix.h): Float and Vector blend linearly (Vector by a uniform or per-component
    factor), Color by the blend mode, with the factor clamped first if asked and the colour
    result clamped after. Rotation: Cycles compiles no node for it, nor does Ember."""
    kind = node.prop("data_type", "FLOAT")
    clamp_factor = node.prop("clamp_factor", True)
    if kind == "VECTOR" and node.prop("factor_mode", "UNIFORM") == "NON_UNIFORM":
        t = triple(inputs["Factor_Vector"])
        t = np.clip(t, 0.0, 1.0) if clamp_factor else t
        return {"Result_Vector": _lerp(t, triple(inputs["A_Vector"]), triple(inputs["B_Vector"]))}
    t = scalar(inputs["Factor_Float"])
    t = np.clip(t, 0.0, 1.0) if clamp_factor else t
    if kind == "FLOAT":
        return {"Result_Float": scalar(_lerp(t, scalar(inputs["A_Float"]), scalar(inputs["B_Float"])))}
    if kind == "VECTOR":
        return {"Result_Vector": _lerp(column(t), triple(inputs["A_Vector"]), triple(inputs["B_Vector"]))}
    if kind == "RGBA":
        out = blend(node.prop("blend_type", "MIX"), t, inputs["A_Color"], inputs["B_Color"])
        return {"Result_Color": np.clip(out, 0.0, 1.0) if node.prop("clamp_result", False) else out}
    return {}


@node("ShaderNodeMixRGB", "Color")  # legacy: in no menu, still in old files
def mix_rgb(node, inputs, state):
    """The legacy Mix RGB (svm/mix.h svm_node_mix): its factor is always clamped to [0, 1]
    (svm_mix_clamped_factor); Clamp clamps the result. Alpha is not used in Cycles."""
    t = np.clip(scalar(inputs["Fac"]), 0.0, 1.0)
    out = blend(node.prop("blend_type", "MIX"), t, inputs["Color1"], inputs["Color2"])
    return {"Color": np.clip(out, 0.0, 1.0) if node.prop("use_clamp", False) else out}


@node("ShaderNodeHueSaturation", "Color")
def hue_saturation(node, inputs, state):
    """svm/hsv.h: hue shifted (wrapped), saturation scaled and clamped to [0, 1], value scaled,
    mixed with the input by Fac, negatives clamped to 0."""
    color = triple(inputs["Color"])
    h, s, v = components(rgb_to_hsv(color))
    h = h + scalar(inputs["Hue"]) + 0.5
    shifted = hsv_to_rgb(stack(h - np.floor(h), np.clip(s * scalar(inputs["Saturation"]), 0.0, 1.0),
                               v * scalar(inputs["Value"])))
    fac = column(inputs["Fac"])
    return {"Color": np.maximum(fac * shifted + (1.0 - fac) * color, 0.0)}


@node("ShaderNodeInvert", "Color")
def invert(node, inputs, state):
    """svm/invert.h: fac (1 - c) + (1 - fac) c."""
    fac, color = column(inputs["Fac"]), triple(inputs["Color"])
    return {"Color": fac * (1.0 - color) + (1.0 - fac) * color}


@node("ShaderNodeGamma", "Color")
def gamma(node, inputs, state):
    """svm/math_util.h svm_math_gamma_color: positive channels raised to gamma, others kept;
    gamma 0 gives white."""
    color, g = triple(inputs["Color"]), column(inputs["Gamma"])
    with np.errstate(all="ignore"):
        raised = np.where(color > 0.0, np.power(np.where(color > 0.0, color, 1.0), g), color)
    return {"Color": np.where(g == 0.0, 1.0, raised)}


@node("ShaderNodeBrightContrast", "Color")
def bright_contrast(node, inputs, state):
    """svm/color_util.h svm_brightness_contrast: max((1 + contrast) c + bright - contrast / 2, 0)."""
    contrast = column(inputs["Contrast"])
    out = (1.0 + contrast) * triple(inputs["Color"]) + (column(inputs["Bright"]) - contrast * 0.5)
    return {"Color": np.maximum(out, 0.0)}


@node("ShaderNodeRGBToBW", "Color")
def rgb_to_bw(node, inputs, state):
    """Cycles compiles it as the colour -> float conversion (svm/convert.h): luminance."""
    return {"Val": scalar(triple(inputs["Color"]) @ LUMINANCE)}


_TO_RGB = {"RGB": triple, "HSV": hsv_to_rgb, "HSL": hsl_to_rgb}
_FROM_RGB = {"RGB": triple, "HSV": rgb_to_hsv, "HSL": rgb_to_hsl}


@node("ShaderNodeSeparateColor", "Color")
def separate_color(node, inputs, state):
    """svm/color_util.h svm_separate_color: the colour's components in the mode's model."""
    x, y, z = components(_FROM_RGB[node.prop("mode", "RGB")](inputs["Color"]))
    return {"Red": scalar(x), "Green": scalar(y), "Blue": scalar(z)}


@node("ShaderNodeCombineColor", "Color")
def combine_color(node, inputs, state):
    """svm/color_util.h svm_combine_color: three components in the mode's model -> RGB."""
    return {"Color": _TO_RGB[node.prop("mode", "RGB")](stack(inputs["Red"], inputs["Green"], inputs["Blue"]))}


# Blackbody (svm/math_util.h svm_math_blackbody_color_rec709, coefficients from kernel/tables.h):
# per temperature band, R and G = a / T + b T + c, B = ((a T + b) T + c) T + d, in Rec.709.
_BLACKBODY_BANDS = np.array([965.0, 1167.0, 1449.0, 1902.0, 3315.0, 6365.0])
_BLACKBODY_R = np.array([
    [1.61919106e+03, -2.05010916e-03, 5.02995757e+00],
    [2.48845471e+03, -1.11330907e-03, 3.22621544e+00],
    [3.34143193e+03, -4.86551192e-04, 1.76486769e+00],
    [4.09461742e+03, -1.27446582e-04, 7.25731635e-01],
    [4.67028036e+03, 2.91258199e-05, 1.26703442e-01],
    [4.59509185e+03, 2.87495649e-05, 1.50345020e-01],
    [3.78717450e+03, 9.35907826e-06, 3.99075871e-01]])
_BLACKBODY_G = np.array([
    [-4.88999748e+02, 6.04330754e-04, -7.55807526e-02],
    [-7.55994277e+02, 3.16730098e-04, 4.78306139e-01],
    [-1.02363977e+03, 1.20223470e-04, 9.36662319e-01],
    [-1.26571316e+03, 4.87340896e-06, 1.27054498e+00],
    [-1.42529332e+03, -4.01150431e-05, 1.43972784e+00],
    [-1.17554822e+03, -2.16378048e-05, 1.30408023e+00],
    [-5.00799571e+02, -4.59832026e-06, 1.09098763e+00]])
_BLACKBODY_B = np.array([
    [5.96945309e-11, -4.85742887e-08, -9.70622247e-05, -4.07936148e-03],
    [2.40430366e-11, 5.55021075e-08, -1.98503712e-04, 2.89312858e-02],
    [-1.40949732e-11, 1.89878968e-07, -3.56632824e-04, 9.10767778e-02],
    [-3.61460868e-11, 2.84822009e-07, -4.93211319e-04, 1.56723440e-01],
    [-1.97075738e-11, 1.75359352e-07, -2.50542825e-04, -2.22783266e-02],
    [-1.61997957e-13, -1.64216008e-08, 3.86216271e-04, -7.38077418e-01],
    [6.72650283e-13, -2.73078809e-08, 4.24098264e-04, -7.52335691e-01]])
# Beyond the fit: at and above 12000 K, and below 800 K (OSL's lower limit), fixed colours.
_BLACKBODY_HOT = np.array([0.8262954810464208, 0.9945080501520986, 1.566307710274283])
_BLACKBODY_COLD = np.array([5.413294490189271, -0.20319390035873933, -0.0822535242887164])


def blackbody_rec709(temperature):
    """Blackbody colour of `temperature` (K) in Rec.709, unclamped (it may be negative)."""
    t = scalar(temperature)
    band = np.searchsorted(_BLACKBODY_BANDS, t, side="right")
    r, g, b = _BLACKBODY_R[band], _BLACKBODY_G[band], _BLACKBODY_B[band]
    with np.errstate(all="ignore"):
        inv = 1.0 / np.where(t != 0.0, t, 1.0)
    fit = stack(r[..., 0] * inv + r[..., 1] * t + r[..., 2], g[..., 0] * inv + g[..., 1] * t + g[..., 2],
                ((b[..., 0] * t + b[..., 1]) * t + b[..., 2]) * t + b[..., 3])
    t3 = t[..., None]
    return np.where(t3 >= 12000.0, _BLACKBODY_HOT, np.where(t3 < 800.0, _BLACKBODY_COLD, fit))


@node("ShaderNodeBlackbody", "Color")
def blackbody(node, inputs, state):
    """svm/blackbody.h: the Rec.709 fit, clamped to 0. The scene-linear space is Rec.709 in
    Blender's default colour management, so Cycles' rec709_to_rgb is the identity (checked
    against the bake)."""
    return {"Color": np.maximum(blackbody_rec709(inputs["Temperature"]), 0.0)}


# CIE 1931 colour matching functions from 380 nm in 5 nm steps (kernel/tables.h cie_color_match).
_CIE_XYZ = np.array([
    [0.0014, 0.0000, 0.0065], [0.0022, 0.0001, 0.0105], [0.0042, 0.0001, 0.0201],
    [0.0076, 0.0002, 0.0362], [0.0143, 0.0004, 0.0679], [0.0232, 0.0006, 0.1102],
    [0.0435, 0.0012, 0.2074], [0.0776, 0.0022, 0.3713], [0.1344, 0.0040, 0.6456],
    [0.2148, 0.0073, 1.0391], [0.2839, 0.0116, 1.3856], [0.3285, 0.0168, 1.6230],
    [0.3483, 0.0230, 1.7471], [0.3481, 0.0298, 1.7826], [0.3362, 0.0380, 1.7721],
    [0.3187, 0.0480, 1.7441], [0.2908, 0.0600, 1.6692], [0.2511, 0.0739, 1.5281],
    [0.1954, 0.0910, 1.2876], [0.1421, 0.1126, 1.0419], [0.0956, 0.1390, 0.8130],
    [0.0580, 0.1693, 0.6162], [0.0320, 0.2080, 0.4652], [0.0147, 0.2586, 0.3533],
    [0.0049, 0.3230, 0.2720], [0.0024, 0.4073, 0.2123], [0.0093, 0.5030, 0.1582],
    [0.0291, 0.6082, 0.1117], [0.0633, 0.7100, 0.0782], [0.1096, 0.7932, 0.0573],
    [0.1655, 0.8620, 0.0422], [0.2257, 0.9149, 0.0298], [0.2904, 0.9540, 0.0203],
    [0.3597, 0.9803, 0.0134], [0.4334, 0.9950, 0.0087], [0.5121, 1.0000, 0.0057],
    [0.5945, 0.9950, 0.0039], [0.6784, 0.9786, 0.0027], [0.7621, 0.9520, 0.0021],
    [0.8425, 0.9154, 0.0018], [0.9163, 0.8700, 0.0017], [0.9786, 0.8163, 0.0014],
    [1.0263, 0.7570, 0.0011], [1.0567, 0.6949, 0.0010], [1.0622, 0.6310, 0.0008],
    [1.0456, 0.5668, 0.0006], [1.0026, 0.5030, 0.0003], [0.9384, 0.4412, 0.0002],
    [0.8544, 0.3810, 0.0002], [0.7514, 0.3210, 0.0001], [0.6424, 0.2650, 0.0000],
    [0.5419, 0.2170, 0.0000], [0.4479, 0.1750, 0.0000], [0.3608, 0.1382, 0.0000],
    [0.2835, 0.1070, 0.0000], [0.2187, 0.0816, 0.0000], [0.1649, 0.0610, 0.0000],
    [0.1212, 0.0446, 0.0000], [0.0874, 0.0320, 0.0000], [0.0636, 0.0232, 0.0000],
    [0.0468, 0.0170, 0.0000], [0.0329, 0.0119, 0.0000], [0.0227, 0.0082, 0.0000],
    [0.0158, 0.0057, 0.0000], [0.0114, 0.0041, 0.0000], [0.0081, 0.0029, 0.0000],
    [0.0058, 0.0021, 0.0000], [0.0041, 0.0015, 0.0000], [0.0029, 0.0010, 0.0000],
    [0.0020, 0.0007, 0.0000], [0.0014, 0.0005, 0.0000], [0.0010, 0.0004, 0.0000],
    [0.0007, 0.0002, 0.0000], [0.0005, 0.0002, 0.0000], [0.0003, 0.0001, 0.0000],
    [0.0002, 0.0001, 0.0000], [0.0002, 0.0001, 0.0000], [0.0001, 0.0000, 0.0000],
    [0.0001, 0.0000, 0.0000], [0.0001, 0.0000, 0.0000], [0.0000, 0.0000, 0.0000]])
# XYZ -> scene linear (kernel_data.film.xyz_to_r/g/b) for Blender's default Linear Rec.709:
# the Rec.709 primaries with a D65 white, no chromatic adaptation (fitted to the bake to 1e-7).
XYZ_TO_REC709 = np.array([[3.2409699419, -1.5373831776, -0.4986107603],
                          [-0.9692436363, 1.8759675015, 0.0415550574],
                          [0.0556300797, -0.2039769589, 1.0569715142]])


def wavelength_xyz(nm):
    """svm/math_util.h svm_math_wavelength_color_xyz: the table interpolated linearly; zero
    outside its 80 intervals. The interval index truncates toward zero, so just below 380 nm
    the first interval is extrapolated (then clamped away in RGB), as in Cycles."""
    x = (scalar(nm) - 380.0) / 5.0
    i = np.trunc(x)
    inside = (i >= 0.0) & (i < 80.0)
    k = np.where(inside, i, 0.0).astype(np.int64)
    f = (x - k)[..., None]
    xyz = _CIE_XYZ[k] + f * (_CIE_XYZ[k + 1] - _CIE_XYZ[k])
    return np.where(inside[..., None], xyz, 0.0)


@node("ShaderNodeWavelength", "Color")
def wavelength(node, inputs, state):
    """svm/wavelength.h: XYZ -> scene linear, scaled by 1 / 2.52 (Cycles' empirical scale that
    keeps every component <= 1), negatives clamped to 0."""
    rgb = wavelength_xyz(inputs["Wavelength"]) @ XYZ_TO_REC709.T
    return {"Color": np.maximum(rgb * (1.0 / 2.52), 0.0)}


_FALLOFF_READS = {"Quadratic": ("ray_length",), "Linear": ("ray_length",), "Constant": ("ray_length",)}


def _falloff(power: int, inputs, state):
    """svm/light_path.h svm_node_light_falloff: Strength times ray_length^power, softened by
    r^2 / (smooth + r^2) where smooth > 0; a ray of length FLT_MAX (distant lights) passes
    Strength through unchanged."""
    strength, smooth = scalar(inputs["Strength"]), scalar(inputs["Smooth"])
    r = scalar(state.ray_length)
    squared = r * r
    with np.errstate(all="ignore"):
        out = strength * r ** power
        out = np.where(smooth > 0.0, out * squared / np.where(smooth > 0.0, smooth + squared, 1.0), out)
    return np.where(r >= _FLT_MAX, strength, out)


@node("ShaderNodeLightFalloff", "Color", reads=_FALLOFF_READS)
def light_falloff(node, inputs, state):
    return {"Quadratic": lambda: _falloff(0, inputs, state), "Linear": lambda: _falloff(1, inputs, state),
            "Constant": lambda: _falloff(2, inputs, state)}


NODES = (mix, mix_rgb, hue_saturation, invert, gamma, bright_contrast, rgb_to_bw, separate_color, combine_color,
         blackbody, wavelength, light_falloff)
