"""The `auto` integrator's rule: from a scene's analysis (engine/choice/analysis.py) to an
integrator, its parameters and the reasons.

    no light, or controls only the path tracer honours         -> path
    caustics (L S+ D) from small or point lights                -> photon (caustic map, final gathering)
    mostly closed and diffuse, with strong indirect light:
      a hot spot of indirect light, lit by finite lights only   -> photon (its map smooths the spot)
      indirect light noisy for a path tracer at this resolution,
      or a tiny light                                           -> icache (irradiance cache)
    anything else (open scenes under a sky, glossy scenes,
      a Cornell box at 64x64)                                   -> path

Why, in short: the path tracer wins where its noise falls fast (open scenes under a sky,
mostly direct light, small images that take thousands of samples); what decides otherwise is
the noise the indirect light adds to a path sample, E[I^2] / E[L]^2 at the first diffuse hits
(the analysis pilot). A cache's advantage grows with the pixels each record serves, so that
noise is scaled by the image's width over 64 pixels before it is compared with NOISY_INDIRECT.
In a hot spot lit by finite lights, final gathering reads the spot from the photon map's
density estimate instead of finding it by chance; sun and sky photons mostly land outside a
room, so distant lights and skies keep the cache. `photon` (not `path_caustic`) is the choice
for caustics because it holds at short and long budgets alike. Every threshold below sits
about a factor of 2 from the nearest bench scene on either side; the measurements that set
them are in bench/results/auto/thresholds.md.
A setting the user changed from its default is never overridden; an integrator chosen by
name is not analysed at all.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..scene import Settings
from .analysis import SceneAnalysis

CAUSTIC_SHARE = 0.01  # caustic light at diffuse surfaces worth a caustic map (pilot's share)
SMALL_LIGHTS = ("delta", "tiny", "small")  # lights whose caustics a path tracer finds rarely or never
SMALL_POWER = 0.5  # ... carrying at least this share of the light power
DIFFUSE_SHARE = 0.9  # of the surface area (albedo-weighted): the irradiance cache's domain
INDIRECT_HEAVY = 0.5  # indirect / direct light at the first diffuse hits
MOSTLY_CLOSED = 0.5  # share of escaping probe rays below which interreflection matters
FEW_GATHER_RAYS, FEW_GATHER_BELOW = 4, 0.5  # photon: gather rays where indirect / direct is below
GATHER_RAYS = 8  # photon: gather rays elsewhere
NOISY_INDIRECT = 2.0  # E[I^2] / E[L]^2 x (image width / 64) from which a cache beats path tracing
HOT_SPOT = 8.0  # E[I^2] / E[L]^2 from which photon mapping beats the irradiance cache
SKY_LIGHTS = ("sun", "environment", "constant")  # light kinds whose photons a room's window wastes
SMALL_IMAGE, SMALL_IMAGE_PHOTONS = 128 * 128, 500_000  # photon: global photons in small images


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
    pixels = s.width * s.height
    if a.caustics_possible and a.caustic_share >= CAUSTIC_SHARE and small >= SMALL_POWER:
        reasons = (f"caustics: {_pct(a.caustic_share)} of the light at diffuse surfaces comes through specular "
                   f"surfaces (L S+ D), {_pct(small)} of the power from small or point lights, which a path "
                   "tracer finds rarely or never",)
        params = {"gather_rays": _gather_rays(a)}
        if a.indirect_ratio >= INDIRECT_HEAVY and pixels <= SMALL_IMAGE:
            params["photons"] = (SMALL_IMAGE_PHOTONS, f"{SMALL_IMAGE_PHOTONS // 1000}k global photons: strong "
                                 f"indirect light in a small image ({s.width}x{s.height}), where the map's bias "
                                 "shows before its noise")
        return _chosen("photon", params, reasons, s)
    closed = a.escape_share < MOSTLY_CLOSED
    if closed and a.diffuse_share >= DIFFUSE_SHARE and a.indirect_ratio >= INDIRECT_HEAVY:
        where = (f"{'enclosed' if a.enclosed else 'mostly closed'} ({_pct(a.escape_share)} of probe rays escape), "
                 f"diffuse ({_pct(a.diffuse_share)} of the area), indirect light {a.indirect_ratio:.2f}x direct")
        sky = [k for k in a.light_kinds if k in SKY_LIGHTS]
        if a.indirect_noise >= HOT_SPOT and not sky:
            reasons = (f"{where}, in a hot spot (its noise in a path sample {a.indirect_noise:.1f} >= {HOT_SPOT:g}) "
                       "lit by finite lights: photon mapping",)
            return _chosen("photon", {"gather_rays": _gather_rays(a)}, reasons, s)
        noise = a.indirect_noise * s.width / 64
        tiny = sum(p for c, p in a.light_power if c == "tiny")
        if noise >= NOISY_INDIRECT or tiny >= SMALL_POWER:
            why = (f"{_pct(tiny)} of the power from tiny lights" if noise < NOISY_INDIRECT else
                   f"its noise in a path sample {a.indirect_noise:.2f}, {noise:.1f} at {s.width} pixels wide "
                   f"(>= {NOISY_INDIRECT:g})")
            params = {}
            if not a.caustics_possible or a.caustic_share == 0:
                params["caustic_photons"] = (0, "no caustic map: " + _no_caustics(a))
            return _chosen("icache", params, (f"{where}, {why}: irradiance cache",), s)
        return Choice("path", {}, (f"{where}, but its noise in a path sample is low ({a.indirect_noise:.2f}, "
                                   f"{noise:.1f} at {s.width} pixels wide, < {NOISY_INDIRECT:g}): path tracing",), ())
    return Choice("path", {}, (_why_path(a),), ())


def _gather_rays(a: SceneAnalysis) -> tuple:
    if a.indirect_ratio < FEW_GATHER_BELOW:
        return FEW_GATHER_RAYS, f"{FEW_GATHER_RAYS} gather rays: indirect light is {_pct(a.indirect_ratio)} of direct"
    return GATHER_RAYS, f"{GATHER_RAYS} gather rays: more camera samples, fewer rays each"


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
    default = Settings()
    mine = {k: v for k, v in params.items() if getattr(settings, k) == getattr(default, k)}
    notes = tuple(note for _, note in mine.values()) + tuple(
        f"{k.replace('_', ' ')}: the user's {getattr(settings, k)}" for k in params if k not in mine)
    return Choice(integrator, {k: v for k, (v, _) in mine.items()}, reasons, notes)
