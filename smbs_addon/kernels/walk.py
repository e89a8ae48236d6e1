"""The manifold walk per lane, from its seed to its outcome: small mutations (the Newton step, beta
halved on rejection, doubled on acceptance), SMBS's large mutations where a trigger fires (total
internal reflection, a back-lit vertex, slow progress), and the walk's bookkeeping.
"""
from __future__ import annotations


import math

import numpy as np
from numba import njit

from .records import (
    CasterSeeds, ChainRows, MAT, MAX_ITER, NF, NS, OBJ, OK, P, RAYS_WALK, REFLECT, SIDE, SINGULAR, STALLED, TIR,
    TRIG_BACKLIT, TRIG_NONE, TRIG_SLOW, TRIG_TIR, TrialJob, TrialSamples, TrialSettings, WalkScratch)
from .typed import TypedOnce
from .newton import copy_rows, lane_newton, lane_scratch
from .large_mutation import lane_large
from .chain import lane_mismatch, seed_lane, spawn1, trace_lane
from ..core.vec3 import add3, cols3, dot1, normalize3, sub3, vertex_cols3
from ..core.embree import ray_state
from ..core.jit import JIT, LANES
from .keyed import keyed_uniform


@njit(inline="always", **JIT)
def _lane_trigger(i, kinds, backlit_at, backlit_on, x0, F, ly, directional, pending):
    """SMBS's trigger of lane i (trigger 2, back-lit, at chain vertex j = backlit_at: for a
    reflection, the vertex before it (x0 for j = 0) and the light on different sides of its
    surface; for a refraction, on the same side; walk.WalkConfig.backlit_vertex); clears pending."""
    tr = pending[i]
    if backlit_on and tr == TRIG_NONE and backlit_at >= 0:
        j = backlit_at
        pj = vertex_cols3(F, i, j, P)
        nj = vertex_cols3(F, i, j, NS)
        prev = cols3(x0, i, 0) if j == 0 else vertex_cols3(F, i, j - 1, P)
        to_light = cols3(ly, i, 0) if directional else sub3(cols3(ly, i, 0), pj)
        a = dot1(sub3(prev, pj), nj) > 0
        b = dot1(to_light, nj) > 0
        if (a != b) if kinds[j] == REFLECT else (a == b):
            tr = TRIG_BACKLIT
    pending[i] = TRIG_NONE
    return tr


@njit(**JIT)
def backlit_lanes(kinds, backlit_at, x0, F, ly, directional):
    """_lane_trigger's back-lit test on every lane (walk.backlit)."""
    n = F.shape[0]
    out = np.zeros(n, np.bool_)
    pending = np.zeros(n, np.int64)
    for i in range(n):
        out[i] = _lane_trigger(i, kinds, backlit_at, True, x0, F, ly, directional, pending) == TRIG_BACKLIT
    return out


@njit(**JIT)
def _spawn_aim1(x0, g, d, target, eps):
    """tracer.spawn of x0 (normal g) towards d, and the unit direction from there to target."""
    on = spawn1(x0, g, d, eps)
    return on, normalize3(sub3(target, on))


