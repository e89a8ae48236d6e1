"""The brute-force reference: light tracing through specular chains.

It defines the caustic layer: paths light -> (specular)+ -> diffuse receiver ->
camera. Photons leave a light towards the casters (lights.emit), bounce through
perfect mirrors and glass (Fresnel decides reflect or refract at glass, by
Russian roulette on the Fresnel weight), and at the first diffuse vertex are
connected to the camera and splatted through the pixel filter. Unbiased and
unclamped; slow for small caustics, which is what the manifold walks are for.

A diffuse vertex seen by the camera only through glass or a mirror is not
splatted here (the connection to the camera is blocked); see the bake notes.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import scene as S
from .optics import fresnel_dielectric, fresnel_schlick, reflect, refract
from .lights import light_radiance, soft_falloff_factor
from .estimators import concentration
from .geometry import vertex_from_hits
from .vec import cosine_hemisphere, dot, frame, normalize, to_world

MAX_SPECULAR_BOUNCES = 32


def splat_to_camera(scene, tracer, cam, film, y, ng, ns, w_in, beta, albedo, stats):
    """Connect diffuse vertices y (arrival direction w_in, pointing away from y)
    carrying flux beta to the camera; splat beta * f * importance."""
    if len(y) == 0:
        return
    rx, ry, depth, cos_axis, dist, valid = cam.project(y)
    if cam.ortho:
        to_cam = np.broadcast_to(cam.axes[:, 2], y.shape).copy()
        tmax = depth - cam.cam.clip_start
    else:
        to_cam = normalize(cam.origin - y)
        tmax = dist * (1.0 - cam.cam.clip_start / np.maximum(depth, 1e-300))
    x0, x1, y0, y1 = cam.region
    r = film.filter_width
    valid &= (rx > x0 - r) & (rx < x1 + r) & (ry > y0 - r) & (ry < y1 + r)
    ci_g, co_g = dot(w_in, ng), dot(to_cam, ng)
    ci_s = dot(w_in, ns)
    valid &= (ci_g * co_g > 0) & (ci_s * np.sign(ci_g) > 0)  # same side, lit per shading normal
    idx = np.flatnonzero(valid)
    if idx.size == 0:
        return
    o = tracer.spawn(y[idx], ng[idx], to_cam[idx])
    blocked = tracer.occluded(o, to_cam[idx], tmax[idx] - tracer.eps)
    stats["rays_camera"] += int(idx.size)
    idx = idx[~blocked]
    if idx.size == 0:
        return
    # diffuse BSDF with the shading-normal correction of the adjoint (Veach 5.3)
    corr = np.abs(ci_s[idx]) / np.maximum(np.abs(ci_g[idx]), 1e-12)
    imp = cam.importance(cos_axis[idx], dist[idx], co_g[idx])
    val = beta[idx] * (albedo[idx] / math.pi) * (corr * imp)[:, None]
    film.splat(rx[idx], ry[idx], val)
    stats["splats"] += int(idx.size)


def scatter_specular(scene, rng, w_in, ns, ng, mat, kind, beta, scale_eta=False, adjoint=False):
    """One perfect-specular interaction per lane: mirror reflection (conductor),
    or reflection/refraction chosen by Fresnel (dielectric, Russian roulette so
    the weight is just the tint). w_in points away from the surface.

    scale_eta: multiply refractions by (eta on the w_in side / eta on the other
    side)^2 -- the radiance change along an eye path in physical units, and, for
    photons, Cycles' convention (Cycles keeps radiance unscaled, so the flux a
    photon delivers changes by that factor instead).

    adjoint: the lanes carry light (photons), not radiance: with a shading normal the
    BSDF is not symmetric, and the photon's weight takes Veach's correction (thesis
    sec. 5.3) |w_in.ns| |w_out.ng| / (|w_in.ng| |w_out.ns|), so that light tracing
    agrees with the radiance view (Cycles, the walks) on bumpy or normal-mapped casters.

    Returns (new unit directions, new weights, kept lane indices): lanes whose
    scattered direction is on the wrong side of the geometric normal (a
    shading-normal artefact) or whose weight is zero are dropped."""
    n_out = np.zeros_like(w_in)
    beta = beta.copy()
    cond = kind == S.CONDUCTOR
    if cond.any():
        ci = np.flatnonzero(cond)
        f = np.where((scene.mat_fresnel[mat[ci]] == S.FRESNEL_SCHLICK)[:, None],
                     fresnel_schlick(dot(w_in[ci], ns[ci]), scene.mat_color[mat[ci]]),
                     scene.mat_color[mat[ci]])
        n_out[ci] = reflect(w_in[ci], ns[ci])
        beta[ci] *= f
    diel = kind == S.DIELECTRIC
    if diel.any():
        di = np.flatnonzero(diel)
        eta = scene.mat_ior[mat[di]]
        wi, n = w_in[di], ns[di]
        choose_r = rng.random(di.size) < fresnel_dielectric(dot(wi, n), eta)
        t, t_ok = refract(wi, n, eta)
        choose_r |= ~t_ok
        n_out[di] = np.where(choose_r[:, None], reflect(wi, n), t)
        beta[di] *= np.where(choose_r[:, None], scene.mat_reflect_color[mat[di]], scene.mat_color[mat[di]])
        if scale_eta:
            inside = dot(wi, ng[di]) < 0
            ratio = np.where(inside, eta, 1.0 / eta)  # eta(w_in side) / eta(other side)
            beta[di] *= np.where(choose_r, 1.0, ratio**2)[:, None]
    # the geometric normal decides the side: reflection stays, refraction crosses
    cin, cout = dot(w_in, ng), dot(n_out, ng)
    if adjoint:
        num = np.abs(dot(w_in, ns) * cout)
        den = np.abs(cin * dot(n_out, ns))
        beta *= np.divide(num, den, out=np.zeros_like(num), where=den > 0)[:, None]
    is_refl = dot(w_in, ns) * dot(n_out, ns) > 0
    ok = np.where(is_refl, cin * cout > 0, cin * cout < 0) & (beta.max(axis=1) > 0)
    keep = np.flatnonzero(ok)
    return normalize(n_out[keep]), beta[keep], keep


@dataclass
class Handoff:
    """The manifold pass hands the paths that focus more than ``tau`` to the photons.

    Photons then splat only where their chain (read from the receiver's side) is
    one of ``types``, every vertex lies on a planned caster, and the chain's
    concentration exceeds tau: exactly the paths the manifold pass drops
    (manifold.estimate), so the two add up to the whole layer, each where it is
    efficient: the light tracer where light piles up (folds, foci), the walks
    elsewhere."""

    tau: dict  # chain type -> concentration threshold; 0: the whole chain type (a weak one)
    directional: bool  # the light is a sun: the light end is the photon's direction

    @property
    def types(self):
        return tuple(self.tau)

    @property
    def max_chain(self):
        return max(len(t) for t in self.types)


def _handoff_select(scene, tracer, handoff, x0, kb, prim, pts, bary, refl, caster, y):
    """Which photons arriving at x0 after kb bounces (history per bounce, light side
    first) carry a handed-off path."""
    take = np.zeros(len(x0), bool)
    K = handoff.max_chain
    ok = (kb >= 1) & (kb <= K)
    for k in np.unique(kb[ok]):
        lanes = np.flatnonzero(ok & (kb == k))
        lanes = lanes[np.all(caster[lanes, :k], axis=1)]
        # chain letters from the receiver's side: the photon's last bounce comes first
        codes = np.zeros(lanes.size, np.int64)
        for j in range(k):
            codes = codes * 2 + refl[lanes, k - 1 - j]
        for code in np.unique(codes):
            types = "".join("R" if (code >> (k - 1 - j)) & 1 else "T" for j in range(k))
            if types not in handoff.types:
                continue
            g = lanes[codes == code]
            verts = [vertex_from_hits(scene, tracer, prim[g, k - 1 - j], pts[g, k - 1 - j], bary[g, k - 1 - j])
                     for j in range(k)]
            etas = [scene.mat_ior[v.mat] for v in verts]
            tau = handoff.tau[types]
            if tau <= 0:
                take[g] = True
                continue
            c = concentration(types, x0[g], verts, etas, y[g], handoff.directional)
            take[g[c > tau]] = True
    return take


def trace_photons(scene, tracer, cam, film, plan, photons, rng, stats, max_bounces=MAX_SPECULAR_BOUNCES,
                  physical=False, handoff: Handoff | None = None):
    """Follow photons through specular chains and splat at the first diffuse vertex
    (with a hand-off: only the paths it names)."""
    o, d, beta = photons.o, photons.d, photons.w
    keep = beta.max(axis=1) > 0
    o, d, beta = o[keep], d[keep], beta[keep]
    soft = photons.soft_center is not None
    stats["photons"] += int(keep.sum())
    bounces = 0
    if handoff is not None:  # per photon: each bounce's triangle, barycentrics, kind, caster flag
        K = handoff.max_chain
        max_bounces = min(max_bounces, K)
        lane = np.arange(len(o))
        y_end = -d if handoff.directional else o.copy()
        h_prim = np.zeros((len(o), K), np.int64)
        h_p = np.zeros((len(o), K, 3))
        h_bary = np.zeros((len(o), K, 2))
        h_refl = np.zeros((len(o), K), np.int64)
        h_cast = np.zeros((len(o), K), bool)
    while len(o):
        h = tracer.intersect(o, d)
        stats["rays_photon"] += len(o)
        idx = np.flatnonzero(h.hit)
        if idx.size == 0:
            break
        o, d, beta = o[idx], d[idx], beta[idx]
        p, ng, ns, prim = h.p[idx], h.ng[idx], h.ns[idx], h.prim[idx]
        if handoff is not None:
            lane = lane[idx]
            bary = h.b[idx]
        if soft and bounces == 0:
            beta = beta * soft_falloff_factor(photons.soft_center, photons.soft_radius, p)[:, None]
        mat = scene.tri_material[prim]
        obj = scene.tri_object[prim]
        kind = scene.mat_kind[mat]
        w_in = -d
        # first hit must be a planned caster; later hits may be any specular object
        spec = (kind == S.CONDUCTOR) | (kind == S.DIELECTRIC)
        if bounces == 0:
            spec &= plan.casters[obj]
        diffuse = (kind == S.DIFFUSE) & plan.receivers[obj] & (bounces > 0)
        if handoff is not None and diffuse.any():
            di = np.flatnonzero(diffuse)
            ln = lane[di]
            take = _handoff_select(scene, tracer, handoff, p[di], np.full(di.size, bounces), h_prim[ln],
                                   h_p[ln], h_bary[ln], h_refl[ln], h_cast[ln], y_end[ln])
            diffuse[di[~take]] = False
            stats["handoff_paths"] = stats.get("handoff_paths", 0) + int(take.sum())
        if diffuse.any():
            di = np.flatnonzero(diffuse)
            splat_to_camera(scene, tracer, cam, film, p[di], ng[di], ns[di], w_in[di], beta[di],
                            scene.mat_color[mat[di]], stats)
        if bounces >= max_bounces:
            stats["truncated"] += int(spec.sum())
            break
        si = np.flatnonzero(spec)
        if si.size == 0:
            break
        d_in = d[si]
        d, beta, keep = scatter_specular(scene, rng, -d[si], ns[si], ng[si], mat[si], kind[si], beta[si],
                                         scale_eta=not physical, adjoint=True)
        stats["lost_shading_normal"] += int(si.size - keep.size)
        if handoff is not None:
            sk = si[keep]
            ln = lane[sk]
            h_prim[ln, bounces] = prim[sk]
            h_p[ln, bounces] = p[sk]
            h_bary[ln, bounces] = bary[sk]
            h_refl[ln, bounces] = (dot(d_in[keep], ns[sk]) * dot(d, ns[sk]) < 0).astype(np.int64)
            h_cast[ln, bounces] = plan.casters[obj[sk]]
            lane = ln
        o = tracer.spawn(p[si][keep], ng[si][keep], d)
        bounces += 1


def trace_eye(scene, tracer, cam, film, plan, light_indices, start, n, n_batch, rng, stats,
              max_bounces=MAX_SPECULAR_BOUNCES, physical=False):
    """Caustics seen through mirrors or glass: camera -> (specular)+ -> diffuse
    receiver x0 -> (specular)+ -> light, by path tracing from the eye.

    The light tracer cannot connect such x0 to the camera (the connection
    passes a delta BSDF), so this estimator covers exactly the paths whose eye
    chain has at least one specular vertex; together they partition the
    caustic layer. From x0 a cosine-sampled direction must find a finite light
    through a specular chain whose last vertex is a caster: unbiased, noisy for
    small lights, blind to point lights of radius 0 and suns of angle 0."""
    from .eye import eye_receivers

    rc = eye_receivers(scene, tracer, cam, film, plan, start, n, n_batch, rng, stats, min_specular=1,
                       max_bounces=max_bounces, scale_eta=physical)
    _shade_receivers(scene, tracer, film, plan, light_indices, rng, stats, rc.rx, rc.ry, rc.weight,
                     rc.p, rc.ng, rc.ns, rc.w_eye, rc.beta * scene.mat_color[rc.mat], max_bounces, physical)


def _shade_receivers(scene, tracer, film, plan, light_indices, rng, stats, rx, ry, weight,
                     p, ng, ns, w_eye, beta, max_bounces, physical=False):
    """From receiver points x0 (reached through the eye chain), follow one
    cosine-sampled direction through specular chains to the lights; splat the
    radiance found at the eye sample's film position."""
    if len(p) == 0:
        return

    side = np.where(dot(w_eye, ng) >= 0, 1.0, -1.0)[:, None]
    nn = ns * side
    s, t = frame(nn)
    d = to_world(cosine_hemisphere(rng.random(len(p)), rng.random(len(p))), s, t, nn)
    ok = dot(d, ng * side) > 0  # cosine lobe below the geometric surface: no light
    rx, ry, weight = rx[ok], ry[ok], weight[ok]
    p, ng, beta, d = p[ok], ng[ok], beta[ok], d[ok]  # f cos / pdf = albedo
    o = tracer.spawn(p, ng, d)
    radiance = np.zeros((len(o), 3))
    alive = np.arange(len(o))
    last_caster = np.zeros(len(o), bool)
    bounces = 0
    while len(o):
        h = tracer.intersect(o, d)
        stats["rays_eye"] += len(o)
        if bounces > 0:  # a light seen after at least one specular vertex, itself a caster
            tsurf = np.where(h.hit, h.t, np.inf)
            best_t = tsurf.copy()
            best_L = np.zeros((len(o), 3))
            for li in light_indices:
                L, tl = light_radiance(scene, li, o, d, escaped=~h.hit)
                closer = tl < best_t
                best_t = np.where(closer, tl, best_t)
                best_L = np.where(closer[:, None], L, best_L)
            radiance[alive] += beta * best_L * last_caster[:, None]
        if bounces >= max_bounces:
            break
        kind = np.where(h.hit, scene.mat_kind[scene.tri_material[np.maximum(h.prim, 0)]], -1)
        si = np.flatnonzero((kind == S.CONDUCTOR) | (kind == S.DIELECTRIC))
        if si.size == 0:
            break
        prim = h.prim[si]
        dd, bb, keep = scatter_specular(scene, rng, -d[si], h.ns[si], h.ng[si], scene.tri_material[prim],
                                        kind[si], beta[si], scale_eta=physical)
        last_caster = plan.casters[scene.tri_object[prim]][keep]
        o = tracer.spawn(h.p[si][keep], h.ng[si][keep], dd)
        d, beta, alive = dd, bb, alive[si][keep]
        bounces += 1
    hit = np.flatnonzero(radiance.max(axis=1) > 0)
    if hit.size:
        film.splat(rx[hit], ry[hit], radiance[hit] * weight[hit, None])
        stats["eye_splats"] += int(hit.size)
