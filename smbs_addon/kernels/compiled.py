"""Compiled (numba) per-lane kernels of the manifold walk: the Newton step of a chain, a chain
vertex from a ray hit, and whole walks. Issue 11: the walks spent their time on numpy's
per-call overhead (dozens of tiny (N,3) operations per Newton step on a few hundred lanes),
then on the round trips through Python between each Newton step and its rays; now a walk runs
from its seed to its outcome inside one kernel call, casting its rays through embree itself
(embree.py): walk_lanes for the primary walks, bernoulli_lanes for the unbiased estimator's
trials.

Each kernel is a loop over lanes doing, per lane, the same IEEE operations in the same order
as the numpy reference it replaces (constraints.blocks + block_solve, geometry.vertex_from_hits,
tracer.intersect's float64 re-computation, constraints.specular_map, walk.propagate's checks);
no fastmath, so results agree with the reference to rounding (tests/test_kernels.py). Degenerate
input gives ok False and zeros, never an exception (error_model="numpy": x / 0 is inf or NaN
as in numpy, and the ok flags catch it).

Compiled on first use and cached on disk (jit.py). nogil: threads run blocks of lanes side by
side (lanes.blocks); each lane's walk depends on its own inputs alone, so the cut changes
nothing.

Chain vertices are packed: F (N, k, NF) float64 with the columns below, I (N, k, 3) int64
(prim, obj, mat).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .embree import KINDS, intersect1, occluded1, ray_state
from ..core.jit import JIT, LANES
from ..shading.coat import LAMBERT_FLOOR, MU_STEPS
from ..shading.optics import bend1, bump_shadowing1, fresnel_dielectric1, scatter1
from ..shading.microfacet import SINGULAR_ALPHA2, frame1
from ..shading.microfacet import dot1 as _dot

# packed vertex columns
P, NG, NS, S, T, DNS, DNT = 0, 3, 6, 9, 12, 15, 18
NF = 21


def chain_kinds(types: str) -> np.ndarray:
    """A chain type's vertices as the kernels take them: 1 for a refraction (T), 0 for a
    reflection (R)."""
    return np.array([1 if c == "T" else 0 for c in types], np.int64)
PRIM, OBJ, MAT = 0, 1, 2

_R_MIN = 1e-6  # as constraints._R_MIN
_R_MIN2 = _R_MIN**2
# walk outcome codes used here (walk.py)
_OK, _MISS, _NOT_CASTER, _WRONG_MATERIAL, _TIR, _SIDE = 0, 1, 2, 3, 4, 5
_TIR_INNER, _SIDE_INNER = 11, 12
_CONDUCTOR, _DIELECTRIC = 1, 2
_RAY_CAMERA, _RAY_DIFFUSE, _RAY_GLOSSY, _RAY_TRANSMISSION = 1, 2, 4, 8  # scene.RAY_*: Cycles' Ray Visibility
_PATH_RAYS = _RAY_DIFFUSE | _RAY_GLOSSY | _RAY_TRANSMISSION  # the kinds a caustic path's rays after the camera's are
# the surfaces of objects a ray's kind does not meet (Scene.hidden_kinds) it passes, at most: past them
# it counts as a miss (a maze of hidden glass)
HIDDEN_PASSES = 16
# ray kinds the walk kernels count (embree.ray_state's counters)
RAYS_SEED, RAYS_WALK = 0, 1

_JIT = JIT
_LANES = LANES

# numpy's flag bits that change an array's numba type: C_CONTIGUOUS, F_CONTIGUOUS, ALIGNED, WRITEABLE
_TYPE_FLAGS = 0x1 | 0x2 | 0x100 | 0x400


def _arg_key(v):
    """What of v decides its numba type, cheaply: dtype, ndim and layout flags of arrays,
    recursively in tuples, the Python type of anything else (bool, int, float)."""
    t = type(v)
    if t is np.ndarray:
        return (v.dtype.char, v.ndim, v.flags.num & _TYPE_FLAGS)
    if t is tuple:
        return tuple(map(_arg_key, v))
    return t


class TypedOnce:
    """A kernel called with tuples (the walk's settings, lane and state, passed as one argument
    each) without numba typing those tuples on every call. numba's dispatcher types a tuple of
    more than 4 items in Python on each call (its C fingerprint cache gives up on them): 0.1-0.5
    ms per call, under the GIL, 1.0 s of a 4.9 s bake (glass sphere 256^2, SMS) before this.
    Here the compiled code for an argument key (_arg_key) is looked up once through the
    dispatcher and then called directly (numba's own wrapper: it unboxes the arguments, releases
    the GIL as nogil asks, raises as the kernel raises). A key whose types numba would convert
    rather than match exactly keeps going through the dispatcher."""

    def __init__(self, dispatcher):
        self.dispatcher = dispatcher
        self.__doc__ = dispatcher.__doc__
        self._entries: dict = {}

    def __call__(self, *args):
        key = _arg_key(args)
        entry = self._entries.get(key)
        if entry is not None:
            return entry(*args)
        out = self.dispatcher(*args)  # types, compiles or loads from the cache
        if key not in self._entries:
            sig = tuple(self.dispatcher.typeof_pyval(a) for a in args)
            cres = self.dispatcher.overloads.get(sig)
            self._entries[key] = cres.entry_point if cres is not None else self.dispatcher
        return out



# ------------------------------------------------------------------ 3-vectors as tuples
# These and the keyed random numbers are called, not inline="always" (jit.py: LLVM inlines them)
@njit(**_JIT)
def _v(a, i, off):
    return (a[i, off], a[i, off + 1], a[i, off + 2])


@njit(**_JIT)
def _vk(F, i, j, off):
    return (F[i, j, off], F[i, j, off + 1], F[i, j, off + 2])


@njit(**_JIT)
def _add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit(**_JIT)
def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(**_JIT)
def _mul(s, a):
    return (s * a[0], s * a[1], s * a[2])


@njit(**_JIT)
def _div(a, s):
    return (a[0] / s, a[1] / s, a[2] / s)


@njit(**_JIT)
def _neg(a):
    return (-a[0], -a[1], -a[2])


@njit(**_JIT)
def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(**_JIT)
def _lambda_ggx(cos, a2):
    c2 = max(cos * cos, 1e-12)
    return 0.5 * (math.sqrt(1.0 + a2 * max(1.0 / c2 - 1.0, 0.0)) - 1.0)


@njit(**_JIT)
def _on_g(c):
    """layer.oren_nayar_g for one cosine."""
    if c < 1e-6:
        return (math.pi / 2 - 2.0 / 3.0) - c
    sn = math.sqrt(max(1.0 - c * c, 0.0))
    th = math.acos(min(c, 1.0))
    return sn * (th - 2.0 / 3.0 - sn * c) + 2.0 / 3.0 * (sn / c) * (1.0 - sn * sn * sn)


@njit(**_JIT)
def _on_ratio(sigma, alb, nv, nl, lv):
    """layer.oren_nayar_ratio for one path and one channel's albedo alb."""
    sigma = min(max(sigma, 0.0), 1.0)
    a = 1.0 / (math.pi + sigma * (math.pi / 2 - 2.0 / 3.0))
    b = sigma * a
    t = lv - nl * nv
    if t > 0:
        t = t / (max(nl, nv) + 1e-38)
    e_avg = a * math.pi + ((2 * math.pi - 5.6) / 3.0) * b
    al = min(max(alb, 0.0), 1.0)
    e_ms = (1.0 / math.pi) * al * al * (e_avg / (1.0 - e_avg)) / (1.0 - al * (1.0 - e_avg))
    e_l = a * math.pi + b * _on_g(nl)
    e_v = a * math.pi + b * _on_g(nv)
    return math.pi * (a + b * t + e_ms * (1.0 - e_v) * (1.0 - e_l))


@njit(**_LANES)
def _coat_factor(mats, m, n, w_view, w_light, share):
    """layer.coat_factor for one path (mats: optics.materials): what Cycles' caustics on-minus-off
    keeps of a path leaving material m's diffuse towards w_light, relative to a Lambert diffuse;
    (1, 1, 1) exactly for a Lambert diffuse without a coat. The same sums as layer.coat_factor."""
    lay = mats[8]
    eta, rough, tint, wgt, sigma = lay[m, 0], lay[m, 1], lay[m, 2], lay[m, 3], lay[m, 4]
    a2 = rough ** 4
    coated = eta > 1.0 and a2 > SINGULAR_ALPHA2 and wgt > 0.0
    if not (coated or sigma > 0.0):
        return 1.0, 1.0, 1.0
    nv = _dot(n, w_view)
    nn = _neg(n) if nv < 0 else n
    mu_o = min(max(abs(nv), 1e-6), 1.0)
    mu_i = _dot(nn, w_light)
    if not mu_i > 1e-9:
        return 1.0, 1.0, 1.0
    if not wgt > 0.0:
        wgt = 1.0
    col = mats[2]
    b0, b1, b2 = col[m, 0] / wgt, col[m, 1] / wgt, col[m, 2] / wgt
    one_minus_a = _tab_weight(mats[9], m, mu_o)  # the glossy coat's alone: a clear coat scales all alike
    sw_d = (b0 + b1 + b2) / 3.0 * one_minus_a
    if not sw_d > 0:
        return 1.0, 1.0, 1.0
    r0 = r1 = r2 = 1.0
    if sigma > 0.0:
        lv = _dot(w_view, w_light)
        r0, r1, r2 = (_on_ratio(sigma, b0, mu_o, mu_i, lv), _on_ratio(sigma, b1, mu_o, mu_i, lv),
                      _on_ratio(sigma, b2, mu_o, mu_i, lv))
    eval_g = 0.0
    s = 1.0
    if coated:
        h = _normalize(_add(w_view, w_light))
        c_nh = _dot(h, nn)
        d = a2 / (math.pi * (1.0 + (a2 - 1.0) * c_nh * c_nh) ** 2)
        lam_o = _lambda_ggx(mu_o, a2)
        g2 = 1.0 / (1.0 + lam_o + _lambda_ggx(mu_i, a2))
        eval_g = _tab_weight(mats[7], m, mu_o) * fresnel_dielectric1(_dot(h, w_view), eta) * tint * d * g2 / (4.0 * mu_o)
        if share:
            pdf_g = d / (4.0 * mu_o * (1.0 + lam_o))
            pdf_d = mu_i / math.pi
            p_d = sw_d / max(sw_d + (1.0 - one_minus_a), 1e-300)
            s = p_d * pdf_d / max(p_d * pdf_d + (1.0 - p_d) * pdf_g, 1e-300)
    e_d = one_minus_a * mu_i / math.pi
    # a channel whose Lambert term is below layer.LAMBERT_FLOOR is black (the coat's share over it
    # would overflow: a colour of 1e-309 made an infinite caustic)
    k0 = s * (r0 + eval_g / (b0 * e_d)) if b0 * e_d > LAMBERT_FLOOR else 1.0
    k1 = s * (r1 + eval_g / (b1 * e_d)) if b1 * e_d > LAMBERT_FLOOR else 1.0
    k2 = s * (r2 + eval_g / (b2 * e_d)) if b2 * e_d > LAMBERT_FLOOR else 1.0
    return k0, k1, k2


@njit(**_JIT)
def _normalize(a):
    """vec.normalize: times 1/|a|, zero stays zero."""
    n = math.sqrt(_dot(a, a))
    inv = 1.0 / n if n > 0 else 0.0
    return (a[0] * inv, a[1] * inv, a[2] * inv)


@njit(**_JIT)
def _absorbed(kinds, a, medium, m_hit, d, g_hit, t, b):
    """b after a segment of length t along d inside a glass: medium (the glass it left into, -1:
    none), else the glass of material m_hit if d arrives at its back (the segment began inside it:
    a path from a receiver under water); times exp(-absorption t) (optics.transmittance; kinds,
    a: optics.materials' mats[0] and mats[10], Scene.mat_absorb; the two arrays, not the whole
    tuple, which numba would copy into every call)."""
    if medium < 0 and kinds[m_hit] == _DIELECTRIC and _dot(d, g_hit) > 0:
        medium = m_hit
    if medium < 0:
        return b
    if a[medium, 0] == 0.0 and a[medium, 1] == 0.0 and a[medium, 2] == 0.0:  # clear glass
        return b
    return (b[0] * math.exp(-a[medium, 0] * t), b[1] * math.exp(-a[medium, 1] * t),
            b[2] * math.exp(-a[medium, 2] * t))


@njit(**_JIT)
def _medium_after(m, kind, dd, g):
    """The medium a path is in leaving a vertex of material m along dd (optics.inside)."""
    return m if kind == _DIELECTRIC and _dot(dd, g) < 0 else -1


@njit(**_JIT)
def _tab_weight(tab, m, mu):
    """layer.weight for one vertex: material m's entry of tab (one of layer.py's tables,
    optics.materials' mats[6], [7] or [9]) at the eye's cosine mu; exactly 1 in a row of ones."""
    x = min(abs(mu), 1.0) * MU_STEPS
    i = min(int(x), MU_STEPS - 1)
    f = x - i
    a = tab[m, i]
    return a + (tab[m, i + 1] - a) * f


@njit(**_JIT)
def _max(a, b):
    """np.maximum: NaN propagates."""
    if a != a:
        return a
    return a if a >= b else b


# ------------------------------------------------------------------ reflection / refraction
@njit(**_JIT)
def _orient(w, n, eta):
    if _dot(w, n) >= 0:
        return n, 1.0 / eta, 1.0
    return _neg(n), eta, -1.0


@njit(inline="always", **_JIT)
def smap(refract, w, n, eta):
    """constraints.specular_map for one lane: (direction, ok)."""
    if not refract:
        return _sub(_mul(2.0 * _dot(w, n), n), w), True
    no, eta_r, _ = _orient(w, n, eta)
    c = _dot(w, no)
    r2 = 1.0 - eta_r**2 * (1.0 - c * c)
    ok = r2 > _R_MIN2
    r = math.sqrt(r2 if ok else 1.0)
    if not ok:
        return (0.0, 0.0, 0.0), False
    out = _sub(_mul(-eta_r, _sub(w, _mul(c, no))), _mul(r, no))
    return out, True


@njit(inline="always", **_JIT)
def smap_d_pre(refract, w, n, eta):
    """The part of constraints.specular_map_d that depends only on (w, n, eta), shared by every
    derivative at one vertex: (oriented normal, eta ratio, orientation sign, w.n', r)."""
    if not refract:
        return n, 1.0, 1.0, _dot(w, n), 0.0
    no, eta_r, sg = _orient(w, n, eta)
    c = _dot(w, no)
    r2 = _max(1.0 - eta_r**2 * (1.0 - c * c), _R_MIN2)
    return no, eta_r, sg, c, math.sqrt(r2)


