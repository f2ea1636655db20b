"""Panoramic cameras (engine/panorama.py, engine/camera.py): each projection's directions map
back to the image points they came from; a ray's direction maps to the pixel Cycles' own
projection shows it at (a small bright marker placed along an Ember pixel's direction lights
that pixel in Cycles' render); each type's render of a small scene agrees with Cycles' per
region (pixels outside a fisheye's circle black and opaque, as Cycles); depth of field; and
the viewport's camera view of a panorama."""
import dataclasses

import numpy as np
import pytest

from ember.engine import camera as camera_mod, panorama
from ember.engine.scene import Camera, Settings

KINDS = panorama.PANORAMAS
PARAMS = {"EQUIRECTANGULAR": dict(pano_range=(-2.0, 1.5, -0.5, 1.0)),
          "CENTRAL_CYLINDRICAL": dict(pano_range=(2.5, -2.0, -0.7, 1.2)),
          "FISHEYE_EQUIDISTANT": dict(fisheye_fov=2.8),
          "FISHEYE_EQUISOLID": dict(fisheye_lens=9.0, fisheye_fov=3.0, sensor=(36.0, 24.0)),
          "FISHEYE_LENS_POLYNOMIAL": dict(fisheye_fov=3.1, sensor=(36.0, 30.0),
                                          polynomial=(-1e-5, -0.0199887, -3.35e-6, 3.1e-6, -2.6e-8))}


def _camera(kind, **kw):
    return Camera(world_from_camera=np.eye(4), window=np.array([0.0, 1.0, 0.0, 1.0]), panorama=kind,
                  **dict(PARAMS.get(kind, {}), **kw))


@pytest.mark.parametrize("kind", KINDS)
def test_directions_map_back_to_their_image_points(kind):
    cam = _camera(kind)
    rng = np.random.default_rng(KINDS.index(kind))
    u, v = rng.random(20_000), rng.random(20_000)
    d = panorama.to_direction(cam, u, v)
    ok = np.any(d != 0, axis=1)
    assert ok.mean() > 0.4
    np.testing.assert_allclose(np.linalg.norm(d[ok], axis=1), 1.0, rtol=1e-12)
    u2, v2 = panorama.from_direction(cam, d[ok])
    np.testing.assert_allclose(u2, u[ok], atol=1e-7)
    np.testing.assert_allclose(v2, v[ok], atol=1e-7)
    if kind in ("FISHEYE_EQUIDISTANT", "FISHEYE_EQUISOLID", "MIRRORBALL"):
        assert not ok.all()  # the corners lie outside the circle


def test_rays_outside_the_image_carry_nothing_and_clip_along_the_ray():
    """A fisheye's corner pixels get rays of length 0 (tmax 0); the others start clip_start
    along the ray and end clip_end - clip_start later (Cycles' camera_sample_to_ray)."""
    cam = dataclasses.replace(_camera("FISHEYE_EQUIDISTANT"), clip_start=0.25, clip_end=7.0,
                              world_from_camera=np.array([[1, 0, 0, 1], [0, 0, -1, 2], [0, 1, 0, 3], [0, 0, 0, 1.0]]))
    s = Settings(width=8, height=8)
    px, py = np.meshgrid(np.arange(8), np.arange(8))
    o, d, tmax = camera_mod.generate_rays(cam, s, px.ravel(), py.ravel(), np.full((64, 2), 0.5))
    corner = np.hypot(px.ravel() + 0.5 - 4, py.ravel() + 0.5 - 4) > 4
    assert np.all(tmax[corner] == 0) and np.all(tmax[~corner] == pytest.approx(6.75))
    np.testing.assert_allclose(np.linalg.norm(o - [1, 2, 3], axis=1), 0.25, rtol=1e-12)
    # The image's centre looks down the camera's -z axis (here world +y).
    centre = camera_mod.generate_rays(cam, Settings(width=2, height=2), np.array([1]), np.array([1]),
                                      np.zeros((1, 2)))[1]
    np.testing.assert_allclose(centre, [[0.0, 1.0, 0.0]], atol=1e-12)


def test_depth_of_field_rays_meet_at_the_focus_distance():
    """Rays of one image point from different aperture points meet focus_distance along the
    pinhole ray, and start on the aperture across it."""
    cam = dataclasses.replace(_camera("EQUIRECTANGULAR"), aperture_radius=0.05, focus_distance=3.0, clip_start=0.0)
    s = Settings(width=16, height=8)
    n = 500
    rng = np.random.default_rng(3)
    px, py = np.full(n, 5), np.full(n, 2)
    o, d, _ = camera_mod.generate_rays(cam, s, px, py, np.full((n, 2), 0.5), rng.random((n, 2)))
    pin = camera_mod.generate_rays(cam, s, px[:1], py[:1], np.full((1, 2), 0.5))[1][0]
    t = np.sum((3.0 * pin - o) * d, axis=1)
    np.testing.assert_allclose(o + t[:, None] * d, np.tile(3.0 * pin, (n, 1)), atol=1e-9)
    np.testing.assert_allclose(o @ pin, 0.0, atol=1e-12)
    assert np.linalg.norm(o, axis=1).max() > 0.02


