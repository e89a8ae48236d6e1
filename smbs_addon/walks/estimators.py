"""The estimator of the manifold walks: for one light and chain type, per receiver, walk from seeds
to solutions and weigh what each solution contributes (contribution.py).

- unbiased (SMS's Algorithm 2, kept by SMBS): 1/p of the found solution by geometric Bernoulli
  trials (repeat the whole seeding and walk until the same solution comes back);
- biased: the sum over the unique solutions of M walks, each with weight one (and MNEE: one walk).
"""
from __future__ import annotations


import dataclasses

import numpy as np

from ..scene.light_paths import Limits
from ..kernels.records import OUTCOMES, TRIGGERS
from ..paths.handoff import SEEN_HANDOFF_MIN
from .seeds import Seeder
from .contribution import _contribution, _count_clamped
from .trials import bernoulli_trials
from ..paths.focus import concentration
from .walk import newton_walk
from ..shading.light_samples import sample_light, sphere_cap
from ..core.qmc import LIGHT, StratifiedDraws
from ..core.vec import dot, normalize


def same_solution(d_a, d_b, obj_a, obj_b, threshold):
    """Two solutions are the same when the first segment's direction agrees and
    the first vertex lies on the same object."""
    return (np.abs(dot(d_a, d_b) - 1.0) < threshold) & (obj_a == obj_b)


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


def estimate(ctx, opts, li, types, rc, rng, guide=None):
    """_estimate's radiance, and its light at receivers seen through mirrors or glass counted."""
    out = _estimate(ctx, opts, li, types, rc, rng, guide)
    _count_seen(ctx, rc, out)
    return out


def _estimate(ctx, opts, li, types, rc, rng, guide=None):
    """Per-receiver radiance (M,3) of one light and one chain type at receivers rc: light samples,
    the lanes worth a walk, the walks, what their solutions contribute, the focusing paths left to
    the photon hand-off, and the estimator's weights (unbiased: Bernoulli trials; biased: each unique
    solution once)."""
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
    # stratified per film cell where the receivers carry their light samples' uniforms
    light = sample_light(ctx.scene, li, n, rng if rc.strata is None else StratifiedDraws(rc.strata[:, LIGHT], rng),
                         cap)
    emit_scale = 1.0 if cap is None else 0.5 * (1.0 - cap[1])  # the cap's share of the sphere's area
    # the eye side of x0 must see the light side: offset origins towards the receiver's eye side
    ng_eye = rc.ng * np.sign(dot(rc.w_eye, rc.ng))[:, None]
    unbiased = opts.estimator == "unbiased" and opts.method != "mnee"
    M = 1 if (unbiased or opts.method == "mnee") else max(1, opts.trials)
    feasible, rr_weight = _walked(ctx, li, types, rc, light, seeder, rng, guide)
    lanes = np.repeat(np.flatnonzero(feasible), M)
    if lanes.size == 0:
        return out
    # primary walks from receivers seen through mirrors or glass (auto's cost of that effect)
    ctx.stats["walks_seen"] = ctx.stats.get("walks_seen", 0) + int((rc.eye_specular[lanes] > 0).sum())
    anchor = _anchor_dir(ctx, opts, seeder, types, light)
    if anchor is not None:  # one solution found by a deterministic walk, the rest by random seeds
        lanes, rr_weight, anchored = _anchored(ctx, opts, (li, types, emit_scale), rc, ng_eye, light, anchor,
                                               (lanes, rr_weight), out, rng)
        if lanes.size == 0:  # auto's anchor alone (ManifoldOptions.anchor_only), or nothing left to walk
            return out
    res = _walk(ctx, opts, seeder, types, rc.p[lanes], ng_eye[lanes], light.take(lanes), rng)
    conv = np.flatnonzero(res.converged)
    if conv.size == 0:
        return out
    chain = res.chain.take(conv)
    owner = lanes[conv]
    val, ok = _contribution(ctx, li, types, rc, owner, light.take(owner), chain, emit_scale)
    if opts.handoff > 0:
        _drop_handed_off(ctx, opts, types, rc, owner, light, chain, val, ok)
    val = val * rr_weight[owner][:, None]
    if anchor is not None:  # the anchor's solution is counted once, by the anchor: no trials for it
        _drop_anchored(ctx, opts, anchored, rc.p[owner], owner, chain, val, ok)
    if opts.method == "mnee" and seeder.reflect_first:  # one caster picked uniformly per lane
        val = val * len(seeder.centers)
    cut = None if ctx.clamp_cut is None else (  # what the clamp removed from the image, with the same weights
        ctx.clamp_cut * rr_weight[owner] * rc.weight[owner]
        * (len(seeder.centers) if opts.method == "mnee" and seeder.reflect_first else 1)
        * (1.0 if ctx.film is None else ctx.film.frame_share(rc.rx[owner], rc.ry[owner])))
    d1 = normalize(chain.verts[0].p - rc.p[owner])
    obj1 = chain.verts[0].obj
    if not unbiased:
        _biased_sum(ctx, opts, out, owner, val, ok, d1, obj1, M, cut)
    else:
        _unbiased_sum(ctx, opts, seeder, types, rc, ng_eye, light, (out, owner, val, ok), (d1, obj1), cut, rng)
    return out