@njit(inline="always", **_JIT)
def smap_d(refract, w, pre, dw, dn):
    """constraints.specular_map_d for one lane (pre: smap_d_pre(refract, w, n, eta))."""
    no, eta_r, sg, c, r = pre
    if not refract:
        return _sub(_mul(2.0, _add(_mul(_dot(dw, no) + _dot(w, dn), no), _mul(c, dn))), dw)
    dno = _mul(sg, dn)
    dc = _dot(dw, no) + _dot(w, dno)
    dr = eta_r**2 * c * dc / r
    return _sub(_sub(_mul(-eta_r, _sub(_sub(dw, _mul(dc, no)), _mul(c, dno))), _mul(dr, no)), _mul(r, dno))


@njit(inline="always", **_JIT)
def smap_d_w(refract, w, pre, dw):
    """smap_d where the normal does not move (dn = 0): the derivative by the vertex before."""
    no, eta_r, sg, c, r = pre
    if not refract:
        return _sub(_mul(2.0, _mul(_dot(dw, no), no)), dw)
    dc = _dot(dw, no)
    dr = eta_r**2 * c * dc / r
    return _sub(_mul(-eta_r, _sub(dw, _mul(dc, no))), _mul(dr, no))


@njit(**_JIT)
def _unit_d(u, length, a):
    return _div(_sub(a, _mul(_dot(u, a), u)), length)


# ------------------------------------------------------------------ constraint blocks
@njit(inline="always", **_JIT)
def _dC(hv, refract, wi, pre, e1, e2, eta_i, eta_o, h, lh, s2, t2, hn, dwi, dn, dwo):
    if not hv:
        dw = _sub(smap_d(refract, wi, pre, dwi, dn), dwo)
        return _dot(e1, dw), _dot(e2, dw)
    dH = _add(_mul(eta_i, dwi), _mul(eta_o, dwo))
    dh = _div(_sub(dH, _mul(_dot(h, dH), h)), _max(lh, 1e-300))
    return _dot(s2, dh) - hn * _dot(s2, dn), _dot(t2, dh) - hn * _dot(t2, dn)


@njit(inline="always", **_JIT)
def _lane_blocks(hv, kinds, x0, F, etas, ly, lys, lyt, directional, lane, C, A, B, D):
    """constraints.blocks for one lane (row `lane` of F/etas/x0/light, written to C/A/B/D[:]):
    returns ok."""
    k = kinds.shape[0]
    ok = True
    zero = (0.0, 0.0, 0.0)
    for j in range(k):
        refract = kinds[j] == 1
        p = _vk(F, lane, j, P)
        n = _vk(F, lane, j, NS)
        prev_p = _v(x0, lane, 0) if j == 0 else _vk(F, lane, j - 1, P)
        wi = _sub(prev_p, p)
        li = math.sqrt(_dot(wi, wi))
        wi = _div(wi, _max(li, 1e-300))
        has_lo = not (j == k - 1 and directional)
        lo = 1.0
        if has_lo:
            nxt = _v(ly, lane, 0) if j == k - 1 else _vk(F, lane, j + 1, P)
            wo = _sub(nxt, p)
            lo = math.sqrt(_dot(wo, wo))
            wo = _div(wo, _max(lo, 1e-300))
            ok = ok and (li > 0) and (lo > 0)
        else:
            wo = _v(ly, lane, 0)
            ok = ok and (li > 0)
        eta = etas[lane, j]
        e1 = e2 = s2 = t2 = h = zero
        eta_i = eta_o = lh = hn = 0.0
        pre = smap_d_pre(refract, wi, n, eta) if not hv else (n, 1.0, 1.0, 0.0, 0.0)
        if not hv:
            wo_p, okm = smap(refract, wi, n, eta)
            ok = ok and okm
            e1, e2 = frame1(wo)
            diff = _sub(wo_p, wo)
            C[j, 0], C[j, 1] = _dot(e1, diff), _dot(e2, diff)
        else:
            if refract:
                if _dot(wi, _vk(F, lane, j, NG)) >= 0:
                    eta_i, eta_o = 1.0, eta
                else:
                    eta_i, eta_o = eta, 1.0
            else:
                eta_i, eta_o = 1.0, 1.0
            H = _add(_mul(eta_i, wi), _mul(eta_o, wo))
            lh = math.sqrt(_dot(H, H))
            ok = ok and (lh > 1e-9 * (eta_i + eta_o))
            h = _div(H, _max(lh, 1e-300))
            s = _vk(F, lane, j, S)
            s2 = _normalize(_sub(s, _mul(_dot(s, n), n)))
            t2 = _cross(n, s2)
            C[j, 0], C[j, 1] = _dot(s2, h), _dot(t2, h)
            hn = _dot(h, n)
        for col in range(2):
            a = _vk(F, lane, j, S if col == 0 else T)
            dna = _vk(F, lane, j, DNS if col == 0 else DNT)
            dwi = _neg(_unit_d(wi, li, a))
            dwo = _neg(_unit_d(wo, lo, a)) if has_lo else zero
            A[j, 0, col], A[j, 1, col] = _dC(hv, refract, wi, pre, e1, e2, eta_i, eta_o, h, lh, s2, t2, hn,
                                             dwi, dna, dwo)
            # B (by the vertex before) moves only w_i, D (by the vertex after or the light) only
            # w_o: in the angle-difference form the specular map's terms in what does not move
            # are left out (they are zeros)
            if j > 0:
                a = _vk(F, lane, j - 1, S if col == 0 else T)
                if hv:
                    B[j, 0, col], B[j, 1, col] = _dC(hv, refract, wi, pre, e1, e2, eta_i, eta_o, h, lh, s2, t2,
                                                     hn, _unit_d(wi, li, a), zero, zero)
                else:
                    dw = smap_d_w(refract, wi, pre, _unit_d(wi, li, a))
                    B[j, 0, col], B[j, 1, col] = _dot(e1, dw), _dot(e2, dw)
            else:
                B[j, 0, col] = B[j, 1, col] = 0.0
            if j < k - 1:
                a = _vk(F, lane, j + 1, S if col == 0 else T)
            else:
                a = _v(lys, lane, 0) if col == 0 else _v(lyt, lane, 0)
            dwo = _unit_d(wo, lo, a) if has_lo else a
            if hv:
                D[j, 0, col], D[j, 1, col] = _dC(hv, refract, wi, pre, e1, e2, eta_i, eta_o, h, lh, s2, t2, hn,
                                                 zero, zero, dwo)
            else:
                D[j, 0, col], D[j, 1, col] = -_dot(e1, dwo), -_dot(e2, dwo)
    return ok


# 2x2 matrices as tuples (m00, m01, m10, m11): held in registers. A view of a (k, 2, 2) array
# (A[j]) takes a reference to the array's memory (an atomic increment and decrement in numba's
# runtime) each time it is made, a tenth of a Newton iteration's time when made per lane.
@njit(**_JIT)
def _m2(M, j):
    return (M[j, 0, 0], M[j, 0, 1], M[j, 1, 0], M[j, 1, 1])


@njit(**_JIT)
def _put2(M, j, v):
    M[j, 0, 0], M[j, 0, 1], M[j, 1, 0], M[j, 1, 1] = v


@njit(**_JIT)
def _sub2(X, Y):
    return (X[0] - Y[0], X[1] - Y[1], X[2] - Y[2], X[3] - Y[3])


@njit(**_JIT)
def _inv2(M):
    """constraints.inv2 of one 2x2: (inverse, ok)."""
    a, b, c, d = M
    det = a * d - b * c
    scale = a * a + b * b + c * c + d * d
    ok = abs(det) > 1e-12 * scale
    inv_det = 1.0 / det if ok else 0.0
    return (d * inv_det, -b * inv_det, -c * inv_det, a * inv_det), ok


@njit(**_JIT)
def _mm(X, Y):
    return (X[0] * Y[0] + X[1] * Y[2], X[0] * Y[1] + X[1] * Y[3],
            X[2] * Y[0] + X[3] * Y[2], X[2] * Y[1] + X[3] * Y[3])


@njit(inline="always", **_JIT)  # inlined: as a plain njit, LLVM left a call to it in the walk (jit.py)
def _copy_rows(dst, i, src, m):
    """dst[i] = src[m] for (N, a, b) arrays, element by element: numba's slice assignment costs
    ~50-100 ns per call on these small rows (views and a generic loop), more than the copy."""
    for j in range(src.shape[1]):
        for c in range(src.shape[2]):
            dst[i, j, c] = src[m, j, c]


@njit(**_JIT)
def _zero_rhs(rhs, k):
    for j in range(k):
        for r in range(2):
            for c in range(2):
                rhs[j, r, c] = 0.0


@njit(**_JIT)
def _lane_scratch(k):
    """Per-lane work arrays of _lane_blocks and _lane_solve for a chain of k vertices:
    C, A, B, D, rhs, Li, Y, X (per vertex)."""
    return (np.zeros((k, 2)), np.zeros((k, 2, 2)), np.zeros((k, 2, 2)), np.zeros((k, 2, 2)),
            np.zeros((k, 2, 2)), np.zeros((k, 2, 2)), np.zeros((k, 2, 2)), np.zeros((k, 2, 2)))


@njit(inline="always", **_JIT)
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
_lane_blocks_called = njit(**_JIT)(_lane_blocks.py_func)
_lane_solve_called = njit(**_JIT)(_lane_solve.py_func)


@njit(**_JIT)
def chain_solve(mode, hv, kinds, x0, F, etas, ly, lys, lyt, directional):
    """Per lane, the constraints' blocks and the block-tridiagonal solve of the first vertex:
    mode 0 (Newton): J x = C, out[:, :, 0] = x_1 (column 1 zero); mode 1 (geometric term):
    J X = -D_k e_k, out = X_1 (2x2). ok False (and out zero) where the constraint or a 2x2 pivot
    is undefined."""
    N = x0.shape[0]
    k = kinds.shape[0]
    out = np.zeros((N, 2, 2))
    oks = np.zeros(N, np.bool_)
    C, A, B, D, rhs, Li, Y, X = _lane_scratch(k)
    for i in range(N):
        ok = _lane_blocks_called(hv, kinds, x0, F, etas, ly, lys, lyt, directional, i, C, A, B, D)
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
            _copy_rows(out, i, X, 0)
            if mode == 0:
                out[i, 0, 1] = out[i, 1, 1] = 0.0
        oks[i] = ok
    return out, oks


@njit(inline="always", **_JIT)
def _lane_newton(i, hv, kinds, x0, F, etas, ly, lys, lyt, directional, beta, max_step,
                 C, A, B, D, rhs, Li, Y, X):
    """The small mutation of lane i (see newton_proposal): (ok, proposed x1, direction). The
    work arrays (_lane_scratch) come one by one, unpacked by the caller before its loop over
    lanes (a tuple of arrays unpacked per lane costs reference counts per array and lane: see
    jit.LANES)."""
    k = kinds.shape[0]
    ok = _lane_blocks(hv, kinds, x0, F, etas, ly, lys, lyt, directional, i, C, A, B, D)
    _zero_rhs(rhs, k)
    for j in range(k):
        rhs[j, 0, 0], rhs[j, 1, 0] = C[j, 0], C[j, 1]
    ok = _lane_solve(A, B, D, rhs, Li, Y, X) and ok
    p1 = _vk(F, i, 0, P)
    if not ok:
        return False, p1, (0.0, 0.0, 0.0)
    s = _vk(F, i, 0, S)
    t = _vk(F, i, 0, T)
    step = _neg(_add(_mul(X[0, 0, 0], s), _mul(X[0, 1, 0], t)))
    ls = math.sqrt(_dot(step, step))
    step = _mul(min(1.0, max_step / _max(ls, 1e-300)), step)
    p = _add(p1, _mul(beta[i], step))
    return True, p, _normalize(_sub(p, _v(x0, i, 0)))


@njit(**_JIT)
def newton_proposal(idx, hv, kinds, x0, F, etas, ly, lys, lyt, directional, beta, max_step):
    """walk.newton_walk's small mutation for lanes idx (rows of the full arrays): the Newton
    step of x1 in its tangent plane, shortened to max_step and scaled by beta; returns the
    proposed x1 p (M,3), the direction d = normalize(p - x0) (M,3), and ok (M,) (False where
    the constraints or the solve are singular; p = x1 and d zero there)."""
    M = idx.shape[0]
    p_out = np.zeros((M, 3))
    d_out = np.zeros((M, 3))
    oks = np.zeros(M, np.bool_)
    C, A, B, D, rhs, Li, Y, X = _lane_scratch(kinds.shape[0])
    for m in range(M):
        ok, p, d = _lane_newton(idx[m], hv, kinds, x0, F, etas, ly, lys, lyt, directional, beta, max_step,
                                C, A, B, D, rhs, Li, Y, X)
        oks[m] = ok
        p_out[m, 0], p_out[m, 1], p_out[m, 2] = p
        d_out[m, 0], d_out[m, 1], d_out[m, 2] = d
    return p_out, d_out, oks


# ------------------------------------------------------------------ a ray's hit in float64
@njit(**_JIT)
def _hit_point(o, d, xo, exact, t32, pr, tv, tng, eps):
    """tracer.intersect's float64 hit of the ray o + t d (the offset origin embree traced from;
    xo, where it really starts when exact, else o) on primitive pr at embree's float32 distance
    t32: the plane of the triangle re-intersected from xo, embree's distance kept where the two
    disagree badly (its own error is absolute: float32 vertices, ~1e-7 of the extent, hence
    + eps). Returns (t from xo, the point, the unit geometric normal, corner 0, edges 1 and 2)."""
    tt = t32 + _dot(_sub(o, xo), d) if exact else t32
    g = _v(tng, pr, 0)
    v0 = (tv[pr, 0, 0], tv[pr, 0, 1], tv[pr, 0, 2])
    v1 = (tv[pr, 1, 0], tv[pr, 1, 1], tv[pr, 1, 2])
    v2 = (tv[pr, 2, 0], tv[pr, 2, 1], tv[pr, 2, 2])
    den = _dot(d, g)
    num = _dot(_sub(v0, xo), g)
    ti = num / den if abs(den) > 1e-12 else tt
    if not math.isfinite(ti) or abs(ti - tt) > 1e-3 * abs(tt) + eps:
        ti = tt
    return ti, _add(xo, _mul(ti, d)), g, v0, _sub(v1, v0), _sub(v2, v0)


@njit(**_JIT)
def _barycentric(e1, e2, q):
    """Barycentrics (b1, b2) of corners 1 and 2 for q = p - v0 on the triangle of edges e1, e2
    (1/3 each where the triangle is degenerate), and the edges' dot products d11, d12, d22."""
    d11, d12, d22 = _dot(e1, e1), _dot(e1, e2), _dot(e2, e2)
    q1, q2 = _dot(q, e1), _dot(q, e2)
    det = d11 * d22 - d12 * d12
    if det > 0:
        inv = 1.0 / det
        return (d22 * q1 - d12 * q2) * inv, (d11 * q2 - d12 * q1) * inv, d11, d12, d22
    return 1.0 / 3.0, 1.0 / 3.0, d11, d12, d22


