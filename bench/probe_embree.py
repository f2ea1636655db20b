"""What embreex alone traces on a scene: the ceiling for Ember's rays per second.

The rays are the ones a path tracer asks for on that scene, made once up front and then
only traced (the timed loop is nothing but `EmbreeScene.run` on ready float32 arrays):
camera rays through every pixel of a size x size image (closest hit), diffuse bounce rays
from their hit points (cosine around the side of the triangle the ray came from; closest
hit), and shadow rays from the same points to random points of the emitting triangles or,
without any, of the scene's bounding box (any hit). Batches of 65536 rays, as Ember's; one
thread, then several threads on the same Embree scene (embreex releases the GIL).
"""
from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ember.engine import camera as camera_mod

BATCH = 1 << 16


def _unit(v):
    return v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-30)


def make_rays(scene, size: int = 256, seed: int = 0):
    """((Embree scene, its device), {"camera"|"bounce"|"shadow": (origins, directions, tfar,
    query)}) as embreex wants them."""
    from embreex import rtcore_scene as rtcs  # noqa: F401  (fail early if missing)
    rng = np.random.default_rng(seed)
    mesh = scene.mesh
    settings = scene.settings.replace(width=size, height=size, border=(0, 0, size, size))
    py, px = np.divmod(np.arange(size * size), size)
    o, d, tmax = camera_mod.generate_rays(scene.camera, settings, px, py, rng.random((size * size, 2)))
    es, device = embree_scene(mesh)
    hit = es.run(o.astype(np.float32), d.astype(np.float32), dists=tmax.astype(np.float32), output=1)
    ok = hit["primID"] >= 0
    p = (o + hit["tfar"][:, None] * d)[ok]
    tri = mesh.vertices.astype(np.float64)[mesh.triangles[hit["primID"][ok]]]
    ng = _unit(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    ng *= -np.sign(np.einsum("ij,ij->i", ng, d[ok]))[:, None]  # the side the camera ray came from
    radius = float(np.ptp(mesh.vertices, axis=0).max())
    p_off = p + ng * 1e-4 * radius
    # cosine-weighted directions around ng
    u = rng.random((len(p), 2))
    r, phi = np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
    t1 = _unit(np.cross(ng, np.where(np.abs(ng[:, :1]) > 0.9, [[0, 1, 0]], [[1, 0, 0]])))
    t2 = np.cross(ng, t1)
    wi = (r * np.cos(phi))[:, None] * t1 + (r * np.sin(phi))[:, None] * t2 + np.sqrt(1 - u[:, :1]) * ng
    emissive = scene.materials.emission.max(axis=1)[mesh.material] > 0
    if emissive.any():
        et = mesh.vertices.astype(np.float64)[mesh.triangles[emissive]]
        pick = et[rng.integers(0, len(et), len(p))]
        b = rng.dirichlet((1, 1, 1), len(p))
        target = np.einsum("ij,ijk->ik", b, pick)
    else:
        lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
        target = lo + rng.random((len(p), 3)) * (hi - lo)
    far = np.full(len(p), 1e30)
    f32 = lambda a: np.ascontiguousarray(a, np.float32)  # noqa: E731
    return (es, device), {
        "camera": (f32(o), f32(d), f32(tmax), "INTERSECT"),
        "bounce": (f32(p_off), f32(wi), f32(far), "INTERSECT"),
        "shadow": (f32(p_off), f32(target - p_off), f32(np.full(len(p), 1 - 1e-4)), "OCCLUDED"),
    }


def embree_scene(mesh):
    from embreex import rtcore as rtc
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh
    device = rtc.EmbreeDevice()
    es = rtcs.EmbreeScene(device)
    TriangleMesh(es, np.ascontiguousarray(mesh.vertices, np.float32), np.ascontiguousarray(mesh.triangles, np.int32))
    return es, device  # the device must outlive the scene


def _batches(rays):
    o, d, tfar, query = rays
    return [(o[i:i + BATCH], d[i:i + BATCH], tfar[i:i + BATCH], query) for i in range(0, len(o), BATCH)]


def _trace(es, batch):
    o, d, tfar, query = batch
    if query == "INTERSECT":
        es.run(o, d, dists=tfar, output=1)
    else:
        es.run(o, d, dists=tfar, query="OCCLUDED")
    return len(o)


def probe(scene, size: int = 256, seconds: float = 2.0, threads=(1, 2)) -> dict:
    """Rays per second per kind and for an equal mix, for each thread count:
    {threads: {"camera": r, "bounce": r, "shadow": r, "mix": r}}."""
    (es, _device), rays = make_rays(scene, size)
    out = {}
    for n in threads:
        rates = {}
        with ThreadPoolExecutor(max_workers=n) as pool:
            for kind, r in rays.items():
                work = _batches(r)
                done, t0 = 0, time.perf_counter()
                while time.perf_counter() - t0 < seconds / len(rays):
                    done += sum(pool.map(lambda b: _trace(es, b), work * n))
                dt = time.perf_counter() - t0
                rates[kind] = done / dt
        # Equal numbers of each kind (a path is one camera ray, then a bounce and a shadow
        # ray per vertex): the harmonic mean of the rates.
        rates["mix"] = len(rays) / sum(1.0 / rates[k] for k in rays)
        out[n] = rates
    return out
