"""The manifold pass (MNEE, SMS, SMBS): receiver points from the eye, a light
sample per light, a walk per chain type, an estimator, and splats.

Lanes = (receiver point, light sample, chain type, trial), processed as
structure-of-arrays chunks. Chain types (one letter per specular vertex, R
reflect, T refract) come from the plan: a conductor gives R; open glass (a
water surface) T and R; closed glass TT and R, plus T when a receiver reaches
inside it.
"""
from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..core import lanes
from ..scene import arrays as S
from ..scene.light_paths import Limits
from ..trace.eye import BatchPart, direct_albedo, eye_receivers
from ..shading.coat import has_layers
from ..shading.lights import cone_solid_angle, distant_cone
from ..shading.fresnel import has_reflection
from .seeds import _closed, _plane
from .estimators import estimate
from ..shading.microfacet import rough_casters, walk_casters
from .walk import WalkConfig
from ..shading.light_samples import light_can_be_hit
from ..paths.gather import (HANDOFF_SAMPLES, UNWALKED_SAMPLES, GatherLights, HandoffRays, bending_lights, bent_gather,
                            bent_receivers, gather_radiance, handoff_gather, splat_gathered)
from ..paths.handoff import Handoff, SEEN_HANDOFF_MIN
from ..kernels.records import EyePaths


@dataclass
class ManifoldOptions:
    method: str = "smbs"  # mnee, sms, smbs
    estimator: str = "unbiased"  # unbiased, biased
    trials: int = 4  # biased: walks per lane
    max_trials: int = 10000  # unbiased: cap of the Bernoulli count (capped lanes count, contribute 0)
    uniqueness: float = 1e-7  # |d.d' - 1| below this: the same solution
    chains: tuple = ()  # explicit chain types, e.g. ("R", "TT"); empty: from the plan
    physical: bool = False  # eta^2 radiance change at refractions (Cycles does not apply it)
    clamp_g: float = 0.0  # > 0: cap on each solution's contribution (luminance); 0: off
    handoff: float = 0.0  # > 0: paths focusing more than this (estimators.concentration) go to photons
    max_chain: int = 4
    anchor: bool = False  # unbiased, one refraction, distant lights: a deterministic walk per lane
    # finds one solution at weight one, the random walks and their trials the others (estimators._anchored)
    anchor_walks: float = 1.0  # the share of lanes that walk from random seeds beside the anchor
    anchor_only: bool = False  # auto, where its pilot bounds the other solutions' light: the anchor alone (biased)
    walk: WalkConfig = field(default_factory=WalkConfig)


