"""The seen hand-off's cosine paths: diffuse bounces from receivers, aimed or cosine-weighted, and
which of their segments can meet a light at all (segments_near).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..core.jit import JIT, LANES
from ..scene.arrays import CONDUCTOR, DIELECTRIC, RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMISSION
from .records import HIST_B, HIST_BENT, HIST_CASTER, HIST_P, HIST_REFL, NEAR_ALL, NEAR_DISK, NEAR_RECT, NEAR_SPHERE, \
    SEG_BETA, SEG_D, SEG_O, SEG_T
from .typed import TypedOnce
from .chain import barycentric1, shading_normal1, spawn1

from ..shading.absorption import absorbed1, medium_after1
from ..core.vec3 import add3, cols3, dot1, frame1, max_nan, neg3, scale3, sub3
from ..shading.optics import bend1, bump_shadowing1, scatter1
from ..shading.coat import coat_factor1
from ..core.embree import ray_state
from .keyed import keyed_uniform, keyed_uniform3
from .rays import hit_or_miss_past


# ------------------------------------------------------------------ diffuse bounces, the hand-off's cosine paths
@njit(inline="always", **JIT)
def _cosine_bounce(u1, u2, w, g, n):
    """path_light.diffuse_bounce's direction: cosine-distributed about the shading normal n on
    w's side of the geometric normal g (vec.frame, vec.cosine_hemisphere); also that side."""
    side = 1.0 if dot1(w, g) >= 0 else -1.0
    nn = scale3(side, n)
    s, t = frame1(nn)
    r = math.sqrt(u1)
    phi = 2.0 * np.pi * u2
    x, y, z = r * math.cos(phi), r * math.sin(phi), math.sqrt(max(0.0, 1.0 - u1))
    return add3(add3(scale3(x, s), scale3(y, t)), scale3(z, nn)), side, nn


@njit(inline="always", **JIT)
def diffuse_scatter(u1, u2, u3, w, g, n, a, beta, adjoint):
    """path_light.diffuse_bounce of one lane: a cosine direction about the shading normal n on w's
    side of g (_cosine_bounce), Russian roulette on the albedo a (u3), the weight beta * a / q,
    with Veach's shading-normal correction when adjoint (light carried from w to the new
    direction). Returns (kept, direction, weight)."""
    zero = (0.0, 0.0, 0.0)
    d, side, nn = _cosine_bounce(u1, u2, w, g, n)
    q = min(max(max_nan(max_nan(a[0], a[1]), a[2]), 0.0), 1.0)
    if not u3 < q:
        return False, zero, zero
    b = (beta[0] * (a[0] / q), beta[1] * (a[1] / q), beta[2] * (a[2] / q))
    cout = dot1(d, scale3(side, g))
    if adjoint:
        num = abs(dot1(w, n) * cout)
        den = abs(dot1(w, g) * dot1(d, n))
        corr = num / den if den > 0 else 0.0
        b = scale3(corr, b)
    if not (cout > 0 and dot1(w, nn) > 0 and max_nan(max_nan(b[0], b[1]), b[2]) > 0):
        return False, zero, zero
    return True, d, b


@njit(**JIT)
def diffuse_rows(u, w, ng, ns, beta, alb, adjoint):
    """diffuse_scatter per lane (u: (3, n) uniform numbers): (new directions, new weights, kept
    lanes), as optics.scatter_rows."""
    n = w.shape[0]
    d_out, b_out, keep = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n, np.int64)
    cnt = 0
    for i in range(n):
        ok, d, b = diffuse_scatter(u[0, i], u[1, i], u[2, i], cols3(w, i, 0), cols3(ng, i, 0), cols3(ns, i, 0),
                                    cols3(alb, i, 0), cols3(beta, i, 0), adjoint)
        if ok:
            keep[cnt] = i
            for c in range(3):
                d_out[cnt, c], b_out[cnt, c] = d[c], b[c]
            cnt += 1
    return d_out[:cnt], b_out[:cnt], keep[:cnt]


@njit(**JIT)
def cdf_pick(cdf, guide, u):
    """min(np.searchsorted(cdf, u * cdf[-1], side="right"), len(cdf) - 1), the same index, through
    a guide table (Chen and Asau 1974; guide_table): a step or two from guide[int(u G)] instead of a
    binary search's log2(len) mispredicted branches (on 4,000 triangles 10 ns a pick against 64)."""
    n = cdf.shape[0]
    x = u * cdf[n - 1]
    j = guide[min(int(u * guide.shape[0]), guide.shape[0] - 1)]
    while j > 0 and cdf[j - 1] > x:
        j -= 1
    while j < n and cdf[j] <= x:
        j += 1
    return min(j, n - 1)