@njit(inline="always", **JIT)
def _lane_update(m, i, prop, e, f, ul, cfg, state):
    """walk.newton_walk's acceptance of proposal row m (of the chain prop, ChainRows; mismatch
    e, f, large or not ul) for lane i (of state, WalkState; cfg: WalkSettings), and its state
    updates: the accepted chain, the mismatch, beta (doubled on acceptance, halved on rejection,
    1 after a large mutation), SMBS's bisection scale and triggers 1 (a large mutation into TIR
    moves the chain) and 3 (slow small steps in a row). Returns whether the lane walks on (a lane
    whose beta fell below cfg.min_beta is stuck: outcome MAX_ITER)."""
    nF, nI, nstatus, nout = prop.F, prop.I, prop.status, prop.out_dir
    smbs, tir_on = cfg.smbs, cfg.tir
    err, beta, lscale, pending, slow_n = state.err, state.beta, state.lscale, state.pending, state.slow_n
    st = nstatus[m]
    okp = st == OK or st == SIDE
    accept = okp and (ul or e < err[i])
    if ul and st == TIR and tir_on:
        # a large mutation that ends in total internal reflection still moves the chain
        accept = True
        e, f = np.inf, False
        pending[i] = TRIG_TIR
    if accept:
        out_dir = state.out_dir
        copy_rows(state.F, i, nF, m)
        copy_rows(state.I, i, nI, m)
        out_dir[i, 0], out_dir[i, 1], out_dir[i, 2] = nout[m, 0], nout[m, 1], nout[m, 2]
    if smbs and cfg.slow:
        slow = okp and not ul and e > cfg.tau * err[i]
        slow_n[i] = slow_n[i] + 1 if slow else 0
        if slow and slow_n[i] >= cfg.slow_run:
            slow_n[i] = 0
            pending[i] = TRIG_SLOW
    if accept:
        err[i], state.front[i] = e, f
        state.valid[i] = st == OK
        beta[i] = min(1.0, 2.0 * beta[i])
        if ul:
            beta[i] = 1.0
            lscale[i] = 1.0
        return True
    if ul:
        lscale[i] *= 0.5
    beta[i] *= 0.5
    if smbs and tir_on and cfg.tir_rejected and st == TIR:
        pending[i] = TRIG_TIR
    if beta[i] < cfg.min_beta:
        state.outcome[i] = MAX_ITER
        return False
    return True


@njit(inline="always", **LANES)
def _walk_lane(i, cfg, geo, lane, state, work, ray, large):
    """walk.newton_walk of lane i (row i of lane and state) from the seed chain in its row of
    state (F, I, out_dir, and its walk outcome in outcome): the set-up (etas of the seed's
    vertices, the mismatch, beta 1; a seed whose last refraction is TIR starts with a large
    mutation), then per iteration the acceptance of the last proposal (_lane_update), the
    convergence test, MAX_ITER at the last iteration, the small mutation (lane_newton), SMBS's
    trigger and large mutation (_lane_trigger, lane_large; large[trigger] counts them), the
    singular test, and the proposal's chain (trace_lane into row 0 of work.proposal). cfg:
    WalkSettings, geo: Geometry, lane: WalkLanes, state: WalkState, work: WalkScratch. Inlined, at
    its one call in walk_jobs: a call per walk passed some 50 arrays field by field (7-8% of a
    ring's walk time in pushes onto the stack)."""
    kinds, smbs, tir_on, stall_window = cfg.kinds, cfg.smbs, cfg.tir, cfg.stall_window
    x0, light, etas, large_ok = lane.x0, lane.light, lane.etas, lane.large_ok
    ly, directional = light.y, light.directional
    F, I, out_dir, err, front, valid = state.F, state.I, state.out_dir, state.err, state.front, state.valid
    beta, lscale, pending, slow_n = state.beta, state.lscale, state.pending, state.slow_n
    outcome, converged, mutations = state.outcome, state.converged, state.mutations
    prop, hist = work.proposal, work.hist
    mat_ior = geo.mat_ior
    k = kinds.shape[0]
    st = outcome[i]
    for j in range(k):
        etas[i, j] = mat_ior[I[i, j, MAT]]
    err[i], front[i] = lane_mismatch(F, i, out_dir, ly, i, directional)
    valid[i] = st == OK  # a lane converges only from a valid chain
    beta[i] = cfg.beta0
    # SMBS: GetRatio's bisection, carried on across iterations: a large mutation whose ray missed
    # the caster (or failed otherwise) would repeat itself exactly from the same vertex, so the
    # next one from there starts at half the weight; an accepted one resets it
    lscale[i] = 1.0
    pending[i] = TRIG_NONE  # SMBS: the trigger for the next step
    slow_n[i] = 0  # slow small steps in a row
    converged[i] = False
    mutations[i] = 0
    walkable = st == OK or st == SIDE  # an exit below the surface is walkable, not yet valid
    if walkable:
        outcome[i] = OK
    if smbs and tir_on and st == TIR and large_ok[i]:  # a seed whose last refraction is TIR mutates first
        pending[i] = TRIG_TIR
        err[i] = np.inf
        front[i] = False
        outcome[i] = OK
        walkable = True
    if not walkable:
        return
    xi = cols3(x0, i, 0)
    gi = cols3(lane.ng0, i, 0)
    ul = False
    # a walk that cannot mutate large (SMS, MNEE, SMBS's defensive lanes) gives up when its last
    # stall_window steps shrank the mismatch by less than stall_factor (from step stall_from on)
    stalls = stall_window > 0 and not (smbs and large_ok[i])
    for it in range(cfg.max_iterations + 1):
        if it > 0:
            e, f = lane_mismatch(prop.F, 0, prop.out_dir, ly, i, directional)
            if not _lane_update(0, i, prop, e, f, ul, cfg, state):
                return
        if err[i] < cfg.threshold and front[i] and valid[i]:
            converged[i] = True
            return
        if stalls:
            if it >= cfg.stall_from and err[i] > cfg.stall_factor * hist[it % stall_window]:
                outcome[i] = STALLED
                return
            hist[it % stall_window] = err[i]
        if it == cfg.max_iterations:
            outcome[i] = MAX_ITER
            return
        ok, p, d = lane_newton(i, cfg.hv, kinds, x0, F, etas, light, beta, cfg.max_step, work.newton)
        ul = False
        if smbs:
            tr = _lane_trigger(i, kinds, cfg.backlit_at, cfg.backlit, x0, F, ly, directional, pending)
            if tr != TRIG_NONE and large_ok[i]:
                dl, okl = lane_large(i, kinds, x0, F, I, etas, ly, directional, lane.obj_lo, lane.obj_hi, lscale,
                                      cfg.max_halvings)
                if okl:
                    ul = True
                    d = dl
                    p = add3(xi, dl)
                    large[tr] += 1
        if not (ok or ul):
            outcome[i] = SINGULAR
            return
        mutations[i] += 1
        on, w = _spawn_aim1(xi, gi, d, p, cfg.eps)
        trace_lane(ray, np.int64(RAYS_WALK), np.int64(0), xi, on, w, kinds, geo, cfg.eps, prop)


