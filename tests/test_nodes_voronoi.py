"""Voronoi Texture against Cycles (tests/node_bake.py): every dimension, feature, metric and
output, the fractal octaves (integer, fractional and per-point Detail, Roughness, Lacunarity,
Normalize), and Smoothness, Exponent, Randomness and Scale at their edges (zero, clamped, per
point). Coordinates are the Generated ones (the Vector unlinked) or a UV-driven vector that
crosses zero, so negative cells and their hashes are met; cells are small (about 3 texels
across) so each case meets hundreds of them. Also the hash functions against values printed
by a C build of Cycles' util/hash.h."""
import numpy as np
import pytest

from ember.engine.nodes import hash as H
from ember.engine.nodes import voronoi as voronoi_module

pytestmark = pytest.mark.blender

import node_bake  # noqa: E402

FEATURES = ("F1", "F2", "SMOOTH_F1")
METRICS = ("EUCLIDEAN", "MANHATTAN", "CHEBYCHEV", "MINKOWSKI")
OUTPUTS = {"1D": ("Distance", "Color", "W"), "2D": ("Distance", "Color", "Position"),
           "3D": ("Distance", "Color", "Position"), "4D": ("Distance", "Color", "Position", "W")}


def _socket(sockets, identifier):
    # Blender 5 hides the sockets a mode does not use from lookups by name.
    return next(s for s in sockets if s.identifier == identifier)


def _sweep(nt, axis: str, lo: float, hi: float):
    """lo + (hi - lo) * the UV coordinate `axis` (X: u, Y: v)."""
    coord = nt.nodes.new("ShaderNodeTexCoord")
    split = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(coord.outputs["UV"], split.inputs["Vector"])
    m = nt.nodes.new("ShaderNodeMath")
    m.operation = "MULTIPLY_ADD"
    nt.links.new(split.outputs[axis], m.inputs[0])
    m.inputs[1].default_value, m.inputs[2].default_value = hi - lo, lo
    return m.outputs[0]


def sweep(axis: str, lo: float, hi: float):
    return lambda nt: _sweep(nt, axis, lo, hi)


def uv_vector(lo: float, hi: float, z: float):
    """(u, v) mapped to [lo, hi]^2, at height z: crosses zero when lo < 0 < hi."""
    def build(nt):
        c = nt.nodes.new("ShaderNodeCombineXYZ")
        nt.links.new(_sweep(nt, "X", lo, hi), c.inputs["X"])
        nt.links.new(_sweep(nt, "Y", lo, hi), c.inputs["Y"])
        c.inputs["Z"].default_value = z
        return c.outputs[0]
    return build


def voronoi(dims: str, feature: str, output: str, metric: str = "EUCLIDEAN", normalize: bool = False,
            **inputs):
    """A case: the Voronoi node's `output`; inputs are values or builders of linked sockets.
    Unless given, Scale is 9.3 over the Generated coordinate and W sweeps [-0.43, 0.54] (times Scale)."""
    inputs.setdefault("Scale", 9.3)
    inputs.setdefault("W", sweep("X", -0.43, 0.54))

    def build(nt):
        v = nt.nodes.new("ShaderNodeTexVoronoi")
        v.voronoi_dimensions, v.feature, v.distance, v.normalize = dims, feature, metric, normalize
        for name, value in inputs.items():
            socket = _socket(v.inputs, name)
            if callable(value):
                nt.links.new(value(nt), socket)
            else:
                socket.default_value = value
        return _socket(v.outputs, output)
    return build


def _check(cases: dict, size: int = node_bake.SIZE):
    results = node_bake.bake(cases, size)
    scores = {name: node_bake.agreement(c, e) for name, (c, e) in results.items()}
    bad = {name: round(s, 4) for name, s in scores.items() if s < 0.999}
    # every case must vary over the plane, or it would test nothing
    flat = [name for name, (c, _) in results.items() if np.ptp(c) == 0.0]
    assert bad == {} and flat == [], (bad, flat)
    return scores


def test_every_dimension_feature_metric_and_output():
    cases = {}
    for dims, outputs in OUTPUTS.items():
        for feature in FEATURES:
            for metric in METRICS if dims != "1D" else ("EUCLIDEAN", "MINKOWSKI"):
                for output in outputs:
                    cases[f"{dims}-{feature}-{metric}-{output}"] = voronoi(dims, feature, output, metric)
        cases[f"{dims}-DISTANCE_TO_EDGE"] = voronoi(dims, "DISTANCE_TO_EDGE", "Distance")
        cases[f"{dims}-N_SPHERE_RADIUS"] = voronoi(dims, "N_SPHERE_RADIUS", "Radius")
    _check(cases)


