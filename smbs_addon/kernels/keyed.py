"""Keyed random numbers inside compiled code: a uniform number from (key, a, b, dimension) alone, so
a lane draws the same numbers whichever thread runs it and whatever else runs.
"""
from __future__ import annotations


import numpy as np
from numba import njit

from ..core.jit import JIT


# ------------------------------------------------------------------ Bernoulli trials
_GOLD = np.uint64(0x9E3779B97F4A7C15)


_M1 = np.uint64(0xBF58476D1CE4E5B9)


_M2 = np.uint64(0x94D049BB133111EB)


@njit(**JIT)
def _mix64(z):
    """splitmix64's finaliser (Steele, Lea and Flood 2014)."""
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


@njit(**JIT)
def _keyed_bits(key, a, b, dim):
    """64 random bits that depend only on (key, a, b, dim)."""
    z = _mix64(np.uint64(key) + _GOLD * np.uint64(a + 1))
    z = _mix64(z + _GOLD * np.uint64(b + 1))
    return _mix64(z + _GOLD * np.uint64(dim + 1))


@njit(**JIT)
def keyed_uniform(key, a, b, dim):
    """A uniform number in [0, 1) that depends only on (key, a, b, dim): counter-based, so a
    trial's random numbers do not depend on when or on which thread it runs."""
    return np.float64(_keyed_bits(key, a, b, dim) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


_SALT = np.uint64(0xD1B54A32D192ED03)


@njit(**JIT)
def keyed_uniform3(key, a, b, dim):
    """keyed_uniform(key, a, b, dim) and two more uniform numbers (32 bits each, from the bits of a
    salted key) for a specular vertex: the lobe, then a rough surface's microfacet normal
    (optics.scatter1). The first is the number a smooth vertex always drew, so its paths stay."""
    z = _keyed_bits(np.uint64(key) + _SALT, a, b, dim)
    lo = np.float64(z & np.uint64(0xFFFFFFFF)) * (1.0 / 4294967296.0)
    hi = np.float64(z >> np.uint64(32)) * (1.0 / 4294967296.0)
    return keyed_uniform(key, a, b, dim), lo, hi
