"""SMBS's large mutation (Jhang & Chang 2022, Algorithms 3 and 4), per lane: GetNextDir traces a
direction backwards from the light sample through the chain's current vertices, GetRatio
interpolates between the first segment and that direction, halving while the ray misses the
bounding box of the object that holds x1.
"""
from __future__ import annotations


import numpy as np
from numba import njit

from .records import NS, OBJ, P, REFRACT
from ..core.vec3 import add3, cols3, dot1, neg3, normalize3, scale3, sub3, vertex_cols3
from .newton import smap
from ..core.jit import JIT


# ------------------------------------------------------------------ SMBS's large mutation
@njit(inline="always", **JIT)
def _ray_box(o, d, lo, hi):
    """large_mutation.ray_box for one ray."""
    tmin = -np.inf
    tmax = np.inf
    for c in range(3):
        inv = 1.0 / d[c]
        t1 = (lo[c] - o[c]) * inv
        t2 = (hi[c] - o[c]) * inv
        if t1 != t1:
            t1 = -np.inf
        if t2 != t2:
            t2 = np.inf
        near, far = min(t1, t2), max(t1, t2)
        if c == 0:
            tmin, tmax = near, far
        else:
            tmin, tmax = max(tmin, near), min(tmax, far)
    return tmax >= max(tmin, 0.0)


@njit(inline="always", **JIT)
def lane_large(i, kinds, x0, F, I, etas, ly, directional, obj_lo, obj_hi, scale, max_halvings):
    """The large mutation of lane i (see large_proposal): (direction, ok)."""
    k = kinds.shape[0]
    if directional:
        v = neg3(cols3(ly, i, 0))
    else:
        v = normalize3(sub3(vertex_cols3(F, i, k - 1, P), cols3(ly, i, 0)))
    ok = True
    for j in range(k - 1, -1, -1):
        v, okm = smap(kinds[j] == REFRACT, neg3(v), vertex_cols3(F, i, j, NS), etas[i, j])
        ok = ok and okm
    xi = cols3(x0, i, 0)
    v1 = normalize3(sub3(vertex_cols3(F, i, 0, P), xi))
    target = neg3(v)
    a = 1.0 if dot1(v1, target) < 0 else 0.5
    a = a * scale[i]
    obj = I[i, 0, OBJ]
    lo = cols3(obj_lo, obj, 0)
    hi = cols3(obj_hi, obj, 0)
    found = False
    for _ in range(max_halvings + 1):
        d = normalize3(add3(scale3(a, target), scale3(1.0 - a, v1)))
        if _ray_box(xi, d, lo, hi) and dot1(d, d) > 0:
            found = True
            break
        a *= 0.5
    if not found:
        a = 0.0
    d = normalize3(add3(scale3(a, target), scale3(1.0 - a, v1)))
    return d, ok and dot1(d, d) > 0.5


@njit(**JIT)
def large_proposal(idx, kinds, x0, F, I, etas, ly, directional, obj_lo, obj_hi, scale, max_halvings):
    """large_mutation.large_direction for lanes idx: GetNextDir back from the light through
    the chain's vertices, then GetRatio's bisection towards it until the ray from x0 meets the
    box of x1's object. Returns the direction (M,3) and ok (M,)."""
    M = idx.shape[0]
    d_out = np.zeros((M, 3))
    oks = np.zeros(M, np.bool_)
    for m in range(M):
        d, oks[m] = lane_large(idx[m], kinds, x0, F, I, etas, ly, directional, obj_lo, obj_hi, scale, max_halvings)
        d_out[m, 0], d_out[m, 1], d_out[m, 2] = d
    return d_out, oks
