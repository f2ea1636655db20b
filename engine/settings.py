"""Ember's render settings, each declared once: the declarations below are the only list.

A declaration says what a setting is (type, default, hard range and the UI's soft limits,
unit, or its choices), what it means (label and description: Blender's name and tooltip),
where its value comes from (`source`), its command-line flag, which integrators honour it,
and how Render Properties draws it. Declarations are grouped by subsystem. From them:

    Settings (below)                    the core's frozen dataclass (engine.scene re-exports it)
    ui/properties.py                    the bpy properties of scene.ember
    ui/panels.py                        the settings in the Render Properties panels
    engine/blender/export_settings.py   scene.ember -> Settings
    engine/validation.py                range and choice checks (`problem`)
    render.py                           the settings' command-line options
    tools/settings_table.py             README's settings table

A new setting is one declaration here plus the code that reads it. Knows nothing of Blender
and imports no engine module (the integrators import it).
"""
from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass

# Where a setting's value comes from.
EMBER = "scene.ember"  # a scene.ember property (named `prop` where that differs), exported into Settings
UI = "ui"  # a scene.ember property that is no Settings field (the export or the viewport reads it)
BLENDER = "blender"  # Blender's own data (`blender` names it), read by engine/blender/export*.py
INTERNAL = "internal"  # set by the engine, or by tests and benches through overrides

# The items of `integrator` are the registry's (engine/integrators: each class's name, label and
# description), which imports this module: engine.integrators.items resolves them.
REGISTERED = "registered integrators"

INT_MAX = 2**31 - 1  # Blender holds integer properties in 32 bits ...
FLOAT_MAX = 3.4028234663852886e38  # ... and float properties in float32

UNITS = {"s": "seconds", "m": "metres", "px": "pixels"}


@dataclass(frozen=True)
class Ui:
    """How its group's panel draws a setting (ui/panels.py). A condition is "name" (that
    setting is on), "name=value" or "name!=value" (an enum's value, in any case)."""

    column: str | None = None  # starts a new column under this heading ("": none)
    text: str | None = None  # the text beside it (None: the label; "": none)
    texts: tuple = ()  # (condition, text): the text while the condition holds
    beside: bool = False  # in the row of the setting before it
    icon: str = ""
    active_if: str = ""  # greyed out unless the condition holds
    shown_if: str = ""  # left out unless the condition holds
    subpanel: str = ""  # in that sub-panel of the group's panel ("advanced")
    precision: int | None = None  # Blender's digits shown for a float ...
    step: float | None = None  # ... and its drag step (in 1/100)


@dataclass(frozen=True)
class Setting:
    """One setting. name: the Settings field (the scene.ember property unless `prop` says
    otherwise); kind: bool, int, float, str (an enum: `items`) or tuple (of `of`).
    Range: min/max hard (everywhere), soft_min/soft_max the UI slider's. items: (value, label,
    description), value the core's; Blender's enum identifier is value.upper().
    honoured_by: integrator names, "name if condition" where a setting decides; () = all."""

    name: str
    kind: type
    default: object
    label: str
    description: str
    min: float | None = None
    max: float | None = None
    soft_min: float | None = None
    soft_max: float | None = None
    unit: str = ""  # a key of UNITS
    items: tuple | str = ()
    of: type | None = None
    flag: str | None = None  # render.py's option
    honoured_by: tuple = ()
    source: str = EMBER
    prop: str | None = None
    ui_default: object = None  # the bpy property's default where it differs from the core's
    sampling_only: bool = False  # how many samples, where, how fast: not what the image converges to
    blender: str = ""  # BLENDER: the data it comes from, from the bpy Scene ("render.film_transparent")
    ui: Ui | None = Ui()  # None: not drawn in Ember's panels

    @property
    def field(self) -> bool:
        """Whether Settings has it."""
        return self.source != UI

    @property
    def bpy_prop(self) -> str | None:
        """The scene.ember property, if it is one."""
        return (self.prop or self.name) if self.source in (EMBER, UI) else None

    @property
    def blender_default(self):
        return self.default if self.ui_default is None else self.ui_default

    @property
    def values(self) -> tuple:
        """An enum's core values as declared (() for `integrator`: engine.integrators.items)."""
        return () if self.items == REGISTERED else tuple(v for v, _, _ in self.items)

    @property
    def honoured(self) -> tuple:
        """honoured_by as (integrator, condition or "")."""
        return tuple((name, condition) for name, _, condition in (h.partition(" if ") for h in self.honoured_by))

    def core(self, value):
        """A value from Blender, the command line or an override, as the core holds it: enums
        by value in any case (Blender's upper-case identifiers), tuples of `of`."""
        if value is None:
            return None
        if self.kind is str:
            text = str(value)
            return next((v for v in self.values if v.lower() == text.lower()), text.lower())
        if self.kind is tuple:
            return tuple(self.of(v) for v in value)
        return self.kind(value)


