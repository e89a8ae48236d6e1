"""One bake of a pipeline, start to finish: validate, plan, trace the plan, make the film, run the
light tracer's or the walks' batches until the stop rule says enough, and turn the film into a
BakeResult. bake.py runs it for the user (auto's choice first); auto's pilot runs it for each
candidate method.
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from ..core.errors import SceneError
from ..paths.gather import bending_lights, bent_candidates
from ..scene.light_paths import Limits
from ..shading.world_parts import split_world
from ..trace.camera import CameraModel
from ..trace.film import Film
from ..trace.tracer import Tracer
from .job import Job, MEMORY_BUDGET
from .light_tracing import bake_light_tracing
from .plan import make_plan, refine_plan
from .result import BakeResult, finish, nothing_to_bake
from .settings import BakeSettings
from .walking import bake_walks


def start(scene, settings, report, cancel, on_plan, watch, keep_partial=False, left_out=None) -> Job | BakeResult:
    """Validate, plan, trace the plan and make the film: the job, or the all-zero result of a scene
    with nothing to bake. on_plan(lines) gets the plan in words before any caustic is traced;
    keep_partial: see Job. left_out: (O,) bool, casters left out before planning (make_plan)."""
    settings = settings or BakeSettings()
    settings.validate()
    scene.validate()
    t0 = time.perf_counter()
    plan = make_plan(scene, settings.use_cycles_flags, left_out)
    cam = CameraModel(scene.camera)
    check_memory(scene, cam.W, cam.H, settings.batches, settings.replicates())
    check_samples(scene, settings)
    if plan.nothing:
        return nothing_to_bake(scene, settings, plan, cam, t0, on_plan)
    tracer = trace_plan(plan, scene, settings, cam)
    film = Film(cam.W, cam.H, scene.camera.filter_width, cam.region, textured=scene.textured_materials() is not None,
                threads=tracer.threads)
    _note_bent(scene, tracer, plan)
    parts = None if plan.nothing else world_parts(scene, settings, plan)
    if on_plan is not None:
        on_plan(plan.words())
    if plan.nothing:
        return nothing_to_bake(scene, settings, plan, cam, t0, None)
    return Job(scene if parts is None else parts.walked, settings, plan, cam, tracer, film, t0, report, cancel, watch,
               keep_partial=keep_partial, sky=parts)


def world_parts(scene, settings, plan):
    """The world's map split for the bake (shading.world_parts.split_world: the bright part walked,
    the rest path-traced), or None: not for the light tracer (method "reference", the independent
    estimator), nor with settings.world_split off, nor where the plan bakes no caustic of the world.
    Where the plan traces no light of the world after a diffuse bounce, its path-traced part keeps to
    one diffuse vertex too. The plan says so."""
    if settings.method == "reference" or not settings.world_split:
        return None
    parts = split_world(scene)
    if parts is None or parts.light not in [lp.index for lp in plan.lights]:
        return None
    traced = parts.traced
    if not (settings.indirect and parts.light in plan.indirect_lights):
        limits = np.array(traced.light_paths, np.int64)
        limits[1] = min(Limits.of(traced).diffuse, 1)  # (total, diffuse, glossy, transmission)
        traced = dataclasses.replace(traced, light_paths=limits)
    parts.walked.validate()
    traced.validate()
    plan.notes.append(parts.words(scene.light_names[parts.light]))
    return dataclasses.replace(parts, traced=traced)


def run(job, light_tracing: bool, choices=None) -> BakeResult:
    """Bake the job by light tracing alone, or by the walks (choices: auto's per light, {} for a
    fixed method)."""
    if light_tracing:
        batches, stop, t_first, rays = bake_light_tracing(job)
    else:
        batches, stop, t_first, rays = bake_walks(job, choices or {})
    return finish(job, batches, stop, t_first, rays)


def bake_fixed(scene, settings, cancel=None, watch=None, left_out=None) -> BakeResult:
    """A whole bake of a fixed method (not auto): what auto's pilot runs for each candidate. left_out:
    (O,) bool, casters left out before planning (auto's pilots: those the bake's plan left out)."""
    job = start(scene, settings, None, cancel, None, watch, left_out=left_out)
    if isinstance(job, BakeResult):
        return job
    return run(job, settings.method == "reference")


def film_memory(width: int, height: int, batches: int, textured: bool = False, replicates: int = 0) -> int:
    """Bytes the film of a bake needs: per pixel the sum, sum of squares and current batch
    (3 float64 each), the image and variance made from them (float64, then float32), and one
    float32 luminance image per batch (kept, then stacked); with textured receivers, their two
    sums and the current batch's two (3 float64 each) and the two float32 images made from them;
    with replicates (Film.use_replicates), each one's sum and then its mean (3 float64 each)."""
    px = int(width) * int(height)
    extra = px * 2 * 3 * (2 * 8 + 4) if textured else 0
    extra += 2 * int(replicates) * px * 3 * 8
    return px * (3 * 3 * 8 + 2 * 3 * 8 + 2 * 3 * 4) + 2 * int(batches) * px * 4 + extra


