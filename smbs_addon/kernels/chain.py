"""A chain of specular vertices from ray hits: a hit re-computed in float64, its shading normal and
differentials packed as a vertex (records.NF columns), the chain a ray traces through mirrors and glass
(trace_lanes, seeds), and the mismatch of its last direction with the light end.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..core.jit import JIT, LANES
from ..scene.arrays import CONDUCTOR, DIELECTRIC, RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMISSION
from .records import (
    DNS, DNT, EPS_REL, HIDDEN_PASSES, MAT, MISS, NF, NG, NOT_CASTER, NS, OBJ, OK, P, PRIM, RAYS_SEED, REFRACT, S,
    SEED_OBJECT, SIDE, SIDE_INNER, T, TIR, TIR_INNER, WRONG_MATERIAL)
from .typed import TypedOnce
from ..core.vec3 import add3, cols3, cross3, div3, dot1, normalize3, scale3, sub3, vertex_cols3
from ..core.embree import intersect1, ray_state
from .newton import smap


# ------------------------------------------------------------------ a ray's hit in float64
@njit(inline="always", **JIT)
def offset1(eps, p, g):
    """The self-intersection offset at point p of unit geometric normal g (tracer.Tracer.offsets):
    eps (Tracer.eps, over what takes part), or, where more, EPS_REL of p's coordinates along g
    (Pharr et al., PBR 3.9.5: float32's error at p, weighted by |g|, so that a flat floor spawns
    as close at 100 km as at its centre), or of its largest (Wachter and Binder, Ray Tracing Gems
    ch. 6: relative to p's magnitude), whichever is less. Within the bounds eps was taken over
    both are below it: eps, bit for bit."""
    a = abs(g[0] * p[0]) + abs(g[1] * p[1]) + abs(g[2] * p[2])
    m = max(abs(p[0]), max(abs(p[1]), abs(p[2])))
    return max(eps, EPS_REL * min(a, m))


@njit(inline="always", **JIT)
def spawn1(p, g, d, eps):
    """tracer.spawn: the origin of a ray leaving point p (unit geometric normal g) along d,
    offset1 off the surface on the side d leaves on."""
    e = offset1(eps, p, g)
    return add3(p, scale3(e if dot1(d, g) >= 0 else -e, g))


@njit(**JIT)
def hit_point(o, d, xo, exact, t32, pr, tv, tng, eps):
    """tracer.intersect's float64 hit of the ray o + t d (the offset origin embree traced from;
    xo, where it really starts when exact, else o) on primitive pr at embree's float32 distance
    t32: the plane of the triangle re-intersected from xo, embree's distance kept where the two
    disagree badly (its own error is absolute: float32 vertices, ~1e-7 of the extent, hence
    + eps). Returns (t from xo, the point, the unit geometric normal, corner 0, edges 1 and 2)."""
    tt = t32 + dot1(sub3(o, xo), d) if exact else t32
    g = cols3(tng, pr, 0)
    v0 = (tv[pr, 0, 0], tv[pr, 0, 1], tv[pr, 0, 2])
    v1 = (tv[pr, 1, 0], tv[pr, 1, 1], tv[pr, 1, 2])
    v2 = (tv[pr, 2, 0], tv[pr, 2, 1], tv[pr, 2, 2])
    den = dot1(d, g)
    num = dot1(sub3(v0, xo), g)
    ti = num / den if abs(den) > 1e-12 else tt
    if not math.isfinite(ti) or abs(ti - tt) > 1e-3 * abs(tt) + offset1(eps, add3(xo, scale3(tt, d)), g):
        ti = tt
    return ti, add3(xo, scale3(ti, d)), g, v0, sub3(v1, v0), sub3(v2, v0)


@njit(**JIT)
def barycentric1(e1, e2, q):
    """Barycentrics (b1, b2) of corners 1 and 2 for q = p - v0 on the triangle of edges e1, e2
    (1/3 each where the triangle is degenerate), and the edges' dot products d11, d12, d22."""
    d11, d12, d22 = dot1(e1, e1), dot1(e1, e2), dot1(e2, e2)
    q1, q2 = dot1(q, e1), dot1(q, e2)
    det = d11 * d22 - d12 * d12
    if det > 0:
        inv = 1.0 / det
        return (d22 * q1 - d12 * q2) * inv, (d11 * q2 - d12 * q1) * inv, d11, d12, d22
    return 1.0 / 3.0, 1.0 / 3.0, d11, d12, d22


