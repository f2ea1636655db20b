"""Image Texture against Cycles (tests/node_bake.py).

Images are made in the test, small (16 x 12, so that texels are coarser than the bake's and
every interpolation shows) and of noise (any texel or weight off shows): float ones with
values above 1, byte ones with every 8-bit level; alpha varies over the image. Coordinates
sweep past the image's edges, so each extension shows; the projections read points of a cube
about the plane.
"""
from dataclasses import dataclass

import numpy as np
import OpenEXR
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


def _with_image(props: dict, make, vector=uv_sweep(), output="Color", user=None, mapping=None):
    def build(nt):
        src = vector(nt) if vector is not None else None
        n = nt.nodes.new("ShaderNodeTexImage")
        n.image = make()
        for key, value in props.items():
            setattr(n, key, value)
        for key, value in (user or {}).items():
            setattr(n.image_user, key, value)
        for key, value in (mapping or {}).items():
            setattr(n.texture_mapping, key, value)
        if src is not None:
            nt.links.new(src, n.inputs["Vector"])
        return n.outputs[output]
    return build


def _errors(cycles, ember):
    err = np.max(np.abs(cycles - ember) / np.maximum(1.0, np.abs(cycles)), axis=1)
    return node_bake.agreement(cycles, ember), float(err.mean()), float(np.percentile(err, 99))


def check(results: dict, agreement: float = 0.999):
    """Each case's agreement with Cycles at least `agreement`. Non-finite values Ember computes
    count as 0, as Cycles' film writes them (film/light_passes.h ensure_finite)."""
    figures = {name: _errors(c, np.where(np.isfinite(e), e, 0.0)) for name, (c, e) in results.items()}
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


# Non-finite channels (row, column, channel): Cycles cleans the pixels of index row * 16 +
# column a multiple of 4 (those of (5, 8) and (8, 4)) and leaves the others.
NON_FINITE = {(2, 3, 0): np.nan, (5, 8, 3): np.inf, (9, 1, 2): -np.inf, (1, 1, 3): np.nan, (8, 4, 2): np.nan,
              (4, 2, 1): np.inf}


def _nonfinite():
    """A float image with NaN and infinite channels in some pixels."""
    made = bpy.data.images.get("float_nan")
    if made is None:
        made = image("float_nan")
        pixels = _pattern(7)
        for at, value in NON_FINITE.items():
            pixels[at] = value
        made.pixels.foreach_set(pixels.ravel())
        made.update()
    return made


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
    cases["float_non_finite"] = _with_image(dict(interpolation="Closest"), _nonfinite, uv_sweep((0, 0), (1, 1)))
    cases["float_non_finite_cubic"] = _with_image(dict(interpolation="Cubic"), _nonfinite)
    cases["float_non_finite_alpha"] = _with_image(dict(interpolation="Linear"), _nonfinite, output="Alpha")
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


# ---- Box projection: smooth planes whose vertex normals sweep the octants ---------------------

@dataclass(frozen=True)
class Smooth:
    """A case baked on a plane of two triangles (corners 0 1 2 and 0 2 3, counter-clockwise
    from UV (0, 0)) shaded smooth with object-space vertex `normals` (4, 3), turned by `rotation`
    and scaled by `scale` (so that the object's normal transform shows)."""

    build: object
    normals: tuple
    rotation: tuple = (0.3, -0.5, 0.8)
    scale: tuple = (1.0, 2.0, 0.5)
    flip: bool = False  # wound clockwise: the triangles face -z in object space


