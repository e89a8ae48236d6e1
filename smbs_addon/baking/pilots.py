"""The plan's traced look at the scene: what the camera sees (directly, or through mirrors and glass),
and pilot photons per light and caster that find where each caustic lands, by which chain types,
on which receivers, carrying how much light (plan.refine_plan reads their answers).
"""
from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np

from ..core import lanes
from ..scene import arrays as S
from ..core.random import PILOT_BOUNCE, PILOT_CASTER, PILOT_INDIRECT, PILOT_PROBE, PLAN_LOOK, light_key, stream
from ..core.vec import cosine_hemisphere, dot, frame, to_world, uniform_cone
from ..shading.light_samples import sample_light
from ..shading.lights import Photons, emit, light_axis, shadow_tmax
from ..shading.microfacet import rough_materials
from ..shading.optics import reflect, refract
from ..paths.photons import scatter_specular
from ..shading.fresnel import specular_weights
from .pilot_sets import HIDDEN_PROBE, Pilots, bounce_count, pilot_count, view_reach

PILOT_PHOTONS = 4096  # per light and caster
PILOT_BOUNCES = 8  # specular bounces a pilot photon follows


class PilotSetup(NamedTuple):
    """What every pilot task of a plan shares: the scene, the camera model, the plan, what the camera
    sees ((direct, through, sides): camera_sees'), the seed, the pilots per caster and the specular
    bounces a pilot follows."""

    scene: object
    cam: object
    plan: object
    seen: tuple
    seed: int
    pilots: int
    max_bounces: int


CAMERA_RAYS = 1 << 18  # at most this many rays for what the camera sees (a grid over the frame)


def _surfaces(scene, tracer, o, d, far=None, passable=None):
    """Trace rays (far: the camera's own, Tracer.camera_intersect, up to the far clip plane at far; passable:
    past the objects it marks, Tracer.intersect_past): (hits, indices of the rays that hit, their object,
    material and kind)."""
    h = tracer.camera_intersect(o, d, far) if far is not None else tracer.intersect_past(o, d, 0, passable)
    i = np.flatnonzero(h.hit)
    mat = scene.tri_material[h.prim[i]]
    return h, i, scene.tri_object[h.prim[i]], mat, scene.mat_kind[mat]


def camera_sees(scene, tracer, cam, plan, max_bounces=PILOT_BOUNCES, scale=None):
    """Receivers the camera sees directly and through mirrors or glass: one ray per pixel
    (a grid of at most CAMERA_RAYS over a larger frame), split at glass into its reflection
    and its refraction. Returns (direct (O,) bool, through (O,2,3): per receiver the box of
    the points seen through mirrors or glass, padded (empty: lo > hi), sides (O,) the sides
    of them seen (1 front, 2 back, by the geometric normal), rays, specular: whether a mirror
    or glass is what some pixel sees first, None where the grid skips pixels). scale: the
    length the boxes are padded by 2% of (None: plan.scale).

    The rays are traced in parts of SEES_PART that the threads take in turn (_sees_part); what
    they find is merged by or, min and max, so the result is the one of a single part (but in a
    maze of glass, where each part keeps its own regular subset of its rays)."""
    return camera_look(scene, tracer, cam, plan, max_bounces, scale)[:5]