@njit(**JIT)
def _corners(tns, pr, d, g):
    """The corner normals of triangle pr a ray of direction d meets (g: its geometric normal): in
    tns[pr, 3:] where it comes from behind and tns holds the normals met from there (Tracer.ns_corner
    (T, 6, 3): Scene.tri_normals_back, bump.py), else tns[pr, :3] (constant indices, the common case)."""
    if tns.shape[1] == 6 and d[0] * g[0] + d[1] * g[1] + d[2] * g[2] > 0:
        return ((tns[pr, 3, 0], tns[pr, 3, 1], tns[pr, 3, 2]), (tns[pr, 4, 0], tns[pr, 4, 1], tns[pr, 4, 2]),
                (tns[pr, 5, 0], tns[pr, 5, 1], tns[pr, 5, 2]))
    return ((tns[pr, 0, 0], tns[pr, 0, 1], tns[pr, 0, 2]), (tns[pr, 1, 0], tns[pr, 1, 1], tns[pr, 1, 2]),
            (tns[pr, 2, 0], tns[pr, 2, 1], tns[pr, 2, 2]))


@njit(**JIT)
def shading_normal1(tns, pr, b1, b2, g, d):
    """tracer.shading_normal: the corner normals interpolated and normalised (not flipped towards
    the geometric normal g, as Cycles' triangle_smooth_normal), g where they give none; those a ray
    of direction d meets (_corners)."""
    b0 = 1.0 - b1 - b2
    c0, c1, c2 = _corners(tns, pr, d, g)
    n = normalize3(add3(add3(scale3(b0, c0), scale3(b1, c1)), scale3(b2, c2)))
    return g if dot1(n, n) < 0.5 else n


@njit(**LANES)
def _intersect_rows(ray, o, d, tmax, xo, exact, tv, tng, tns, eps, hits):
    """intersect_rays' loop over its rays (its caller holds the arrays)."""
    prim, t, p, ng, ns, b = hits.prim, hits.t, hits.p, hits.ng, hits.ns, hits.b
    for i in range(o.shape[0]):
        oi, di = cols3(o, i, 0), cols3(d, i, 0)
        pr, t32 = intersect1(ray, oi, di, tmax[i] if tmax.shape[0] else np.inf, 0)
        prim[i] = pr
        if pr < 0:
            t[i] = np.inf
            continue
        ti, pi, g, v0, e1, e2 = hit_point(oi, di, cols3(xo, i, 0) if exact else oi, exact, t32, pr, tv, tng, eps)
        b1, b2, _, _, _ = barycentric1(e1, e2, sub3(pi, v0))
        n = shading_normal1(tns, pr, b1, b2, g, di)
        t[i] = ti
        b[i, 0], b[i, 1] = b1, b2
        for c in range(3):
            p[i, c], ng[i, c], ns[i, c] = pi[c], g[c], n[c]


@TypedOnce
@njit(**JIT)
def intersect_rays(rt, o, d, tmax, xo, exact, tv, tng, tns, eps, hits):
    """tracer.intersect: closest hits of rays o + t d (offset origins o; xo where they really
    start when exact), t < tmax (empty: no limit), with float64 hit records (hit_point,
    barycentric1, shading_normal1) written to hits (HitRows: prim -1 on a miss, t inf on a miss;
    p, ng, ns, b left as they are on a miss). Returns the ray counters (embree.ray_state)."""
    ray = ray_state(rt)
    _intersect_rows(ray, o, d, tmax, xo, exact, tv, tng, tns, eps, hits)
    return ray.counts


