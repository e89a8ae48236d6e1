"""A ray's next surface from inside compiled code: hit or miss, the hit re-computed in float64, and
the surfaces of objects a ray's kind does not meet (Ray Visibility) passed.
"""
from __future__ import annotations


import numpy as np
from numba import njit

from ..core.jit import JIT


from .records import HIDDEN_PASSES
from ..core.vec3 import sub3
from .chain import barycentric1, hit_point, shading_normal1, spawn1
from ..core.embree import intersect1
@njit(inline="always", **JIT)
def hit_or_miss(ray, o, d, tv, tng, eps):
    """The closest hit of the ray o + t d (cast here, kind 0): (primitive, -1 on a miss; the float64
    distance, inf on a miss; hit_point's point, unit geometric normal, corner 0, edges 1 and 2)."""
    pr, t32 = intersect1(ray, o, d, np.inf, 0)
    if pr < 0:
        z = (0.0, 0.0, 0.0)
        return pr, np.inf, z, z, z, z, z
    t, p, g, v0, e1, e2 = hit_point(o, d, o, False, t32, pr, tv, tng, eps)
    return pr, t, p, g, v0, e1, e2


@njit(inline="always", **JIT)
def hit_or_miss_past(ray, o, d, tv, tng, tri_object, hid, bit, eps):
    """hit_or_miss past the surfaces of objects a ray of kind bit (a scene.RAY_* bit) does not meet
    (hid: (O,) the kinds each object does not meet, Scene.hidden_kinds; empty: none), up to
    HIDDEN_PASSES of them (then a miss); each next hit re-computed on the line from o (tracer.intersect's
    exact_origin), t from o."""
    pr, t, p, g, v0, e1, e2 = hit_or_miss(ray, o, d, tv, tng, eps)
    k = 0
    while hid.shape[0] > 0 and pr >= 0 and hid[tri_object[pr]] & bit:
        if k == HIDDEN_PASSES:
            pr = -1
            break
        ob = spawn1(p, g, d, eps)  # tracer.spawn
        pr, t32 = intersect1(ray, ob, d, np.inf, 0)
        if pr >= 0:
            t, p, g, v0, e1, e2 = hit_point(ob, d, o, True, t32, pr, tv, tng, eps)
        k += 1
    if pr < 0:
        z = (0.0, 0.0, 0.0)
        return pr, np.inf, z, z, z, z, z
    return pr, t, p, g, v0, e1, e2


@njit(inline="always", **JIT)
def next_past(ray, o, d, tv, tng, tns, tri_object, hid, bit, eps):
    """next_surface past the surfaces a ray of kind bit does not meet (hit_or_miss_past)."""
    pr, t, p, g, v0, e1, e2 = hit_or_miss_past(ray, o, d, tv, tng, tri_object, hid, bit, eps)
    if pr < 0:
        return pr, t, p, g, g, 0.0, 0.0
    b1, b2, _, _, _ = barycentric1(e1, e2, sub3(p, v0))
    return pr, t, p, g, shading_normal1(tns, pr, b1, b2, g, d), b1, b2


@njit(inline="always", **JIT)
def next_surface(ray, o, d, tv, tng, tns, eps):
    """The closest hit of the ray o + t d, from its offset origin (tracer.intersect without an
    exact origin; the ray cast here, counted as kind 0): (primitive, -1 on a miss; the float64
    distance, inf on a miss; point, unit geometric normal, shading normal, barycentrics b1, b2)."""
    pr, t, p, g, v0, e1, e2 = hit_or_miss(ray, o, d, tv, tng, eps)
    if pr < 0:
        return pr, t, p, g, g, 0.0, 0.0
    b1, b2, _, _, _ = barycentric1(e1, e2, sub3(p, v0))
    return pr, t, p, g, shading_normal1(tns, pr, b1, b2, g, d), b1, b2