def _count_seen(ctx, rc, out) -> None:
    """The light the walks bring to receivers seen through mirrors or glass (as splatted), against
    which manifold._hand_off_seen weighs the hand-off's."""
    if ctx.first_order:
        seen = rc.eye_specular > 0
        ctx.stats["seen_energy"] = ctx.stats.get("seen_energy", 0.0) + float(
            (out[seen].mean(axis=1) * rc.weight[seen]).sum())


def _anchor_dir(ctx, opts, seeder, types, light):
    """The anchor's seed directions (N,3), towards the light, where the walks are anchored
    (ManifoldOptions.anchor: the unbiased estimator, one refraction, a distant light: water or a window
    under a sun or a world); else None. (A mirror's anchor, the light's direction mirrored in its mean
    plane, is not measured yet: mirrors walk as before.)"""
    if not (opts.anchor and opts.estimator == "unbiased" and opts.method != "mnee" and types == "T"
            and light.directional):
        return None
    return light.y


def _anchored(ctx, opts, what, rc, ng_eye, light, anchor, walked, out, rng):
    """The anchor of an unbiased estimate: per lane one walk from a fixed seed (anchor's direction,
    the walk deterministic), whose solution s* adds its contribution with weight one; the random
    walks and their Bernoulli trials then count only the other solutions (_drop_anchored), so
    sum_s f(s) = f(s*) + E[the rest] stays unbiased whatever s* the anchor finds. Where s* is the
    one solution (most of a pool), the trials never run. The random walks run on a share
    opts.anchor_walks of the lanes (Russian roulette, weight 1/share). what: (light index, chain
    type, emitter scale); walked: (lanes, rr_weight) of _walked. Adds into out; returns the lanes
    that walk from random seeds, their weights, and the anchor's solutions (owner, d1, obj1)."""
    li, types, emit_scale = what
    lanes, rr_weight = walked
    cfg = dataclasses.replace(opts.walk, beta0=1.0)
    res = newton_walk(ctx, cfg, types, rc.p[lanes], ng_eye[lanes], light.take(lanes),
                      large_ok=np.ones(len(lanes), bool), seed=(anchor[lanes], None))
    st = ctx.stats
    st["anchor_walks"] = st.get("anchor_walks", 0) + len(lanes)
    st["anchor_successes"] = st.get("anchor_successes", 0) + int(res.converged.sum())
    st["anchor_mutations"] = st.get("anchor_mutations", 0) + int(res.mutations.sum())
    conv = np.flatnonzero(res.converged)
    chain = res.chain.take(conv)
    owner = lanes[conv]
    val, ok = _contribution(ctx, li, types, rc, owner, light.take(owner), chain, emit_scale)
    if opts.handoff > 0:
        _drop_handed_off(ctx, opts, types, rc, owner, light, chain, val, ok)
    np.add.at(out, owner[ok], val[ok] * rr_weight[owner[ok]][:, None])
    # the anchor's light, against which auto weighs what the random walks add (auto.anchor_bias)
    st["anchor_energy"] = st.get("anchor_energy", 0.0) + float(
        (val[ok].mean(axis=1) * rr_weight[owner[ok]] * rc.weight[owner[ok]]).sum())
    if ctx.clamp_cut is not None:
        _count_clamped(ctx, (ctx.clamp_cut * rr_weight[owner] * rc.weight[owner] * (
            1.0 if ctx.film is None else ctx.film.frame_share(rc.rx[owner], rc.ry[owner])))[ok])
    d1 = normalize(chain.verts[0].p - rc.p[owner])
    if opts.anchor_only:
        return lanes[:0], rr_weight, (owner, d1, chain.verts[0].obj)
    share = opts.anchor_walks
    if share < 1.0:
        keep = rng.random(len(lanes)) < share
        lanes = lanes[keep]
        rr_weight = rr_weight / share
    return lanes, rr_weight, (owner, d1, chain.verts[0].obj)