@njit(**JIT)
def barycentric_rows(tv, prim, p):
    """tracer.barycentrics: (b1, b2) of points p on triangles prim."""
    out = np.zeros((prim.shape[0], 2))
    for i in range(prim.shape[0]):
        pr = prim[i]
        v0 = (tv[pr, 0, 0], tv[pr, 0, 1], tv[pr, 0, 2])
        e1 = (tv[pr, 1, 0] - v0[0], tv[pr, 1, 1] - v0[1], tv[pr, 1, 2] - v0[2])
        e2 = (tv[pr, 2, 0] - v0[0], tv[pr, 2, 1] - v0[1], tv[pr, 2, 2] - v0[2])
        out[i, 0], out[i, 1], _, _, _ = barycentric1(e1, e2, sub3(cols3(p, i, 0), v0))
    return out


@njit(**JIT)
def shading_normal_rows(tns, tng, prim, b):
    """tracer.shading_normal at barycentrics b on triangles prim (the normals met from the front)."""
    out = np.zeros((prim.shape[0], 3))
    front = (0.0, 0.0, 0.0)
    for i in range(prim.shape[0]):
        n = shading_normal1(tns, prim[i], b[i, 0], b[i, 1], cols3(tng, prim[i], 0), front)
        out[i, 0], out[i, 1], out[i, 2] = n
    return out


# ------------------------------------------------------------------ a vertex from a ray hit
@njit(inline="always", **JIT)
def _lane_vertex(kinds, j, lane, o, d, prev, exact, pr, t32, geo, eps, rows):
    """walk.propagate's work for vertex j (of the chain's kinds) of chain row `lane` (rows:
    ChainRows) once its ray o + t d (3-tuples) hit primitive pr at embree's distance t32:
    tracer.intersect's float64 hit point (the plane of the hit triangle (geo: Geometry)
    re-intersected from prev, the ray's true start, when exact, else from o),
    geometry.vertex_from_hits, the material checks, the reflection or refraction of
    w_in = normalize(prev - p) and the side checks. Writes the walk outcome to rows.status, the
    vertex to F and I where it is kept (valid, or at the last vertex TIR or SIDE), the unit
    outgoing direction to out_dir; returns whether the chain goes on, and the next ray's offset
    origin and direction, and the vertex."""
    refract, last = kinds[j] == REFRACT, j == kinds.shape[0] - 1
    tv, tng, tns = geo.tv, geo.tng, geo.tns
    F, I, status, out = rows.F, rows.I, rows.status, rows.out_dir
    zero = (0.0, 0.0, 0.0)
    ti, p, g, v0, e1, e2 = hit_point(o, d, prev if exact else o, exact, t32, pr, tv, tng, eps)
    b1, b2, d11, d12, d22 = barycentric1(e1, e2, sub3(p, v0))
    # geometry.vertex_from_hits
    s = normalize3(e1)
    t = cross3(g, s)
    c0, c1, c2 = _corners(tns, pr, d, g)
    b0 = 1.0 - b1 - b2
    nraw = add3(add3(scale3(b0, c0), scale3(b1, c1)), scale3(b2, c2))
    ln = math.sqrt(dot1(nraw, nraw))
    good = ln > 1e-3
    n = div3(nraw, ln) if good else g
    dns = dnt = zero
    if good:
        g11, g12, g22 = d11, d12, d22
        det2 = g11 * g22 - g12 * g12
        inv2 = 1.0 / det2 if det2 > 1e-300 else 0.0
        dn1, dn2 = sub3(c1, c0), sub3(c2, c0)
        for col in range(2):
            w = s if col == 0 else t
            r1, r2 = dot1(w, e1), dot1(w, e2)
            alpha = (g22 * r1 - g12 * r2) * inv2
            beta = (g11 * r2 - g12 * r1) * inv2
            dN = add3(scale3(alpha, dn1), scale3(beta, dn2))
            dv = div3(sub3(dN, scale3(dot1(dN, n), n)), ln)
            if col == 0:
                dns = dv
            else:
                dnt = dv
    mat = geo.tri_material[pr]
    mk = geo.mat_kind[mat]
    obj = geo.tri_object[pr]
    code = OK
    if not geo.casters[obj]:
        code = NOT_CASTER
    need = (mk == DIELECTRIC) if refract else (mk == CONDUCTOR or mk == DIELECTRIC)
    if not need and code == OK:
        code = WRONG_MATERIAL
    w_in = normalize3(sub3(prev, p))
    w_out, okm = smap(refract, w_in, n, geo.mat_ior[mat])
    if not okm and code == OK:
        code = TIR if last else TIR_INNER
    cin, cout = dot1(w_in, g), dot1(w_out, g)
    side_ok = ((cin * cout < 0) if refract else (cin * cout > 0)) and (dot1(w_in, n) * dot1(n, g) * cin > 0)
    if not side_ok and code == OK:
        code = SIDE if last else SIDE_INNER
    status[lane] = code
    keep = code == OK or (last and (code == TIR or code == SIDE))
    if not keep:
        return False, zero, zero, zero
    wn = normalize3(w_out)
    for c in range(3):
        F[lane, j, P + c] = p[c]
        F[lane, j, NG + c] = g[c]
        F[lane, j, NS + c] = n[c]
        F[lane, j, S + c] = s[c]
        F[lane, j, T + c] = t[c]
        F[lane, j, DNS + c] = dns[c]
        F[lane, j, DNT + c] = dnt[c]
    I[lane, j, PRIM], I[lane, j, OBJ], I[lane, j, MAT] = pr, obj, mat
    if code == TIR:
        return False, zero, zero, zero
    out[lane, 0], out[lane, 1], out[lane, 2] = wn
    if code != OK:
        return False, zero, zero, zero
    return True, spawn1(p, g, wn, eps), wn, p


