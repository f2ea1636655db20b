"""Environment Texture against Cycles (tests/node_bake.py, tests/world_bake.py): a small
generated image (float with values above 1, or 8-bit sRGB with alpha, or Non-Color) read in
directions that sweep the sphere, normalised or not, with either projection and every
interpolation, in materials and in a world.

Each case asserts Cycles' agreement figure (share of texels within 1e-4, absolute up to 1,
relative above) and the mean and 99th percentile of the error measured the same way.
"""
import numpy as np
import pytest

pytestmark = pytest.mark.blender

import bpy  # noqa: E402

import node_bake  # noqa: E402
import world_bake  # noqa: E402


def _errors(cycles, ember):
    """(agreement, mean error, 99th percentile error), errors absolute up to 1, relative above."""
    err = np.max(np.abs(cycles - ember) / np.maximum(1.0, np.abs(cycles)), axis=1)
    return node_bake.agreement(cycles, ember), float(err.mean()), float(np.percentile(err, 99))


def _check(results: dict, mean: float = 1e-5, p99: float = 5e-5, agreement: float = 0.999):
    figures = {name: _errors(c, e) for name, (c, e) in results.items()}
    bad = {name: f for name, f in figures.items() if f[0] < agreement or f[1] > mean or f[2] > p99}
    assert bad == {}, bad
    for c, _ in results.values():  # the cases show something
        assert np.ptp(c) > 1e-3


# ---- direction fields over the plane's UV ------------------------------------------------------

def _uv(nt):
    split = nt.nodes.get("uv")
    if split is None:
        coord = nt.nodes.new("ShaderNodeTexCoord")
        split = nt.nodes.new("ShaderNodeSeparateXYZ")
        split.name = "uv"
        nt.links.new(coord.outputs["UV"], split.inputs["Vector"])
    return split


def _math(nt, operation, *args):
    m = nt.nodes.new("ShaderNodeMath")
    m.operation = operation
    for i, a in enumerate(args):
        if isinstance(a, (int, float)):
            m.inputs[i].default_value = a
        else:
            nt.links.new(a, m.inputs[i])
    return m.outputs[0]


def _vector_math(nt, operation, a, scale=None):
    m = nt.nodes.new("ShaderNodeVectorMath")
    m.operation = operation
    nt.links.new(a, m.inputs[0])
    if scale is not None:
        m.inputs["Scale"].default_value = scale
    return m.outputs[0]


def sphere(theta=(np.pi, 0.0), phi=(2.0 * np.pi, -np.pi + 0.05), length=1.0, pole="z"):
    """Directions at angle theta = a v + b from the pole (+z; "-y": -y) and azimuth
    phi = a u + b about it, scaled by `length`: by default the whole sphere, the seam of
    azimuth +-pi crossed."""
    def socket(nt):
        s = _uv(nt)
        th = _math(nt, "MULTIPLY_ADD", s.outputs["Y"], theta[0], theta[1])
        ph = _math(nt, "MULTIPLY_ADD", s.outputs["X"], phi[0], phi[1])
        sin_t = _math(nt, "SINE", th)
        combine = nt.nodes.new("ShaderNodeCombineXYZ")
        axes = (0, 1, 2) if pole == "z" else (0, 2, 1)
        nt.links.new(_math(nt, "MULTIPLY", sin_t, _math(nt, "COSINE", ph)), combine.inputs[axes[0]])
        nt.links.new(_math(nt, "MULTIPLY", sin_t, _math(nt, "SINE", ph)), combine.inputs[axes[1]])
        cos_t = _math(nt, "COSINE", th)
        nt.links.new(cos_t if pole == "z" else _math(nt, "MULTIPLY", cos_t, -1.0), combine.inputs[axes[2]])
        out = combine.outputs[0]
        return out if length == 1.0 else _vector_math(nt, "SCALE", out, length)
    return socket


def cone(center, spread: float):
    """Unit directions center + spread ((2u - 1) t1 + (2v - 1) t2), t1 and t2 across it."""
    c = np.asarray(center, np.float64)
    c = c / np.linalg.norm(c)
    t1 = np.cross(c, [0.0, 0.0, 1.0]) if abs(c[2]) < 0.99 else np.cross(c, [1.0, 0.0, 0.0])
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(c, t1)

    def socket(nt):
        s = _uv(nt)
        combine = nt.nodes.new("ShaderNodeCombineXYZ")
        for k in range(3):
            base = c[k] - spread * (t1[k] + t2[k])
            au = _math(nt, "MULTIPLY_ADD", s.outputs["X"], 2.0 * spread * t1[k], float(base))
            nt.links.new(_math(nt, "MULTIPLY_ADD", s.outputs["Y"], 2.0 * spread * t2[k], au), combine.inputs[k])
        return _vector_math(nt, "NORMALIZE", combine.outputs[0])
    return socket


