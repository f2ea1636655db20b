"""The settings' declarations (engine/settings.py) and what is generated from them: Settings,
scene.ember's properties, the panels, the export, validation, render.py's options and README's
table. Every declared setting reaches the core with its value from Blender's UI and from the
command line; a new declaration is enough for every generated piece."""
from __future__ import annotations

import dataclasses
import math
import pathlib
import pickle

import numpy as np
import pytest

from ember.engine import rng
from ember.engine import settings as declared
from ember.engine.integrators import REGISTRY, auto, choices, honours, items
from ember.engine.integrators.irradiance import cache
from ember.engine.integrators.photon import photon_map
from ember.engine.scene import SAMPLING_ONLY, Scene, Settings
from ember.engine.errors import EmberError
from ember.engine.validation import settings_problems

from core_scenes import furnace_box

ROOT = pathlib.Path(__file__).resolve().parents[1]
DECLARED = declared.DECLARED


def probe(s: declared.Setting):
    """A value of `s` in its range other than its default (and Blender's), exact in float32."""
    if s.kind is bool:
        return not s.default
    if s.kind is str:
        return next(v for v in choices(s) if v not in (s.default, s.blender_default))
    if s.kind is int:
        return s.default + 1 if s.max is None or s.default + 1 <= s.max else s.default - 1
    lo, hi = s.min or 0.0, s.max if s.max is not None else (s.min or 0.0) + 2.0
    return float(np.float32(lo + 0.375 * (hi - lo)))


# ---- the declarations ---------------------------------------------------------------------------
def test_declarations_are_well_formed():
    names = [s.name for g in declared.GROUPS for s in g.settings]
    assert len(names) == len(set(names)) == len(DECLARED)
    flags = [s.flag for s in DECLARED.values() if s.flag]
    assert len(flags) == len(set(flags)) and all(f.startswith("--") for f in flags)
    props = [s.bpy_prop for s in DECLARED.values() if s.bpy_prop]
    assert len(props) == len(set(props))
    for s in DECLARED.values():
        assert s.label and s.description.strip() == s.description, s.name
        assert s.source in (declared.EMBER, declared.UI, declared.BLENDER, declared.INTERNAL), s.name
        assert (s.source == declared.BLENDER) == bool(s.blender), s.name
        assert not s.flag or s.bpy_prop, f"{s.name}: a flag sets a scene.ember property"
        assert not s.unit or s.unit in declared.UNITS, s.name
        assert s.kind is not str or choices(s), s.name
        for value in {s.default, s.blender_default} - {None}:
            assert declared.problem(s, value, choices(s) if s.kind is str else None) is None, (s.name, value)
        for name, condition in s.honoured:
            assert name in REGISTRY and name != auto.AutoIntegrator.name, (s.name, name)
        conditions = [c for _, c in s.honoured if c]
        if s.ui is not None:
            conditions += [c for c in (s.ui.active_if, s.ui.shown_if) if c] + [c for c, _ in s.ui.texts]
        for condition in conditions:
            assert declared._split(condition)[0] in DECLARED, (s.name, condition)


def test_integrators_agree_with_what_the_declarations_say_they_honour():
    """The integrators' own flags (what the session and `auto` act on) and honoured_by."""
    get = lambda name: getattr(Settings(), name)  # noqa: E731
    for name, cls in REGISTRY.items():
        for flag, setting in (("adaptive", "adaptive"), ("noise_target", "noise_target"),
                              ("sample_offset", "sample_offset")):
            assert getattr(cls, flag) == honours(DECLARED[setting], name, get), (name, setting)


def test_choices_have_one_home():
    assert rng.PATTERNS == DECLARED["pattern"].values == ("sobol", "random")
    assert photon_map.KERNELS == DECLARED["photon_kernel"].values
    assert cache.WEIGHTS == DECLARED["icache_weight"].values
    assert choices(DECLARED["integrator"]) == tuple(REGISTRY)