def guide_table(cdf):
    """cdf_pick's guide over an increasing cdf: entry k is where the search for u = k / len starts."""
    g = len(cdf)
    return np.searchsorted(cdf, np.arange(g) / g * cdf[-1], side="right").astype(np.int64)


@njit(inline="always", **JIT)
def put_vertex(hist, h_prim, lane, j, pr, p, b1, b2, refl, caster):
    """Lane `lane`'s j-th specular vertex as the hand-off reads it: hist[lane, j] (HIST_* columns:
    point, barycentrics, 1 for a reflection, 1 on a planned caster), h_prim[lane, j] its triangle."""
    h_prim[lane, j] = pr
    for c in range(3):
        hist[lane, j, HIST_P + c] = p[c]
    hist[lane, j, HIST_B], hist[lane, j, HIST_B + 1] = b1, b2
    hist[lane, j, HIST_REFL] = 1.0 if refl else 0.0
    hist[lane, j, HIST_CASTER] = 1.0 if caster else 0.0


@njit(inline="always", **JIT)
def _toward_triangle(u0, u1, u2, x, w, g, n, a, beta, aim, geo):
    """bent_gather's first bounce from the diffuse receiver x (w: back to the eye; g, n: its
    normals; a: albedo): towards a point uniform in area over the candidate triangles aim.cand
    (BentTargets; cdf: their cumulative areas, guide: its guide_table; geo: Geometry), weighted by
    the Lambertian BSDF x cosine over
    the point's density in solid angle; kept only where the point's normal bends for that direction
    (optics.scatter1's test, before any ray is cast: on cube_grey_reflect 2.4% of the points do).
    Returns (kept, direction, weight, the triangle the ray must meet first, the point and its
    barycentrics: the vertex the path takes, exactly the one sampled, wherever the offset ray
    origin puts the hit)."""
    zero = (0.0, 0.0, 0.0)
    cdf, tv, tng, tns = aim.cdf, geo.tv, geo.tng, geo.tns
    total = cdf[cdf.shape[0] - 1]
    pr = aim.cand[cdf_pick(cdf, aim.guide, u0)]
    su = math.sqrt(u1)
    b1, b2 = su * (1.0 - u2), su * u2  # uniform over the triangle
    v0 = (tv[pr, 0, 0], tv[pr, 0, 1], tv[pr, 0, 2])
    e1 = (tv[pr, 1, 0] - v0[0], tv[pr, 1, 1] - v0[1], tv[pr, 1, 2] - v0[2])
    e2 = (tv[pr, 2, 0] - v0[0], tv[pr, 2, 1] - v0[1], tv[pr, 2, 2] - v0[2])
    q = sub3(add3(v0, add3(scale3(b1, e1), scale3(b2, e2))), x)
    dist2 = dot1(q, q)
    if not dist2 > 0:
        return False, zero, zero, -1, zero, 0.0, 0.0
    d = scale3(1.0 / math.sqrt(dist2), q)
    side = 1.0 if dot1(w, g) >= 0 else -1.0
    nn = scale3(side, n)
    cos0 = dot1(d, nn)
    cos_p = abs(d[0] * tng[pr, 0] + d[1] * tng[pr, 1] + d[2] * tng[pr, 2])
    if not (cos0 > 0 and side * dot1(d, g) > 0 and dot1(w, nn) > 0 and cos_p > 0):
        return False, zero, zero, -1, zero, 0.0, 0.0
    gp = (tng[pr, 0], tng[pr, 1], tng[pr, 2])
    if not bend1(neg3(d), shading_normal1(tns, pr, b1, b2, gp, d), gp)[1]:  # -d: the eye's direction there
        return False, zero, zero, -1, zero, 0.0, 0.0
    f = cos0 * cos_p * total / (math.pi * dist2)  # (a / pi) cos0 / pdf, pdf = dist^2 / (total cos_p)
    return True, d, (beta[0] * a[0] * f, beta[1] * a[1] * f, beta[2] * a[2] * f), pr, add3(x, q), b1, b2


