"""Image Texture against Cycles (tests/node_bake.py).

Images are made in the test, small (16 x 12, so that texels are coarser than the bake's and
every interpolation shows) and of noise (any texel or weight off shows): float ones with
values above 1, byte ones with every 8-bit level; alpha varies over the image. Coordinates
sweep past the image's edges, so each extension shows; the projections read points of a cube
about the plane.
"""
import numpy as np
import pytest

pytestmark = pytest.mark.blender

import bpy  # noqa: E402

import node_bake  # noqa: E402

WIDTH, HEIGHT = 16, 12
INTERPOLATIONS = ("Closest", "Linear", "Cubic", "Smart")
EXTENSIONS = ("REPEAT", "EXTEND", "CLIP", "MIRROR")


def _pattern(seed: int, width: int = WIDTH, height: int = HEIGHT) -> np.ndarray:
    """(height, width, 4) float32 noise in [0, 1], rows bottom-up."""
    return np.random.default_rng(seed).random((height, width, 4)).astype(np.float32)


def image(name: str, is_float: bool = True, colorspace=None, alpha_mode=None, scale: float = 1.0,
          alpha: str = "noise", size=(WIDTH, HEIGHT)):
    """A generated image of noise (float: colour up to `scale`; byte: 8-bit levels), made once
    per bake scene. alpha: "noise", "one", or "edges" (0 and 1 among the values)."""
    found = bpy.data.images.get(name)
    if found is not None:
        return found
    made = bpy.data.images.new(name, size[0], size[1], alpha=True, float_buffer=is_float)
    if colorspace is not None:
        made.colorspace_settings.name = colorspace
    if alpha_mode is not None:
        made.alpha_mode = alpha_mode
    pixels = _pattern(sum(map(ord, name)), *size)
    pixels[..., :3] *= scale
    if alpha == "one":
        pixels[..., 3] = 1.0
    elif alpha == "edges":
        pixels[..., 3] = np.round(pixels[..., 3] * 2.0) / 2.0
    made.pixels.foreach_set(pixels.ravel())
    made.update()
    return made


def _node(nt, props: dict, vector=None, image_args=("float",)):
    n = nt.nodes.new("ShaderNodeTexImage")
    n.image = image(*image_args) if image_args is not None else None
    for key, value in props.items():
        setattr(n, key, value)
    if vector is not None:
        nt.links.new(vector, n.inputs["Vector"])
    return n


def uv_sweep(lo=(-0.3, -0.4), hi=(1.4, 1.25), z=(0.0, 0.0)):
    """The plane's UV mapped linearly onto [lo, hi] (and z from z[0] at u = 0 to z[1] at u = 1)."""
    def socket(nt):
        coord = nt.nodes.new("ShaderNodeTexCoord")
        split = nt.nodes.new("ShaderNodeSeparateXYZ")
        nt.links.new(coord.outputs["UV"], split.inputs["Vector"])
        combine = nt.nodes.new("ShaderNodeCombineXYZ")
        for k, axis in enumerate("XY"):
            m = nt.nodes.new("ShaderNodeMath")
            m.operation = "MULTIPLY_ADD"
            nt.links.new(split.outputs[axis], m.inputs[0])
            m.inputs[1].default_value, m.inputs[2].default_value = hi[k] - lo[k], lo[k]
            nt.links.new(m.outputs[0], combine.inputs[k])
        m = nt.nodes.new("ShaderNodeMath")
        m.operation = "MULTIPLY_ADD"
        nt.links.new(split.outputs["X"], m.inputs[0])
        m.inputs[1].default_value, m.inputs[2].default_value = z[1] - z[0], z[0]
        nt.links.new(m.outputs[0], combine.inputs[2])
        return combine.outputs[0]
    return socket


def case(props: dict, vector=uv_sweep(), image_args=("float",), output="Color", alpha_linked=False):
    """A case: an Image Texture with `props` reading `vector` (None: unlinked). output "Color" or
    "Alpha"; alpha_linked: the Alpha output also used (Color + Alpha, so Cycles divides the
    colour by alpha)."""
    def build(nt):
        src = vector(nt) if vector is not None else None
        n = _node(nt, props, src, image_args)
        if not alpha_linked:
            return n.outputs[output]
        add = nt.nodes.new("ShaderNodeVectorMath")
        add.operation = "ADD"
        nt.links.new(n.outputs["Color"], add.inputs[0])
        nt.links.new(n.outputs["Alpha"], add.inputs[1])
        return add.outputs[0]
    return build


def _errors(cycles, ember):
    err = np.max(np.abs(cycles - ember) / np.maximum(1.0, np.abs(cycles)), axis=1)
    return node_bake.agreement(cycles, ember), float(err.mean()), float(np.percentile(err, 99))


def check(results: dict, agreement: float = 0.999):
    figures = {name: _errors(c, e) for name, (c, e) in results.items()}
    bad = {name: f for name, f in figures.items() if f[0] < agreement}
    assert bad == {}, bad
    return figures


def test_interpolations_and_extensions_match_cycles():
    cases = {f"{i}_{e}": case(dict(interpolation=i, extension=e)) for i in INTERPOLATIONS for e in EXTENSIONS}
    results = node_bake.bake(cases)
    check(results)
    for c, _ in results.values():
        assert np.ptp(c) > 0.1


# Points of a cube about [0, 1]^3, across the sphere's and the tube's seams and poles.
CUBE = uv_sweep(lo=(-0.15, -0.1), hi=(1.1, 1.2), z=(0.15, 0.95))


