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

import numpy as np

from . import scene as S
from .optics import fresnel_dielectric, fresnel_schlick, reflect, refract
from .vec import dot, normalize

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


def trace_photons(scene, tracer, cam, film, plan, photons, rng, stats, max_bounces=MAX_SPECULAR_BOUNCES):
    """Follow photons through specular chains and splat at the first diffuse vertex."""
    o, d, beta = photons.o, photons.d, photons.w
    keep = beta.max(axis=1) > 0
    o, d, beta = o[keep], d[keep], beta[keep]
    stats["photons"] += int(keep.sum())
    bounces = 0
    while len(o):
        h = tracer.intersect(o, d)
        stats["rays_photon"] += len(o)
        idx = np.flatnonzero(h.hit)
        if idx.size == 0:
            break
        o, d, beta = o[idx], d[idx], beta[idx]
        p, ng, ns, prim = h.p[idx], h.ng[idx], h.ns[idx], h.prim[idx]
        mat = scene.tri_material[prim]
        obj = scene.tri_object[prim]
        kind = scene.mat_kind[mat]
        w_in = -d
        # first hit must be a planned caster; later hits may be any specular object
        spec = (kind == S.CONDUCTOR) | (kind == S.DIELECTRIC)
        if bounces == 0:
            spec &= plan.casters[obj]
        diffuse = (kind == S.DIFFUSE) & plan.receivers[obj] & (bounces > 0)
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
        p, ng, ns, w_in, beta, mat, kind = p[si], ng[si], ns[si], w_in[si], beta[si], mat[si], kind[si]
        n_out = np.zeros_like(p)
        ok = np.ones(len(p), bool)
        cond = kind == S.CONDUCTOR
        if cond.any():
            ci = np.flatnonzero(cond)
            r = reflect(w_in[ci], ns[ci])
            f = np.where((scene.mat_fresnel[mat[ci]] == S.FRESNEL_SCHLICK)[:, None],
                         fresnel_schlick(dot(w_in[ci], ns[ci]), scene.mat_color[mat[ci]]),
                         scene.mat_color[mat[ci]])
            n_out[ci] = r
            beta[ci] = beta[ci] * f
        diel = kind == S.DIELECTRIC
        if diel.any():
            di = np.flatnonzero(diel)
            eta = scene.mat_ior[mat[di]]
            wi, n = w_in[di], ns[di]
            F = fresnel_dielectric(dot(wi, n), eta)
            choose_r = rng.random(di.size) < F
            t, t_ok = refract(wi, n, eta)
            choose_r |= ~t_ok
            out = np.where(choose_r[:, None], reflect(wi, n), t)
            tint = np.where(choose_r[:, None], scene.mat_reflect_color[mat[di]], scene.mat_color[mat[di]])
            n_out[di] = out
            beta[di] = beta[di] * tint
        # the geometric normal decides the side: reflection stays, refraction crosses
        cin, cout = dot(w_in, ng), dot(n_out, ng)
        is_refl = dot(w_in, ns) * dot(n_out, ns) > 0
        ok &= np.where(is_refl, cin * cout > 0, cin * cout < 0)
        ok &= beta.max(axis=1) > 0
        stats["lost_shading_normal"] += int((~ok).sum())
        keep = np.flatnonzero(ok)
        d = normalize(n_out[keep])
        o = tracer.spawn(p[keep], ng[keep], d)
        beta = beta[keep]
        bounces += 1
