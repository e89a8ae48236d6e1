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
from ..shading.light_samples import LightEnd
from .estimators import chain_throughput, same_solution
from ..paths.focus import concentration, geometric_term
from ..shading.light_samples import light_end_at_solution
from ..trace.eye import direct_albedo, eye_receivers
from ..scene.geometry import area_points, triangle_areas
from ..shading.coat import coat_factor, has_layers
from ..shading.lights import cone_solid_angle, distant_cone, shadow_tmax
from ..shading.optics import bump_shadowing
from ..shading.fresnel import has_reflection
from ..shading.microfacet import rough_casters, walk_casters
from .trials import bernoulli_trials
from ..core.vec import channel_mean, dot, normalize
from ..kernels.records import OUTCOMES, TRIGGERS, EyePaths
from .walk import WalkConfig, newton_walk, propagate
from ..shading.light_samples import light_can_be_hit, sample_light, sphere_cap
from ..paths.gather import (HANDOFF_SAMPLES, UNWALKED_SAMPLES, bending_lights, bent_gather, bent_receivers, gather,
                            handoff_gather)
from ..paths.handoff import Handoff


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
    walk: WalkConfig = field(default_factory=WalkConfig)


# At receivers seen through mirrors or glass the hand-off goes to cosine sampling, weaker than
# light tracing: only paths focusing more than this (the default hand-off) go there
SEEN_HANDOFF_MIN = 4.0
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
# ... and there the paths no walk takes (chains longer than max_chain, ...) go to it too, for each
# light whose photon pre-pass (the guide) found them carrying at least this share of the light it
# brought into the frame: below, they are left out at those receivers (their cosine rays cost as
# much as a focus's, and over a pool under a sun, seen through its water everywhere, would find
# next to nothing). At receivers seen directly the photons take them whatever their share
OTHERS_MIN_SHARE = 0.01
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
        self.coated = has_layers(scene)  # receivers under a Principled coat (layer.coat_factor)

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


def _closed(scene, obj) -> bool:
    """Is the object's mesh watertight (every edge shared by exactly two triangles)?"""
    return scene.derived(("closed", int(obj)), lambda: _watertight(scene, obj))


def _watertight(scene, obj) -> bool:
    """Every edge of the object's triangles shared by exactly two, its vertices merged where their
    coordinates agree to 1e-9. Sorted by coordinates (np.lexsort) and by one integer per edge: a
    bumped water's 131,072 triangles in ~0.07 s, where np.unique over rows took 0.66 s (once per
    scene a bake makes: auto's pilots are scenes of their own)."""
    tv = scene.tri_vertices[scene.tri_object == obj]
    if len(tv) == 0:
        return False
    p = np.round(tv.reshape(-1, 3), 9)
    order = np.lexsort((p[:, 2], p[:, 1], p[:, 0]))
    q = p[order]
    new = np.ones(len(q), bool)
    new[1:] = np.any(q[1:] != q[:-1], axis=1)
    ids = np.empty(len(q), np.int64)
    ids[order] = np.cumsum(new) - 1
    f = ids.reshape(-1, 3)
    a, b = f.ravel(), f[:, [1, 2, 0]].ravel()
    key = np.minimum(a, b) * (int(ids.max()) + 1) + np.maximum(a, b)
    _, counts = np.unique(key, return_counts=True)
    return bool(np.all(counts == 2))


def _plane(scene, obj):
    """(unit normal, centre) of an object whose vertices all lie in one plane, else None."""
    return scene.derived(("plane", int(obj)), lambda: _fit_plane(scene, obj))


def _fit_plane(scene, obj):
    pts = scene.tri_vertices[scene.tri_object == obj].reshape(-1, 3)
    c = pts.mean(axis=0)
    _, sv, vt = np.linalg.svd(pts - c, full_matrices=False)
    return (vt[-1], c) if sv[-1] <= 1e-9 * max(sv[0], 1e-300) else None


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


