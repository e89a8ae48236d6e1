"""Bake settings stored on each scene as ``scene.smbs_caustics``.

Property names match the fields of ``smbs_addon.bake.BakeSettings`` wherever the
core has the same setting; the operator copies them across by name.
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

METHOD_ITEMS = (
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

CYCLES_FLAGS_ITEMS = (
    ("AUTO", "Auto",
     "Use the Cycles shadow-caustics flags (caster, receiver, light) if the scene sets "
     "any of them; otherwise every specular object casts, every diffuse one receives "
     "and every light takes part"),
    ("ON", "On",
     "Only objects marked Cast or Receive Shadow Caustics and lights marked Shadow "
     "Caustics take part, as in Cycles"),
    ("OFF", "Off",
     "Ignore the Cycles flags: every specular object casts, every diffuse one receives "
     "and every light takes part"),
)


class SMBSCausticsSettings(bpy.types.PropertyGroup):
    """Settings for baking the caustic layer of one scene."""

    method: EnumProperty(
        name="Method", items=METHOD_ITEMS, default="smbs",
        description="How the caustic light paths are found",
    )
    estimator: EnumProperty(
        name="Estimator", items=ESTIMATOR_ITEMS, default="unbiased",
        description="How the solutions of SMS and SMBS are weighted",
    )
    trials: IntProperty(
        name="Trials", default=32, min=1, soft_max=1000, max=1_000_000,
        description="Biased: seeds tried per light sample. Unbiased: the most "
                    "Bernoulli trials spent on one inverse-probability estimate",
    )
    spp: IntProperty(
        name="Samples", default=16, min=1, soft_max=1024, max=1_000_000,
        description="Samples per pixel",
    )
    seed: IntProperty(
        name="Seed", default=0, min=0,
        description="Random seed; the same seed and settings give the same image",
    )
    time_budget: FloatProperty(
        name="Time Limit", default=0.0, min=0.0, soft_max=3600.0,
        unit='TIME_ABSOLUTE', subtype='TIME_ABSOLUTE',
        description="Stop after this many seconds, keeping the samples finished so "
                    "far (0 = no limit)",
    )
    output_path: StringProperty(
        name="Output", default="//caustics.exr", subtype='FILE_PATH',
        description="Where the caustic layer is written as an OpenEXR file "
                    "(// means relative to the blend file)",
    )
    use_cycles_flags: EnumProperty(
        name="Cycles Flags", items=CYCLES_FLAGS_ITEMS, default="AUTO",
        description="Whether the Cycles shadow-caustics flags choose which objects "
                    "and lights take part",
    )

    # Advanced solver parameters.
    max_iterations: IntProperty(
        name="Max Iterations", default=20, min=1, soft_max=200, max=10_000,
        description="Newton steps (small and large mutations) before a walk gives up",
    )
    solver_threshold: FloatProperty(
        name="Threshold", default=1e-5, min=1e-12, soft_min=1e-8, max=1e-1,
        precision=6, step=0.001,
        description="A walk has converged when its distance to the light sample is "
                    "below this fraction of the path length",
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

    # Written by the bake operator, shown by the statistics panel.
    last_stats: StringProperty(
        name="Last Bake Statistics", default="",
        description="Statistics of the last bake, as JSON",
    )


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