@njit(**_JIT)
def _corners(tns, pr, d, g):
    """The corner normals of triangle pr a ray of direction d meets (g: its geometric normal): in
    tns[pr, 3:] where it comes from behind and tns holds the normals met from there (Tracer.ns_corner
    (T, 6, 3): Scene.tri_normals_back, bump.py), else tns[pr, :3] (constant indices, the common case)."""
    if tns.shape[1] == 6 and d[0] * g[0] + d[1] * g[1] + d[2] * g[2] > 0:
        return ((tns[pr, 3, 0], tns[pr, 3, 1], tns[pr, 3, 2]), (tns[pr, 4, 0], tns[pr, 4, 1], tns[pr, 4, 2]),
                (tns[pr, 5, 0], tns[pr, 5, 1], tns[pr, 5, 2]))
    return ((tns[pr, 0, 0], tns[pr, 0, 1], tns[pr, 0, 2]), (tns[pr, 1, 0], tns[pr, 1, 1], tns[pr, 1, 2]),
            (tns[pr, 2, 0], tns[pr, 2, 1], tns[pr, 2, 2]))


@njit(**_JIT)
def _shading_normal(tns, pr, b1, b2, g, d):
    """tracer.shading_normal: the corner normals interpolated and normalised (not flipped towards
    the geometric normal g, as Cycles' triangle_smooth_normal), g where they give none; those a ray
    of direction d meets (_corners)."""
    b0 = 1.0 - b1 - b2
    c0, c1, c2 = _corners(tns, pr, d, g)
    n = _normalize(_add(_add(_mul(b0, c0), _mul(b1, c1)), _mul(b2, c2)))
    return g if _dot(n, n) < 0.5 else n


@njit(**_LANES)
def _intersect_rows(ray, o, d, tmax, xo, exact, tv, tng, tns, eps, prim, t, p, ng, ns, b):
    """intersect_rays' loop over its rays (its caller holds the arrays)."""
    for i in range(o.shape[0]):
        oi, di = _v(o, i, 0), _v(d, i, 0)
        pr, t32 = intersect1(ray, oi, di, tmax[i] if tmax.shape[0] else np.inf, 0)
        prim[i] = pr
        if pr < 0:
            t[i] = np.inf
            continue
        ti, pi, g, v0, e1, e2 = _hit_point(oi, di, _v(xo, i, 0) if exact else oi, exact, t32, pr, tv, tng, eps)
        b1, b2, _, _, _ = _barycentric(e1, e2, _sub(pi, v0))
        n = _shading_normal(tns, pr, b1, b2, g, di)
        t[i] = ti
        b[i, 0], b[i, 1] = b1, b2
        for c in range(3):
            p[i, c], ng[i, c], ns[i, c] = pi[c], g[c], n[c]


@njit(**_JIT)
def intersect_rays(rt, o, d, tmax, xo, exact, tv, tng, tns, eps, prim, t, p, ng, ns, b):
    """tracer.intersect: closest hits of rays o + t d (offset origins o; xo where they really
    start when exact), t < tmax (empty: no limit), with float64 hit records (_hit_point,
    _barycentric, _shading_normal) written to prim (-1 on a miss), t (inf on a miss), p, ng,
    ns, b (left as they are on a miss). Returns the ray counters (embree.ray_state)."""
    ray = ray_state(rt)
    _intersect_rows(ray, o, d, tmax, xo, exact, tv, tng, tns, eps, prim, t, p, ng, ns, b)
    return ray[6]


@njit(**_JIT)
def barycentric_rows(tv, prim, p):
    """tracer.barycentrics: (b1, b2) of points p on triangles prim."""
    out = np.zeros((prim.shape[0], 2))
    for i in range(prim.shape[0]):
        pr = prim[i]
        v0 = (tv[pr, 0, 0], tv[pr, 0, 1], tv[pr, 0, 2])
        e1 = (tv[pr, 1, 0] - v0[0], tv[pr, 1, 1] - v0[1], tv[pr, 1, 2] - v0[2])
        e2 = (tv[pr, 2, 0] - v0[0], tv[pr, 2, 1] - v0[1], tv[pr, 2, 2] - v0[2])
        out[i, 0], out[i, 1], _, _, _ = _barycentric(e1, e2, _sub(_v(p, i, 0), v0))
    return out


@njit(**_JIT)
def shading_normal_rows(tns, tng, prim, b):
    """tracer.shading_normal at barycentrics b on triangles prim (the normals met from the front)."""
    out = np.zeros((prim.shape[0], 3))
    front = (0.0, 0.0, 0.0)
    for i in range(prim.shape[0]):
        n = _shading_normal(tns, prim[i], b[i, 0], b[i, 1], _v(tng, prim[i], 0), front)
        out[i, 0], out[i, 1], out[i, 2] = n
    return out


# ------------------------------------------------------------------ a vertex from a ray hit
@njit(inline="always", **_JIT)
def _lane_vertex(refract, last, j, lane, o, d, prev, exact, pr, t32, tv, tng, tns, eps, tri_material, mat_kind,
                 tri_object, casters, mat_ior, F, I, status, out):
    """walk.propagate's work for vertex j of chain row `lane` once its ray o + t d (3-tuples)
    hit primitive pr at embree's distance t32: tracer.intersect's float64 hit point (the plane
    of the hit triangle re-intersected from prev, the ray's true start, when exact, else from
    o), geometry.vertex_from_hits, the material checks, the reflection or refraction of
    w_in = normalize(prev - p) and the side checks. Writes the walk outcome to status, the
    vertex to F and I where it is kept (valid, or at the last vertex TIR or SIDE), the unit
    outgoing direction to out; returns whether the chain goes on, and the next ray's offset
    origin and direction, and the vertex."""
    zero = (0.0, 0.0, 0.0)
    ti, p, g, v0, e1, e2 = _hit_point(o, d, prev if exact else o, exact, t32, pr, tv, tng, eps)
    b1, b2, d11, d12, d22 = _barycentric(e1, e2, _sub(p, v0))
    # geometry.vertex_from_hits
    s = _normalize(e1)
    t = _cross(g, s)
    c0, c1, c2 = _corners(tns, pr, d, g)
    b0 = 1.0 - b1 - b2
    nraw = _add(_add(_mul(b0, c0), _mul(b1, c1)), _mul(b2, c2))
    ln = math.sqrt(_dot(nraw, nraw))
    good = ln > 1e-3
    n = _div(nraw, ln) if good else g
    dns = dnt = zero
    if good:
        g11, g12, g22 = d11, d12, d22
        det2 = g11 * g22 - g12 * g12
        inv2 = 1.0 / det2 if det2 > 1e-300 else 0.0
        dn1, dn2 = _sub(c1, c0), _sub(c2, c0)
        for col in range(2):
            w = s if col == 0 else t
            r1, r2 = _dot(w, e1), _dot(w, e2)
            alpha = (g22 * r1 - g12 * r2) * inv2
            beta = (g11 * r2 - g12 * r1) * inv2
            dN = _add(_mul(alpha, dn1), _mul(beta, dn2))
            dv = _div(_sub(dN, _mul(_dot(dN, n), n)), ln)
            if col == 0:
                dns = dv
            else:
                dnt = dv
    mat = tri_material[pr]
    mk = mat_kind[mat]
    obj = tri_object[pr]
    code = _OK
    if not casters[obj]:
        code = _NOT_CASTER
    need = (mk == _DIELECTRIC) if refract else (mk == _CONDUCTOR or mk == _DIELECTRIC)
    if not need and code == _OK:
        code = _WRONG_MATERIAL
    w_in = _normalize(_sub(prev, p))
    w_out, okm = smap(refract, w_in, n, mat_ior[mat])
    if not okm and code == _OK:
        code = _TIR if last else _TIR_INNER
    cin, cout = _dot(w_in, g), _dot(w_out, g)
    side_ok = ((cin * cout < 0) if refract else (cin * cout > 0)) and (_dot(w_in, n) * _dot(n, g) * cin > 0)
    if not side_ok and code == _OK:
        code = _SIDE if last else _SIDE_INNER
    status[lane] = code
    keep = code == _OK or (last and (code == _TIR or code == _SIDE))
    if not keep:
        return False, zero, zero, zero
    wn = _normalize(w_out)
    for c in range(3):
        F[lane, j, P + c] = p[c]
        F[lane, j, NG + c] = g[c]
        F[lane, j, NS + c] = n[c]
        F[lane, j, S + c] = s[c]
        F[lane, j, T + c] = t[c]
        F[lane, j, DNS + c] = dns[c]
        F[lane, j, DNT + c] = dnt[c]
    I[lane, j, PRIM], I[lane, j, OBJ], I[lane, j, MAT] = pr, obj, mat
    if code == _TIR:
        return False, zero, zero, zero
    out[lane, 0], out[lane, 1], out[lane, 2] = wn
    if code != _OK:
        return False, zero, zero, zero
    side = 1.0 if _dot(wn, g) >= 0 else -1.0
    return True, _add(p, _mul(eps * side, g)), wn, p


@njit(**_LANES)
def _trace_lane(ray, kind, lane, x0, o, d, kinds, geo, eps, F, I, status, out):
    """walk.propagate for chain row `lane`: the ray from x0 (its offset origin o, direction d;
    3-tuples) and its reflections and refractions through the chain's vertices, each ray cast
    here (embree.intersect1, counted as `kind`). The row of F, I, status (walk outcome, OK
    where every vertex is valid) and out (the direction leaving the last vertex) is written
    from scratch. geo: (tv, tng, tns, tri_material, mat_kind, tri_object, casters, mat_ior).
    Called, not inlined (compiled once for the seeds and the walks): its callers pass kind and
    lane as int64, as numba compiles a function once per value of a constant argument."""
    tv, tng, tns, tri_material, mat_kind, tri_object, casters, mat_ior, hid = geo
    k = kinds.shape[0]
    for j in range(k):
        for c in range(NF):
            F[lane, j, c] = 0.0
        I[lane, j, 0] = I[lane, j, 1] = I[lane, j, 2] = 0
    status[lane] = _OK
    out[lane, 0] = out[lane, 1] = out[lane, 2] = 0.0
    prev = x0
    for j in range(k):
        pr, t32 = intersect1(ray, o, d, np.inf, kind)
        passed = False
        if hid.shape[0] > 0:  # past what this ray's kind does not meet (x0's diffuse bounce, then the letter before)
            bit = _RAY_DIFFUSE if j == 0 else (_RAY_TRANSMISSION if kinds[j - 1] == 1 else _RAY_GLOSSY)  # 1: refracts
            for _ in range(HIDDEN_PASSES + 1):
                if pr < 0 or not hid[tri_object[pr]] & bit:
                    break
                g = (tng[pr, 0], tng[pr, 1], tng[pr, 2])
                o = _add(_add(o, _mul(t32, d)), _mul(eps if _dot(d, g) >= 0 else -eps, g))  # tracer.spawn
                pr, t32 = intersect1(ray, o, d, np.inf, kind)
                passed = True
            if pr >= 0 and hid[tri_object[pr]] & bit:
                pr = -1
        if pr < 0:
            status[lane] = _MISS
            return
        # from the true previous vertex, not the offset ray origin: the chain stays exact. At the
        # last vertex the vertex of a chain whose exit is TIR (SMBS can mutate from it) and of one
        # whose exit dips below the geometric surface (a shading normal leaning away, as on a
        # normal-mapped mirror) is kept: every walk goes on from it, as SMS does from any seed on
        # the caster, and converges only once the exit is valid
        go, o, d, prev = _lane_vertex(kinds[j] == 1, j == k - 1, j, lane, o, d, prev, j > 0 or passed, pr, t32, tv,
                                      tng, tns, eps, tri_material, mat_kind, tri_object, casters, mat_ior, F, I,
                                      status, out)
        if not go:
            return


@njit(**_LANES)
def _seed_rows(ray, kinds, x0, ng0, d, want_obj, geo, eps, F, I, status, out):
    """trace_lanes' loop over its lanes (its caller holds the arrays)."""
    for i in range(x0.shape[0]):
        _seed_lane(ray, i, x0, ng0, d, want_obj, kinds, geo, eps, F, I, status, out)


@TypedOnce
@njit(**_JIT)
def trace_lanes(rt, kinds, x0, ng0, d, want_obj, geo, eps, F, I, status, out):
    """walk.propagate of every lane: the ray from x0 (offset along ng0 to the side d leaves
    on, as tracer.spawn) in direction d through the chain; where want_obj[i] >= 0, a chain
    whose first vertex lies on another object ends as SEED_OBJECT. Returns the ray counters
    (embree.ray_state)."""
    ray = ray_state(rt)
    _seed_rows(ray, kinds, x0, ng0, d, want_obj, geo, eps, F, I, status, out)
    return ray[6]


@njit(**_LANES)
def _seed_lane(ray, i, x0, ng0, d, want_obj, kinds, geo, eps, F, I, status, out):
    """The seed chain of lane i (trace_lanes), its rays counted as seeds. Not inlined: one call
    per walk, and one compiled copy of _trace_lane for every kernel that seeds (inlined into
    each, the walk kernels took minutes to compile)."""
    xi = _v(x0, i, 0)
    di = _v(d, i, 0)
    g = _v(ng0, i, 0)
    side = 1.0 if _dot(di, g) >= 0 else -1.0
    # (np.int64: a constant argument would compile _trace_lane once per value, see its docstring)
    _trace_lane(ray, np.int64(RAYS_SEED), i, xi, _add(xi, _mul(eps * side, g)), di, kinds, geo, eps, F, I, status, out)
    if want_obj[i] >= 0 and status[i] == _OK and I[i, 0, OBJ] != want_obj[i]:
        status[i] = _SEED_OBJECT


@njit(inline="always", **_JIT)
def _lane_mismatch(F, m, out_dir, ly, i, directional):
    """walk.end_mismatch of chain row m against lane i's light end: (|w_o' - w_o|, front)."""
    k = F.shape[1]
    if directional:
        to_light = _v(ly, i, 0)
    else:
        to_light = _normalize(_sub(_v(ly, i, 0), _vk(F, m, k - 1, P)))
    od = _v(out_dir, m, 0)
    diff = _sub(od, to_light)
    return math.sqrt(_dot(diff, diff)), _dot(od, to_light) > 0


@njit(**_JIT)
def end_mismatch(idx, F, out_dir, ly, directional):
    """walk.end_mismatch of a chain (rows 0.. of F, out_dir) against the light end rows idx:
    |w_o' - w_o| at the last vertex and whether w_o' points to the light's side."""
    M = idx.shape[0]
    err = np.zeros(M)
    front = np.zeros(M, np.bool_)
    for m in range(M):
        err[m], front[m] = _lane_mismatch(F, m, out_dir, ly, idx[m], directional)
    return err, front


# ------------------------------------------------------------------ SMBS's large mutation
@njit(inline="always", **_JIT)
def _ray_box(o, d, lo, hi):
    """large_mutation.ray_box for one ray."""
    tmin = -np.inf
    tmax = np.inf
    for c in range(3):
        inv = 1.0 / d[c]
        t1 = (lo[c] - o[c]) * inv
        t2 = (hi[c] - o[c]) * inv
        if t1 != t1:
            t1 = -np.inf
        if t2 != t2:
            t2 = np.inf
        near, far = min(t1, t2), max(t1, t2)
        if c == 0:
            tmin, tmax = near, far
        else:
            tmin, tmax = max(tmin, near), min(tmax, far)
    return tmax >= max(tmin, 0.0)


