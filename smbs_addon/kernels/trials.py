"""The unbiased estimator's Bernoulli trials per lane: walks from fresh seeds until one finds the same
solution again (Zeltner et al. 2020, Algorithm 2), each trial's random numbers keyed by the lane.
"""
from __future__ import annotations


import numpy as np
from numba import njit

from ..core.jit import JIT
from .records import NF
from .typed import TypedOnce
from .walk import walk_jobs, walk_scratch
from ..core.embree import ray_state


@TypedOnce
@njit(**JIT)
def bernoulli_lanes(rt, samples, seeds, trials, cfg, geo, directional, obj_lo, obj_hi):
    """trials.bernoulli_trials for samples (x0, ng0, light point or direction, first segment's
    direction d1, first vertex's object obj1; (S, ...) each): per sample, walks from seeds at
    uniform points on the casters (seeds: the casters' triangle area cdf, vertices and objects)
    one after the other until one finds the sample's solution (estimators.same_solution) or
    max_trials have not. trials: (the cdf's total, key, p0 (the index of the first sample in the
    batch), max_trials, SMBS's defensive share, uniqueness threshold). Trial t of sample p draws
    from keyed_uniform(key, p0 + p, t, .): each sample's first success does not depend on which
    thread or block runs it. Returns the first successful trial per sample (max_trials: none),
    the walks and Newton steps made, and the ray counters (embree.ray_state)."""
    k = cfg[1].shape[0]
    z3 = np.zeros((1, 3))
    lane = (z3.copy(), z3.copy(), z3.copy(), z3, z3, directional, np.zeros((1, k)), np.ones(1, np.bool_),
            obj_lo, obj_hi)
    state = (np.zeros((1, k, NF)), np.zeros((1, k, 3), np.int64), np.zeros((1, 3)), np.zeros(1),
             np.zeros(1, np.bool_), np.zeros(1, np.bool_), np.ones(1), np.ones(1), np.zeros(1, np.int64),
             np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(1, np.bool_), np.zeros(1, np.int64))
    ray = ray_state(rt)
    scratch, proposal = walk_scratch(k, cfg[17])
    large = np.zeros(4, np.int64)
    first = np.full(samples[0].shape[0], trials[3], np.int64)
    tally = np.zeros(2, np.int64)
    walk_jobs(np.bool_(True), np.bool_(True), samples, seeds, trials, cfg, geo, lane, state, scratch, proposal, ray,
               large, first, tally, np.zeros((1, 3)), np.zeros(1, np.int64))
    return first, tally[0], tally[1], ray[6]
