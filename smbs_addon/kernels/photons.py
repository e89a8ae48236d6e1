"""The light tracer's photons: from a light through mirrors and glass to their first diffuse vertex,
recorded for the splat into the camera (and, after a diffuse bounce, onward).
"""
from __future__ import annotations


from numba import njit
from ..scene.arrays import CONDUCTOR, DIELECTRIC, DIFFUSE, PATH_RAYS, RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMISSION
from .records import HIDDEN_PASSES, PH_BEYOND, PH_LOST, PH_PHOTONS, PH_TRUNCATED, REC_BETA, REC_NG, REC_NS, REC_P, REC_W
from ..core.embree import KINDS, ray_state
from .typed import TypedOnce
from .chain import shading_normal1
from .handoff import diffuse_scatter
from ..shading.absorption import absorbed1, medium_after1
from ..core.vec3 import add3, cols3, dot1, max_nan, neg3, scale3, sub3
from .keyed import keyed_uniform, keyed_uniform3
from ..shading.optics import scatter1
from ..shading.coat import table_weight1

from ..core.jit import JIT, LANES
from .rays import next_surface


@njit(**JIT)
def fits_limits(lim, d, g, t):
    """bounces.Limits.allowed of event counts d, g, t; lim = Limits.array()."""
    return d <= lim[0] and g <= lim[1] and t <= lim[2] and d + g + t <= lim[3]