@njit(inline="always", **_JIT)
def _lane_large(i, kinds, x0, F, I, etas, ly, directional, obj_lo, obj_hi, scale, max_halvings):
    """The large mutation of lane i (see large_proposal): (direction, ok)."""
    k = kinds.shape[0]
    if directional:
        v = _neg(_v(ly, i, 0))
    else:
        v = _normalize(_sub(_vk(F, i, k - 1, P), _v(ly, i, 0)))
    ok = True
    for j in range(k - 1, -1, -1):
        v, okm = smap(kinds[j] == 1, _neg(v), _vk(F, i, j, NS), etas[i, j])
        ok = ok and okm
    xi = _v(x0, i, 0)
    v1 = _normalize(_sub(_vk(F, i, 0, P), xi))
    target = _neg(v)
    a = 1.0 if _dot(v1, target) < 0 else 0.5
    a = a * scale[i]
    obj = I[i, 0, OBJ]
    lo = _v(obj_lo, obj, 0)
    hi = _v(obj_hi, obj, 0)
    found = False
    for _ in range(max_halvings + 1):
        d = _normalize(_add(_mul(a, target), _mul(1.0 - a, v1)))
        if _ray_box(xi, d, lo, hi) and _dot(d, d) > 0:
            found = True
            break
        a *= 0.5
    if not found:
        a = 0.0
    d = _normalize(_add(_mul(a, target), _mul(1.0 - a, v1)))
    return d, ok and _dot(d, d) > 0.5


@njit(**_JIT)
def large_proposal(idx, kinds, x0, F, I, etas, ly, directional, obj_lo, obj_hi, scale, max_halvings):
    """large_mutation.large_direction for lanes idx: GetNextDir back from the light through
    the chain's vertices, then GetRatio's bisection towards it until the ray from x0 meets the
    box of x1's object. Returns the direction (M,3) and ok (M,)."""
    M = idx.shape[0]
    d_out = np.zeros((M, 3))
    oks = np.zeros(M, np.bool_)
    for m in range(M):
        d, oks[m] = _lane_large(idx[m], kinds, x0, F, I, etas, ly, directional, obj_lo, obj_hi, scale, max_halvings)
        d_out[m, 0], d_out[m, 1], d_out[m, 2] = d
    return d_out, oks


# ------------------------------------------------------------------ the walk's bookkeeping
_NONE, _TRIG_TIR, _TRIG_BACKLIT, _TRIG_SLOW = 0, 1, 2, 3
_SINGULAR, _MAX_ITER, _STALLED = 7, 8, 13


@njit(inline="always", **_JIT)
def _lane_trigger(i, kinds, backlit_at, backlit_on, x0, F, ly, directional, pending):
    """SMBS's trigger of lane i (trigger 2, back-lit, at chain vertex j = backlit_at: for a
    reflection, the vertex before it (x0 for j = 0) and the light on different sides of its
    surface; for a refraction, on the same side; walk.WalkConfig.backlit_vertex); clears pending."""
    tr = pending[i]
    if backlit_on and tr == _NONE and backlit_at >= 0:
        j = backlit_at
        pj = _vk(F, i, j, P)
        nj = _vk(F, i, j, NS)
        prev = _v(x0, i, 0) if j == 0 else _vk(F, i, j - 1, P)
        to_light = _v(ly, i, 0) if directional else _sub(_v(ly, i, 0), pj)
        a = _dot(_sub(prev, pj), nj) > 0
        b = _dot(to_light, nj) > 0
        if (a != b) if kinds[j] == 0 else (a == b):
            tr = _TRIG_BACKLIT
    pending[i] = _NONE
    return tr


@njit(**_JIT)
def backlit_lanes(kinds, backlit_at, x0, F, ly, directional):
    """_lane_trigger's back-lit test on every lane (walk.backlit)."""
    n = F.shape[0]
    out = np.zeros(n, np.bool_)
    pending = np.zeros(n, np.int64)
    for i in range(n):
        out[i] = _lane_trigger(i, kinds, backlit_at, True, x0, F, ly, directional, pending) == _TRIG_BACKLIT
    return out


@njit(**_JIT)
def _spawn_aim1(x0, g, d, target, eps):
    """tracer.spawn of x0 (normal g) towards d, and the unit direction from there to target."""
    side = 1.0 if _dot(d, g) >= 0 else -1.0
    on = _add(x0, _mul(eps * side, g))
    return on, _normalize(_sub(target, on))


@njit(inline="always", **_JIT)
def _lane_update(m, i, nF, nI, nstatus, nout, e, f, ul, smbs, tir_on, slow_on, tir_rejected, tau, slow_run,
                 min_beta, F, I, out_dir, err, front, valid, beta, lscale, pending, slow_n, outcome):
    """walk.newton_walk's acceptance of proposal row m (of the chain nF/nI/nstatus/nout, mismatch
    e, f, large or not ul) for lane i, and its state updates: the accepted chain, the mismatch,
    beta (doubled on acceptance, halved on rejection, 1 after a large mutation), SMBS's
    bisection scale and triggers 1 (a large mutation into TIR moves the chain) and 3 (slow
    small steps in a row). Returns whether the lane walks on (a lane whose beta fell below
    min_beta is stuck: outcome MAX_ITER)."""
    st = nstatus[m]
    okp = st == _OK or st == _SIDE
    accept = okp and (ul or e < err[i])
    if ul and st == _TIR and tir_on:
        # a large mutation that ends in total internal reflection still moves the chain
        accept = True
        e, f = np.inf, False
        pending[i] = _TRIG_TIR
    if accept:
        _copy_rows(F, i, nF, m)
        _copy_rows(I, i, nI, m)
        out_dir[i, 0], out_dir[i, 1], out_dir[i, 2] = nout[m, 0], nout[m, 1], nout[m, 2]
    if smbs and slow_on:
        slow = okp and not ul and e > tau * err[i]
        slow_n[i] = slow_n[i] + 1 if slow else 0
        if slow and slow_n[i] >= slow_run:
            slow_n[i] = 0
            pending[i] = _TRIG_SLOW
    if accept:
        err[i], front[i] = e, f
        valid[i] = st == _OK
        beta[i] = min(1.0, 2.0 * beta[i])
        if ul:
            beta[i] = 1.0
            lscale[i] = 1.0
        return True
    if ul:
        lscale[i] *= 0.5
    beta[i] *= 0.5
    if smbs and tir_on and tir_rejected and st == _TIR:
        pending[i] = _TRIG_TIR
    if beta[i] < min_beta:
        outcome[i] = _MAX_ITER
        return False
    return True


@njit(inline="always", **_LANES)
def _walk_lane(i, cfg, geo, lane, state, scratch, proposal, ray, large):
    """walk.newton_walk of lane i (row i of lane and state) from the seed chain in its row of
    state (F, I, out_dir, and its walk outcome in outcome): the set-up (etas of the seed's
    vertices, the mismatch, beta 1; a seed whose last refraction is TIR starts with a large
    mutation), then per iteration the acceptance of the last proposal (_lane_update), the
    convergence test, MAX_ITER at the last iteration, the small mutation (_lane_newton), SMBS's
    trigger and large mutation (_lane_trigger, _lane_large; large[trigger] counts them), the
    singular test, and the proposal's chain (_trace_lane into row 0 of proposal). Inlined, at
    its one call in _walk_jobs: a call per walk passed some 50 arrays field by field (7-8% of a
    ring's walk time in pushes onto the stack)."""
    (hv, kinds, smbs, tir_on, backlit_on, slow_on, tir_rejected, backlit_at, tau, slow_run, min_beta, threshold,
     max_step, eps, max_halvings, max_iterations, beta0, stall_window, stall_factor, stall_from) = cfg
    x0, ng0, ly, lys, lyt, directional, etas, large_ok, obj_lo, obj_hi = lane
    F, I, out_dir, err, front, valid, beta, lscale, pending, slow_n, outcome, converged, mutations = state
    C, A, B, D, rhs, Li, Y, X = scratch
    nF, nI, nstatus, nout, hist = proposal
    mat_ior = geo[7]
    k = kinds.shape[0]
    st = outcome[i]
    for j in range(k):
        etas[i, j] = mat_ior[I[i, j, MAT]]
    err[i], front[i] = _lane_mismatch(F, i, out_dir, ly, i, directional)
    valid[i] = st == _OK  # a lane converges only from a valid chain
    beta[i] = beta0
    # SMBS: GetRatio's bisection, carried on across iterations: a large mutation whose ray missed
    # the caster (or failed otherwise) would repeat itself exactly from the same vertex, so the
    # next one from there starts at half the weight; an accepted one resets it
    lscale[i] = 1.0
    pending[i] = _NONE  # SMBS: the trigger for the next step
    slow_n[i] = 0  # slow small steps in a row
    converged[i] = False
    mutations[i] = 0
    walkable = st == _OK or st == _SIDE  # an exit below the surface is walkable, not yet valid
    if walkable:
        outcome[i] = _OK
    if smbs and tir_on and st == _TIR and large_ok[i]:  # a seed whose last refraction is TIR mutates first
        pending[i] = _TRIG_TIR
        err[i] = np.inf
        front[i] = False
        outcome[i] = _OK
        walkable = True
    if not walkable:
        return
    xi = _v(x0, i, 0)
    gi = _v(ng0, i, 0)
    ul = False
    # a walk that cannot mutate large (SMS, MNEE, SMBS's defensive lanes) gives up when its last
    # stall_window steps shrank the mismatch by less than stall_factor (from step stall_from on)
    stalls = stall_window > 0 and not (smbs and large_ok[i])
    for it in range(max_iterations + 1):
        if it > 0:
            e, f = _lane_mismatch(nF, 0, nout, ly, i, directional)
            if not _lane_update(0, i, nF, nI, nstatus, nout, e, f, ul, smbs, tir_on, slow_on, tir_rejected, tau,
                                slow_run, min_beta, F, I, out_dir, err, front, valid, beta, lscale, pending, slow_n,
                                outcome):
                return
        if err[i] < threshold and front[i] and valid[i]:
            converged[i] = True
            return
        if stalls:
            if it >= stall_from and err[i] > stall_factor * hist[it % stall_window]:
                outcome[i] = _STALLED
                return
            hist[it % stall_window] = err[i]
        if it == max_iterations:
            outcome[i] = _MAX_ITER
            return
        ok, p, d = _lane_newton(i, hv, kinds, x0, F, etas, ly, lys, lyt, directional, beta, max_step,
                                C, A, B, D, rhs, Li, Y, X)
        ul = False
        if smbs:
            tr = _lane_trigger(i, kinds, backlit_at, backlit_on, x0, F, ly, directional, pending)
            if tr != _NONE and large_ok[i]:
                dl, okl = _lane_large(i, kinds, x0, F, I, etas, ly, directional, obj_lo, obj_hi, lscale,
                                      max_halvings)
                if okl:
                    ul = True
                    d = dl
                    p = _add(xi, dl)
                    large[tr] += 1
        if not (ok or ul):
            outcome[i] = _SINGULAR
            return
        mutations[i] += 1
        on, w = _spawn_aim1(xi, gi, d, p, eps)
        _trace_lane(ray, np.int64(RAYS_WALK), np.int64(0), xi, on, w, kinds, geo, eps, nF, nI, nstatus, nout)


@njit(inline="always", **_JIT)
def _walk_scratch(k, stall_window):
    """The work arrays of one thread's walks: the constraint blocks and solve (_lane_scratch),
    one proposal chain (F, I, status, out_dir) and the last stall_window mismatches of a walk."""
    return _lane_scratch(k), (np.zeros((1, k, NF)), np.zeros((1, k, 3), np.int64), np.zeros(1, np.int64),
                              np.zeros((1, 3)), np.zeros(max(stall_window, 1)))


@TypedOnce
@njit(**_JIT)
def walk_lanes(rt, seeded, d, want_obj, cfg, geo, lane, state):
    """walk.newton_walk of every lane, one after the other, each from its seed to its outcome
    with every ray cast here: seeded, from the seed chains in state (F, I, out_dir, outcome);
    else from seed rays in directions d (a chain whose first vertex is off want_obj[i] >= 0
    ends as SEED_OBJECT, as trace_lanes). cfg (walk.kernel_config), geo (_trace_lane), lane
    and state: see walk.newton_walk. Returns the large mutations per trigger (4,) and the ray
    counters (embree.ray_state)."""
    ray = ray_state(rt)
    scratch, proposal = _walk_scratch(cfg[1].shape[0], cfg[17])
    large = np.zeros(4, np.int64)
    z3, zi = np.zeros((0, 3)), np.zeros(0, np.int64)  # bernoulli_lanes' arguments, unused here
    # (np.bool_: a literal True or False would compile _walk_jobs once per value)
    _walk_jobs(np.bool_(False), seeded, (z3, z3, z3, z3, zi), (np.zeros(0), np.zeros((0, 3, 3)), zi),
               (0.0, np.int64(0), np.int64(0), np.int64(0), 0.0, 0.0), cfg, geo, lane, state, scratch, proposal,
               ray, large, zi, np.zeros(2, np.int64), d, want_obj)
    return large, ray[6]


# ------------------------------------------------------------------ Bernoulli trials
_GOLD = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_SEED_OBJECT = 6


@njit(**_JIT)
def _mix64(z):
    """splitmix64's finaliser (Steele, Lea and Flood 2014)."""
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


@njit(**_JIT)
def _keyed_bits(key, a, b, dim):
    """64 random bits that depend only on (key, a, b, dim)."""
    z = _mix64(np.uint64(key) + _GOLD * np.uint64(a + 1))
    z = _mix64(z + _GOLD * np.uint64(b + 1))
    return _mix64(z + _GOLD * np.uint64(dim + 1))


