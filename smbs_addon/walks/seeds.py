"""Seed chains for the walks: SMS's uniform point on a caster (the first hit must be on the caster
aimed at), MNEE's straight line to the light, and which light samples the casters can join at all.
"""
from __future__ import annotations


from ..shading.light_samples import LightEnd
from ..scene import arrays as S
from ..scene.geometry import area_points, triangle_areas
from ..core.vec import dot, normalize
from .walk import propagate
import numpy as np

def _closed(scene, obj) -> bool:
    """Is the object's mesh watertight (every edge shared by exactly two triangles)?"""
    return scene.derived(("closed", int(obj)), lambda: _watertight(scene, obj))


def _watertight(scene, obj) -> bool:
    """Every edge of the object's triangles shared by exactly two, its vertices merged where their
    coordinates agree to 1e-9. Sorted by coordinates (np.lexsort) and by one integer per edge: a
    bumped water's 131,072 triangles in ~0.07 s, where np.unique over rows took 0.66 s (once per
    scene a bake makes: auto's pilots are scenes of their own)."""
    tv = scene.tri_vertices[scene.tri_object == obj]
    if len(tv) == 0:
        return False
    p = np.round(tv.reshape(-1, 3), 9)
    order = np.lexsort((p[:, 2], p[:, 1], p[:, 0]))
    q = p[order]
    new = np.ones(len(q), bool)
    new[1:] = np.any(q[1:] != q[:-1], axis=1)
    ids = np.empty(len(q), np.int64)
    ids[order] = np.cumsum(new) - 1
    f = ids.reshape(-1, 3)
    a, b = f.ravel(), f[:, [1, 2, 0]].ravel()
    key = np.minimum(a, b) * (int(ids.max()) + 1) + np.maximum(a, b)
    _, counts = np.unique(key, return_counts=True)
    return bool(np.all(counts == 2))


def _plane(scene, obj):
    """(unit normal, centre) of an object whose vertices all lie in one plane, else None."""
    return scene.derived(("plane", int(obj)), lambda: _fit_plane(scene, obj))


def _fit_plane(scene, obj):
    pts = scene.tri_vertices[scene.tri_object == obj].reshape(-1, 3)
    c = pts.mean(axis=0)
    _, sv, vt = np.linalg.svd(pts - c, full_matrices=False)
    return (vt[-1], c) if sv[-1] <= 1e-9 * max(sv[0], 1e-300) else None


class Seeder:
    """Seed chains: SMS's uniform point on a caster (the first hit must be on
    that caster), or MNEE's straight line towards the light (towards the
    caster's box centre for a reflection first)."""

    def __init__(self, scene, casters, types, method):
        self.method = method
        kinds = scene.mat_kind[scene.tri_material]
        ok_kind = (kinds == S.DIELECTRIC) if types[0] == "T" else ((kinds == S.CONDUCTOR) | (kinds == S.DIELECTRIC))
        self.tris = np.flatnonzero(casters[scene.tri_object] & ok_kind)
        v = scene.tri_vertices[self.tris]
        self.cdf = np.cumsum(triangle_areas(v))
        self.total = float(self.cdf[-1]) if len(self.cdf) else 0.0
        self.v = v
        self.obj = scene.tri_object[self.tris]
        self.reflect_first = types[0] == "R"
        self.types = types
        # planar casters: a one-vertex chain needs the receiver and the light on the
        # same side (R) or on opposite sides (T) of the plane, which culls lanes up front
        self.planes = None
        if len(types) == 1:
            planes = [_plane(scene, o) for o in np.unique(self.obj)]
            self.planes = None if any(p is None for p in planes) else planes
        objs = np.unique(self.obj)
        self.centers = np.array([np.mean(scene.object_bounds(o), axis=0) for o in objs]).reshape(-1, 3)
        self.center_obj = objs

    def feasible(self, x0, light: LightEnd, margin):
        """Lanes that can have a solution at all (always True unless every eligible
        caster is planar and the receiver/light sides rule it out)."""
        if not self.planes:
            return np.ones(len(x0), bool)
        ok = np.zeros(len(x0), bool)
        for nrm, c in self.planes:
            a = dot(x0 - c, nrm)
            b = dot(light.y, nrm) if light.directional else dot(light.y - c, nrm)
            straddle = np.abs(b) <= (0 if light.directional else margin)
            same = (a > 0) == (b > 0)
            ok |= straddle | (same if self.types == "R" else ~same)
        return ok

    def directions(self, rng, x0, light: LightEnd, ctx):
        n = len(x0)
        if self.method == "mnee":
            if self.reflect_first:  # a mirror is not on the line to the light: aim at its box centre
                k = rng.integers(len(self.centers), size=n) if len(self.centers) > 1 else np.zeros(n, int)
                # the pick counts only solutions on the caster it aimed at (weight K): a seed
                # that lands on another caster, or on a coincident copy, is that caster's
                return normalize(self.centers[k] - x0), self.center_obj[k]
            if light.directional:
                return light.y.copy(), None
            return normalize(light.y - x0), None
        q, t = area_points(self.v, self.cdf, self.total, n, rng)
        return normalize(q - x0), self.obj[t]

    def seed(self, ctx, rng, types, x0, ng0, light):
        """Seed chains (a seed off the caster it aimed at ends as SEED_OBJECT)."""
        d, want_obj = self.directions(rng, x0, light, ctx)
        return propagate(ctx, x0, ng0, d, types, want_obj)
