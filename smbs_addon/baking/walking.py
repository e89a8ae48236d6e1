"""A bake by the manifold walks (MNEE, SMS, SMBS, or auto's per-light choice): the chain types the
scene calls for, the photon pre-pass that steers the walks (the guide), then per batch the walks,
the photon hand-off beside them, and light after a diffuse bounce.
"""
from __future__ import annotations

import dataclasses
import math
import time
from concurrent.futures import wait
from dataclasses import dataclass, field

import numpy as np

from ..core import lanes
from ..core.random import GUIDE
from ..scene.light_paths import Limits
from ..shading.microfacet import rough_casters
from ..walks.guide import Guide, build_guide, hidden_in_reach, photon_budget
from ..walks.manifold import chain_types
from .job import Progress
from .passes import (DeferredFilm, WALK_CHUNK, eye_rays, handoff_batch, hands_off, indirect_batch, rays, sky_batch,
                     walks_batch)
from .stop import run_batches


@dataclass
class WalkSetup:
    """What the walks of a bake use: their options (per light where auto chose), the chain types
    walked, the guide, and auto's photons per walk sample where light tracing serves a light's
    directly seen receivers."""

    opts: object  # walks.manifold.ManifoldOptions
    types: list
    opts_by_light: dict = field(default_factory=dict)
    guide: object = None  # walks.guide.Guide
    factors: dict = field(default_factory=dict)


def setup_walks(job, choices) -> WalkSetup:
    """The walks' options and chain types, what the plan says of them, and the guide."""
    scene, plan, settings = job.scene, job.plan, job.settings
    opts = settings.manifold_options()
    walk = WalkSetup(opts, chain_types(scene, plan, opts),
                     {li: dataclasses.replace(settings.manifold_options(c.walk), anchor_only=c.anchor_only)
                      for li, c in choices.items()})
    rough = [scene.object_names[o] for o in np.flatnonzero(rough_casters(scene, plan.casters))]
    if rough:
        plan.notes.append(f"{', '.join(rough)}: rough, so {'its' if len(rough) == 1 else 'their'} caustic comes "
                          f"from the photons (a walk solves for a perfect mirror's or glass's paths)")
    cut = [t for t in chain_types(scene, plan, opts, light_paths=False) if t not in walk.types]
    if cut:
        plan.notes.append(f"{Limits.of(scene).words()}: Cycles renders no caustic along "
                          f"{', '.join(cut)}, so neither do we")
    _add_guide(job, walk)
    photon_lights = {(li, t) for li, c in choices.items() if c.photons_direct for t in walk.types}
    if photon_lights and opts.handoff > 0:  # auto: light tracing serves these lights' direct receivers
        if walk.guide is None:
            walk.guide = Guide(job.cam, {}, {})
        walk.guide.weak = frozenset(walk.guide.weak) | photon_lights
    walk.factors = {li: c.photon_factor for li, c in choices.items() if c.photons_direct}
    return walk


def _add_guide(job, walk) -> None:
    """The photon pre-pass: where caustics land per light and chain type (walks.guide). Chain types
    that brought no light at all are not walked; weak ones go to the photon hand-off."""
    scene, plan, settings, tracer = job.scene, job.plan, job.settings, job.tracer
    # the guide's pre-pass traces its photons past no surface: where some object's Ray Visibility leaves
    # out a kind of a path's rays it would miss paths that pass it, and leave their chain types unwalked
    # (such an object out of the photons' reach changes nothing: guide.hidden_in_reach)
    hides = hidden_in_reach(scene, tracer, plan)
    if hides and settings.guide:
        plan.notes.append("the photon pre-pass (the guide) is off: some object's Ray Visibility leaves out "
                          "diffuse, glossy or transmission rays")
    if not settings.guide or hides:
        return
    t_g = time.perf_counter()
    types = walk.types
    masks, gstats, weak = build_guide(scene, tracer, job.cam, plan, types, job.rng(GUIDE, 0),
                                      photon_budget(job.cam), check=Progress(1, None, job.cancel).check)
    gstats["time_s"] = time.perf_counter() - t_g
    # chain types that brought no light at all in the pre-pass are not walked (internal
    # reflections a closed glass shape does not produce for these lights)
    lit = [t for t in types if any(sh.get(t, 0.0) > 0 for sh in gstats["flux_share"].values())]
    if lit and len(lit) < len(types):
        gstats["not_walked"] = [t for t in types if t not in lit]
        masks = {k: v for k, v in masks.items() if k[1] in lit}
        weak = frozenset(w for w in weak if w[1] in lit)
        walk.types = lit
    # weak chain types go to the photon hand-off (which the user may turn off: then walk them)
    walk.guide = Guide(job.cam, masks, gstats, weak if walk.opts.handoff > 0 else frozenset())
    gstats["left_to_photons"] = sorted(f"{scene.light_names[li]}: {t}" for li, t in walk.guide.weak)
    job.extra["guide"] = gstats


