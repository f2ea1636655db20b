"""Scenes built directly as arrays (no Blender) for analytic tests."""
import numpy as np

from ember.engine.scene import (Camera, Lights, Materials, Mesh, Scene, Settings, World, MAT_DIFFUSE,
                               MAT_EMISSION_ONLY)


def look_at(eye, target, up=(0, 0, 1)):
    """world_from_camera for a camera at eye looking at target (camera looks down -z)."""
    eye, target, up = (np.asarray(v, np.float64) for v in (eye, target, up))
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross(up, back)
    if np.linalg.norm(right) < 1e-9:
        right = np.cross((0, 1, 0), back)
    right /= np.linalg.norm(right)
    true_up = np.cross(back, right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, true_up, back, eye
    return m


def perspective(eye, target, fov_deg=40.0, aspect=1.0, **kw):
    h = np.tan(np.radians(fov_deg) / 2)
    return Camera(world_from_camera=look_at(eye, target), window=np.array([-h * aspect, h * aspect, -h, h]), **kw)


def quads_mesh(quads, material_ids):
    """quads (Q,4,3) corners in order; flat normals from the winding."""
    quads = np.asarray(quads, np.float64)
    v = quads.reshape(-1, 3)
    tris = []
    for q in range(len(quads)):
        b = 4 * q
        tris += [[b, b + 1, b + 2], [b, b + 2, b + 3]]
    tris = np.array(tris, np.int32)
    p = v[tris]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    normals = np.repeat(n[:, None, :], 3, axis=1)
    mat = np.repeat(np.asarray(material_ids, np.int32), 2)
    return Mesh(v.astype(np.float32), tris, normals.astype(np.float32), mat)


def box_quads(lo, hi):
    """Six faces of an axis-aligned box, normals pointing outward."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    return np.array([
        [[x0, y0, z0], [x0, y1, z0], [x1, y1, z0], [x1, y0, z0]],  # bottom (-z)
        [[x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]],  # top (+z)
        [[x0, y0, z0], [x1, y0, z0], [x1, y0, z1], [x0, y0, z1]],  # -y
        [[x0, y1, z0], [x0, y1, z1], [x1, y1, z1], [x1, y1, z0]],  # +y
        [[x0, y0, z0], [x0, y0, z1], [x0, y1, z1], [x0, y1, z0]],  # -x
        [[x1, y0, z0], [x1, y1, z0], [x1, y1, z1], [x1, y0, z1]],  # +x
    ])


def uv_sphere(center, radius, n_theta=24, n_phi=48):
    """A closed triangulated sphere (outward winding) with smooth corner normals."""
    c = np.asarray(center, np.float64)
    th = np.linspace(0, np.pi, n_theta + 1)
    ph = np.linspace(0, 2 * np.pi, n_phi + 1)
    T, P = np.meshgrid(th, ph, indexing="ij")
    dirs = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1)
    verts = (c + radius * dirs).reshape(-1, 3)
    ndir = dirs.reshape(-1, 3)
    tris = []
    w = n_phi + 1
    for i in range(n_theta):
        for j in range(n_phi):
            a, b, cc, d = i * w + j, i * w + j + 1, (i + 1) * w + j + 1, (i + 1) * w + j
            if i != 0:
                tris.append([a, d, b])
            if i != n_theta - 1:
                tris.append([b, d, cc])
    tris = np.array(tris, np.int32)
    return verts.astype(np.float32), tris, ndir[tris].astype(np.float32)


def settings(**kw):
    """Small renders by the path tracer (the core's default is `auto`, which may choose another)."""
    base = dict(width=16, height=16, samples=8, seed=1, filter="BOX", filter_width=1.0, batch_size=4096,
                integrator="path")
    base.update(kw)
    return Settings(**base)


def furnace_box(albedo=0.5, Le=1.0, **kw):
    """Closed box, every face diffuse `albedo` and emitting Le: radiance Le / (1 - albedo) everywhere."""
    mesh = quads_mesh(box_quads((-1, -1, -1), (1, 1, 1)), [0] * 6)
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(albedo,) * 3, emission=(Le,) * 3)])
    return Scene(mesh, mats, Lights.make([]), World(), perspective((0, -0.5, 0.2), (0, 1, 0), 70), settings(**kw))


def sphere_with_point_light(albedo=0.5, intensity=np.pi, radius=0.0, soft=False, **kw):
    """pbrt-v4's analytic test: inside a unit sphere (albedo 0.5) a point light I = pi gives L = 1."""
    v, t, n = uv_sphere((0, 0, 0), 1.0, 48, 96)
    mesh = Mesh(v, t, n, np.zeros(len(t), np.int32))
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(albedo,) * 3)])
    Le = intensity if radius == 0 else intensity / (np.pi * radius**2)
    lights = Lights.make([dict(kind=0, position=(0, 0, 0), radius=radius, Le=(Le,) * 3, soft=soft)])
    return Scene(mesh, mats, lights, World(), perspective((0, 0.3, 0), (0, 1, 0), 50), settings(**kw))