# ... and only where cosine sampling can find them. Under a sun of 0.5 degrees (handoff_hits 0.005
# paths per receiver) the gather found 10 paths where the walks met 1,796 (bumped water, SMBS 16 spp):
# each one a firefly, the bake's relative error 1.36-1.85 against 0.27-0.43 walked, in 2.3x the time.
# A light below SEEN_HANDOFF_HITS (a sun under about 1.6 degrees, a bulb of 1 cm 2.6 m from its
# caster) is walked; elsewhere, once the walks have met SEEN_HANDOFF_EVIDENCE focusing paths, the
# hand-off goes on while its gather has found at least SEEN_HANDOFF_RATIO as many. On the conformance
# scenes the gather found 1.4-105x the walks' focusing paths where it lowered the error (a disk seen
# through a pane, glass balls under soft point lights, a cube's internal reflections, an egg under a
# spot: 17 to 12, 0.213 against 0.254 walked) and fewer where it only cost time (a normal-mapped pool
# under a 4-degree sun, 1 to 9: 1.4x the time, the same error; too few to tell, so it goes on there).
SEEN_HANDOFF_HITS = 0.05
SEEN_HANDOFF_EVIDENCE = 16
SEEN_HANDOFF_RATIO = 0.5
# ... and under a world only while the paths it takes carry this share of the light's caustic at those
# receivers or more. A world fills every cosine direction: its 64 per receiver find the dim sky's paths
# focused near the horizon. On issue 61's pool lit by a sky and a bright disc they were 75% of a
# bake's time (the walks met 1 focusing path where the gather found 39,000, so the count rule kept it
# on) for 0.02% of the caustic seen there
SEEN_HANDOFF_SHARE = 0.02
# ... and there the paths no walk takes (chains longer than max_chain, ...) go to it too, for each
# light whose photon pre-pass (the guide) found them carrying at least this share of the light it
# brought into the frame: below, they are left out at those receivers (their cosine rays cost as
# much as a focus's, and over a pool under a sun, seen through its water everywhere, would find
# next to nothing). At receivers seen directly the photons take them whatever their share
OTHERS_MIN_SHARE = 0.01
# gathers after a diffuse bounce per receiver seen through glass where every light walks its straight line
# alone (gather_copies). pool_sun (64 spp, 160 x 120): a quarter of its layer comes after a diffuse bounce
# (its own caustic through the water's underside) and held most of the variance; 1, 2, 3, 4 copies: relative
# RMSE 0.0406, 0.0307, 0.0259, 0.0239 in 8.0, 10.4, 13.5, 14.1 s (error^2 x time 1.6x lower at 4); with the
# gather compiled since, 3, 4, 6, 8 copies: error^2 x time 0.0053, 0.0050, 0.0049, 0.0054. Under SMBS's walks
# at the second vertex (pool_hdri's whole map, before its sky was path-traced) 4 copies cost 2.3x the time for
# 0.82x the error: 1
GATHER_COPIES = 4
# the gather after a diffuse bounce (_gather_after_bounce) runs a chunk's receivers in two halves at once from
# this many receivers on
GATHER_SPLIT = 4096
# receivers per part of a chunk's walks (manifold_chunk): parts run on the threads in turn, so one
# part's numpy (light samples, contributions) runs beside another's walk kernels
ESTIMATE_PART = 8192


class Ctx:
    """What the walk needs: scene, tracer, caster mask, object boxes, counters."""

    def __init__(self, scene, tracer, plan, stats):
        # the walks' casters: the planned ones but rough mirrors and glass (their paths: photons)
        self.scene, self.tracer, self.casters, self.stats = scene, tracer, walk_casters(scene, plan.casters), stats
        self.scale = plan.scale  # a length for tolerances, over what takes part
        self.obj_lo, self.obj_hi = tracer.obj_lo, tracer.obj_hi  # built once per bake
        cast = np.flatnonzero(self.casters & tracer.obj_has_tris)
        self.caster_lo = self.obj_lo[cast].min(axis=0) if cast.size else np.zeros(3)
        self.caster_hi = self.obj_hi[cast].max(axis=0) if cast.size else np.zeros(3)
        self.physical = False
        self.clamp = 0.0  # cap on a solution's luminance (ManifoldOptions.clamp_g); 0: off
        self.clamp_cut = None  # per solution of the last _contribution: luminance the cap removed
        self.film = None  # the film the estimates are splatted on (the clamp's statistics count what lands)
        self.handoff_seen = False  # hand off focusing paths at receivers seen through mirrors or glass too
        self.first_order = False  # walking from receivers the camera sees (not later diffuse vertices)
        self.coated = has_layers(scene)  # receivers under a Principled coat (coat.coat_factor1)

    def part(self) -> "Ctx":
        """A copy for one part of a chunk's receivers, with counters of its own (merged by the
        caller in part order: lanes.add_stats)."""
        c = copy.copy(self)
        c.stats = {}
        c.clamp_cut = None
        return c

    def count(self, key, n):
        with lanes.LOCK:  # walk blocks on several threads count here
            self.stats[key] = self.stats.get(key, 0) + int(n)