class Seeder:
    """Seed chains: SMS's uniform point on a caster (the first hit must be on
    that caster), or MNEE's straight line towards the light (towards the
    caster's box centre for a reflection first)."""

    def __init__(self, scene, casters, types, method):
        self.method = method
        kinds = scene.mat_kind[scene.tri_material]
        ok_kind = (kinds == S.DIELECTRIC) if types[0] == "T" else ((kinds == S.CONDUCTOR) | (kinds == S.DIELECTRIC))
        self.tris = np.flatnonzero(casters[scene.tri_object] & ok_kind)
        v = scene.tri_vertices[self.tris]
        self.cdf = np.cumsum(triangle_areas(v))
        self.total = float(self.cdf[-1]) if len(self.cdf) else 0.0
        self.v = v
        self.obj = scene.tri_object[self.tris]
        self.reflect_first = types[0] == "R"
        self.types = types
        # planar casters: a one-vertex chain needs the receiver and the light on the
        # same side (R) or on opposite sides (T) of the plane, which culls lanes up front
        self.planes = None
        if len(types) == 1:
            planes = [_plane(scene, o) for o in np.unique(self.obj)]
            self.planes = None if any(p is None for p in planes) else planes
        objs = np.unique(self.obj)
        self.centers = np.array([np.mean(scene.object_bounds(o), axis=0) for o in objs]).reshape(-1, 3)
        self.center_obj = objs

    def feasible(self, x0, light: LightEnd, margin):
        """Lanes that can have a solution at all (always True unless every eligible
        caster is planar and the receiver/light sides rule it out)."""
        if not self.planes:
            return np.ones(len(x0), bool)
        ok = np.zeros(len(x0), bool)
        for nrm, c in self.planes:
            a = dot(x0 - c, nrm)
            b = dot(light.y, nrm) if light.directional else dot(light.y - c, nrm)
            straddle = np.abs(b) <= (0 if light.directional else margin)
            same = (a > 0) == (b > 0)
            ok |= straddle | (same if self.types == "R" else ~same)
        return ok

    def directions(self, rng, x0, light: LightEnd, ctx):
        n = len(x0)
        if self.method == "mnee":
            if self.reflect_first:  # a mirror is not on the line to the light: aim at its box centre
                k = rng.integers(len(self.centers), size=n) if len(self.centers) > 1 else np.zeros(n, int)
                # the pick counts only solutions on the caster it aimed at (weight K): a seed
                # that lands on another caster, or on a coincident copy, is that caster's
                return normalize(self.centers[k] - x0), self.center_obj[k]
            if light.directional:
                return light.y.copy(), None
            return normalize(light.y - x0), None
        q, t = area_points(self.v, self.cdf, self.total, n, rng)
        return normalize(q - x0), self.obj[t]

    def seed(self, ctx, rng, types, x0, ng0, light):
        """Seed chains (a seed off the caster it aimed at ends as SEED_OBJECT)."""
        d, want_obj = self.directions(rng, x0, light, ctx)
        return propagate(ctx, x0, ng0, d, types, want_obj)


def _walk(ctx, opts, seeder, types, x0, ng0, light, rng):
    """Seed and walk (in one kernel call per block of lanes: walk.newton_walk); the statistics
    count these primary walks (the paper's SR and mpp), Bernoulli re-walks apart."""
    d, want_obj = seeder.directions(rng, x0, light, ctx)
    large_ok = rng.random(len(x0)) >= opts.walk.defensive if opts.walk.smbs else None
    res = newton_walk(ctx, opts.walk, types, x0, ng0, light, large_ok=large_ok, seed=(d, want_obj))
    st = ctx.stats
    st["walks"] = st.get("walks", 0) + len(x0)
    st["successes"] = st.get("successes", 0) + int(res.converged.sum())
    st["mutations"] = st.get("mutations", 0) + int(res.mutations.sum())
    lm = st.setdefault("large_mutations", dict.fromkeys(TRIGGERS[1:], 0))
    for k, v in res.large.items():
        lm[k] += v
    oc = st.setdefault("outcomes", {})
    for code, cnt in zip(*np.unique(res.outcome, return_counts=True)):
        oc[OUTCOMES[code]] = oc.get(OUTCOMES[code], 0) + int(cnt)
    # the same per chain type: internal reflections (T R T) behave unlike a lens's T T
    bc = st.setdefault("by_chain", {}).setdefault(types, {"walks": 0, "successes": 0, "mutations": 0,
                                                          "large_mutations": 0})
    bc["walks"] += len(x0)
    bc["successes"] += int(res.converged.sum())
    bc["mutations"] += int(res.mutations.sum())
    bc["large_mutations"] += int(sum(res.large.values()))
    return res


