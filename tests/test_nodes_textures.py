"""Noise, White Noise, Gradient, Checker, Magic, Wave and Brick textures against Cycles
(tests/node_bake.py): every mode Blender offers, with scales that put many cells, bands,
bricks and octaves across the plane, fractional details, distortion, the colour outputs, and
the nodes' texture mapping. All cases bake in one call; each is asserted on its own."""
import numpy as np
import pytest

pytestmark = pytest.mark.blender

import node_bake  # noqa: E402
from ember.engine.nodes.graph import Input, Link, Node  # noqa: E402
from ember.engine.nodes.registry import REGISTRY  # noqa: E402
from ember.engine.nodes.textures import NODES  # noqa: E402

SIZE = 64  # texels per side: 4096 points per case, so 99.9 % allows 4 disagreeing texels
NOISE_TYPES = ("FBM", "MULTIFRACTAL", "HYBRID_MULTIFRACTAL", "HETERO_TERRAIN", "RIDGED_MULTIFRACTAL")
DIMENSIONS = ("1D", "2D", "3D", "4D")


def _sweep(nt, axis: str, lo: float, hi: float):
    """A value running from lo to hi across the plane along UV axis "X" or "Y"."""
    coord = nt.nodes.new("ShaderNodeTexCoord")
    split = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(coord.outputs["UV"], split.inputs["Vector"])
    m = nt.nodes.new("ShaderNodeMath")
    m.operation = "MULTIPLY_ADD"
    nt.links.new(split.outputs[axis], m.inputs[0])
    m.inputs[1].default_value, m.inputs[2].default_value = hi - lo, lo
    return m.outputs[0]


def _math(nt, operation, *args):
    """A Math node of sockets or constants."""
    m = nt.nodes.new("ShaderNodeMath")
    m.operation = operation
    for socket, value in zip(m.inputs, args):
        if isinstance(value, (int, float)):
            socket.default_value = value
        else:
            nt.links.new(value, socket)
    return m.outputs[0]


def _vector(nt, x, y, z):
    """A Combine XYZ of sockets or constants."""
    c = nt.nodes.new("ShaderNodeCombineXYZ")
    for socket, value in zip(c.inputs, (x, y, z)):
        if isinstance(value, (int, float)):
            socket.default_value = value
        else:
            nt.links.new(value, socket)
    return c.outputs[0]


def _texture(kind, output, props=None, inputs=None, links=None, mapping=None):
    """A case: node `kind` with settings `props`, input values `inputs`, inputs linked from
    `links` {socket: build(nt) -> output socket}, texture mapping `mapping` {attr: value};
    the output `output` is tested."""
    def build(nt):
        n = nt.nodes.new(kind)
        for key, value in (props or {}).items():
            setattr(n, key, value)
        for key, value in (inputs or {}).items():
            if key in n.inputs:
                n.inputs[key].default_value = value
        for key, make in (links or {}).items():
            if key in n.inputs:  # a socket the node's mode hides is not there to link
                nt.links.new(make(nt), n.inputs[key])
        for key, value in (mapping or {}).items():
            setattr(n.texture_mapping, key, value)
        return n.outputs[output]
    return build


def _snapped(nt, n=64):
    """The UV coordinate snapped to the texel grid, floor(uv * n) / n, with z = x - y: values
    exact in float32 on both sides, so high octaves (whose coordinates are large and whose
    float32 steps are wide) see the same coordinates as the kernel's."""
    coord = nt.nodes.new("ShaderNodeTexCoord")
    split = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(coord.outputs["UV"], split.inputs["Vector"])
    x, y = (_math(nt, "DIVIDE", _math(nt, "FLOOR", _math(nt, "MULTIPLY", split.outputs[k], float(n))), float(n))
            for k in range(2))
    return _vector(nt, x, y, _math(nt, "SUBTRACT", x, y))


def _far(shift):
    """_snapped scaled by 7 and moved by `shift` along x and y (one float32 rounding, the
    same on both sides): noise wraps coordinates every 1e5 and nudges them past 1e6."""
    def make(nt):
        v = _snapped(nt)
        split = nt.nodes.new("ShaderNodeSeparateXYZ")
        nt.links.new(v, split.inputs["Vector"])
        x, y = (_math(nt, "MULTIPLY_ADD", split.outputs[k], 7.0, shift) for k in range(2))
        return _vector(nt, x, y, split.outputs[2])
    return make


