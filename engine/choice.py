"""The `auto` integrator's rule: from a scene's analysis (engine/analysis.py) to an integrator,
its parameters and the reasons (issue 11).

    no light, or controls only the path tracer honours      -> path
    caustics (L S+ D) from small or point lights             -> photon (caustic map, final gathering)
    mostly closed, diffuse, strong indirect light            -> icache (irradiance cache)
    anything else (open scenes under a sky, glossy scenes)   -> path

Measured on the bench scenes at 64x64 (README "Automatic choice"): the path tracer wins where
its noise falls fast - open scenes under a sky (hdri: 6-17x less error than the cache at 8 and
30 s), mostly direct light - and loses where light arrives along paths it samples badly (the
caustic of a small or point light: 15x the photon map's error at 8 s) or where diffuse
interreflection dominates: with records refined between pass blocks and path-traced gathers
the irradiance cache beat it on the interior (4.5x at 8 s), on the Cornell box, open at the
front (28 % of probe rays escape; 1.2x at 8 s, 1.1x at 30 s in one run, but the bench run
after it had the path tracer ahead, 1.35x and 2.8x: not settled), and on its hard variants (a
light 5 mm from a wall: 5x at both budgets; a 1 cm light: 70x and 47x).
For caustics, path tracing with a caustic map (`path_caustic`) beat `photon` at 30 s (caustic
7.2e-3 against 1.0e-2, caustic_point 5.3e-3 against 5.7e-3, at a load of 9) but lost 4-7x at
8 s on caustic_point (2.7e-2 - 4.3e-2 against 6.1e-3: a path tracer's early noise against
final gathering's smooth estimate), so `photon` is the choice that holds at both budgets.
Its 4 gather rays where indirect light is weak: the caustic scene's error fell 3.4x at 8 s
and 1.4x at 30 s against 16 (bench/results/photon/notes.md, "tuned_photon_4_gather").
A setting the user changed from its default is never overridden; an integrator chosen by
name is not analysed at all.
"""
from __future__ import annotations

from dataclasses import dataclass

from .analysis import SceneAnalysis

CAUSTIC_SHARE = 0.01  # caustic light at diffuse surfaces worth a caustic map (pilot's share)
SMALL_LIGHTS = ("delta", "tiny", "small")  # lights whose caustics a path tracer finds rarely or never
SMALL_POWER = 0.5  # ... carrying at least this share of the light power
DIFFUSE_SHARE = 0.9  # of the surface area (albedo-weighted): the irradiance cache's domain
INDIRECT_HEAVY = 0.5  # indirect / direct light at the first diffuse hits
MOSTLY_CLOSED = 0.5  # share of escaping probe rays below which interreflection matters
FEW_GATHER_RAYS, FEW_GATHER_BELOW = 4, 0.5  # photon: gather rays where indirect / direct is below


@dataclass(frozen=True)
class Choice:
    integrator: str
    settings: dict  # Settings fields auto sets (only ones the user left at their defaults)
    reasons: tuple  # why this integrator
    notes: tuple  # parameters chosen and stages left out, each with its reason

    def text(self) -> str:
        return f"auto chose '{self.integrator}': " + "; ".join(self.reasons)


def _pct(x) -> str:
    return f"{100 * x:.0f} %"


def choose(a: SceneAnalysis, settings, path_only: tuple = ()) -> Choice:
    """The integrator for a scene with analysis `a` and Settings `settings`; path_only: the
    features the scene uses that only the path tracer honours (light passes, ray visibility,
    per-kind bounce limits, clamping, a noise target, ...), each a short phrase."""
    s = settings
    if not a.has_light:
        return Choice("path", {}, ("no light: nothing to cache or map",), ())
    if path_only:
        return Choice("path", {}, ("uses what only the path tracer honours: " + ", ".join(path_only),), ())
    small = sum(p for c, p in a.light_power if c in SMALL_LIGHTS)
    if a.caustics_possible and a.caustic_share >= CAUSTIC_SHARE and small >= SMALL_POWER:
        reasons = (f"caustics: {_pct(a.caustic_share)} of the light at diffuse surfaces comes through specular "
                   f"surfaces (L S+ D), {_pct(small)} of the power from small or point lights, which a path "
                   "tracer finds rarely or never",)
        params = {}
        if a.indirect_ratio < FEW_GATHER_BELOW:
            params["gather_rays"] = (FEW_GATHER_RAYS, f"{FEW_GATHER_RAYS} gather rays: indirect light is "
                                                      f"{_pct(a.indirect_ratio)} of direct")
        return _chosen("photon", params, reasons, s)
    closed = a.escape_share < MOSTLY_CLOSED
    if closed and a.diffuse_share >= DIFFUSE_SHARE and a.indirect_ratio >= INDIRECT_HEAVY:
        reasons = (f"{'enclosed' if a.enclosed else 'mostly closed'} ({_pct(a.escape_share)} of probe rays escape), "
                   f"diffuse ({_pct(a.diffuse_share)} of the area), indirect light {a.indirect_ratio:.2f}x direct: "
                   "irradiance cache",)
        params = {}
        if not a.caustics_possible or a.caustic_share == 0:
            params["caustic_photons"] = (0, "no caustic map: " + _no_caustics(a))
        return _chosen("icache", params, reasons, s)
    return Choice("path", {}, (_why_path(a),), ())


def _no_caustics(a: SceneAnalysis) -> str:
    if not a.caustics_possible:
        return "no specular surface"
    return "no specular surface carries light to a diffuse one (photon pilot)"


def _why_path(a: SceneAnalysis) -> str:
    if a.caustics_possible and a.caustic_share >= CAUSTIC_SHARE:
        return f"caustics ({_pct(a.caustic_share)} of the light) from large lights: path tracing finds them"
    why = []
    if not a.escape_share < MOSTLY_CLOSED:
        sky = [k for k in a.light_kinds if k in ("environment", "constant", "sun")]
        why.append(f"open ({_pct(a.escape_share)} of probe rays escape" + (f", lit by {'/'.join(sky)})" if sky else ")"))
    if a.diffuse_share < DIFFUSE_SHARE:
        why.append(f"glossy/specular ({_pct(1 - a.diffuse_share)} of the area)")
    if a.indirect_ratio < INDIRECT_HEAVY:  # NaN: no diffuse surface seen (said above)
        why.append(f"mostly direct light (indirect {a.indirect_ratio:.2f}x direct)")
    return (", ".join(why) or "nothing to cache or map") + ": path tracing"


def _chosen(integrator: str, params: dict, reasons: tuple, settings) -> Choice:
    """The Choice with params {field: (value, note)}, except the fields the user set (a value
    other than the default): those keep the user's value."""
    from .scene import Settings

    default = Settings()
    mine = {k: v for k, v in params.items() if getattr(settings, k) == getattr(default, k)}
    notes = tuple(note for _, note in mine.values()) + tuple(
        f"{k.replace('_', ' ')}: the user's {getattr(settings, k)}" for k in params if k not in mine)
    return Choice(integrator, {k: v for k, (v, _) in mine.items()}, reasons, notes)
