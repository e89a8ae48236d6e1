"""The light tracer's photons: from a light through mirrors and glass to their first diffuse vertex,
recorded for the splat into the camera (and, after a diffuse bounce, onward).
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit
from ..scene.arrays import CONDUCTOR, DIELECTRIC, DIFFUSE, PATH_RAYS, RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMISSION
from ..scene.light_paths import ALL_EVENTS, DIFFUSE_EVENTS, GLOSSY_EVENTS, TRANSMISSION_EVENTS
from .records import HIDDEN_PASSES, PH_BEYOND, PH_LOST, PH_PHOTONS, PH_TRUNCATED
from ..core.embree import KINDS, LOGGED, SEEN, ray_state
from .typed import TypedOnce
from .chain import shading_normal1, spawn1
from .eye import put_record
from .handoff import diffuse_scatter, put_vertex
from ..shading.absorption import absorbed1, medium_after1
from ..core.vec3 import cols3, dot1, max_nan, neg3, scale3, sub3
from .keyed import keyed_uniform, keyed_uniform3
from ..shading.optics import scatter1
from ..shading.coat import table_weight1

from ..core.jit import JIT, LANES
from .rays import next_surface


@njit(**JIT)
def fits_limits(lim, d, g, t):
    """bounces.Limits.allowed of event counts d, g, t; lim = Limits.array()."""
    return (d <= lim[DIFFUSE_EVENTS] and g <= lim[GLOSSY_EVENTS] and t <= lim[TRANSMISSION_EVENTS]
            and d + g + t <= lim[ALL_EVENTS])


# What a photon does at a surface (_photon_passes): meets it, passes it, or ends there
_MEET, _PASS, _END = 0, 1, 2

# A photon's path so far (_photon_path): its events (the path's vertices so far), Cycles' diffuse,
# glossy and transmission events, its diffuse vertices (indirect), whether a specular vertex on a
# planned caster lies behind (indirect)
_Events = namedtuple("_Events", "it nd ngl nt n_diff has_s")

# The surface a photon meets (_photon_path): its triangle, point, geometric and shading normals,
# barycentrics b1, b2; the triangle's material, its kind and object
_Hit = namedtuple("_Hit", "pr p g n b1 b2 m kind obj")


@njit(inline="always", **JIT)
def _photon_passes(photons, key, lane, it, pr, geo, indirect, b, n_unshadow, passed, n_pass):
    """Whether photon `lane` (of photons, PhotonBatch) at its event it passes the surface of triangle pr
    (_PASS), ends there (_END: past HIDDEN_PASSES such surfaces) or meets it (_MEET).

    Shadow Linking: Cycles' rays to the light pass an object that does not shadow it, and a path
    that meets the object goes on from it too: where it could (the object lit, and a caster, or any
    surface for the indirect photons), either, at random, weighted 2; else passed. Ray Visibility
    (geo's hid, Scene.hidden_kinds): a surface some kinds of ray do not meet: the path may pass it or
    meet it, as the kind of the ray the next vertex casts decides (checked there): hidden from all,
    it is passed; else either, at random, weighted 2.

    Returns (that; the weight b; the objects passed that do not shadow the light, the kinds of ray
    of the surfaces passed since the last vertex, and how many were passed)."""
    ob = geo.tri_object[pr]
    unshadowing, lit, hid = photons.unshadowing, photons.lit, geo.hid
    if it == 0 and unshadowing.shape[0] > 0 and unshadowing[ob]:
        k0 = geo.mat_kind[geo.tri_material[pr]]
        go_on = (lit.shape[0] == 0 or lit[ob]) and (indirect or ((k0 == CONDUCTOR or k0 == DIELECTRIC)
                                                                 and geo.casters[ob]))
        go_past = True
        if go_on:
            go_past = keyed_uniform(key, lane, it, 4 + HIDDEN_PASSES + n_unshadow) < 0.5
            b = scale3(2.0, b)
        if go_past:
            if n_unshadow == HIDDEN_PASSES:
                return _END, b, n_unshadow, passed, n_pass
            return _PASS, b, n_unshadow + 1, passed, n_pass
    h = hid[ob] & PATH_RAYS if hid.shape[0] > 0 else 0
    if h != 0:
        go_past = h == PATH_RAYS
        if not go_past:
            go_past = keyed_uniform(key, lane, it, 3 + n_pass) < 0.5
            b = scale3(2.0, b)
        if go_past:
            if n_pass == HIDDEN_PASSES:
                return _END, b, n_unshadow, passed, n_pass
            return _PASS, b, n_unshadow, passed | (PATH_RAYS & ~h), n_pass + 1
    return _MEET, b, n_unshadow, passed, n_pass


@njit(inline="always", **JIT)
def _photon_diffuse(key, lane, d, hit, b, ev, diffuse_seen, mats, rules):
    """An indirect photon's diffuse bounce at hit (_Hit), within the Light Paths
    limits, its direction back towards the previous vertex seen (diffuse_seen): (kept, new
    direction, new weight, the events after it)."""
    zero = (0.0, 0.0, 0.0)
    it, m = ev.it, hit.m
    step = 0 if it == 0 else 1  # the photon's first event is the path's free last one
    if not fits_limits(rules.lim, ev.nd + step + 1, ev.ngl, ev.nt) or not diffuse_seen:
        return False, zero, zero, ev
    ok, dd, bb = diffuse_scatter(keyed_uniform(key, lane, it, 0), keyed_uniform(key, lane, it, 1),
                                  keyed_uniform(key, lane, it, 2), neg3(d), hit.g, hit.n, cols3(mats.color, m, 0),
                                  b, True)
    if not ok:
        return False, zero, zero, ev
    # the eye's path, the other way, arrives here from dd: the glossy layer's share
    bb = scale3(table_weight1(mats.weight, m, dot1(dd, hit.n)), bb)
    return True, dd, bb, _Events(it, ev.nd + step, ev.ngl, ev.nt, ev.n_diff + 1, ev.has_s)


@njit(inline="always", **JIT)
def _photon_specular(key, lane, d, hit, b, ev, prev_vis, passed, geo, mats, rules, out):
    """A photon's specular event at hit (_Hit) within its rules (PhotonRules): (kept, new
    direction, new weight, the events after it). A caustic photon stops past rules.max_bounces; a
    photon whose ray towards the light would not meet the previous vertex (prev_vis, passed: the
    kinds of ray it meets and those of the surfaces passed since) or whose events no splat can fit
    any more stops. Adds to out.tally (PH_TRUNCATED, PH_LOST, PH_BEYOND); writes the hand-off's
    record of the vertex (out.hist, out.h_prim) for its first K events."""
    zero = (0.0, 0.0, 0.0)
    it, pr, m, kind, g, n = ev.it, hit.pr, hit.m, hit.kind, hit.g, hit.n
    tally, casters = out.tally, geo.casters
    spec = kind == CONDUCTOR or kind == DIELECTRIC
    if not rules.indirect and it == 0:
        spec = spec and casters[hit.obj]  # a caustic photon's first hit: a planned caster
    if not rules.indirect and it >= rules.max_bounces:
        if spec:
            tally[PH_TRUNCATED] += 1
        return False, zero, zero, ev
    if not spec:
        return False, zero, zero, ev
    if kind == DIELECTRIC and geo.tns.shape[1] == 6:
        # a bumped glass's normals as Cycles' eye path meets them: through the glass it
        # comes from the side the photon goes to (bump.py; a Fresnel reflection or a total
        # internal one off such a surface takes them from the wrong side)
        n = shading_normal1(geo.tns, pr, hit.b1, hit.b2, g, neg3(d))
    ok, dd, bb, _ = scatter1(keyed_uniform3(key, lane, it, 0), neg3(d), n, g, m, kind, mats, b,
                             not rules.physical, True)
    if not ok:
        tally[PH_LOST] += 1
        return False, zero, zero, ev
    refl = dot1(d, g) * dot1(dd, g) < 0  # bounces.specular_kind
    e = RAY_GLOSSY if refl else RAY_TRANSMISSION
    if not prev_vis & e or passed & e:
        return False, zero, zero, ev  # the ray this vertex casts towards the light does not meet the previous vertex
    step = 0 if it == 0 else 1
    ngl, nt = ev.ngl, ev.nt
    if refl:
        ngl += step
    else:
        nt += step
    if not fits_limits(rules.lim, ev.nd + 1, ngl, nt):  # no splat can fit any more
        tally[PH_BEYOND] += 1
        return False, zero, zero, ev
    if it < out.hist.shape[1]:  # the hand-off's record of the chain, light side first
        put_vertex(out.hist, out.h_prim, lane, it, pr, hit.p, hit.b1, hit.b2, dot1(d, n) * dot1(dd, n) < 0,
                   casters[hit.obj])
    return True, dd, bb, _Events(it, ev.nd, ngl, nt, ev.n_diff, ev.has_s or casters[hit.obj])


@njit(inline="always", **JIT)
def _photon_path(ray, photons, key, lane, b, geo, receivers, mats, rules, eps, out, nrec):
    """The path of photon `lane` (flux b) from its light to its end (photon_lanes), its splat
    records written from row nrec of out.rec on. Returns (the rows written up to, whether a record
    did not fit)."""
    tri_material, mat_kind, tri_object, hid = geo.tri_material, geo.mat_kind, geo.tri_object, geo.hid
    indirect, lim, lit = rules.indirect, rules.lim, photons.lit
    soft_c, soft_r = photons.soft_center, photons.soft_radius
    o, d = cols3(photons.o, lane, 0), cols3(photons.d, lane, 0)
    # events so far as Cycles counts them: diffuse, glossy, transmission; diffuse vertices, a specular
    # vertex on a planned caster (indirect); the path's vertices (the photon's events)
    ev = _Events(np.int64(0), np.int64(0), np.int64(0), np.int64(0), np.int64(0), False)
    medium = -1  # inside a glass (its material) or not
    # Ray Visibility (geo's hid, Scene.hidden_kinds): the kinds of ray the previous vertex meets (the
    # light's at first), those the surfaces passed since meet (a ray of such a kind would have stopped
    # there), and how many were passed
    prev_vis, passed, n_pass = photons.visibility, 0, 0
    n_unshadow = 0  # objects that do not shadow the light passed on the first segment (Shadow Linking)
    while ev.it < rules.max_iter:
        it = ev.it
        pr, t, p, g, n, b1, b2 = next_surface(ray, o, d, geo.tv, geo.tng, geo.tns, eps)
        if pr < 0:
            break
        b = absorbed1(mats.kind, mats.absorb, medium, tri_material[pr], d, g, t, b)
        act, b, n_unshadow, passed, n_pass = _photon_passes(photons, key, lane, it, pr, geo, indirect, b, n_unshadow,
                                                            passed, n_pass)
        if act == _END:
            break
        if act == _PASS:
            o = spawn1(p, g, d, eps)  # tracer.spawn, on along d
            continue
        if it == 0 and soft_r > 0:  # lights.soft_falloff_factor
            dc = sub3(p, (soft_c[0], soft_c[1], soft_c[2]))
            d2 = dot1(dc, dc)
            b = scale3(d2 / (d2 + soft_r * soft_r), b)
        m = tri_material[pr]
        kind = mat_kind[m]
        obj = tri_object[pr]
        if it == 0 and lit.shape[0] > 0 and not lit[obj]:
            break  # Light Linking: the light does not light the object the camera's path leaves it from
        # a splat where the camera's x0 would be: after a specular vertex (indirect: after a
        # specular vertex on a caster and a diffuse one), x0's own bounce within the limits
        # a diffuse event casts a diffuse ray towards where the photon came from: it must meet the previous
        # vertex and pass what the photon passed
        diffuse_seen = (prev_vis & RAY_DIFFUSE) != 0 and (passed & RAY_DIFFUSE) == 0
        if (kind == DIFFUSE and receivers[obj] and fits_limits(lim, ev.nd + 1, ev.ngl, ev.nt) and diffuse_seen
                and ((ev.has_s and ev.n_diff >= 1) if indirect else it > 0)):
            if nrec == out.rec.shape[0]:
                return nrec, True
            put_record(out.rec, out.rec_i, nrec, p, g, n, neg3(d), b, lane, it, m)
            nrec += 1
        hit = _Hit(pr, p, g, n, b1, b2, m, kind, obj)
        if indirect and kind == DIFFUSE:
            ok, dd, bb, ev = _photon_diffuse(key, lane, d, hit, b, ev, diffuse_seen, mats, rules)
        else:
            ok, dd, bb, ev = _photon_specular(key, lane, d, hit, b, ev, prev_vis, passed, geo, mats, rules, out)
        if not ok:
            break
        o = spawn1(p, g, dd, eps)  # tracer.spawn
        medium = medium_after1(m, kind, dd, g)
        d, b = dd, bb
        prev_vis, passed, n_pass = PATH_RAYS & ~hid[obj] if hid.shape[0] > 0 else PATH_RAYS, 0, 0
        ev = _Events(it + 1, ev.nd, ev.ngl, ev.nt, ev.n_diff, ev.has_s)
    return nrec, False


@njit(**LANES)
def _photon_rows(ray, photons, key, lane0, geo, receivers, mats, rules, eps, out):
    """photon_lanes' loop over its lanes from lane0 (its caller holds the arrays).
    Returns (the lane it stopped before: the last + 1, or one whose records did not fit; records
    written)."""
    counts, tally = ray.counts, out.tally
    nrec = 0
    for lane in range(lane0, photons.o.shape[0]):
        b = cols3(photons.w, lane, 0)
        if not max_nan(max_nan(b[0], b[1]), b[2]) > 0:
            continue
        # what to restore if this lane's records do not fit (it is traced again in the next call)
        rec0, c0, c1, c2 = nrec, counts[LOGGED], counts[SEEN], counts[KINDS]
        t0 = (tally[0], tally[1], tally[2], tally[3])
        tally[PH_PHOTONS] += 1
        nrec, full = _photon_path(ray, photons, key, lane, b, geo, receivers, mats, rules, eps, out, nrec)
        if full:
            counts[LOGGED], counts[SEEN], counts[KINDS] = c0, c1, c2
            tally[0], tally[1], tally[2], tally[3] = t0
            return lane, rec0
    return photons.o.shape[0], nrec


@TypedOnce
@njit(**JIT)
def photon_lanes(rt, photons, key, lane0, geo, receivers, mats, rules, eps, out):
    """The light tracer's photons (PhotonBatch: o, d: origin and unit direction; w: flux), each
    traced from its light to its end by its rules (PhotonRules), every ray cast here, its random
    numbers keyed_uniform(key, lane, event, .): the same path whichever call or thread traces it.

    Caustic photons (reference.trace_photons, indirect False): the first hit a planned caster,
    then through mirrors and glass (optics.scatter1, adjoint; physical: Cycles' radiance is not
    scaled at refractions, so the flux is), up to max_bounces specular vertices; a record where
    the path meets a diffuse receiver after at least one. Indirect photons (indirect
    .trace_photons): every surface, diffuse bounces with Russian roulette (diffuse_scatter),
    up to max_iter events; a record at each diffuse receiver once the path holds a specular
    vertex on a caster and a diffuse one. Both keep the scene's Light Paths limits (lim:
    Limits.array(); bounces.py: the photon's first event is free, x0's diffuse bounce counts).
    soft_center, soft_radius: a soft-falloff light's (radius 0: none), applied at the first hit;
    visibility: the rays that see the light (scene.RAY_* bits): the first event must cast such a ray; lit:
    (O,) bool, the objects the light lights (Light Linking: the first event must be on one; empty: any);
    unshadowing: (O,) bool, the objects that do not shadow it (Shadow Linking: the first segment passes
    them, or where the path could go on from one, passes it or meets it at random; empty: none).

    Writes to out (PhotonOut) splat records (rec: REC_* columns, rec_i: lane, specular bounces
    before it, material) and, for the hand-off, the first K = hist.shape[1] specular vertices of
    each lane (hist: HIST_* columns but HIST_BENT; h_prim: the triangle); adds to tally (PH_*).
    Returns (the lane to go on from, photons.o's length when done: a lane whose records would not
    fit in rec is left whole for the next call; records written; the ray counters,
    embree.ray_state)."""
    ray = ray_state(rt)
    nxt, nrec = _photon_rows(ray, photons, key, lane0, geo, receivers, mats, rules, eps, out)
    return nxt, nrec, ray.counts
