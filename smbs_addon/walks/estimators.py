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


import numpy as np

from ..scene import arrays as S
from ..shading.optics import absorbing, arriving, bent, bump_correction, inside, transmittance
from ..shading.fresnel import specular_weights
from ..core.vec import dot, normalize

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


def same_solution(d_a, d_b, obj_a, obj_b, threshold):
    """Two solutions are the same when the first segment's direction agrees and
    the first vertex lies on the same object."""
    return (np.abs(dot(d_a, d_b) - 1.0) < threshold) & (obj_a == obj_b)