def Bool(name, default, label, description, **kw) -> Setting:
    return Setting(name, bool, default, label, description, **kw)


def Int(name, default, label, description, **kw) -> Setting:
    return Setting(name, int, default, label, description, **kw)


def Float(name, default, label, description, **kw) -> Setting:
    return Setting(name, float, default, label, description, **kw)


def Enum(name, default, label, description, items, **kw) -> Setting:
    return Setting(name, str, default, label, description, items=items, **kw)


def Tuple(name, default, label, description, of, **kw) -> Setting:
    return Setting(name, tuple, default, label, description, of=of, ui=None, **kw)


@dataclass(frozen=True)
class Group:
    """The settings of one subsystem, in the order the UI, --help and README show them."""

    name: str
    label: str
    settings: tuple


def group(name: str, label: str, *settings: Setting) -> Group:
    return Group(name, label, settings)


# ---- the declarations ---------------------------------------------------------------------------
PATH = ("path",)
PHOTON_MAPS = ("photon", "path_caustic", "icache")  # integrators whose estimates read photon maps
# Every pass of ppm shrinks every pixel's radius: its passes cover all pixels and are no
# independent samples of one image (the integrators' own `adaptive` and `noise_target`).
NOT_PPM = ("path", "photon", "icache", "path_caustic")
# Whose passes stand alone given the published data (the integrators' `sample_offset`).
SAMPLE_RANGES = ("path", "photon", "path_caustic")

