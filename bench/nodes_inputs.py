"""Cost per shading point of the input nodes (engine/nodes/geometry.py, attribute.py, fresnel.py,
light_path.py, normal_map.py, tangent.py, object_info.py, displacement.py, bump.py): each node
in a compiled program reading a synthetic shading state (points on random triangles), the best
of several runs in microseconds per point, process time (the machine is shared). A Bump's cost
is shown with its Height (a 3D noise) and beside that Height alone: the Bump runs the Height
subgraph three times. No Blender needed.

    ./dev python bench/nodes_inputs.py              # 100k points, every node
    ./dev python bench/nodes_inputs.py --points 20000 --only bump
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from _bootstrap import load_ember  # noqa: E402

load_ember()
from ember.engine.nodes import light_path  # noqa: E402
from ember.engine.nodes.graph import Graph, Input, Link, Node  # noqa: E402
from ember.engine.nodes.program import compile  # noqa: E402
from ember.engine.nodes.state import Attribute, ShadingState  # noqa: E402


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


class Source:
    """A batch of points on random triangles, every field the input nodes read."""

    def __init__(self, n: int, seed: int = 1):
        rng = np.random.default_rng(seed)
        self.n = n
        self.corners = rng.normal(size=(n, 3, 3))
        self.w = rng.dirichlet((1.0, 1.0, 1.0), n)
        self.made = {}
        e0, e1 = self.corners[:, 1] - self.corners[:, 0], self.corners[:, 2] - self.corners[:, 0]
        self.fields = dict(
            P=np.einsum("nk,nkc->nc", self.w, self.corners), Ng=_unit(np.cross(e0, e1)), dPdu=e0, dPdv=e1,
            triangle=self.corners, barycentric=self.w[:, 1:], dP=rng.uniform(0.001, 0.01, n),
            backfacing=np.zeros(n, bool), smooth=np.ones(n, bool), ray_length=rng.uniform(0.1, 10.0, n),
            uv=np.pad(rng.uniform(size=(n, 2)), [(0, 0), (0, 1)]), generated=rng.uniform(size=(n, 3)),
            uv_du=rng.normal(size=(n, 3)) * [1, 1, 0], uv_dv=rng.normal(size=(n, 3)) * [1, 1, 0],
            generated_du=rng.normal(size=(n, 3)), generated_dv=rng.normal(size=(n, 3)),
            object_color=np.tile([0.2, 0.5, 0.8], (n, 1)), object_alpha=np.ones(n), object_index=np.full(n, 3.0),
            object_random=np.full(n, 0.42), material_index=np.full(n, 1.0),
            path_flag=np.full(n, light_path.CAMERA, np.uint32), instancer_uv=np.zeros((n, 3)))
        self.fields["N"] = _unit(self.fields["Ng"] + rng.normal(scale=0.1, size=(n, 3)))
        self.fields["I"] = _unit(self.fields["N"] + rng.normal(scale=0.5, size=(n, 3)))
        self.fields["vertex_normal"] = self.fields["N"]
        self.fields["N_du"] = rng.normal(scale=0.1, size=(n, 3))
        self.fields["N_dv"] = rng.normal(scale=0.1, size=(n, 3))
        self.fields["object"] = self.fields["P"]
        m = np.eye(4)
        m[:3, :3] = [[1.2, 0.3, 0.0], [-0.2, 0.8, 0.1], [0.0, 0.2, 1.1]]
        m[:3, 3] = [0.5, -1.0, 2.0]
        self.fields["world_from_object"] = np.broadcast_to(m, (n, 4, 4))
        self.fields["object_from_world"] = np.broadcast_to(np.linalg.inv(m), (n, 4, 4))
        self.fields["camera_from_world"] = np.linalg.inv(m)
        for name in ("bounce", "diffuse_bounce", "glossy_bounce", "transmission_bounce", "transparent_bounce",
                     "portal_bounce"):
            self.fields[name] = np.zeros(n, np.int64)

    def attribute(self, name):
        """Made once per name: the run measures the nodes, not the synthetic attributes."""
        if name not in self.made:
            self.made[name] = self._attribute(name)
        return self.made[name]

    def _attribute(self, name):
        rng = np.random.default_rng(len(name))
        n = self.n
        width = {"tangent_sign": 1, "undisplaced_tangent_sign": 1, "pointiness": 1, "random_per_island": 1,
                 "f_point": 1, "col": 4}.get(name, 3)
        kind = {1: "float", 3: "float3", 4: "rgba"}[width]
        du = None if name == "random_per_island" else rng.normal(size=(n, width))
        dv = None if du is None else rng.normal(size=(n, width))
        return Attribute(kind, rng.uniform(-1.0, 1.0, (n, width)), du, dv)

    def state(self):
        return ShadingState(self.n, source=self, **self.fields)


def _graph(kind, props, inputs, output, outputs):
    node = Node(kind, kind, tuple(sorted(props.items())),
                tuple(Input(k, "vector" if isinstance(v, tuple) else "value", v) for k, v in inputs.items()),
                tuple(outputs))
    return Graph((node,), (("out", Input("out", outputs[0][1], link=Link(0, output, dict(outputs)[output]))),))


def _bump_graph(with_bump: bool):
    """A 3D noise of Generated (scale 5, detail 2) as a Bump's Height, or alone."""
    props = (("noise_dimensions", "3D"), ("noise_type", "FBM"), ("normalize", True))
    noise = Node("ShaderNodeTexNoise", "noise", props,
                 tuple(Input(k, "value", v) for k, v in (("Scale", 5.0), ("Detail", 2.0), ("Roughness", 0.5),
                                                         ("Lacunarity", 2.0), ("Distortion", 0.0), ("W", 0.0),
                                                         ("Offset", 0.0), ("Gain", 1.0))),
                 (("Fac", "value"), ("Color", "rgba")))
    if not with_bump:
        return Graph((noise,), (("out", Input("out", "value", link=Link(0, "Fac", "value"))),))
    bump = Node("ShaderNodeBump", "bump", (("invert", False),),
                (Input("Strength", "value", 1.0), Input("Distance", "value", 0.1), Input("Filter Width", "value", 0.1),
                 Input("Height", "value", 0.0, Link(0, "Fac", "value")), Input("Normal", "vector", (0.0, 0.0, 0.0))),
                (("Normal", "vector"),))
    return Graph((noise, bump), (("out", Input("out", "vector", link=Link(1, "Normal", "vector"))),))