@njit(inline="always", **JIT)
def walk_scratch(k, stall_window):
    """The work arrays of one thread's walks (WalkScratch): the constraint blocks and solve
    (lane_scratch), one proposal chain (ChainRows) and the last stall_window mismatches of a walk."""
    return WalkScratch(lane_scratch(k), ChainRows(np.zeros((1, k, NF)), np.zeros((1, k, 3), np.int64),
                                                  np.zeros(1, np.int64), np.zeros((1, 3))),
                       np.zeros(max(stall_window, 1)))


@TypedOnce
@njit(**JIT)
def walk_lanes(rt, seeded, seeds, cfg, geo, lane, state):
    """walk.newton_walk of every lane, one after the other, each from its seed to its outcome
    with every ray cast here: seeded, from the seed chains in state (F, I, out_dir, outcome);
    else from seed rays (seeds: SeedRays; a chain whose first vertex is off seeds.want[i] >= 0
    ends as SEED_OBJECT, as trace_lanes). cfg (WalkSettings: walk.kernel_config), geo (Geometry),
    lane (WalkLanes) and state (WalkState): see walk.newton_walk. Returns the large mutations per
    trigger (4,) and the ray counters (embree.ray_state)."""
    ray = ray_state(rt)
    work = walk_scratch(cfg.kinds.shape[0], cfg.stall_window)
    large = np.zeros(4, np.int64)
    z3, zi = np.zeros((0, 3)), np.zeros(0, np.int64)  # bernoulli_lanes' job, unused here
    job = TrialJob(TrialSamples(z3, z3, z3, z3, zi), CasterSeeds(np.zeros(0), np.zeros((0, 3, 3)), zi),
                   TrialSettings(0.0, np.int64(0), np.int64(0), np.int64(0), 0.0, 0.0), zi, np.zeros(2, np.int64))
    # (np.bool_: a literal True or False would compile walk_jobs once per value)
    walk_jobs(np.bool_(False), seeded, job, cfg, geo, lane, state, seeds, work, ray, large)
    return large, ray.counts


