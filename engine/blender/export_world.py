"""World -> World: a constant, an environment image (the fast path), or the world's node graph.

As Cycles' sync_world (intern/cycles/blender/shader.cpp, 5.x): the view layer's world
override, else the scene world; with a node tree, the World Output Surface link; without
one, world.color at strength 1; no world -> black. The view layer's Environment toggle
(use_sky) off disables the background shader entirely. Camera visibility comes from
world.cycles_visibility.camera and film_transparent (a transparent film shows the background
black, alpha 1, for now).

The Surface is exported as a node graph (export_nodes.export_graph) and compiled:
- a graph that folds to a constant (Background colour x strength, Blackbody, Math...) is
  World.color, no table;
- the fast path: a Background (or Emission) of unlinked Strength whose Color is an Environment
  Texture with Closest interpolation (one texel per direction, no filtering) whose Vector is
  unlinked (the ray direction) or comes through Mapping nodes (no Location) from Texture
  Coordinate Generated/Object: the image itself (World.image, looked up nearest-pixel exactly
  as Closest reads it) with the Mapping chain as World.env_from_world (Cycles'
  kernel/svm/mapping_util.h):
    POINT  R S v + location     VECTOR  R S v     TEXTURE  S^-1 R^T (v - location)
    NORMAL normalize(R S^-1 v)  with R = Rz Ry Rx (Euler XYZ, util/transform.h euler_to_transform);
  pixels read with foreach_get into float32, byte images decoded per their colour space;
- anything else (Sky Texture, Mix of backgrounds, gradients, procedurals, filtered images,
  Light Path) is World.graph, evaluated at escaped rays and importance sampled from a table of
  its values (engine/lights/world.py); world.cycles.sampling_method gives the table's
  resolution (Manual: sample_map_resolution) or none (None).
Nodes Ember cannot evaluate are warned about with their fallback (engine/nodes/program.py).
Not supported, with a warning: world volumes; per-ray-type visibility beyond Cycles' world
ray visibility.
"""
from __future__ import annotations

import numpy as np

from ..lights.world import Background
from ..nodes.closures import closures
from ..nodes.program import compile
from ..scene import ENV_PROJECTIONS, RAY_ALL, RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMIT, World
from ..textures import srgb_to_linear
from .export_material import find_output, follow_link
from .export_nodes import export_graph

MISSING_IMAGE = (1.0, 0.0, 1.0)  # Cycles' colour for an image it cannot load (TEX_IMAGE_MISSING_*)
_LINEAR_SPACES = {"Linear Rec.709", "scene_linear", "Non-Color"}
_SRGB_TABLE = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)


def euler_xyz_matrix(rotation) -> np.ndarray:
    """Blender/Cycles Euler XYZ rotation matrix Rz @ Ry @ Rx (3,3)."""
    x, y, z = (float(a) for a in rotation)
    cx, sx, cy, sy, cz, sz = np.cos(x), np.sin(x), np.cos(y), np.sin(y), np.cos(z), np.sin(z)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def mapping_matrix(vector_type: str, rotation, scale) -> np.ndarray:
    """The linear part (3,3) of a Mapping node of `vector_type` (see the module docstring)."""
    R = euler_xyz_matrix(rotation)
    s = np.asarray(scale, np.float64)
    inv_s = np.divide(1.0, s, out=np.zeros(3), where=s != 0)  # Cycles' safe_divide
    if vector_type in ("POINT", "VECTOR"):
        return R @ np.diag(s)
    if vector_type == "TEXTURE":
        return np.diag(inv_s) @ R.T
    return R @ np.diag(inv_s)  # NORMAL


