"""Ember's render settings, stored in the .blend at `scene.ember`.

These are user-facing values only; engine/blender/export.py turns them into
engine.scene.Settings.
"""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty

from ..engine.integrators import REGISTRY

# One item per registered integrator (engine/integrators/__init__.py is the one list).
INTEGRATOR_ITEMS = [(cls.name.upper(), cls.label, cls.description) for cls in REGISTRY.values()]


PATTERN_ITEMS = [
    ('SOBOL', "Sobol-Burley", "Owen-scrambled Sobol sequence (as Cycles): lower noise per sample"),
    ('RANDOM', "Independent", "Independent random numbers per sample (for studies)"),
]


PHOTON_KERNEL_ITEMS = [
    ('UNIFORM', "Uniform", "Every photon within the radius counts the same (the seed's estimate)"),
    ('CONE', "Cone", "Jensen's cone filter: nearer photons count more (sharper caustics)"),
    ('EPANECHNIKOV', "Epanechnikov", "Smooth (1 - d^2/r^2)^2 weight, as Mitsuba and pbrt-v2"),
]

PHOTON_VIEW_ITEMS = [
    ('FULL', "Full", "The rendered image"),
    ('GLOBAL', "Global Map", "Debug: the global photon map's radiance estimate seen directly"),
    ('CAUSTIC', "Caustic Map", "Debug: the caustic map's radiance estimate alone"),
    ('POSITIONS', "Photon Positions", "Debug: where photons landed (white), caustic photons in orange"),
    ('INDIRECT', "Indirect", "Debug: final gathering alone (diffuse indirect light, no direct light or caustics)"),
]

ICACHE_WEIGHT_ITEMS = [
    ('WARD', "Ward", "Ward's weight 1 / (|p - p_i| / R_i + sqrt(1 - n.n_i)) with the accuracy threshold (the seed's)"),
    ('TABELLION', "Tabellion-Lamorlette", "1 - max(distance, normal) terms: falls to 0 at the edge (no contours)"),
]

ICACHE_GATHER_ITEMS = [
    ('PATH', "Path Tracing", "Gather rays trace paths: unbiased records, refined as the passes grow"),
    ('PHOTON', "Photon Map", "Gather rays read the global photon map (the seed's combination: smooth, "
                             "biased where photons are sparse, slower per record here)"),
]

ICACHE_VIEW_ITEMS = [
    ('FULL', "Full", "The rendered image"),
    ('RECORDS', "Records", "Debug: record positions as white dots over the dimmed indirect light"),
    ('INDIRECT', "Indirect", "Debug: the cached diffuse indirect light alone (no direct light or caustics)"),
]


