"""Cycles' shadow behaviours against Cycles itself (scenes in tests/shadow_scenes.py):

- transparent shadows: a leaf card (Principled Alpha from an image) casts a shadow with holes
  and half-transparent texels under an area light; the image agrees with Cycles', and its
  noise at equal samples is at most NOISE_RATIO x Cycles' (opaque shadow rays made it ~20x:
  the light through the card came from BSDF samples alone). With no transparent bounces left
  the card shadows as an opaque one, in both.
- the shadow terminator: a smooth icosphere under a grazing sun, with Blender's default
  offsets (Geometry 0.1: the terminator's shadow rays rise; 5 % brighter than without), the
  Geometry Offset 0, and a Shading Offset of 0.5 (the BSDF's terminator softened; 35 % darker).
- light and shadow linking: a light linked to one sphere, a light that excludes it and that
  only the other sphere shadows, an emissive card linked to the other sphere (16 % off when
  the linking is ignored); its noise too is at most NOISE_RATIO x Cycles'.

Each compares the region means of SEEDS independent renders (tests/cycles_renders.py agree:
within TOL plus the Sidak-corrected noise band).
"""
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

import ember  # noqa: E402

import shadow_scenes  # noqa: E402
from cycles_renders import agree, cycles_image, ember_image  # noqa: E402

pytestmark = pytest.mark.blender
SIZE = 24
SEEDS = 4
TOL = 0.01
NOISE_RATIO = 1.5  # noise (standard deviation per pixel) at equal samples, Ember / Cycles
TESTS = 6  # comparisons in this file (the Sidak correction)


@pytest.fixture(scope="module", autouse=True)
def addon():
    ember.register()
    yield
    ember.unregister()


def _renders(sc, samples, tmp_path):
    e = np.array([ember_image(sc, "PATH", samples, seed) for seed in range(SEEDS)])
    c = np.array([cycles_image(sc, samples, seed, tmp_path / f"c{seed}.exr") for seed in range(SEEDS)])
    return e, c


def _bounces(sc, transparent):
    """The same light-path limits in both (Ember's count the interactions: Cycles' + 1)."""
    sc.cycles.max_bounces = 3
    sc.cycles.diffuse_bounces = sc.cycles.glossy_bounces = sc.cycles.transmission_bounces = 3
    sc.cycles.transparent_max_bounces = transparent
    sc.ember.max_depth = sc.ember.diffuse_bounces = sc.ember.glossy_bounces = sc.ember.transmission_bounces = 4
    sc.ember.transparent_bounces = transparent


def _noise(e, c):
    """Ember's noise at equal samples (per-pixel standard deviation over the seeds, pooled)
    as a multiple of Cycles'."""
    return np.sqrt(e.var(axis=0, ddof=1).mean() / c.var(axis=0, ddof=1).mean())


def test_leaf_card_shadow(tmp_path):
    sc = shadow_scenes.leaf_card(SIZE)
    _bounces(sc, 8)
    e, c = _renders(sc, 16, tmp_path)
    agree(e, c, TESTS, TOL)
    assert _noise(e, c) <= NOISE_RATIO


def test_leaf_card_without_transparent_bounces(tmp_path):
    sc = shadow_scenes.leaf_card(SIZE)
    _bounces(sc, 0)
    agree(*_renders(sc, 8, tmp_path), TESTS, TOL)


@pytest.mark.parametrize("geometry, shading", [(None, None), (0.0, None), (None, 0.5)])
def test_terminator_offsets(geometry, shading, tmp_path):
    sc = shadow_scenes.terminator(SIZE, geometry, shading)
    agree(*_renders(sc, 4, tmp_path), TESTS, TOL)


def test_light_and_shadow_linking(tmp_path):
    sc = shadow_scenes.linking(SIZE)
    _bounces(sc, 8)
    e, c = _renders(sc, 16, tmp_path)
    agree(e, c, TESTS, TOL)
    assert _noise(e, c) <= NOISE_RATIO  # light a point may not see, found by its rays: fireflies


def test_linking_export():
    """Include, exclude and both in a receiver collection; a blocker collection; Cast Shadow
    off: the sets each object falls in and the masks each light gets."""
    from ember.engine.blender.export import export_scene
    from ember.engine.lights.linking import Links
    shadow_scenes.linking(8)
    objects = bpy.data.objects
    key, fill = objects["Key"], objects["Fill"]
    key.light_linking.receiver_collection.objects.link(objects["B"])  # A included, B now too ...
    both = key.light_linking.receiver_collection
    for ob, entry in zip(both.objects, both.collection_objects):
        entry.light_linking.link_state = "EXCLUDE" if ob.name == "B" else "INCLUDE"  # ... but excluded
    fill.data.use_shadow = False
    scene, _ = export_scene(bpy.context.evaluated_depsgraph_get())
    mesh, lights = scene.mesh, scene.lights
    links = Links(lights, mesh, np.zeros(0, np.int64), len(lights.kind))
    first = {name: mesh.objects[i] for i, name in enumerate(_object_names(scene))}
    lit = {(light, name): bool(links.lights(np.array([lights.names.index(light)]),
                                            links.receiver(np.array([first[name]])))[0])
           for light in ("Key", "Fill") for name in ("A", "B", "floor", "shade")}
    assert lit == {("Key", "A"): True, ("Key", "B"): False, ("Key", "floor"): False, ("Key", "shade"): False,
                   ("Fill", "A"): False, ("Fill", "B"): True, ("Fill", "floor"): True, ("Fill", "shade"): True}
    assert links.block[lights.names.index("Fill")] == 0  # no shadows: no blockers
    assert links.block[lights.names.index("Key")] == np.uint64(0xFFFFFFFFFFFFFFFF)
    glow = mesh.link_membership[_object_names(scene).index("glow")]
    receivers = mesh.link_sets[:, 0]
    names = _object_names(scene)
    assert [bool(int(glow[0]) >> int(receivers[names.index(n)]) & 1) for n in ("A", "B", "floor")] == [False, True, False]


def _object_names(scene):
    """The exported objects' names in Mesh.objects order (each mesh's material names it here)."""
    names = []
    for i in range(len(scene.mesh.objects) - 1):
        m = scene.mesh.material[scene.mesh.objects[i]]
        names.append(scene.materials.names[m])
    return names
