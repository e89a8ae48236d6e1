"""SMBS's large mutation (Jhang & Chang 2022, Algorithms 3 and 4).

GetNextDir traces a direction backwards from the light sample through the
chain's current vertices (reflecting or refracting with each vertex's shading
normal); GetRatio interpolates between the current first segment and that
direction, halving the weight until the ray still meets the bounding box of the
specular object that holds x1. Trigger conditions live in walk.py.
"""
from __future__ import annotations

import numpy as np

from .constraints import specular_map
from smbs_addon.core.vec import dot, normalize
from smbs_addon.walks.walk import MAX_HALVINGS


def get_next_dir(types: str, verts: list, etas: list, light):
    """Algorithm 3. Returns v2' (N,3), the direction leaving x1 towards the
    receiver's side, and ok (False where a refraction on the way back is total
    internal reflection: the large mutation then fails, never a NaN)."""
    k = len(types)
    if light.directional:
        v = -light.y
    else:
        v = normalize(verts[k - 1].p - light.y)
    ok = np.ones(len(v), bool)
    for j in range(k - 1, -1, -1):
        out, okm = specular_map(types[j], -v, verts[j].n, etas[j])
        ok &= okm
        v = out
    return v, ok


def ray_box(o, d, lo, hi):
    """Does the ray o + t d (t > 0) meet the axis-aligned box [lo, hi]? (slab test)"""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        t1 = (lo - o) * inv
        t2 = (hi - o) * inv
    t1 = np.where(np.isnan(t1), -np.inf, t1)
    t2 = np.where(np.isnan(t2), np.inf, t2)
    near, far = np.minimum(t1, t2), np.maximum(t1, t2)
    # the three slabs by hand: np.max(axis=1) over 3 columns costs several times more
    tmin = np.maximum(np.maximum(near[:, 0], near[:, 1]), near[:, 2])
    tmax = np.minimum(np.minimum(far[:, 0], far[:, 1]), far[:, 2])
    return (tmax >= np.maximum(tmin, 0.0))


def get_ratio(x0, v1, target, lo, hi, scale=None):
    """Algorithm 4: the interpolation weight a between v1 (current) and target (-v2').
    scale (N,) <= 1 continues the bisection where an earlier large mutation from
    the same vertex missed the caster itself (the box test cannot see that)."""
    a = np.where(dot(v1, target) < 0, 1.0, 0.5)
    if scale is not None:
        a = a * scale
    lo, hi = np.broadcast_to(lo, x0.shape), np.broadcast_to(hi, x0.shape)
    found = np.zeros(len(a), bool)
    left = np.arange(len(a))  # lanes still halving
    for _ in range(MAX_HALVINGS + 1):
        if left.size == 0:
            break
        al = a[left]
        d = normalize(al[:, None] * target[left] + (1.0 - al)[:, None] * v1[left])
        hit = ray_box(x0[left], d, lo[left], hi[left]) & (dot(d, d) > 0)
        found[left[hit]] = True
        left = left[~hit]
        a[left] *= 0.5
    return np.where(found, a, 0.0)


def large_direction(types, verts, etas, light, x0, obj_lo, obj_hi, scale=None):
    """The SMBS proposal direction from x0 and whether it could be built."""
    v2, ok = get_next_dir(types, verts, etas, light)
    v1 = normalize(verts[0].p - x0)
    target = -v2
    a = get_ratio(x0, v1, target, obj_lo, obj_hi, scale)
    d = normalize(a[:, None] * target + (1.0 - a)[:, None] * v1)
    ok &= dot(d, d) > 0.5
    return d, ok