# ---- against Cycles -------------------------------------------------------------------------------

def _cycles_scene(kind, size, props, markers=None):
    """A camera of `kind` at (0.3, 0.2, 1.2) among four coloured spheres on a floor under a sun,
    or, with markers (world directions), black but for small emissive spheres along them."""
    import bpy
    from cycles_scenes import camera, diffuse_floor, new_scene, node_material
    wide = kind in ("EQUIRECTANGULAR", "CENTRAL_CYLINDRICAL")
    sc = new_scene(size, world=(0.0, 0.0, 0.0) if markers is not None else (0.05, 0.05, 0.05))
    sc.render.resolution_y = size // 2 if wide else size
    cam = camera(sc, (0.3, 0.2, 1.2), (1.4, 0.0, 0.5))
    cam.data.type = "PANO"
    cam.data.panorama_type = kind
    for k, v in props.items():
        setattr(cam.data.dof if k.startswith("dof_") else cam.data, k.removeprefix("dof_"), v)
    if markers is not None:
        mat, nt, out = node_material("Marker")
        e = nt.nodes.new("ShaderNodeEmission")
        e.inputs["Strength"].default_value = 50.0
        nt.links.new(e.outputs[0], out.inputs["Surface"])
        for d in markers:
            bpy.ops.mesh.primitive_ico_sphere_add(radius=0.004, subdivisions=1,
                                                  location=tuple(np.array((0.3, 0.2, 1.2)) + 0.5 * np.asarray(d)))
            bpy.context.active_object.data.materials.append(mat)
        return sc
    diffuse_floor(20)
    for i, (loc, col) in enumerate([((3, 0, 1), (1, 0.1, 0.1)), ((0, 3, 1), (0.1, 1, 0.1)), ((-3, 0, 1), (0.1, 0.1, 1)),
                                    ((0, -3, 1), (1, 1, 0.1))]):
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.8, location=loc)
        mat, nt, out = node_material(f"m{i}")
        d = nt.nodes.new("ShaderNodeBsdfDiffuse")
        d.inputs["Color"].default_value = (*col, 1)
        nt.links.new(d.outputs[0], out.inputs["Surface"])
        bpy.context.active_object.data.materials.append(mat)
    bpy.ops.object.light_add(type="SUN", rotation=(0.5, 0.2, 0.3))
    bpy.context.active_object.data.energy = 3.0
    return sc


BLENDER_PROPS = {"EQUIRECTANGULAR": dict(latitude_min=-0.5, latitude_max=1.0, longitude_min=-2.0, longitude_max=1.5),
                 "CENTRAL_CYLINDRICAL": dict(central_cylindrical_range_u_min=-2.5, central_cylindrical_range_u_max=2.0,
                                             central_cylindrical_range_v_min=-0.5,
                                             central_cylindrical_range_v_max=1.5, central_cylindrical_radius=1.3),
                 "FISHEYE_EQUIDISTANT": dict(fisheye_fov=2.8),
                 "FISHEYE_EQUISOLID": dict(fisheye_lens=9.0, fisheye_fov=3.0, sensor_fit="VERTICAL")}


