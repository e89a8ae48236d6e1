"""The unbiased estimator's Bernoulli trials per lane: walks from fresh seeds until one finds the same
solution again (Zeltner et al. 2020, Algorithm 2), each trial's random numbers keyed by the lane.
"""
from __future__ import annotations


import numpy as np
from numba import njit

from ..core.jit import JIT
from .records import NF, LightRows, SeedRays, TrialJob, WalkLanes, WalkState
from .typed import TypedOnce
from .walk import walk_jobs, walk_scratch
from ..core.embree import ray_state


@TypedOnce
@njit(**JIT)
def bernoulli_lanes(rt, samples, seeds, trials, cfg, geo, directional, obj_lo, obj_hi):
    """trials.bernoulli_trials for samples (TrialSamples: x0, ng0, light point or direction, first
    segment's direction d1, first vertex's object obj1; (S, ...) each): per sample, walks from
    seeds at uniform points on the casters (CasterSeeds: the casters' triangle area cdf, vertices
    and objects) one after the other until one finds the sample's solution
    (estimators.same_solution) or trials.max_trials have not (TrialSettings). Trial t of sample p
    draws from keyed_uniform(trials.key, trials.p0 + p, t, .): each sample's first success does
    not depend on which thread or block runs it. cfg: WalkSettings, geo: Geometry. Returns the
    first successful trial per sample (max_trials: none), the walks and Newton steps made, and
    the ray counters (embree.ray_state)."""
    k = cfg.kinds.shape[0]
    z3 = np.zeros((1, 3))
    lane = WalkLanes(z3.copy(), z3.copy(), LightRows(z3.copy(), z3, z3, directional), np.zeros((1, k)),
                     np.ones(1, np.bool_), obj_lo, obj_hi)
    state = WalkState(np.zeros((1, k, NF)), np.zeros((1, k, 3), np.int64), np.zeros((1, 3)), np.zeros(1),
                      np.zeros(1, np.bool_), np.zeros(1, np.bool_), np.ones(1), np.ones(1), np.zeros(1, np.int64),
                      np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(1, np.bool_), np.zeros(1, np.int64))
    ray = ray_state(rt)
    work = walk_scratch(k, cfg.stall_window)
    large = np.zeros(4, np.int64)
    job = TrialJob(samples, seeds, trials, np.full(samples.x0.shape[0], trials.max_trials, np.int64),
                   np.zeros(2, np.int64))
    walk_jobs(np.bool_(True), np.bool_(True), job, cfg, geo, lane, state,
              SeedRays(np.zeros((1, 3)), np.zeros(1, np.int64)), work, ray, large)
    return job.first, job.tally[0], job.tally[1], ray.counts
