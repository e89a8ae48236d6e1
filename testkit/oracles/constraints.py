"""Specular constraints C_j(x_{j-1}, x_j, x_{j+1}) = 0 and their exact derivatives.

Two forms, both dimensionless (so thresholds need no scene scale):

- half-vector (MNEE, Jakob & Marschner 2012 / Hanika et al. 2015): the
  generalised half-vector h = normalize(eta_i w_i + eta_o w_o) projected on the
  tangent plane of the shading normal, C = (s'.h, t'.h);
- angle difference (SMS, Zeltner et al. 2020, eq. 8), written in a local frame
  (e1, e2) perpendicular to the current outgoing direction w_o instead of world
  spherical coordinates, so there is no pole: C = (e1.(w_o' - w_o),
  e2.(w_o' - w_o)) with w_o' the mirror/refraction image of w_i. The frame is
  held fixed while differentiating; its own derivative multiplies w_o' - w_o and
  vanishes on the manifold, so the Jacobian is exact at every solution.

Derivatives are taken with respect to the orthonormal tangent coordinates
(s, t) of each vertex (geometry.Vertex), and, for the last vertex, of the light
sample: a point moving in its tangent plane, or a direction moving on the unit
sphere (sun).
"""
from __future__ import annotations


import numpy as np

from smbs_addon.core.vec import dot, frame, normalize
from smbs_addon.shading.light_samples import LightEnd
from smbs_addon.walks.walk import ANGLE_DIFF

_R_MIN = 1e-6  # refraction at grazing exit: the derivative of sqrt blows up below this


def _unit_d(u, length, a):
    """d/dq of (q - x)/|q - x| = u along a (moving q); negate for moving x."""
    return (a - dot(u, a)[:, None] * u) / length[:, None]


def _orient(w, n, eta):
    """Normal on w's side and the ratio eta_from / eta_to for light leaving along the refraction."""
    outside = dot(w, n) >= 0
    no = np.where(outside[:, None], n, -n)
    eta_r = np.where(outside, 1.0 / eta, eta)
    return no, eta_r, np.where(outside, 1.0, -1.0)


def specular_map(kind: str, w, n, eta):
    """w -> mirror image (kind 'R') or refraction (kind 'T'); ok False on TIR/grazing."""
    if kind == "R":
        return 2.0 * dot(w, n)[:, None] * n - w, np.ones(len(w), bool)
    no, eta_r, _ = _orient(w, n, eta)
    c = dot(w, no)
    r2 = 1.0 - eta_r**2 * (1.0 - c * c)
    ok = r2 > _R_MIN**2
    r = np.sqrt(np.where(ok, r2, 1.0))
    out = -eta_r[:, None] * (w - c[:, None] * no) - r[:, None] * no
    return np.where(ok[:, None], out, 0.0), ok


def specular_map_d(kind: str, w, n, eta, dw, dn):
    """Directional derivative of specular_map along (dw, dn)."""
    if kind == "R":
        wn = dot(w, n)
        return 2.0 * ((dot(dw, n) + dot(w, dn))[:, None] * n + wn[:, None] * dn) - dw
    no, eta_r, sg = _orient(w, n, eta)
    dno = dn * sg[:, None]
    c = dot(w, no)
    r2 = np.maximum(1.0 - eta_r**2 * (1.0 - c * c), _R_MIN**2)
    r = np.sqrt(r2)
    dc = dot(dw, no) + dot(w, dno)
    dr = eta_r**2 * c * dc / r
    return (-eta_r[:, None] * (dw - dc[:, None] * no - c[:, None] * dno)
            - dr[:, None] * no - r[:, None] * dno)


def media(kind: str, w_i, ng, eta):
    """Indices of refraction on the w_i side and the w_o side of a vertex."""
    if kind == "R":
        one = np.ones(len(w_i))
        return one, one
    outside = dot(w_i, ng) >= 0
    return np.where(outside, 1.0, eta), np.where(outside, eta, 1.0)