@njit(**_JIT)
def keyed_uniform(key, a, b, dim):
    """A uniform number in [0, 1) that depends only on (key, a, b, dim): counter-based, so a
    trial's random numbers do not depend on when or on which thread it runs."""
    return np.float64(_keyed_bits(key, a, b, dim) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


_SALT = np.uint64(0xD1B54A32D192ED03)


@njit(**_JIT)
def keyed_uniform3(key, a, b, dim):
    """keyed_uniform(key, a, b, dim) and two more uniform numbers (32 bits each, from the bits of a
    salted key) for a specular vertex: the lobe, then a rough surface's microfacet normal
    (optics.scatter1). The first is the number a smooth vertex always drew, so its paths stay."""
    z = _keyed_bits(np.uint64(key) + _SALT, a, b, dim)
    lo = np.float64(z & np.uint64(0xFFFFFFFF)) * (1.0 / 4294967296.0)
    hi = np.float64(z >> np.uint64(32)) * (1.0 / 4294967296.0)
    return keyed_uniform(key, a, b, dim), lo, hi


@njit(**_LANES)
def _walk_jobs(trial, seeded, samples, seeds, trials, cfg, geo, lane, state, scratch, proposal, ray, large, first,
               tally, d, want):
    """The walks of walk_lanes (trial False: every lane of lane and state, from its seed chain
    where seeded, else from a seed ray in direction d[i], want[i] its object; samples, seeds,
    trials, first and tally unused) and of bernoulli_lanes (trial True: its samples' trials in
    the one row of lane and state, d and want that row's seed ray) in one loop, so that the walk
    (_walk_lane) is inlined at one call and compiled once. The caller holds the arrays."""
    x0, ng0, ly, lys, lyt, directional, etas, large_ok, obj_lo, obj_hi = lane
    F, I, out_dir, outcome, converged, mutations = state[0], state[1], state[2], state[10], state[11], state[12]
    kinds, smbs, eps = cfg[1], cfg[2], cfg[13]
    sx0, sng, sly, d1, obj1 = samples
    cdf, tv, tobj = seeds
    total, key, p0, max_trials, defensive, uniqueness = trials
    row = x0.shape[0] - 1  # trial: the one row of lane and state (not a literal 0: one compiled walk)
    n = sx0.shape[0] if trial else x0.shape[0]
    if trial and max_trials <= 0:
        return
    p = t = 0  # the lane (trial: the sample) and its trial
    while p < n:
        i = p
        if trial:
            i = row
            if t == 0:
                for c in range(3):
                    x0[row, c], ng0[row, c], ly[row, c] = sx0[p, c], sng[p, c], sly[p, c]
            # trial t of sample p: a seed aimed at a uniform point on the casters (manifold.Seeder
            # for SMS), its random numbers keyed by (key, p0 + p, t)
            u0 = keyed_uniform(key, p0 + p, t, 0)
            u1 = keyed_uniform(key, p0 + p, t, 1)
            u2 = keyed_uniform(key, p0 + p, t, 2)
            tri = min(np.searchsorted(cdf, u0 * total, side="right"), cdf.shape[0] - 1)
            su = math.sqrt(u1)
            b0, b1, b2 = 1 - su, su * (1 - u2), su * u2
            q = (b0 * tv[tri, 0, 0] + b1 * tv[tri, 1, 0] + b2 * tv[tri, 2, 0],
                 b0 * tv[tri, 0, 1] + b1 * tv[tri, 1, 1] + b2 * tv[tri, 2, 1],
                 b0 * tv[tri, 0, 2] + b1 * tv[tri, 1, 2] + b2 * tv[tri, 2, 2])
            dq = _normalize(_sub(q, _v(x0, row, 0)))
            d[row, 0], d[row, 1], d[row, 2] = dq
            want[row] = tobj[tri]
            large_ok[row] = keyed_uniform(key, p0 + p, t, 3) >= defensive if smbs else True
        if trial or not seeded:
            _seed_lane(ray, i, x0, ng0, d, want, kinds, geo, eps, F, I, outcome, out_dir)
        _walk_lane(i, cfg, geo, lane, state, scratch, proposal, ray, large)
        if not trial:
            p += 1
            continue
        tally[0] += 1
        tally[1] += mutations[row]
        found = False
        if converged[row]:
            d2 = _normalize(_sub(_vk(F, row, 0, P), _v(x0, row, 0)))
            found = abs(_dot(d2, _v(d1, p, 0)) - 1.0) < uniqueness and I[row, 0, OBJ] == obj1[p]
        if found:
            first[p] = t
        t += 1
        if found or t == max_trials:
            p += 1
            t = 0


@TypedOnce
@njit(**_JIT)
def bernoulli_lanes(rt, samples, seeds, trials, cfg, geo, directional, obj_lo, obj_hi):
    """trials.bernoulli_trials for samples (x0, ng0, light point or direction, first segment's
    direction d1, first vertex's object obj1; (S, ...) each): per sample, walks from seeds at
    uniform points on the casters (seeds: the casters' triangle area cdf, vertices and objects)
    one after the other until one finds the sample's solution (estimators.same_solution) or
    max_trials have not. trials: (the cdf's total, key, p0 (the index of the first sample in the
    batch), max_trials, SMBS's defensive share, uniqueness threshold). Trial t of sample p draws
    from keyed_uniform(key, p0 + p, t, .): each sample's first success does not depend on which
    thread or block runs it. Returns the first successful trial per sample (max_trials: none),
    the walks and Newton steps made, and the ray counters (embree.ray_state)."""
    k = cfg[1].shape[0]
    z3 = np.zeros((1, 3))
    lane = (z3.copy(), z3.copy(), z3.copy(), z3, z3, directional, np.zeros((1, k)), np.ones(1, np.bool_),
            obj_lo, obj_hi)
    state = (np.zeros((1, k, NF)), np.zeros((1, k, 3), np.int64), np.zeros((1, 3)), np.zeros(1),
             np.zeros(1, np.bool_), np.zeros(1, np.bool_), np.ones(1), np.ones(1), np.zeros(1, np.int64),
             np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(1, np.bool_), np.zeros(1, np.int64))
    ray = ray_state(rt)
    scratch, proposal = _walk_scratch(k, cfg[17])
    large = np.zeros(4, np.int64)
    first = np.full(samples[0].shape[0], trials[3], np.int64)
    tally = np.zeros(2, np.int64)
    _walk_jobs(np.bool_(True), np.bool_(True), samples, seeds, trials, cfg, geo, lane, state, scratch, proposal, ray,
               large, first, tally, np.zeros((1, 3)), np.zeros(1, np.int64))
    return first, tally[0], tally[1], ray[6]


# ------------------------------------------------------------------ the film
@njit(**_JIT)
def _blackman_harris(x, r):
    """film.blackman_harris of one offset (r already at least 0.5)."""
    if not abs(x) <= r:
        return 0.0
    c = math.cos(2.0 * math.pi * (x / (2.0 * r) + 0.5))
    c2 = 2.0 * c * c - 1.0  # cos 2v
    c3 = c * (2.0 * c2 - 1.0)  # cos 3v = 4 c^3 - 3 c
    h = 0.35875 - 0.48829 * c + 0.14128 * c2 - 0.01168 * c3
    return h / (0.35875 * 2.0 * r)


@njit(**_JIT)
def blackman_harris(x, r):
    """Cycles' Blackman-Harris window of half-width r (>= 0.5) at offsets x, normalised to one."""
    out = np.zeros(x.shape[0])
    for i in range(x.shape[0]):
        out[i] = _blackman_harris(x[i], r)
    return out


@njit(**_JIT)
def splat(cur, W, x0, x1, y0, y1, r, k, rx, ry, rgb):
    """film.Film.splat's loop: every sample through the (2k+1)^2 filter taps into cur (H*W, 3),
    samples in order, on the rows y0 <= y < y1 and columns x0 <= x < x1 alone (each pixel's sums
    in the samples' order, whoever adds them: threads given rows of their own make the image one
    thread makes, bit for bit)."""
    wx = np.zeros(2 * k + 1)
    for i in range(rx.shape[0]):
        fx = math.floor(rx[i])
        fy = math.floor(ry[i])
        if fy + k < y0 or fy - k >= y1:
            continue  # no tap on these rows
        for ox in range(-k, k + 1):
            wx[ox + k] = _blackman_harris(fx + ox + 0.5 - rx[i], r)
        for oy in range(-k, k + 1):
            py = fy + oy
            if py < y0 or py >= y1:
                continue
            wy = _blackman_harris(py + 0.5 - ry[i], r)
            if wy == 0.0:
                continue
            for ox in range(-k, k + 1):
                px = fx + ox
                w = wy * wx[ox + k]
                if not (w > 0) or px < x0 or px >= x1:
                    continue
                idx = int(py) * W + int(px)
                for c in range(3):
                    cur[idx, c] += rgb[i, c] * w


# ------------------------------------------------------------------ diffuse bounces, the hand-off's cosine paths
@njit(inline="always", **_JIT)
def _cosine_bounce(u1, u2, w, g, n):
    """indirect._diffuse_bounce's direction: cosine-distributed about the shading normal n on
    w's side of the geometric normal g (vec.frame, vec.cosine_hemisphere); also that side."""
    side = 1.0 if _dot(w, g) >= 0 else -1.0
    nn = _mul(side, n)
    s, t = frame1(nn)
    r = math.sqrt(u1)
    phi = 2.0 * np.pi * u2
    x, y, z = r * math.cos(phi), r * math.sin(phi), math.sqrt(max(0.0, 1.0 - u1))
    return _add(_add(_mul(x, s), _mul(y, t)), _mul(z, nn)), side, nn


@njit(inline="always", **_JIT)
def _diffuse_scatter(u1, u2, u3, w, g, n, a, beta, adjoint):
    """indirect._diffuse_bounce of one lane: a cosine direction about the shading normal n on w's
    side of g (_cosine_bounce), Russian roulette on the albedo a (u3), the weight beta * a / q,
    with Veach's shading-normal correction when adjoint (light carried from w to the new
    direction). Returns (kept, direction, weight)."""
    zero = (0.0, 0.0, 0.0)
    d, side, nn = _cosine_bounce(u1, u2, w, g, n)
    q = min(max(_max(_max(a[0], a[1]), a[2]), 0.0), 1.0)
    if not u3 < q:
        return False, zero, zero
    b = (beta[0] * (a[0] / q), beta[1] * (a[1] / q), beta[2] * (a[2] / q))
    cout = _dot(d, _mul(side, g))
    if adjoint:
        num = abs(_dot(w, n) * cout)
        den = abs(_dot(w, g) * _dot(d, n))
        corr = num / den if den > 0 else 0.0
        b = _mul(corr, b)
    if not (cout > 0 and _dot(w, nn) > 0 and _max(_max(b[0], b[1]), b[2]) > 0):
        return False, zero, zero
    return True, d, b


@njit(**_JIT)
def diffuse_rows(u, w, ng, ns, beta, alb, adjoint):
    """_diffuse_scatter per lane (u: (3, n) uniform numbers): (new directions, new weights, kept
    lanes), as optics.scatter_rows."""
    n = w.shape[0]
    d_out, b_out, keep = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n, np.int64)
    cnt = 0
    for i in range(n):
        ok, d, b = _diffuse_scatter(u[0, i], u[1, i], u[2, i], _v(w, i, 0), _v(ng, i, 0), _v(ns, i, 0),
                                    _v(alb, i, 0), _v(beta, i, 0), adjoint)
        if ok:
            keep[cnt] = i
            for c in range(3):
                d_out[cnt, c], b_out[cnt, c] = d[c], b[c]
            cnt += 1
    return d_out[:cnt], b_out[:cnt], keep[:cnt]


@njit(inline="always", **_JIT)
def _hit_or_miss(ray, o, d, tv, tng, eps):
    """The closest hit of the ray o + t d (cast here, kind 0): (primitive, -1 on a miss; the float64
    distance, inf on a miss; _hit_point's point, unit geometric normal, corner 0, edges 1 and 2)."""
    pr, t32 = intersect1(ray, o, d, np.inf, 0)
    if pr < 0:
        z = (0.0, 0.0, 0.0)
        return pr, np.inf, z, z, z, z, z
    t, p, g, v0, e1, e2 = _hit_point(o, d, o, False, t32, pr, tv, tng, eps)
    return pr, t, p, g, v0, e1, e2


@njit(**_JIT)
def cdf_pick(cdf, guide, u):
    """min(np.searchsorted(cdf, u * cdf[-1], side="right"), len(cdf) - 1), the same index, through
    a guide table (Chen and Asau 1974; guide_table): a step or two from guide[int(u G)] instead of a
    binary search's log2(len) mispredicted branches (on 4,000 triangles 10 ns a pick against 64)."""
    n = cdf.shape[0]
    x = u * cdf[n - 1]
    j = guide[min(int(u * guide.shape[0]), guide.shape[0] - 1)]
    while j > 0 and cdf[j - 1] > x:
        j -= 1
    while j < n and cdf[j] <= x:
        j += 1
    return min(j, n - 1)


def guide_table(cdf):
    """cdf_pick's guide over an increasing cdf: entry k is where the search for u = k / len starts."""
    g = len(cdf)
    return np.searchsorted(cdf, np.arange(g) / g * cdf[-1], side="right").astype(np.int64)


@njit(inline="always", **_JIT)
def _toward_triangle(u0, u1, u2, x, w, g, n, a, beta, cand, cdf, guide, tv, tng, tns):
    """bent_gather's first bounce from the diffuse receiver x (w: back to the eye; g, n: its
    normals; a: albedo): towards a point uniform in area over the candidate triangles cand (cdf:
    their cumulative areas, guide: its guide_table), weighted by the Lambertian BSDF x cosine over
    the point's density in solid angle; kept only where the point's normal bends for that direction
    (optics.scatter1's test, before any ray is cast: on cube_grey_reflect 2.4% of the points do).
    Returns (kept, direction, weight, the triangle the ray must meet first, the point and its
    barycentrics: the vertex the path takes, exactly the one sampled, wherever the offset ray
    origin puts the hit)."""
    zero = (0.0, 0.0, 0.0)
    total = cdf[cdf.shape[0] - 1]
    pr = cand[cdf_pick(cdf, guide, u0)]
    su = math.sqrt(u1)
    b1, b2 = su * (1.0 - u2), su * u2  # uniform over the triangle
    v0 = (tv[pr, 0, 0], tv[pr, 0, 1], tv[pr, 0, 2])
    e1 = (tv[pr, 1, 0] - v0[0], tv[pr, 1, 1] - v0[1], tv[pr, 1, 2] - v0[2])
    e2 = (tv[pr, 2, 0] - v0[0], tv[pr, 2, 1] - v0[1], tv[pr, 2, 2] - v0[2])
    q = _sub(_add(v0, _add(_mul(b1, e1), _mul(b2, e2))), x)
    dist2 = _dot(q, q)
    if not dist2 > 0:
        return False, zero, zero, -1, zero, 0.0, 0.0
    d = _mul(1.0 / math.sqrt(dist2), q)
    side = 1.0 if _dot(w, g) >= 0 else -1.0
    nn = _mul(side, n)
    cos0 = _dot(d, nn)
    cos_p = abs(d[0] * tng[pr, 0] + d[1] * tng[pr, 1] + d[2] * tng[pr, 2])
    if not (cos0 > 0 and side * _dot(d, g) > 0 and _dot(w, nn) > 0 and cos_p > 0):
        return False, zero, zero, -1, zero, 0.0, 0.0
    gp = (tng[pr, 0], tng[pr, 1], tng[pr, 2])
    if not bend1(_neg(d), _shading_normal(tns, pr, b1, b2, gp, d), gp)[1]:  # -d: the eye's direction there
        return False, zero, zero, -1, zero, 0.0, 0.0
    f = cos0 * cos_p * total / (math.pi * dist2)  # (a / pi) cos0 / pdf, pdf = dist^2 / (total cos_p)
    return True, d, (beta[0] * a[0] * f, beta[1] * a[1] * f, beta[2] * a[2] * f), pr, _add(x, q), b1, b2