def image_pixels(image, warn, owner: str) -> np.ndarray:
    """(H, W, 3) float32 scene-linear pixels of a bpy Image, rows top-down.

    Read once with foreach_get into a float32 buffer (pixels[:] builds a Python list: many times slower). None if the
    image has no pixels (missing file): the caller renders Cycles' magenta.
    """
    w, h = (int(v) for v in image.size)
    channels = int(image.channels)
    if w == 0 or h == 0 or channels == 0:
        return None
    buf = np.empty(w * h * channels, np.float32)
    image.pixels.foreach_get(buf)
    buf = buf.reshape(h, w, channels)[::-1]  # Blender rows are bottom-up
    rgb_view = buf[:, :, :3] if channels >= 3 else buf[:, :, :1].repeat(3, axis=2)
    pixels = np.ascontiguousarray(rgb_view)
    if not image.is_float:
        space = image.colorspace_settings.name
        if space == "sRGB":
            # Byte values are k / 255 exactly: decode through the table.
            index = np.rint(pixels * 255.0).astype(np.uint8)
            pixels = _SRGB_TABLE[index]
        elif space not in _LINEAR_SPACES:
            warn(f"{owner}: image '{image.name}' is in colour space '{space}', which Ember does "
                 "not convert; its values are used as linear.")
    bad = ~np.isfinite(pixels)
    if bad.any():
        warn(f"{owner}: image '{image.name}' has {int(bad.sum())} NaN or infinite values; "
             "they are rendered as 0.")
        pixels[bad] = 0.0
    return pixels


def _source(socket):
    """(node, output socket name) feeding `socket` through reroutes, or (None, "")."""
    node = follow_link(socket)
    if node is None:
        return None, ""
    link = socket.links[0]
    while link.from_node.bl_idname == "NodeReroute":
        link = link.from_node.inputs[0].links[0]
    return node, link.from_socket.name


def _env_from_world(node, warn, owner: str) -> np.ndarray:
    """Follow the Environment Texture's Vector input back to the ray direction; returns the
    linear map (3,3) applied to the direction, identity if unsupported (with a warning)."""
    A = np.eye(3)
    socket = node.inputs["Vector"]
    for _ in range(64):
        src, out_name = _source(socket)
        if src is None:
            return A
        if src.mute and src.inputs:  # a muted node passes its first input through
            socket = src.inputs[0]
            continue
        if src.bl_idname == "ShaderNodeMapping":
            loc, rot, scl = (src.inputs.get(k) for k in ("Location", "Rotation", "Scale"))  # no Location: VECTOR, NORMAL
            linked = [s.name for s in (loc, rot, scl) if s is not None and s.is_linked and getattr(s, "enabled", True)]
            if linked:
                warn(f"{owner}: linked {', '.join(linked)} of Mapping node '{src.name}' is not "
                     "supported; its unlinked value is used.")
            if loc is not None and src.vector_type in ("POINT", "TEXTURE") and any(abs(v) > 0 for v in loc.default_value):
                warn(f"{owner}: the Location of Mapping node '{src.name}' is ignored (the "
                     "environment depends only on the direction).")
            A = A @ mapping_matrix(src.vector_type, rot.default_value, scl.default_value)
            socket = src.inputs["Vector"]
            if not socket.is_linked:
                warn(f"{owner}: Mapping node '{src.name}' has no input vector; the ray direction "
                     "is used.")
                return A
            continue
        if src.bl_idname == "ShaderNodeTexCoord" and out_name in ("Generated", "Object"):
            if out_name == "Object" and src.object is not None:
                warn(f"{owner}: Texture Coordinate '{src.name}' uses object '{src.object.name}'; "
                     "its transform is ignored.")
            return A
        warn(f"{owner}: the environment's vector comes from '{src.name}' ({src.bl_label}"
             f"{' ' + out_name if out_name else ''}), which is not supported; the ray direction is used.")
        return A
    return A


def _environment(node, warn, owner: str) -> dict:
    """World fields for an Environment Texture node: image, projection, env_from_world; a
    missing image gives Cycles' magenta as a constant colour."""
    if node.projection not in ENV_PROJECTIONS:
        warn(f"{owner}: environment projection '{node.projection}' is not supported; "
             "equirectangular is used.")
    projection = node.projection if node.projection in ENV_PROJECTIONS else "EQUIRECTANGULAR"
    image = node.image
    pixels = image_pixels(image, warn, owner) if image is not None else None
    if pixels is None:
        what = f"image '{image.name}' could not be loaded" if image is not None else "has no image"
        warn(f"{owner}: Environment Texture '{node.name}' {what}; rendered magenta, as Cycles does.")
        return dict(tint=np.array(MISSING_IMAGE))
    tm = node.texture_mapping
    if (any(abs(v) > 0 for v in tm.translation) or any(abs(v) > 0 for v in tm.rotation)
            or any(abs(v - 1) > 0 for v in tm.scale)):
        warn(f"{owner}: the texture mapping of '{node.name}' is ignored; use a Mapping node.")
    return dict(image=pixels, projection=projection, env_from_world=_env_from_world(node, warn, owner))