def chain_types(scene, plan, opts: ManifoldOptions, light_paths: bool = True) -> list:
    """The chain types the materials call for, up to opts.max_chain (opts.chains: the user's);
    light_paths: leave out those the scene's Light Paths limits cut even seen directly."""
    if opts.chains:
        return [c for c in opts.chains if 1 <= len(c) <= opts.max_chain]
    kinds = scene.mat_kind[scene.tri_material]
    types = []
    rec_lo = np.array([np.inf] * 3)
    rec_hi = -rec_lo
    for o in np.flatnonzero(plan.receivers):
        lo, hi = scene.object_bounds(o)
        rec_lo, rec_hi = np.minimum(rec_lo, lo), np.maximum(rec_hi, hi)
    casters = walk_casters(scene, plan.casters)  # a rough caster's paths go to the photons
    conductors = [o for o in np.flatnonzero(casters)
                  if np.any(kinds[scene.tri_object == o] == S.CONDUCTOR)]
    for o in np.flatnonzero(casters):
        k = kinds[scene.tri_object == o]
        if any(has_reflection(scene, m) for m in np.unique(scene.tri_material[scene.tri_object == o])):
            types.append("R")  # not for Cycles' Refraction BSDF, which never reflects
        if o in conductors and (len(conductors) > 1 or _plane(scene, o) is None):
            types.append("RR")  # a curved mirror (a ring, a bowl) or two mirrors see each other
        if np.any(k == S.DIELECTRIC):
            if _closed(scene, o):
                types.append("TT")
                # light reflected inside closed glass (a cube's faces, a prism's hypotenuse by total
                # internal reflection): T R..R T up to max_chain; the photon pre-pass drops the
                # ones that carry no light
                types += ["T" + "R" * r + "T" for r in range(1, opts.max_chain - 1)]
                lo, hi = scene.object_bounds(o)
                inside = [scene.light_matrix[lp.index][:3, 3] for lp in plan.lights
                          if scene.light_type[lp.index] not in S.DISTANT]
                lit_inside = any(np.all(lo <= y) and np.all(y <= hi) for y in inside)
                if (np.all(rec_lo <= hi) and np.all(lo <= rec_hi)) or lit_inside \
                        or not scene.object_seen_by(o, S.RAY_TRANSMISSION):
                    # a receiver may reach inside, or a light sits inside, or the glass's own inside passes
                    # the ray a refraction casts (its Ray Visibility): one refraction, then the light
                    types.append("T")
            else:
                types.append("T")
    out = []
    lim = Limits.of(scene)
    for t in types:  # a chain the scene's Light Paths limits cut even seen directly is not walked
        if t not in out and len(t) <= opts.max_chain and (lim.chain_fits(t) or not light_paths):
            out.append(t)
    return out