def cases():
    geometry_outputs = (("Position", "vector"), ("Normal", "vector"), ("Tangent", "vector"), ("True Normal", "vector"),
                        ("Incoming", "vector"), ("Parametric", "vector"), ("Backfacing", "value"),
                        ("Pointiness", "value"), ("Random Per Island", "value"))
    out = [(f"geometry {name}", _graph("ShaderNodeNewGeometry", {}, {}, name, geometry_outputs))
           for name, _ in geometry_outputs]
    out.append(("object info random", _graph("ShaderNodeObjectInfo", {}, {}, "Random", (("Random", "value"),))))
    out.append(("camera data view vector", _graph("ShaderNodeCameraData", {}, {}, "View Vector",
                                                  (("View Vector", "vector"),))))
    out += [(f"attribute {name}", _graph("ShaderNodeAttribute", {"attribute_name": name}, {}, "Color",
                                         (("Color", "rgba"), ("Fac", "value"))))
            for name in ("f_point", "col")]
    out.append(("fresnel", _graph("ShaderNodeFresnel", {}, {"IOR": 1.45, "Normal": (0.0, 0.0, 0.0)}, "Fac",
                                  (("Fac", "value"),))))
    out.append(("layer weight facing", _graph("ShaderNodeLayerWeight", {}, {"Blend": 0.3, "Normal": (0.0, 0.0, 0.0)},
                                              "Facing", (("Fresnel", "value"), ("Facing", "value")))))
    out.append(("light path ray depth", _graph("ShaderNodeLightPath", {}, {}, "Ray Depth", (("Ray Depth", "value"),))))
    out.append(("wireframe pixel", _graph("ShaderNodeWireframe", {"use_pixel_size": True}, {"Size": 1.0}, "Fac",
                                          (("Fac", "value"),))))
    out.append(("tangent uv map", _graph("ShaderNodeTangent", {"direction_type": "UV_MAP"}, {}, "Tangent",
                                         (("Tangent", "vector"),))))
    out.append(("normal map tangent", _graph("ShaderNodeNormalMap", {"space": "TANGENT"},
                                             {"Strength": 0.8, "Color": (0.6, 0.4, 0.9)}, "Normal",
                                             (("Normal", "vector"),))))
    out.append(("vector displacement tangent", _graph("ShaderNodeVectorDisplacement", {"space": "TANGENT"},
                                                      {"Vector": (0.3, 0.2, 0.9), "Midlevel": 0.0, "Scale": 1.0},
                                                      "Displacement", (("Displacement", "vector"),))))
    out.append(("noise 3D alone (a Bump's Height)", _bump_graph(False)))
    out.append(("bump of that noise", _bump_graph(True)))
    return out


def _time(graph, state_source, repeats):
    program = compile(graph, {"out": "vector"})
    best = float("inf")
    for _ in range(repeats):
        state = state_source.state()
        t0 = time.process_time()
        program.run(state)
        best = min(best, time.process_time() - t0)
    return best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=100_000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--only", default="", help="a substring of the labels to run")
    args = ap.parse_args(argv)
    source = Source(args.points)
    print(f"{'node':40s} us/point")
    for label, graph in cases():
        if args.only and args.only not in label:
            continue
        seconds = _time(graph, source, args.repeats)
        print(f"{label:40s} {seconds / args.points * 1e6:8.3f}")


if __name__ == "__main__":
    main()