GROUPS = (
    group(
        "sampling", "Sampling",
        Enum("integrator", "auto", "Integrator", "Method used to compute light transport", REGISTERED,
             flag="--integrator"),
        Bool("adaptive", False, "Use Adaptive Sampling",
             "Stop sampling each pixel once its estimated noise is below the noise threshold "
             "(decided every 16 passes after the minimum samples; path tracing and photon mapping)",
             prop="use_adaptive_sampling", flag="--adaptive", honoured_by=NOT_PPM,
             ui=Ui(column="Noise Threshold", text="")),
        Float("adaptive_threshold", 0.01, "Noise Threshold",
              "Noise level at which a pixel stops; lower: less noise, longer renders "
              "(0 = automatic from the samples, as Cycles)",
              min=0.0, max=1.0, soft_min=0.001, flag="--adaptive-threshold", honoured_by=NOT_PPM,
              ui=Ui(beside=True, text="", active_if="adaptive", precision=4)),
        Int("samples", 16, "Samples", "Samples per pixel (full passes over the image)",
            min=1, soft_max=4096, ui_default=64, flag="--samples", sampling_only=True,
            ui=Ui(column="", texts=(("adaptive", "Max Samples"),))),
        Int("adaptive_min_samples", 0, "Min Samples",
            "Samples every pixel gets before adaptive sampling may stop it "
            "(0 = automatic from the noise threshold, as Cycles)",
            min=0, max=4096, flag="--adaptive-min-samples", honoured_by=NOT_PPM, ui=Ui(shown_if="adaptive")),
        Int("preview_samples", 64, "Viewport Samples",
            "Samples per pixel the viewport's Rendered shading refines to",
            min=1, soft_max=4096, source=UI),
        Float("time_limit", 0.0, "Time Limit",
              "Stop after this many seconds (0 = no limit); the last pass finishes first",
              min=0.0, soft_max=3600.0, unit="s", flag="--time-limit", sampling_only=True),
        Float("noise_target", 0.0, "Noise Target",
              "Stop once the estimated relative noise (RMS over pixels of the standard "
              "error of the mean over mean + 0.01) falls to this value (0 = off)",
              min=0.0, soft_max=0.1, flag="--noise-target", sampling_only=True,
              honoured_by=NOT_PPM,
              ui=Ui(column="", precision=4, step=0.1)),
        Int("seed", 0, "Seed", "Random seed; a render with the same seed and settings is reproducible",
            min=0, flag="--seed", sampling_only=True),
        Bool("use_animated_seed", False, "Use Animated Seed",
             "A different seed, and so a different noise pattern, on every frame",
             source=UI, flag="--animated-seed", ui=Ui(beside=True, text="", icon="TIME")),
        Enum("pattern", "sobol", "Pattern", "Random number pattern used to place samples", (
            ("sobol", "Sobol-Burley", "Owen-scrambled Sobol sequence (as Cycles): lower noise per sample"),
            ("random", "Independent", "Independent random numbers per sample (for studies)"),
        ), flag="--pattern"),
        Int("sample_offset", 0, "Sample Offset",
            "Take samples [offset, offset + samples) of the sample sequence, so that renders of "
            "disjoint ranges (on several machines) merge exactly into one (render.py merge)",
            min=0, flag="--sample-offset", sampling_only=True, honoured_by=SAMPLE_RANGES,
            ui=Ui(subpanel="advanced")),
    ),
    # Limits count surface interactions of one kind on a path, like max_depth: Cycles' bounces
    # + 1 (transparent passes as Cycles counts them; they do not count toward max_depth).
    group(
        "light_paths", "Light Paths",
        Int("max_depth", 64, "Max Bounces",
            "Longest light path, in surface interactions (0: emitters seen directly only)",
            min=0, max=1024, flag="--max-depth"),
        Int("diffuse_bounces", 64, "Diffuse",
            "Most diffuse reflections on a path; the last one sees emitters only "
            "(1 = direct light only: Cycles' Diffuse bounces + 1)",
            min=1, max=1024, flag="--diffuse-bounces", honoured_by=PATH, ui=Ui(column="Bounces")),
        Int("glossy_bounces", 64, "Glossy",
            "Most glossy and mirror reflections on a path (Cycles' Glossy bounces + 1)",
            min=1, max=1024, flag="--glossy-bounces", honoured_by=PATH),
        Int("transmission_bounces", 64, "Transmission",
            "Most refractions on a path (Cycles' Transmission bounces + 1)",
            min=1, max=1024, flag="--transmission-bounces", honoured_by=PATH),
        Int("transparent_bounces", 64, "Transparent",
            "Most passes through transparent surfaces (as Cycles'); they do not count toward Max Bounces",
            min=0, max=1024, flag="--transparent-bounces", honoured_by=PATH),
        Int("volume_bounces", 1, "Volume",
            "Most scattering events in volumes on a path; past it a path is only attenuated "
            "(1 = single scattering: Cycles' Volume bounces + 1, Cycles' default)",
            min=1, max=1024, flag="--volume-bounces", honoured_by=PATH),
        Float("clamp_direct", 0.0, "Direct Light",
              "Scale down direct-light samples whose mean RGB exceeds this (0 = off; "
              "biased, as Cycles' clamping)",
              min=0.0, soft_max=100.0, flag="--clamp-direct", honoured_by=PATH, ui=Ui(column="Clamping")),
        Float("clamp_indirect", 0.0, "Indirect Light",
              "Scale down indirect-light samples whose mean RGB exceeds this (0 = off; "
              "tames fireflies, biased, as Cycles' clamping)",
              min=0.0, soft_max=100.0, flag="--clamp-indirect", honoured_by=PATH),
        Float("filter_glossy", 0.0, "Filter Glossy",
              "Blur glossy reflections after rough bounces to reduce noise from caustics "
              "(0 = off; biased, as Cycles' Filter Glossy)",
              min=0.0, soft_max=10.0, flag="--filter-glossy", honoured_by=PATH, ui=Ui(column="Caustics")),
        Bool("caustics_reflective", True, "Reflective Caustics",
             "Glossy reflection seen right after a diffuse bounce (off: less noise, no reflective caustics)",
             flag="--caustics-reflective", honoured_by=PATH, ui=Ui(text="Reflective")),
        Bool("caustics_refractive", True, "Refractive Caustics",
             "Refraction seen right after a diffuse bounce (off: less noise, no refractive caustics)",
             flag="--caustics-refractive", honoured_by=PATH, ui=Ui(text="Refractive")),
    ),
    # Radii 0 = relative to the scene's size. The irradiance cache reads the global map only
    # when its gather rays read photons.
    group(
        "photons", "Photon Mapping",
        Int("photons", 200_000, "Global Photons",
            "Photon paths emitted for the global map (indirect light read by final gathering; "
            "progressive photon mapping: per pass)",
            min=0, soft_max=10_000_000, flag="--photons",
            honoured_by=("photon", "ppm", "icache if icache_gather=photon"),
            ui=Ui(texts=(("integrator=ppm", "Photons per Pass"),))),
        Int("caustic_photons", 1_000_000, "Caustic Photons",
            "Photon paths emitted for the caustic map (light focused by glass and mirrors "
            "onto diffuse surfaces); skipped when the scene has no specular surface",
            min=0, soft_max=50_000_000, flag="--caustic-photons", honoured_by=PHOTON_MAPS),
        Int("photon_k", 50, "Photons per Estimate",
            "Nearest photons in one radiance estimate (more: smoother, more blurred)",
            min=2, soft_max=500, flag="--photon-k", honoured_by=PHOTON_MAPS),
        Enum("photon_kernel", "uniform", "Kernel", "Weight of a photon by its distance in a radiance estimate", (
            ("uniform", "Uniform", "Every photon within the radius counts the same (the seed's estimate)"),
            ("cone", "Cone", "Jensen's cone filter: nearer photons count more (sharper caustics)"),
            ("epanechnikov", "Epanechnikov", "Smooth (1 - d^2/r^2)^2 weight, as Mitsuba and pbrt-v2"),
        ), flag="--photon-kernel", honoured_by=PHOTON_MAPS),
        Float("global_radius", 0.0, "Global Radius",
              "Largest search radius in the global map (0 = 5 % of the scene's bounding radius)",
              min=0.0, unit="m", flag="--global-radius", honoured_by=("photon", "icache if icache_gather=photon")),
        Float("caustic_radius", 0.0, "Caustic Radius",
              "Largest search radius in the caustic map (0 = 1.25 % of the scene's bounding radius)",
              min=0.0, unit="m", flag="--caustic-radius", honoured_by=PHOTON_MAPS),
        Int("gather_rays", 16, "Gather Rays",
            "Final-gathering rays per camera sample at the first diffuse surface "
            "(irradiance cache: where no record serves)",
            min=0, soft_max=256, flag="--gather-rays", honoured_by=("photon", "icache"),
            ui=Ui(texts=(("integrator=icache", "Gather Rays (uncached)"),))),
        Bool("radiance_photons", True, "Radiance Photons",
             "Precompute irradiance at every 4th photon so a gather ray needs one lookup "
             "(Christensen 1999): much faster, slightly more blurred",
             flag="--radiance-photons", honoured_by=("photon",)),
        Enum("photon_view", "full", "View", "What the photon integrator shows", (
            ("full", "Full", "The rendered image"),
            ("global", "Global Map", "Debug: the global photon map's radiance estimate seen directly"),
            ("caustic", "Caustic Map", "Debug: the caustic map's radiance estimate alone"),
            ("positions", "Photon Positions", "Debug: where photons landed (white), caustic photons in orange"),
            ("indirect", "Indirect",
             "Debug: final gathering alone (diffuse indirect light, no direct light or caustics)"),
        ), flag="--photon-view", honoured_by=("photon",)),
        Float("ppm_radius", 0.0, "Initial Radius",
              "Progressive photon mapping: each pixel's first gathering radius "
              "(0 = 1 % of the scene's bounding radius); it shrinks every pass",
              min=0.0, unit="m", flag="--ppm-radius", honoured_by=("ppm",)),
        Float("ppm_alpha", 2.0 / 3.0, "Alpha",
              "Progressive photon mapping: share of each pass's photons kept as the radius "
              "shrinks (smaller: faster shrinking, more noise)",
              min=0.01, max=0.99, flag="--ppm-alpha", honoured_by=("ppm",)),
    ),
    group(
        "icache", "Irradiance Cache",
        Float("icache_a", 0.2, "Accuracy",
              "Ward's accuracy a: a record is used where its estimated error is below a "
              "(smaller: more records, more accurate; the seed recommends 0.1-0.35)",
              min=0.05, max=0.5, flag="--icache-a", honoured_by=("icache",)),
        Int("icache_rays", 392, "Rays per Record",
            "Stratified gather rays per irradiance record (M x 2M cells; Mitsuba 0.6's 14 x 28)",
            min=50, max=2000, flag="--icache-rays", honoured_by=("icache",)),
        Bool("icache_gradients", True, "Gradients",
             "Extrapolate records by their rotational and translational irradiance gradients",
             flag="--icache-gradients", honoured_by=("icache",)),
        Enum("icache_weight", "ward", "Weight", "How records are weighted when interpolated", (
            ("ward", "Ward",
             "Ward's weight 1 / (|p - p_i| / R_i + sqrt(1 - n.n_i)) with the accuracy threshold (the seed's)"),
            ("tabellion", "Tabellion-Lamorlette",
             "1 - max(distance, normal) terms: falls to 0 at the edge (no contours)"),
        ), flag="--icache-weight", honoured_by=("icache",)),
        Enum("icache_gather", "path", "Gather", "Radiance found by a record's gather rays", (
            ("path", "Path Tracing", "Gather rays trace paths: unbiased records, refined as the passes grow"),
            ("photon", "Photon Map", "Gather rays read the global photon map (the seed's combination: smooth, "
                                     "biased where photons are sparse, slower per record here)"),
        ), flag="--icache-gather", honoured_by=("icache",)),
        Enum("icache_view", "full", "View", "What the irradiance cache shows", (
            ("full", "Full", "The rendered image"),
            ("records", "Records", "Debug: record positions as white dots over the dimmed indirect light"),
            ("indirect", "Indirect", "Debug: the cached diffuse indirect light alone (no direct light or caustics)"),
        ), flag="--icache-view", honoured_by=("icache",)),
        Bool("icache_radiance", False, "Radiance Caching",
             "Rough glossy surfaces also take their indirect light from the records, which then "
             "hold the incident radiance in spherical harmonics (Krivanek et al. 2005); sharper "
             "lobes keep final gathering",
             flag="--icache-radiance", honoured_by=("icache",)),
        Int("icache_radiance_order", 7, "Harmonics Order",
            "Spherical-harmonics order of radiance records (order^2 coefficients). It sets the "
            "sharpest lobe cached: GGX roughness >= 0.70 / 0.65 / 0.61 / 0.58 at order 5 / 6 / 7 / 8",
            min=2, max=8, flag="--icache-radiance-order", honoured_by=("icache",),
            ui=Ui(active_if="icache_radiance")),
    ),
    group(
        "performance", "Performance",
        Int("batch_size", 1 << 17, "Batch Size",
            "Rays traced together in one wavefront; bigger is faster but uses more memory",
            min=1, soft_min=1024, soft_max=1 << 20, sampling_only=True),
        Int("threads", 0, "Threads",
            "Worker processes, one per CPU thread (0 = every CPU the process may use; 1: all in the "
            "render process); render.py --threads",
            min=0, source=BLENDER, blender="render.threads", sampling_only=True, ui=None),
        Bool("persistent", False, "Persistent Data",
             "Keep worker processes, Embree scenes and light tables for the next render (animations): "
             "only the scene parts that changed are built again",
             source=BLENDER, blender="render.use_persistent_data", sampling_only=True, ui=None),
    ),
    # Pixel rows count from the top of the image in the core.
    group(
        "film", "Film",
        Int("width", 64, "Width", "Full frame width (resolution percentage applied); render.py --resolution",
            min=1, unit="px", source=BLENDER, blender="render.resolution_x", ui=None),
        Int("height", 64, "Height", "Full frame height (resolution percentage applied); render.py --resolution",
            min=1, unit="px", source=BLENDER, blender="render.resolution_y", ui=None),
        Tuple("border", None, "Render Region",
              "The pixel rectangle rendered (x0, y0, x1, y1): top-left origin, half-open; "
              "the whole frame when unset; render.py --border",
              of=int, unit="px", source=BLENDER, blender="render.use_border", sampling_only=True),
        Bool("film_transparent", False, "Transparent",
             "Camera rays that escape give alpha 0 and no world (the world still lights the scene)",
             source=BLENDER, blender="render.film_transparent"),
        Enum("filter", "BLACKMAN_HARRIS", "Pixel Filter", "Reconstruction filter of the samples (Cycles')", (
            ("BOX", "Box", "Box filter, one pixel wide"),
            ("GAUSSIAN", "Gaussian", "Gaussian filter"),
            ("BLACKMAN_HARRIS", "Blackman-Harris", "Blackman-Harris filter"),
        ), source=BLENDER, blender="cycles.pixel_filter_type"),
        Float("filter_width", 1.5, "Width", "Pixel filter width (a box filter is one pixel wide, as Cycles renders it)",
              min=0.01, max=10.0, unit="px", source=BLENDER, blender="cycles.filter_width",
              ui=Ui(active_if="filter!=box")),
        Tuple("passes", (), "Passes", "Render passes besides Combined, by Blender name (engine/passes.py)",
              of=str, source=BLENDER, blender="view_layer"),
    ),
    group(
        "internal", "Internal",
        Enum("strategy", "mis", "Strategy",
             "Direct light: light and BSDF samples combined by MIS, or one alone (studies and the "
             "strategy-agreement tests; each alone is unbiased too, where it can reach the light)", (
                 ("mis", "MIS", "Light and BSDF samples combined by the balance heuristic"),
                 ("bsdf", "BSDF", "BSDF samples alone"),
                 ("light", "Light", "Light samples alone"),
             ), source=INTERNAL, honoured_by=PATH, ui=None),
        Int("rr_depth", 3, "Roulette Depth", "Bounces before Russian roulette may end a path",
            min=0, source=INTERNAL, honoured_by=PATH, ui=None),
        Tuple("origin", (0.0, 0.0, 0.0), "Origin",
              "World position of the core's (0, 0, 0) (engine/scene.py: recentred)",
              of=float, unit="m", source=INTERNAL),
    ),
)

