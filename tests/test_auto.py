"""Integrator `auto` (engine/choice/): on the hand-built scenes of
test_analysis it picks what the rule says, with the reasons in the stats, keeps what the user
set, and the render builds nothing the scene does not use."""
import dataclasses

import numpy as np
import pytest

from ember.engine import choice
from ember.engine.integrators import NAMES
from ember.engine.scene import World
from ember.engine.session import RenderSession

from test_analysis import (closed_interior, exterior_under_environment, glass_caustic_under_point_light, glossy_scene,
                           hot_spot_room, no_light)


def _auto(scene, **kw):
    return scene.replace(settings=scene.settings.replace(integrator="auto", **kw))


def _wide(scene, width=384):
    """The scene rendered `width` pixels wide (the rule weighs a cache's gain by the image size)."""
    return scene.replace(settings=scene.settings.replace(width=width, height=width))


def interior(width=384):
    return _wide(closed_interior(), width)


def test_auto_is_registered_last():
    # Blender stores the enum by index: the integrators before it keep theirs.
    assert NAMES[-1] == "auto" and NAMES[:4] == ("path", "photon", "ppm", "icache")


@pytest.mark.parametrize("build, integrator, why", [
    (exterior_under_environment, "path", ("open (", "lit by environment", "mostly direct light")),
    (glass_caustic_under_point_light, "photon", ("caustics: ", "100 % of the power from small or point lights")),
    (interior, "icache", ("enclosed (0 % of probe rays escape), diffuse (100 % of the area)",
                          "its noise in a path sample 0.52, 3.1 at 384 pixels wide (>= 2)")),
    (lambda: interior(64), "path", ("but its noise in a path sample is low (0.52, 0.5 at 64 pixels wide, < 2)",)),
    (hot_spot_room, "photon", ("in a hot spot (its noise in a path sample 2", "lit by finite lights: photon mapping")),
    (lambda: hot_spot_room(sun=True), "icache", ("irradiance cache",)),
    (glossy_scene, "path", ("glossy/specular (100 % of the area)",)),
    (no_light, "path", ("no light: nothing to cache or map",)),
])
def test_auto_chooses_by_the_rule(build, integrator, why):
    r = choice.resolve(_auto(build()))
    assert r.scene.settings.integrator == integrator
    assert r.lines[0] == r.choice.text() and all(w in r.lines[0] for w in why)
    assert r.lines[1:1 + len(r.analysis.summary.splitlines())] == tuple(r.analysis.summary.splitlines())


def test_parameters_from_the_analysis_and_the_users_win():
    r = choice.resolve(_auto(glass_caustic_under_point_light()))
    assert r.analysis.indirect_ratio < 0.5 and r.scene.settings.gather_rays == 4  # little indirect light
    assert "4 gather rays: indirect light is 0 % of direct" in r.lines
    mine = choice.resolve(_auto(glass_caustic_under_point_light(), gather_rays=9))
    assert mine.scene.settings.gather_rays == 9 and "gather rays: the user's 9" in mine.lines
    r = choice.resolve(_auto(interior()))
    assert r.scene.settings.caustic_photons == 0 and "no caustic map: no specular surface" in r.lines


@pytest.mark.parametrize("override, reason", [
    (dict(clamp_indirect=10.0), "uses what only the path tracer honours: per-kind bounce limits or clamping"),
    (dict(passes=("Diffuse Direct",)), "uses what only the path tracer honours: light passes"),
    (dict(sample_offset=4), "'icache' would fit, but the render asks for a sample offset"),
    ("negative", "uses what only the path tracer honours: negative light"),
])
def test_settings_that_only_the_path_tracer_honours_choose_it(override, reason):
    scene = interior()
    if override == "negative":
        scene, override = scene.replace(lights=dataclasses.replace(scene.lights, Le=-scene.lights.Le)), {}
    r = choice.resolve(_auto(scene, **override))
    assert r.scene.settings.integrator == "path" and reason in r.lines[0]


def _session(scene):
    session = RenderSession(scene.replace(settings=scene.settings.replace(threads=1, samples=1)))
    return session, session.run()


def test_a_named_integrator_is_not_analysed():
    session, stats = _session(exterior_under_environment())
    assert session.auto == () and stats.auto == () and "auto chose" not in stats.summary()


def test_exterior_under_an_environment_builds_its_table_and_says_why_path():
    session, stats = _session(_auto(exterior_under_environment()))
    assert session.scene.settings.integrator == "path" and session.tracer.lights.env is not None
    assert stats.auto[0] in stats.summary() and "no photon maps, no irradiance cache: path tracing" in stats.auto
    assert not any(line.startswith("no environment table") for line in stats.auto)


def test_constant_world_builds_no_environment_table():
    scene = exterior_under_environment()
    scene = scene.replace(world=World(color=np.full(3, 0.5)))
    session, stats = _session(_auto(scene))
    assert session.tracer.lights.env is None and "no environment table: the world is a constant colour" in stats.auto


def test_no_light_builds_no_light_table():
    session, stats = _session(_auto(no_light()))
    assert session.tracer.lights.select is None and session.tracer.lights.tree is None
    assert "no light-sampling table: no lights" in stats.auto and np.all(session.film.mean() == 0)


def test_caustic_scene_builds_the_caustic_map_and_the_interior_none():
    session, stats = _session(_auto(glass_caustic_under_point_light(), photons=2000, caustic_photons=20000))
    photon = session.tracer.integrator
    assert session.scene.settings.integrator == "photon" and len(photon.caustic_map) > 0
    session, stats = _session(_auto(interior(), photons=2000, icache_rays=50, border=(0, 0, 8, 8)))
    icache = session.tracer.integrator
    assert session.scene.settings.integrator == "icache" and icache.n_caustic_items == 0
    assert icache.caustic_map is None and icache.global_map is None and "photons" not in stats.stage_seconds
    assert "no caustic map: no specular surface" in stats.auto
    assert "no global photon map: the records' gather rays trace paths" in stats.auto
