"""What the path tracer keeps of a path for node programs (engine/integrators/path_state.py
Bounces.track, record; engine/nodes/hits.py RayState): Cycles' path flags as path_state_next
sets them, the bounce counts by kind, and the compact ray differentials carried as Cycles
carries them (the footprint grows by t dD along a ray, a bounce starts the next ray with it)."""
import types

import numpy as np

from ember.engine.accel import Hit
from ember.engine.bsdf.closure import LABEL_DIFFUSE, LABEL_GLOSSY, LABEL_TRANSMIT, LABEL_TRANSPARENT
from ember.engine.integrators.path_state import Bounces, PathState
from ember.engine.nodes import light_path as lp
from ember.engine.nodes.hits import camera_differentials, camera_footprint
from ember.engine.scene import Camera


def _sample(labels, delta):
    return types.SimpleNamespace(label=np.array(labels, np.int8), delta=np.array(delta, bool),
                                 pdf=np.ones(len(labels)))


def test_bounces_set_cycles_path_flags_and_counts_by_kind():
    n = 4
    b = Bounces.start(n, 8, counts=True).track(flag=np.full(n, lp.CAMERA, np.uint32))
    rows = np.arange(n)
    b.count(_sample([LABEL_DIFFUSE, LABEL_GLOSSY, LABEL_TRANSMIT, LABEL_TRANSPARENT], [0, 1, 0, 0]), rows,
            np.full(4, 99))
    assert b.flag.tolist() == [lp.REFLECT | lp.DIFFUSE, lp.REFLECT | lp.GLOSSY | lp.SINGULAR, lp.TRANSMIT | lp.GLOSSY,
                               lp.CAMERA | lp.TRANSPARENT]
    # A transparent bounce keeps the kind; the next bounce of any other kind replaces it.
    b.count(_sample([LABEL_TRANSPARENT, LABEL_DIFFUSE, LABEL_TRANSMIT, LABEL_GLOSSY], [0, 0, 1, 1]), rows,
            np.full(4, 99))
    assert b.flag.tolist() == [lp.REFLECT | lp.DIFFUSE | lp.TRANSPARENT, lp.REFLECT | lp.DIFFUSE,
                               lp.TRANSMIT | lp.GLOSSY | lp.SINGULAR, lp.REFLECT | lp.GLOSSY | lp.SINGULAR]
    r = b.record()
    assert r.bounce.tolist() == [1, 2, 2, 1]  # transparent bounces are not counted
    assert r.diffuse_bounce.tolist() == [1, 1, 0, 0] and r.glossy_bounce.tolist() == [0, 1, 0, 1]
    assert r.transmission_bounce.tolist() == [0, 0, 2, 0] and r.transparent_bounce.tolist() == [1, 0, 0, 1]
    # Gather rays leaving a surface count that bounce as a diffuse one.
    g = Bounces.start(2, 8, counts=True).track(flag=np.full(2, lp.REFLECT | lp.DIFFUSE, np.uint32), base=1)
    assert g.record().bounce.tolist() == [1, 1] and g.record().diffuse_bounce.tolist() == [1, 1]


def test_the_footprint_grows_along_rays_and_starts_the_next_ray_at_a_bounce():
    n = 3
    o = np.zeros((n, 3))
    paths = PathState.rays(o, o.astype(np.float32), np.tile([0, 0, 1.0], (n, 1)), None, np.full(n, -1))
    paths.bounces = Bounces.start(n, 8, per_path=True).track(dP=np.array([0.0, 0.1, 0.0]), dD=np.array([0.01, 0, 2e-3]))
    rows12 = np.tile(np.array([0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1.0]), (1, 1))
    hit = Hit(np.zeros(n, np.int64), np.array([2.0, 5.0, 10.0]), np.full(n, 0.2), np.full(n, 0.3), rows12)
    assert np.allclose(paths.bounces.record(np.arange(n), hit.t).dP, [0.02, 0.1, 0.02])  # the rays' emission
    at = paths.arrive(hit, np.arange(n), np.zeros(1, np.int64))
    assert np.allclose(at.bounces.record().dP, [0.02, 0.1, 0.02])  # sd->dP = dP + t dD
    at.ng = np.tile([0, 0, 1.0], (n, 1))
    nxt = at.leave(np.array([0, 2]), np.tile([0, 0, 1.0], (2, 1)), np.ones((2, 3)))
    hit2 = Hit(np.zeros(2, np.int64), np.array([1.0, 4.0]), np.full(2, 0.2), np.full(2, 0.3), rows12)
    assert np.allclose(nxt.arrive(hit2, np.arange(2), np.zeros(1, np.int64)).bounces.record().dP, [0.03, 0.028])


def _scene(ortho=False):
    camera = Camera(world_from_camera=np.eye(4), window=np.array([-0.5, 0.5, -0.25, 0.25]), ortho=ortho)
    return types.SimpleNamespace(camera=camera, settings=types.SimpleNamespace(width=200, height=100))


def test_camera_differentials_are_cycles_compact_pixel_spread():
    s = _scene()
    d = np.array([[0.0, 0.0, -1.0], [0.3, -0.2, -1.0]])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    dP, dD = camera_differentials(s, d)
    assert np.all(dP == 0.0)
    # At the centre one pixel (1/200 at unit depth) turns the direction by about its size.
    assert np.isclose(dD[0], 0.005, rtol=1e-4)
    # Off axis: Cycles' normalize(D + dx) - normalize(D), whose length falls with the distance.
    v = d[1] / -d[1, 2]
    want = 0.5 * sum(np.linalg.norm((v + s_) / np.linalg.norm(v + s_) - v / np.linalg.norm(v))
                     for s_ in (np.array([0.005, 0, 0]), np.array([0, 0.005, 0])))
    assert np.isclose(dD[1], want) and dD[1] < dD[0]
    p = 4.0 * d  # at 4 m the footprint is 4 dD
    assert np.allclose(camera_footprint(s, p), 4.0 * dD)
    dP, dD = camera_differentials(_scene(ortho=True), d)  # orthographic: the pixel's size, no spread
    assert np.allclose(dP, 0.005) and np.all(dD == 0.0)