def _w_sweep(nt):
    return _sweep(nt, "X", -1.3, 2.1)


# --- Noise Texture --------------------------------------------------------------------------

def _noise(dimensions, noise_type, output="Fac", normalize=True, mapping=None, links=None, **inputs):
    values = {"Scale": 9.0, "Detail": 4.6, "Roughness": 0.6, "Lacunarity": 2.13, "Offset": 0.35,
              "Gain": 1.3, "Distortion": 0.0, "W": 0.37}
    values.update(inputs)
    links = dict(links or {})
    if dimensions == "1D" and "W" not in links:
        links["W"] = _w_sweep
    return _texture("ShaderNodeTexNoise", output,
                    {"noise_dimensions": dimensions, "noise_type": noise_type, "normalize": normalize},
                    values, links, mapping)


def noise_cases():
    cases = {}
    for d in DIMENSIONS:
        for t in NOISE_TYPES:
            cases[f"noise {d} {t}"] = _noise(d, t)
            cases[f"noise {d} {t} colour distorted"] = _noise(d, t, "Color", Detail=2.3, Distortion=0.8)
        cases[f"noise {d} FBM raw"] = _noise(d, "FBM", normalize=False, Detail=3.0, Roughness=0.7)
        cases[f"noise {d} FBM detail 0"] = _noise(d, "FBM", Detail=0.0, Scale=23.0)
        cases[f"noise {d} FBM detail 15"] = _noise(d, "FBM", Detail=15.0, Roughness=0.5, Lacunarity=1.7)
    cases["noise 3D FBM detail 21 (clamped to 15)"] = _noise("3D", "FBM", Detail=21.0, Lacunarity=1.7)
    detail = {"Detail": lambda nt: _sweep(nt, "Y", 0.0, 6.0)}
    for t in NOISE_TYPES:
        cases[f"noise 3D {t} detail per point"] = _noise("3D", t, links=detail)
        cases[f"noise 3D {t} roughness 0"] = _noise("3D", t, Roughness=0.0, Detail=3.5)
        # Large values over many octaves: on exact coordinates (_snapped), as the plane's
        # Generated coordinate differs from the kernel's by float32 ulps, which these amplify.
        cases[f"noise 3D {t} big"] = _noise("3D", t, Scale=31.0, Detail=6.7, Roughness=0.8, Offset=1.0, Gain=2.0,
                                            links={"Vector": _snapped})
    for shift in (123456.0, -2500000.0):
        for d in DIMENSIONS:
            w = {"W": lambda nt, shift=shift: _math(nt, "ADD", _w_sweep(nt), shift)}
            cases[f"noise {d} far {shift:g}"] = _noise(d, "FBM", Scale=1.0, Detail=1.0,
                                                        links=dict(w, Vector=_far(shift)))
    cases["noise 2D lacunarity per point"] = _noise("2D", "FBM",
                                                    links={"Lacunarity": lambda nt: _sweep(nt, "Y", 1.0, 3.0)})
    cases["noise 4D W per point"] = _noise("4D", "FBM", links={"W": _w_sweep})
    cases["noise 3D scale per point"] = _noise("3D", "FBM", links={"Scale": lambda nt: _sweep(nt, "Y", 2.0, 20.0)})
    cases["noise constant vector"] = _noise("3D", "HETERO_TERRAIN", "Color", Distortion=0.3,
                                            links={"Vector": lambda nt: _vector(nt, 0.3, -1.7, 2.2)})
    return cases


def mapping_cases():
    base = {"translation": (0.3, -0.7, 0.2), "rotation": (0.4, -0.3, 1.1), "scale": (1.5, 0.8, -2.0)}
    cases = {}
    for vector_type in ("POINT", "TEXTURE", "VECTOR", "NORMAL"):
        cases[f"mapping {vector_type}"] = _noise("3D", "FBM", mapping=dict(base, vector_type=vector_type), Detail=1.0)
    cases["mapping axes"] = _noise("3D", "FBM", mapping={"mapping_x": "Y", "mapping_y": "NONE", "mapping_z": "X"})
    cases["mapping min max (not synced)"] = _noise("3D", "FBM", mapping={"use_min": True, "min": (0.4, 0.4, 0.4)})

    def colour_mapped(nt):  # Cycles does not apply a texture's ColorMapping
        socket = _noise("3D", "FBM", "Color")(nt)
        socket.node.color_mapping.brightness, socket.node.color_mapping.saturation = 1.7, 0.3
        return socket
    cases["colour mapping (not synced)"] = colour_mapped
    return cases


