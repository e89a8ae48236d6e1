"""The unbiased estimator's Bernoulli trials: how many walks it takes to find a solution again.

A sample whose walk found a solution needs the number of independent walks (trials) it takes
to find that same solution again (estimators.py). trials.bernoulli_lanes runs a sample's
trials one after the other, each a whole walk from a fresh seed with its rays cast inside the
kernel, until one finds the solution: no trial runs that the sample turns out not to need.
The samples are cut into blocks of TRIAL_BLOCK that the threads take in turn (lanes.blocks),
shrinking to TRIAL_BLOCK_MIN towards the end: a sample's trial count is heavy-tailed (thousands
on a hammered mirror), and with blocks of 128 to the end one thread was often left with the
last heavy block (hammered mirror 48^2 SMS: cpu/wall 1.57; shrinking blocks: 1.92).

Trial t of sample s draws its random numbers from a counter-based hash of (key, s, t)
(keyed.keyed_uniform), so each sample's first success does not depend on the cut, the
thread or the order: one seed, one image.

(Until issue 11's kernels called embree themselves, the trials ran as a lane pool: one
wavefront of 16384 lanes, refilled with the next trial of a sample that still needed one, so
that every numpy and embree call from Python saw many lanes; with no calls from Python per
ray, the pool's bookkeeping and its speculative trials cost more than they saved.)
"""
from __future__ import annotations

import numpy as np

from ..core import embree, lanes
from ..kernels.records import CasterSeeds, TrialSamples, TrialSettings
from ..kernels.trials import bernoulli_lanes
from .walk import count_rays, kernel_config, walk_geometry

TRIAL_BLOCK = 128  # samples per block, shrinking towards TRIAL_BLOCK_MIN at the end (lanes.block_edges)
TRIAL_BLOCK_MIN = 8


def bernoulli_trials(ctx, opts, seeder, types: str, x0, ng0, light, d1, obj1, key: int) -> np.ndarray:
    """Per sample (x0, ng0, light row), the index of the first trial (0, 1, ...) whose walk finds
    the sample's solution (first segment d1, first vertex on object obj1); opts.max_trials where
    none of the first max_trials does. Trials are keyed by the sample's index in the whole
    batch: the image does not depend on the cut, and the cut not on the thread count."""
    S = len(x0)
    first = np.full(S, opts.max_trials, np.int64)
    if S == 0:
        return first
    f64 = lambda a: np.ascontiguousarray(a, np.float64)  # noqa: E731
    samples = TrialSamples(f64(x0), f64(ng0), f64(light.y), f64(d1), np.ascontiguousarray(obj1, np.int64))
    seeds = CasterSeeds(seeder.cdf, f64(seeder.v), seeder.obj.astype(np.int64))
    cfg_t, geo, tracer = kernel_config(ctx, opts.walk, types), walk_geometry(ctx), ctx.tracer

    def part(a, b):
        rt = tracer.rays()
        trials = TrialSettings(seeder.total, key, a, opts.max_trials, opts.walk.defensive, opts.uniqueness)
        first[a:b], walks, steps, counts = bernoulli_lanes(
            rt, TrialSamples(*(x[a:b] for x in samples)), seeds, trials, cfg_t, geo, light.directional, ctx.obj_lo,
            ctx.obj_hi)
        tracer.cast_by_kernel(rt, counts)
        return walks, steps, counts

    parts = lanes.blocks(part, S, TRIAL_BLOCK, tracer.threads, TRIAL_BLOCK_MIN, whole=True)
    count_rays(ctx, sum((p[2] for p in parts), embree.counters()))
    st = ctx.stats
    st["bernoulli_walks"] = st.get("bernoulli_walks", 0) + sum(int(p[0]) for p in parts)
    st["bernoulli_mutations"] = st.get("bernoulli_mutations", 0) + sum(int(p[1]) for p in parts)
    return first