@njit(**LANES)
def _photon_rows(ray, indirect, o0, d0, w0, soft, lvis, lit, unshadowing, key, lane0, geo, receivers, mats, lim,
                 max_bounces, max_iter, physical, eps, rec, rec_i, hist, h_prim, tally):
    """photon_lanes' loop over its lanes from lane0 (its caller holds the arrays).
    Returns (the lane it stopped before: the last + 1, or one whose records did not fit; records
    written)."""
    tv, tng, tns, tri_material, mat_kind, tri_object, casters, _, hid = geo
    mat_color = mats[2]
    counts = ray[6]
    K = hist.shape[1]
    cap = rec.shape[0]
    nrec = 0
    for lane in range(lane0, o0.shape[0]):
        b = cols3(w0, lane, 0)
        if not max_nan(max_nan(b[0], b[1]), b[2]) > 0:
            continue
        # what to restore if this lane's records do not fit (it is traced again in the next call)
        rec0, c0, c1, c2 = nrec, counts[0], counts[1], counts[KINDS]
        t0 = (tally[0], tally[1], tally[2], tally[3])
        tally[PH_PHOTONS] += 1
        o, d = cols3(o0, lane, 0), cols3(d0, lane, 0)
        nd = ngl = nt = 0  # events so far as Cycles counts them: diffuse, glossy, transmission
        has_s = False  # a specular vertex on a planned caster so far (indirect)
        n_diff = 0  # diffuse vertices so far (indirect)
        full = False
        medium = -1  # inside a glass (its material) or not
        # Ray Visibility (geo's hid, Scene.hidden_kinds): the kinds of ray the previous vertex meets (the
        # light's, lvis, at first), those the surfaces passed since meet (a ray of such a kind would have
        # stopped there), and how many were passed
        prev_vis, passed, n_pass = lvis, 0, 0
        n_unshadow = 0  # objects that do not shadow the light passed on the first segment (Shadow Linking)
        it = 0  # the path's vertices so far (the photon's events)
        while it < max_iter:
            pr, t, p, g, n, b1, b2 = next_surface(ray, o, d, tv, tng, tns, eps)
            if pr < 0:
                break
            b = absorbed1(mats[0], mats[10], medium, tri_material[pr], d, g, t, b)
            if it == 0 and unshadowing.shape[0] > 0 and unshadowing[tri_object[pr]]:
                # Shadow Linking: Cycles' rays to the light pass an object that does not shadow it, and a path
                # that meets the object goes on from it too: where it could (the object lit, and a caster, or
                # any surface for the indirect photons), either, at random, weighted 2; else passed
                ob0, k0 = tri_object[pr], mat_kind[tri_material[pr]]
                go_on = (lit.shape[0] == 0 or lit[ob0]) and (indirect or ((k0 == CONDUCTOR or k0 == DIELECTRIC)
                                                                           and casters[ob0]))
                go_past = True
                if go_on:
                    go_past = keyed_uniform(key, lane, it, 4 + HIDDEN_PASSES + n_unshadow) < 0.5
                    b = scale3(2.0, b)
                if go_past:
                    if n_unshadow == HIDDEN_PASSES:
                        break
                    n_unshadow += 1
                    o = add3(p, scale3(eps if dot1(d, g) >= 0 else -eps, g))  # tracer.spawn, on along d
                    continue
            h = hid[tri_object[pr]] & PATH_RAYS if hid.shape[0] > 0 else 0
            if h != 0:
                # a surface some kinds of ray do not meet: the path may pass it or meet it, as the kind of
                # the ray the next vertex casts decides (checked there): hidden from all, it is passed;
                # else either, at random, weighted 2
                go_past = h == PATH_RAYS
                if not go_past:
                    go_past = keyed_uniform(key, lane, it, 3 + n_pass) < 0.5
                    b = scale3(2.0, b)
                if go_past:
                    if n_pass == HIDDEN_PASSES:
                        break
                    passed |= PATH_RAYS & ~h
                    n_pass += 1
                    o = add3(p, scale3(eps if dot1(d, g) >= 0 else -eps, g))  # tracer.spawn, on along d
                    continue
            if it == 0 and soft[3] > 0:  # lights.soft_falloff_factor
                dc = sub3(p, (soft[0], soft[1], soft[2]))
                d2 = dot1(dc, dc)
                b = scale3(d2 / (d2 + soft[3] * soft[3]), b)
            m = tri_material[pr]
            kind = mat_kind[m]
            obj = tri_object[pr]
            if it == 0 and lit.shape[0] > 0 and not lit[obj]:
                break  # Light Linking: the light does not light the object the camera's path leaves it from
            spec = kind == CONDUCTOR or kind == DIELECTRIC
            if not indirect and it == 0:
                spec = spec and casters[obj]  # a caustic photon's first hit: a planned caster
            # a splat where the camera's x0 would be: after a specular vertex (indirect: after a
            # specular vertex on a caster and a diffuse one), x0's own bounce within the limits
            # a diffuse event casts a diffuse ray towards where the photon came from: it must meet the previous
            # vertex and pass what the photon passed
            diffuse_seen = (prev_vis & RAY_DIFFUSE) != 0 and (passed & RAY_DIFFUSE) == 0
            if (kind == DIFFUSE and receivers[obj] and fits_limits(lim, nd + 1, ngl, nt) and diffuse_seen
                    and ((has_s and n_diff >= 1) if indirect else it > 0)):
                if nrec == cap:
                    full = True
                    break
                w = neg3(d)
                for c in range(3):
                    rec[nrec, REC_P + c], rec[nrec, REC_NG + c], rec[nrec, REC_NS + c] = p[c], g[c], n[c]
                    rec[nrec, REC_W + c], rec[nrec, REC_BETA + c] = w[c], b[c]
                rec_i[nrec, 0], rec_i[nrec, 1], rec_i[nrec, 2] = lane, it, m
                nrec += 1
            step = 0 if it == 0 else 1  # the photon's first event is the path's free last one
            if indirect and kind == DIFFUSE:
                if not fits_limits(lim, nd + step + 1, ngl, nt) or not diffuse_seen:
                    break
                ok, dd, bb = diffuse_scatter(keyed_uniform(key, lane, it, 0), keyed_uniform(key, lane, it, 1),
                                              keyed_uniform(key, lane, it, 2), neg3(d), g, n, cols3(mat_color, m, 0),
                                              b, True)
                if not ok:
                    break
                # the eye's path, the other way, arrives here from dd: the glossy layer's share
                bb = scale3(table_weight1(mats[6], m, dot1(dd, n)), bb)
                nd += step
                n_diff += 1
            else:
                if not indirect and it >= max_bounces:
                    if spec:
                        tally[PH_TRUNCATED] += 1
                    break
                if not spec:
                    break
                if kind == DIELECTRIC and tns.shape[1] == 6:
                    # a bumped glass's normals as Cycles' eye path meets them: through the glass it
                    # comes from the side the photon goes to (bump.py; a Fresnel reflection or a total
                    # internal one off such a surface takes them from the wrong side)
                    n = shading_normal1(tns, pr, b1, b2, g, neg3(d))
                ok, dd, bb, _ = scatter1(keyed_uniform3(key, lane, it, 0), neg3(d), n, g, m, kind, mats, b,
                                         not physical, True)
                if not ok:
                    tally[PH_LOST] += 1
                    break
                refl = dot1(d, g) * dot1(dd, g) < 0  # bounces.specular_kind
                e = RAY_GLOSSY if refl else RAY_TRANSMISSION
                if not prev_vis & e or passed & e:
                    break  # the ray this vertex casts towards the light does not meet the previous vertex
                if refl:
                    ngl += step
                else:
                    nt += step
                if not fits_limits(lim, nd + 1, ngl, nt):  # no splat can fit any more
                    tally[PH_BEYOND] += 1
                    break
                has_s = has_s or casters[obj]
                if it < K:  # the hand-off's record of the chain, light side first
                    h_prim[lane, it] = pr
                    for c in range(3):
                        hist[lane, it, c] = p[c]
                    hist[lane, it, 3], hist[lane, it, 4] = b1, b2
                    hist[lane, it, 5] = 1.0 if dot1(d, n) * dot1(dd, n) < 0 else 0.0
                    hist[lane, it, 6] = 1.0 if casters[obj] else 0.0
            o = add3(p, scale3(eps if dot1(dd, g) >= 0 else -eps, g))  # tracer.spawn
            medium = medium_after1(m, kind, dd, g)
            d, b = dd, bb
            prev_vis, passed, n_pass = PATH_RAYS & ~hid[obj] if hid.shape[0] > 0 else PATH_RAYS, 0, 0
            it += 1
        if full:
            counts[0], counts[1], counts[KINDS] = c0, c1, c2
            tally[0], tally[1], tally[2], tally[3] = t0
            return lane, rec0
    return o0.shape[0], nrec