DECLARED = {s.name: s for g in GROUPS for s in g.settings}  # name -> Setting
FIELDS = tuple(s for s in DECLARED.values() if s.field)
# Settings that say how many samples to take, where and how fast - not what the image
# converges to: partial renders differing only in these merge into one (render.py merge).
SAMPLING_ONLY = tuple(s.name for s in FIELDS if s.sampling_only)


# ---- Settings -----------------------------------------------------------------------------------
def _post_init(self):
    if self.border is None:
        object.__setattr__(self, "border", (0, 0, self.width, self.height))


def _replace(self, **kw) -> "Settings":
    return dataclasses.replace(self, **kw)


Settings = dataclasses.make_dataclass(
    "Settings", [(s.name, s.kind, dataclasses.field(default=s.default)) for s in FIELDS], frozen=True,
    namespace=dict(__module__=__name__, __post_init__=_post_init, replace=_replace, __doc__=(
        "Render settings, one field per declaration of engine/settings.py (FIELDS). border: the "
        "pixel rectangle to render, half-open, top-left origin (None: the whole frame).")))


# ---- values and checks --------------------------------------------------------------------------
def _split(condition: str) -> tuple[str, str, str]:
    for op in ("!=", "="):
        if op in condition:
            name, want = condition.split(op)
            return name.strip(), op, want.strip()
    return condition.strip(), "", ""