class EmberSceneSettings(bpy.types.PropertyGroup):
    integrator: EnumProperty(
        name="Integrator",
        description="Method used to compute light transport",
        items=INTEGRATOR_ITEMS,
        default='AUTO',  # the analysis and the choice's reasons are in the render's stats
    )
    samples: IntProperty(
        name="Samples",
        description="Samples per pixel (full passes over the image)",
        default=64, min=1, soft_max=4096,
    )
    preview_samples: IntProperty(
        name="Viewport Samples",
        description="Samples per pixel the viewport's Rendered shading refines to",
        default=64, min=1, soft_max=4096,
    )
    max_depth: IntProperty(
        name="Max Bounces",
        description="Longest light path, in surface interactions",
        default=64, min=1, max=1024,
    )
    seed: IntProperty(
        name="Seed",
        description="Random seed; a render with the same seed and settings is reproducible",
        default=0, min=0,
    )
    time_limit: FloatProperty(
        name="Time Limit",
        description="Stop after this many seconds (0 = no limit); the last pass finishes first",
        default=0.0, min=0.0, soft_max=3600.0, subtype='TIME_ABSOLUTE', unit='TIME_ABSOLUTE',
    )
    noise_target: FloatProperty(
        name="Noise Target",
        description="Stop once the estimated relative noise (RMS over pixels of the standard "
                    "error of the mean over mean + 0.01) falls to this value (0 = off)",
        default=0.0, min=0.0, soft_max=0.1, step=0.1, precision=4,
    )
    pattern: EnumProperty(
        name="Pattern",
        description="Random number pattern used to place samples",
        items=PATTERN_ITEMS,
        default='SOBOL',
    )
    sample_offset: IntProperty(
        name="Sample Offset",
        description="Take samples [offset, offset + samples) of the sample sequence, so that renders of "
                    "disjoint ranges (on several machines) merge exactly into one (render.py merge)",
        default=0, min=0,
    )
    batch_size: IntProperty(
        name="Batch Size",
        description="Rays traced together in one wavefront; bigger is faster but uses more memory",
        default=131072, min=1024, soft_max=1 << 20,
    )
    # Photon mapping (defaults are engine.scene.Settings'; radii 0 = relative to the scene size).
    photons: IntProperty(
        name="Global Photons",
        description="Photon paths emitted for the global map (indirect light read by final gathering)",
        default=200_000, min=0, soft_max=10_000_000,
    )
    caustic_photons: IntProperty(
        name="Caustic Photons",
        description="Photon paths emitted for the caustic map (light focused by glass and mirrors "
                    "onto diffuse surfaces); skipped when the scene has no specular surface",
        default=1_000_000, min=0, soft_max=50_000_000,
    )
    photon_k: IntProperty(
        name="Photons per Estimate",
        description="Nearest photons in one radiance estimate (more: smoother, more blurred)",
        default=50, min=2, soft_max=500,
    )
    photon_kernel: EnumProperty(
        name="Kernel",
        description="Weight of a photon by its distance in a radiance estimate",
        items=PHOTON_KERNEL_ITEMS,
        default='UNIFORM',
    )
    global_radius: FloatProperty(
        name="Global Radius",
        description="Largest search radius in the global map (0 = 5 % of the scene's bounding radius)",
        default=0.0, min=0.0, subtype='DISTANCE', unit='LENGTH',
    )
    caustic_radius: FloatProperty(
        name="Caustic Radius",
        description="Largest search radius in the caustic map (0 = 1.25 % of the scene's bounding radius)",
        default=0.0, min=0.0, subtype='DISTANCE', unit='LENGTH',
    )
    gather_rays: IntProperty(
        name="Gather Rays",
        description="Final-gathering rays per camera sample at the first diffuse surface",
        default=16, min=0, soft_max=256,
    )
    radiance_photons: BoolProperty(
        name="Radiance Photons",
        description="Precompute irradiance at every 4th photon so a gather ray needs one lookup "
                    "(Christensen 1999): much faster, slightly more blurred",
        default=True,
    )
    ppm_radius: FloatProperty(
        name="Initial Radius",
        description="Progressive photon mapping: each pixel's first gathering radius "
                    "(0 = 1 % of the scene's bounding radius); it shrinks every pass",
        default=0.0, min=0.0, subtype='DISTANCE', unit='LENGTH',
    )
    ppm_alpha: FloatProperty(
        name="Alpha",
        description="Progressive photon mapping: share of each pass's photons kept as the radius "
                    "shrinks (smaller: faster shrinking, more noise)",
        default=2.0 / 3.0, min=0.01, max=0.99,
    )
    photon_view: EnumProperty(
        name="View",
        description="What the photon integrator shows",
        items=PHOTON_VIEW_ITEMS,
        default='FULL',
    )
    icache_rays: IntProperty(
        name="Rays per Record",
        description="Stratified gather rays per irradiance record (M x 2M cells)",
        default=392, min=50, max=2000,
    )
    icache_a: FloatProperty(
        name="Accuracy",
        description="Ward's accuracy a: a record is used where its estimated error is below a "
                    "(smaller: more records, more accurate; the seed recommends 0.1-0.35)",
        default=0.2, min=0.05, max=0.5,
    )
    icache_gradients: BoolProperty(
        name="Gradients",
        description="Extrapolate records by their rotational and translational irradiance gradients",
        default=True,
    )
    icache_weight: EnumProperty(
        name="Weight",
        description="How records are weighted when interpolated",
        items=ICACHE_WEIGHT_ITEMS,
        default='WARD',
    )
    icache_gather: EnumProperty(
        name="Gather",
        description="Radiance found by a record's gather rays",
        items=ICACHE_GATHER_ITEMS,
        default='PATH',
    )
    icache_view: EnumProperty(
        name="View",
        description="What the irradiance cache shows",
        items=ICACHE_VIEW_ITEMS,
        default='FULL',
    )
    icache_radiance: BoolProperty(
        name="Radiance Caching",
        description="Rough glossy surfaces also take their indirect light from the records, which then "
                    "hold the incident radiance in spherical harmonics (Krivanek et al. 2005); sharper "
                    "lobes keep final gathering",
        default=False,
    )
    icache_radiance_order: IntProperty(
        name="Harmonics Order",
        description="Spherical-harmonics order of radiance records (order^2 coefficients). It sets the "
                    "sharpest lobe cached: GGX roughness >= 0.70 / 0.65 / 0.61 / 0.58 at order 5 / 6 / 7 / 8",
        default=7, min=2, max=8,
    )
    # Light paths (path tracer). Limits count interactions like Max Bounces: Cycles' value + 1.
    diffuse_bounces: IntProperty(
        name="Diffuse",
        description="Most diffuse reflections on a path; the last one sees emitters only "
                    "(1 = direct light only: Cycles' Diffuse bounces + 1)",
        default=64, min=1, max=1024,
    )
    glossy_bounces: IntProperty(
        name="Glossy",
        description="Most glossy and mirror reflections on a path (Cycles' Glossy bounces + 1)",
        default=64, min=1, max=1024,
    )
    transmission_bounces: IntProperty(
        name="Transmission",
        description="Most refractions on a path (Cycles' Transmission bounces + 1)",
        default=64, min=1, max=1024,
    )
    transparent_bounces: IntProperty(
        name="Transparent",
        description="Most passes through transparent surfaces (as Cycles'); they do not count "
                    "toward Max Bounces",
        default=64, min=0, max=1024,
    )
    caustics_reflective: BoolProperty(
        name="Reflective Caustics",
        description="Glossy reflection seen right after a diffuse bounce (off: less noise, "
                    "no reflective caustics)",
        default=True,
    )
    caustics_refractive: BoolProperty(
        name="Refractive Caustics",
        description="Refraction seen right after a diffuse bounce (off: less noise, no "
                    "refractive caustics)",
        default=True,
    )
    clamp_direct: FloatProperty(
        name="Direct Light",
        description="Scale down direct-light samples whose mean RGB exceeds this (0 = off; "
                    "biased, as Cycles' clamping)",
        default=0.0, min=0.0, soft_max=100.0,
    )
    clamp_indirect: FloatProperty(
        name="Indirect Light",
        description="Scale down indirect-light samples whose mean RGB exceeds this (0 = off; "
                    "tames fireflies, biased, as Cycles' clamping)",
        default=0.0, min=0.0, soft_max=100.0,
    )
    filter_glossy: FloatProperty(
        name="Filter Glossy",
        description="Blur glossy reflections after rough bounces to reduce noise from caustics "
                    "(0 = off; biased, as Cycles' Filter Glossy)",
        default=0.0, min=0.0, soft_max=10.0,
    )
    # Sampling controls with Cycles' names and meaning (Render Properties > Sampling).
    use_adaptive_sampling: BoolProperty(
        name="Use Adaptive Sampling",
        description="Stop sampling each pixel once its estimated noise is below the noise threshold "
                    "(decided every 16 passes after the minimum samples; path tracing and photon mapping)",
        default=False,
    )
    adaptive_threshold: FloatProperty(
        name="Noise Threshold",
        description="Noise level at which a pixel stops; lower: less noise, longer renders "
                    "(0 = automatic from the samples, as Cycles)",
        default=0.01, min=0.0, max=1.0, soft_min=0.001, precision=4,
    )
    adaptive_min_samples: IntProperty(
        name="Min Samples",
        description="Samples every pixel gets before adaptive sampling may stop it "
                    "(0 = automatic from the noise threshold, as Cycles)",
        default=0, min=0, max=4096,
    )
    use_animated_seed: BoolProperty(
        name="Use Animated Seed",
        description="A different seed, and so a different noise pattern, on every frame",
        default=False,
    )