def _fast_environment(node, owner: str) -> dict | None:
    """World fields of the fast path (the module docstring) for the Surface's node, or None
    where the graph is not exactly that: an Environment Texture read with Closest
    interpolation, through what _env_from_world follows without a warning, its image loaded
    and clean."""
    if node.bl_idname not in ("ShaderNodeBackground", "ShaderNodeEmission") or node.mute:
        return None
    col, stre = node.inputs["Color"], node.inputs["Strength"]
    src = follow_link(col) if col.is_linked else None
    if stre.is_linked or src is None or src.bl_idname != "ShaderNodeTexEnvironment" or src.mute:
        return None
    if src.interpolation != "Closest" or src.projection not in ENV_PROJECTIONS or src.image is None:
        return None
    notes = []
    env = _environment(src, notes.append, owner)
    if notes or "image" not in env:
        return None
    return dict(color=np.ones(3) * float(stre.default_value), **env)


def _graph_fields(socket, warn, owner: str) -> dict:
    """World fields of the Surface `socket`'s node graph: a constant colour where it folds to
    one, else the graph (World.graph)."""
    notes = []
    graph = export_graph({"surface": socket}, notes.append)
    try:
        program = compile(graph, {"surface": "shader"})
        if not program.constant:  # fail here, not in the render processes
            Background(graph).radiance(np.array([[0.0, 0.0, 1.0], [0.6, 0.0, -0.8]]))
    except (ValueError, KeyError, TypeError, IndexError) as exc:
        warn(f"{owner}: its node graph could not be evaluated ({exc}); the background is black.")
        return dict(color=np.zeros(3))
    for note in notes + list(program.warnings):
        warn(f"{owner}: {note}")
    if program.constant:
        made = closures(program.run()["surface"])
        weights = [np.asarray(c.weight, np.float64) for c in made if c.kind in ("background", "emission")]
        return dict(color=sum(weights, np.zeros(3)))
    return dict(color=np.ones(3), graph=(graph,))


def _map_resolution(world) -> int:
    """World.map_resolution from Cycles' world sampling settings (the original's: a change
    of these does not tag the evaluated copy)."""
    settings = getattr(getattr(world, "original", world), "cycles", None)
    method = getattr(settings, "sampling_method", "AUTOMATIC")
    if method == "NONE":
        return -1
    if method == "MANUAL":
        return max(int(getattr(settings, "sample_map_resolution", 1024)), 2)
    return 0


def _world_fields(world, warn) -> dict:
    """color, and an image's fields (image/projection/env_from_world) or a graph's
    (graph/map_resolution)."""
    tree = world.node_tree
    owner = f"World '{world.name}'"
    if tree is None:
        return dict(color=np.array(world.color[:3], np.float64))
    out = find_output(tree, "ShaderNodeOutputWorld")
    if out is None:
        warn(f"{owner}: no World Output node; the background is black.")
        return dict(color=np.zeros(3))
    volume = out.inputs.get("Volume")
    if volume is not None and follow_link(volume) is not None:
        warn(f"{owner}: world volume shaders are not supported and are ignored.")
    node = follow_link(out.inputs["Surface"])
    if node is None:
        return dict(color=np.zeros(3))
    fields = _fast_environment(node, owner) or _graph_fields(out.inputs["Surface"], warn, owner)
    if fields.get("graph"):
        fields["map_resolution"] = _map_resolution(world)
    return fields


def export_world(depsgraph, scene, warn) -> World:
    view_layer = depsgraph.view_layer_eval
    world = getattr(view_layer, "world_override", None) or scene.world
    if world is None or not getattr(view_layer, "use_sky", True):
        return World(color=np.zeros(3), visible=True)
    fields = _world_fields(world, warn)
    vis = getattr(world, "cycles_visibility", None)
    visible = bool(getattr(vis, "camera", True)) and not scene.render.film_transparent
    bits = RAY_ALL
    if vis is not None:
        for prop, bit in (("diffuse", RAY_DIFFUSE), ("glossy", RAY_GLOSSY), ("transmission", RAY_TRANSMIT)):
            if not getattr(vis, prop, True):
                bits &= ~bit
    return World(visible=visible, ray_visibility=bits, **fields)
