"""What a converged chain contributes, and the two ways to weight it.

Contribution of a solution x0 -> x1..xk -> y (Zeltner et al. 2020, eq. 7):

    beta_eye * f_d(x0) cos(x0) * T(x1..xk) * G(x0 <-> y) * L_e(y) / p(y)

with the generalised geometric term G = |dw0/dA_y| (or |dw0/dw_y| for a
sun), computed from the block-tridiagonal Jacobian (Jakob & Marschner 2012):
solving J X = -D_k gives dx1/dy in orthonormal tangent coordinates, so
dw0/dA_y = |cos theta_1| / |x1 - x0|^2 * |det dx1/dy|. T multiplies each
vertex's Fresnel term and colour, and the radiance change (eta_to/eta_from)^2
at refractions in physical units (Cycles leaves radiance unscaled, and so do
we by default: the layer is added to a Cycles render).

Estimators over M trials of the stochastic walk:
- unbiased: 1/p of the found solution by geometric Bernoulli trials (repeat the
  whole procedure until the same solution comes back);
- biased: the sum over the unique solutions found, each with weight one.
"""
from __future__ import annotations

import math

import numpy as np

from ..scene import arrays as S
from .constraints import LightEnd
from ..scene.geometry import packed_floats
from ..kernels.compiled import chain_kinds, chain_solve
from ..shading.lights import distant_cone, env_map, has_spread, soft_falloff_factor, spot_mask, spread_factor
from ..shading.optics import absorbing, arriving, bent, bump_correction, inside, specular_weights, transmittance
from ..core.vec import cross, dot, frame, normalize

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


def light_end_at_solution(scene, li, light: LightEnd, xk):
    """Tangents of the light end at the solution (for the geometric term) and
    the emission factor L_e / p per lane, zero where the light does not face xk."""
    typ = scene.light_type[li]
    color = scene.light_color[li]
    n = len(xk)
    if typ in S.DISTANT:  # L / p over the cone of directions: the strength, or the map's L / p
        ys, yt = frame(light.y)
        env = env_map(scene, li)
        if env is not None:
            return LightEnd(True, light.y, ys, yt), env.value(light.y)
        return LightEnd(True, light.y, ys, yt), np.broadcast_to(distant_cone(scene, li)[2], (n, 3)).copy()
    m = scene.light_matrix[li]
    if typ == S.MESH:  # (L) / (1 / A) from both sides, the tangents those sample_light drew
        nrm = cross(light.ys, light.yt)
        facing = dot(xk - light.y, nrm) != 0
        e = np.where(facing[:, None], color * scene.mesh_light(li)[4], 0.0)
        return LightEnd(False, light.y, light.ys, light.yt), e
    if typ == S.AREA:
        ax = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)
        nrm = -ax[:, 2]
        facing = dot(xk - light.y, nrm) > 0
        ys = np.broadcast_to(ax[:, 0], (n, 3)).copy()
        yt = np.broadcast_to(ax[:, 1], (n, 3)).copy()
        e = np.where(facing[:, None], color / math.pi, 0.0)  # (P / (pi A)) / (1 / A)
        if has_spread(scene, li):  # Cycles' soft-box spread, along the light's last segment
            e = e * spread_factor(scene, li, dot(normalize(xk - light.y), nrm))[:, None]
        return LightEnd(False, light.y, ys, yt), e
    r = float(scene.light_radius[li])
    c = m[:3, 3]
    if r > 0:
        nrm = normalize(light.y - c)
        facing = dot(xk - light.y, nrm) > 0
        e = np.where(facing[:, None], color / math.pi, 0.0)  # (P / (4 pi^2 r^2)) / (1 / (4 pi r^2))
    else:
        nrm = normalize(xk - c)  # a point light: the tangent plane faces the chain
        e = np.broadcast_to(color / (4.0 * math.pi), (n, 3)).copy()  # intensity, per unit dA_perp
    ys, yt = frame(nrm)
    if typ == S.SPOT:  # Cycles masks the ray leaving the light's point, not its centre (the light tracer too)
        e = e * spot_mask(scene, li, normalize(xk - light.y))[:, None]
    if r > 0 and scene.light_soft_falloff[li]:
        e = e * soft_falloff_factor(c, r, xk)[:, None]
    return LightEnd(False, light.y, ys, yt), e


def geometric_term(types, x0, verts, etas, light_end: LightEnd):
    """|d w0 / d A_y| (or d w0 / d w_y for a sun) at converged chains, and ok."""
    # constraints.blocks + block_solve with the right-hand side -D_k, per lane in one kernel
    F = packed_floats(verts)
    X1, oks = chain_solve(1, False, chain_kinds(types), x0, F, np.stack(np.broadcast_arrays(*etas), 1), light_end.y,
                          light_end.ys, light_end.yt, light_end.directional)
    det = X1[:, 0, 0] * X1[:, 1, 1] - X1[:, 0, 1] * X1[:, 1, 0]
    d01 = verts[0].p - x0
    r2 = dot(d01, d01)
    cos1 = np.abs(dot(d01, verts[0].ng)) / np.sqrt(np.maximum(r2, 1e-300))
    g = cos1 / np.maximum(r2, 1e-300) * np.abs(det)
    ok = oks & np.isfinite(g)
    return np.where(ok, g, 0.0), ok


def concentration(types, x0, verts, etas, y, directional):
    """How strongly the chain focuses light onto x0, a function of the path alone:
    G of the path with its light end taken as a point at y (tangent plane facing
    the chain) times the squared unfolded length, |d w0 / d w_y| for a sun. An
    unfocused chain (a flat mirror) gives 1; it grows without bound at a fold.
    The manifold pass and the photon hand-off both evaluate it, on the same
    paths, so a threshold on it partitions path space exactly between them."""
    n = len(x0)
    if directional:
        ys, yt = frame(y)
        g, ok = geometric_term(types, x0, verts, etas, LightEnd(True, y, ys, yt))
        return np.where(ok, g, np.inf)
    last = verts[len(types) - 1].p
    ys, yt = frame(normalize(last - y))
    g, ok = geometric_term(types, x0, verts, etas, LightEnd(False, y, ys, yt))
    length = np.zeros(n)
    prev = x0
    for v in verts:
        d = v.p - prev
        length += np.sqrt(dot(d, d))
        prev = v.p
    d = y - prev
    length += np.sqrt(dot(d, d))
    return np.where(ok, g * length**2, np.inf)


def same_solution(d_a, d_b, obj_a, obj_b, threshold):
    """Two solutions are the same when the first segment's direction agrees and
    the first vertex lies on the same object."""
    return (np.abs(dot(d_a, d_b) - 1.0) < threshold) & (obj_a == obj_b)
