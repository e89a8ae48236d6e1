"""A bake by light tracing alone (method "reference", or auto's choice where it wins everywhere):
photons per light, eye paths for what is seen through mirrors and glass, and light after a
diffuse bounce, batch after batch.
"""
from __future__ import annotations

import math

from ..trace.eye import film_cells, specular_cells
from .job import Progress
from .passes import CHUNK, eye_rays, indirect_batch, light_tracing_batch, rays, sky_batch, specular_visible
from .stop import run_batches

PHOTON_COUNTERS = ("photons", "rays_photon", "rays_camera", "splats", "truncated", "lost_shading_normal")


def bake_light_tracing(job):
    """Run the batches: (batches done, the stop rule, seconds before the first, rays cast)."""
    scene, settings, cam, film = job.scene, job.settings, job.cam, job.film
    for st in job.light_stats.values():
        st.update(dict.fromkeys(PHOTON_COUNTERS, 0))
    # the film cells that can see a mirror or glass first: the look for one in view casts
    # from their pixels alone, and the eye paths start in them alone
    plan = job.plan
    unseen = None if plan.first_specular is None else ~plan.casters & ~plan.first_specular
    eye_cells = specular_cells(scene, job.tracer, cam, film, unseen)
    enabled, rays_visible = specular_visible(job, eye_cells)
    eye_stats = {"eye_paths": 0, "rays_eye": 0, "rays_visible": rays_visible, "eye_splats": 0, "time_s": 0.0,
                 "enabled": enabled, "film_cells": film_cells(cam, film)}
    eye_cells = eye_cells if enabled else None
    eye_stats["cells"] = eye_stats["film_cells"] if eye_cells is None else int(eye_cells.sum())
    per_batch = max(1, job.per_light // settings.batches)
    eye_chunks = math.ceil(job.eye_per_batch() / CHUNK) if eye_stats["enabled"] else 0
    job.prog = Progress(settings.batches * (len(job.plan.lights) * math.ceil(per_batch / CHUNK) + eye_chunks),
                        job.report, job.cancel)

    def run_batch(b):
        light_tracing_batch(job, b, eye_stats, eye_cells)
        indirect_batch(job, b)
        sky_batch(job, b)  # auto's light tracing alone on a split world: the sky as the walks' bakes take it

    b, stop, t_first = run_batches(job, run_batch)
    job.extra["batches_done"] = b
    job.extra["eye_pass"] = eye_stats
    cast = (sum(s["rays_photon"] + s["rays_camera"] for s in job.light_stats.values())
            + eye_rays(eye_stats) + job.plan.cost.get("rays", 0) + rays(job.extra.get("sky", {})))
    return b, stop, t_first, cast
