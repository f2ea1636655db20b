"""A path's value must not depend on the other paths of its batch: batch sizes, the unit
sizes the runner picks at run time, and worker counts change which paths share a wavefront,
never the image. Each path's random numbers are a pure function of seed, pixel, sample and
dimension and it sums its own contributions, so the only way a neighbour can matter is a
computation chosen per batch - as the Lambert fast path was (engine/bsdf/closure.py): a
plain Lambertian point got the fast path's numbers in an all-Lambertian batch and the
general closure's, different by an ulp, when another path of its batch hit glass or a
glossy wall (found in the path-regeneration work)."""
import numpy as np

from ember.engine.scene import (LIGHT_POINT, LOBE_DIELECTRIC, LOBE_MICROFACET, LOBE_TRANSPARENT, MAT_DIFFUSE, Lights,
                               Materials, Mesh, Scene, World)
from ember.engine.session import RenderSession

from core_scenes import box_quads, perspective, quads_mesh, settings, uv_sphere


def open_box(**kw):
    """A box open towards the camera under a constant sky: diffuse, glossy (GGX) and emitting
    walls, a glass sphere (delta lobes), a transparent sheet, a point light. Paths end by
    escaping, by Russian roulette and at bounce limits, at many different depths, and most
    deep wavefronts mix plain Lambertian points with others."""
    walls = [q for q in box_quads((-1, -1, -1), (1, 1, 1)) if not np.allclose(np.asarray(q)[:, 1], -1)]
    sheet = [[(-0.9, -0.2, -0.9), (0.9, -0.2, -0.9), (0.9, -0.2, -0.1), (-0.9, -0.2, -0.1)]]
    quads = quads_mesh(walls + sheet, [0, 1, 2, 0, 3, 4][:len(walls)] + [5])
    v, t, n = uv_sphere((0.3, 0.3, -0.5), 0.4, 12, 24)
    mesh = Mesh(np.concatenate([quads.vertices, v]), np.concatenate([quads.triangles, t + len(quads.vertices)]),
                np.concatenate([quads.normals, n]),
                np.concatenate([quads.material, np.full(len(t), 6, np.int32)]))
    mats = Materials.make([
        dict(kind=MAT_DIFFUSE, base_color=(0.7, 0.7, 0.7)),
        dict(kind=MAT_DIFFUSE, base_color=(0.7, 0.2, 0.2)),
        dict(lobes=[dict(kind=LOBE_MICROFACET, roughness=0.3, color=(0.9, 0.9, 0.9))]),
        dict(kind=MAT_DIFFUSE, base_color=(0.2, 0.7, 0.2)),
        dict(kind=MAT_DIFFUSE, base_color=(0.5, 0.5, 0.5), emission=(2.0, 2.0, 2.0)),
        dict(lobes=[dict(kind=LOBE_TRANSPARENT, color=(0.8, 0.8, 0.8))]),
        dict(lobes=[dict(kind=LOBE_DIELECTRIC, roughness=0.0, ior=1.5, color=(1.0,) * 3, tint=(1.0,) * 3)]),
    ])
    lights = Lights.make([dict(kind=LIGHT_POINT, position=(0.0, 0.2, 0.8), Le=(3.0, 3.0, 3.0))])
    base = dict(width=16, height=16, samples=12, batch_size=512, threads=1)
    base.update(kw)
    return Scene(mesh, mats, lights, World(color=np.array([0.3, 0.4, 0.5])), perspective((0, -3.5, 0), (0, 0, 0), 45),
                 settings(**base))


def _image(scene, **kw):
    session = RenderSession(scene.replace(settings=scene.settings.replace(**kw)))
    session.run()
    if "threads" in kw:
        assert session.processes == kw["threads"]
    return session.film.mean()


def test_image_does_not_depend_on_batches_or_workers():
    """Batch sizes 512 (two passes per item), 200 and 56 (items of part of a pass: the
    runner cuts passes at the batch size), 4096 (one item) and two worker processes give the
    same image bit for bit. Failed before plain points of mixed batches got the fast path's
    numbers (batch 56: a pixel 1 ulp off)."""
    scene = open_box(diffuse_bounces=3)
    first = _image(scene)
    assert first.min() > 0
    for kw in (dict(batch_size=200), dict(batch_size=56), dict(batch_size=4096), dict(threads=2)):
        assert np.array_equal(first, _image(scene, **kw)), kw

