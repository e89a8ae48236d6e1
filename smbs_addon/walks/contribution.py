"""What a converged chain contributes.

Contribution of a solution x0 -> x1..xk -> y (Zeltner et al. 2020, eq. 7):

    beta_eye * f_d(x0) cos(x0) * T(x1..xk) * G(x0 <-> y) * L_e(y) / p(y)

with the generalised geometric term G = |dw0/dA_y| (or |dw0/dw_y| for a
sun), computed from the block-tridiagonal Jacobian (Jakob & Marschner 2012):
solving J X = -D_k gives dx1/dy in orthonormal tangent coordinates, so
dw0/dA_y = |cos theta_1| / |x1 - x0|^2 * |det dx1/dy| (paths/focus.py). T multiplies
each vertex's Fresnel term and colour, and the radiance change (eta_to/eta_from)^2
at refractions in physical units (Cycles leaves radiance unscaled, and so do
we by default: the layer is added to a Cycles render).
"""
from __future__ import annotations

import math

import numpy as np
from ..scene import arrays as S
from ..shading.optics import absorbing, arriving, bent, bump_correction, bump_shadowing, coat_factor, inside, transmittance
from ..core.vec import channel_mean, dot, normalize
from ..paths.focus import geometric_term
from ..shading.light_samples import light_end_at_solution
from ..shading.lights import shadow_tmax
from ..shading.fresnel import specular_weights

def chain_throughput(scene, types, x0, verts, light_point, directional, physical=False):
    """Product over the chain of the specular weights (optics.specular_weights), (N,3); zero
    through a vertex whose normal Cycles would bend (optics.bent: indirect.bent_gather's paths)."""
    n = len(x0)
    T = np.ones((n, 3))
    corr = bump_correction(scene)
    for j, kind in enumerate(types):
        v = verts[j]
        prev = x0 if j == 0 else verts[j - 1].p
        wi = normalize(prev - v.p)
        if corr.any():  # a vertex Cycles' Bump Map Correction bends: not Cycles' path (optics.scatter1)
            c = np.flatnonzero(corr[v.mat])
            if c.size:
                T[c[bent(wi[c], v.n[c], v.ng[c])]] = 0.0
        R, Tr = specular_weights(scene, v.mat, dot(wi, v.n))
        if kind == "R":
            T *= R
        else:
            w = Tr
            if physical:  # light arrives from the w_o side and leaves on the w_i side
                eta = scene.mat_ior[v.mat]
                ratio = np.where(dot(wi, v.ng) < 0, eta, 1.0 / eta)  # eta(w_i side) / eta(w_o side)
                w = w * (ratio**2)[:, None]
            T *= w
    if absorbing(scene):  # inside glass: what its Volume Absorption leaves (optics.transmittance)
        glass = scene.mat_kind == S.DIELECTRIC
        v0 = verts[0]  # x0 to the first vertex: inside where x0 lies under it (a pool's floor)
        seg = x0 - v0.p
        T *= transmittance(scene, inside(scene, v0.mat, glass[v0.mat], seg, v0.ng), np.sqrt(dot(seg, seg)))
        for j in range(len(types)):
            v = verts[j]
            if j + 1 < len(types):
                q, nxt = verts[j + 1].p, verts[j + 1]
            elif directional:
                continue  # towards a sun: out of every glass
            else:
                q, nxt = light_point, None
            seg = q - v.p
            medium = inside(scene, v.mat, glass[v.mat], seg, v.ng)
            if nxt is not None:  # or arriving at the next vertex from its back
                medium = arriving(scene, medium, nxt.mat, np.ones(len(seg), bool), seg, nxt.ng)
            T *= transmittance(scene, medium, np.sqrt(dot(seg, seg)))
    return T


