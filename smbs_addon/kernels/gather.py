"""Gathering after a diffuse bounce: cosine paths from receivers through the casters, recording the
segments that may meet a light and the diffuse vertices to light directly.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit
from ..scene.arrays import CONDUCTOR, DIELECTRIC, DIFFUSE, RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMISSION
from ..scene.light_paths import DIFFUSE_EVENTS, GLOSSY_EVENTS, TRANSMISSION_EVENTS
from ..core.embree import KINDS, LOGGED, SEEN, ray_state
from .records import (CX_BETA, CX_CNT, CX_MAT, CX_NG, CX_NS, CX_P, CX_W, SEG_BETA, SEG_D, SEG_O, SEG_OBJ, SEG_REFL, SEG_T,
                      VX_BETA, VX_NG, VX_NS, VX_OBJ, VX_P, VX_W)
from .typed import TypedOnce
from .handoff import diffuse_scatter
from .photons import fits_limits
from .eye import next_past
from .chain import spawn1
from ..shading.absorption import absorbed1, medium_after1
from ..core.vec3 import cols3, dot1, neg3, scale3
from ..shading.coat import coat_factor1, table_weight1
from .keyed import keyed_uniform, keyed_uniform3
from ..shading.optics import scatter1

from ..core.jit import JIT, LANES


# A gather path's diffuse vertex (_gather_bounces): point, geometric and shading normals, the
# direction back along the path, material
_Vertex = namedtuple("_Vertex", "p g n w m")

# A gather lane's counts so far (_gather_rows): every event of the path (Cycles' diffuse, glossy and
# transmission), whether a specular vertex on a planned caster lies behind, the diffuse vertices
# after x0, the random numbers' events (keying them); and the call's records written (segments,
# vertices)
_Counts = namedtuple("_Counts", "nd ngl nt has_s depth ev nseg nvx ncx")


@njit(inline="always", **JIT)
def _put_segment(seg, seg_i, row, lane, o, d, t, b, refl, obj):
    """A segment record at row `row` of seg (SEG_* columns) and seg_i (its lane)."""
    for c in range(3):
        seg[row, SEG_O + c], seg[row, SEG_D + c], seg[row, SEG_BETA + c] = o[c], d[c], b[c]
    seg[row, SEG_T] = t
    seg[row, SEG_REFL] = 1.0 if refl else 0.0
    seg[row, SEG_OBJ] = obj
    seg_i[row] = lane


@njit(inline="always", **JIT)
def _put_vertex(vx, vx_i, row, lane, v, b, a, obj):
    """A vertex record at row `row` of vx (VX_* columns: v's point, normals and direction back, the
    throughput b times the albedo a, the object) and vx_i (its lane)."""
    for c in range(3):
        vx[row, VX_P + c], vx[row, VX_NG + c], vx[row, VX_NS + c] = v.p[c], v.g[c], v.n[c]
        vx[row, VX_W + c], vx[row, VX_BETA + c] = v.w[c], b[c] * a[c]
    vx[row, VX_OBJ] = obj
    vx_i[row] = lane


@njit(inline="always", **JIT)
def _put_connect(cx, cx_i, row, lane, v, b, nd, ngl, nt):
    """A connect record at row `row` of cx (CX_* columns: v's point, normals, direction back and
    material, the throughput b, the events so far: nd diffuse, ngl glossy, nt transmission) and cx_i
    (its lane)."""
    for c in range(3):
        cx[row, CX_P + c], cx[row, CX_NG + c], cx[row, CX_NS + c] = v.p[c], v.g[c], v.n[c]
        cx[row, CX_W + c], cx[row, CX_BETA + c] = v.w[c], b[c]
    cx[row, CX_MAT] = v.m
    cx[row, CX_CNT], cx[row, CX_CNT + 1], cx[row, CX_CNT + 2] = nd, ngl, nt
    cx_i[row] = lane


@njit(inline="always", **JIT)
def _gather_bounces(ray, key, lane, vx0, d, b, cnt, geo, mats, rules, eps, out):
    """A gather path from its diffuse vertex vx0 (_Vertex) along d (its bounce, weight b) through up
    to rules.max_specular mirrors and glass (GatherRules) to the next diffuse vertex: the segments
    after a specular vertex on a caster and that vertex recorded in out (GatherOut) as
    gather_lanes says. Returns (whether a record did not fit, whether the path goes on from a next
    diffuse vertex, that vertex, the weight, the counts after it (_Counts))."""
    tv, tng, tns, tri_material, mat_kind = geo.tv, geo.tng, geo.tns, geo.tri_material, geo.mat_kind
    tri_object, casters, hid = geo.tri_object, geo.casters, geo.hid
    lim, max_specular = rules.lim, rules.max_specular
    seg, vx = out.seg, out.vx
    nd, ngl, nt, has_s, depth, ev, nseg, nvx, ncx = (cnt.nd, cnt.ngl, cnt.nt, cnt.has_s, cnt.depth, cnt.ev, cnt.nseg,
                                                     cnt.nvx, cnt.ncx)
    v = vx0
    bd, bg, bt = nd, ngl, nt  # the events before the latest
    o = spawn1(v.p, v.g, d, eps)  # tracer.spawn
    last_caster = False
    last_obj = -1  # the latest specular vertex's object
    last_refl = False  # the latest specular event a reflection
    go_on = False  # a next diffuse vertex to bounce from
    full = False
    medium = -1
    for bounce in range(max_specular + 1):
        # past what this ray's kind does not meet: the diffuse bounce's, then the latest event's
        bit = RAY_DIFFUSE if bounce == 0 else (RAY_GLOSSY if last_refl else RAY_TRANSMISSION)
        pr, t, hp, hg, hn, _, _ = next_past(ray, o, d, tv, tng, tns, tri_object, hid, bit, eps)
        if (rules.want_seg and bounce > 0 and last_caster and (depth >= 1 or rules.count_first)
                and fits_limits(lim, bd, bg, bt)):
            if nseg == seg.shape[0]:
                full = True
                break
            _put_segment(seg, out.seg_i, nseg, lane, o, d, t, b, last_refl, last_obj)
            nseg += 1
        if pr < 0 or rules.ends[tri_object[pr]]:  # nothing, or a caster the plan left out: the path ends
            break
        b = absorbed1(mats.kind, mats.absorb, medium, tri_material[pr], d, hg, t, b)
        hm = tri_material[pr]
        kind = mat_kind[hm]
        if kind == DIFFUSE:  # the next diffuse vertex
            depth += 1
            v = _Vertex(hp, hg, hn, neg3(d), np.int64(hm))  # (the receivers' materials are int64)
            b = scale3(table_weight1(mats.weight, hm, dot1(v.w, hn)), b)  # under its glossy layer, towards w
            if rules.want_vx and has_s and fits_limits(lim, nd, ngl, nt):  # direct light: every event before fits
                if nvx == vx.shape[0]:
                    full = True
                    break
                _put_vertex(vx, out.vx_i, nvx, lane, v, b, cols3(mats.color, hm, 0), tri_object[pr])
                nvx += 1
            # the walks' caustic at a planned receiver: its own bounce must fit
            if rules.want_cx and rules.receivers[tri_object[pr]] and fits_limits(lim, nd + 1, ngl, nt):
                if ncx == out.cx.shape[0]:
                    full = True
                    break
                _put_connect(out.cx, out.cx_i, ncx, lane, v, b, nd, ngl, nt)
                ncx += 1
            go_on = True
            break
        if not (kind == CONDUCTOR or kind == DIELECTRIC) or bounce == max_specular:
            break
        ok, dd, bb, _ = scatter1(keyed_uniform3(key, lane, ev, 0), neg3(d), hn, hg, hm, kind, mats, b,
                                 rules.physical, False)
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
        o = spawn1(hp, hg, dd, eps)
        medium = medium_after1(hm, kind, dd, hg)
        d, b = dd, bb
    return full, go_on, v, b, _Counts(nd, ngl, nt, has_s, depth, ev, nseg, nvx, ncx)


@njit(**LANES)
def _gather_rows(ray, key, lane0, receivers, geo, mats, rules, eps, out):
    """gather_lanes' loop over its lanes from lane0 (its caller holds the arrays).
    Returns (the lane it stopped before: the last + 1, or one whose records did not fit; segment
    records written; vertex records written; connect records written)."""
    x0, lim, u0 = receivers.p, rules.lim, receivers.u0
    counts = ray.counts
    nseg = nvx = ncx = 0
    for lane in range(lane0, x0.shape[0]):
        # what to restore if this lane's records do not fit (it is traced again in the next call)
        s0, v0_, x0_, c0, c1, c2 = nseg, nvx, ncx, counts[LOGGED], counts[SEEN], counts[KINDS]
        full = False
        v = _Vertex(cols3(x0, lane, 0), cols3(receivers.ng, lane, 0), cols3(receivers.ns, lane, 0),
                    cols3(receivers.w_eye, lane, 0), receivers.mat[lane])
        b = cols3(receivers.beta, lane, 0)
        prior = receivers.prior
        # every event so far; a specular vertex on a planned caster so far; diffuse vertices after x0;
        # the lane's events, keying its random numbers
        cnt = _Counts(prior[lane, DIFFUSE_EVENTS], prior[lane, GLOSSY_EVENTS], prior[lane, TRANSMISSION_EVENTS], False,
                      np.int64(0), np.int64(0), nseg, nvx, ncx)
        while True:
            # a diffuse bounce is never a caustic path's last event: it must fit the limits
            if not fits_limits(lim, cnt.nd + 1, cnt.ngl, cnt.nt):
                break
            ev = cnt.ev
            ua, ub = keyed_uniform(key, lane, ev, 0), keyed_uniform(key, lane, ev, 1)
            if cnt.depth == 0 and u0.shape[0] > 0:  # x0's own bounce, stratified (its direction's two numbers)
                ua, ub = u0[lane, 0], u0[lane, 1]
            ok, d, b = diffuse_scatter(ua, ub, keyed_uniform(key, lane, ev, 2), v.w, v.g, v.n, cols3(mats.color, v.m, 0),
                                       b, False)
            cnt = _Counts(cnt.nd, cnt.ngl, cnt.nt, cnt.has_s, cnt.depth, ev + 1, cnt.nseg, cnt.nvx, cnt.ncx)
            if not ok:
                break
            if cnt.depth == 0:  # x0 under a Principled coat: what on-minus-off keeps (coat.coat_factor1)
                kc = coat_factor1(mats, v.m, v.n, v.w, d, True)
                b = (b[0] * kc[0], b[1] * kc[1], b[2] * kc[2])
            cnt = _Counts(cnt.nd + 1, cnt.ngl, cnt.nt, cnt.has_s, cnt.depth, cnt.ev, cnt.nseg, cnt.nvx, cnt.ncx)
            full, go_on, v, b, cnt = _gather_bounces(ray, key, lane, v, d, b, cnt, geo, mats, rules, eps, out)
            if full or not go_on:
                break
        nseg, nvx, ncx = cnt.nseg, cnt.nvx, cnt.ncx
        if full:
            counts[LOGGED], counts[SEEN], counts[KINDS] = c0, c1, c2
            return lane, s0, v0_, x0_
    return x0.shape[0], nseg, nvx, ncx


@TypedOnce
@njit(**JIT)
def gather_lanes(rt, key, lane0, receivers, geo, mats, rules, eps, out):
    """indirect.gather's paths, the light tracer's and the walks' (who connect at the vertices recorded
    here): from each receiver x0 (GatherReceivers: p, ng, ns, w_eye: the direction back to the eye,
    beta: the eye path's throughput, mat, prior: the camera's events before x0), cosine bounces with Russian roulette
    (diffuse_scatter; x0's own bounce direction from receivers.u0 where given) through up to
    rules.max_specular mirrors and glass (GatherRules; optics.scatter1, not adjoint; physical:
    scale_eta) to the next diffuse vertices, within the Light Paths limits (lim: Limits.array()),
    every ray cast here, the random numbers keyed_uniform(key, lane, event, .); a path ends at an
    object of rules.ends.

    Writes to out (GatherOut), for the caller to light: with want_seg, the segments right after a
    specular vertex on a caster (seg: SEG_* columns; seg_i: the lane) from x0 when count_first,
    else from later diffuse vertices, whose events before the latest fit; with want_vx, the later
    diffuse vertices with a specular vertex on a caster behind them whose events fit (vx: VX_*
    columns, the throughput times the vertex's albedo; vx_i: the lane); with want_cx, the later
    diffuse vertices on an object of rules.receivers whose events and own bounce fit, for the walks
    to estimate their caustic (cx: CX_* columns; cx_i: the lane). A lane whose records would not fit
    is left whole for the next call. Returns (the lane to go on from, x0's length when done;
    segments written; vertices written; connect records written; the ray counters,
    embree.ray_state)."""
    ray = ray_state(rt)
    nxt, nseg, nvx, ncx = _gather_rows(ray, key, lane0, receivers, geo, mats, rules, eps, out)
    return nxt, nseg, nvx, ncx, ray.counts