@njit(**LANES)
def trace_lane(ray, kind, lane, x0, o, d, kinds, geo, eps, rows):
    """walk.propagate for chain row `lane`: the ray from x0 (its offset origin o, direction d;
    3-tuples) and its reflections and refractions through the chain's vertices (geo: Geometry),
    each ray cast here (embree.intersect1, counted as `kind`). The row of rows (ChainRows: F, I,
    status (walk outcome, OK where every vertex is valid) and out_dir (the direction leaving the
    last vertex)) is written from scratch. Called, not inlined (compiled once for the seeds and
    the walks): its callers pass kind and lane as int64, as numba compiles a function once per
    value of a constant argument."""
    tng, tri_object, hid = geo.tng, geo.tri_object, geo.hid
    F, I, status, out = rows.F, rows.I, rows.status, rows.out_dir
    k = kinds.shape[0]
    for j in range(k):
        for c in range(NF):
            F[lane, j, c] = 0.0
        I[lane, j, 0] = I[lane, j, 1] = I[lane, j, 2] = 0
    status[lane] = OK
    out[lane, 0] = out[lane, 1] = out[lane, 2] = 0.0
    prev = x0
    for j in range(k):
        pr, t32 = intersect1(ray, o, d, np.inf, kind)
        passed = False
        if hid.shape[0] > 0:  # past what this ray's kind does not meet (x0's diffuse bounce, then the letter before)
            bit = RAY_DIFFUSE if j == 0 else (RAY_TRANSMISSION if kinds[j - 1] == REFRACT else RAY_GLOSSY)
            for _ in range(HIDDEN_PASSES + 1):
                if pr < 0 or not hid[tri_object[pr]] & bit:
                    break
                g = (tng[pr, 0], tng[pr, 1], tng[pr, 2])
                o = spawn1(add3(o, scale3(t32, d)), g, d, eps)
                pr, t32 = intersect1(ray, o, d, np.inf, kind)
                passed = True
            if pr >= 0 and hid[tri_object[pr]] & bit:
                pr = -1
        if pr < 0:
            status[lane] = MISS
            return
        # from the true previous vertex, not the offset ray origin: the chain stays exact. At the
        # last vertex the vertex of a chain whose exit is TIR (SMBS can mutate from it) and of one
        # whose exit dips below the geometric surface (a shading normal leaning away, as on a
        # normal-mapped mirror) is kept: every walk goes on from it, as SMS does from any seed on
        # the caster, and converges only once the exit is valid
        go, o, d, prev = _lane_vertex(kinds, j, lane, o, d, prev, j > 0 or passed, pr, t32, geo, eps, rows)
        if not go:
            return