# ---- Settings -----------------------------------------------------------------------------------
def test_settings_is_generated_from_the_declarations(tmp_path):
    fields = dataclasses.fields(Settings)
    assert [f.name for f in fields] == [s.name for s in declared.FIELDS]
    assert all(f.default == DECLARED[f.name].default for f in fields)
    assert "use_animated_seed" not in {f.name for f in fields}  # UI only
    s = Settings()
    assert s.integrator == "auto" and s.samples == 16 and s.border == (0, 0, 64, 64)
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.samples = 3
    changed = s.replace(**{d.name: probe(d) for d in declared.FIELDS if d.kind is not tuple},
                        border=(1, 2, 30, 40), passes=("Depth", "Normal"), origin=(1.0, 2.0, 3.0))
    assert pickle.loads(pickle.dumps(changed)) == changed
    assert SAMPLING_ONLY == tuple(d.name for d in declared.FIELDS if d.sampling_only)
    scene = furnace_box()
    scene = scene.replace(settings=changed)
    scene.save(tmp_path / "scene.npz")
    assert Scene.load(tmp_path / "scene.npz").settings == changed


def test_validation_checks_every_range_and_choice():
    """Each declared range and choice in one message format: '<setting> must be ...'."""
    assert settings_problems(Settings()) == []
    for s in declared.FIELDS:
        bad = []
        if s.kind is str:
            bad.append(("nope", f"{s.name.replace('_', ' ')} must be one of: "))
        if s.kind in (int, float) and s.min is not None:
            bad.append((s.kind(s.min - 1), f"{s.name.replace('_', ' ')} must be at least"))
        if s.kind in (int, float) and s.max is not None:
            bad.append((s.kind(s.max + 1), f"{s.name.replace('_', ' ')} must be at most"))
        if s.kind is float:
            bad.append((math.nan, f"{s.name.replace('_', ' ')} must be a finite number"))
        for value, words in bad:
            problems = settings_problems(Settings().replace(**{s.name: value}))
            assert any(p.startswith(words) for p in problems), (s.name, value, problems)


def test_path_only_warnings_follow_honoured_by():
    from ember.engine.validation import PATH_ONLY, path_only_warnings
    assert {s.name for s in PATH_ONLY} == {"diffuse_bounces", "glossy_bounces", "transmission_bounces",
                                           "transparent_bounces", "volume_bounces", "caustics_reflective",
                                           "caustics_refractive",
                                           "clamp_direct", "clamp_indirect", "filter_glossy"}
    scene = furnace_box(integrator="photon", clamp_direct=2.0, glossy_bounces=3)
    (warning,) = path_only_warnings(scene)
    assert "ignores glossy bounces, clamp direct (Path Tracing only" in warning


def test_readme_table_is_what_the_declarations_generate():
    from tools.settings_table import README, START, row, updated
    text = README.read_text()
    assert START in text and updated(text) == text, "README.md is stale: ./dev python tools/settings_table.py"
    for s in DECLARED.values():
        assert row(s, items(s) if s.kind is str else ()) in text


@pytest.mark.blender
def test_presets_are_declared_values_in_range():
    pytest.importorskip("bpy")
    from ember.ui.presets import PRESETS
    by_prop = {s.bpy_prop: s for s in DECLARED.values() if s.bpy_prop}
    for name, values in PRESETS.items():
        for prop, value in values.items():
            assert prop in by_prop, (name, prop)
            s = by_prop[prop]
            assert type(value) is s.kind, (name, prop)
            assert declared.problem(s, s.core(value), blender=True) is None, (name, prop, value)


# ---- through Blender and the command line ------------------------------------------------------
@pytest.fixture(scope="module")
def bpy():
    bpy = pytest.importorskip("bpy")
    import ember
    ember.register()
    yield bpy
    ember.unregister()


@pytest.fixture
def scene(bpy):
    sc = bpy.data.scenes.new("EmberSettings")
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 32, 24, 100
    yield sc
    bpy.data.scenes.remove(sc)


def _exported(sc):
    from ember.engine.blender.export_settings import export_settings
    return export_settings(sc)


EXPORTED = [s for s in DECLARED.values() if s.source == declared.EMBER]
FLAGGED = [s for s in DECLARED.values() if s.flag]


@pytest.mark.blender
@pytest.mark.parametrize("s", EXPORTED, ids=lambda s: s.name)
def test_every_ui_setting_reaches_the_core(scene, s):
    value = probe(s)
    setattr(scene.ember, s.bpy_prop, value.upper() if s.kind is str else value)
    assert getattr(_exported(scene), s.name) == value