def _contribution(ctx, li, types, rc, idx, light, chain, emit_scale=1.0):
    """Radiance estimate (without estimator weight) of converged lanes, and visibility.
    emit_scale: the light sample's pdf relative to uniform over the light."""
    scene, tracer = ctx.scene, ctx.tracer
    x0 = rc.p[idx]
    verts = chain.verts
    k = len(types)
    xk = verts[k - 1].p
    le, emit = light_end_at_solution(scene, li, light, xk)
    emit = emit * emit_scale
    etas = [scene.mat_ior[v.mat] for v in verts]
    G, okg = geometric_term(types, x0, verts, etas, le)
    d01 = normalize(verts[0].p - x0)
    ng0, ns0, w_eye = rc.ng[idx], rc.ns[idx], rc.w_eye[idx]
    side = np.sign(dot(w_eye, ng0))
    cos0 = dot(d01, ns0) * side
    ok = okg & (dot(d01, ng0) * side > 0) & (cos0 > 0)
    if scene.light_linked(li):  # Light Linking: Cycles asks it of the vertex the light leaves last
        ok &= scene.lit_by(li)[verts[k - 1].obj]
    if np.any(scene.mat_view_bump):  # bumped receivers: Cycles' shadowing of their bent normals
        cos0 = cos0 * bump_shadowing(scene, rc.mat[idx], rc.sn[idx], ns0, d01)
    T = chain_throughput(scene, types, x0, verts, le.y, le.directional, ctx.physical)
    albedo = scene.mat_color[rc.mat[idx]]
    if ctx.coated:  # under a Principled coat: Cycles' on-minus-off keeps (f_d + f_g) x the diffuse's MIS share
        albedo = albedo * coat_factor(scene, rc.mat[idx], ns0, w_eye, d01, share=ctx.first_order)
    val = rc.beta[idx] * albedo / math.pi * (np.maximum(cos0, 0) * G)[:, None] * T * emit
    ok &= val.max(axis=1) > 0
    # shadow ray from the last vertex to the light sample
    if le.directional:
        dirs, tmax = le.y, np.full(len(xk), np.inf)
    else:
        to = le.y - xk
        dist = np.sqrt(dot(to, to))
        dirs, tmax = to / np.maximum(dist, 1e-300)[:, None], dist * (1 - 1e-7)
    vis_idx = np.flatnonzero(ok)
    if vis_idx.size:
        o = tracer.spawn(xk[vis_idx], verts[k - 1].ng[vis_idx], dirs[vis_idx])
        # the ray leaving the last vertex, glossy or transmission: it passes what its kind does not meet,
        # and what does not shadow the light (Shadow Linking)
        t_far = tmax[vis_idx] - tracer.eps if le.directional else \
            shadow_tmax(scene, li, le.y[vis_idx], le.ys[vis_idx], le.yt[vis_idx], o, dirs[vis_idx],
                        dist[vis_idx], tracer.eps)
        blocked = tracer.occluded_past(o, dirs[vis_idx], t_far,
                                       S.RAY_GLOSSY if types[-1] == "R" else S.RAY_TRANSMISSION,
                                       scene.unshadowing(li))
        ctx.count("rays_shadow", vis_idx.size)
        ctx.stats["occluded"] = ctx.stats.get("occluded", 0) + int(blocked.sum())
        ok[vis_idx[blocked]] = False
    finite = np.all(np.isfinite(val), axis=1)
    ctx.stats["non_finite"] = ctx.stats.get("non_finite", 0) + int((ok & ~finite).sum())
    ok &= finite
    val = np.where(ok[:, None], val, 0.0)
    ctx.clamp_cut = None
    if ctx.clamp > 0:  # biased: caps the fold's (and G's) spikes; what is cut goes to the statistics
        lum = channel_mean(val)
        over = lum > ctx.clamp
        val[over] *= (ctx.clamp / lum[over])[:, None]
        ctx.clamp_cut = np.where(over, lum - ctx.clamp, 0.0)
    return val, ok


def _count_clamped(ctx, removed):
    """Clamp statistics: solutions cut and the luminance they lost, weighted as splatted
    (the bake divides by the number of batches, so the sum is in image units)."""
    if removed is None:
        return
    st = ctx.stats
    st["clamped"] = st.get("clamped", 0) + int((removed > 0).sum())
    st["clamped_energy"] = st.get("clamped_energy", 0.0) + float(removed.sum())