MAX_SAMPLES = 2 ** 48  # light paths or eye samples per light and pass; more are refused (check_samples)
FAST_SAMPLES_PER_S = 1e7  # faster than any bake here samples (bench/results/throughput.md): a lower bound on time


def check_samples(scene, settings) -> None:
    """Refuse, before anything is traced, a bake whose samples per light and pass of its batches
    (spp x the render region's pixels) are past what it can count (MAX_SAMPLES), saying how long it
    would take at least."""
    cam = CameraModel(scene.camera)
    x0, x1, y0, y1 = cam.region
    n = int(settings.spp) * max(0, x1 - x0) * max(0, y1 - y0)
    if n > MAX_SAMPLES:
        years = n * max(scene.n_lights, 1) / FAST_SAMPLES_PER_S / (365.25 * 86400)
        raise SceneError(f"spp {settings.spp} asks for {n:.3g} samples per light over the "
                         f"{x1 - x0} x {y1 - y0} pixels, more than a bake counts ({MAX_SAMPLES:.3g}); it would take "
                         f"more than {years:.3g} years even at {FAST_SAMPLES_PER_S:.0e} samples a second; at most "
                         f"spp {MAX_SAMPLES // max((x1 - x0) * (y1 - y0), 1)} here")


def check_memory(scene, width: int, height: int, batches: int, replicates: int = 0) -> None:
    """Refuse, before anything is allocated, a film bigger than MEMORY_BUDGET."""
    need = film_memory(width, height, batches, scene.textured_materials() is not None, replicates)
    if need > MEMORY_BUDGET:
        raise SceneError(
            f"scene '{scene.name}': a {width} x {height} caustic layer needs about "
            f"{need / 2**30:.1f} GiB for its film ({batches} batches), more than the "
            f"{MEMORY_BUDGET / 2**30:g} GiB limit; lower the resolution (or its percentage) "
            f"or the number of batches")


def trace_plan(plan, scene, settings, cam) -> Tracer:
    """The traced part of the plan (plan.refine_plan) with the bake's tracer; the tracer's
    tolerances then follow what takes part, not objects out of the plan."""
    tracer = Tracer(scene, threads=settings.threads or None)
    tracer.set_extent(*scene.bounds(), plan.casters)  # the pilots' tolerances: no caster lost to them either
    refine_plan(plan, scene, tracer, cam, settings.seed, settings.pilots, indirect=settings.indirect)
    tracer.set_extent(*plan.bounds, plan.casters)
    return tracer


def _note_bent(scene, tracer, plan) -> None:
    """The plan says where Cycles' Bump Map Correction bends normals (indirect.bent_gather)."""
    if not bending_lights(scene, tracer, plan):
        return
    cand = bent_candidates(scene, tracer, plan)[0]
    names = ", ".join(sorted({scene.object_names[o] for o in scene.tri_object[cand]}))
    plan.notes.append(f"{names}: smooth normals that Cycles' Bump Map Correction bends at grazing angles; "
                      "those paths are traced from the receivers")