def _drop_anchored(ctx, opts, anchored, x0, owner, chain, val, ok) -> None:
    """Random walks that found their lane's anchor solution (estimators.same_solution) add nothing
    and need no trials (val and ok, in place)."""
    a_owner, a_d1, a_obj = anchored
    idx = np.full(int(max(owner.max(initial=-1), a_owner.max(initial=-1))) + 1, -1, np.int64)
    idx[a_owner] = np.arange(len(a_owner))
    j = idx[owner]
    has = j >= 0
    jj = np.where(has, j, 0)
    same = np.zeros(len(owner), bool)
    if len(a_owner):
        d1 = normalize(chain.verts[0].p - x0)
        same = has & same_solution(d1, a_d1[jj], chain.verts[0].obj, a_obj[jj], opts.uniqueness)
    ok[same] = False
    val[same] = 0.0
    if ctx.clamp_cut is not None:
        ctx.clamp_cut[same] = 0.0
    ctx.stats["anchor_found_again"] = ctx.stats.get("anchor_found_again", 0) + int(same.sum())


def _walked(ctx, li, types, rc, light, seeder, rng, guide):
    """Which receivers walk: those whose light sample the casters can join (the seeder's test), within
    Cycles' Light Paths limits, not left to the photon hand-off (a weak chain type at receivers seen
    directly), and past the guide's Russian roulette. Returns (feasible (M,) bool, the roulette's
    weights 1/q)."""
    n = len(rc.p)
    feasible = seeder.feasible(rc.p, light, 1e-9 * ctx.scale)
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
    return feasible, rr_weight


def _drop_handed_off(ctx, opts, types, rc, owner, light, chain, val, ok) -> None:
    """The fold's paths belong to the photon hand-off (baking.passes.handoff_batch) at receivers the
    camera sees directly, and to indirect.handoff_gather at those it sees through mirrors or glass
    once an earlier chunk found such focusing paths there (ctx.handoff_seen); what they take, this
    pass drops (val and ok, in place)."""
    seen = rc.eye_specular[owner] > 0
    cand = ok & (~seen | ctx.first_order)
    if not cand.any():
        return
    di = np.flatnonzero(cand)
    ch_d = chain.take(di)
    etas = [ctx.scene.mat_ior[v.mat] for v in ch_d.verts]
    c = concentration(types, rc.p[owner[di]], ch_d.verts, etas, light.y[owner[di]], light.directional)
    seen_tau = max(opts.handoff, SEEN_HANDOFF_MIN)
    seen_focus = seen[di] & (c > seen_tau)
    ctx.stats["seen_focus"] = ctx.stats.get("seen_focus", 0) + int(seen_focus.sum())
    handed = di[(~seen[di] & (c > opts.handoff)) | (seen_focus & ctx.handoff_seen)]
    ok[handed] = False
    val[handed] = 0.0
    if ctx.clamp_cut is not None:
        ctx.clamp_cut[handed] = 0.0
    ctx.stats["handed_off"] = ctx.stats.get("handed_off", 0) + int(handed.size)


def _biased_sum(ctx, opts, out, owner, val, ok, d1, obj1, M, cut) -> None:
    """The biased estimator: each unique solution of a receiver's M walks once (earlier trials win),
    added into out."""
    keep = np.ones(len(owner), bool)
    if M > 1:
        order = np.argsort(owner, kind="stable")
        o_s, d_s, ob_s = owner[order], d1[order], obj1[order]
        for shift in range(1, M):
            same_owner = o_s[shift:] == o_s[:-shift]
            dup = same_owner & same_solution(d_s[shift:], d_s[:-shift], ob_s[shift:], ob_s[:-shift],
                                             opts.uniqueness)
            k2 = np.ones(len(owner), bool)
            k2[shift:] = ~dup
            keep[order] &= k2
    np.add.at(out, owner[keep & ok], val[keep & ok])
    _count_clamped(ctx, None if cut is None else cut[keep & ok])


def _unbiased_sum(ctx, opts, seeder, types, rc, ng_eye, light, found, first_dir, cut, rng) -> None:
    """The unbiased estimator: 1/p by Bernoulli trials, only where the contribution is non-zero: the
    count is that of the first trial that finds the same solution again (trials.py: each sample's
    trials in turn inside a kernel, random numbers keyed by sample and trial). found: (out, owner,
    val, ok), out added into; first_dir: (d1, obj1), each solution's first direction and object."""
    out, owner, val, ok = found
    d1, obj1 = first_dir
    pend = np.flatnonzero(ok)
    own = owner[pend]
    first = bernoulli_trials(ctx, opts, seeder, types, rc.p[own], ng_eye[own], light.take(own), d1[pend], obj1[pend],
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
    # what the random walks add, per lane as splatted (under an anchor: the other solutions' light,
    # whose mean and spread bound the anchor-alone estimator's bias: auto.anchor_bias)
    e = val[pend].mean(axis=1) * w * rc.weight[owner[pend]]
    st["walk_energy"] = st.get("walk_energy", 0.0) + float(e.sum())
    st["walk_energy_sq"] = st.get("walk_energy_sq", 0.0) + float((e * e).sum())
    _count_clamped(ctx, None if cut is None else cut[pend] * w)
