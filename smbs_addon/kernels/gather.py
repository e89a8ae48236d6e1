"""Gathering after a diffuse bounce: cosine paths from receivers through the casters, recording the
segments that may meet a light and the diffuse vertices to light directly.
"""
from __future__ import annotations


from numba import njit
from ..scene.arrays import CONDUCTOR, DIELECTRIC, DIFFUSE, RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMISSION
from ..core.embree import KINDS, ray_state
from .records import SEG_BETA, SEG_D, SEG_O, SEG_OBJ, SEG_REFL, SEG_T, VX_BETA, VX_NG, VX_NS, VX_OBJ, VX_P, VX_W
from .typed import TypedOnce
from .handoff import diffuse_scatter
from .photons import fits_limits
from .eye import next_past
from ..shading.absorption import absorbed1, medium_after1
from ..core.vec3 import add3, cols3, dot1, neg3, scale3
from ..shading.coat import coat_factor1, table_weight1
from .keyed import keyed_uniform, keyed_uniform3
from ..shading.optics import scatter1

from ..core.jit import JIT, LANES


@njit(**LANES)
def _gather_rows(ray, key, lane0, x0, ng0, ns0, w0, beta0, mat0, prior, geo, mats, lim, max_specular, physical,
                 count_first, want_seg, want_vx, eps, seg, seg_i, vx, vx_i):
    """gather_lanes' loop over its lanes from lane0 (its caller holds the arrays).
    Returns (the lane it stopped before: the last + 1, or one whose records did not fit; segment
    records written; vertex records written)."""
    tv, tng, tns, tri_material, mat_kind, tri_object, casters, _, hid = geo
    mat_color = mats[2]
    counts = ray[6]
    nseg = nvx = 0
    for lane in range(lane0, x0.shape[0]):
        # what to restore if this lane's records do not fit (it is traced again in the next call)
        s0, v0_, c0, c1, c2 = nseg, nvx, counts[0], counts[1], counts[KINDS]
        full = False
        p, g, n, w, b = cols3(x0, lane, 0), cols3(ng0, lane, 0), cols3(ns0, lane, 0), cols3(w0, lane, 0), cols3(beta0, lane, 0)
        m = mat0[lane]
        nd, ngl, nt = prior[lane, 0], prior[lane, 1], prior[lane, 2]  # every event so far
        has_s = False  # a specular vertex on a planned caster so far
        depth = 0  # diffuse vertices after x0
        ev = 0  # the lane's events, keying its random numbers
        while True:
            # a diffuse bounce is never a caustic path's last event: it must fit the limits
            if not fits_limits(lim, nd + 1, ngl, nt):
                break
            ok, d, b = diffuse_scatter(keyed_uniform(key, lane, ev, 0), keyed_uniform(key, lane, ev, 1),
                                        keyed_uniform(key, lane, ev, 2), w, g, n, cols3(mat_color, m, 0), b, False)
            ev += 1
            if not ok:
                break
            if depth == 0:  # x0 under a Principled coat: what on-minus-off keeps (layer.coat_factor)
                kc = coat_factor1(mats, m, n, w, d, True)
                b = (b[0] * kc[0], b[1] * kc[1], b[2] * kc[2])
            nd += 1
            bd, bg, bt = nd, ngl, nt  # the events before the latest
            o = add3(p, scale3(eps if dot1(d, g) >= 0 else -eps, g))  # tracer.spawn
            last_caster = False
            last_obj = -1  # the latest specular vertex's object
            last_refl = False  # the latest specular event a reflection
            go_on = False  # a next diffuse vertex to bounce from
            medium = -1
            for bounce in range(max_specular + 1):
                # past what this ray's kind does not meet: the diffuse bounce's, then the latest event's
                bit = RAY_DIFFUSE if bounce == 0 else (RAY_GLOSSY if last_refl else RAY_TRANSMISSION)
                pr, t, hp, hg, hn, _, _ = next_past(ray, o, d, tv, tng, tns, tri_object, hid, bit, eps)
                if (want_seg and bounce > 0 and last_caster and (depth >= 1 or count_first)
                        and fits_limits(lim, bd, bg, bt)):
                    if nseg == seg.shape[0]:
                        full = True
                        break
                    for c in range(3):
                        seg[nseg, SEG_O + c], seg[nseg, SEG_D + c], seg[nseg, SEG_BETA + c] = o[c], d[c], b[c]
                    seg[nseg, SEG_T] = t
                    seg[nseg, SEG_REFL] = 1.0 if last_refl else 0.0
                    seg[nseg, SEG_OBJ] = last_obj
                    seg_i[nseg] = lane
                    nseg += 1
                if pr < 0:
                    break
                b = absorbed1(mats[0], mats[10], medium, tri_material[pr], d, hg, t, b)
                hm = tri_material[pr]
                kind = mat_kind[hm]
                if kind == DIFFUSE:  # the next diffuse vertex
                    depth += 1
                    p, g, n, w, m = hp, hg, hn, neg3(d), hm
                    b = scale3(table_weight1(mats[6], m, dot1(w, n)), b)  # under its glossy layer, towards w
                    if want_vx and has_s and fits_limits(lim, nd, ngl, nt):  # direct light: every event before fits
                        if nvx == vx.shape[0]:
                            full = True
                            break
                        a = cols3(mat_color, m, 0)
                        for c in range(3):
                            vx[nvx, VX_P + c], vx[nvx, VX_NG + c], vx[nvx, VX_NS + c] = p[c], g[c], n[c]
                            vx[nvx, VX_W + c], vx[nvx, VX_BETA + c] = w[c], b[c] * a[c]
                        vx[nvx, VX_OBJ] = tri_object[pr]
                        vx_i[nvx] = lane
                        nvx += 1
                    go_on = True
                    break
                if not (kind == CONDUCTOR or kind == DIELECTRIC) or bounce == max_specular:
                    break
                ok, dd, bb, _ = scatter1(keyed_uniform3(key, lane, ev, 0), neg3(d), hn, hg, hm, kind, mats, b,
                                         physical, False)
                ev += 1
                if not ok:
                    break
                last_obj = tri_object[pr]
                last_caster = casters[last_obj]
                has_s = has_s or last_caster
                bd, bg, bt = nd, ngl, nt
                last_refl = dot1(d, hg) * dot1(dd, hg) < 0  # bounces.specular_kind
                if last_refl:
                    ngl += 1
                else:
                    nt += 1
                if not fits_limits(lim, bd, bg, bt):  # the events before the latest no longer fit
                    break
                o = add3(hp, scale3(eps if dot1(dd, hg) >= 0 else -eps, hg))
                medium = medium_after1(hm, kind, dd, hg)
                d, b = dd, bb
            if full or not go_on:
                break
        if full:
            counts[0], counts[1], counts[KINDS] = c0, c1, c2
            return lane, s0, v0_
    return x0.shape[0], nseg, nvx