def test_negative_coordinates_and_other_parameters():
    """A linked vector through zero (negative cells: the PCG hash's sign bit, the float hash of
    -1.0 ...), Minkowski exponents, partial and zero randomness, smoothness."""
    vector = uv_vector(-3.1, 2.9, -0.77)
    w = sweep("Y", -5.3, 4.1)
    cases = {}
    for dims, outputs in OUTPUTS.items():
        base = dict(Vector=vector, W=w, Scale=2.3)
        for feature in FEATURES + ("DISTANCE_TO_EDGE", "N_SPHERE_RADIUS"):
            output = {"DISTANCE_TO_EDGE": "Distance", "N_SPHERE_RADIUS": "Radius"}.get(feature)
            for out in (output,) if output else outputs:
                cases[f"{dims}-{feature}-{out}-negative"] = voronoi(dims, feature, out, **base)
            for r in (0.41,) if feature == "N_SPHERE_RADIUS" else (0.0, 0.41):  # 0: all radii 0.5
                cases[f"{dims}-{feature}-randomness{r}"] = voronoi(dims, feature, output or "Distance",
                                                                   Randomness=r, **base)
        if dims != "1D":
            for e in (1.0, 3.7, 0.31):
                cases[f"{dims}-minkowski{e}"] = voronoi(dims, "F1", "Distance", "MINKOWSKI", Exponent=e)
                cases[f"{dims}-minkowski{e}-F2"] = voronoi(dims, "F2", "Distance", "MINKOWSKI", Exponent=e)
            cases[f"{dims}-minkowski-per-point"] = voronoi(dims, "SMOOTH_F1", "Distance", "MINKOWSKI",
                                                           Exponent=sweep("X", 0.4, 4.0))
        for s in (0.0, 0.35, 1.6):  # 0: F1; above 1 the kernel clamps it (to 0.5 after halving)
            for out in ("Distance", "Color"):
                cases[f"{dims}-smooth{s}-{out}"] = voronoi(dims, "SMOOTH_F1", out, Smoothness=s, **base)
        cases[f"{dims}-smooth-per-point"] = voronoi(dims, "SMOOTH_F1", "Distance",
                                                    Smoothness=sweep("X", -0.3, 1.2))
        cases[f"{dims}-randomness-per-point"] = voronoi(dims, "F2", "Color", Randomness=sweep("Y", -0.2, 1.3))
        cases[f"{dims}-scale-per-point"] = voronoi(dims, "F1", outputs[-1], Scale=sweep("X", 3.0, 12.0))
        cases[f"{dims}-scale-negative"] = voronoi(dims, "F1", outputs[-1], Scale=-7.7)
        cases[f"{dims}-constant-vector"] = voronoi(dims, "F2", "Distance", Vector=_constant_vector(0.3, -0.6, 0.45),
                                                   W=0.7, Randomness=sweep("X", 0.0, 1.0))
    _check(cases)


def _snapped(nt, axis: str):
    coord = nt.nodes.new("ShaderNodeTexCoord")
    split = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(coord.outputs["UV"], split.inputs["Vector"])
    m = nt.nodes.new("ShaderNodeMath")
    m.operation = "SNAP"
    nt.links.new(split.outputs[axis], m.inputs[0])
    m.inputs[1].default_value = 1.0 / 4096
    return m.outputs[0]


def snapped_uv(nt):
    """The UV coordinate snapped to multiples of 1/4096 (at z 0.5): the same float32 numbers in
    Cycles and here. Interpolated coordinates differ from Cycles' by a float32 rounding, which
    scales of 10^4 (or a Detail of 15 at Roughness 1) make larger than the tolerance; on
    snapped ones what is left is the node's own arithmetic."""
    c = nt.nodes.new("ShaderNodeCombineXYZ")
    for axis in "XY":
        nt.links.new(_snapped(nt, axis), c.inputs[axis])
    c.inputs["Z"].default_value = 0.5
    return c.outputs[0]


def test_float32_coordinates_at_large_scales():
    """Cells picked by float32 coordinates as Cycles picks them: Scale 10^4 (coordinates whose
    float32 steps are 1e-3) and 15 octaves at full Roughness (the last at 2.3^15 times the
    scale, the octave scales multiplied up in float32)."""
    cases = {}
    for dims in ("1D", "2D", "3D", "4D"):
        for feature in FEATURES + ("DISTANCE_TO_EDGE",):
            cases[f"{dims}-{feature}-scale1e4"] = voronoi(dims, feature, "Distance", Scale=10000.3, Vector=snapped_uv,
                                                          W=lambda nt: _snapped(nt, "Y"))
        cases[f"{dims}-detail15"] = voronoi(dims, "F1", "Distance", Detail=15.0, Roughness=1.0, Lacunarity=2.3,
                                            Vector=snapped_uv,
                                            W=lambda nt: _snapped(nt, "Y"))
    _check(cases)


