"""What a gather path meets at its vertices and along its segments: the cosine bounce off a diffuse
vertex, a light's direct light there (one light sample), and the lights a segment sees before its next
surface. The compiled gather (gather.py), its numpy form (gather_generations.py) and the hand-off's cosine
gather take them from here.
"""
from __future__ import annotations

import math

import numpy as np

from ..kernels import handoff
from ..scene import arrays as S
from ..core.vec import cross, dot, normalize
from ..shading.lights import area_light_shape, light_radiance, shadow_tmax
from ..shading.light_samples import light_end_at_solution, sample_light

MAX_SPECULAR = 32  # specular vertices a gather path follows between two diffuse ones


def albedo(scene, mat):
    """The diffuse colour of materials mat."""
    return scene.mat_color[mat]


def diffuse_bounce(rng, w_in, ng, ns, beta, albedo, adjoint, direction_u=None):
    """Cosine-sampled bounce off diffuse vertices (about the shading normal on w_in's side),
    with Russian roulette on the albedo (handoff.diffuse_rows). direction_u: (rows, (n, 2)
    uniforms) the direction's two numbers of those rows (stratified: qmc.BOUNCE). Returns
    (directions, weights, kept vertices)."""
    f64 = lambda a: np.ascontiguousarray(a, np.float64)  # noqa: E731
    u = rng.random((3, len(w_in)))
    if direction_u is not None:
        u[:2, direction_u[0]] = direction_u[1].T
    return handoff.diffuse_rows(u, f64(w_in), f64(ng), f64(ns), f64(beta), f64(albedo), bool(adjoint))


def direct_light(scene, tracer, li, p, ng, ns, w_eye, rng, stats, obj=None):
    """Direct light of light li at diffuse points (one light sample each), as outgoing
    radiance towards w_eye divided by the albedo: cos * L_e * G / (pi p). obj: the points'
    objects, none lit where the light's Light Linking leaves the object out (None: all lit)."""

    n = len(p)
    out = np.zeros((n, 3))
    if n == 0:
        return out
    light = sample_light(scene, li, n, rng)
    _, e = light_end_at_solution(scene, li, light, p)
    typ = scene.light_type[li]
    if light.directional:
        dirs, dist = light.y, np.full(n, np.inf)
        g = np.ones(n)
    else:
        to = light.y - p
        dist = np.sqrt(dot(to, to))
        dirs = to / np.maximum(dist, 1e-300)[:, None]
        if typ == S.AREA:
            nrm = area_light_shape(scene, li).nrm
            cos_y = np.maximum(0.0, -dot(dirs, nrm))
        elif typ == S.MESH:  # both sides shine
            cos_y = np.abs(dot(dirs, cross(light.ys, light.yt)))
        elif scene.light_radius[li] > 0:
            cos_y = np.maximum(0.0, -dot(dirs, normalize(light.y - scene.light_matrix[li][:3, 3])))
        else:
            cos_y = np.ones(n)
        g = cos_y / np.maximum(dist, 1e-300) ** 2
    side = np.sign(dot(w_eye, ng))
    cos_x = dot(dirs, ns) * side
    ok = (cos_x > 0) & (dot(dirs, ng) * side > 0) & (g > 0) & (e.max(axis=1) > 0)
    if obj is not None and scene.light_linked(li):
        ok &= scene.lit_by(li)[obj]
    idx = np.flatnonzero(ok)
    if idx.size:
        o = tracer.spawn(p[idx], ng[idx], dirs[idx])
        tmax = np.full(idx.size, np.inf) if light.directional else \
            shadow_tmax(scene, li, light.y[idx], light.ys[idx], light.yt[idx], o, dirs[idx], dist[idx], tracer.eps)
        blocked = tracer.occluded_past(o, dirs[idx], tmax, S.RAY_SHADOW, scene.unshadowing(li))  # Shadow Linking
        stats["rays_direct"] = stats.get("rays_direct", 0) + int(idx.size)
        idx = idx[~blocked]
        out[idx] = (cos_x[idx] * g[idx] / math.pi)[:, None] * e[idx]
    return out


def seen_light(scene, tracer, li, o, d, refl, surf_t, obj):
    """Where segments o + t d (leaving a reflection where refl, a refraction elsewhere; their next surface
    at surf_t, inf where none) see light li before that surface, its radiance and distance: (seen, L, tl).
    Cycles' lights are transparent (shade_light adds the emission and the path goes on): a light counts
    wherever it lies in front of the next surface, not only the nearest. Under Shadow Linking, past the
    surfaces of the objects that do not shadow the light as well (Cycles' dedicated light rays): the light
    is found beyond the surfaces (tl its distance there) and the segments that meet it are traced again,
    passing those objects. Light Linking: where the light lights obj, the object of the vertex each segment
    leaves."""
    refl = np.broadcast_to(np.asarray(refl, bool), (len(o),))
    passable = scene.unshadowing(li)
    if passable is None:
        L, tl = light_radiance(scene, li, o, d, escaped=~np.isfinite(surf_t), refl=refl, surf_t=surf_t,
                               eps=tracer.eps)
        seen = tl < surf_t
    else:
        L, tl = light_radiance(scene, li, o, d, refl=refl, beyond=True, eps=tracer.eps)
        seen = L.max(axis=1) > 0
        for r, kind in ((True, S.RAY_GLOSSY), (False, S.RAY_TRANSMISSION)):
            j = np.flatnonzero(seen & (refl == r))
            if j.size:  # short of the light itself (a mesh light's triangles are surfaces)
                seen[j] = ~tracer.occluded_past(o[j], d[j], tl[j] * (1.0 - 1e-6), kind, passable)
    seen &= L.max(axis=1) > 0
    if scene.light_linked(li):
        seen &= scene.lit_by(li)[obj]
    return seen, L, tl