def manifold_chunk(job, walk, start, n, rng, eye_stats, strata=None) -> None:
    """Eye samples start..start+n of a batch (of job.eye_per_batch()): receivers, then every light x
    chain type; for receivers seen through mirrors or glass, also the caustic light that meets more
    diffuse surfaces (indirect.gather, with these walks at every diffuse vertex).

    job: the bake (baking.job.Job: scene, tracer, cam, film, plan, light_stats, physical,
    indirect_lights(): the lights whose direct light counts after a diffuse bounce); walk: its walks
    (baking.walking.WalkSetup: opts, types, guide, opts_by_light: {light index: ManifoldOptions}
    where a light walks otherwise, method auto); strata: the eye samples stratified (eye.film_samples)."""
    scene, tracer, film, plan, opts = job.scene, job.tracer, job.film, job.plan, walk.opts
    rc = eye_receivers(scene, tracer, job.cam, film, plan, BatchPart(start, n, job.eye_per_batch()), rng, eye_stats,
                       EyePaths(min_specular=0, scale_eta=opts.physical), strata=strata)
    ctxs = {}
    for lp in plan.lights:
        ctx = Ctx(scene, tracer, plan, job.light_stats[lp.name])
        ctx.physical = opts.physical
        ctx.clamp = opts.clamp_g
        ctx.film = film
        ctxs[lp.index] = ctx
    caustic = CausticEstimate(job, walk, ctxs, rng)
    handoffs, focus = _seen_handoffs(scene, plan, walk, ctxs)
    for li, ctx in ctxs.items():
        ctx.handoff_seen = li in focus
        ctx.first_order = True
    total = caustic(rc)
    for ctx in ctxs.values():  # the walks at later diffuse vertices (indirect.gather) keep every path
        ctx.handoff_seen = ctx.first_order = False
    hit = np.flatnonzero(total.max(axis=1) > 0)
    film.splat(rc.rx[hit], rc.ry[hit], total[hit] * rc.weight[hit, None], direct_albedo(scene, rc, hit))
    bent = bending_lights(scene, tracer, plan)
    if bent:  # its counters where the light tracer keeps its bent pass's: the eye pass's "bent" part
        t_bent, bent_stats = time.perf_counter(), eye_stats.setdefault("bent", {"time_s": 0.0})
        bent_gather(scene, tracer, film, plan, bent_receivers(rc, rng), rng, bent_stats, bent, physical=opts.physical)
        bent_stats["time_s"] += time.perf_counter() - t_bent
    seen = np.flatnonzero(rc.eye_specular > 0)
    if seen.size == 0:
        return
    rc_seen = rc.take(seen)
    if handoffs:
        found = {}
        handoff_gather(scene, tracer, film, plan, rc_seen, rng, eye_stats, handoffs, physical=opts.physical,
                       rays=HandoffRays(HANDOFF_SAMPLES if walk.types else UNWALKED_SAMPLES), found=found)
        for li in handoffs:
            st = ctxs[li].stats
            st["seen_handoff_paths"] = st.get("seen_handoff_paths", 0) + found.get(li, 0)
            st["seen_handoff_energy"] = st.get("seen_handoff_energy", 0.0) + found.get(("energy", li), 0.0)
    if job.indirect_lights():
        _gather_after_bounce(job, walk, caustic, rc_seen, handoffs, rng, eye_stats)