def camera_look(scene, tracer, cam, plan, max_bounces=PILOT_BOUNCES, scale=None):
    """camera_sees, the box (lo, hi) around every receiver point its rays saw, directly or through
    mirrors or glass (unpadded; lo > hi where none), and (O,) bool: the objects whose mirror or
    glass some pixel's ray meets first, None where the grid skips pixels."""
    direct, through, sides = _nothing_seen(len(scene.object_names))
    view = np.stack([np.full(3, np.inf), np.full(3, -np.inf)])
    first = np.zeros(len(scene.object_names), bool)
    x0, x1, y0, y1 = cam.region
    w, h = max(0, x1 - x0), max(0, y1 - y0)
    if w * h == 0 or scene.n_tris == 0:
        return direct, through, sides, 0, False, view, first
    step = max(1, math.ceil(math.sqrt(w * h / CAMERA_RAYS)))
    _, _, o, d = cam.pixel_rays(step)
    far, n = cam.clip_far(d), len(o)

    def part(a, b):
        return _sees_part(scene, tracer, plan, (o[a:b], d[a:b], far[a:b]), max_bounces,
                          4 * CAMERA_RAYS * (b - a) // max(n, 1), stream(0, PLAN_LOOK, a))

    rays, specular = 0, False
    for p_direct, p_through, p_sides, p_rays, p_specular, (p_view, p_first) in lanes.blocks(part, n, SEES_PART,
                                                                                             tracer.threads):
        specular |= p_specular
        first |= p_first
        direct |= p_direct
        np.minimum(through[:, 0], p_through[:, 0], out=through[:, 0])
        np.maximum(through[:, 1], p_through[:, 1], out=through[:, 1])
        np.minimum(view[0], p_view[0], out=view[0])
        np.maximum(view[1], p_view[1], out=view[1])
        sides |= p_sides
        rays += p_rays
    # the samples are a pixel apart: pad each box by a tenth of its size and 2% of the scene
    seen = through[:, 0, 0] <= through[:, 1, 0]
    pad = 0.1 * np.linalg.norm(through[:, 1] - through[:, 0], axis=1) + 0.02 * (plan.scale if scale is None else scale)
    through[seen, 0] -= pad[seen, None]
    through[seen, 1] += pad[seen, None]
    return direct, through, sides, rays, (specular if step == 1 else None), view, (first if step == 1 else None)


SEES_PART = 1 << 16  # camera rays per part of camera_sees


def _nothing_seen(n_objects: int):
    """camera_sees' answer before any ray: (direct, through (empty boxes: lo > hi), sides)."""
    through = np.empty((n_objects, 2, 3))
    through[:, 0], through[:, 1] = np.inf, -np.inf
    return np.zeros(n_objects, bool), through, np.zeros(n_objects, np.int64)


def _sees_part(scene, tracer, plan, rays_in, max_bounces, cap, rng):
    """camera_sees for the camera rays rays_in (origins, directions, clip_far's distances): (direct,
    through (unpadded), sides, rays cast, whether a mirror or glass is the first hit of one of them,
    (the box around the receiver points seen, (O,) bool: the objects whose mirror or glass some ray
    meets first)); past cap rays at a bounce, a regular subset of them goes on. rng: the rough
    surfaces' directions (drawn only where the rays meet one)."""
    direct, through, sides = _nothing_seen(len(scene.object_names))
    o, d, far = rays_in
    view = np.stack([np.full(3, np.inf), np.full(3, -np.inf)])
    first = np.zeros(len(scene.object_names), bool)  # objects whose mirror or glass a ray meets first
    rays, specular = 0, False
    for depth in range(max_bounces + 1):
        if len(o) == 0:
            break
        hit, i, obj, mat, kind = _surfaces(scene, tracer, o, d, far if depth == 0 else None)
        rays += len(o)
        r = np.flatnonzero((kind == S.DIFFUSE) & plan.receivers[obj])
        if r.size:
            np.minimum(view[0], hit.p[i[r]].min(axis=0), out=view[0])
            np.maximum(view[1], hit.p[i[r]].max(axis=0), out=view[1])
        if depth == 0:
            direct[np.unique(obj[r])] = True
        else:
            np.minimum.at(through[:, 0], obj[r], hit.p[i[r]])
            np.maximum.at(through[:, 1], obj[r], hit.p[i[r]])
            front = dot(d[i[r]], hit.ng[i[r]]) < 0
            np.bitwise_or.at(sides, obj[r], np.where(front, 1, 2))
        spec = np.flatnonzero((kind == S.CONDUCTOR) | (kind == S.DIELECTRIC))  # any mirror or glass, as the eye
        specular |= depth == 0 and spec.size > 0
        if depth == 0:
            first[obj[spec]] = True
        if spec.size == 0 or depth == max_bounces:
            break
        j = i[spec]
        p, ng, ns, w_in = hit.p[j], hit.ng[j], hit.ns[j], -d[j]
        m = mat[spec]
        rough = _rough_lanes(scene, m)
        if rough is not None:  # what the eye sees in a rough mirror or glass: the perfect one's and one sampled
            jr = j[rough]
            _, rd, _, _, kept = _rough_scatter(scene, tracer, rng, hit.p[jr], hit.ng[jr], hit.ns[jr], -d[jr],
                                                m[rough], adjoint=False)
        refl = scene.mat_fresnel[m] != S.REFRACTION_ONLY
        glass = scene.mat_kind[m] == S.DIELECTRIC
        d_r = reflect(w_in[refl], ns[refl])
        d_t, ok = refract(w_in[glass], ns[glass], scene.mat_ior[m[glass]])
        no = np.concatenate([p[refl], p[glass][ok]])
        nd = np.concatenate([d_r, d_t[ok]])
        nn = np.concatenate([ng[refl], ng[glass][ok]])
        if rough is not None:
            no, nd, nn = (np.concatenate([no, hit.p[jr[kept]]]), np.concatenate([nd, rd]),
                          np.concatenate([nn, hit.ng[jr[kept]]]))
        if len(nd) > max(cap, 1):  # a maze of glass: keep a regular subset
            keep = np.arange(0, len(nd), math.ceil(len(nd) / max(cap, 1)))
            no, nd, nn = no[keep], nd[keep], nn[keep]
        o, d = tracer.spawn(no, nn, nd), nd
    return direct, through, sides, rays, specular, (view, first)


def _sees_point(scene, tracer, cam, p, ng, w_in):
    """Does the camera see the lit side of each point p (lit from w_in, pointing away)?"""
    rx, ry, to_cam, tmax, cos_axis, dist, valid = cam.towards(p, max(cam.cam.filter_width, 0.5))
    valid &= dot(w_in, ng) * dot(to_cam, ng) > 0
    idx = np.flatnonzero(valid)
    if idx.size:
        blocked = tracer.camera_occluded(tracer.spawn(p[idx], ng[idx], to_cam[idx]), to_cam[idx],
                                         tmax[idx] - tracer.eps)
        valid[idx[blocked]] = False
    return valid, int(idx.size)


def _rough_lanes(scene, m):
    """(N,) bool: the lanes of materials m on a rough mirror or glass, or None where there is none."""
    rough = rough_materials(scene)[m]
    return rough if rough.any() else None


def _rough_scatter(scene, tracer, rng, p, ng, ns, w_in, m, adjoint):
    """A rough mirror's or glass's scattering for the plan's rays (w_in pointing away from the
    surface): one lobe and one microfacet normal drawn per lane, as the bake draws them
    (reference.scatter_specular), where a smooth surface's two lobes are followed both. A rough
    reflection reaches where the perfect one cannot: a floor lit by a bulb sends light up into a
    rough standing mirror, which sends some of it down onto the floor again. Returns the new
    lanes' (origins, directions, weights (luminance-like mean), letters 1 R / 2 T, the lanes kept)."""
    beta = np.ones((len(w_in), 3))
    d, b, keep = scatter_specular(scene, rng, w_in, ns, ng, m, scene.mat_kind[m], beta, adjoint=adjoint)
    letter = np.where(dot(d, ng[keep]) * dot(w_in[keep], ng[keep]) > 0, 1, 2).astype(np.int8)
    return tracer.spawn(p[keep], ng[keep], d), d, b.mean(axis=1), letter, keep


def _pilot(scene, tracer, cam, plan, ph, direct, through, sides, rng, max_bounces, target):
    """Follow pilot photons from caster ``target`` (the photons whose first hit is on it)
    through mirrors and glass (glass: both ways while the lanes stay few, else one way at
    random; a rough one: one sampled way, _rough_scatter) to their first diffuse surface.
    Returns, per photon path that lands where the camera sees it: the casters it met (K, max_bounces) object
    ids (-1 past its end), its chain letters, the receiver, the flux it carries
    (luminance, through the Fresnel weights) and where it lands; and the rays cast. target None: photons
    leaving a diffuse surface (ph.o is on it), the first specular hit on any caster."""
    n0 = len(ph.o)
    keep = ph.w.max(axis=1) > 0
    o, d = ph.o[keep], ph.d[keep]
    w = ph.w[keep].mean(axis=1)  # the flux a lane carries (its photon's, times Fresnel weights)
    if target is None:
        target = np.flatnonzero(plan.flag_casters)
    hist = np.full((len(o), max_bounces), -1, np.int64)
    letters = np.zeros((len(o), max_bounces), np.int8)  # 1 R, 2 T
    out = []
    rays = 0
    for depth in range(max_bounces + 1):
        if len(o) == 0:
            break
        # a photon's first segment passes what does not shadow its light (Shadow Linking)
        h, i, obj, mat, kind = _surfaces(scene, tracer, o, d, passable=ph.unshadowing if depth == 0 else None)
        rays += len(o)
        land = np.flatnonzero((kind == S.DIFFUSE) & plan.receivers[obj] & (depth > 0))
        if land.size:
            li_ = i[land]
            box = through[obj[land]]
            pl = h.p[li_]
            side = np.where(dot(d[li_], h.ng[li_]) < 0, 1, 2)
            seen = np.all((box[:, 0] <= pl) & (pl <= box[:, 1]), axis=1) & (sides[obj[land]] & side > 0)
            check = np.flatnonzero(~seen & direct[obj[land]])
            if check.size:
                v, r = _sees_point(scene, tracer, cam, h.p[li_[check]], h.ng[li_[check]], -d[li_[check]])
                rays += r
                seen[check] = v
            out.append((hist[li_[seen]], letters[li_[seen]], obj[land[seen]], w[li_[seen]], pl[seen]))
        spec = (kind == S.CONDUCTOR) | (kind == S.DIELECTRIC)
        spec &= np.isin(obj, target) if depth == 0 else True  # the pilots of caster target: paths from it
        sp = np.flatnonzero(spec)
        if sp.size == 0 or depth == max_bounces:
            break
        j = i[sp]
        p, ng, ns, w_in, m = h.p[j], h.ng[j], h.ns[j], -d[j], mat[sp]
        hist[j, depth] = np.where(plan.flag_casters[obj[sp]], obj[sp], -1)
        rough = _rough_lanes(scene, m)
        if rough is not None:  # rough mirrors and glass: one sampled microfacet scattering each
            jr, j = j[rough], j[~rough]
            ro, rd, rw, letter, kept = _rough_scatter(scene, tracer, rng, h.p[jr], h.ng[jr], h.ns[jr], -d[jr],
                                                      m[rough], adjoint=True)
            p, ng, ns, w_in, m = p[~rough], ng[~rough], ns[~rough], w_in[~rough], m[~rough]
            rw *= w[jr[kept]]
            rh, rlet = hist[jr[kept]], letters[jr[kept]].copy()
            rlet[:, depth] = letter
        wr, wt = specular_weights(scene, m, dot(w_in, ns))
        wr, wt = wr.mean(axis=1), wt.mean(axis=1)
        d_t, ok = refract(w_in, ns, np.where(scene.mat_kind[m] == S.DIELECTRIC, scene.mat_ior[m], 1.0))
        refl = wr > 0
        ok &= wt > 0
        if 2 * len(j) > 8 * n0:  # too many lanes: where both lobes are open, go one way at random
            both = refl & ok
            coin = rng.random(len(j)) < 0.5
            refl &= ~(both & coin)
            ok &= ~(both & ~coin)
            wr, wt = np.where(both, 2 * wr, wr), np.where(both, 2 * wt, wt)
        wj = w[j]
        hj = hist[j]
        lr, lt = letters[j].copy(), letters[j].copy()
        lr[:, depth], lt[:, depth] = 1, 2
        d = np.concatenate([reflect(w_in[refl], ns[refl]), d_t[ok]])
        o = tracer.spawn(np.concatenate([p[refl], p[ok]]), np.concatenate([ng[refl], ng[ok]]), d)
        w = np.concatenate([(wj * wr)[refl], (wj * wt)[ok]])
        hist = np.concatenate([hj[refl], hj[ok]])
        letters = np.concatenate([lr[refl], lt[ok]])
        if rough is not None:
            o, d, w = np.concatenate([o, ro]), np.concatenate([d, rd]), np.concatenate([w, rw])
            hist, letters = np.concatenate([hist, rh]), np.concatenate([letters, rlet])
    if out:
        return tuple(np.concatenate(x) for x in zip(*out)) + (rays,)
    return (np.zeros((0, max_bounces), np.int64), np.zeros((0, max_bounces), np.int8), np.zeros(0, np.int64),
            np.zeros(0), np.zeros((0, 3)), rays)


MIN_SAMPLE_SHARE = 1.0 / 16.0


def sample_share(ratio: float) -> float:
    """The share of a light's samples for a world whose caustic can be at most `ratio` of the lamps'
    (caustic_irradiance): sqrt(ratio), from 1/16 to 1. Samples in proportion to each light's noise
    (Neyman) would give it `ratio`; its own noise per sample is the larger (its directions fill the
    sphere), so the root. Blender's default grey beside the glass ball's area light: ratio 0.033,
    0.18 of the samples."""
    return float(min(1.0, max(MIN_SAMPLE_SHARE, math.sqrt(max(ratio, 0.0)))))


def caustic_irradiance(at: np.ndarray, w: np.ndarray, scale: float) -> float:
    """The irradiance of a caustic over its bright part, from pilot photons landing at ``at`` (K,3)
    with flux ``w`` (K,): their flux summed in cubes of side scale / CELLS, the mean over the cubes
    holding more than 5% of the fullest one's (as convergence.caustic_region picks pixels), per
    unit area. Cubes wider than the caustic's focus dilute it, so it errs low: a world compared
    with it is left out only when its caustic is surely faint. 0 for no photon."""
    if not len(at):
        return 0.0
    h = scale / CELLS
    _, inv = np.unique(np.floor(at / h).astype(np.int64), axis=0, return_inverse=True)
    cell = np.bincount(inv.ravel(), weights=w)
    bright = cell > 0.05 * cell.max()
    return float(cell[bright].sum() / (bright.sum() * h * h))


def spot_target(scene, li: int, sphere: np.ndarray) -> tuple[np.ndarray, float]:
    """Where light li's photons aim at a sphere (1,4) that holds what they may light (the
    diffuse surfaces for the plan's pilots, the scene for the bake's photons after a diffuse
    bounce): for a narrow spot, a sphere filling its cone instead, so the photons are not
    masked away. Aimed at the whole diffuse bounding sphere, a 16 deg spot kept 2% of its pilots,
    and a crescent of floor it lights past a glass ball (glass_spot.blend) got none: the plan
    dropped its light through a diffuse bounce, 1.3% of the layer, 5-25% of it 30-200 px from
    the focus.

    Returns (the target, the share of the photons aimed at the sphere that the spot lets
    through at most: the solid angle of the new aim over the old one's, 1 where unchanged)."""
    if scene.light_type[li] != S.SPOT:
        return sphere, 1.0
    c = scene.light_matrix[li][:3, 3]
    axis = light_axis(scene, li)
    dist = float(np.linalg.norm(sphere[0, :3] - c))
    half = 0.5 * float(scene.light_spot_size[li])  # the cone masks directions (lights.spot_mask)
    if not (dist > 0 and half < math.radians(60.0)):
        return sphere, 1.0
    target = np.concatenate([c + dist * axis, [dist * math.sin(half)]])[None, :]
    r = float(scene.light_radius[li])  # lights.emit widens each aim by the light's radius

    def solid_angle(radius):
        s = (radius + r) / dist
        return 4.0 * math.pi if s >= 1.0 else 2.0 * math.pi * (1.0 - math.sqrt(1.0 - s * s))

    return target, min(1.0, solid_angle(target[0, 3]) / solid_angle(float(sphere[0, 3])))


def _caster_pilot(setup: PilotSetup, tracer, lp, k, extent, view, part=None, view_sphere=None):
    """refine_plan's pilots of light lp's k-th caster, traced with tracer (its tolerances those of
    extent: the diffuse surfaces and this caster): (photons traced, rays, Pilots). view: the
    light's flux towards what the camera sees (view_sphere: where); the photons traced are
    pilot_count's share of the pilots, the first of those emitted (a caster catching little of
    the light, or far from where the camera looks, costs few rays; one catching enough traces
    every photon, as it always did, once the light was found to reach it: _lit_points), or part:
    (a, b) the photons a..b-1 of them, traced with a random stream of their own (refine_plan's
    second round)."""
    scene, cam, plan, seen, seed, pilots, max_bounces = setup
    o = lp.caster_objects[k]
    rng = stream(seed, PILOT_CASTER, lp.key, light_key(scene.object_names[o]))
    ph = emit(scene, lp.index, lp.targets[k:k + 1], pilots, rng, extent)
    aimed = float(ph.w.mean(axis=1).sum())
    a, b = part or (0, pilot_count(aimed, view, pilots, view_reach(view_sphere, lp.targets[k])))
    probed = 0
    if part is None and b > HIDDEN_PROBE:
        # shadow rays from HIDDEN_PROBE points on the caster towards the light: none unblocked, something
        # nearer hides it from the light (a ball under the floor): the plan leaves it out on those
        probed = HIDDEN_PROBE
        probe = stream(seed, PILOT_PROBE, lp.key, light_key(scene.object_names[o]))
        if not _lit_points(scene, tracer, lp.index, o, HIDDEN_PROBE, probe):
            return 0, probed, Pilots.none(HIDDEN_PROBE, aimed, max_bounces, hidden=True)
    if (a, b) != (0, pilots):
        ph = dataclasses.replace(ph, o=ph.o[a:b], d=ph.d[a:b], w=ph.w[a:b] * (pilots / (b - a)))
    if part is not None:
        rng = stream(seed, PILOT_CASTER, lp.key, light_key(scene.object_names[o]), a)
    hist, letters, recv, wgt, at, r = _pilot(scene, tracer, cam, plan, ph, *seen, rng, max_bounces, o)
    first = hist[:, 0] == o
    return b - a, r + probed, Pilots(b - a, aimed, hist[first], letters[first], recv[first], at[first], wgt[first])


def _lit_points(scene, tracer, li, o, n, rng) -> int:
    """Of n points uniform in area on object o, how many light li reaches unblocked (a shadow ray
    each, towards a point of the light, or a direction of a sun or the world; past what does not
    shadow it, Shadow Linking). A point on the far side of a closed caster is blocked by the caster:
    a lit ball counts about half."""
    tri = np.flatnonzero(scene.tri_object == o)
    area = tracer.area2[tri]
    if not area.sum() > 0:
        return n
    j = tri[np.minimum(np.searchsorted(np.cumsum(area), rng.random(n) * area.sum(), side="right"), len(tri) - 1)]
    u, v = rng.random(n), rng.random(n)
    flip = u + v > 1
    u, v = np.where(flip, 1 - u, u), np.where(flip, 1 - v, v)
    tv = tracer.v[j]
    p = tv[:, 0] + u[:, None] * (tv[:, 1] - tv[:, 0]) + v[:, None] * (tv[:, 2] - tv[:, 0])
    light = sample_light(scene, li, n, rng)
    if light.directional:
        to, dist = light.y, np.full(n, np.inf)
    else:
        to = light.y - p
        dist = np.sqrt(dot(to, to))
        to = to / np.maximum(dist, 1e-300)[:, None]
    start = tracer.spawn(p, tracer.ng[j], to)
    tmax = np.full(n, np.inf) if light.directional else \
        shadow_tmax(scene, li, light.y, light.ys, light.yt, start, to, dist, tracer.eps)  # short of a mesh light
    blocked = tracer.occluded_past(start, to, tmax, S.RAY_SHADOW, scene.unshadowing(li))
    return int((~blocked).sum())


def _indirect_pilot(setup: PilotSetup, tracer, li, n_ind, dif_sphere, extent):
    """refine_plan's pilots of light li through a diffuse bounce: n_ind photons onto the diffuse
    surfaces (the sphere dif_sphere), a cosine bounce, then _pilot. (photons, rays, (Pilots, the
    bounce's sources: the diffuse points lit, their normals on the lit side and the flux each
    sends on; None for none))."""
    scene, cam, plan, seen, seed, _, max_bounces = setup
    rng = stream(seed, PILOT_INDIRECT, light_key(scene.light_names[li]))
    ph = emit(scene, li, spot_target(scene, li, dif_sphere)[0], n_ind, rng, extent)  # onto the diffuse surfaces
    lit = np.flatnonzero(ph.w.max(axis=1) > 0)
    h = tracer.intersect_past(ph.o[lit], ph.d[lit], 0, ph.unshadowing)  # past what does not shadow it
    i = np.flatnonzero(h.hit)
    mat = scene.tri_material[h.prim[i]]
    dif = scene.mat_kind[mat] == S.DIFFUSE
    if ph.lit is not None:  # Light Linking: a diffuse surface the light does not light sends none of it on
        dif &= ph.lit[scene.tri_object[h.prim[i]]]
    dif = np.flatnonzero(dif)
    if dif.size == 0:
        return n_ind, lit.size, (Pilots.none(n_ind, 0.0, max_bounces), None)
    j = i[dif]
    ng = h.ng[j] * np.sign(-dot(ph.d[lit[j]], h.ng[j]))[:, None]  # the lit side
    s_, t_ = frame(ng)
    d2 = to_world(cosine_hemisphere(rng.random(j.size), rng.random(j.size)), s_, t_, ng)
    w2 = ph.w[lit[j]] * scene.mat_color[mat[dif]]  # cosine sampling: the albedo
    sources = (h.p[j], ng, w2)
    bounce = Photons(tracer.spawn(h.p[j], ng, d2), d2, w2)
    hist, letters, recv, wgt, at, r = _pilot(scene, tracer, cam, plan, bounce, *seen, rng, max_bounces, None)
    return n_ind, lit.size + r, (Pilots(n_ind, 0.0, hist, letters, recv, at, wgt), sources)


def _bounce_pilot(setup: PilotSetup, tracer, li, o, sources, need):
    """Pilots of light li's light after a diffuse bounce into caster o, which the plan leaves out:
    from the diffuse points li lights (sources: _indirect_pilot's), towards o's bounding sphere (a
    cone per point that has o above its horizon, picked in proportion to the most of its flux a
    Lambertian bounce can send into the cone), then _pilot, its first hit on o. n photons
    (pilot_sets.bounce_count): enough that none landing in view bounds o's flux in view below
    `need`, or pilot_count's share, whichever is fewer. Returns (n, rays, Pilots or None where no
    lit point can send any into the cone)."""
    scene, cam, plan, seen, seed, pilots, max_bounces = setup
    p, ng, w = sources
    lo, hi = scene.object_bounds(o)
    sph = np.concatenate([(lo + hi) / 2, [max(np.linalg.norm(hi - lo) / 2, 1e-9 * scene.scale)]])
    to = sph[:3] - p
    dist = np.sqrt(dot(to, to))
    axis = to / np.maximum(dist, 1e-300)[:, None]
    cos_half = np.where(dist <= sph[3], -1.0, np.sqrt(np.maximum(0.0, 1.0 - (sph[3] / np.maximum(dist, 1e-300)) ** 2)))
    sin_half = np.sqrt(np.maximum(0.0, 1.0 - cos_half ** 2))
    c_axis = dot(axis, ng)
    # the largest cosine to the normal within the cone: 1 where the normal lies in it
    top = np.where(c_axis >= cos_half, 1.0, c_axis * cos_half + np.sqrt(np.maximum(0.0, 1.0 - c_axis ** 2)) * sin_half)
    omega = 2.0 * math.pi * (1.0 - cos_half)
    bound = w.mean(axis=1) * np.maximum(top, 0.0) * omega / math.pi
    most = float(bound.sum())
    if not most > 0:
        return 0, 0, None
    n = bounce_count(most, float(w.mean(axis=1).sum()), need, pilots)
    rng = stream(seed, PILOT_BOUNCE, light_key(scene.light_names[li]), light_key(scene.object_names[o]))
    cdf = np.cumsum(bound)
    k = np.minimum(np.searchsorted(cdf, rng.random(n) * cdf[-1], side="right"), len(cdf) - 1)
    s_, t_ = frame(axis[k])
    d = to_world(uniform_cone(rng.random(n), rng.random(n), cos_half[k]), s_, t_, axis[k])
    # the point's flux x cos / pi into the direction, over the direction's density (1 / the cone's
    # solid angle) and the point's (its bound over the sum), per photon
    wk = w[k] * (np.maximum(dot(d, ng[k]), 0.0) * omega[k] / math.pi * most / (bound[k] * n))[:, None]
    ph = Photons(tracer.spawn(p[k], ng[k], d), d, wk)
    hist, letters, recv, wgt, at, r = _pilot(scene, tracer, cam, plan, ph, *seen, rng, max_bounces, o)
    first = hist[:, 0] == o
    return n, r, Pilots(n, float(wk.mean(axis=1).sum()), hist[first], letters[first], recv[first], at[first],
                        wgt[first])


CELLS = 64  # caustic_irradiance's cells: this many across the diagonal of what takes part