def blocks(form: str, types: str, x0: np.ndarray, verts: list, etas: list, light: LightEnd):
    """Constraint values and Jacobian blocks of a chain of k = len(types) vertices.

    Returns C (N,k,2); A (N,k,2,2) = dC_j/dx_j; B = dC_j/dx_{j-1}; D = dC_j/dx_{j+1}
    (for j = k: with respect to the light end's tangents); ok (N,) False where the
    constraint is undefined (grazing refraction, vanishing half-vector)."""
    k = len(types)
    N = len(x0)
    C = np.zeros((N, k, 2))
    A = np.zeros((N, k, 2, 2))
    B = np.zeros((N, k, 2, 2))
    D = np.zeros((N, k, 2, 2))
    ok = np.ones(N, bool)
    for j in range(k):
        v = verts[j]
        prev_p = x0 if j == 0 else verts[j - 1].p
        wi = prev_p - v.p
        li = np.sqrt(dot(wi, wi))
        wi = wi / np.maximum(li, 1e-300)[:, None]
        if j == k - 1 and light.directional:
            wo, lo = light.y, None
        else:
            nxt = light.y if j == k - 1 else verts[j + 1].p
            wo = nxt - v.p
            lo = np.sqrt(dot(wo, wo))
            wo = wo / np.maximum(lo, 1e-300)[:, None]
        ok &= (li > 0) & ((lo > 0) if lo is not None else True)
        eta = etas[j]
        kind = types[j]
        prev_t = None if j == 0 else (verts[j - 1].s, verts[j - 1].t)
        if j < k - 1:
            next_t = (verts[j + 1].s, verts[j + 1].t)
        else:
            next_t = (light.ys, light.yt)
        self_t = ((v.s, v.dn_s), (v.t, v.dn_t))
        if form == ANGLE_DIFF:
            wo_p, okm = specular_map(kind, wi, v.n, eta)
            ok &= okm
            e1, e2 = frame(wo)
            diff = wo_p - wo
            C[:, j, 0], C[:, j, 1] = dot(e1, diff), dot(e2, diff)

            def dC(dwi, dn, dwo):
                dw = specular_map_d(kind, wi, v.n, eta, dwi, dn) - dwo
                return dot(e1, dw), dot(e2, dw)
        else:
            eta_i, eta_o = media(kind, wi, v.ng, eta)
            H = eta_i[:, None] * wi + eta_o[:, None] * wo
            lh = np.sqrt(dot(H, H))
            ok &= lh > 1e-9 * (eta_i + eta_o)
            h = H / np.maximum(lh, 1e-300)[:, None]
            s2 = normalize(v.s - dot(v.s, v.n)[:, None] * v.n)
            t2 = np.cross(v.n, s2)
            C[:, j, 0], C[:, j, 1] = dot(s2, h), dot(t2, h)
            hn = dot(h, v.n)

            def dC(dwi, dn, dwo):
                dH = eta_i[:, None] * dwi + eta_o[:, None] * dwo
                dh = (dH - dot(h, dH)[:, None] * h) / np.maximum(lh, 1e-300)[:, None]
                # frame rotation about n is O(C) and dropped: exact on the manifold
                return dot(s2, dh) - hn * dot(s2, dn), dot(t2, dh) - hn * dot(t2, dn)

        zero = np.zeros_like(wi)
        for col, (a, dna) in enumerate(self_t):
            dwi = -_unit_d(wi, li, a)
            dwo = zero if lo is None else -_unit_d(wo, lo, a)
            A[:, j, 0, col], A[:, j, 1, col] = dC(dwi, dna, dwo)
        if prev_t is not None:
            for col, a in enumerate(prev_t):
                B[:, j, 0, col], B[:, j, 1, col] = dC(_unit_d(wi, li, a), zero, zero)
        for col, a in enumerate(next_t):
            dwo = a if lo is None else _unit_d(wo, lo, a)  # a direction moves along its tangent
            D[:, j, 0, col], D[:, j, 1, col] = dC(zero, zero, dwo)
    return C, A, B, D, ok


# ----------------------------------------------------------------- 2x2 algebra
def inv2(M: np.ndarray, rel_eps: float = 1e-12):
    """Inverse of (N,2,2) matrices by Cramer's rule; ok False where |det| is
    tiny relative to the entries (a fold of the manifold)."""
    a, b, c, d = M[:, 0, 0], M[:, 0, 1], M[:, 1, 0], M[:, 1, 1]
    det = a * d - b * c
    scale = a * a + b * b + c * c + d * d
    ok = np.abs(det) > rel_eps * scale
    inv_det = np.divide(1.0, det, out=np.zeros_like(det), where=ok)
    out = np.empty_like(M)
    out[:, 0, 0], out[:, 0, 1] = d * inv_det, -b * inv_det
    out[:, 1, 0], out[:, 1, 1] = -c * inv_det, a * inv_det
    return out, ok


def _mm(X, Y):
    return np.einsum("nij,njk->nik", X, Y)


def block_solve(A, B, D, rhs):
    """Solve the block-tridiagonal system J x = rhs (Kaplanyan et al. 2014, supp. Fig. 2).

    A, B, D: (N,k,2,2); rhs: (N,k,2,m). Returns x (N,k,2,m) and ok (N,)."""
    N, k = A.shape[:2]
    lam_inv = [None] * k
    y = [None] * k
    ok = np.ones(N, bool)
    Li, o = inv2(A[:, 0])
    ok &= o
    lam_inv[0], y[0] = Li, rhs[:, 0]
    for j in range(1, k):
        T = _mm(B[:, j], lam_inv[j - 1])
        Li, o = inv2(A[:, j] - _mm(T, D[:, j - 1]))
        ok &= o
        lam_inv[j] = Li
        y[j] = rhs[:, j] - _mm(T, y[j - 1])
    x = [None] * k
    x[k - 1] = _mm(lam_inv[k - 1], y[k - 1])
    for j in range(k - 2, -1, -1):
        x[j] = _mm(lam_inv[j], y[j] - _mm(D[:, j], x[j + 1]))
    return np.stack(x, axis=1), ok
