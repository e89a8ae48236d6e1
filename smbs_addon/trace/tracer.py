"""Ray casting with embree, hit records re-computed in float64.

One embree scene holds every triangle (embree.Scene: embreex's library, called from compiled
kernels). A kernel call casts its rays on one core without the GIL, so large batches are split
across a thread pool; the walks cast theirs from their own kernels (kernels.walk_lanes).
Embree works in float32; positions, normals and barycentrics are re-computed in float64 from
the primitive id (ray-plane intersection), and spawned rays are offset along the geometric
normal by a distance relative to the size of what takes part, at most a small part of the smallest
caster's, and more where float32 needs it at the point (Tracer.offsets).
"""
from __future__ import annotations

import copy
import os
from dataclasses import dataclass

import numpy as np

from ..core import embree, lanes
from ..scene import arrays as S
from ..kernels.chain import barycentric_rows, intersect_rays, shading_normal_rows
from ..core.vec import cross, dot, norm, normalize
from ..kernels.records import EPS_OF_CASTER, EPS_REL, HIDDEN_PASSES, Geometry, HitRows

_MIN_SPLIT = 8192  # rays per thread task below which splitting does not pay

# bench/throughput.py records the rays a bake casts: a list to collect (ray logs of
# embree.LOG_COLUMNS), every RAY_LOG_STRIDE-th ray of each kernel call, at most RAY_LOG_ROWS each
RAY_LOG: list | None = None
RAY_LOG_ROWS = 1 << 16
RAY_LOG_STRIDE = 4


def default_threads() -> int:
    return max(1, min(os.cpu_count() or 1, 64))


@dataclass
class Hits:
    """Float64 hit records for a batch of rays (valid where ``hit``)."""

    hit: np.ndarray  # (N,) bool
    prim: np.ndarray  # (N,) int64, -1 on miss
    t: np.ndarray  # (N,) distance along the (unit) ray
    p: np.ndarray  # (N,3) position
    ng: np.ndarray  # (N,3) unit geometric normal (triangle winding)
    ns: np.ndarray  # (N,3) unit shading normal (interpolated, not flipped towards ng, as in Cycles)
    b: np.ndarray  # (N,2) barycentrics (b1, b2) of corners 1 and 2