# ---- Environment Texture -------------------------------------------------------------------------

WIDTH, HEIGHT = 64, 32


def _pattern(seed: int) -> np.ndarray:
    """(HEIGHT, WIDTH, 4) texels: noise, so that any texel or weight off shows."""
    return np.random.default_rng(seed).random((HEIGHT, WIDTH, 4)).astype(np.float32)


def _image(name: str, is_float: bool = True, colorspace=None, alpha_mode=None, scale: float = 1.0):
    """A generated image of the pattern (float: values up to `scale`; byte: 8-bit)."""
    image = bpy.data.images.get(name)
    if image is None:
        image = bpy.data.images.new(name, WIDTH, HEIGHT, alpha=True, float_buffer=is_float)
        if colorspace is not None:
            image.colorspace_settings.name = colorspace
        if alpha_mode is not None:
            image.alpha_mode = alpha_mode
        pixels = _pattern(len(name))
        pixels[..., :3] *= scale
        image.pixels.foreach_set(pixels.ravel())
        image.update()
    return image


def _environment(direction, image=("hdr",), projection="EQUIRECTANGULAR", interpolation="Linear"):
    def build(nt):
        src = direction(nt) if direction is not None else None
        n = nt.nodes.new("ShaderNodeTexEnvironment")
        n.image = _image(*image) if image is not None else None
        n.projection, n.interpolation = projection, interpolation
        if src is not None:
            nt.links.new(src, n.inputs["Vector"])
        return n.outputs["Color"]
    return build


HDR = ("hdr", True, None, None, 4.0)


def test_environment_projections_and_interpolations_match_cycles():
    cases = {}
    # Mirror Ball divides by sqrt(1 - y): toward +y, where the whole rim of the image meets,
    # the float32 rounding of Cycles' directions moves the lookup by 1e-4 texels and more, and
    # the noise image differs by that. Its sweep stops 30 degrees short of +y.
    views = {"EQUIRECTANGULAR": sphere(), "MIRROR_BALL": sphere(theta=(np.pi - 0.5, 0.0), pole="-y")}
    for projection in ("EQUIRECTANGULAR", "MIRROR_BALL"):
        for interpolation in ("Closest", "Linear", "Cubic", "Smart"):
            cases[f"{projection}_{interpolation}"] = _environment(views[projection], HDR, projection, interpolation)
    # Unnormalised and zero vectors (normalised, zero stays zero), the poles.
    cases["scaled"] = _environment(sphere(length=3.7), HDR, "EQUIRECTANGULAR", "Cubic")
    cases["poles"] = _environment(cone((0.0, 0.0, -1.0), 0.2), HDR, "EQUIRECTANGULAR", "Cubic")
    cases["zero"] = _environment(sphere(length=0.0), HDR, "MIRROR_BALL", "Linear")
    results = node_bake.bake(cases, size=64)
    _check({k: v for k, v in results.items() if k != "zero"})
    cycles, ember = results["zero"]
    assert np.allclose(cycles, ember, atol=1e-6) and np.ptp(cycles, axis=0).max() == 0.0


def test_environment_images_as_cycles_stores_them():
    """8-bit sRGB texels premultiplied in 8 bits and converted after interpolating; Non-Color
    and ignored alpha as they are; a float image in sRGB is linear already; no image is
    magenta; an unlinked Vector is the position."""
    cases = {
        "byte_srgb_linear": _environment(sphere(), ("srgb", False), interpolation="Linear"),
        "byte_srgb_cubic": _environment(sphere(), ("srgb", False), interpolation="Cubic"),
        "byte_non_color": _environment(sphere(), ("data", False, "Non-Color"), interpolation="Linear"),
        "byte_alpha_none": _environment(sphere(), ("opaque", False, None, "NONE"), interpolation="Closest"),
        "float_srgb": _environment(sphere(), ("float_srgb", True, "sRGB"), interpolation="Linear"),
        "no_image": _environment(sphere(), None),
        "position": _environment(None, HDR, interpolation="Linear"),
    }
    results = node_bake.bake(cases, size=64)
    _check({k: v for k, v in results.items() if k != "no_image"})
    cycles, ember = results["no_image"]
    assert np.allclose(cycles, [1.0, 0.0, 1.0]) and np.allclose(ember, [1.0, 0.0, 1.0])


def test_environment_as_a_world():
    def build(nt):
        n = nt.nodes.new("ShaderNodeTexEnvironment")
        n.image, n.interpolation = _image(*HDR), "Cubic"
        return n.outputs["Color"]
    cycles, ember, _ = world_bake.bake_world(build)
    _check({"world": (cycles, ember)})
