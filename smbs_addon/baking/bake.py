"""The bake: plan the scene, run the caustic passes per light, gather statistics.

Data flows one way: Scene -> plan -> (auto's choice per light) -> passes per batch (chunks of
lanes) -> film -> image + error bar + statistics. Randomness is keyed by (seed, stream, light,
batch, chunk) (core/random.py), so one seed gives the same image bit for bit, whatever the thread
count.
"""
from __future__ import annotations

import time

from ..core import lanes
from ..core.compiles import CompileWatch
from ..trace.camera import CameraModel
from . import auto, engine
from .plan import make_plan
from .result import BakeResult
from .settings import BakeSettings


def bake(scene, settings: BakeSettings | None = None, progress=None, cancel=None, on_plan=None,
         keep_partial: bool = False) -> BakeResult:
    """Bake the caustic layer of a Scene.

    progress(fraction, message) is called between chunks; cancel() returning
    True stops the bake with BakeCancelled (nothing is returned or written);
    on_plan(lines) gets the plan in words before any caustic is traced. A scene
    with nothing to bake gives an all-zero layer, stats["nothing_to_bake"] says why.
    A signal (core/signals.py) stops it as cancel() does; with keep_partial, a bake by a time
    or noise rule that a signal stops after a batch or more returns the batches done instead
    (stats["stopped_by"] "signal", stats["signal"] its name).

    The first bake after installing or updating compiles the kernels it uses (compiles.py):
    progress says so while it does, stats["compile_s"] is the time it took (in time_s, not in
    the price of more batches: later bakes load the kernels from the disk cache)."""
    report = _Reporter(progress)
    with CompileWatch(on_start=report.compiling, on_end=report.compiled) as watch:
        try:
            result = _bake(scene, settings, report, cancel, on_plan, watch, keep_partial)
        finally:
            lanes.free_scratch()  # the work arrays the threads kept (lanes.scratch)
    result.stats["compile_s"] = watch.seconds
    result.stats["kernels_compiled"] = watch.kernels
    return result


def _bake(scene, settings, report, cancel, on_plan, watch, keep_partial=False) -> BakeResult:
    job = engine.start(scene, settings, report, cancel, on_plan, watch, keep_partial)
    if isinstance(job, BakeResult):
        return job
    if job.settings.method != "auto":
        return engine.run(job, job.settings.method == "reference")
    light_tracing, choices = _choose(job, on_plan)
    return engine.run(job, light_tracing, choices)


def _choose(job, on_plan) -> tuple[bool, dict]:
    """auto: a pilot per light (auto.py) chooses who bakes what; the plan's words say so. Returns
    (light tracing alone?, {light index: auto.Choice})."""
    settings, plan, scene = job.settings, job.plan, job.scene
    t_a = time.perf_counter()
    choices = {}
    if auto.pilot_fits(settings.time_budget, len(plan.lights)):
        choices = auto.choose(scene, settings, plan, job.cancel, job.watch)
        why = {lp.name: choices[lp.index].why for lp in plan.lights}
    else:
        why = {lp.name: f"SMBS (a {settings.time_budget:g} s budget leaves no time for the pilot, which "
                        f"needs {auto.PILOT_MIN_BUDGET_PER_LIGHT:g} s per light)" for lp in plan.lights}
    # light tracing alone where it wins everywhere and no caustic is seen through mirrors or glass
    alone = bool(choices) and all(c.alone or (c.photons_direct and not c.through) for c in choices.values())
    job.extra["auto"] = {
        "time_s": time.perf_counter() - t_a, "bake": "reference" if alone else "manifold", "pilot": bool(choices),
        "rays": sum(c.rays for c in choices.values()),
        "lights": {scene.light_names[li]: {"walks": c.walk, "direct": "photons" if c.photons_direct else c.walk,
                                           "photon_factor": c.photon_factor, "why": c.why, "pilot": c.measured,
                                           "anchor_only": c.anchor_only, "anchor_bound": c.anchor_bound}
                   for li, c in choices.items()}}
    for li, c in choices.items():
        if c.anchor_only:
            job.light_stats[scene.light_names[li]]["anchor_only_bound"] = c.anchor_bound
    for lp in plan.lights:
        plan.notes.append(f"auto, {lp.name}: {why[lp.name]}")
    if on_plan is not None:
        on_plan([f"auto, {lp.name}: {why[lp.name]}" for lp in plan.lights])
    return alone, choices


def plan_words(scene, settings: BakeSettings | None = None) -> list:
    """The plan of a bake in words, without baking (the panel's Show Plan)."""
    settings = settings or BakeSettings()
    settings.validate()
    scene.validate()
    plan = make_plan(scene, settings.use_cycles_flags)
    if not plan.nothing:
        engine.trace_plan(plan, scene, settings, CameraModel(scene.camera))
    return plan.words()


class _Reporter:
    """The caller's progress(fraction, message), remembering the last call, so that a compile
    (the first bake after installing or updating) can say so and then give the message back."""

    COMPILING = ("compiling the kernels for this machine (once after installing or updating; "
                 "later bakes load them from the cache)")

    def __init__(self, progress):
        self.progress = progress
        self.last = (0.0, "")

    def __call__(self, fraction, message=""):
        self.last = (fraction, message or self.last[1])
        if self.progress is not None:
            self.progress(fraction, message)

    def compiling(self):
        if self.progress is not None:
            self.progress(self.last[0], self.COMPILING)

    def compiled(self):
        if self.progress is not None:
            self.progress(*self.last)