@TypedOnce
@njit(**JIT)
def photon_lanes(rt, indirect, o0, d0, w0, soft, lvis, lit, unshadowing, key, lane0, geo, receivers, mats, lim,
                 max_bounces, max_iter, physical, eps, rec, rec_i, hist, h_prim, tally):
    """The light tracer's photons (o0, d0: origin and unit direction; w0: flux), each traced from
    its light to its end, every ray cast here, its random numbers keyed_uniform(key, lane,
    event, .): the same path whichever call or thread traces it.

    Caustic photons (reference.trace_photons, indirect False): the first hit a planned caster,
    then through mirrors and glass (optics.scatter1, adjoint; physical: Cycles' radiance is not
    scaled at refractions, so the flux is), up to max_bounces specular vertices; a record where
    the path meets a diffuse receiver after at least one. Indirect photons (indirect
    .trace_photons): every surface, diffuse bounces with Russian roulette (diffuse_scatter),
    up to max_iter events; a record at each diffuse receiver once the path holds a specular
    vertex on a caster and a diffuse one. Both keep the scene's Light Paths limits (lim:
    Limits.array(); bounces.py: the photon's first event is free, x0's diffuse bounce counts).
    soft: a soft-falloff light's centre and radius (radius 0: none), applied at the first hit;
    lvis: the rays that see the light (scene.RAY_* bits): the first event must cast such a ray; lit:
    (O,) bool, the objects the light lights (Light Linking: the first event must be on one; empty: any);
    unshadowing: (O,) bool, the objects that do not shadow it (Shadow Linking: the first segment passes
    them, or where the path could go on from one, passes it or meets it at random; empty: none).

    Writes splat records (rec: REC_* columns, rec_i: lane, specular bounces before it,
    material) and, for the hand-off, the first K = hist.shape[1] specular vertices of each lane
    (hist: point, barycentrics, 1 for a reflection, 1 on a caster; h_prim: the triangle); adds
    to tally (PH_*). Returns (the lane to go on from, o0's length when done: a lane whose
    records would not fit in rec is left whole for the next call; records written; the ray
    counters, embree.ray_state)."""
    ray = ray_state(rt)
    nxt, nrec = _photon_rows(ray, indirect, o0, d0, w0, soft, lvis, lit, unshadowing, key, lane0, geo, receivers,
                             mats, lim, max_bounces, max_iter, physical, eps, rec, rec_i, hist, h_prim, tally)
    return nxt, nrec, ray[6]