@pytest.mark.blender
def test_ui_only_settings_reach_what_reads_them(scene):
    """The scene.ember properties that are no Settings field: the animated seed (the export)
    and the viewport's samples."""
    from ember.engine.blender.viewport import viewport_overrides
    assert {s.name for s in DECLARED.values() if s.source == declared.UI} == {"preview_samples", "use_animated_seed"}
    scene.ember.seed = 7
    scene.ember.use_animated_seed = True
    assert _exported(scene).seed not in (7, Settings.seed)
    scene.ember.preview_samples = 5
    assert viewport_overrides(scene, (8, 6))["samples"] == 5


@pytest.mark.blender
@pytest.mark.parametrize("s", FLAGGED, ids=lambda s: s.flag)
def test_every_flag_reaches_the_core(scene, s):
    """render.py's parser and its settings application onto a scene, then the export."""
    import render
    value = probe(s)
    args = render.build_parser(False).parse_args([s.flag, declared.to_text(s, value)])
    render._apply_settings(scene, args)
    exported = _exported(scene)
    if s.name == "use_animated_seed":
        assert exported.seed not in (scene.ember.seed, Settings.seed)
    else:
        assert getattr(exported, s.name) == value


@pytest.mark.blender
def test_every_declaration_has_its_generated_pieces(bpy):
    """Property (with the declared range and default), option, validation and table row."""
    import render
    props = bpy.types.Scene.bl_rna.properties["ember"].fixed_type.properties
    parser_flags = {o for a in render.build_parser(False)._actions for o in a.option_strings}
    text = (ROOT / "README.md").read_text()
    for s in DECLARED.values():
        assert f"| `{s.name}`" in text, s.name
        assert not s.flag or s.flag in parser_flags, s.name
        if not s.bpy_prop:
            continue
        p = props[s.bpy_prop]
        assert p.name == s.label and p.description == s.description, s.name
        if s.kind is str:
            assert p.default == s.blender_default.upper()
            assert [i.identifier for i in p.enum_items] == [v.upper() for v in choices(s)]
        else:
            assert p.default == pytest.approx(s.blender_default), s.name
        if s.kind in (int, float):  # the declared range is soft: Blender never clamps, Ember refuses
            assert p.soft_min == pytest.approx(s.min if s.soft_min is None else s.soft_min), s.name
            if s.max is not None:
                assert p.soft_max == pytest.approx(s.max if s.soft_max is None else s.soft_max), s.name
            assert p.hard_min < (s.min if s.min is not None else 0) - 1, s.name


@pytest.mark.blender
def test_a_new_declaration_is_enough(bpy):
    """A setting declared anywhere gets its bpy property, option, checks and table row."""
    import argparse

    import render
    from tools.settings_table import row
    from ember.ui.properties import bpy_property

    knob = declared.Float("knob", 0.5, "Knob", "A test knob", min=0.25, max=2.0, unit="m", flag="--knob",
                          honoured_by=("path",))
    mode = declared.Enum("mode", "a", "Mode", "A test mode", (("a", "A", "first"), ("b", "B", "second")),
                         flag="--mode")
    prop = bpy_property(knob)
    assert prop.function is bpy.props.FloatProperty
    assert {k: prop.keywords[k] for k in ("name", "default", "soft_min", "soft_max", "subtype", "unit")} == dict(
        name="Knob", default=0.5, soft_min=0.25, soft_max=2.0, subtype='DISTANCE', unit='LENGTH')
    assert "min" not in prop.keywords and "max" not in prop.keywords  # refused by Ember, not clamped by Blender
    assert [i[0] for i in bpy_property(mode).keywords["items"]] == ["A", "B"]
    parser = argparse.ArgumentParser()
    render.add_setting_options(parser, declared, [declared.group("test", "Test", knob, mode)])
    assert parser.parse_args(["--knob", "1.5", "--mode", "B"]) == argparse.Namespace(knob=1.5, mode="b")
    assert declared.problem(knob, 3.0) == "must be at most 2 (got 3)"
    assert declared.problem(mode, "c") == "must be one of: a, b (got 'c')"
    assert row(knob) == "| `knob` | Knob | `--knob` | 0.5 | 0.25..2 metres | path |"


