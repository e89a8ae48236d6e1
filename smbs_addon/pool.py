"""The lane pool: the unbiased estimator's Bernoulli re-walks as one persistent wavefront.

A sample whose walk found a solution needs the number of independent walks (trials) it takes
to find that same solution again (estimators.py). Trials of all such samples share a pool of
lanes: a lane whose trial ends is refilled at once with the next trial of a sample that still
needs one (kernels.pool_refill), so every intersect and kernel call sees a full wavefront until
the work runs out (Laine, Karras and Aila 2013), instead of rounds of walks whose last
iterations run on a few lanes. Per round: one refill kernel, then per chain vertex one
intersect call and one kernel (walk.trace_chain), then one kernel for every lane's walk
(kernels.pool_advance: a seed starts a walk, a walk does its Newton iteration).

Trial t of sample s draws its random numbers from a counter-based hash of (key, s, t)
(kernels.keyed_uniform), and trials of a sample start in order, so each sample's first success
is the same whatever ran when and on which thread: one seed, one image.
"""
from __future__ import annotations

import numpy as np

from . import lanes
from .kernels import NF, pool_advance, pool_refill
from .walk import MIN_PART, WALK_BLOCK, _joined, kernel_config, trace_chain

POOL = 16384  # lanes
MAX_PARALLEL = 64  # trials of one sample at once (a sample found at trial t wastes those after t)


def bernoulli_trials(ctx, opts, seeder, types: str, x0, ng0, light, d1, obj1, key: int) -> np.ndarray:
    """Per sample (x0, ng0, light row), the index of the first trial (0, 1, ...) whose walk finds
    the sample's solution (first segment d1, first vertex on object obj1); opts.max_trials where
    none of the first max_trials does.

    The samples are cut into blocks of walk.WALK_BLOCK (lanes.blocks), each with a pool of its
    own, taken by the threads in turn: one block's Python work overlaps another's kernels and
    rays. Trials are keyed by the sample's index in the whole batch: the image does not depend
    on the cut, and the cut not on the thread count."""
    S = len(x0)
    if S == 0:
        return np.full(0, opts.max_trials, np.int64)

    def part(a, b):
        return _block_trials(ctx, opts, seeder, types, x0[a:b], ng0[a:b], light.take(slice(a, b)), d1[a:b],
                             obj1[a:b], key, a)

    parts = lanes.blocks(part, S, WALK_BLOCK, ctx.tracer.threads)
    st = ctx.stats
    st["bernoulli_walks"] = st.get("bernoulli_walks", 0) + sum(p[1] for p in parts)
    st["bernoulli_mutations"] = st.get("bernoulli_mutations", 0) + sum(p[2] for p in parts)
    return np.concatenate([p[0] for p in parts])


def _block_trials(ctx, opts, seeder, types: str, x0, ng0, light, d1, obj1, key: int, p0: int):
    """bernoulli_trials on one block of samples (p0: the index of its first sample in the
    batch); returns (first trials, walks, Newton steps)."""
    S = len(x0)
    first = np.full(S, opts.max_trials, np.int64)
    cfg = opts.walk
    k = len(types)
    P = int(min(POOL, S * MAX_PARALLEL))
    z3 = np.zeros((P, 3))
    lane = (z3.copy(), z3.copy(), z3.copy(), z3, z3, light.directional, np.zeros((P, k)), np.zeros(P, bool),
            ctx.obj_lo, ctx.obj_hi)
    state = (np.zeros((P, k, NF)), np.zeros((P, k, 3), np.int64), np.zeros((P, 3)), np.zeros(P), np.zeros(P, bool),
             np.zeros(P, bool), np.ones(P), np.ones(P), np.zeros(P, np.int64), np.zeros(P, np.int64),
             np.zeros(P, np.int64), np.zeros(P, bool), np.zeros(P, np.int64))
    pool = (np.zeros(P, np.int64), np.zeros(P, np.int64), np.zeros(P, np.int64), np.zeros(P, np.int64),
            np.zeros(P, np.int64))
    samples = (np.ascontiguousarray(x0, np.float64), np.ascontiguousarray(ng0, np.float64),
               np.ascontiguousarray(light.y, np.float64), first, np.zeros(S, np.int64), np.zeros(S, np.int64),
               np.arange(S), np.zeros(P, np.int64), np.array([S, 0], np.int64))
    seeds = (seeder.cdf, seeder.total, np.ascontiguousarray(seeder.v, np.float64), seeder.obj.astype(np.int64))
    cfg_t = kernel_config(ctx, cfg, types)
    d1 = np.ascontiguousarray(d1, np.float64)
    obj1 = np.asarray(obj1, np.int64)
    eps = ctx.tracer.eps
    rows, o, dirs, ul = np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, bool)
    ended, found_end = np.zeros(0, np.int64), np.zeros(0, bool)
    walks = steps = 0
    while True:
        new, o_new, d_new = pool_refill(ended, found_end, pool, lane, samples, seeds, key, p0, opts.max_trials,
                                        MAX_PARALLEL, cfg.defensive, cfg.smbs, eps)
        walks += len(new)
        seeding = np.concatenate([np.zeros(len(rows), bool), np.ones(len(new), bool)])
        rows = np.concatenate([rows, new])
        if rows.size == 0:
            break
        o, dirs = np.concatenate([o, o_new]), np.concatenate([dirs, d_new])
        ul = np.concatenate([ul, np.zeros(len(new), bool)])
        # slots in increasing order, so the kernels read the pool's arrays front to back (in the
        # order slots free up they are scattered, and a round cost twice as long from cache
        # misses); the order changes nothing else. Two sorted runs: a stable sort merges them
        order = np.argsort(rows, kind="stable")
        rows, o, dirs, ul, seeding = rows[order], o[order], dirs[order], ul[order], seeding[order]
        ch = trace_chain(ctx, lane[0][rows], o, dirs, types, seeding)

        def part(a, b, rows=rows, ch=ch, ul=ul):
            return pool_advance(rows[a:b], ch.F[a:b], ch.I[a:b], ch.status[a:b], ch.out_dir[a:b], ul[a:b], cfg_t,
                                lane, state, pool, ctx.scene.mat_ior, d1, obj1, opts.uniqueness, cfg.max_iterations)

        parts = lanes.run(part, rows.size, ctx.tracer.threads, MIN_PART)
        rows, o, dirs, ul = _joined([p[:4] for p in parts])
        ended, found_end = _joined([p[4:6] for p in parts])
        steps += sum(int(p[6]) for p in parts)
    return first, walks, steps
