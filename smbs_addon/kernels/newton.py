"""The Newton step of a specular chain (Zeltner et al. 2020): the constraints of every vertex and their
derivatives in tangent coordinates (angle-difference for SMS and SMBS, half-vector for MNEE), the
block-tridiagonal solve, and the proposal x1 - beta dx1 it makes.
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from ..core.jit import JIT
from .records import DNS, DNT, NG, NS, P, REFRACT, S, T, LightRows, NewtonScratch
from ..core.vec3 import add3, cols3, cross3, div3, dot1, frame1, max_nan, neg3, normalize3, scale3, sub3, vertex_cols3


_R_MIN = 1e-6  # as constraints._R_MIN


_R_MIN2 = _R_MIN**2


# ------------------------------------------------------------------ reflection / refraction
@njit(**JIT)
def _orient(w, n, eta):
    if dot1(w, n) >= 0:
        return n, 1.0 / eta, 1.0
    return neg3(n), eta, -1.0


@njit(inline="always", **JIT)
def smap(refract, w, n, eta):
    """constraints.specular_map for one lane: (direction, ok)."""
    if not refract:
        return sub3(scale3(2.0 * dot1(w, n), n), w), True
    no, eta_r, _ = _orient(w, n, eta)
    c = dot1(w, no)
    r2 = 1.0 - eta_r**2 * (1.0 - c * c)
    ok = r2 > _R_MIN2
    r = math.sqrt(r2 if ok else 1.0)
    if not ok:
        return (0.0, 0.0, 0.0), False
    out = sub3(scale3(-eta_r, sub3(w, scale3(c, no))), scale3(r, no))
    return out, True


@njit(inline="always", **JIT)
def smap_d_pre(refract, w, n, eta):
    """The part of constraints.specular_map_d that depends only on (w, n, eta), shared by every
    derivative at one vertex: (oriented normal, eta ratio, orientation sign, w.n', r)."""
    if not refract:
        return n, 1.0, 1.0, dot1(w, n), 0.0
    no, eta_r, sg = _orient(w, n, eta)
    c = dot1(w, no)
    r2 = max_nan(1.0 - eta_r**2 * (1.0 - c * c), _R_MIN2)
    return no, eta_r, sg, c, math.sqrt(r2)


@njit(inline="always", **JIT)
def smap_d(refract, w, pre, dw, dn):
    """constraints.specular_map_d for one lane (pre: smap_d_pre(refract, w, n, eta))."""
    no, eta_r, sg, c, r = pre
    if not refract:
        return sub3(scale3(2.0, add3(scale3(dot1(dw, no) + dot1(w, dn), no), scale3(c, dn))), dw)
    dno = scale3(sg, dn)
    dc = dot1(dw, no) + dot1(w, dno)
    dr = eta_r**2 * c * dc / r
    return sub3(sub3(scale3(-eta_r, sub3(sub3(dw, scale3(dc, no)), scale3(c, dno))), scale3(dr, no)), scale3(r, dno))


@njit(inline="always", **JIT)
def smap_d_w(refract, w, pre, dw):
    """smap_d where the normal does not move (dn = 0): the derivative by the vertex before."""
    no, eta_r, sg, c, r = pre
    if not refract:
        return sub3(scale3(2.0, scale3(dot1(dw, no), no)), dw)
    dc = dot1(dw, no)
    dr = eta_r**2 * c * dc / r
    return sub3(scale3(-eta_r, sub3(dw, scale3(dc, no))), scale3(dr, no))


@njit(**JIT)
def _unit_d(u, length, a):
    return div3(sub3(a, scale3(dot1(u, a), u)), length)


# ------------------------------------------------------------------ constraint blocks
# What a vertex's constraint is measured in (_lane_blocks): the angle-difference form's frame about
# w_o (e1, e2); the half-vector form's etas on the two sides, half-vector h (unit) and its length
# lh, tangent frame (s2, t2) and h.n
_Frame = namedtuple("_Frame", "e1 e2 eta_i eta_o h lh s2 t2 hn")


@njit(inline="always", **JIT)
def _dC(hv, refract, wi, pre, fr, dwi, dn, dwo):
    """A constraint's derivative where w_i, the normal and w_o move by dwi, dn, dwo (fr: _Frame)."""
    if not hv:
        dw = sub3(smap_d(refract, wi, pre, dwi, dn), dwo)
        return dot1(fr.e1, dw), dot1(fr.e2, dw)
    dH = add3(scale3(fr.eta_i, dwi), scale3(fr.eta_o, dwo))
    dh = div3(sub3(dH, scale3(dot1(fr.h, dH), fr.h)), max_nan(fr.lh, 1e-300))
    return dot1(fr.s2, dh) - fr.hn * dot1(fr.s2, dn), dot1(fr.t2, dh) - fr.hn * dot1(fr.t2, dn)


@njit(inline="always", **JIT)
def _lane_blocks(hv, kinds, x0, F, etas, light, lane, scratch):
    """constraints.blocks for one lane (row `lane` of F/etas/x0/light (LightRows), written to
    scratch's C/A/B/D[:]): returns ok."""
    ly, lys, lyt, directional = light.y, light.ys, light.yt, light.directional
    C, A, B, D = scratch.C, scratch.A, scratch.B, scratch.D
    k = kinds.shape[0]
    ok = True
    zero = (0.0, 0.0, 0.0)
    for j in range(k):
        refract = kinds[j] == REFRACT
        p = vertex_cols3(F, lane, j, P)
        n = vertex_cols3(F, lane, j, NS)
        prev_p = cols3(x0, lane, 0) if j == 0 else vertex_cols3(F, lane, j - 1, P)
        wi = sub3(prev_p, p)
        li = math.sqrt(dot1(wi, wi))
        wi = div3(wi, max_nan(li, 1e-300))
        has_lo = not (j == k - 1 and directional)
        lo = 1.0
        if has_lo:
            nxt = cols3(ly, lane, 0) if j == k - 1 else vertex_cols3(F, lane, j + 1, P)
            wo = sub3(nxt, p)
            lo = math.sqrt(dot1(wo, wo))
            wo = div3(wo, max_nan(lo, 1e-300))
            ok = ok and (li > 0) and (lo > 0)
        else:
            wo = cols3(ly, lane, 0)
            ok = ok and (li > 0)
        eta = etas[lane, j]
        e1 = e2 = s2 = t2 = h = zero
        eta_i = eta_o = lh = hn = 0.0
        pre = smap_d_pre(refract, wi, n, eta) if not hv else (n, 1.0, 1.0, 0.0, 0.0)
        if not hv:
            wo_p, okm = smap(refract, wi, n, eta)
            ok = ok and okm
            e1, e2 = frame1(wo)
            diff = sub3(wo_p, wo)
            C[j, 0], C[j, 1] = dot1(e1, diff), dot1(e2, diff)
        else:
            if refract:
                if dot1(wi, vertex_cols3(F, lane, j, NG)) >= 0:
                    eta_i, eta_o = 1.0, eta
                else:
                    eta_i, eta_o = eta, 1.0
            else:
                eta_i, eta_o = 1.0, 1.0
            H = add3(scale3(eta_i, wi), scale3(eta_o, wo))
            lh = math.sqrt(dot1(H, H))
            ok = ok and (lh > 1e-9 * (eta_i + eta_o))
            h = div3(H, max_nan(lh, 1e-300))
            s = vertex_cols3(F, lane, j, S)
            s2 = normalize3(sub3(s, scale3(dot1(s, n), n)))
            t2 = cross3(n, s2)
            C[j, 0], C[j, 1] = dot1(s2, h), dot1(t2, h)
            hn = dot1(h, n)
        fr = _Frame(e1, e2, eta_i, eta_o, h, lh, s2, t2, hn)
        for col in range(2):
            a = vertex_cols3(F, lane, j, S if col == 0 else T)
            dna = vertex_cols3(F, lane, j, DNS if col == 0 else DNT)
            dwi = neg3(_unit_d(wi, li, a))
            dwo = neg3(_unit_d(wo, lo, a)) if has_lo else zero
            A[j, 0, col], A[j, 1, col] = _dC(hv, refract, wi, pre, fr, dwi, dna, dwo)
            # B (by the vertex before) moves only w_i, D (by the vertex after or the light) only
            # w_o: in the angle-difference form the specular map's terms in what does not move
            # are left out (they are zeros)
            if j > 0:
                a = vertex_cols3(F, lane, j - 1, S if col == 0 else T)
                if hv:
                    B[j, 0, col], B[j, 1, col] = _dC(hv, refract, wi, pre, fr, _unit_d(wi, li, a), zero, zero)
                else:
                    dw = smap_d_w(refract, wi, pre, _unit_d(wi, li, a))
                    B[j, 0, col], B[j, 1, col] = dot1(e1, dw), dot1(e2, dw)
            else:
                B[j, 0, col] = B[j, 1, col] = 0.0
            if j < k - 1:
                a = vertex_cols3(F, lane, j + 1, S if col == 0 else T)
            else:
                a = cols3(lys, lane, 0) if col == 0 else cols3(lyt, lane, 0)
            dwo = _unit_d(wo, lo, a) if has_lo else a
            if hv:
                D[j, 0, col], D[j, 1, col] = _dC(hv, refract, wi, pre, fr, zero, zero, dwo)
            else:
                D[j, 0, col], D[j, 1, col] = -dot1(e1, dwo), -dot1(e2, dwo)
    return ok


# 2x2 matrices as tuples (m00, m01, m10, m11): held in registers. A view of a (k, 2, 2) array
# (A[j]) takes a reference to the array's memory (an atomic increment and decrement in numba's
# runtime) each time it is made, a tenth of a Newton iteration's time when made per lane.
@njit(**JIT)
def _m2(M, j):
    return (M[j, 0, 0], M[j, 0, 1], M[j, 1, 0], M[j, 1, 1])


@njit(**JIT)
def _put2(M, j, v):
    M[j, 0, 0], M[j, 0, 1], M[j, 1, 0], M[j, 1, 1] = v


@njit(**JIT)
def _sub2(X, Y):
    return (X[0] - Y[0], X[1] - Y[1], X[2] - Y[2], X[3] - Y[3])


@njit(**JIT)
def _inv2(M):
    """constraints.inv2 of one 2x2: (inverse, ok)."""
    a, b, c, d = M
    det = a * d - b * c
    scale = a * a + b * b + c * c + d * d
    ok = abs(det) > 1e-12 * scale
    inv_det = 1.0 / det if ok else 0.0
    return (d * inv_det, -b * inv_det, -c * inv_det, a * inv_det), ok


@njit(**JIT)
def _mm(X, Y):
    return (X[0] * Y[0] + X[1] * Y[2], X[0] * Y[1] + X[1] * Y[3],
            X[2] * Y[0] + X[3] * Y[2], X[2] * Y[1] + X[3] * Y[3])


@njit(inline="always", **JIT)  # inlined: as a plain njit, LLVM left a call to it in the walk (jit.py)
def copy_rows(dst, i, src, m):
    """dst[i] = src[m] for (N, a, b) arrays, element by element: numba's slice assignment costs
    ~50-100 ns per call on these small rows (views and a generic loop), more than the copy."""
    for j in range(src.shape[1]):
        for c in range(src.shape[2]):
            dst[i, j, c] = src[m, j, c]


@njit(**JIT)
def _zero_rhs(rhs, k):
    for j in range(k):
        for r in range(2):
            for c in range(2):
                rhs[j, r, c] = 0.0


@njit(**JIT)
def lane_scratch(k):
    """Per-lane work arrays of _lane_blocks and _lane_solve for a chain of k vertices
    (NewtonScratch)."""
    return NewtonScratch(np.zeros((k, 2)), np.zeros((k, 2, 2)), np.zeros((k, 2, 2)), np.zeros((k, 2, 2)),
                         np.zeros((k, 2, 2)), np.zeros((k, 2, 2)), np.zeros((k, 2, 2)), np.zeros((k, 2, 2)))


@njit(inline="always", **JIT)
def _lane_solve(A, B, D, rhs, Li, Y, X):
    """constraints.block_solve for one lane, 2 right-hand columns; X[:] the solution; ok."""
    k = A.shape[0]
    L, ok = _inv2(_m2(A, 0))
    _put2(Li, 0, L)
    _put2(Y, 0, _m2(rhs, 0))
    for j in range(1, k):
        Tm = _mm(_m2(B, j), _m2(Li, j - 1))
        L, okj = _inv2(_sub2(_m2(A, j), _mm(Tm, _m2(D, j - 1))))
        ok = okj and ok
        _put2(Li, j, L)
        _put2(Y, j, _sub2(_m2(rhs, j), _mm(Tm, _m2(Y, j - 1))))
    _put2(X, k - 1, _mm(_m2(Li, k - 1), _m2(Y, k - 1)))
    for j in range(k - 2, -1, -1):
        _put2(X, j, _mm(_m2(Li, j), _sub2(_m2(Y, j), _mm(_m2(D, j), _m2(X, j + 1)))))
    return ok


# chain_solve's copies of the two, called rather than inlined (compiled once, ~10 s, where inlined in
# chain_solve they took ~25 s more of a first bake's compile); the walk keeps them inlined (called
# there too, the walks compiled ~35 s less, but the hammered mirror's bakes took 8-15% longer)
_lane_blocks_called = njit(**JIT)(_lane_blocks.py_func)


_lane_solve_called = njit(**JIT)(_lane_solve.py_func)


@njit(**JIT)
def chain_solve(mode, hv, kinds, x0, F, etas, ly, lys, lyt, directional):
    """Per lane, the constraints' blocks and the block-tridiagonal solve of the first vertex:
    mode 0 (Newton): J x = C, out[:, :, 0] = x_1 (column 1 zero); mode 1 (geometric term):
    J X = -D_k e_k, out = X_1 (2x2). ok False (and out zero) where the constraint or a 2x2 pivot
    is undefined."""
    N = x0.shape[0]
    k = kinds.shape[0]
    out = np.zeros((N, 2, 2))
    oks = np.zeros(N, np.bool_)
    scratch = lane_scratch(k)
    light = LightRows(ly, lys, lyt, directional)
    C, A, B, D, rhs, Li, Y, X = (scratch.C, scratch.A, scratch.B, scratch.D, scratch.rhs, scratch.Li, scratch.Y,
                                 scratch.X)
    for i in range(N):
        ok = _lane_blocks_called(hv, kinds, x0, F, etas, light, i, scratch)
        _zero_rhs(rhs, k)
        if mode == 0:
            for j in range(k):
                rhs[j, 0, 0], rhs[j, 1, 0] = C[j, 0], C[j, 1]
        else:
            for r in range(2):
                for c in range(2):
                    rhs[k - 1, r, c] = -D[k - 1, r, c]
        oks_ = _lane_solve_called(A, B, D, rhs, Li, Y, X)
        ok = ok and oks_
        if ok:
            copy_rows(out, i, X, 0)
            if mode == 0:
                out[i, 0, 1] = out[i, 1, 1] = 0.0
        oks[i] = ok
    return out, oks


@njit(inline="always", **JIT)
def lane_newton(i, hv, kinds, x0, F, etas, light, beta, max_step, scratch):
    """The small mutation of lane i (see newton_proposal; light: LightRows, scratch: lane_scratch's
    NewtonScratch): (ok, proposed x1, direction). Its callers are LANES kernels (jit.LANES): where
    numba counts references, each array a record gives up costs a count per lane."""
    k = kinds.shape[0]
    ok = _lane_blocks(hv, kinds, x0, F, etas, light, i, scratch)
    C, rhs, X = scratch.C, scratch.rhs, scratch.X
    _zero_rhs(rhs, k)
    for j in range(k):
        rhs[j, 0, 0], rhs[j, 1, 0] = C[j, 0], C[j, 1]
    ok = _lane_solve(scratch.A, scratch.B, scratch.D, rhs, scratch.Li, scratch.Y, X) and ok
    p1 = vertex_cols3(F, i, 0, P)
    if not ok:
        return False, p1, (0.0, 0.0, 0.0)
    s = vertex_cols3(F, i, 0, S)
    t = vertex_cols3(F, i, 0, T)
    step = neg3(add3(scale3(X[0, 0, 0], s), scale3(X[0, 1, 0], t)))
    ls = math.sqrt(dot1(step, step))
    step = scale3(min(1.0, max_step / max_nan(ls, 1e-300)), step)
    p = add3(p1, scale3(beta[i], step))
    return True, p, normalize3(sub3(p, cols3(x0, i, 0)))


@njit(**JIT)
def newton_proposal(idx, hv, kinds, x0, F, etas, ly, lys, lyt, directional, beta, max_step):
    """walk.newton_walk's small mutation for lanes idx (rows of the full arrays): the Newton
    step of x1 in its tangent plane, shortened to max_step and scaled by beta; returns the
    proposed x1 p (M,3), the direction d = normalize(p - x0) (M,3), and ok (M,) (False where
    the constraints or the solve are singular; p = x1 and d zero there)."""
    M = idx.shape[0]
    p_out = np.zeros((M, 3))
    d_out = np.zeros((M, 3))
    oks = np.zeros(M, np.bool_)
    scratch = lane_scratch(kinds.shape[0])
    light = LightRows(ly, lys, lyt, directional)
    for m in range(M):
        ok, p, d = lane_newton(idx[m], hv, kinds, x0, F, etas, light, beta, max_step, scratch)
        oks[m] = ok
        p_out[m, 0], p_out[m, 1], p_out[m, 2] = p
        d_out[m, 0], d_out[m, 1], d_out[m, 2] = d
    return p_out, d_out, oks