def _contribution(ctx, li, types, rc, idx, light, chain, emit_scale=1.0):
    """Radiance estimate (without estimator weight) of converged lanes, and visibility.
    emit_scale: the light sample's pdf relative to uniform over the light."""
    scene, tracer = ctx.scene, ctx.tracer
    x0 = rc.p[idx]
    verts = chain.verts
    k = len(types)
    xk = verts[k - 1].p
    le, emit = light_end_at_solution(scene, li, light, xk)
    emit = emit * emit_scale
    etas = [scene.mat_ior[v.mat] for v in verts]
    G, okg = geometric_term(types, x0, verts, etas, le)
    d01 = normalize(verts[0].p - x0)
    ng0, ns0, w_eye = rc.ng[idx], rc.ns[idx], rc.w_eye[idx]
    side = np.sign(dot(w_eye, ng0))
    cos0 = dot(d01, ns0) * side
    ok = okg & (dot(d01, ng0) * side > 0) & (cos0 > 0)
    if scene.light_linked(li):  # Light Linking: Cycles asks it of the vertex the light leaves last
        ok &= scene.lit_by(li)[verts[k - 1].obj]
    if np.any(scene.mat_view_bump):  # bumped receivers: Cycles' shadowing of their bent normals
        cos0 = cos0 * bump_shadowing(scene, rc.mat[idx], rc.sn[idx], ns0, d01)
    T = chain_throughput(scene, types, x0, verts, le.y, le.directional, ctx.physical)
    albedo = scene.mat_color[rc.mat[idx]]
    if ctx.coated:  # under a Principled coat: Cycles' on-minus-off keeps (f_d + f_g) x the diffuse's MIS share
        albedo = albedo * coat_factor(scene, rc.mat[idx], scene.mat_color, ns0, w_eye, d01, share=ctx.first_order)
    val = rc.beta[idx] * albedo / math.pi * (np.maximum(cos0, 0) * G)[:, None] * T * emit
    ok &= val.max(axis=1) > 0
    # shadow ray from the last vertex to the light sample
    if le.directional:
        dirs, tmax = le.y, np.full(len(xk), np.inf)
    else:
        to = le.y - xk
        dist = np.sqrt(dot(to, to))
        dirs, tmax = to / np.maximum(dist, 1e-300)[:, None], dist * (1 - 1e-7)
    vis_idx = np.flatnonzero(ok)
    if vis_idx.size:
        o = tracer.spawn(xk[vis_idx], verts[k - 1].ng[vis_idx], dirs[vis_idx])
        # the ray leaving the last vertex, glossy or transmission: it passes what its kind does not meet,
        # and what does not shadow the light (Shadow Linking)
        t_far = tmax[vis_idx] - tracer.eps if le.directional else \
            shadow_tmax(scene, li, le.y[vis_idx], le.ys[vis_idx], le.yt[vis_idx], o, dirs[vis_idx],
                        dist[vis_idx], tracer.eps)
        blocked = tracer.occluded_past(o, dirs[vis_idx], t_far,
                                       S.RAY_GLOSSY if types[-1] == "R" else S.RAY_TRANSMISSION,
                                       scene.unshadowing(li))
        ctx.count("rays_shadow", vis_idx.size)
        ctx.stats["occluded"] = ctx.stats.get("occluded", 0) + int(blocked.sum())
        ok[vis_idx[blocked]] = False
    finite = np.all(np.isfinite(val), axis=1)
    ctx.stats["non_finite"] = ctx.stats.get("non_finite", 0) + int((ok & ~finite).sum())
    ok &= finite
    val = np.where(ok[:, None], val, 0.0)
    ctx.clamp_cut = None
    if ctx.clamp > 0:  # biased: caps the fold's (and G's) spikes; what is cut goes to the statistics
        lum = channel_mean(val)
        over = lum > ctx.clamp
        val[over] *= (ctx.clamp / lum[over])[:, None]
        ctx.clamp_cut = np.where(over, lum - ctx.clamp, 0.0)
    return val, ok