class Tracer:
    def __init__(self, scene, threads: int | None = None):
        self.scene = scene
        self.threads = threads or default_threads()
        self.v = np.ascontiguousarray(scene.tri_vertices, dtype=np.float64)
        e1 = self.v[:, 1] - self.v[:, 0]
        e2 = self.v[:, 2] - self.v[:, 0]
        n_raw = cross(e1, e2)
        self.area2 = np.sqrt(dot(n_raw, n_raw))  # twice the triangle area
        self.ng = normalize(n_raw)
        # (T, 3, 3) corner normals, or (T, 6, 3) with those a ray meets from behind after them
        # (Scene.tri_normals_back: a bumped surface's, bump.py; kernels._corners)
        self.ns_corner = scene.tri_normals.astype(np.float64) if not scene.tri_normals_back.size else \
            np.ascontiguousarray(np.concatenate([scene.tri_normals, scene.tri_normals_back], axis=1), np.float64)
        # every object's bounding box (zeros for an object without triangles; kept with a validated
        # scene): SMBS's GetRatio and the sphere-light cap read them for every chunk and light
        self.obj_lo, self.obj_hi, self.obj_has_tris = (x.copy() for x in scene.object_boxes())
        self.set_extent(*scene.bounds())
        self._embree = embree.Scene(self.v) if scene.n_tris else None
        self._cast = [0]  # rays cast, shared with the views of with_extent
        self.hid = scene.hidden_kinds()  # (O,) the kinds of ray each object does not meet (empty: none)
        self.hidden = scene.camera_hidden()  # (O,) bool: objects camera rays pass (empty: none)

    def set_extent(self, lo, hi, casters: np.ndarray | None = None) -> None:
        """Tolerances for geometry within [lo, hi] (the bake's plan: objects out of it change
        none): the self-intersection offset, a few float32 ulps of the largest coordinate
        (scene.offset_eps), and the area below which a triangle counts as degenerate. With
        casters ((O,) bool: the planned ones), neither takes more than EPS_OF_CASTER of the
        smallest caster's size, so that a floor of 100 km loses no glass ball of 1 m: where
        float32 needs more, at points far from the origin, spawn takes it point by point
        (offsets). Where the bounds' offset is below that cap, as in every scene of ordinary
        extent, it is kept as it was, bit for bit."""
        d = float(np.linalg.norm(np.asarray(hi) - np.asarray(lo)))
        scale = d if d > 0 else 1.0
        cap = np.inf
        if casters is not None and (casters & self.obj_has_tris).any():
            c = np.flatnonzero(casters & self.obj_has_tris)
            cap = EPS_OF_CASTER * float(np.linalg.norm(self.obj_hi[c] - self.obj_lo[c], axis=1).min())
        self.eps = min(S.offset_eps(lo, hi), cap)
        # the scale at which offset_eps would reach the cap (past the bounds' own in ordinary scenes)
        scale = min(scale, cap / EPS_REL)
        self.degenerate = ~(self.area2 > 1e-14 * max(scale, 1e-30) ** 2)

    @property
    def rays_cast(self) -> int:
        """Rays cast by this tracer and its views (with_extent)."""
        return self._cast[0]

    @rays_cast.setter
    def rays_cast(self, n: int) -> None:
        self._cast[0] = n

    def with_extent(self, lo, hi, casters: np.ndarray | None = None) -> "Tracer":
        """A view of this tracer (the same embree scene, arrays, threads and ray count) whose
        tolerances follow [lo, hi] and casters (set_extent), for tracing on several threads at once
        with tolerances of their own (the plan's pilots: plan.refine_plan)."""
        view = copy.copy(self)
        view.set_extent(lo, hi, casters)
        return view

    # ------------------------------------------------------------- low level
    def rays(self) -> embree.RayContext:
        """What a kernel that casts rays takes (embree.rays), with a fresh ray log while
        bench/throughput.py records (RAY_LOG)."""
        log = None if RAY_LOG is None else np.zeros((RAY_LOG_ROWS, embree.LOG_COLUMNS), np.float32)
        return embree.rays(self._embree, log, RAY_LOG_STRIDE)

    def cast_by_kernel(self, rt, counts) -> None:
        """Count the rays a kernel cast (counts: embree.ray_state's counters) and keep its log."""
        with lanes.LOCK:  # kernels on several threads count here
            self.rays_cast += int(counts[embree.KINDS:].sum())
            if RAY_LOG is not None and counts[embree.LOGGED]:
                RAY_LOG.append(rt.log[:counts[embree.LOGGED]].copy())

    def _run(self, o, d, tmax, query):
        n = len(o)
        if n == 0:
            return np.zeros(0, np.int64), np.zeros(0)
        if self._embree is None:
            with lanes.LOCK:
                self.rays_cast += n
            return np.full(n, -1, np.int64), np.full(n, np.inf)
        o = np.ascontiguousarray(o, dtype=np.float64)
        d = np.ascontiguousarray(d, dtype=np.float64)
        tmax = np.zeros(0) if tmax is None else np.ascontiguousarray(np.broadcast_to(tmax, (n,)), np.float64)
        occl = query == "OCCLUDED"
        prim = np.empty(n, np.int64)
        t = np.empty(0 if occl else n)

        def job(a, b):
            rt = self.rays()
            self.cast_by_kernel(rt, embree.cast_rays(rt, o[a:b], d[a:b], tmax[a:b] if tmax.size else tmax, occl,
                                                     prim[a:b], t[a:b] if t.size else t))

        lanes.run(job, n, self.threads, _MIN_SPLIT)
        return prim, None if occl else t

    # -------------------------------------------------------------- queries
    def occluded(self, o: np.ndarray, d: np.ndarray, tmax: np.ndarray) -> np.ndarray:
        """True where something lies on the segment o + t d, 0 < t < tmax (d unit)."""
        prim, _ = self._run(o, d, tmax, "OCCLUDED")
        return prim >= 0

    def cast(self, o: np.ndarray, d: np.ndarray):
        """Embree's closest hits of rays o + t d as they come: primitive ids (int64, -1 on a
        miss) and float32 distances as float64, for callers that re-compute the hits
        themselves."""
        return self._run(o, d, None, "INTERSECT")

    def intersect(self, o: np.ndarray, d: np.ndarray, tmax: np.ndarray | None = None,
                  exact_origin: np.ndarray | None = None) -> Hits:
        """Closest hits of rays o + t d (d unit), re-computed in float64 (kernels.intersect_rays:
        the plane of the hit triangle re-intersected, barycentrics, the shading normal).

        exact_origin: where the ray really starts (o is then only the offset
        origin embree traces from); the hit is re-computed on the line
        exact_origin + t d, so chains of specular vertices stay exact."""
        n = len(o)
        prim = np.full(n, -1, np.int64)
        t = np.full(n, np.inf)
        p, ng, ns, b = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 2))
        if n and self._embree is None:
            with lanes.LOCK:
                self.rays_cast += n
        elif n:
            o = np.ascontiguousarray(o, dtype=np.float64)
            d = np.ascontiguousarray(d, dtype=np.float64)
            tmax = np.zeros(0) if tmax is None else np.ascontiguousarray(np.broadcast_to(tmax, (n,)), np.float64)
            exact = exact_origin is not None
            xo = np.ascontiguousarray(exact_origin, dtype=np.float64) if exact else o

            def job(a, c):
                rt = self.rays()
                counts = intersect_rays(rt, o[a:c], d[a:c], tmax[a:c] if tmax.size else tmax, xo[a:c], exact,
                                        self.v, self.ng, self.ns_corner, self.eps,
                                        HitRows(prim[a:c], t[a:c], p[a:c], ng[a:c], ns[a:c], b[a:c]))
                self.cast_by_kernel(rt, counts)

            lanes.run(job, n, self.threads, _MIN_SPLIT)
        return Hits(hit=prim >= 0, prim=prim, t=t, p=p, ng=ng, ns=ns, b=b)

    def intersect_past(self, o: np.ndarray, d: np.ndarray, kind, passable: np.ndarray | None = None) -> Hits:
        """intersect for rays of kind `kind` (a scene.RAY_* bit, or one per ray): past the surfaces of
        the objects such rays do not meet (self.hid, Cycles' Ray Visibility) and of the objects passable
        marks ((O,) bool, or None), up to kernels.HIDDEN_PASSES of them (then a miss), each next hit on
        the ray's own line, as the kernels' rays (kernels.hit_or_miss_past)."""
        h = self.intersect(o, d)
        if passable is None and not (self.hid.size and (self.hid & np.bitwise_or.reduce(np.ravel(kind))).any()):
            return h  # nothing these rays pass: plain intersect
        kind = np.broadcast_to(kind, (len(o),))
        obj = self.scene.tri_object
        hid = self.hid if self.hid.size else np.zeros(len(self.scene.object_names), np.int64)
        for k in range(HIDDEN_PASSES + 1):
            on = obj[np.maximum(h.prim, 0)]
            j = np.flatnonzero(h.hit & ((hid[on] & kind != 0) | (passable[on] if passable is not None else False)))
            if j.size == 0:
                break
            if k == HIDDEN_PASSES:
                h.hit[j], h.prim[j], h.t[j] = False, -1, np.inf
                break
            g = self.intersect(self.spawn(h.p[j], h.ng[j], d[j]), d[j], exact_origin=o[j])
            for f in ("hit", "prim", "t", "p", "ng", "ns", "b"):
                getattr(h, f)[j] = getattr(g, f)
        return h

    def camera_intersect(self, o: np.ndarray, d: np.ndarray, far: np.ndarray | None = None) -> Hits:
        """intersect_past for the camera's own rays; with far (CameraModel.clip_far), what lies
        past the far clip plane is a miss, as in Cycles (kernels.eye._eye_rows)."""
        h = self.intersect_past(o, d, S.RAY_CAMERA)
        if far is not None:
            j = np.flatnonzero(h.hit & (h.t > far))
            h.hit[j], h.prim[j], h.t[j] = False, -1, np.inf
        return h

    def occluded_past(self, o: np.ndarray, d: np.ndarray, tmax: np.ndarray, kind: int,
                      passable: np.ndarray | None = None) -> np.ndarray:
        """occluded for rays of kind `kind` (a scene.RAY_* bit): the surfaces of the objects such rays do
        not meet are passed (kernels._camera_clear for the camera's), and those of the objects passable
        ((O,) bool: Shadow Linking's, the objects that do not shadow the light the rays go to) marks."""
        hidden = self.hid & kind != 0 if self.hid.size and (self.hid & kind).any() else None
        if passable is not None:
            hidden = passable if hidden is None else hidden | passable
        if hidden is None:
            return self.occluded(o, d, tmax)
        o, tmax = np.array(o, np.float64), np.array(np.broadcast_to(tmax, (len(o),)), np.float64)
        d = np.array(d, np.float64)
        end = o + np.where(np.isfinite(tmax), tmax, 0.0)[:, None] * d  # where each finite segment stops
        blocked, todo = np.zeros(len(o), bool), np.arange(len(o))
        for _ in range(HIDDEN_PASSES + 1):
            h = self.intersect(o[todo], d[todo], tmax[todo])
            passed = h.hit & hidden[self.scene.tri_object[np.maximum(h.prim, 0)]]
            blocked[todo[h.hit & ~passed]] = True
            go = np.flatnonzero(passed)  # on past the hidden surface, what is left of the segment
            if go.size == 0:
                return blocked
            todo = todo[go]
            o[todo] = self.spawn(h.p[go], h.ng[go], d[todo])
            # the rest of the segment ends where the segment did: the spawn moved the ray up to eps off
            # its line, and a mesh light's triangle lies just past that end (shadow_tmax), so the ray
            # is aimed at the end again rather than run on by what is left of tmax (which met the
            # light's own triangle on 18% of the walks' shadow rays past shadow_linked_glow's plate)
            finite = np.isfinite(tmax[todo])
            f = todo[finite]
            to = end[f] - o[f]
            ahead = dot(to, d[f]) > 0  # else the surface lay at the end: nothing is left
            tmax[f] = np.where(ahead, norm(to), 0.0)
            d[f] = np.where(ahead[:, None], to / np.maximum(tmax[f], 1e-300)[:, None], d[f])
            todo = np.concatenate([f[ahead], todo[~finite]])
        blocked[todo] = True
        return blocked

    def camera_occluded(self, o: np.ndarray, d: np.ndarray, tmax: np.ndarray) -> np.ndarray:
        """occluded_past for rays towards the camera."""
        return self.occluded_past(o, d, tmax, S.RAY_CAMERA)

    def kernel_geometry(self, casters: np.ndarray) -> Geometry:
        """The scene as the kernels trace paths through it (records.Geometry), with the plan's caster
        flags per object and the kinds of ray each object does not meet (self.hid)."""
        sc = self.scene
        return Geometry(tv=self.v, tng=self.ng, tns=self.ns_corner, tri_material=sc.tri_material, mat_kind=sc.mat_kind,
                        tri_object=sc.tri_object, casters=casters, mat_ior=sc.mat_ior, hid=self.hid)

    # ------------------------------------------------------------- geometry
    def barycentrics(self, prim: np.ndarray, p: np.ndarray) -> np.ndarray:
        """(b1, b2) of points p on triangles prim (1/3 each on a degenerate triangle)."""
        return barycentric_rows(self.v, np.ascontiguousarray(prim, np.int64), np.ascontiguousarray(p, np.float64))

    def shading_normal(self, prim: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Interpolated, normalised corner normal (not flipped towards the geometric
        normal, like Cycles' triangle_smooth_normal); falls back to the geometric
        normal where the interpolated corner normals are zero."""
        return shading_normal_rows(self.ns_corner, self.ng, np.ascontiguousarray(prim, np.int64),
                                   np.ascontiguousarray(b, np.float64))

    def differentials(self, prim: np.ndarray, b: np.ndarray) -> dict:
        """dp/du, dp/dv from the triangle's UVs (per-triangle default UVs when
        degenerate) and dn/du, dn/dv of the normalised interpolated normal."""
        v = self.v[prim]
        uv = self.scene.tri_uvs[prim]
        e1, e2 = v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]
        duv1, duv2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
        det = duv1[:, 0] * duv2[:, 1] - duv1[:, 1] * duv2[:, 0]
        scale = np.maximum(np.abs(duv1).max(1), np.abs(duv2).max(1)) ** 2
        ok = np.abs(det) > 1e-12 * np.maximum(scale, 1e-300)
        inv = np.divide(1.0, det, out=np.zeros_like(det), where=ok)
        # barycentric derivatives w.r.t. (u, v): [db1/du db1/dv; db2/du db2/dv] = M^-1
        db1du = np.where(ok, duv2[:, 1] * inv, 1.0)
        db1dv = np.where(ok, -duv2[:, 0] * inv, 0.0)
        db2du = np.where(ok, -duv1[:, 1] * inv, 0.0)
        db2dv = np.where(ok, duv1[:, 0] * inv, 1.0)
        dpdu = e1 * db1du[:, None] + e2 * db2du[:, None]
        dpdv = e1 * db1dv[:, None] + e2 * db2dv[:, None]
        c = self.ns_corner[prim]
        b0 = 1.0 - b[:, 0] - b[:, 1]
        nraw = b0[:, None] * c[:, 0] + b[:, 0:1] * c[:, 1] + b[:, 1:2] * c[:, 2]
        ln = np.sqrt(dot(nraw, nraw))
        good = ln > 0.5 * 1e-3
        n = np.where(good[:, None], nraw / np.where(good, ln, 1.0)[:, None], self.ng[prim])
        dn1 = c[:, 1] - c[:, 0]
        dn2 = c[:, 2] - c[:, 0]

        def proj(x):  # d(N/|N|) = (I - n n^T) dN / |N|
            return np.where(good[:, None], (x - dot(x, n)[:, None] * n) / np.where(good, ln, 1.0)[:, None], 0.0)

        dndu = proj(dn1 * db1du[:, None] + dn2 * db2du[:, None])
        dndv = proj(dn1 * db1dv[:, None] + dn2 * db2dv[:, None])
        return {"dpdu": dpdu, "dpdv": dpdv, "dndu": dndu, "dndv": dndv, "n": n}

    def offsets(self, p: np.ndarray, ng: np.ndarray) -> np.ndarray:
        """The offset of a ray spawned at each point p (N,3) of unit geometric normal ng
        (kernels.chain.offset1, row by row): self.eps, or what float32 needs there if more."""
        need = np.minimum(np.abs(ng * p).sum(1), np.abs(p).max(1, initial=0.0))
        return np.maximum(self.eps, EPS_REL * need)

    def spawn(self, p: np.ndarray, ng: np.ndarray, d: np.ndarray) -> np.ndarray:
        """Ray origins offset from surface points to the side d leaves on."""
        side = np.where(dot(d, ng) >= 0, 1.0, -1.0)
        return p + (self.offsets(p, ng) * side)[:, None] * ng