class EmberViewLayerSettings(bpy.types.PropertyGroup):
    """Passes Blender has no view-layer checkbox for (engine/passes.py: "ember.*")."""

    denoising_store_passes: BoolProperty(
        name="Denoising Data", default=False,
        description="Denoising Albedo and Denoising Normal passes, for the compositor's Denoise node")
    pass_sample_count: BoolProperty(name="Sample Count", default=False,
                                    description="Debug pass: samples taken in each pixel")
    pass_variance: BoolProperty(name="Variance", default=False,
                                description="Debug pass: estimated variance of each pixel's mean")
    pass_caustics: BoolProperty(name="Caustics", default=False,
                                description="The caustic photon map's estimate (photon-map integrators)")


classes = (EmberSceneSettings, EmberViewLayerSettings)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.ember = PointerProperty(type=EmberSceneSettings, name="Ember",
                                            description="Ember render settings")
    bpy.types.ViewLayer.ember = PointerProperty(type=EmberViewLayerSettings, name="Ember",
                                                description="Ember view layer settings")


def unregister():
    if hasattr(bpy.types.Scene, "ember"):
        del bpy.types.Scene.ember
    if hasattr(bpy.types.ViewLayer, "ember"):
        del bpy.types.ViewLayer.ember
    for cls in reversed(classes):
        if getattr(cls, "is_registered", False):
            bpy.utils.unregister_class(cls)