@pytest.mark.blender
def test_a_direction_lights_the_pixel_cycles_projects_it_to(tmp_path):
    """For each type: markers along the directions Ember gives three pixel centres; in Cycles'
    render each marker's pixel is the brightest of its neighbourhood (the projection is
    Cycles' to the pixel). The directions come from the exported camera."""
    import bpy
    from cycles_renders import cycles_image
    from cycles_scenes import addon
    from ember.engine.blender.export import export_scene
    size = 40
    with addon():
        for kind in KINDS:
            sc = _cycles_scene(kind, size, BLENDER_PROPS.get(kind, {}))
            scene, _ = export_scene(bpy.context.evaluated_depsgraph_get())
            w, h = scene.settings.width, scene.settings.height
            pixels = np.array([[7, h // 2 - 3], [w // 2 + 4, h // 3], [w - 12, h - 9]])
            o, d, tmax = camera_mod.generate_rays(scene.camera, scene.settings, pixels[:, 0], pixels[:, 1],
                                                  np.full((3, 2), 0.5))
            assert np.all(tmax > 0), kind
            sc = _cycles_scene(kind, size, BLENDER_PROPS.get(kind, {}), markers=d)
            sc.cycles.pixel_filter_type = "BOX"
            img = cycles_image(sc, 16, 0, tmp_path / f"{kind}.exr").sum(axis=2)
            for x, y in pixels:
                around = img[y - 2:y + 3, x - 2:x + 3]
                assert np.unravel_index(np.argmax(around), around.shape) == (2, 2), (kind, x, y, around.round(2))


@pytest.mark.blender
def test_each_panorama_renders_as_cycles(tmp_path):
    """Region means of Ember's and Cycles' renders of each type (and of a fisheye with depth
    of field) within 1 % plus the noise band; the fisheye's corners black and opaque in both."""
    from cycles_renders import agree, cycles_image, ember_image
    from cycles_scenes import addon
    cases = [(kind, BLENDER_PROPS.get(kind, {})) for kind in KINDS]
    cases.append(("FISHEYE_EQUIDISTANT", dict(dof_use_dof=True, dof_focus_distance=2.0, dof_aperture_fstop=0.5)))
    with addon():
        for i, (kind, props) in enumerate(cases):
            sc = _cycles_scene(kind, 32, props)
            cycles = [cycles_image(sc, 128, 100 + k, tmp_path / f"c{i}_{k}.exr") for k in range(3)]
            ember = [ember_image(sc, "PATH", 48, k) for k in range(3)]
            agree(ember, cycles, len(cases), 0.01)
            if kind == "FISHEYE_EQUIDISTANT":
                assert np.all(np.asarray(cycles)[:, 0, 0] == 0) and np.all(np.asarray(ember)[:, 0, 0] == 0)


@pytest.mark.blender
def test_a_camera_view_shows_the_panorama_in_the_camera_frame():
    """The region's pixels map to the frame's (u, v): the frame's corners to 0 and 1."""
    from ember.engine.blender.viewport import pano_view_camera
    cam = _camera("FISHEYE_EQUIDISTANT")
    view = pano_view_camera(cam, (20.0, 120.0, 10.0, 60.0), (140, 80), (36.0, 18.0))
    left, right, bottom, top = view.window
    assert left + (right - left) * 20 / 140 == pytest.approx(0.0)
    assert left + (right - left) * 120 / 140 == pytest.approx(1.0)
    assert bottom + (top - bottom) * 60 / 80 == pytest.approx(1.0)
    assert view.sensor == (36.0, 18.0) and view.panorama == cam.panorama


def test_a_panoramic_camera_survives_save_and_load(tmp_path):
    from ember.engine.scene import Lights, Materials, Scene, World
    from core_scenes import quads_mesh, settings
    cam = _camera("FISHEYE_LENS_POLYNOMIAL")
    scene = Scene(quads_mesh([[[-1, 1, -1], [-1, 1, 1], [1, 1, 1], [1, 1, -1]]], [0]), Materials.make([]),
                  Lights.make([]), World(), cam, settings())
    scene.save(tmp_path / "s.npz")
    back = Scene.load(tmp_path / "s.npz").camera
    assert back.panorama == cam.panorama and tuple(back.polynomial) == cam.polynomial
    assert tuple(back.sensor) == cam.sensor and back.fisheye_fov == cam.fisheye_fov


def test_pixel_angle_of_a_panorama():
    """A full equirectangular image of W pixels spans 2 pi: a pixel is 2 pi / W at the horizon."""
    cam = _camera("EQUIRECTANGULAR", pano_range=(-np.pi, np.pi, -0.5 * np.pi, 0.5 * np.pi))
    assert camera_mod.pixel_angle(cam, Settings(width=90, height=45)) == pytest.approx(2 * np.pi / 90, rel=1e-9)


def _texco_scene(kind, output, world):
    """|Texture Coordinate `output`| as the emission of a sphere around a `kind` camera, or as
    the world's colour (world)."""
    import bpy
    from cycles_scenes import camera, new_scene, node_material
    sc = new_scene(32)
    if world:
        sc.world.cycles.sampling_method = "NONE"  # nothing it lights: spares Cycles its importance map
        nt = sc.world.node_tree
        target = nt.nodes["Background"].inputs["Color"]
    else:
        bpy.ops.mesh.primitive_uv_sphere_add(radius=6)
        mat, nt, out = node_material("Coordinates")
        em = nt.nodes.new("ShaderNodeEmission")
        nt.links.new(em.outputs[0], out.inputs["Surface"])
        bpy.context.active_object.data.materials.append(mat)
        target = em.inputs["Color"]
    tc, ab = nt.nodes.new("ShaderNodeTexCoord"), nt.nodes.new("ShaderNodeVectorMath")
    ab.operation = "ABSOLUTE"
    nt.links.new(tc.outputs[output], ab.inputs[0])
    nt.links.new(ab.outputs[0], target)
    cam = camera(sc, (0.3, 0.2, 1.2), (1.4, 0.0, 0.5))
    cam.data.type, cam.data.panorama_type = "PANO", kind
    return sc


@pytest.mark.blender
@pytest.mark.parametrize("kind, output, world", [("FISHEYE_EQUIDISTANT", "Camera", False),
                                                 ("MIRRORBALL", "Window", True)])
def test_camera_and_window_coordinates_of_a_panorama_as_cycles(kind, output, world, tmp_path):
    """Cycles' camera space of a panorama is the projection's; Window is where it shows a point."""
    from cycles_renders import agree, cycles_image, ember_image
    from cycles_scenes import addon
    with addon():
        sc = _texco_scene(kind, output, world)
        cycles = [cycles_image(sc, 16, k, tmp_path / f"c{k}.exr") for k in range(3)]
        ember = [ember_image(sc, "PATH", 16, k) for k in range(3)]
    for c in range(3):  # each axis apart: swapped axes must not pass (Window's z is 0)
        if np.mean(cycles[0][..., c]) > 0:
            agree([e[..., c:c + 1] for e in ember], [x[..., c:c + 1] for x in cycles], 6, 0.01)