def _smooth_plane(k: int, case: Smooth):
    mesh = bpy.data.meshes.new(f"smooth_{k}")
    faces = [(0, 2, 1), (0, 3, 2)] if case.flip else [(0, 1, 2), (0, 2, 3)]
    mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], faces)
    uv = mesh.uv_layers.new(name="UVMap")
    corners = {0: (0, 0), 1: (1, 0), 2: (1, 1), 3: (0, 1)}
    for loop, data in zip(mesh.loops, uv.data):
        data.uv = corners[loop.vertex_index]
    for poly in mesh.polygons:
        poly.use_smooth = True
    mesh.normals_split_custom_set_from_vertices([tuple(n) for n in case.normals])
    ob = bpy.data.objects.new(f"smooth_{k}", mesh)
    bpy.context.scene.collection.objects.link(ob)
    ob.location = (node_bake.SPACING * k, 0.0, 0.0)
    ob.rotation_euler, ob.scale = case.rotation, case.scale
    return ob


def bake_smooth(cases: dict, size: int = node_bake.SIZE) -> dict:
    """node_bake.bake for Smooth cases: {name: (cycles, ember)}."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device, scene.cycles.samples = "CPU", 1
    camera = node_bake._camera()
    made = {}
    for k, (name, case) in enumerate(cases.items()):
        ob = _smooth_plane(k, case)
        mat, out = node_bake._material(name, case.build)
        target = bpy.data.images.new(f"bake_{k}", size, size, float_buffer=True)
        tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
        tex.image = target
        mat.node_tree.nodes.active = tex
        ob.data.materials.append(mat)
        made[name] = (ob, out, target)
    for first in range(0, len(made), node_bake.BAKE_CHUNK):
        bpy.ops.object.select_all(action="DESELECT")
        chunk = [ob for ob, _, _ in list(made.values())[first:first + node_bake.BAKE_CHUNK]]
        for ob in chunk:
            ob.select_set(True)
        bpy.context.view_layer.objects.active = chunk[0]
        bpy.ops.object.bake(type="EMIT")
    bpy.context.view_layer.update()
    world_from_camera = node_bake._world_from_camera(camera)
    results = {}
    for name, (ob, out, target) in made.items():
        cycles = np.array(target.pixels[:], np.float64).reshape(size * size, 4)[:, :3]
        state = node_bake._state(ob, size, camera, world_from_camera, "ABOVE_SURFACE")
        results[name] = (cycles, node_bake.evaluate(out, state))
    return results


# Vertex normals (corners 0 1 2 3): the first triangle spans an octant from axis to axis, the
# second runs from x past the diagonal to z; signs vary so that every plane's flip shows.
NORMALS = {
    "ppp": ((1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1)),
    "nnp": ((-1, 0.05, 0.1), (0.1, -1, 0.05), (0.05, 0.1, 1), (-1, -1.2, 0.9)),
    "pnn": ((1, 0.2, -0.1), (0.3, -1, -0.2), (0.1, -0.2, -1), (0.8, -1, -1.1)),
}
# For triangles facing -z: normals below the plane (those above it are seen from behind).
FLIPPED = {
    "pnn_flipped": NORMALS["pnn"],
    "npn_flipped": ((-1, 0.1, -0.05), (0.05, 1, -0.1), (-0.1, 0.05, -1), (-1.1, 0.9, -1)),
}


def test_box_projection_matches_cycles():
    cases = {}
    for sign, normals in NORMALS.items():
        for blend in (0.0, 0.15, 0.5, 1.0):
            cases[f"{sign}_{blend}"] = Smooth(case(dict(projection="BOX", projection_blend=blend), CUBE), normals)
    for sign, normals in FLIPPED.items():
        for blend in (0.0, 0.3):
            cases[f"{sign}_{blend}"] = Smooth(case(dict(projection="BOX", projection_blend=blend), CUBE), normals,
                                              flip=True)
    cases["alpha"] = Smooth(case(dict(projection="BOX", projection_blend=0.3, interpolation="Cubic"), CUBE,
                                 output="Alpha"), NORMALS["nnp"])
    cases["byte_unassociated"] = Smooth(case(dict(projection="BOX", projection_blend=0.4, extension="MIRROR"), CUBE,
                                             image_args=("byte_srgb", False), alpha_linked=True), NORMALS["pnn"])
    check(bake_smooth(cases))


# ---- UDIM tiles and image sequences: files on disk ---------------------------------------------

TILES = {1001: (16, 12), 1002: (8, 8), 1011: (12, 16)}


def _write(path: str, width: int, height: int, seed: int, is_float: bool = True):
    """An image file of noise: OpenEXR float (written with the OpenEXR module, so that no colour
    management touches it), or 8-bit PNG (Blender writes a byte image's bytes as they are)."""
    pixels = _pattern(seed, width, height)
    if is_float:
        pixels[..., :3] *= 2.0
        OpenEXR.File({"type": OpenEXR.scanlineimage}, {"RGBA": np.ascontiguousarray(pixels[::-1])}).write(path)
        return
    made = bpy.data.images.new("written", width, height, alpha=True)
    made.pixels.foreach_set(pixels.ravel())
    made.filepath_raw, made.file_format = path, "PNG"
    made.save()
    bpy.data.images.remove(made)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """UDIM tiles of three sizes (1003 and 1012 missing), and a sequence of three 8-bit frames."""
    folder = tmp_path_factory.mktemp("images")
    for number, (w, h) in TILES.items():
        _write(str(folder / f"tiles.{number}.exr"), w, h, number)
    for frame in (1, 2, 3):
        _write(str(folder / f"frame_{frame:03d}.png"), 10 + frame, 9, frame, is_float=False)
    return folder


def _udim(folder):
    def make():
        found = bpy.data.images.get("tiles.1001.exr")
        if found is None:
            found = bpy.data.images.load(str(folder / "tiles.1001.exr"))
            found.source = "TILED"
        return found
    return make


def test_udim_tiles_match_cycles(files):
    """Each point reads the tile its coordinate's integer parts name, at the coordinate less
    them, extended within the tile; -1 < u < 0 truncates to tile 1001; a missing tile, u < -1
    or v < -1 is magenta. Box projection reads tile 1001."""
    make = _udim(files)
    across = uv_sweep(lo=(-1.3, -1.2), hi=(2.7, 2.4))
    cases = {f"{i}_{e}": _with_image(dict(interpolation=i, extension=e), make, across)
             for i in INTERPOLATIONS for e in ("REPEAT", "EXTEND", "CLIP")}
    cases["alpha"] = _with_image(dict(interpolation="Cubic", extension="MIRROR"), make, across, output="Alpha")
    cases["sphere"] = _with_image(dict(projection="SPHERE"), make, CUBE)
    check(node_bake.bake(cases))
    box = {"box": Smooth(_with_image(dict(projection="BOX", projection_blend=0.2), make, across),
                         NORMALS["ppp"])}
    check(bake_smooth(box))


def _sequence(folder):
    def make():
        found = bpy.data.images.get("frame_001.png")
        if found is None:
            found = bpy.data.images.load(str(folder / "frame_001.png"))
            found.source = "SEQUENCE"
        return found
    return make


# Image users at scene frame 1: (frame_start, frame_duration, frame_offset, use_cyclic) -> the
# frame shown (BKE_image_user_frame_get).
USERS = {
    "first": ((1, 3, 0, False), 1),
    "offset": ((1, 3, 1, False), 2),
    "started_before": ((-1, 3, 0, False), 3),
    "held_at_start": ((4, 3, 1, False), 1),
    "held_at_end": ((-9, 2, 1, False), 3),
    "cyclic": ((-3, 3, 0, True), 2),
    "cyclic_wrapped": ((-1, 3, 0, True), 3),
    "cyclic_past": ((-2, 3, 1, True), 2),
}


def _heard(monkeypatch, expected: str) -> list:
    """Warnings of the graph export that contain `expected`, kept aside (the harness allows
    none); others still fail the bake."""
    heard = []
    export = node_bake.export_graph

    def export_graph(sockets, warn=None):
        def sort(text):
            if expected in text:
                heard.append(text)
            else:
                warn(text)
        return export(sockets, sort)
    monkeypatch.setattr(node_bake, "export_graph", export_graph)
    return heard


def test_image_sequences_read_the_scene_frames_file(files, monkeypatch):
    """Each node reads the frame its ImageUser shows at the scene's frame; a frame whose file
    is missing is magenta, with a warning."""
    heard = _heard(monkeypatch, "is missing")
    make = _sequence(files)
    cases = {}
    for name, ((start, duration, offset, cyclic), frame) in USERS.items():
        user = dict(frame_start=start, frame_duration=duration, frame_offset=offset, use_cyclic=cyclic)
        cases[name] = _with_image(dict(interpolation="Linear", extension="EXTEND"), make, user=user)
    cases["missing"] = _with_image(dict(), make, user=dict(frame_duration=3, frame_offset=5))
    results = node_bake.bake(cases)
    check(results)
    assert np.allclose(results["missing"][0], [1.0, 0.0, 1.0]) and len(heard) == 1
    from ember.engine.blender.export_image import frame_number
    for name, ((start, duration, offset, cyclic), frame) in USERS.items():
        user = type("User", (), dict(frame_start=start, frame_duration=duration, frame_offset=offset,
                                     use_cyclic=cyclic))
        assert frame_number(user, 1) == frame, name


# ---- image files: what Cycles reads with OpenImageIO, Ember through Blender -------------------

# name -> (file format, colour mode, depth) as Blender writes them.
FORMATS = {"rgba8.png": ("PNG", "RGBA", "8"), "rgb8.png": ("PNG", "RGB", "8"), "grey8.png": ("PNG", "BW", "8"),
           "rgb16.png": ("PNG", "RGB", "16"), "rgba16.png": ("PNG", "RGBA", "16"),
           "rgba.exr": ("OPEN_EXR", "RGBA", "32"), "grey.exr": ("OPEN_EXR", "BW", "16"), "rgb.jpg": ("JPEG", "RGB", None),
           "rgba.tif": ("TIFF", "RGBA", "8"), "rgba.tga": ("TARGA", "RGBA", None)}


@pytest.fixture(scope="module")
def formats(tmp_path_factory):
    folder = tmp_path_factory.mktemp("formats")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = "Standard"
    settings = scene.render.image_settings
    for k, (name, (kind, mode, depth)) in enumerate(FORMATS.items()):
        source = bpy.data.images.new("source", WIDTH, HEIGHT, alpha=True, float_buffer=True)
        source.pixels.foreach_set(_pattern(100 + k).ravel())
        settings.file_format, settings.color_mode = kind, mode
        if depth is not None:
            settings.color_depth = depth
        source.save_render(str(folder / name), scene=scene)
        bpy.data.images.remove(source)
    return folder


def _file(folder, name: str, colorspace=None, pack: bool = False):
    def make():
        key = f"{name}:{colorspace}:{pack}"
        found = bpy.data.images.get(key)
        if found is None:
            found = bpy.data.images.load(str(folder / name))
            found.name = key
            if colorspace is not None:
                found.colorspace_settings.name = colorspace
            if pack:
                found.pack()
        return found
    return make


def test_image_files_match_cycles(formats):
    """8-bit PNG (RGBA, RGB, grey), JPEG, TIFF, Targa, OpenEXR (RGBA, grey) and 16-bit PNG,
    read from disk (Cycles' OpenImageIO: grey files are one channel, 16-bit sRGB stays sRGB
    and is premultiplied in 16 bits) and packed (Cycles reads Blender's buffer)."""
    cases = {}
    for name in FORMATS:
        cases[name] = _with_image(dict(interpolation="Cubic"), _file(formats, name))
        cases[f"{name}_alpha"] = _with_image(dict(interpolation="Linear"), _file(formats, name), output="Alpha")
    cases["rgba8_non_color"] = _with_image(dict(interpolation="Linear"), _file(formats, "rgba8.png", "Non-Color"))
    cases["rgba8_packed"] = _with_image(dict(interpolation="Linear"), _file(formats, "rgba8.png", pack=True))
    cases["rgba16_packed"] = _with_image(dict(interpolation="Linear"), _file(formats, "rgba16.png", pack=True))
    cases["rgb16_packed"] = _with_image(dict(interpolation="Linear"), _file(formats, "rgb16.png", pack=True))
    cases["rgba8_unassociated"] = _unassociated(_file(formats, "rgba8.png"))
    check(node_bake.bake(cases))


def _unassociated(make):
    def build(nt):
        n = nt.nodes.new("ShaderNodeTexImage")
        n.image = make()
        nt.links.new(uv_sweep()(nt), n.inputs["Vector"])
        add = nt.nodes.new("ShaderNodeVectorMath")
        nt.links.new(n.outputs["Color"], add.inputs[0])
        nt.links.new(n.outputs["Alpha"], add.inputs[1])
        return add.outputs[0]
    return build


# ---- what no bake shows -------------------------------------------------------------------------

def test_sources_ember_cannot_read_exactly_warn():
    """Byte images in colour spaces Cycles converts with OpenColorIO, movies, and UDIM tiles
    held only in memory export with a warning (the bakes above show the rest)."""
    from ember.engine.blender.export_image import image_texels, sequence_path
    from ember.engine.nodes.image import Texels, Tiles
    bpy.ops.wm.read_factory_settings(use_empty=True)
    heard = []
    context = type("Context", (), dict(node=None, path=(), warn=heard.append))
    acescg = image("acescg", False, "ACEScg")
    assert isinstance(image_texels(acescg, context), Texels) and "ACEScg" in heard[-1]
    tiled = bpy.data.images.new("tiled", 4, 4, tiled=True)
    tiled.tiles.new(tile_number=1002)
    tiles = image_texels(tiled, context)
    assert isinstance(tiles, Tiles) and [n for n, _ in tiles.tiles] == [1001, 1002] and "UDIM" in heard[-1]
    assert sequence_path("//render/shot_0042.v2.png", 7) == "//render/shot_0042.v7.png"
    assert sequence_path("/a/b/frame_001.exr", 12) == "/a/b/frame_012.exr"
    assert sequence_path("/a/b/frame_99.exr", 123) == "/a/b/frame_123.exr"
    assert len(heard) == 2


def test_constant_coordinates_fold_and_box_reads_the_normal():
    """A Flat, Sphere or Tube texture fed constants is evaluated once, at compile time; Box reads
    the shading normal and the object's transform; an unlinked Vector reads the UV map."""
    from ember.engine.nodes.graph import Graph, Input, Link, Node
    from ember.engine.nodes.image import Texels
    from ember.engine.nodes.program import compile
    texels = Texels("t", _pattern(3))
    for projection, reads in (("FLAT", set()), ("SPHERE", set()), ("BOX", {"N", "world_from_object"})):
        tex = Node("ShaderNodeTexImage", "t", (("image", texels), ("projection", projection)),
                   (Input("Vector", "vector", (0.2, 0.7, 0.4), Link(0, "Vector", "vector")),),
                   (("Color", "rgba"), ("Alpha", "value")))
        value = Node("ShaderNodeCombineXYZ", "c", (), (Input("X", "value", 0.2), Input("Y", "value", 0.7),
                                                       Input("Z", "value", 0.4)), (("Vector", "vector"),))
        graph = Graph((value, tex), (("out", Input("out", "rgba", (0, 0, 0), Link(1, "Color", "rgba"))),))
        program = compile(graph, {"out": "rgba"})
        assert set(program.reads) == reads and (not program.ops) == (not reads), projection
    unlinked = Node("ShaderNodeTexImage", "t", (("image", texels),), (Input("Vector", "vector", (0, 0, 0)),),
                    (("Color", "rgba"), ("Alpha", "value")))
    graph = Graph((unlinked,), (("out", Input("out", "value", 0.0, Link(0, "Alpha", "value"))),))
    assert set(compile(graph, {"out": "value"}).reads) == {"uv"}