@TypedOnce
@njit(**JIT)
def gather_lanes(rt, key, lane0, x0, ng0, ns0, w0, beta0, mat0, prior, geo, mats, lim, max_specular, physical,
                 count_first, want_seg, want_vx, eps, seg, seg_i, vx, vx_i):
    """indirect.gather's paths for the light tracer (no walks to connect): from each receiver x0
    (x0, ng0, ns0, w0: the direction back to the eye, beta0: the eye path's throughput, mat0, prior:
    the camera's events before x0), cosine bounces with Russian roulette (diffuse_scatter)
    through up to max_specular mirrors and glass (optics.scatter1, not adjoint; physical:
    scale_eta) to the next diffuse vertices, within the Light Paths limits (lim: Limits.array()),
    every ray cast here, the random numbers keyed_uniform(key, lane, event, .).

    Writes, for the caller to light: with want_seg, the segments right after a specular vertex
    on a caster (seg: SEG_* columns; seg_i: the lane) from x0 when count_first, else from later
    diffuse vertices, whose events before the latest fit; with want_vx, the later diffuse
    vertices with a specular vertex on a caster behind them whose events fit (vx: VX_* columns,
    the throughput times the vertex's albedo; vx_i: the lane). A lane whose records would not
    fit is left whole for the next call. Returns (the lane to go on from, x0's length when done;
    segments written; vertices written; the ray counters, embree.ray_state)."""
    ray = ray_state(rt)
    nxt, nseg, nvx = _gather_rows(ray, key, lane0, x0, ng0, ns0, w0, beta0, mat0, prior, geo, mats, lim,
                                  max_specular, physical, count_first, want_seg, want_vx, eps, seg, seg_i, vx, vx_i)
    return nxt, nseg, nvx, ray[6]