@njit(**LANES)
def _handoff_rows(ray, key, a0, samples, K, receivers, geo, mats, physical, eps, out, aim):
    """handoff_lanes' loop over its lanes (its caller holds the arrays)."""
    tv, tng, tns, tri_material, mat_kind = geo.tv, geo.tng, geo.tns, geo.tri_material, geo.mat_kind
    tri_object, casters, hid = geo.tri_object, geo.casters, geo.hid
    x0, ng0, ns0, sn0, w0 = receivers.p, receivers.ng, receivers.ns, receivers.sn, receivers.w_eye
    beta0, alb, mat0 = receivers.beta, receivers.albedo, receivers.mat
    seg, seg_n, hist, h_prim = out.seg, out.seg_n, out.hist, out.h_prim
    targeted = aim.cand.shape[0] > 0
    for lane in range(x0.shape[0] * samples):
        seg_n[lane] = 0
        i = lane // samples
        s = lane - i * samples
        g = cols3(ng0, i, 0)
        first, p_first, f1, f2 = -1, (0.0, 0.0, 0.0), 0.0, 0.0
        r = a0 + i
        u0, u1, u2 = keyed_uniform(key, r, s, 0), keyed_uniform(key, r, s, 1), keyed_uniform(key, r, s, 2)
        if targeted:
            ok, d, b, first, p_first, f1, f2 = _toward_triangle(u0, u1, u2, cols3(x0, i, 0), cols3(w0, i, 0), g,
                                                                cols3(ns0, i, 0), cols3(alb, i, 0), cols3(beta0, i, 0),
                                                                aim, geo)
        else:
            ok, d, b = diffuse_scatter(u0, u1, u2, cols3(w0, i, 0), g, cols3(ns0, i, 0),
                                        cols3(alb, i, 0), cols3(beta0, i, 0), False)
        if not ok:
            continue
        kc = coat_factor1(mats, mat0[i], cols3(ns0, i, 0), cols3(w0, i, 0), d, True)  # under a Principled coat
        # and a bumped receiver's shadowing (1 where ns0 is sn0, its smooth normal: no bump)
        kc = scale3(bump_shadowing1(cols3(sn0, i, 0), cols3(ns0, i, 0), d, mats.bump_correction[mat0[i]] != 0), kc)
        b = (b[0] * kc[0], b[1] * kc[1], b[2] * kc[2])
        o = spawn1(cols3(x0, i, 0), g, d, eps)  # tracer.spawn
        medium = -1
        bit = RAY_DIFFUSE  # the kind of the next ray: x0's bounce, then the latest event's
        for bounce in range(K + 1):
            pr, t, p, gg, v0, e1, e2 = hit_or_miss_past(ray, o, d, tv, tng, tri_object, hid, bit, eps)
            if bounce > 0:  # a segment after a specular vertex: the caller looks for lights on it
                k = seg_n[lane]
                for c in range(3):
                    seg[lane, k, SEG_O + c], seg[lane, k, SEG_D + c], seg[lane, k, SEG_BETA + c] = o[c], d[c], b[c]
                seg[lane, k, SEG_T] = t
                seg_n[lane] = k + 1
            if pr < 0 or bounce == K or (bounce == 0 and targeted and pr != first):
                break
            b = absorbed1(mats.kind, mats.absorb, medium, tri_material[pr], d, gg, t, b)
            m = tri_material[pr]
            kind = mat_kind[m]
            if kind != CONDUCTOR and kind != DIELECTRIC:
                break
            if targeted and bounce == 0:  # the sampled point itself (_toward_triangle)
                p, b1, b2 = p_first, f1, f2
            else:
                b1, b2, _, _, _ = barycentric1(e1, e2, sub3(p, v0))
            n = shading_normal1(tns, pr, b1, b2, gg, d)
            ok, dd, bb, bent = scatter1(keyed_uniform3(key, r, s, 3 + bounce), neg3(d), n, gg, m, kind, mats, b,
                                        physical, False)
            if not ok or (targeted and bounce == 0 and not bent):  # bent_gather: bent first vertices only
                break
            if hist.shape[2] > HIST_BENT:
                hist[lane, bounce, HIST_BENT] = 1.0 if bent else 0.0
            refl = dot1(d, n) * dot1(dd, n) < 0
            put_vertex(hist, h_prim, lane, bounce, pr, p, b1, b2, refl, casters[tri_object[pr]])
            bit = RAY_GLOSSY if refl else RAY_TRANSMISSION
            o = spawn1(p, gg, dd, eps)
            medium = medium_after1(m, kind, dd, gg)
            d, b = dd, bb