# ---- panels -------------------------------------------------------------------------------------
class _Layout:
    """Records the properties a panel draws: (property, text, active)."""

    def __init__(self, drawn, parent=None):
        self.drawn, self.parent, self.active, self.enabled = drawn, parent, True, True
        self.use_property_split = self.use_property_decorate = False

    def _is_active(self):
        return self.active and (self.parent is None or self.parent._is_active())

    def column(self, **kw):
        return _Layout(self.drawn, self)

    row = column

    def prop(self, owner, name, text=None, icon='NONE'):
        self.drawn.append((name, text, self._is_active()))

    def label(self, text="", icon='NONE'):
        self.drawn.append(("label", text, True))

    def menu(self, *args, **kw):
        pass


def _draw(scene, group, **kw):
    from ember.ui import panels
    drawn = []
    panels.draw_settings(_Layout(drawn), scene, group, **kw)
    return drawn


@pytest.mark.blender
def test_panels_draw_the_declared_settings(scene):
    e = scene.ember
    e.integrator = 'PPM'
    assert _draw(scene, "photons") == [("photons", "Photons per Pass", True), ("ppm_radius", "Initial Radius", True),
                                       ("ppm_alpha", "Alpha", True)]
    e.integrator, e.icache_gather = 'ICACHE', 'PATH'
    assert [d[0] for d in _draw(scene, "photons")] == ["caustic_photons", "photon_k", "photon_kernel",
                                                        "caustic_radius", "gather_rays"]
    e.icache_gather = 'PHOTON'
    assert ("gather_rays", "Gather Rays (uncached)", True) in _draw(scene, "photons")
    assert ("global_radius", "Global Radius", True) in _draw(scene, "photons")
    e.icache_radiance = False
    assert ("icache_radiance_order", "Harmonics Order", False) in _draw(scene, "icache")
    e.integrator = 'PATH'
    assert _draw(scene, "photons") == [] and _draw(scene, "icache") == []
    sampling = _draw(scene, "sampling", hide_unhonoured=False)
    assert ("adaptive_threshold", "", False) in sampling and ("samples", "Samples", True) in sampling
    assert "adaptive_min_samples" not in [d[0] for d in sampling] and "sample_offset" not in [d[0] for d in sampling]
    e.use_adaptive_sampling = True
    sampling = _draw(scene, "sampling", hide_unhonoured=False)
    assert ("samples", "Max Samples", True) in sampling and ("adaptive_min_samples", "Min Samples", True) in sampling
    assert _draw(scene, "sampling", subpanel="advanced", hide_unhonoured=False) == [("sample_offset", "Sample Offset",
                                                                                    True)]
    e.integrator = 'PHOTON'
    paths = _draw(scene, "light_paths", hide_unhonoured=False)
    assert ("max_depth", "Max Bounces", True) in paths and ("diffuse_bounces", "Diffuse", False) in paths
    # Every drawn scene.ember setting shows in its panel for some integrator (auto: its candidates').
    shown = set()
    for integrator in REGISTRY:
        e.integrator = integrator.upper()
        for g in declared.GROUPS:
            shown |= {d[0] for d in _draw(scene, g.name) + _draw(scene, g.name, subpanel="advanced")}
    assert {s.bpy_prop for s in DECLARED.values() if s.bpy_prop and s.ui is not None} <= shown


@pytest.mark.blender
def test_out_of_range_values_are_refused_never_clamped(scene):
    """One rule for every declared setting: Blender keeps a value out of the declared range as
    set (no hard limits to clamp it silently) and the render refuses it with one line naming
    the setting, its limit and the value (the CLI's options give the same words)."""
    from ember.engine.blender.export_settings import export_settings
    cases = [(s, (s.max * 1.5 if s.max else s.max + 1) if s.max is not None else s.min - 1)
             for s in DECLARED.values() if s.bpy_prop and s.kind in (int, float) and s.source == declared.EMBER
             and (s.max is not None or s.min is not None)]
    assert {"ppm_alpha", "icache_a", "icache_rays", "icache_radiance_order"} <= {s.name for s, _ in cases}
    for s, value in cases:
        value = s.kind(value)
        setattr(scene.ember, s.bpy_prop, value)
        assert getattr(scene.ember, s.bpy_prop) == pytest.approx(value), f"{s.name} was clamped"
        try:
            refusal = "; ".join(settings_problems(export_settings(scene)))
        except EmberError as e:
            refusal = str(e)
        assert f"{s.name.replace('_', ' ')} {declared.problem(s, s.core(getattr(scene.ember, s.bpy_prop)))}" \
            in refusal, s.name
        setattr(scene.ember, s.bpy_prop, s.blender_default)