def holds(condition: str, get) -> bool:
    """Whether a Ui or honoured_by condition holds; get(name) -> that setting's value."""
    name, op, want = _split(condition)
    value = get(name)
    if not op:
        return bool(value)
    return (str(value).lower() == want.lower()) == (op == "=")


def honours(setting: Setting, integrator: str, get) -> bool:
    """Whether `integrator` honours `setting` given the other settings (get(name) -> value);
    engine.integrators.honours answers for `auto` too."""
    return not setting.honoured_by or any(name == integrator and (not cond or holds(cond, get))
                                          for name, cond in setting.honoured)


def number_text(value) -> str:
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return str(int(value))
    return f"{float(value):g}" if isinstance(value, numbers.Real) else repr(value)


def range_problem(value, lo=None, hi=None) -> str | None:
    """'must be at least lo (got value)' or 'at most hi', or None."""
    if lo is not None and not value >= lo:
        return f"must be at least {number_text(lo)} (got {number_text(value)})"
    if hi is not None and not value <= hi:
        return f"must be at most {number_text(hi)} (got {number_text(value)})"
    return None


def problem(setting: Setting, value, choices: tuple | None = None, blender: bool = False) -> str | None:
    """What is wrong with `value` for `setting` ("must be at least 1 (got 0)"), or None.
    choices: the enum's values where they are not declared here (the integrator's);
    blender: Blender's 32-bit limits too (a value for a bpy property)."""
    kind = setting.kind
    if kind is str:
        values = setting.values if choices is None else tuple(choices)
        if values and value not in values:
            return f"must be one of: {', '.join(values)} (got {value!r})"
        return None
    if kind not in (int, float):
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Integral if kind is int else numbers.Real):
        return f"must be a {'whole ' if kind is int else ''}number (got {value!r})"
    if kind is float and not math.isfinite(value):
        return f"must be a finite number (got {value})"
    hi = setting.max
    if blender and hi is None:
        hi = INT_MAX if kind is int else FLOAT_MAX
    return range_problem(value, setting.min, hi)


def from_text(setting: Setting, text: str):
    """A value written as text (render.py's options): on|off, a whole number, a number or a
    choice in any case -> the core's value. ValueError with what is wrong."""
    kind = setting.kind
    if kind is bool:
        if text.strip().lower() not in ("on", "off"):
            raise ValueError(f"must be on or off (got {text!r})")
        return text.strip().lower() == "on"
    try:
        return setting.core(text.strip()) if kind is str else kind(text)
    except ValueError:
        raise ValueError(f"must be a {'whole ' if kind is int else ''}number (got {text!r})") from None


def to_text(setting: Setting, value) -> str:
    """The text from_text reads back as `value`."""
    if setting.kind is bool:
        return "on" if value else "off"
    return str(value)


def range_text(setting: Setting, items: tuple = ()) -> str:
    """The range or the choices, as the README and render.py --help show them: "0..1024",
    "1.." (no maximum), "sobol, random"."""
    if setting.kind is str:
        return ", ".join(v for v, _, _ in (items or setting.items))
    if setting.kind is bool:
        return "on, off"
    if setting.min is None and setting.max is None:
        return ""
    lo = "" if setting.min is None else number_text(setting.min)
    return f"{lo}..{'' if setting.max is None else number_text(setting.max)}"
