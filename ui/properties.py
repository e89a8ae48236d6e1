"""Bake settings stored on each scene as ``scene.smbs_caustics``.

The properties named in ``BAKE_FIELDS`` are the fields of
``smbs_addon.baking.bake.BakeSettings`` with the same names and the same defaults; the
operator copies them across by name. The rest are the layer's file, the
Cycles policy and what the last bake left behind for the panels.
"""
import bpy
from bpy.props import (
    BoolProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

# Blender 4.5+ warns when a path property without this option is set to a // path; older ones lack it
_RELATIVE_PATH = ({'ANIMATABLE', 'PATH_SUPPORTS_BLEND_RELATIVE'}
                  if "is_path_supports_blend_relative" in bpy.types.Property.bl_rna.properties else {'ANIMATABLE'})

# Properties passed to BakeSettings by name (each must be a BakeSettings field).
BAKE_FIELDS = (
    "method", "estimator", "trials", "max_trials", "spp", "seed", "batches", "threads",
    "time_budget", "noise_target", "use_cycles_flags", "radiance", "guide", "max_iterations", "first_step",
    "stall_stop", "anchor", "solver_threshold",
    "uniqueness", "tau", "large_mutation_tir", "large_mutation_backlit", "large_mutation_slow",
    "max_chain", "clamp_g", "handoff", "indirect", "pilots", "seeding", "sampling", "world_split",
)

METHOD_ITEMS = (
    ("auto", "Auto",
     "Per light, a short pilot measures light tracing, SMS and SMBS, and each effect (receivers "
     "seen directly; seen through mirrors and glass) gets the cheapest for its noise"),
    ("reference", "Reference",
     "Brute-force light tracing. Slow but unbiased; use it to check the other methods"),
    ("mnee", "MNEE",
     "Manifold next event estimation: one Newton walk per light sample, seeded on the "
     "straight line to the light, as in Cycles' shadow caustics (fast, biased)"),
    ("sms", "SMS",
     "Specular manifold sampling: Newton walks from random seeds on the caster"),
    ("smbs", "SMBS",
     "Specular manifold bisection sampling: SMS plus large mutations where the Newton "
     "walk stalls (total internal reflection, back-lit vertices, slow progress)"),
)

ESTIMATOR_ITEMS = (
    ("unbiased", "Unbiased",
     "Repeat the seed sampling until the same solution turns up again; the count "
     "estimates the solution's inverse probability"),
    ("biased", "Biased",
     "Sum the distinct solutions found in a fixed number of trials. Less noise, "
     "but solutions that are hard to find are missed"),
)

STOP_ITEMS = (
    ("SAMPLES", "Samples", "Bake Samples per pixel, in Batches batches"),
    ("TIME", "Time", "Bake for Time Limit seconds, one sample per pixel per batch"),
    ("NOISE", "Noise", "Bake until the relative error is at or below Noise Target"),
)

CYCLES_FLAGS_ITEMS = (
    ("AUTO", "Auto",
     "Use the Cycles shadow-caustics flags of a kind (casters, receivers, lights) as soon "
     "as one object of that kind is flagged; otherwise every specular object casts, every "
     "diffuse one receives and every light takes part"),
    ("ON", "On",
     "Only objects marked Cast or Receive Shadow Caustics and lights marked Shadow "
     "Caustics take part, as in Cycles"),
    ("OFF", "Off",
     "Ignore the Cycles flags: every specular object casts, every diffuse one receives "
     "and every light takes part"),
)


RADIANCE_ITEMS = (
    ("cycles", "Like Cycles",
     "Radiance keeps its value through refractions, as in Cycles (the layer then adds up "
     "with Cycles' render)"),
    ("physical", "Physical",
     "Radiance scales with the square of the ratio of the indices of refraction at each refraction"),
)


# Compare Methods' toggles, in the order its table lists them.
COMPARE_ITEMS = (
    ("reference", "Light Tracing", "Brute-force light tracing (the Reference method)"),
    ("mnee", "MNEE", "Manifold next event estimation (biased: its error bar leaves the bias out)"),
    ("sms", "SMS", "Specular manifold sampling"),
    ("smbs", "SMBS", "Specular manifold bisection sampling"),
    ("auto", "Auto", "A short pilot picks a method per light and effect"),
)


class SMBSCausticsSettings(bpy.types.PropertyGroup):
    """Settings for baking the caustic layer of one scene."""

    method: EnumProperty(
        name="Method", items=METHOD_ITEMS, default="auto",
        description="How the caustic light paths are found",
    )
    estimator: EnumProperty(
        name="Estimator", items=ESTIMATOR_ITEMS, default="unbiased",
        description="How the solutions of SMS and SMBS are weighted",
    )
    trials: IntProperty(
        name="Trials", default=4, min=1, soft_max=256, max=1_000_000,
        description="Biased estimator: Newton walks per receiver point, light and chain type",
    )
    max_trials: IntProperty(
        name="Max Trials", default=10000, min=1, soft_max=100_000, max=100_000_000,
        description="Unbiased estimator: most Bernoulli trials spent on one inverse-probability "
                    "estimate (a lane that reaches it counts as zero)",
    )
    spp: IntProperty(
        name="Samples", default=16, min=1, soft_max=1024, max=1_000_000,
        description="Samples per pixel (reference: light paths per pixel and light). With a "
                    "time limit, each batch takes Samples / Batches",
    )
    seed: IntProperty(
        name="Seed", default=0, min=0,
        description="Random seed; the same seed and settings give the same image",
    )
    batches: IntProperty(
        name="Batches", default=8, min=1, soft_max=64, max=10_000,
        description="Independent batches; their spread gives the noise estimate",
    )
    threads: IntProperty(
        name="Threads", default=0, min=0, soft_max=64, max=1024,
        description="Worker threads for ray tracing (0: all cores). The image does not depend on it",
    )
    stop_rule: EnumProperty(
        name="Stop By", items=STOP_ITEMS, default="SAMPLES",
        description="What ends the bake: a number of samples, a time, or a noise level",
    )
    time_budget: FloatProperty(
        name="Time Limit", default=0.0, min=0.0, soft_max=3600.0,
        unit='TIME_ABSOLUTE', subtype='TIME_ABSOLUTE',
        description="Stop By Time: bake (plan, pre-pass and walks) for this many seconds, refining "
                    "the image in passes. Stop By Noise: give up after this long (0 = no limit)",
    )
    noise_target: FloatProperty(
        name="Noise Target", default=0.05, min=0.001, soft_max=0.5, max=10.0, subtype='FACTOR',
        description="Stop By Noise: bake until the estimated relative error of the layer (RMS over "
                    "its caustic pixels, from the spread of the batches) is at or below this",
    )
    use_cycles_flags: EnumProperty(
        name="Cycles Flags", items=CYCLES_FLAGS_ITEMS, default="AUTO",
        description="Whether the Cycles shadow-caustics flags choose which objects "
                    "and lights take part",
    )
    radiance: EnumProperty(
        name="Radiance", items=RADIANCE_ITEMS, default="cycles",
        description="How radiance changes when light refracts",
    )
    guide: BoolProperty(
        name="Photon Guide", default=True,
        description="A photon pre-pass finds where caustics land; walks elsewhere are "
                    "thinned out by Russian roulette (unbiased)",
    )
    indirect: BoolProperty(
        name="Indirect Caustics", default=True,
        description="Also bake caustics that reach the camera through further diffuse "
                    "bounces (light focused on the floor, bounced onto a wall), as Cycles' "
                    "caustics on/off difference includes them",
    )
    output_path: StringProperty(
        name="Output", default="//caustics.exr", subtype='FILE_PATH', options=_RELATIVE_PATH,
        description="Where the caustic layer is written as an OpenEXR file, with the bake's "
                    "statistics beside it as JSON (// means relative to the blend file)",
    )
    frame_range: EnumProperty(
        name="Frames", default='SCENE',
        items=(('SCENE', "Scene Range", "The scene's frame range (Output Properties > Frame Range), with its step"),
               ('CUSTOM', "Custom", "The frames from Start to End")),
        description="Which frames Bake Frame Range bakes",
    )
    range_start: IntProperty(name="Start", default=1, description="Bake Frame Range: the first frame (Custom)")
    range_end: IntProperty(name="End", default=250, description="Bake Frame Range: the last frame (Custom)")
    seeding: EnumProperty(
        name="Noise", default="fixed",
        items=(("fixed", "Fixed", "The same random numbers every frame: what moves little keeps its noise, so "
                "frames flicker less (bench/results/flicker.md)"),
               ("frame", "Per Frame", "Random numbers keyed by the frame as well: each frame's noise is "
                "independent of the others'")),
        description="The random numbers from frame to frame (a still's image does not depend on it with Fixed)",
    )
    keep_out_of_cycles: BoolProperty(
        name="Keep Out of Cycles", default=True,
        description="When the layer covers every caster, receiver and light, turn off "
                    "Cycles' own caustics (Light Paths > Caustics) so that nothing is counted "
                    "twice. Remove Caustic Layer turns them back on",
    )

    # Advanced solver parameters.
    max_iterations: IntProperty(
        name="Max Iterations", default=20, min=1, soft_max=200, max=10_000,
        description="Newton steps (small and large mutations) before a walk gives up",
    )
    first_step: FloatProperty(
        name="First Step", default=0.125, min=1e-3, max=1.0, subtype='FACTOR',
        description="Unbiased SMS and SMBS: the share of the full Newton step a walk's first step "
                    "takes (doubled while steps succeed). 1: the walk as published. MNEE and the "
                    "biased estimator always take 1",
    )
    stall_stop: BoolProperty(
        name="Stop Stalled Walks", default=True,
        description="Unbiased SMS and SMBS: a walk that cannot make large mutations gives up when "
                    "four steps in a row shrank its distance to the light by less than 10%; the "
                    "estimate stays unbiased. MNEE and the biased estimator never give up early",
    )
    sampling: EnumProperty(
        name="Sampling", default="stratified",
        items=(("stratified", "Stratified", "Each pixel's positions and light samples over the whole bake "
                "spread evenly (a scrambled Sobol' sequence per pixel): less noise for the same samples"),
               ("independent", "Independent", "Each sample's position and light sample drawn independently")),
        description="How the manifold walks' eye samples and their light samples are drawn (unbiased either way)",
    )
    world_split: BoolProperty(
        name="Split the World's Map", default=True,
        description="A world map with a sun's disc in a dimmer sky: the walks take the disc, path tracing from "
                    "the receivers the sky (the sky's light through water is rare and bright for a walk, easy "
                    "for a bounce). Unbiased either way; off: the walks take the whole map",
    )
    anchor: BoolProperty(
        name="Anchor Walk", default=True,
        description="Unbiased SMS and SMBS, one refraction (water, a window) under a sun or the world: "
                    "each sample also walks once from the straight line to the light and counts that "
                    "solution with weight 1; the random walks count only the others. Unbiased; fewer "
                    "Bernoulli trials where the solution is unique",
    )
    solver_threshold: FloatProperty(
        name="Threshold", default=1e-6, min=1e-12, soft_min=1e-9, max=1e-5,
        precision=7, step=0.0001,
        description="A walk has converged when its direction towards the light sample is "
                    "off by less than this angle (radians)",
    )
    uniqueness: FloatProperty(
        name="Uniqueness", default=1e-7, min=1e-10, soft_min=1e-10, max=1e-1,
        precision=8, step=0.0001,
        description="Two solutions are the same when their directions differ by less than this",
    )
    tau: FloatProperty(
        name="Tau", default=0.85, min=0.01, max=0.999, subtype='FACTOR',
        description="Slow progress: a large mutation follows a small one that shrank "
                    "the distance to the light by less than this factor",
    )
    large_mutation_tir: BoolProperty(
        name="Total Internal Reflection", default=True,
        description="Make a large mutation when propagation hits total internal reflection",
    )
    large_mutation_backlit: BoolProperty(
        name="Back-Lit", default=True,
        description="Make a large mutation when the light is on the wrong side of the "
                    "first specular vertex",
    )
    large_mutation_slow: BoolProperty(
        name="Slow Progress", default=True,
        description="Make a large mutation when a small one made too little progress (see Tau)",
    )
    max_chain: IntProperty(
        name="Max Chain", default=4, min=1, max=16,
        description="Most specular interactions (reflections and refractions) on one "
                    "caustic path",
    )
    clamp_g: FloatProperty(
        name="Clamp", default=0.0, min=0.0, soft_max=100.0,
        description="Largest luminance one manifold solution may add (0: no clamp). Clamping "
                    "tames the spikes at caustic folds but loses energy; the statistics show "
                    "how much",
    )

    handoff: FloatProperty(
        name="Photon Hand-off", default=4.0, min=0.0, soft_max=64.0,
        description="Caustic paths that focus light more than this many times (foci, the "
                    "bright folds) are traced from the light instead of walked, which is much "
                    "faster and less noisy there; the result stays unbiased. 0: walks only",
    )
    pilots: IntProperty(
        name="Plan Pilots", default=4096, min=0, soft_max=65536, max=10_000_000,
        description="Pilot photons per light and caster that find where its caustic lands before "
                    "baking; casters whose caustic the camera cannot see are skipped. 0: plan by "
                    "bounds only (bake every caster a light reaches)",
    )

    # Compare Methods (operators/compare.py).
    compare_methods: EnumProperty(
        name="Methods", items=COMPARE_ITEMS, options={'ENUM_FLAG'}, default={"reference", "sms", "smbs"},
        description="The methods Compare Methods bakes, each for the same time",
    )
    compare_seconds: FloatProperty(
        name="Seconds Each", default=10.0, min=1.0, soft_max=600.0, max=86400.0,
        unit='TIME_ABSOLUTE', subtype='TIME_ABSOLUTE',
        description="Compare Methods: how long each method bakes (plan, pre-pass and its samples); "
                    "the other settings are the bake's, one sample per pixel per batch",
    )
    compare_report: StringProperty(
        name="Comparison", default="", options={'HIDDEN'},
        description="The last Compare Methods' table, as JSON",
    )

    # The participants list (UI only).
    participant_index: IntProperty(name="Active Participant", default=0, min=0, options={'HIDDEN'})

    # Written by the bake operator, shown by the panels.
    last_stats: StringProperty(
        name="Last Bake Statistics", default="", options={'HIDDEN'},
        description="Statistics of the last bake, as JSON",
    )
    plan_text: StringProperty(
        name="Plan", default="",
        description="What the bake will trace (Show Plan), one line each: light -> caster (chains) -> "
                    "receivers, and what it skips and why",
    )
    cycles_note: StringProperty(
        name="Cycles Note", default="", options={'HIDDEN'},
        description="What the last bake left to Cycles and what it turned off, one line each",
    )
    bake_warnings: StringProperty(
        name="Bake Warnings", default="", options={'HIDDEN'},
        description="The last bake's warnings (what it could not read or had to approximate), one per line",
    )
    # Cycles' own caustic switches as they were before a bake turned them off.
    cycles_kept_out: BoolProperty(name="Cycles Caustics Turned Off", default=False, options={'HIDDEN'})
    saved_caustics_reflective: BoolProperty(default=True, options={'HIDDEN'})
    saved_caustics_refractive: BoolProperty(default=True, options={'HIDDEN'})


classes = (SMBSCausticsSettings,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.smbs_caustics = PointerProperty(type=SMBSCausticsSettings)


def unregister():
    if hasattr(bpy.types.Scene, "smbs_caustics"):
        del bpy.types.Scene.smbs_caustics
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