# --- White Noise ----------------------------------------------------------------------------

def _cells(nt, n=13.0):
    """The Generated coordinate snapped to a lattice of n cells, shifted to take in negative
    cells: integers, exact in float32, so the hashed bits are the kernel's."""
    coord = nt.nodes.new("ShaderNodeTexCoord")
    split = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(coord.outputs["Generated"], split.inputs["Vector"])
    return [_math(nt, "FLOOR", _math(nt, "MULTIPLY_ADD", split.outputs[k], n, -n / 2 + 0.25 * k)) for k in range(3)]


def _cell_vector(nt):
    x, y, z = _cells(nt)
    return _vector(nt, x, y, _math(nt, "MULTIPLY", z, 0.5))


def _cell_w(nt):
    return _math(nt, "FLOOR", _sweep(nt, "Y", -7.0, 9.0))


def white_noise_cases():
    cases = {}
    for d in DIMENSIONS:
        props = {"noise_dimensions": d}
        for output in ("Value", "Color"):
            cases[f"white noise {d} {output}"] = _texture("ShaderNodeTexWhiteNoise", output, props, {"W": 0.75},
                                                           {"Vector": _cell_vector, "W": _cell_w})
        # Cycles gives White Noise's Vector no default link: unlinked, it hashes (0, 0, 0).
        cases[f"white noise {d} unlinked"] = _texture("ShaderNodeTexWhiteNoise", "Color", props, {"W": 0.25})
    return cases


# --- Gradient, Checker, Magic ---------------------------------------------------------------

_CENTRED = {"translation": (-0.55, -0.45, -0.5), "scale": (2.2, 2.2, 2.2)}  # POINT: (p + t) * s, in [-1.2, 1]


def gradient_cases():
    cases = {}
    for t in ("LINEAR", "QUADRATIC", "EASING", "DIAGONAL", "SPHERICAL", "QUADRATIC_SPHERE", "RADIAL"):
        cases[f"gradient {t}"] = _texture("ShaderNodeTexGradient", "Fac", {"gradient_type": t}, mapping=_CENTRED)
        cases[f"gradient {t} colour"] = _texture("ShaderNodeTexGradient", "Color", {"gradient_type": t},
                                                 mapping={"scale": (1.3, 1.3, 1.3)})
    return cases


def checker_cases():
    colours = {"Color1": (0.9, 0.2, 0.1, 1.0), "Color2": (0.05, 0.3, 0.7, 1.0)}
    return {"checker": _texture("ShaderNodeTexChecker", "Fac", inputs={"Scale": 11.3}, mapping=_CENTRED),
            "checker colour": _texture("ShaderNodeTexChecker", "Color", inputs=dict(colours, Scale=7.7)),
            "checker scale per point": _texture("ShaderNodeTexChecker", "Fac",
                                                links={"Scale": lambda nt: _sweep(nt, "Y", 3.0, 15.0)})}


def magic_cases():
    cases = {}
    # Each fold multiplies differences by up to the distortion: at depth 10 the plane's
    # Generated coordinate (float32 ulps off the kernel's) leaves a few texels apart, so the
    # deepest levels are also tested on exact coordinates (_snapped).
    for depth in range(10):
        cases[f"magic depth {depth}"] = _texture("ShaderNodeTexMagic", "Color", {"turbulence_depth": depth},
                                                 {"Scale": 3.1, "Distortion": 1.7})
    cases["magic fac"] = _texture("ShaderNodeTexMagic", "Fac", {"turbulence_depth": 4},
                                  {"Scale": 2.0, "Distortion": 0.6})
    cases["magic no distortion"] = _texture("ShaderNodeTexMagic", "Color", {"turbulence_depth": 0},
                                            {"Distortion": 0.0})
    for depth in (8, 9, 10):
        cases[f"magic depth {depth} snapped"] = _texture("ShaderNodeTexMagic", "Color", {"turbulence_depth": depth},
                                                         {"Scale": 3.1, "Distortion": 1.7}, links={"Vector": _snapped})
    cases["magic negative"] = _texture("ShaderNodeTexMagic", "Color", {"turbulence_depth": 2},
                                       {"Scale": 4.0, "Distortion": -1.2}, mapping=_CENTRED)
    return cases