@njit(**_LANES)
def _handoff_rows(ray, key, a0, samples, K, x0, ng0, ns0, sn0, w0, beta0, alb, mat0, geo, mats, physical, eps, seg,
                  seg_n, hist, h_prim, cand, cdf, guide):
    """handoff_lanes' loop over its lanes (its caller holds the arrays)."""
    tv, tng, tns, tri_material, mat_kind, tri_object, casters, _, hid = geo
    targeted = cand.shape[0] > 0
    for lane in range(x0.shape[0] * samples):
        seg_n[lane] = 0
        i = lane // samples
        s = lane - i * samples
        g = _v(ng0, i, 0)
        first, p_first, f1, f2 = -1, (0.0, 0.0, 0.0), 0.0, 0.0
        r = a0 + i
        u0, u1, u2 = keyed_uniform(key, r, s, 0), keyed_uniform(key, r, s, 1), keyed_uniform(key, r, s, 2)
        if targeted:
            ok, d, b, first, p_first, f1, f2 = _toward_triangle(u0, u1, u2, _v(x0, i, 0), _v(w0, i, 0), g,
                                               _v(ns0, i, 0), _v(alb, i, 0), _v(beta0, i, 0), cand, cdf, guide,
                                               tv, tng, tns)
        else:
            ok, d, b = _diffuse_scatter(u0, u1, u2, _v(w0, i, 0), g, _v(ns0, i, 0),
                                        _v(alb, i, 0), _v(beta0, i, 0), False)
        if not ok:
            continue
        kc = _coat_factor(mats, mat0[i], _v(ns0, i, 0), _v(w0, i, 0), d, True)  # under a Principled coat
        # and a bumped receiver's shadowing (1 where ns0 is sn0, its smooth normal: no bump)
        kc = _mul(bump_shadowing1(_v(sn0, i, 0), _v(ns0, i, 0), d, mats[5][mat0[i]] != 0), kc)
        b = (b[0] * kc[0], b[1] * kc[1], b[2] * kc[2])
        o = _add(_v(x0, i, 0), _mul(eps if _dot(d, g) >= 0 else -eps, g))  # tracer.spawn
        medium = -1
        bit = _RAY_DIFFUSE  # the kind of the next ray: x0's bounce, then the latest event's
        for bounce in range(K + 1):
            pr, t, p, gg, v0, e1, e2 = _hit_or_miss_past(ray, o, d, tv, tng, tri_object, hid, bit, eps)
            if bounce > 0:  # a segment after a specular vertex: the caller looks for lights on it
                k = seg_n[lane]
                for c in range(3):
                    seg[lane, k, c], seg[lane, k, 3 + c], seg[lane, k, 7 + c] = o[c], d[c], b[c]
                seg[lane, k, 6] = t
                seg_n[lane] = k + 1
            if pr < 0 or bounce == K or (bounce == 0 and targeted and pr != first):
                break
            b = _absorbed(mats[0], mats[10], medium, tri_material[pr], d, gg, t, b)
            m = tri_material[pr]
            kind = mat_kind[m]
            if kind != _CONDUCTOR and kind != _DIELECTRIC:
                break
            if targeted and bounce == 0:  # the sampled point itself (_toward_triangle)
                p, b1, b2 = p_first, f1, f2
            else:
                b1, b2, _, _, _ = _barycentric(e1, e2, _sub(p, v0))
            n = _shading_normal(tns, pr, b1, b2, gg, d)
            ok, dd, bb, bent = scatter1(keyed_uniform3(key, r, s, 3 + bounce), _neg(d), n, gg, m, kind, mats, b,
                                        physical, False)
            if not ok or (targeted and bounce == 0 and not bent):  # bent_gather: bent first vertices only
                break
            h_prim[lane, bounce] = pr
            if hist.shape[2] > 7:
                hist[lane, bounce, 7] = 1.0 if bent else 0.0
            for c in range(3):
                hist[lane, bounce, c] = p[c]
            hist[lane, bounce, 3], hist[lane, bounce, 4] = b1, b2
            hist[lane, bounce, 5] = 1.0 if _dot(d, n) * _dot(dd, n) < 0 else 0.0
            hist[lane, bounce, 6] = 1.0 if casters[tri_object[pr]] else 0.0
            bit = _RAY_GLOSSY if hist[lane, bounce, 5] > 0 else _RAY_TRANSMISSION
            o = _add(p, _mul(eps if _dot(dd, gg) >= 0 else -eps, gg))
            medium = _medium_after(m, kind, dd, gg)
            d, b = dd, bb


@TypedOnce
@njit(**_JIT)
def handoff_lanes(rt, key, a0, samples, K, x0, ng0, ns0, sn0, w0, beta0, alb, mat0, geo, mats, physical, eps, seg,
                  seg_n, hist, h_prim, cand, cdf, guide):
    """indirect.handoff_gather's paths, lane i // samples's receiver (x0, ng0, ns0, w0: the
    direction back to the eye, beta0: the throughput, alb: the albedo; sn0: the smooth normal ns0
    a bump bent, eye.Receivers.sn): a cosine bounce with
    Russian roulette on the albedo (indirect._diffuse_bounce), then through up to K specular
    vertices (optics.scatter1, not adjoint; physical: scale_eta), every ray cast here. Lane l is
    sample s = l % samples of receiver a0 + l // samples, its uniform numbers keyed_uniform(key,
    a0 + l // samples, s, dim) (dim 0-2: direction and roulette, 3 + j: the j-th specular vertex),
    so a path does not depend on the block or thread that traces it. Writes per lane the
    segments after each specular vertex, in order, seg_n of them (seg[lane, k]: origin,
    direction, distance to the next surface (inf: none), throughput), and the specular vertices
    (hist[lane, j]: point, barycentrics, 1 for a reflection, 1 on a caster, 1 where Cycles' Bump Map
    Correction bent the normal (optics.scatter1); h_prim[lane, j]: the triangle).

    cand, cdf, guide (indirect.bent_gather; empty: the cosine bounce above): the first bounce goes
    towards a point uniform in area over the triangles cand (cdf: their cumulative areas, guide: its
    guide_table; _toward_triangle), the ray must meet that triangle first, and its normal must be
    one Cycles' Bump Map Correction bends there, or the lane ends. Returns the ray counters
    (embree.ray_state)."""
    ray = ray_state(rt)
    _handoff_rows(ray, key, a0, samples, K, x0, ng0, ns0, sn0, w0, beta0, alb, mat0, geo, mats, physical, eps, seg,
                  seg_n, hist, h_prim, cand, cdf, guide)
    return ray[6]

# the shapes segments_near tests (a row of NEAR_F numbers per light)
NEAR_ALL, NEAR_NONE, NEAR_SPHERE, NEAR_RECT, NEAR_DISK = 0, 1, 2, 3, 4
NEAR_F = 15


@njit(**_JIT)
def segments_near(seg, seg_n, shapes, near):
    """indirect._handoff_block's lights, ahead of their exact test (lights.light_radiance): near[i, k]
    (i < seg's lanes, k < its K) is set where lane i's k-th segment (k < seg_n[i]; seg[i, k]: origin,
    unit direction) could meet one of the lights shapes describes, a row each: NEAR_ALL (any segment:
    a light at infinity), NEAR_NONE (none: a point), NEAR_SPHERE (centre, radius: any ray that
    passes within it ahead of its origin, or starts inside), NEAR_RECT and NEAR_DISK (an area light:
    centre, x and y axes, normal, half sizes, as lights.area_light_shape: its plane met ahead, in
    front, within 1 + 1e-6 of its half sizes; a ray within 1e-6 of its plane's direction, whose
    distance there the two tests could disagree on, counts). Conservative: every segment the exact
    test finds is set; the callers widen the spheres. seg, shapes: float64; seg_n: int64."""
    m, K = near.shape
    for i in range(m):
        for k in range(K):
            near[i, k] = False
        for k in range(min(seg_n[i], K)):
            o = (seg[i, k, 0], seg[i, k, 1], seg[i, k, 2])
            d = (seg[i, k, 3], seg[i, k, 4], seg[i, k, 5])
            for j in range(shapes.shape[0]):
                kind = int(shapes[j, 0])
                if kind == NEAR_ALL:
                    near[i, k] = True
                elif kind == NEAR_SPHERE:
                    oc = _sub(o, (shapes[j, 1], shapes[j, 2], shapes[j, 3]))
                    r = shapes[j, 4]
                    b = _dot(oc, d)
                    cc = _dot(oc, oc) - r * r
                    near[i, k] = cc <= 0.0 or (b < 0.0 and b * b >= cc)
                elif kind == NEAR_RECT or kind == NEAR_DISK:
                    cen = (shapes[j, 1], shapes[j, 2], shapes[j, 3])
                    nrm = (shapes[j, 10], shapes[j, 11], shapes[j, 12])
                    den = _dot(d, nrm)
                    if den > -1e-6:
                        near[i, k] = den < 1e-6  # behind the light, or along its plane
                    else:
                        tt = _dot(_sub(cen, o), nrm) / den
                        if tt > 0.0:
                            q = _sub(_add(o, _mul(tt, d)), cen)
                            a = _dot(q, (shapes[j, 4], shapes[j, 5], shapes[j, 6])) / shapes[j, 13]
                            c = _dot(q, (shapes[j, 7], shapes[j, 8], shapes[j, 9])) / shapes[j, 14]
                            lim = 1.0 + 1e-6
                            near[i, k] = a * a + c * c <= lim * lim if kind == NEAR_DISK else \
                                (abs(a) <= lim and abs(c) <= lim)
                if near[i, k]:
                    break


# ------------------------------------------------------------------ the light tracer's photons
# tally entries of photon_lanes: photons with flux, specular paths cut at max_bounces, lanes a
# shading normal stopped (scatter1 said no), paths whose events left Cycles' Light Paths limits
PH_PHOTONS, PH_TRUNCATED, PH_LOST, PH_BEYOND = 0, 1, 2, 3
PH_TALLY = 4
# a splat record: the diffuse vertex (point, geometric and shading normals), the direction the
# photon arrived from (away from the surface), its flux; and (lane, specular bounces, material)
REC_P, REC_NG, REC_NS, REC_W, REC_BETA = 0, 3, 6, 9, 12
REC_F = 15
_DIFFUSE = 0


@njit(**_JIT)
def _fits(lim, d, g, t):
    """bounces.Limits.allowed of event counts d, g, t; lim = Limits.array()."""
    return d <= lim[0] and g <= lim[1] and t <= lim[2] and d + g + t <= lim[3]


@njit(inline="always", **_JIT)
def _next_surface(ray, o, d, tv, tng, tns, eps):
    """The closest hit of the ray o + t d, from its offset origin (tracer.intersect without an
    exact origin; the ray cast here, counted as kind 0): (primitive, -1 on a miss; the float64
    distance, inf on a miss; point, unit geometric normal, shading normal, barycentrics b1, b2)."""
    pr, t, p, g, v0, e1, e2 = _hit_or_miss(ray, o, d, tv, tng, eps)
    if pr < 0:
        return pr, t, p, g, g, 0.0, 0.0
    b1, b2, _, _, _ = _barycentric(e1, e2, _sub(p, v0))
    return pr, t, p, g, _shading_normal(tns, pr, b1, b2, g, d), b1, b2


@njit(**_LANES)
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
        b = _v(w0, lane, 0)
        if not _max(_max(b[0], b[1]), b[2]) > 0:
            continue
        # what to restore if this lane's records do not fit (it is traced again in the next call)
        rec0, c0, c1, c2 = nrec, counts[0], counts[1], counts[KINDS]
        t0 = (tally[0], tally[1], tally[2], tally[3])
        tally[PH_PHOTONS] += 1
        o, d = _v(o0, lane, 0), _v(d0, lane, 0)
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
            pr, t, p, g, n, b1, b2 = _next_surface(ray, o, d, tv, tng, tns, eps)
            if pr < 0:
                break
            b = _absorbed(mats[0], mats[10], medium, tri_material[pr], d, g, t, b)
            if it == 0 and unshadowing.shape[0] > 0 and unshadowing[tri_object[pr]]:
                # Shadow Linking: Cycles' rays to the light pass an object that does not shadow it, and a path
                # that meets the object goes on from it too: where it could (the object lit, and a caster, or
                # any surface for the indirect photons), either, at random, weighted 2; else passed
                ob0, k0 = tri_object[pr], mat_kind[tri_material[pr]]
                go_on = (lit.shape[0] == 0 or lit[ob0]) and (indirect or ((k0 == _CONDUCTOR or k0 == _DIELECTRIC)
                                                                           and casters[ob0]))
                go_past = True
                if go_on:
                    go_past = keyed_uniform(key, lane, it, 4 + HIDDEN_PASSES + n_unshadow) < 0.5
                    b = _mul(2.0, b)
                if go_past:
                    if n_unshadow == HIDDEN_PASSES:
                        break
                    n_unshadow += 1
                    o = _add(p, _mul(eps if _dot(d, g) >= 0 else -eps, g))  # tracer.spawn, on along d
                    continue
            h = hid[tri_object[pr]] & _PATH_RAYS if hid.shape[0] > 0 else 0
            if h != 0:
                # a surface some kinds of ray do not meet: the path may pass it or meet it, as the kind of
                # the ray the next vertex casts decides (checked there): hidden from all, it is passed;
                # else either, at random, weighted 2
                go_past = h == _PATH_RAYS
                if not go_past:
                    go_past = keyed_uniform(key, lane, it, 3 + n_pass) < 0.5
                    b = _mul(2.0, b)
                if go_past:
                    if n_pass == HIDDEN_PASSES:
                        break
                    passed |= _PATH_RAYS & ~h
                    n_pass += 1
                    o = _add(p, _mul(eps if _dot(d, g) >= 0 else -eps, g))  # tracer.spawn, on along d
                    continue
            if it == 0 and soft[3] > 0:  # lights.soft_falloff_factor
                dc = _sub(p, (soft[0], soft[1], soft[2]))
                d2 = _dot(dc, dc)
                b = _mul(d2 / (d2 + soft[3] * soft[3]), b)
            m = tri_material[pr]
            kind = mat_kind[m]
            obj = tri_object[pr]
            if it == 0 and lit.shape[0] > 0 and not lit[obj]:
                break  # Light Linking: the light does not light the object the camera's path leaves it from
            spec = kind == _CONDUCTOR or kind == _DIELECTRIC
            if not indirect and it == 0:
                spec = spec and casters[obj]  # a caustic photon's first hit: a planned caster
            # a splat where the camera's x0 would be: after a specular vertex (indirect: after a
            # specular vertex on a caster and a diffuse one), x0's own bounce within the limits
            # a diffuse event casts a diffuse ray towards where the photon came from: it must meet the previous
            # vertex and pass what the photon passed
            diffuse_seen = (prev_vis & _RAY_DIFFUSE) != 0 and (passed & _RAY_DIFFUSE) == 0
            if (kind == _DIFFUSE and receivers[obj] and _fits(lim, nd + 1, ngl, nt) and diffuse_seen
                    and ((has_s and n_diff >= 1) if indirect else it > 0)):
                if nrec == cap:
                    full = True
                    break
                w = _neg(d)
                for c in range(3):
                    rec[nrec, REC_P + c], rec[nrec, REC_NG + c], rec[nrec, REC_NS + c] = p[c], g[c], n[c]
                    rec[nrec, REC_W + c], rec[nrec, REC_BETA + c] = w[c], b[c]
                rec_i[nrec, 0], rec_i[nrec, 1], rec_i[nrec, 2] = lane, it, m
                nrec += 1
            step = 0 if it == 0 else 1  # the photon's first event is the path's free last one
            if indirect and kind == _DIFFUSE:
                if not _fits(lim, nd + step + 1, ngl, nt) or not diffuse_seen:
                    break
                ok, dd, bb = _diffuse_scatter(keyed_uniform(key, lane, it, 0), keyed_uniform(key, lane, it, 1),
                                              keyed_uniform(key, lane, it, 2), _neg(d), g, n, _v(mat_color, m, 0),
                                              b, True)
                if not ok:
                    break
                # the eye's path, the other way, arrives here from dd: the glossy layer's share
                bb = _mul(_tab_weight(mats[6], m, _dot(dd, n)), bb)
                nd += step
                n_diff += 1
            else:
                if not indirect and it >= max_bounces:
                    if spec:
                        tally[PH_TRUNCATED] += 1
                    break
                if not spec:
                    break
                if kind == _DIELECTRIC and tns.shape[1] == 6:
                    # a bumped glass's normals as Cycles' eye path meets them: through the glass it
                    # comes from the side the photon goes to (bump.py; a Fresnel reflection or a total
                    # internal one off such a surface takes them from the wrong side)
                    n = _shading_normal(tns, pr, b1, b2, g, _neg(d))
                ok, dd, bb, _ = scatter1(keyed_uniform3(key, lane, it, 0), _neg(d), n, g, m, kind, mats, b,
                                         not physical, True)
                if not ok:
                    tally[PH_LOST] += 1
                    break
                refl = _dot(d, g) * _dot(dd, g) < 0  # bounces.specular_kind
                e = _RAY_GLOSSY if refl else _RAY_TRANSMISSION
                if not prev_vis & e or passed & e:
                    break  # the ray this vertex casts towards the light does not meet the previous vertex
                if refl:
                    ngl += step
                else:
                    nt += step
                if not _fits(lim, nd + 1, ngl, nt):  # no splat can fit any more
                    tally[PH_BEYOND] += 1
                    break
                has_s = has_s or casters[obj]
                if it < K:  # the hand-off's record of the chain, light side first
                    h_prim[lane, it] = pr
                    for c in range(3):
                        hist[lane, it, c] = p[c]
                    hist[lane, it, 3], hist[lane, it, 4] = b1, b2
                    hist[lane, it, 5] = 1.0 if _dot(d, n) * _dot(dd, n) < 0 else 0.0
                    hist[lane, it, 6] = 1.0 if casters[obj] else 0.0
            o = _add(p, _mul(eps if _dot(dd, g) >= 0 else -eps, g))  # tracer.spawn
            medium = _medium_after(m, kind, dd, g)
            d, b = dd, bb
            prev_vis, passed, n_pass = _PATH_RAYS & ~hid[obj] if hid.shape[0] > 0 else _PATH_RAYS, 0, 0
            it += 1
        if full:
            counts[0], counts[1], counts[KINDS] = c0, c1, c2
            tally[0], tally[1], tally[2], tally[3] = t0
            return lane, rec0
    return o0.shape[0], nrec