@njit(**LANES)
def _seed_rows(ray, kinds, x0, ng0, seeds, geo, eps, rows):
    """trace_lanes' loop over its lanes (its caller holds the arrays)."""
    for i in range(x0.shape[0]):
        seed_lane(ray, i, x0, ng0, seeds, kinds, geo, eps, rows)


@TypedOnce
@njit(**JIT)
def trace_lanes(rt, kinds, x0, ng0, seeds, geo, eps, rows):
    """walk.propagate of every lane: the ray from x0 (offset along ng0 to the side it leaves
    on, as tracer.spawn) in direction seeds.d (SeedRays) through the chain, into rows
    (ChainRows); where seeds.want[i] >= 0, a chain whose first vertex lies on another object
    ends as SEED_OBJECT. Returns the ray counters (embree.ray_state)."""
    ray = ray_state(rt)
    _seed_rows(ray, kinds, x0, ng0, seeds, geo, eps, rows)
    return ray.counts


@njit(**LANES)
def seed_lane(ray, i, x0, ng0, seeds, kinds, geo, eps, rows):
    """The seed chain of lane i (trace_lanes), its rays counted as seeds. Not inlined: one call
    per walk, and one compiled copy of trace_lane for every kernel that seeds (inlined into
    each, the walk kernels took minutes to compile)."""
    want_obj = seeds.want
    xi = cols3(x0, i, 0)
    di = cols3(seeds.d, i, 0)
    g = cols3(ng0, i, 0)
    # (np.int64: a constant argument would compile trace_lane once per value, see its docstring)
    trace_lane(ray, np.int64(RAYS_SEED), i, xi, spawn1(xi, g, di, eps), di, kinds, geo, eps, rows)
    if want_obj[i] >= 0 and rows.status[i] == OK and rows.I[i, 0, OBJ] != want_obj[i]:
        rows.status[i] = SEED_OBJECT


@njit(inline="always", **JIT)
def lane_mismatch(F, m, out_dir, ly, i, directional):
    """walk.end_mismatch of chain row m against lane i's light end: (|w_o' - w_o|, front)."""
    k = F.shape[1]
    if directional:
        to_light = cols3(ly, i, 0)
    else:
        to_light = normalize3(sub3(cols3(ly, i, 0), vertex_cols3(F, m, k - 1, P)))
    od = cols3(out_dir, m, 0)
    diff = sub3(od, to_light)
    return math.sqrt(dot1(diff, diff)), dot1(od, to_light) > 0


@njit(**JIT)
def end_mismatch(idx, F, out_dir, ly, directional):
    """walk.end_mismatch of a chain (rows 0.. of F, out_dir) against the light end rows idx:
    |w_o' - w_o| at the last vertex and whether w_o' points to the light's side."""
    M = idx.shape[0]
    err = np.zeros(M)
    front = np.zeros(M, np.bool_)
    for m in range(M):
        err[m], front[m] = lane_mismatch(F, m, out_dir, ly, idx[m], directional)
    return err, front