def _gather_after_bounce(job, walk, caustic, rc, others, rng, eye_stats) -> None:
    """The caustic light after a diffuse bounce at the receivers rc, seen through mirrors or glass
    (indirect.gather, these walks at every diffuse vertex; others: the hand-off's Handoffs for the
    paths no walk takes), gather_copies gathers per receiver, in two halves (from GATHER_SPLIT
    receivers on) that the threads take at once (lanes.blocks), each with its random stream (keyed by
    one draw from rng and its first receiver), its walks' (CausticEstimate.keyed) and its counters:
    the gather's kernel call (indirect._connected_gather) is one thread's, and so is the numpy
    between the calls. Their light is splatted and their counters added here, in order, so the image
    does not depend on the thread count. Halves, not blocks of a fixed size: a default bake's batch
    is one chunk of 40,000 receivers on the pool, and blocks of 32,768 left one thread a small rest;
    blocks of 8,192 paid a walk call's fixed cost too often. Inside a half the walks' kernels do not
    split over more threads (on more than 2 cores the halves leave some idle)."""
    copies = gather_copies(job.plan, walk)
    lights = job.indirect_lights()
    key = int(rng.integers(2**63))

    def block(a, b):
        brng = np.random.default_rng([key, a])
        connect, st = caustic.keyed(brng), {}
        sub = rc.take(slice(a, b))
        radiance = np.zeros((b - a, 3))
        for k in range(copies):
            radiance += gather_radiance(job.scene, job.tracer, job.plan, _gather_copy(sub, k, copies), brng, st,
                                        GatherLights(direct=lights, connect=connect, others=others),
                                        physical=walk.opts.physical)
        return radiance, st, connect.light_stats

    n = len(rc.p)
    parts = lanes.blocks(block, n, -(-n // 2) if n >= GATHER_SPLIT else n, job.tracer.threads)
    for _, st, light_stats in parts:
        lanes.add_stats(eye_stats, st)
        for name, ls in light_stats.items():
            lanes.add_stats(job.light_stats[name], ls)
    if parts:
        splat_gathered(job.scene, job.film, rc, np.concatenate([p[0] for p in parts]), eye_stats)


def gather_copies(plan, walk) -> int:
    """How many gathers after a diffuse bounce each receiver seen through mirrors or glass takes
    (each with 1/copies of its weight): GATHER_COPIES where every light walks its straight line alone
    (auto's anchor alone: the walks at the second vertex cost what MNEE's do), else 1."""
    if plan.lights and all(getattr(walk.opts_by_light.get(lp.index), "anchor_only", False) for lp in plan.lights):
        return GATHER_COPIES
    return 1


def _gather_copy(rc, k: int, copies: int):
    """Copy k of copies of the receivers rc for the gather after a diffuse bounce: 1/copies of their
    weight, and their stratified bounce and light samples shifted by k/copies (mod 1: each copy's
    uniform, the copies spread over the pair's square)."""
    if copies == 1:
        return rc
    out = rc.take(slice(None))
    out.beta = rc.beta / copies
    if rc.strata is not None and k:
        out.strata = (rc.strata + k / copies) % 1.0
    return out


class CausticEstimate:
    """receivers -> (M,3): every light x chain type at these receivers (estimators.estimate), in parts
    of ESTIMATE_PART receivers that the threads take in turn (lanes.blocks), each part with its own
    random stream (keyed by one draw from the chunk's and the part's first receiver) and its own
    counters, added in part order: one thread's numpy runs beside another's walks, and the image does
    not depend on the thread count."""

    def __init__(self, job, walk, ctxs, rng):
        self.job, self.walk, self.ctxs, self.rng = job, walk, ctxs, rng
        self.light_stats = job.light_stats  # per light name: where the parts' counters are added

    def keyed(self, rng) -> "CausticEstimate":
        """The same estimate for a block of receivers on a thread of its own: its random stream rng, and
        counters of its own (light_stats, for the caller to add in block order)."""
        c = copy.copy(self)
        c.rng, c.light_stats = rng, {name: {"time_s": 0.0} for name in self.job.light_stats}
        return c

    def __call__(self, receivers):
        n = len(receivers.p)
        key = int(self.rng.integers(2**63))
        t0 = time.perf_counter()
        # below two parts' worth, one part: its walks split over the threads in blocks, balanced
        # lane by lane (a part and a small rest would leave a thread idle beside the part's walks)
        parts = lanes.blocks(lambda a, b: self._part(receivers, key, a, b), n,
                             ESTIMATE_PART if n >= 2 * ESTIMATE_PART else max(n, 1), self.job.tracer.threads)
        wall = time.perf_counter() - t0
        busy = sum(sum(p[2].values()) for p in parts)
        stats_per_light = self.light_stats
        for _, stats, secs in parts:
            for name, st in stats.items():
                lanes.add_stats(stats_per_light[name], st)
                # each light's share of the wall time (parts of several lights run at once)
                stats_per_light[name]["time_s"] += wall * secs[name] / busy if busy > 0 else 0.0
        return np.concatenate([p[0] for p in parts]) if parts else np.zeros((0, 3))

    def _part(self, receivers, key, a, b):
        """Receivers a..b: (their radiance, counters per light, seconds per light)."""
        plan, walk = self.job.plan, self.walk
        prng = np.random.default_rng([key, a])
        sub = receivers.take(slice(a, b))
        total = np.zeros((b - a, 3))
        stats, secs = {}, {}
        for lp in plan.lights:
            t = time.perf_counter()
            ctx = self.ctxs[lp.index].part()
            o = walk.opts if not walk.opts_by_light else walk.opts_by_light.get(lp.index, walk.opts)
            share = plan.sample_share.get(lp.index, 1.0)
            if share < 1.0:  # a share of the receivers, at random (a stream of its own), weighed up
                keep = np.flatnonzero(np.random.default_rng([key, a, lp.key]).random(b - a) < share)
                thin = sub.take(keep)
                thin.weight = thin.weight / share
                for types in walk.types:
                    total[keep] += estimate(ctx, o, lp.index, types, thin, prng, walk.guide) / share
            else:
                for types in walk.types:
                    total += estimate(ctx, o, lp.index, types, sub, prng, walk.guide)
            stats[lp.name], secs[lp.name] = ctx.stats, time.perf_counter() - t
        return total, stats, secs


def _seen_handoffs(scene, plan, walk, ctxs):
    """Which lights hand paths off at receivers seen through mirrors or glass in this chunk:
    ({light index: Handoff}, the lights whose focusing paths go)."""
    # at receivers seen through mirrors or glass, paths focusing more than opts.handoff go to
    # cosine sampling from x0 (indirect.handoff_gather) for the lights it can hit; per light,
    # in the bake's first chunk (before any walk could tell) where a caster of the light is
    # smooth-shaded (what can focus: through flat faces a path's concentration is constant,
    # never a fold), then in every chunk once an earlier one found such paths, by its walks
    # (seen_focus) or by the hand-off itself (seen_handoff_paths). All is decided before the
    # chunk's own samples (each chunk stays unbiased, and chunks run in order, so the image
    # does not depend on the thread count). Without the first-chunk rule, that chunk walked
    # the fold: one path of concentration 25 seen through a pane carried a quarter of a 2 spp
    # bake's T T energy (through_glass_disk, SMBS). Handing off in every chunk of a smooth
    # caster instead cost the pool under a sun, seen through its water everywhere, 2-3x in
    # samples (64 cosine rays per receiver and bounce) where neither ever finds a focus. The
    # hand-off's own evidence is the surer: on the disk seen through a pane its first chunk
    # took 101 paths where the walks of that chunk met none, and a second chunk without the
    # hand-off met the fold (seed 1: 0.915 relative RMSE at 20 s against 0.165 with it)
    # The same gather also takes, at these receivers, the paths no walk takes (a chain type not
    # walked, longer than max_chain, or through a specular vertex that is no planned caster), as
    # the photons take them at receivers seen directly (bake._handoff_batch, Handoff.others):
    # for each light whose pre-pass (the guide) saw them bring OTHERS_MIN_SHARE of its light into
    # the frame or more (every light without the guide). They used to be lost wherever the camera
    # looks through glass: on a bevelled cube's floor seen through the cube, chains of 5 and more
    # vertices carry 8% of the light reaching the frame.
    # Paths through a rough mirror or glass (no walk takes them) are such paths too, whatever
    # opts.handoff says (MNEE's, or the user's 0).
    opts, types_list, guide = walk.opts, walk.types, walk.guide
    handoffs, focus = {}, set()
    rough = bool(rough_casters(scene, plan.casters).any())
    if not ((opts.handoff > 0 and types_list) or rough):
        return handoffs, focus
    for lp in plan.lights:
        if not light_can_be_hit(scene, lp.index):
            continue
        seen_focus = opts.handoff > 0 and bool(types_list) and _hand_off_seen(scene, lp, ctxs[lp.index].stats)
        others = rough or guide is None or \
            guide.stats.get("other_share", {}).get(lp.name, 1.0) >= OTHERS_MIN_SHARE
        if seen_focus or others:
            tau = max(opts.handoff, SEEN_HANDOFF_MIN) if seen_focus else math.inf
            handoffs[lp.index] = Handoff({t: tau for t in types_list}, bool(scene.light_type[lp.index] in S.DISTANT),
                                         others=others)
        if seen_focus:
            focus.add(lp.index)
            st = ctxs[lp.index].stats
            st["seen_handoff_chunks"] = st.get("seen_handoff_chunks", 0) + 1
    return handoffs, focus


def _hand_off_seen(scene, lp, st) -> bool:
    """Does this chunk hand off light lp's focusing paths at receivers seen through mirrors
    or glass? Never for a light too small for cosine sampling to hit (handoff_hits); in the bake's
    first chunk where its caster can focus, later where an earlier chunk found such paths, by its
    walks or by the hand-off itself; but no more once the hand-off has run and found fewer than
    SEEN_HANDOFF_RATIO of the SEEN_HANDOFF_EVIDENCE or more that the walks met (st: the light's
    statistics so far, from earlier chunks only, so each chunk's estimate stays unbiased and the
    image does not depend on the thread count)."""
    if handoff_hits(scene, lp.index, lp.caster_objects) < SEEN_HANDOFF_HITS:
        return False
    walked, gathered = st.get("seen_focus", 0), st.get("seen_handoff_paths", 0)
    if st.get("seen_handoff_chunks", 0) > 0 and walked >= SEEN_HANDOFF_EVIDENCE \
            and gathered < SEEN_HANDOFF_RATIO * walked:
        return False
    # ... nor, for a world, once it has run and brought under SEEN_HANDOFF_SHARE of the light's caustic
    # seen there
    e_gather, e_walks = st.get("seen_handoff_energy", 0.0), st.get("seen_energy", 0.0)
    if scene.light_type[lp.index] == S.WORLD and st.get("seen_handoff_chunks", 0) > 0 \
            and e_gather < SEEN_HANDOFF_SHARE * (e_gather + e_walks):
        return False
    if walked > 0 or gathered > 0:
        return True
    # the first chunk: no walk of any kind yet (an anchored bake's straight-line walks count; auto's
    # anchor alone walks no other, and counting only the others kept the hand-off on in every chunk of
    # pool_sun, 80% of its time for no path found)
    return st.get("walks", 0) + st.get("anchor_walks", 0) == 0 and can_focus(scene, lp)


def handoff_hits(scene, li, casters=()) -> float:
    """The paths to light li that handoff_gather's cosine directions from one receiver can expect
    to find at the least concentration handed off there (SEEN_HANDOFF_MIN: the light's image through
    the chain that many times its solid angle): a sun's cone; a point or spot light's sphere
    and an area light (its area over the squared distance) as seen from the nearest point of its
    casters' boxes (casters: object ids), the largest they can look there. inf for a world."""
    typ = scene.light_type[li]
    if typ == S.WORLD:
        return math.inf
    if typ == S.SUN:
        omega = cone_solid_angle(distant_cone(scene, li)[1])
    else:
        pos = np.asarray(scene.light_matrix[li], float)[:3, 3]
        d2 = math.inf
        for o in casters:
            lo, hi = scene.object_bounds(int(o))
            d2 = min(d2, float(np.sum((pos - np.clip(pos, lo, hi)) ** 2)))
        if not math.isfinite(d2):
            return math.inf
        if typ in (S.AREA, S.MESH):
            if typ == S.MESH:
                area = scene.mesh_light(li)[4]
            else:
                sx, sy = (float(x) for x in scene.light_size[li])
                area = sx * sy * (math.pi / 4.0 if scene.light_shape[li] in (S.DISK, S.ELLIPSE) else 1.0)
            omega = 2.0 * math.pi if area >= 2.0 * math.pi * d2 else area / d2
        else:
            r2 = float(scene.light_radius[li]) ** 2
            omega = 2.0 * math.pi if r2 >= d2 else 2.0 * math.pi * (1.0 - math.sqrt(1.0 - r2 / d2))
    return HANDOFF_SAMPLES * SEEN_HANDOFF_MIN * omega / math.pi


def can_focus(scene, lp) -> bool:
    """Can a path through this light's casters focus (a fold, where the walks' estimate has
    no bound)? Only where shading normals vary over a face: a smooth-shaded caster."""
    return bool(np.any(scene.object_smooth[np.asarray(lp.caster_objects, np.int64)]))