@TypedOnce
@njit(**JIT)
def handoff_lanes(rt, key, a0, samples, K, receivers, geo, mats, physical, eps, out, aim):
    """indirect.handoff_gather's paths, lane i // samples's receiver (HandoffReceivers: p, ng, ns,
    w_eye: the direction back to the eye, beta: the throughput, albedo; sn: the smooth normal ns
    a bump bent, eye.Receivers.sn): a cosine bounce with
    Russian roulette on the albedo (path_light.diffuse_bounce), then through up to K specular
    vertices (optics.scatter1, not adjoint; physical: scale_eta), every ray cast here. Lane l is
    sample s = l % samples of receiver a0 + l // samples, its uniform numbers keyed_uniform(key,
    a0 + l // samples, s, dim) (dim 0-2: direction and roulette, 3 + j: the j-th specular vertex),
    so a path does not depend on the block or thread that traces it. Writes to out (HandoffOut)
    per lane the segments after each specular vertex, in order, seg_n of them (seg[lane, k]: SEG_O
    origin, SEG_D direction, SEG_T distance to the next surface (inf: none), SEG_BETA throughput),
    and the specular vertices (hist[lane, j]: HIST_* columns, HIST_BENT 1 where Cycles' Bump Map
    Correction bent the normal (optics.scatter1); h_prim[lane, j]: the triangle).

    aim (BentTargets: cand, cdf, guide; indirect.bent_gather; empty: the cosine bounce above): the
    first bounce goes towards a point uniform in area over the triangles cand (cdf: their cumulative
    areas, guide: its guide_table; _toward_triangle), the ray must meet that triangle first, and its
    normal must be one Cycles' Bump Map Correction bends there, or the lane ends. Returns the ray
    counters (embree.ray_state)."""
    ray = ray_state(rt)
    _handoff_rows(ray, key, a0, samples, K, receivers, geo, mats, physical, eps, out, aim)
    return ray.counts


@njit(**JIT)
def segments_near(seg, seg_n, shapes, near):
    """indirect._handoff_block's lights, ahead of their exact test (lights.light_radiance): near[i, k]
    (i < seg's lanes, k < its K) is set where lane i's k-th segment (k < seg_n[i]; seg[i, k]: SEG_O origin,
    SEG_D unit direction) could meet one of the lights shapes describes, a row each: NEAR_ALL (any segment:
    a light at infinity), NEAR_NONE (none: a point), NEAR_SPHERE (centre, radius: any ray that
    passes within it ahead of its origin, or starts inside), NEAR_RECT and NEAR_DISK (an area light:
    centre, x and y axes, normal, half sizes, as lights.area_light_shape: its plane met ahead, in
    front, within 1 + 1e-6 of its half sizes; a ray within 1e-6 of its plane's direction, whose
    distance there the two tests could disagree on, counts). Conservative: every segment the exact
    test finds is set; the callers widen the spheres. seg, shapes: float64; seg_n: int64."""
    m, K = near.shape
    for i in range(m):
        for k in range(K):
            near[i, k] = False
        for k in range(min(seg_n[i], K)):
            o = (seg[i, k, SEG_O], seg[i, k, SEG_O + 1], seg[i, k, SEG_O + 2])
            d = (seg[i, k, SEG_D], seg[i, k, SEG_D + 1], seg[i, k, SEG_D + 2])
            for j in range(shapes.shape[0]):
                kind = int(shapes[j, 0])
                if kind == NEAR_ALL:
                    near[i, k] = True
                elif kind == NEAR_SPHERE:
                    oc = sub3(o, (shapes[j, 1], shapes[j, 2], shapes[j, 3]))
                    r = shapes[j, 4]
                    b = dot1(oc, d)
                    cc = dot1(oc, oc) - r * r
                    near[i, k] = cc <= 0.0 or (b < 0.0 and b * b >= cc)
                elif kind == NEAR_RECT or kind == NEAR_DISK:
                    cen = (shapes[j, 1], shapes[j, 2], shapes[j, 3])
                    nrm = (shapes[j, 10], shapes[j, 11], shapes[j, 12])
                    den = dot1(d, nrm)
                    if den > -1e-6:
                        near[i, k] = den < 1e-6  # behind the light, or along its plane
                    else:
                        tt = dot1(sub3(cen, o), nrm) / den
                        if tt > 0.0:
                            q = sub3(add3(o, scale3(tt, d)), cen)
                            a = dot1(q, (shapes[j, 4], shapes[j, 5], shapes[j, 6])) / shapes[j, 13]
                            c = dot1(q, (shapes[j, 7], shapes[j, 8], shapes[j, 9])) / shapes[j, 14]
                            lim = 1.0 + 1e-6
                            near[i, k] = a * a + c * c <= lim * lim if kind == NEAR_DISK else \
                                (abs(a) <= lim and abs(c) <= lim)
                if near[i, k]:
                    break