def many_lights(n=1000, kind="triangle", size=0.1, lift=0.3, extent=15.0, decades=3.0, layout=0, radius=0.0, **kw):
    """n small lights of very different power spread over a large diffuse floor (40 m x 40 m,
    albedo 0.5) under a black world, seen from above at an angle: the many-lights case
    (bench/results/many_lights/report.md). kind "triangle": emissive squares of side `size` at
    height `lift` facing down (two triangles each, two-sided); "point": point lights at height
    `lift` (delta, or spheres of `radius`). Positions are uniform over [-extent, extent]^2,
    radiance or intensity log-uniform over `decades` decades (total power about the same for
    every n; `layout` seeds both). A few boxes cast shadows."""
    rng = np.random.default_rng(layout)
    xy = rng.uniform(-extent, extent, (n, 2))
    level = 10.0 ** rng.uniform(0.0, decades, n)
    level *= 300.0 / level.sum()  # total power independent of n
    floor = [[[-20, -20, 0], [20, -20, 0], [20, 20, 0], [-20, 20, 0]]]
    boxes = [q for c in ((-3, 2), (4, -1), (0, -6)) for q in box_quads((c[0] - 1, c[1] - 1, 0), (c[0] + 1, c[1] + 1, 1.5))]
    quads = floor + boxes
    mats = [dict(kind=MAT_DIFFUSE, base_color=(0.5,) * 3)]
    ids = [0] * len(quads)
    light_rows = []
    if kind == "triangle":
        s = 0.5 * size
        for (x, y), le in zip(xy, level):
            quads.append([[x - s, y - s, lift], [x - s, y + s, lift], [x + s, y + s, lift], [x + s, y - s, lift]])
            ids.append(len(mats))
            mats.append(dict(kind=MAT_EMISSION_ONLY, emission=(le / (2 * size * size),) * 3))
    else:
        area = np.pi * radius**2 if radius > 0 else 1.0  # a sphere's radiance: I / (pi r^2)
        light_rows = [dict(kind=0, position=(x, y, lift), radius=radius, soft=False, Le=(le / (4 * np.pi * area),) * 3)
                      for (x, y), le in zip(xy, level)]
    mesh = quads_mesh(quads, ids)
    camera = perspective((0.0, -22.0, 14.0), (0.0, -2.0, 0.0), 50)
    return Scene(mesh, Materials.make(mats), Lights.make(light_rows), World(), camera, settings(**kw))


def icosphere(center, radius, subdivisions=2):
    """A flat-faceted icosphere (outward winding): the icosahedron's faces split in four
    `subdivisions` times, vertices pushed onto the sphere. Returns (F,3,3) triangles."""
    t = (1 + 5 ** 0.5) / 2
    v = np.array([(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
                  (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)], np.float64)
    f = np.array([(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
                  (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5),
                  (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)])
    tris = v[f] / np.linalg.norm(v[f], axis=2, keepdims=True)
    for _ in range(subdivisions):
        a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
        ab, bc, ca = [m / np.linalg.norm(m, axis=1, keepdims=True) for m in (a + b, b + c, c + a)]
        tris = np.concatenate([np.stack(x, 1) for x in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    return np.asarray(center, np.float64) + radius * tris


def glass_sphere_on_floor(light: dict, subdivisions=2, **kw):
    """bench/glass_particles.py's scene: a flat-faceted glass icosphere (IOR 1.5, radius 0.5)
    just above a 4 x 4 m floor, a back wall at y = 2 (both diffuse 0.8), black world; `light`
    a Lights.make row. Returns (scene, glass triangles (F,3,3))."""
    from ember.engine.scene import LOBE_DIELECTRIC
    glass = icosphere((0.0, 0.0, 0.501), 0.5, subdivisions)
    floor = [[(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)], [(-2, 2, 0), (-2, 2, 2.5), (2, 2, 2.5), (2, 2, 0)]]
    planes = quads_mesh(floor, [0, 0])
    n = np.cross(glass[:, 1] - glass[:, 0], glass[:, 2] - glass[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    v = np.concatenate([planes.vertices, glass.reshape(-1, 3).astype(np.float32)])
    t = np.concatenate([planes.triangles, len(planes.vertices) + np.arange(3 * len(glass), dtype=np.int32).reshape(-1, 3)])
    normals = np.concatenate([planes.normals, np.repeat(n[:, None], 3, axis=1).astype(np.float32)])
    mat = np.concatenate([planes.material, np.ones(len(glass), np.int32)])
    mats = Materials.make([dict(kind=MAT_DIFFUSE, base_color=(0.8,) * 3, name="floor"),
                           dict(name="glass", lobes=[dict(kind=LOBE_DIELECTRIC, roughness=0.0, ior=1.5,
                                                          color=(1.0,) * 3, tint=(1.0,) * 3)])])
    scene = Scene(Mesh(v, t, normals, mat), mats, Lights.make([light]), World(),
                  perspective((0.0, -3.2, 2.2), (-0.2, 0.1, 0.3), 40), settings(**kw))
    return scene, glass