def bake_walks(job, choices):
    """Run the batches: (batches done, the stop rule, seconds before the first, rays cast)."""
    walk = setup_walks(job, choices)
    if job.settings.replicates():  # each replicate one stratified sequence per pixel (Job.strata)
        job.film.use_replicates(job.settings.replicates())
    eye_stats = {"eye_paths": 0, "rays_eye": 0}
    job.prog = Progress(job.settings.batches * math.ceil(job.eye_per_batch() / WALK_CHUNK), job.report, job.cancel)
    beside = job.tracer.threads > 1 and not lanes.nested() and hands_off(job.scene, job.plan, walk.opts, walk.types)

    def run_batch(b):
        if beside:
            _walks_beside_photons(job, b, walk, eye_stats)
        else:
            walks_batch(job, b, walk, eye_stats)
            handoff_batch(job, b, walk, job.light_stats)
        indirect_batch(job, b)
        sky_batch(job, b, job.strata(b))

    b, stop, t_first = run_batches(job, run_batch)
    job.extra["batches_done"] = b
    _summarise(job, walk, eye_stats, b)
    cast = (sum(st["rays"] for st in job.light_stats.values()) + eye_rays(eye_stats)
            + job.extra.get("guide", {}).get("rays", 0) + job.plan.cost.get("rays", 0) + rays(job.extra.get("sky", {})))
    return b, stop, t_first, cast


def _walks_beside_photons(job, b, walk, eye_stats) -> None:
    """The photon hand-off beside the walks (lanes.beside): at a few spp a batch's photons are one
    chunk, whose emission and selection ran on one thread while the others waited. Its splats
    are made after the walks' and its counters added then: the image and the statistics are
    those of the two passes in turn."""
    late, own = DeferredFilm(job.film), {lp.name: {"time_s": 0.0} for lp in job.plan.lights}
    photons = lanes.beside(lambda: handoff_batch(job.on_film(late), b, walk, own))
    try:
        walks_batch(job, b, walk, eye_stats)
    finally:
        wait([photons])
    photons.result()
    late.replay(job.film)
    for name, st in own.items():
        lanes.add_stats(job.light_stats[name], st)


def _summarise(job, walk, eye_stats, batches) -> None:
    """The walks' statistics per light and over the bake."""
    settings, light_stats, extra = job.settings, job.light_stats, job.extra
    for st in light_stats.values():
        summarise_walks(st)
        if settings.clamp_g > 0:  # the clamp's bias, in image units (summed over pixels)
            st["clamped"] = st.get("clamped", 0)
            st["clamped_energy"] = st.get("clamped_energy", 0.0) / batches
        st["trials"]["capped_energy_min"] = st.pop("capped_energy_min", 0.0) / batches
    walks = sum(st.get("walks", 0) for st in light_stats.values())
    extra.update({
        "chain_types": walk.types, "eye_pass": eye_stats, "walks": walks,
        "successes": sum(st.get("successes", 0) for st in light_stats.values()),
        "mutations": sum(st.get("mutations", 0) for st in light_stats.values()),
    })
    extra["success_rate"] = extra["successes"] / walks if walks else 0.0
    extra["mutations_per_path"] = extra["mutations"] / walks if walks else 0.0
    extra["mutations_per_success"] = extra["mutations"] / extra["successes"] if extra["successes"] else 0.0




def summarise_walks(st: dict) -> None:
    """A light's walk statistics: rates and means from its counts."""
    for key in ("walks", "successes", "mutations"):  # a light auto leaves to photons walks nowhere
        st.setdefault(key, 0)
    st.setdefault("large_mutations", {})
    walks = st["walks"]
    st["success_rate"] = st.get("successes", 0) / walks if walks else 0.0
    st["mutations_per_path"] = st.get("mutations", 0) / walks if walks else 0.0
    succ = st.get("successes", 0)
    st["mutations_per_success"] = st.get("mutations", 0) / succ if succ else 0.0
    for bc in st.get("by_chain", {}).values():
        bc["success_rate"] = bc["successes"] / bc["walks"] if bc["walks"] else 0.0
        bc["mutations_per_success"] = bc["mutations"] / bc["successes"] if bc["successes"] else 0.0
    n_lanes = st.get("bernoulli_lanes", 0)
    st["trials"] = {"mean": st.get("bernoulli_trials", 0) / n_lanes if n_lanes else 0.0,
                    "max": st.get("bernoulli_trials_max", 0), "capped": st.get("capped", 0)}
    st["rays"] = rays(st)
    hs = st.get("handoff")
    if hs:
        st["rays"] += hs["rays_photon"] + hs["rays_camera"]