def _count_clamped(ctx, removed):
    """Clamp statistics: solutions cut and the luminance they lost, weighted as splatted
    (the bake divides by the number of batches, so the sum is in image units)."""
    if removed is None:
        return
    st = ctx.stats
    st["clamped"] = st.get("clamped", 0) + int((removed > 0).sum())
    st["clamped_energy"] = st.get("clamped_energy", 0.0) + float(removed.sum())


def estimate(ctx, opts, li, types, rc, rng, guide=None):
    """Per-receiver radiance (M,3) of one light and one chain type."""
    n = len(rc.p)
    out = np.zeros((n, 3))
    if n == 0 or not ctx.scene.chain_lit(li, types):  # the light's Ray Visibility leaves the chain's last ray out
        return out
    # the same for every chunk: built once per bake (its areas, cdf and planes cost ~50 ms per
    # chunk on a 131k-triangle mirror)
    seeder = ctx.scene.derived(("seeder", types, opts.method, ctx.casters.tobytes()),
                               lambda: Seeder(ctx.scene, ctx.casters, types, opts.method))
    if seeder.total <= 0:
        return out
    cap = sphere_cap(ctx.scene, li, ctx.caster_lo, ctx.caster_hi)
    light = sample_light(ctx.scene, li, n, rng, cap)
    emit_scale = 1.0 if cap is None else 0.5 * (1.0 - cap[1])  # the cap's share of the sphere's area
    x0, ng0 = rc.p, rc.ng
    # the eye side of x0 must see the light side: offset origins towards the receiver's eye side
    ng_eye = ng0 * np.sign(dot(rc.w_eye, ng0))[:, None]
    unbiased = opts.estimator == "unbiased" and opts.method != "mnee"
    M = 1 if (unbiased or opts.method == "mnee") else max(1, opts.trials)
    feasible = seeder.feasible(x0, light, 1e-9 * ctx.scale)
    ctx.stats["culled_lanes"] = ctx.stats.get("culled_lanes", 0) + int((~feasible).sum())
    # Cycles' Light Paths limits on the whole path: the camera's events before x0, x0's diffuse
    # bounce and the chain's vertices but the last (bounces.py)
    fits = Limits.of(ctx.scene).chain_fits(types, rc.prior[:, 0] + 1, rc.prior[:, 1], rc.prior[:, 2])
    if not fits.all():
        ctx.stats["light_paths_skips"] = ctx.stats.get("light_paths_skips", 0) + int((feasible & ~fits).sum())
        feasible &= fits
    rr_weight = np.ones(n)
    if guide is not None and guide.is_weak(li, types):  # the photon hand-off serves direct receivers
        weak = feasible & (rc.eye_specular == 0)
        ctx.stats["weak_skips"] = ctx.stats.get("weak_skips", 0) + int(weak.sum())
        feasible &= ~weak
    if guide is not None:  # Russian roulette outside the tiles the photon pre-pass reached
        q = guide.keep_probability(li, types, rc.rx, rc.ry, rc.eye_specular, rc.p)
        survive = rng.random(n) < q
        skipped = feasible & ~survive
        ctx.stats["guided_skips"] = ctx.stats.get("guided_skips", 0) + int(skipped.sum())
        seen_skips = int((skipped & (rc.eye_specular > 0)).sum())
        ctx.stats["guided_skips_seen"] = ctx.stats.get("guided_skips_seen", 0) + seen_skips
        feasible &= survive
        rr_weight = 1.0 / q
    lanes = np.repeat(np.flatnonzero(feasible), M)
    if lanes.size == 0:
        return out
    # primary walks from receivers seen through mirrors or glass (auto's cost of that effect)
    ctx.stats["walks_seen"] = ctx.stats.get("walks_seen", 0) + int((rc.eye_specular[lanes] > 0).sum())
    res = _walk(ctx, opts, seeder, types, x0[lanes], ng_eye[lanes], light.take(lanes), rng)
    conv = np.flatnonzero(res.converged)
    if conv.size == 0:
        return out
    chain = res.chain.take(conv)
    owner = lanes[conv]
    val, ok = _contribution(ctx, li, types, rc, owner, light.take(owner), chain, emit_scale)
    if opts.handoff > 0:
        # the fold's paths belong to the photon hand-off (bake._handoff_batch) at receivers the
        # camera sees directly, and to indirect.handoff_gather at those it sees through mirrors
        # or glass once an earlier chunk found such focusing paths there (ctx.handoff_seen);
        # what they take, this pass drops
        seen = rc.eye_specular[owner] > 0
        cand = ok & (~seen | ctx.first_order)
        if cand.any():
            di = np.flatnonzero(cand)
            ch_d = chain.take(di)
            etas = [ctx.scene.mat_ior[v.mat] for v in ch_d.verts]
            c = concentration(types, x0[owner[di]], ch_d.verts, etas, light.y[owner[di]], light.directional)
            seen_tau = max(opts.handoff, SEEN_HANDOFF_MIN)
            seen_focus = seen[di] & (c > seen_tau)
            ctx.stats["seen_focus"] = ctx.stats.get("seen_focus", 0) + int(seen_focus.sum())
            handed = di[(~seen[di] & (c > opts.handoff)) | (seen_focus & ctx.handoff_seen)]
            ok[handed] = False
            val[handed] = 0.0
            if ctx.clamp_cut is not None:
                ctx.clamp_cut[handed] = 0.0
            ctx.stats["handed_off"] = ctx.stats.get("handed_off", 0) + int(handed.size)
    val = val * rr_weight[owner][:, None]
    if opts.method == "mnee" and seeder.reflect_first:  # one caster picked uniformly per lane
        val = val * len(seeder.centers)
    cut = None if ctx.clamp_cut is None else (  # what the clamp removed from the image, with the same weights
        ctx.clamp_cut * rr_weight[owner] * rc.weight[owner]
        * (len(seeder.centers) if opts.method == "mnee" and seeder.reflect_first else 1)
        * (1.0 if ctx.film is None else ctx.film.frame_share(rc.rx[owner], rc.ry[owner])))
    d1 = normalize(chain.verts[0].p - x0[owner])
    obj1 = chain.verts[0].obj
    if not unbiased:
        # biased: each unique solution once (earlier trials win)
        keep = np.ones(conv.size, bool)
        if M > 1:
            order = np.argsort(owner, kind="stable")
            o_s, d_s, ob_s = owner[order], d1[order], obj1[order]
            for shift in range(1, M):
                same_owner = o_s[shift:] == o_s[:-shift]
                dup = same_owner & same_solution(d_s[shift:], d_s[:-shift], ob_s[shift:], ob_s[:-shift],
                                                 opts.uniqueness)
                k2 = np.ones(conv.size, bool)
                k2[shift:] = ~dup
                keep[order] &= k2
        np.add.at(out, owner[keep & ok], val[keep & ok])
        _count_clamped(ctx, None if cut is None else cut[keep & ok])
        return out
    # unbiased: 1/p by Bernoulli trials, only where the contribution is non-zero: the count is
    # that of the first trial that finds the same solution again (trials.py: each sample's trials
    # in turn inside a kernel, random numbers keyed by sample and trial)
    pend = np.flatnonzero(ok)
    own = owner[pend]
    first = bernoulli_trials(ctx, opts, seeder, types, x0[own], ng_eye[own], light.take(own), d1[pend], obj1[pend],
                             int(rng.integers(2**63)))
    done = first < opts.max_trials
    count = 1.0 + first
    capped = ~done
    ctx.stats["capped"] = ctx.stats.get("capped", 0) + int(capped.sum())
    st = ctx.stats
    st["bernoulli_lanes"] = st.get("bernoulli_lanes", 0) + int(pend.size)
    st["bernoulli_trials"] = st.get("bernoulli_trials", 0) + int(count.sum())
    st["bernoulli_trials_max"] = max(st.get("bernoulli_trials_max", 0), int(count.max()) if count.size else 0)
    # what the cap leaves out: a capped lane's weight would have exceeded max_trials, so
    # max_trials times its value is a lower bound on its share (luminance, as splatted)
    cp = pend[capped]
    st["capped_energy_min"] = st.get("capped_energy_min", 0.0) + float(
        (val[cp].mean(axis=1) * rc.weight[owner[cp]]).sum() * opts.max_trials)
    w = np.where(capped, 0.0, count)
    np.add.at(out, owner[pend], val[pend] * w[:, None])
    _count_clamped(ctx, None if cut is None else cut[pend] * w)
    return out