# --- Wave -----------------------------------------------------------------------------------

_TILTED = {"rotation": (0.5, 0.3, 0.2), "translation": (-0.5, -0.5, -0.5)}  # z varies over the plane


def wave_cases():
    cases = {}
    for profile in ("SIN", "SAW", "TRI"):
        for direction in ("X", "Y", "Z", "DIAGONAL"):
            props = {"wave_type": "BANDS", "bands_direction": direction, "wave_profile": profile}
            cases[f"wave bands {direction} {profile}"] = _texture(
                "ShaderNodeTexWave", "Fac", props, {"Scale": 2.3, "Phase Offset": 0.7}, mapping=_TILTED)
        for direction in ("X", "Y", "Z", "SPHERICAL"):
            props = {"wave_type": "RINGS", "rings_direction": direction, "wave_profile": profile}
            cases[f"wave rings {direction} {profile}"] = _texture(
                "ShaderNodeTexWave", "Fac", props, {"Scale": 1.7, "Phase Offset": -0.4}, mapping=_TILTED)
    for detail in (0.0, 2.5, 7.0):
        cases[f"wave distorted detail {detail}"] = _texture(
            "ShaderNodeTexWave", "Color", {"wave_type": "BANDS", "bands_direction": "DIAGONAL"},
            {"Scale": 2.0, "Distortion": 6.0, "Detail": detail, "Detail Scale": 3.3, "Detail Roughness": 0.65})
    cases["wave rings distorted"] = _texture(
        "ShaderNodeTexWave", "Fac", {"wave_type": "RINGS", "rings_direction": "SPHERICAL", "wave_profile": "TRI"},
        {"Scale": 1.5, "Distortion": 3.0, "Detail": 4.0, "Detail Scale": 1.2}, mapping=_TILTED)
    return cases


# --- Brick ----------------------------------------------------------------------------------

def _brick(output="Color", props=None, mapping=None, **inputs):
    values = {"Scale": 4.0, "Color1": (0.8, 0.3, 0.1, 1.0), "Color2": (0.2, 0.6, 0.3, 1.0),
              "Mortar": (0.05, 0.05, 0.9, 1.0), "Mortar Size": 0.03, "Mortar Smooth": 0.2, "Bias": 0.1,
              "Brick Width": 0.4, "Row Height": 0.15}
    values.update(inputs)
    return _texture("ShaderNodeTexBrick", output, props, values, mapping=mapping)


def brick_cases():
    return {
        "brick": _brick(),
        "brick fac": _brick("Fac"),
        "brick negative": _brick(mapping=_CENTRED),
        "brick sharp mortar": _brick("Fac", **{"Mortar Smooth": 0.0, "Mortar Size": 0.05}),
        "brick offset squash": _brick(props={"offset": 0.3, "offset_frequency": 3, "squash": 0.6,
                                             "squash_frequency": 2}),
        "brick offset every row": _brick(props={"offset": 0.7, "offset_frequency": 1}),
        "brick squash every row": _brick(props={"squash": 2.5, "squash_frequency": 1}),
        "brick bias": _brick(**{"Bias": -0.4, "Brick Width": 0.9, "Row Height": 0.3}),
        "brick tint": _brick("Color", **{"Mortar Size": 0.0}),
    }


def all_cases():
    cases = {}
    for make in (noise_cases, mapping_cases, white_noise_cases, gradient_cases, checker_cases, magic_cases,
                 wave_cases, brick_cases):
        cases.update(make())
    return cases


CASES = all_cases()


GROUP = 20  # cases per bake: Blender's bake time grows faster than the number of objects