@TypedOnce
@njit(**_JIT)
def photon_lanes(rt, indirect, o0, d0, w0, soft, lvis, lit, unshadowing, key, lane0, geo, receivers, mats, lim,
                 max_bounces, max_iter, physical, eps, rec, rec_i, hist, h_prim, tally):
    """The light tracer's photons (o0, d0: origin and unit direction; w0: flux), each traced from
    its light to its end, every ray cast here, its random numbers keyed_uniform(key, lane,
    event, .): the same path whichever call or thread traces it.

    Caustic photons (reference.trace_photons, indirect False): the first hit a planned caster,
    then through mirrors and glass (optics.scatter1, adjoint; physical: Cycles' radiance is not
    scaled at refractions, so the flux is), up to max_bounces specular vertices; a record where
    the path meets a diffuse receiver after at least one. Indirect photons (indirect
    .trace_photons): every surface, diffuse bounces with Russian roulette (_diffuse_scatter),
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


# ------------------------------------------------------------------ eye paths
# camera.CameraModel.kernel_params: the origin, the axes (row by row: world x, y, z of the camera's
# x, y, z columns), the view plane's corner and pixel size, the height in pixels, 1 if orthographic,
# the near clip distance
CAM_ORIGIN, CAM_AXES, CAM_XMIN, CAM_YMIN, CAM_PIX_W, CAM_PIX_H, CAM_H, CAM_ORTHO, CAM_CLIP = 0, 3, 12, 13, 14, 15, 16, \
    17, 18
# ... the far clip distance, a pixel's area on the view plane, world -> camera (row by row), the
# render region (x0, x1, y0, y1 raster pixels)
CAM_CLIP_END, CAM_PIX_AREA, CAM_INV, CAM_REGION = 19, 20, 21, 30
CAM_F = 34


# a point of Scene.view_points is the receiver's own where it lies on its plane within this share of the
# sub-pixel's footprint, and at most VIEW_NEAR footprints from it
VIEW_PLANE, VIEW_NEAR = 0.05, 4.0


@njit(inline="always", **_JIT)
def view_normal1(vn, vp, t, px, py, p, ng, ns, to_cam, foot):
    """The shading normal Cycles' camera ray through raster position (px, py) meets at p, a point of
    a bumped diffuse receiver that projects there (ng, ns: its geometric and smooth shading
    normals; to_cam: unit, towards the camera; foot: the width a pixel covers there): the normal of
    Scene.view_normals' sub-pixel there (vn, vp: view_normals, view_points; t: eye.view_tables'
    raster to the view's), turned to ns's side (Cycles' faces the camera), where the sub-pixel's
    point is p's surface (on its plane, near it: VIEW_PLANE, VIEW_NEAR); else ns."""
    h, w = vn.shape[0], vn.shape[1]
    c = min(max(int(math.floor(t[0] * px + t[1])), 0), w - 1)
    r = min(max(int(math.floor(t[2] * py + t[3])), 0), h - 1)
    q = (float(vp[r, c, 0]) - p[0], float(vp[r, c, 1]) - p[1], float(vp[r, c, 2]) - p[2])
    f = foot / t[0]
    slant = max(abs(_dot(to_cam, ng)), 0.02)
    if not (abs(_dot(q, ng)) <= VIEW_PLANE * f + 1e-6 * (abs(p[0]) + abs(p[1]) + abs(p[2]))
            and _dot(q, q) <= (VIEW_NEAR * f / slant) ** 2):
        return ns
    n = (float(vn[r, c, 0]), float(vn[r, c, 1]), float(vn[r, c, 2]))
    ln = math.sqrt(_dot(n, n))
    if not ln > 0.5:
        return ns
    k = (1.0 if _dot(to_cam, ng) * _dot(ns, ng) >= 0 else -1.0) / ln
    return (k * n[0], k * n[1], k * n[2])


@njit(**_JIT)
def view_normal_rows(vn, vp, t, px, py, p, ng, ns, to_cam, foot, out):
    """view_normal1 per row into out (N,3)."""
    for i in range(p.shape[0]):
        n = view_normal1(vn, vp, t, px[i], py[i], _v(p, i, 0), _v(ng, i, 0), _v(ns, i, 0), _v(to_cam, i, 0),
                         foot[i])
        out[i, 0], out[i, 1], out[i, 2] = n[0], n[1], n[2]


@njit(**_JIT)
def _cam_mat(cam, a, v):
    """The 3x3 matrix kept row by row at cam[a:a + 9] (CAM_AXES, CAM_INV) times v."""
    return (cam[a] * v[0] + cam[a + 1] * v[1] + cam[a + 2] * v[2],
            cam[a + 3] * v[0] + cam[a + 4] * v[1] + cam[a + 5] * v[2],
            cam[a + 6] * v[0] + cam[a + 7] * v[1] + cam[a + 8] * v[2])


@njit(inline="always", **_JIT)
def _camera_ray(cam, x, y):
    """camera.CameraModel.rays of raster position (x, y), moved to the near clip plane: (origin,
    unit direction)."""
    fx = cam[CAM_XMIN] + x * cam[CAM_PIX_W]
    fy = cam[CAM_YMIN] + (cam[CAM_H] - y) * cam[CAM_PIX_H]
    if cam[CAM_ORTHO] > 0:
        lo, ld = (fx, fy, 0.0), (0.0, 0.0, -1.0)
    else:
        r = 1.0 / math.sqrt(fx * fx + fy * fy + 1.0)
        lo, ld = (0.0, 0.0, 0.0), (fx * r, fy * r, -r)
    o = _add((cam[CAM_ORIGIN], cam[CAM_ORIGIN + 1], cam[CAM_ORIGIN + 2]), _cam_mat(cam, CAM_AXES, lo))
    d = _cam_mat(cam, CAM_AXES, ld)
    stretch = math.sqrt(_dot(d, d))  # 1 unless the axes are sheared
    d = _mul(1.0 / stretch, d)
    return _add(o, _mul(cam[CAM_CLIP] * stretch / abs(ld[2]), d)), d


@njit(**_JIT)
def camera_rays(cam, x, y):
    """_camera_ray per raster position (CameraModel.pixel_rays): (origins on the near clip
    plane, unit directions)."""
    n = x.shape[0]
    o, d = np.empty((n, 3)), np.empty((n, 3))
    for i in range(n):
        oi, di = _camera_ray(cam, x[i], y[i])
        for c in range(3):
            o[i, c], d[i, c] = oi[c], di[c]
    return o, d


@njit(inline="always", **_JIT)
def _hit_or_miss_past(ray, o, d, tv, tng, tri_object, hid, bit, eps):
    """_hit_or_miss past the surfaces of objects a ray of kind bit (a scene.RAY_* bit) does not meet
    (hid: (O,) the kinds each object does not meet, Scene.hidden_kinds; empty: none), up to
    HIDDEN_PASSES of them (then a miss); each next hit re-computed on the line from o (tracer.intersect's
    exact_origin), t from o."""
    pr, t, p, g, v0, e1, e2 = _hit_or_miss(ray, o, d, tv, tng, eps)
    k = 0
    while hid.shape[0] > 0 and pr >= 0 and hid[tri_object[pr]] & bit:
        if k == HIDDEN_PASSES:
            pr = -1
            break
        ob = _add(p, _mul(eps if _dot(d, g) >= 0 else -eps, g))  # tracer.spawn
        pr, t32 = intersect1(ray, ob, d, np.inf, 0)
        if pr >= 0:
            t, p, g, v0, e1, e2 = _hit_point(ob, d, o, True, t32, pr, tv, tng, eps)
        k += 1
    if pr < 0:
        z = (0.0, 0.0, 0.0)
        return pr, np.inf, z, z, z, z, z
    return pr, t, p, g, v0, e1, e2


@njit(inline="always", **_JIT)
def _next_past(ray, o, d, tv, tng, tns, tri_object, hid, bit, eps):
    """_next_surface past the surfaces a ray of kind bit does not meet (_hit_or_miss_past)."""
    pr, t, p, g, v0, e1, e2 = _hit_or_miss_past(ray, o, d, tv, tng, tri_object, hid, bit, eps)
    if pr < 0:
        return pr, t, p, g, g, 0.0, 0.0
    b1, b2, _, _, _ = _barycentric(e1, e2, _sub(p, v0))
    return pr, t, p, g, _shading_normal(tns, pr, b1, b2, g, d), b1, b2


@njit(inline="always", **_JIT)
def _camera_clear(ray, o, d, tmax, tng, tri_object, hid, eps):
    """Whether nothing camera rays meet lies on o + t d, 0 < t < tmax (the shadow ray towards the
    camera, counted as kind 1): the surfaces of objects camera rays do not meet (hid & RAY_CAMERA,
    Scene.hidden_kinds) are passed, up to HIDDEN_PASSES of them."""
    if hid.shape[0] == 0:
        return not occluded1(ray, o, d, tmax, 1)
    for _ in range(HIDDEN_PASSES + 1):
        pr, t = intersect1(ray, o, d, tmax, 1)
        if pr < 0:
            return True
        if not hid[tri_object[pr]] & _RAY_CAMERA:
            return False
        g = (tng[pr, 0], tng[pr, 1], tng[pr, 2])
        o = _add(_add(o, _mul(t, d)), _mul(eps if _dot(d, g) >= 0 else -eps, g))  # tracer.spawn
        tmax -= t
    return False


@njit(**_LANES)
def _camera_splat_rows(ray, cam, margin, rec, mat, mats, first_order, eps, textured, view, hide, rx, ry, val, alb):
    """camera_splats' loop (its caller holds the arrays). Returns (rays cast, splats
    written)."""
    v_flag, v_n, v_p, v_t = view
    tng, tri_object, hid = hide
    mat_color = mats[2]
    x0, x1, y0, y1 = cam[CAM_REGION], cam[CAM_REGION + 1], cam[CAM_REGION + 2], cam[CAM_REGION + 3]
    org = (cam[CAM_ORIGIN], cam[CAM_ORIGIN + 1], cam[CAM_ORIGIN + 2])
    ortho = cam[CAM_ORTHO] > 0
    a = CAM_AXES
    rays = n = 0
    for i in range(rec.shape[0]):
        y = _v(rec, i, REC_P)
        ng, ns, w = _v(rec, i, REC_NG), _v(rec, i, REC_NS), _v(rec, i, REC_W)
        # camera.CameraModel.project
        q = _sub(y, org)
        c0, c1, c2 = _cam_mat(cam, CAM_INV, q)
        depth = -c2
        if not (depth >= cam[CAM_CLIP] and depth <= cam[CAM_CLIP_END]):
            continue
        if ortho:
            fx, fy, dist, cos_axis = c0, c1, depth, 1.0
        else:
            fx, fy = c0 / depth, c1 / depth
            dist = math.sqrt(_dot(q, q))
            cos_axis = depth / dist if dist > 0 else 0.0
        px = (fx - cam[CAM_XMIN]) / cam[CAM_PIX_W]
        py = cam[CAM_H] - (fy - cam[CAM_YMIN]) / cam[CAM_PIX_H]
        if not (px > x0 - margin and px < x1 + margin and py > y0 - margin and py < y1 + margin):
            continue
        # camera.CameraModel.towards
        if ortho:
            to_cam = (cam[a + 2], cam[a + 5], cam[a + 8])
            tmax = depth - cam[CAM_CLIP]
        else:
            to_cam = _mul(1.0 / max(dist, 1e-300), _neg(q))
            tmax = dist * (1.0 - cam[CAM_CLIP] / max(depth, 1e-300))
        m = mat[i]
        sn = ns
        if v_t[0] > 0 and v_flag[m]:  # a bumped receiver: its normal as Cycles' camera ray meets it (eye.view_bumped)
            ns = view_normal1(v_n, v_p, v_t, px, py, y, ng, sn, to_cam,
                              cam[CAM_PIX_W] * (1.0 if ortho else dist))
        ci_g, co_g, ci_s = _dot(w, ng), _dot(to_cam, ng), _dot(w, ns)
        if not (ci_g * co_g > 0 and ci_s * (1.0 if ci_g > 0 else -1.0) > 0):  # same side, lit per shading normal
            continue
        o = _add(y, _mul(eps if co_g >= 0 else -eps, ng))  # tracer.spawn
        rays += 1
        if not _camera_clear(ray, o, to_cam, tmax - eps, tng, tri_object, hid, eps):
            continue
        # the diffuse BSDF with the shading-normal correction of the adjoint (Veach 5.3), the
        # camera's importance (CameraModel.importance)
        corr = abs(ci_s) / max(abs(ci_g), 1e-12) * bump_shadowing1(sn, ns, w, mats[5][m] != 0)
        if ortho:
            imp = abs(co_g) / cam[CAM_PIX_AREA]
        else:
            c3 = max(cos_axis, 1e-12) ** 3
            imp = abs(co_g) / (max(dist, 1e-300) ** 2 * cam[CAM_PIX_AREA] * c3)
        tw = _tab_weight(mats[6], m, _dot(to_cam, ns))  # under a glossy coat
        k = corr * imp / math.pi * tw
        kc = _coat_factor(mats, m, ns, to_cam, w, first_order)  # and what on-minus-off keeps of it
        rx[n], ry[n] = px, py
        tex = textured.shape[0] > 0 and textured[m]
        for c in range(3):
            val[n, c] = rec[i, REC_BETA + c] * mat_color[m, c] * k * kc[c]
            if alb.shape[0] > 0:  # Cycles' Diffuse Color pass there (Film.splat)
                alb[n, c] = mat_color[m, c] * tw if tex else 0.0
        n += 1
    return rays, n


@TypedOnce
@njit(**_JIT)
def camera_splats(rt, cam, margin, rec, mat, mats, first_order, eps, textured, view, hide, rx, ry, val, alb):
    """reference.splat_records: the light tracer's records (rec: REC_* columns; mat: their
    materials, diffuse with albedo mats[2][mat] under a Principled coat: layer.py, first_order: the
    records are x0's own caustic, not light after a diffuse bounce): each diffuse vertex connected
    to the camera
    (cam: CameraModel.kernel_params; margin: the film's filter width in pixels around the render
    region), its shadow ray cast here, the splat's raster position and value (the flux times the
    diffuse BSDF, Veach's shading-normal correction and the camera's importance) written to rx,
    ry, val; with textured (Scene.mat_textured, or empty) and alb (as val, or empty), the albedo of
    each splat on a textured material (Film.splat), zero elsewhere; view (eye.view_tables): a bumped
    receiver's normals as the camera sees them; hide: (triangles' geometric normals, objects,
    Scene.hidden_kinds): the shadow rays pass the surfaces camera rays do not meet.
    Returns (shadow rays cast, splats written, the ray counters)."""
    ray = ray_state(rt)
    rays, n = _camera_splat_rows(ray, cam, margin, rec, mat, mats, first_order, eps, textured, view, hide, rx, ry,
                                 val, alb)
    return rays, n, ray[6]


@njit(**_LANES)
def _eye_rows(ray, cam, rx, ry, sample, key, geo, receivers, mats, max_bounces, min_specular, scale_eta, eps, rec,
              rec_i, prior):
    """eye_lanes' loop over its lanes (its caller holds the arrays). Returns the
    records written."""
    tv, tng, tns, tri_material, mat_kind, tri_object, _, _, hid = geo
    nrec = 0
    for lane in range(rx.shape[0]):
        o, d = _camera_ray(cam, rx[lane], ry[lane])
        b = (1.0, 1.0, 1.0)
        ngl = nt = 0  # the camera's glossy and transmission bounces so far
        medium = -1
        bit = _RAY_CAMERA  # the kind of the next ray: the camera's, then the latest event's
        for depth in range(max_bounces + 1):
            pr, t, p, g, n, b1, b2 = _next_past(ray, o, d, tv, tng, tns, tri_object, hid, bit, eps)
            if pr < 0:
                break
            b = _absorbed(mats[0], mats[10], medium, tri_material[pr], d, g, t, b)
            m = tri_material[pr]
            kind = mat_kind[m]
            if kind == _DIFFUSE:
                if depth >= min_specular and receivers[tri_object[pr]]:
                    w = _neg(d)
                    for c in range(3):
                        rec[nrec, REC_P + c], rec[nrec, REC_NG + c], rec[nrec, REC_NS + c] = p[c], g[c], n[c]
                        rec[nrec, REC_W + c], rec[nrec, REC_BETA + c] = w[c], b[c]
                    rec_i[nrec, 0], rec_i[nrec, 1], rec_i[nrec, 2] = lane, depth, m
                    prior[nrec, 0], prior[nrec, 1], prior[nrec, 2] = 0, ngl, nt
                    nrec += 1
                break
            if depth >= max_bounces or not (kind == _CONDUCTOR or kind == _DIELECTRIC):
                break
            ok, dd, bb, _ = scatter1(keyed_uniform3(key, sample[lane], depth, 0), _neg(d), n, g, m, kind, mats, b,
                                     scale_eta, False)
            if not ok:
                break
            if _dot(d, g) * _dot(dd, g) < 0:  # bounces.specular_kind
                ngl += 1
                bit = _RAY_GLOSSY
            else:
                nt += 1
                bit = _RAY_TRANSMISSION
            o = _add(p, _mul(eps if _dot(dd, g) >= 0 else -eps, g))  # tracer.spawn
            medium = _medium_after(m, kind, dd, g)
            d, b = dd, bb
    return nrec


@TypedOnce
@njit(**_JIT)
def eye_lanes(rt, cam, rx, ry, sample, key, geo, receivers, mats, max_bounces, min_specular, scale_eta, eps, rec,
              rec_i, prior):
    """eye.eye_receivers' paths: from the camera (cam: CameraModel.kernel_params; rx, ry: raster
    positions, each ray starting on the near clip plane) through mirrors and glass
    (optics.scatter1, the lobe picked by keyed_uniform(key, sample[lane], depth, 0): a sample's
    path does not depend on which others are traced with it; scale_eta: radiance in physical
    units) to the first diffuse surface, recorded (rec: REC_* columns with the eye path's
    throughput; rec_i: lane, specular vertices before it, material; prior: the camera's diffuse,
    glossy and transmission bounces, Cycles' counts) where it is a receiver after at least
    min_specular specular vertices; up to max_bounces of them. Each ray passes the objects its kind
    does not meet (the camera's, then glossy or transmission: geo's Scene.hidden_kinds). Returns the
    records written and the ray counters (embree.ray_state)."""
    ray = ray_state(rt)
    nrec = _eye_rows(ray, cam, rx, ry, sample, key, geo, receivers, mats, max_bounces, min_specular, scale_eta, eps,
                     rec, rec_i, prior)
    return nrec, ray[6]


# ------------------------------------------------------------------ the light tracer's gathering
# a segment record of gather_lanes (after a specular vertex on a caster: the caller looks for
# lights on it): origin, direction, distance to the next surface (inf: none), throughput, 1 if the
# vertex it leaves reflected (a glossy ray; 0: a refraction, a transmission ray), the object of that
# vertex (Light Linking's)
SEG_O, SEG_D, SEG_T, SEG_BETA, SEG_REFL, SEG_OBJ = 0, 3, 6, 7, 10, 11
SEG_F = 12
# a vertex record (a diffuse vertex after a specular one on a caster, lit directly by the caller):
# point, geometric and shading normals, the direction back along the path, throughput x albedo, its object
VX_P, VX_NG, VX_NS, VX_W, VX_BETA, VX_OBJ = 0, 3, 6, 9, 12, 15
VX_F = 16


@njit(**_LANES)
def _gather_rows(ray, key, lane0, x0, ng0, ns0, w0, beta0, mat0, prior, geo, mats, lim, max_specular, physical,
                 count_first, want_seg, want_vx, eps, seg, seg_i, vx, vx_i):
    """gather_lanes' loop over its lanes from lane0 (its caller holds the arrays).
    Returns (the lane it stopped before: the last + 1, or one whose records did not fit; segment
    records written; vertex records written)."""
    tv, tng, tns, tri_material, mat_kind, tri_object, casters, _, hid = geo
    mat_color = mats[2]
    counts = ray[6]
    nseg = nvx = 0
    for lane in range(lane0, x0.shape[0]):
        # what to restore if this lane's records do not fit (it is traced again in the next call)
        s0, v0_, c0, c1, c2 = nseg, nvx, counts[0], counts[1], counts[KINDS]
        full = False
        p, g, n, w, b = _v(x0, lane, 0), _v(ng0, lane, 0), _v(ns0, lane, 0), _v(w0, lane, 0), _v(beta0, lane, 0)
        m = mat0[lane]
        nd, ngl, nt = prior[lane, 0], prior[lane, 1], prior[lane, 2]  # every event so far
        has_s = False  # a specular vertex on a planned caster so far
        depth = 0  # diffuse vertices after x0
        ev = 0  # the lane's events, keying its random numbers
        while True:
            # a diffuse bounce is never a caustic path's last event: it must fit the limits
            if not _fits(lim, nd + 1, ngl, nt):
                break
            ok, d, b = _diffuse_scatter(keyed_uniform(key, lane, ev, 0), keyed_uniform(key, lane, ev, 1),
                                        keyed_uniform(key, lane, ev, 2), w, g, n, _v(mat_color, m, 0), b, False)
            ev += 1
            if not ok:
                break
            if depth == 0:  # x0 under a Principled coat: what on-minus-off keeps (layer.coat_factor)
                kc = _coat_factor(mats, m, n, w, d, True)
                b = (b[0] * kc[0], b[1] * kc[1], b[2] * kc[2])
            nd += 1
            bd, bg, bt = nd, ngl, nt  # the events before the latest
            o = _add(p, _mul(eps if _dot(d, g) >= 0 else -eps, g))  # tracer.spawn
            last_caster = False
            last_obj = -1  # the latest specular vertex's object
            last_refl = False  # the latest specular event a reflection
            go_on = False  # a next diffuse vertex to bounce from
            medium = -1
            for bounce in range(max_specular + 1):
                # past what this ray's kind does not meet: the diffuse bounce's, then the latest event's
                bit = _RAY_DIFFUSE if bounce == 0 else (_RAY_GLOSSY if last_refl else _RAY_TRANSMISSION)
                pr, t, hp, hg, hn, _, _ = _next_past(ray, o, d, tv, tng, tns, tri_object, hid, bit, eps)
                if (want_seg and bounce > 0 and last_caster and (depth >= 1 or count_first)
                        and _fits(lim, bd, bg, bt)):
                    if nseg == seg.shape[0]:
                        full = True
                        break
                    for c in range(3):
                        seg[nseg, SEG_O + c], seg[nseg, SEG_D + c], seg[nseg, SEG_BETA + c] = o[c], d[c], b[c]
                    seg[nseg, SEG_T] = t
                    seg[nseg, SEG_REFL] = 1.0 if last_refl else 0.0
                    seg[nseg, SEG_OBJ] = last_obj
                    seg_i[nseg] = lane
                    nseg += 1
                if pr < 0:
                    break
                b = _absorbed(mats[0], mats[10], medium, tri_material[pr], d, hg, t, b)
                hm = tri_material[pr]
                kind = mat_kind[hm]
                if kind == _DIFFUSE:  # the next diffuse vertex
                    depth += 1
                    p, g, n, w, m = hp, hg, hn, _neg(d), hm
                    b = _mul(_tab_weight(mats[6], m, _dot(w, n)), b)  # under its glossy layer, towards w
                    if want_vx and has_s and _fits(lim, nd, ngl, nt):  # direct light: every event before fits
                        if nvx == vx.shape[0]:
                            full = True
                            break
                        a = _v(mat_color, m, 0)
                        for c in range(3):
                            vx[nvx, VX_P + c], vx[nvx, VX_NG + c], vx[nvx, VX_NS + c] = p[c], g[c], n[c]
                            vx[nvx, VX_W + c], vx[nvx, VX_BETA + c] = w[c], b[c] * a[c]
                        vx[nvx, VX_OBJ] = tri_object[pr]
                        vx_i[nvx] = lane
                        nvx += 1
                    go_on = True
                    break
                if not (kind == _CONDUCTOR or kind == _DIELECTRIC) or bounce == max_specular:
                    break
                ok, dd, bb, _ = scatter1(keyed_uniform3(key, lane, ev, 0), _neg(d), hn, hg, hm, kind, mats, b,
                                         physical, False)
                ev += 1
                if not ok:
                    break
                last_obj = tri_object[pr]
                last_caster = casters[last_obj]
                has_s = has_s or last_caster
                bd, bg, bt = nd, ngl, nt
                last_refl = _dot(d, hg) * _dot(dd, hg) < 0  # bounces.specular_kind
                if last_refl:
                    ngl += 1
                else:
                    nt += 1
                if not _fits(lim, bd, bg, bt):  # the events before the latest no longer fit
                    break
                o = _add(hp, _mul(eps if _dot(dd, hg) >= 0 else -eps, hg))
                medium = _medium_after(hm, kind, dd, hg)
                d, b = dd, bb
            if full or not go_on:
                break
        if full:
            counts[0], counts[1], counts[KINDS] = c0, c1, c2
            return lane, s0, v0_
    return x0.shape[0], nseg, nvx


@TypedOnce
@njit(**_JIT)
def gather_lanes(rt, key, lane0, x0, ng0, ns0, w0, beta0, mat0, prior, geo, mats, lim, max_specular, physical,
                 count_first, want_seg, want_vx, eps, seg, seg_i, vx, vx_i):
    """indirect.gather's paths for the light tracer (no walks to connect): from each receiver x0
    (x0, ng0, ns0, w0: the direction back to the eye, beta0: the eye path's throughput, mat0, prior:
    the camera's events before x0), cosine bounces with Russian roulette (_diffuse_scatter)
    through up to max_specular mirrors and glass (optics.scatter1, not adjoint; physical:
    scale_eta) to the next diffuse vertices, within the Light Paths limits (lim: Limits.array()),
    every ray cast here, the random numbers keyed_uniform(key, lane, event, .).

    Writes, for the caller to light: with want_seg, the segments right after a specular vertex
    on a caster (seg: SEG_* columns; seg_i: the lane) from x0 when count_first, else from later
    diffuse vertices, whose events before the latest fit; with want_vx, the later diffuse
    vertices with a specular vertex on a caster behind them whose events fit (vx: VX_* columns,
    the throughput times the vertex's albedo; vx_i: the lane). A lane whose records would not
    fit is left whole for the next call. Returns (the lane to go on from, x0's length when done;
    segments written; vertices written; the ray counters, embree.ray_state)."""
    ray = ray_state(rt)
    nxt, nseg, nvx = _gather_rows(ray, key, lane0, x0, ng0, ns0, w0, beta0, mat0, prior, geo, mats, lim,
                                  max_specular, physical, count_first, want_seg, want_vx, eps, seg, seg_i, vx, vx_i)
    return nxt, nseg, nvx, ray[6]