def manifold_chunk(scene, tracer, cam, film, plan, opts, types_list, start, n, n_batch, rng, stats_per_light,
                   eye_stats, guide=None, lights_direct=(), opts_by_light=None):
    """Eye samples start..start+n of a batch: receivers, then every light x chain type;
    for receivers seen through mirrors or glass, also the caustic light that meets more
    diffuse surfaces (indirect.gather, with these walks at every diffuse vertex);
    lights_direct: the lights whose direct light counts there (empty: none of it);
    opts_by_light: {light index: ManifoldOptions} where a light walks otherwise (method auto)."""
    rc = eye_receivers(scene, tracer, cam, film, plan, start, n, n_batch, rng, eye_stats,
                       EyePaths(min_specular=0, scale_eta=opts.physical))
    ctxs = {}
    for lp in plan.lights:
        ctx = Ctx(scene, tracer, plan, stats_per_light[lp.name])
        ctx.physical = opts.physical
        ctx.clamp = opts.clamp_g
        ctx.film = film
        ctxs[lp.index] = ctx

    def caustic(receivers):
        """Every light x chain type at these receivers, in parts of ESTIMATE_PART receivers that
        the threads take in turn (lanes.blocks), each part with its own random stream (keyed by
        one draw from the chunk's and the part's first receiver) and its own counters, added in
        part order: one thread's numpy runs beside another's walks, and the image does not
        depend on the thread count."""
        n = len(receivers.p)
        key = int(rng.integers(2**63))

        def part(a, b):
            prng = np.random.default_rng([key, a])
            sub = receivers.take(slice(a, b))
            total = np.zeros((b - a, 3))
            stats, secs = {}, {}
            for lp in plan.lights:
                t = time.perf_counter()
                ctx = ctxs[lp.index].part()
                o = opts if not opts_by_light else opts_by_light.get(lp.index, opts)
                share = plan.sample_share.get(lp.index, 1.0)
                if share < 1.0:  # a share of the receivers, at random (a stream of its own), weighed up
                    keep = np.flatnonzero(np.random.default_rng([key, a, lp.key]).random(b - a) < share)
                    thin = sub.take(keep)
                    thin.weight = thin.weight / share
                    for types in types_list:
                        total[keep] += estimate(ctx, o, lp.index, types, thin, prng, guide) / share
                else:
                    for types in types_list:
                        total += estimate(ctx, o, lp.index, types, sub, prng, guide)
                stats[lp.name], secs[lp.name] = ctx.stats, time.perf_counter() - t
            return total, stats, secs

        t0 = time.perf_counter()
        # below two parts' worth, one part: its walks split over the threads in blocks, balanced
        # lane by lane (a part and a small rest would leave a thread idle beside the part's walks)
        parts = lanes.blocks(part, n, ESTIMATE_PART if n >= 2 * ESTIMATE_PART else max(n, 1), tracer.threads)
        wall = time.perf_counter() - t0
        busy = sum(sum(p[2].values()) for p in parts)
        for _, stats, secs in parts:
            for name, st in stats.items():
                lanes.add_stats(stats_per_light[name], st)
                # each light's share of the wall time (parts of several lights run at once)
                stats_per_light[name]["time_s"] += wall * secs[name] / busy if busy > 0 else 0.0
        return np.concatenate([p[0] for p in parts]) if parts else np.zeros((0, 3))

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
    handoffs, focus = {}, set()
    rough = bool(rough_casters(scene, plan.casters).any())
    if (opts.handoff > 0 and types_list) or rough:
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
                       found=found, samples=HANDOFF_SAMPLES if types_list else UNWALKED_SAMPLES)
        for li in handoffs:
            st = ctxs[li].stats
            st["seen_handoff_paths"] = st.get("seen_handoff_paths", 0) + found.get(li, 0)
    if lights_direct:
        gather(scene, tracer, film, plan, rc_seen, rng, eye_stats, lights_direct,
               physical=opts.physical, connect=caustic, others=handoffs)


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
    if walked > 0 or gathered > 0:
        return True
    return st.get("walks", 0) == 0 and can_focus(scene, lp)


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