@pytest.fixture(scope="module")
def baked():
    names, results = sorted(CASES), {}
    for start in range(0, len(names), GROUP):
        results.update(node_bake.bake({k: CASES[k] for k in names[start:start + GROUP]}, SIZE))
    return results


@pytest.mark.parametrize("name", sorted(CASES), ids=lambda name: name.replace(" ", "_"))
def test_texture_matches_cycles(baked, name):
    cycles, ember = baked[name]
    assert np.std(cycles) > 0.0, "a case should vary over the plane, or between channels"
    assert node_bake.agreement(cycles, ember) >= 0.999


# --- Constants: what constant folding evaluates ---------------------------------------------

def _folding_cases():
    """(kind, props, scalar inputs, colour inputs) covering every texture and its modes."""
    noise = {"W": 0.7, "Scale": 3.0, "Detail": 3.5, "Roughness": 0.6, "Lacunarity": 2.0, "Offset": 0.2, "Gain": 1.1,
             "Distortion": 0.4}
    colours = {"Color1": (0.9, 0.2, 0.1), "Color2": (0.1, 0.3, 0.8), "Mortar": (0.0, 0.5, 0.0)}
    out = [("ShaderNodeTexNoise", {"noise_dimensions": d, "noise_type": t, "normalize": True}, noise, {})
           for d in DIMENSIONS for t in NOISE_TYPES]
    out += [("ShaderNodeTexWhiteNoise", {"noise_dimensions": d}, {"W": 0.3}, {}) for d in DIMENSIONS]
    out += [("ShaderNodeTexGradient", {"gradient_type": t}, {}, {})
            for t in ("LINEAR", "QUADRATIC", "EASING", "DIAGONAL", "SPHERICAL", "QUADRATIC_SPHERE", "RADIAL")]
    out += [("ShaderNodeTexChecker", {}, {"Scale": 4.0}, colours)]
    out += [("ShaderNodeTexMagic", {"turbulence_depth": k}, {"Scale": 3.0, "Distortion": 1.5}, {}) for k in (0, 5, 10)]
    out += [("ShaderNodeTexWave", {"wave_type": "RINGS", "rings_direction": "SPHERICAL", "wave_profile": p},
             {"Scale": 2.0, "Distortion": 2.0, "Detail": 2.5, "Detail Scale": 1.5, "Detail Roughness": 0.5,
              "Phase Offset": 0.3}, {}) for p in ("SIN", "SAW", "TRI")]
    out += [("ShaderNodeTexBrick", {"offset": 0.5, "offset_frequency": 2, "squash": 0.7, "squash_frequency": 3},
             {"Scale": 3.0, "Mortar Size": 0.05, "Mortar Smooth": 0.3, "Bias": 0.1, "Brick Width": 0.5,
              "Row Height": 0.25}, colours)]
    assert {k for k, *_ in out} == {t.kind for t in NODES}
    return out


def test_constant_inputs_give_each_point_its_value():
    """A texture of constant inputs (0-d scalars, (3,) vectors, as constant folding passes
    them) gives what it gives per point: evaluated at 5 points at once and at each alone."""
    rng = np.random.default_rng(3)
    vectors = rng.uniform(-2.0, 2.0, (5, 3))
    for kind, props, scalars, colours in _folding_cases():
        linked = Input("Vector", "vector", (0.0, 0.0, 0.0), Link(0, "Vector", "vector"))
        node = Node(kind, kind, tuple(sorted(props.items())), (linked,))
        base = {k: np.float64(v) for k, v in scalars.items()}
        base.update({k: np.array(v) for k, v in colours.items()})
        many = REGISTRY[kind].evaluate(node, dict(base, Vector=vectors), None)
        for output, value in many.items():
            value = value() if callable(value) else value
            for i, v in enumerate(vectors):
                one = REGISTRY[kind].evaluate(node, dict(base, Vector=v), None)[output]
                one = one() if callable(one) else one
                assert np.shape(one) == ((3,) if output == "Color" else ()), (kind, props, output)
                # (1D noise ignores the vector: its value is one constant for all 5 points)
                each = np.broadcast_to(value, (len(vectors),) + np.shape(one))[i]
                assert np.allclose(one, each, rtol=0.0, atol=1e-12), (kind, props, output)