def _constant_vector(x, y, z):
    def build(nt):
        c = nt.nodes.new("ShaderNodeCombineXYZ")
        for axis, value in zip("XYZ", (x, y, z)):
            c.inputs[axis].default_value = value
        return c.outputs[0]
    return build


def test_points_in_chunks(monkeypatch):
    """Batches larger than a chunk go through in parts (here of 300 points, so the last part
    is short), per-point and constant inputs alike."""
    monkeypatch.setattr(voronoi_module, "CHUNK", 300)
    cases = {}
    for dims, outputs in OUTPUTS.items():
        for feature in FEATURES:
            cases[f"{dims}-{feature}"] = voronoi(dims, feature, outputs[-1], Detail=sweep("X", 0.0, 2.0),
                                                 normalize=True)
        cases[f"{dims}-constant-vector"] = voronoi(dims, "SMOOTH_F1", "Color", Vector=_constant_vector(0.3, -0.6, 0.45),
                                                   W=0.7, Randomness=sweep("X", 0.0, 1.0))
        cases[f"{dims}-edge"] = voronoi(dims, "DISTANCE_TO_EDGE", "Distance", Detail=1.5)
    _check(cases)


def test_fractal_octaves_and_normalize():
    cases = {}
    for dims, outputs in OUTPUTS.items():
        for feature in FEATURES + ("DISTANCE_TO_EDGE",):
            for normalize in (False, True):
                for detail in (2.0, 2.6):
                    # Normalize divides Distance and Color only
                    for out in outputs if not normalize else ("Distance", "Color"):
                        if feature == "DISTANCE_TO_EDGE" and out != "Distance":
                            continue
                        cases[f"{dims}-{feature}-detail{detail}-norm{normalize}-{out}"] = voronoi(
                            dims, feature, out, normalize=normalize, Scale=3.1, Detail=detail,
                            Roughness=0.63, Lacunarity=2.3)
            cases[f"{dims}-{feature}-detail-per-point"] = voronoi(
                dims, feature, "Distance", normalize=True, Scale=3.1, Detail=sweep("X", -0.5, 3.5),
                Roughness=sweep("Y", -0.1, 0.9), Lacunarity=1.7)
            cases[f"{dims}-{feature}-roughness0"] = voronoi(dims, feature, "Distance", normalize=True,
                                                            Detail=3.0, Roughness=0.0)
        cases[f"{dims}-F1-lacunarity-per-point"] = voronoi(
            dims, "F1", outputs[-1], Scale=2.7, Detail=1.5, Lacunarity=sweep("Y", 0.5, 3.0))
        cases[f"{dims}-MINKOWSKI-normalized"] = voronoi(dims, "F2", "Distance", "MINKOWSKI", normalize=True,
                                                        Detail=1.3, Exponent=1.9, Randomness=0.7)
    _check(cases)


def test_hashes_match_cycles_bit_for_bit():
    """Values printed by util/hash.h compiled with a C compiler (uint32 and int32 wrapping)."""
    bits = lambda f: H.float_bits(np.float32(f))  # noqa: E731
    assert [int(H.hash_uint(k)) for k in (0, 1, 0xFFFFFFFF)] == [2501500005, 1255655072, 1116397369]
    assert int(H.hash_uint2(1, 2)) == 272092061
    assert int(H.hash_uint2(bits(-3.0), bits(1.0))) == 2312180040
    assert int(H.hash_uint3(1, 2, 3)) == 3100736010
    assert int(H.hash_uint3(bits(-0.0), bits(7.0), bits(2.0))) == 1389192149
    assert int(H.hash_uint4(1, 2, 3, 4)) == 92593857
    assert int(H.hash_uint4(bits(-5.0), bits(0.0), bits(12.0), bits(1.0))) == 1061567495
    assert float(H.hash_float(-2.0)) == float(np.float32(0.0757429525))
    assert [int(v) for v in H.hash_pcg2d_i(3, -7)] == [535200693, 530612707]
    assert [int(v) for v in H.hash_pcg3d_i(-1, 0, 5)] == [366783755, 1242854365, 231447579]
    assert [int(v) for v in H.hash_pcg3d_i(np.array([123456]), np.array([-654321]), np.array([0]))[2]] == [133895375]
    assert [int(v) for v in H.hash_pcg4d_i(2, -3, 4, -100000)] == [100803113, 2110546178, 1326738341, 188238666]
    assert float(H.hash_int2_to_float2(3, -7)[0]) == float(np.float32(0.249222249))