@njit(**LANES)
def walk_jobs(trial, seeded, job, cfg, geo, lane, state, seeds, work, ray, large):
    """The walks of walk_lanes (trial False: every lane of lane and state, from its seed chain
    where seeded, else from a seed ray in direction seeds.d[i], seeds.want[i] its object; job
    unused) and of bernoulli_lanes (trial True: the trials of job's samples (TrialJob) in the one
    row of lane and state, seeds that row's seed ray; job.first and job.tally written) in one
    loop, so that the walk (_walk_lane) is inlined at one call and compiled once. The caller
    holds the arrays."""
    x0, ng0, ly, large_ok = lane.x0, lane.ng0, lane.light.y, lane.large_ok
    F, I, outcome, converged, mutations = state.F, state.I, state.outcome, state.converged, state.mutations
    seed_rows = ChainRows(F, I, outcome, state.out_dir)
    kinds, smbs, eps = cfg.kinds, cfg.smbs, cfg.eps
    samples, cdf, tv, tobj = job.samples, job.seeds.cdf, job.seeds.tv, job.seeds.obj
    sx0, sng, sly, d1, obj1 = samples.x0, samples.ng0, samples.y, samples.d1, samples.obj1
    total, key, p0 = job.settings.total, job.settings.key, job.settings.p0
    max_trials, defensive, uniqueness = job.settings.max_trials, job.settings.defensive, job.settings.uniqueness
    first, tally = job.first, job.tally
    d, want = seeds.d, seeds.want
    row = x0.shape[0] - 1  # trial: the one row of lane and state (not a literal 0: one compiled walk)
    n = sx0.shape[0] if trial else x0.shape[0]
    if trial and max_trials <= 0:
        return
    p = t = 0  # the lane (trial: the sample) and its trial
    while p < n:
        i = p
        if trial:
            i = row
            if t == 0:
                for c in range(3):
                    x0[row, c], ng0[row, c], ly[row, c] = sx0[p, c], sng[p, c], sly[p, c]
            # trial t of sample p: a seed aimed at a uniform point on the casters (manifold.Seeder
            # for SMS), its random numbers keyed by (key, p0 + p, t)
            u0 = keyed_uniform(key, p0 + p, t, 0)
            u1 = keyed_uniform(key, p0 + p, t, 1)
            u2 = keyed_uniform(key, p0 + p, t, 2)
            tri = min(np.searchsorted(cdf, u0 * total, side="right"), cdf.shape[0] - 1)
            su = math.sqrt(u1)
            b0, b1, b2 = 1 - su, su * (1 - u2), su * u2
            q = (b0 * tv[tri, 0, 0] + b1 * tv[tri, 1, 0] + b2 * tv[tri, 2, 0],
                 b0 * tv[tri, 0, 1] + b1 * tv[tri, 1, 1] + b2 * tv[tri, 2, 1],
                 b0 * tv[tri, 0, 2] + b1 * tv[tri, 1, 2] + b2 * tv[tri, 2, 2])
            dq = normalize3(sub3(q, cols3(x0, row, 0)))
            d[row, 0], d[row, 1], d[row, 2] = dq
            want[row] = tobj[tri]
            large_ok[row] = keyed_uniform(key, p0 + p, t, 3) >= defensive if smbs else True
        if trial or not seeded:
            seed_lane(ray, i, x0, ng0, seeds, kinds, geo, eps, seed_rows)
        _walk_lane(i, cfg, geo, lane, state, work, ray, large)
        if not trial:
            p += 1
            continue
        tally[0] += 1
        tally[1] += mutations[row]
        found = False
        if converged[row]:
            d2 = normalize3(sub3(vertex_cols3(F, row, 0, P), cols3(x0, row, 0)))
            found = abs(dot1(d2, cols3(d1, p, 0)) - 1.0) < uniqueness and I[row, 0, OBJ] == obj1[p]
        if found:
            first[p] = t
        t += 1
        if found or t == max_trials:
            p += 1
            t = 0
