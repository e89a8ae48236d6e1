"""A glass's absorption (Volume Absorption inside it): what a path keeps crossing it, per lane and
over arrays.
"""
from __future__ import annotations

import math

from numba import njit

from ..scene.arrays import DIELECTRIC
from ..core.vec3 import dot1
from ..core.jit import JIT


@njit(**JIT)
def absorbed1(kinds, a, medium, m_hit, d, g_hit, t, b):
    """b after a segment of length t along d inside a glass: medium (the glass it left into, -1:
    none), else the glass of material m_hit if d arrives at its back (the segment began inside it:
    a path from a receiver under water); times exp(-absorption t) (optics.transmittance; kinds,
    a: optics.MaterialTables' kind and absorb, Scene.mat_absorb; the two arrays, not the whole
    tuple, which numba would copy into every call)."""
    if medium < 0 and kinds[m_hit] == DIELECTRIC and dot1(d, g_hit) > 0:
        medium = m_hit
    if medium < 0:
        return b
    if a[medium, 0] == 0.0 and a[medium, 1] == 0.0 and a[medium, 2] == 0.0:  # clear glass
        return b
    return (b[0] * math.exp(-a[medium, 0] * t), b[1] * math.exp(-a[medium, 1] * t),
            b[2] * math.exp(-a[medium, 2] * t))


@njit(**JIT)
def medium_after1(m, kind, dd, g):
    """The medium a path is in leaving a vertex of material m along dd (optics.inside)."""
    return m if kind == DIELECTRIC and dot1(dd, g) < 0 else -1