def test_sphere_and_tube_projections_match_cycles():
    cases = {f"{p}_{i}": case(dict(projection=p, interpolation=i), CUBE) for p in ("SPHERE", "TUBE")
             for i in INTERPOLATIONS}
    cases["SPHERE_CLIP"] = case(dict(projection="SPHERE", extension="CLIP"), uv_sweep(z=(-0.4, 0.5)))
    cases["TUBE_MIRROR"] = case(dict(projection="TUBE", extension="MIRROR"), uv_sweep(z=(-0.6, 1.7)))
    cases["FLAT_cube"] = case(dict(projection="FLAT", interpolation="Cubic"), CUBE)
    check(node_bake.bake(cases))


def test_alpha_and_alpha_modes_match_cycles():
    """Alpha as stored; the colour divided by alpha where the Alpha output is linked (alpha 0
    and 1 left alone), unless the image is data, Channel Packed or None; byte images
    premultiplied in 8 bits unless they are."""
    images = {
        "float": ("float",),
        "float_edges": ("float_edges", True, None, None, 3.0, "edges"),
        "byte_srgb": ("byte_srgb", False),
        "byte_edges": ("byte_edges", False, None, None, 1.0, "edges"),
        "byte_linear": ("byte_linear", False, "Linear Rec.709"),
        "byte_data": ("byte_data", False, "Non-Color"),
        "float_data": ("float_data", True, "Non-Color"),
        "byte_premul": ("byte_premul", False, None, "PREMUL"),
        "byte_packed": ("byte_packed", False, None, "CHANNEL_PACKED"),
        "float_packed": ("float_packed", True, None, "CHANNEL_PACKED"),
        "byte_none": ("byte_none", False, None, "NONE"),
        "float_none": ("float_none", True, None, "NONE"),
    }
    cases = {}
    for name, args in images.items():
        cases[f"{name}_color"] = case(dict(interpolation="Linear"), image_args=args)
        cases[f"{name}_alpha"] = case(dict(interpolation="Cubic"), image_args=args, output="Alpha")
        # Divided by alpha, a colour interpolated toward a texel of alpha 0 magnifies the bake's
        # float32 positions past the tolerance: images with such texels are read at texels only.
        smooth = "Closest" if "edges" in name else "Linear"
        cases[f"{name}_unassociated"] = case(dict(interpolation=smooth), image_args=args, alpha_linked=True)
    check(node_bake.bake(cases))


def _nonfinite(name: str):
    """A float image with NaN and infinite channels in some pixels (Cycles zeroes those pixels)."""
    made = image(name)
    pixels = _pattern(7)
    pixels[2, 3, 0] = np.nan
    pixels[5, 8, 3] = np.inf
    pixels[9, 1, 2] = -np.inf
    made.pixels.foreach_set(pixels.ravel())
    made.update()
    return (name,)


def _mapped(props: dict, vector=uv_sweep(), **mapping):
    """A case whose node's own mapping has `mapping` (translation, rotation, scale, vector_type)."""
    def build(nt):
        src = vector(nt) if vector is not None else None
        n = _node(nt, props, src)
        for key, value in mapping.items():
            setattr(n.texture_mapping, key, value)
        return n.outputs["Color"]
    return build


def _constant(nt):
    combine = nt.nodes.new("ShaderNodeCombineXYZ")
    combine.inputs[0].default_value, combine.inputs[1].default_value = 0.37, 0.81
    return combine.outputs[0]


def test_colour_spaces_coordinates_and_mapping_match_cycles():
    """8-bit sRGB decoded after every interpolation; float images in any colour space read as
    they are; non-finite pixels transparent black; the unlinked Vector is the UV map; the
    node's mapping; a constant coordinate; no image is magenta."""
    srgb = ("byte_srgb", False)
    cases = {f"srgb_{i}_{e}": case(dict(interpolation=i, extension=e), image_args=srgb)
             for i, e in zip(INTERPOLATIONS, EXTENSIONS)}
    cases["srgb_alpha_clip"] = case(dict(interpolation="Cubic", extension="CLIP"), image_args=srgb, output="Alpha")
    cases["float_srgb"] = case(dict(interpolation="Cubic"), image_args=("float_srgb", True, "sRGB", None, 2.0))
    cases["float_non_finite"] = case(dict(interpolation="Linear"), image_args=_nonfinite("float_nan"))
    cases["float_non_finite_alpha"] = case(dict(interpolation="Linear"), image_args=("float_nan",), output="Alpha")
    cases["uv_unlinked"] = case(dict(interpolation="Linear"), vector=None)
    cases["uv_unlinked_sphere"] = case(dict(projection="SPHERE"), vector=None)
    cases["mapping_point"] = _mapped(dict(interpolation="Linear", extension="MIRROR"), vector_type="POINT",
                                     translation=(0.3, -0.2, 0.1), rotation=(0.0, 0.0, 0.6), scale=(1.5, 0.8, 1.0))
    cases["mapping_texture_unlinked"] = _mapped(dict(interpolation="Cubic"), None, vector_type="TEXTURE",
                                                translation=(0.1, 0.25, 0.0), rotation=(0.2, 0.1, -0.4),
                                                scale=(2.0, 3.0, 1.0))
    cases["constant"] = case(dict(interpolation="Cubic"), vector=_constant)
    cases["no_image"] = case(dict(), image_args=None)
    results = node_bake.bake(cases)
    check({k: v for k, v in results.items() if k not in ("no_image", "constant")})
    for name in ("no_image", "constant"):
        cycles, ember = results[name]
        assert np.ptp(cycles, axis=0).max() < 1e-6 and np.allclose(cycles, ember, atol=1e-6), name
    assert np.allclose(results["no_image"][0], [1.0, 0.0, 1.0])
