"""Compiled (numba) per-lane kernels of the manifold walk: the Newton step of a chain, and a
chain vertex from a ray hit. Issue 11: the walks spent their time on numpy's per-call overhead
(dozens of tiny (N,3) operations per Newton step on a few hundred lanes), not on rays.

Each kernel is a loop over lanes doing, per lane, the same IEEE operations in the same order
as the numpy reference it replaces (constraints.blocks + block_solve, geometry.vertex_from_hits,
tracer.intersect's float64 re-computation, constraints.specular_map, walk.propagate's checks);
no fastmath, so results agree with the reference to rounding (tests/test_kernels.py). Degenerate
input gives ok False and zeros, never an exception (error_model="numpy": x / 0 is inf or NaN
as in numpy, and the ok flags catch it).

Compiled on first use and cached on disk (cache=True; numba falls back to a user cache folder
when the package folder is read-only). nogil: threads can run lanes side by side.

Chain vertices are packed: F (N, k, NF) float64 with the columns below, I (N, k, 3) int64
(prim, obj, mat).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

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

_JIT = dict(cache=True, nogil=True, error_model="numpy")


def _cache_per_module_name():
    """Keep one disk cache per name this module is imported under. numba's cache is keyed by
    the source file, but a cached kernel rebuilds its environment by importing the module by the
    name it was compiled under: the same file imported as smbs_addon.kernels (command line) and
    as bl_ext.<repo>.smbs_caustics.smbs_addon.kernels (Blender) would each fail to load the
    other's entries (ModuleNotFoundError). The module's name goes into the cache file names."""
    try:
        import hashlib

        from numba.core import caching
    except ImportError:  # pragma: no cover - numba's layout changed: default caching
        return
    name = __name__

    class Locator(caching._CacheLocator):
        def __init__(self, inner):
            self._inner = inner
            self._tag = hashlib.sha1(name.encode()).hexdigest()[:10]

        def ensure_cache_path(self):
            self._inner.ensure_cache_path()

        def get_cache_path(self):
            return self._inner.get_cache_path()

        def get_source_stamp(self):
            return self._inner.get_source_stamp()

        def get_disambiguator(self):
            return f"{self._inner.get_disambiguator()}-{self._tag}"

        @classmethod
        def from_function(cls, py_func, py_file):
            if getattr(py_func, "__module__", None) != name:
                return None
            for base in caching.CacheImpl._locator_classes:
                if base is not cls and not getattr(base, "_smbs_per_module", False):
                    inner = base.from_function(py_func, py_file)
                    if inner is not None:
                        return cls(inner)
            return None

    Locator._smbs_per_module = True
    caching.CacheImpl._locator_classes.insert(0, Locator)


_cache_per_module_name()

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



# ------------------------------------------------------------------ borrowed arrays
@intrinsic
def _borrowed(typingctx, tup):
    """The arrays of a tuple (or one array) without their reference to the memory they view
    (numba's meminfo set to NULL; other items as they are). numba counts references to an array
    each time a variable takes it, a tuple is unpacked or an inlined per-lane helper receives it
    (an atomic increment and decrement per array and lane, which its pruning pass leaves where
    the helper branches): a third of a Newton iteration's time in walk_iterate and pool_advance.
    A borrowed array's counts do nothing. Only for arrays owned by someone else for as long as
    the borrowed ones are used: the arguments of the (not inlined) kernel that borrows them,
    which its caller holds; never returned or stored."""
    items = tup.types if isinstance(tup, types.BaseTuple) else (tup,)
    if not all(isinstance(t, (types.Array, types.Number, types.Boolean)) for t in items):
        return None  # anything else counted by reference would be released once too often

    def one(context, builder, ty, v):
        if not isinstance(ty, types.Array):
            return v
        a = context.make_array(ty)(context, builder, value=v)
        a.meminfo = cgutils.get_null_value(a.meminfo.type)
        a.parent = cgutils.get_null_value(a.parent.type)
        return a._getvalue()

    def codegen(context, builder, sig, args):
        ty, v = sig.args[0], args[0]
        if isinstance(ty, types.BaseTuple):
            return context.make_tuple(builder, sig.return_type, [
                one(context, builder, t, builder.extract_value(v, i)) for i, t in enumerate(ty.types)])
        return one(context, builder, ty, v)

    return tup(tup), codegen


# ------------------------------------------------------------------ 3-vectors as tuples
@njit(inline="always", **_JIT)
def _v(a, i, off):
    return (a[i, off], a[i, off + 1], a[i, off + 2])


@njit(inline="always", **_JIT)
def _vk(F, i, j, off):
    return (F[i, j, off], F[i, j, off + 1], F[i, j, off + 2])


@njit(inline="always", **_JIT)
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(inline="always", **_JIT)
def _add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit(inline="always", **_JIT)
def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(inline="always", **_JIT)
def _mul(s, a):
    return (s * a[0], s * a[1], s * a[2])


@njit(inline="always", **_JIT)
def _div(a, s):
    return (a[0] / s, a[1] / s, a[2] / s)


@njit(inline="always", **_JIT)
def _neg(a):
    return (-a[0], -a[1], -a[2])


@njit(inline="always", **_JIT)
def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(inline="always", **_JIT)
def _normalize(a):
    """vec.normalize: times 1/|a|, zero stays zero."""
    n = math.sqrt(_dot(a, a))
    inv = 1.0 / n if n > 0 else 0.0
    return (a[0] * inv, a[1] * inv, a[2] * inv)


@njit(inline="always", **_JIT)
def _max(a, b):
    """np.maximum: NaN propagates."""
    if a != a:
        return a
    return a if a >= b else b


@njit(inline="always", **_JIT)
def _frame(n):
    """vec.frame."""
    sign = 1.0 if n[2] >= 0 else -1.0
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    s = (1.0 + sign * n[0] ** 2 * a, sign * b, -sign * n[0])
    t = (b, sign + n[1] ** 2 * a, -n[1])
    return s, t


# ------------------------------------------------------------------ reflection / refraction
@njit(inline="always", **_JIT)
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
            e1, e2 = _frame(wo)
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
            if j > 0:
                a = _vk(F, lane, j - 1, S if col == 0 else T)
                B[j, 0, col], B[j, 1, col] = _dC(hv, refract, wi, pre, e1, e2, eta_i, eta_o, h, lh, s2, t2,
                                                 hn, _unit_d(wi, li, a), zero, zero)
            else:
                B[j, 0, col] = B[j, 1, col] = 0.0
            if j < k - 1:
                a = _vk(F, lane, j + 1, S if col == 0 else T)
            else:
                a = _v(lys, lane, 0) if col == 0 else _v(lyt, lane, 0)
            dwo = _unit_d(wo, lo, a) if has_lo else a
            D[j, 0, col], D[j, 1, col] = _dC(hv, refract, wi, pre, e1, e2, eta_i, eta_o, h, lh, s2, t2, hn,
                                             zero, zero, dwo)
    return ok


# 2x2 matrices as tuples (m00, m01, m10, m11): held in registers. A view of a (k, 2, 2) array
# (A[j]) takes a reference to the array's memory (an atomic increment and decrement in numba's
# runtime) each time it is made, a tenth of a Newton iteration's time when made per lane.
@njit(inline="always", **_JIT)
def _m2(M, j):
    return (M[j, 0, 0], M[j, 0, 1], M[j, 1, 0], M[j, 1, 1])


@njit(inline="always", **_JIT)
def _put2(M, j, v):
    M[j, 0, 0], M[j, 0, 1], M[j, 1, 0], M[j, 1, 1] = v


@njit(inline="always", **_JIT)
def _sub2(X, Y):
    return (X[0] - Y[0], X[1] - Y[1], X[2] - Y[2], X[3] - Y[3])


@njit(inline="always", **_JIT)
def _inv2(M):
    """constraints.inv2 of one 2x2: (inverse, ok)."""
    a, b, c, d = M
    det = a * d - b * c
    scale = a * a + b * b + c * c + d * d
    ok = abs(det) > 1e-12 * scale
    inv_det = 1.0 / det if ok else 0.0
    return (d * inv_det, -b * inv_det, -c * inv_det, a * inv_det), ok


@njit(inline="always", **_JIT)
def _mm(X, Y):
    return (X[0] * Y[0] + X[1] * Y[2], X[0] * Y[1] + X[1] * Y[3],
            X[2] * Y[0] + X[3] * Y[2], X[2] * Y[1] + X[3] * Y[3])


@njit(inline="always", **_JIT)
def _copy_rows(dst, i, src, m):
    """dst[i] = src[m] for (N, a, b) arrays, element by element: numba's slice assignment costs
    ~50-100 ns per call on these small rows (views and a generic loop), more than the copy."""
    for j in range(src.shape[1]):
        for c in range(src.shape[2]):
            dst[i, j, c] = src[m, j, c]


@njit(inline="always", **_JIT)
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
        ok = _lane_blocks(hv, kinds, x0, F, etas, ly, lys, lyt, directional, i, C, A, B, D)
        _zero_rhs(rhs, k)
        if mode == 0:
            for j in range(k):
                rhs[j, 0, 0], rhs[j, 1, 0] = C[j, 0], C[j, 1]
        else:
            for r in range(2):
                for c in range(2):
                    rhs[k - 1, r, c] = -D[k - 1, r, c]
        oks_ = _lane_solve(A, B, D, rhs, Li, Y, X)
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
    _borrowed)."""
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


# ------------------------------------------------------------------ a vertex from a ray hit
@njit(**_JIT)
def propagate_step(refract, last, j, act, o, d, prev, exact, prim, t32, tv, tng, tns, eps,
                   tri_material, mat_kind, tri_object, casters, mat_ior, F, I, status, out):
    """walk.propagate's work after the intersect call for vertex j, per lane (rows act of the
    chain's F, I, status, out): tracer.intersect's float64 hit point (the plane of the hit
    triangle re-intersected from prev, the ray's true start, when exact, else from o),
    geometry.vertex_from_hits, the material checks, the reflection or refraction of
    w_in = normalize(prev - p) and the side checks. Writes the walk outcome to status, the
    vertex to F and I where it is kept (valid, or at the last vertex TIR or SIDE), the unit
    outgoing direction to out; returns the lanes that go on (act, the next ray's offset origin
    and direction, the vertex)."""
    M = o.shape[0]
    nxt = np.zeros(M, np.int64)
    o_next = np.zeros((M, 3))
    d_next = np.zeros((M, 3))
    p_next = np.zeros((M, 3))
    cnt = 0
    for i in range(M):
        lane = act[i]
        pr = prim[i]
        if pr < 0:
            status[lane] = _MISS
            continue
        # tracer.intersect: the hit re-computed in float64
        oi = _v(prev, i, 0) if exact else _v(o, i, 0)
        di = _v(d, i, 0)
        tt = t32[i]
        if exact:
            tt = tt + _dot(_sub(_v(o, i, 0), oi), di)
        g = _v(tng, pr, 0)
        v0 = (tv[pr, 0, 0], tv[pr, 0, 1], tv[pr, 0, 2])
        v1 = (tv[pr, 1, 0], tv[pr, 1, 1], tv[pr, 1, 2])
        v2 = (tv[pr, 2, 0], tv[pr, 2, 1], tv[pr, 2, 2])
        den = _dot(di, g)
        num = _dot(_sub(v0, oi), g)
        ti = num / den if abs(den) > 1e-12 else tt
        if not math.isfinite(ti) or abs(ti - tt) > 1e-3 * abs(tt) + eps:
            ti = tt
        p = _add(oi, _mul(ti, di))
        e1, e2, q = _sub(v1, v0), _sub(v2, v0), _sub(p, v0)
        d11, d12, d22 = _dot(e1, e1), _dot(e1, e2), _dot(e2, e2)
        q1, q2 = _dot(q, e1), _dot(q, e2)
        det = d11 * d22 - d12 * d12
        if det > 0:
            inv = 1.0 / det
            b1 = (d22 * q1 - d12 * q2) * inv
            b2 = (d11 * q2 - d12 * q1) * inv
        else:
            b1 = b2 = 1.0 / 3.0
        # geometry.vertex_from_hits
        s = _normalize(e1)
        t = _cross(g, s)
        c0 = (tns[pr, 0, 0], tns[pr, 0, 1], tns[pr, 0, 2])
        c1 = (tns[pr, 1, 0], tns[pr, 1, 1], tns[pr, 1, 2])
        c2 = (tns[pr, 2, 0], tns[pr, 2, 1], tns[pr, 2, 2])
        b0 = 1.0 - b1 - b2
        nraw = _add(_add(_mul(b0, c0), _mul(b1, c1)), _mul(b2, c2))
        ln = math.sqrt(_dot(nraw, nraw))
        good = ln > 1e-3
        n = _div(nraw, ln) if good else g
        dns = dnt = (0.0, 0.0, 0.0)
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
        w_in = _normalize(_sub(_v(prev, i, 0), p))
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
            continue
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
            continue
        out[lane, 0], out[lane, 1], out[lane, 2] = wn
        if code != _OK:
            continue
        side = 1.0 if _dot(wn, g) >= 0 else -1.0
        on = _add(p, _mul(eps * side, g))
        nxt[cnt] = lane
        for c in range(3):
            o_next[cnt, c] = on[c]
            d_next[cnt, c] = wn[c]
            p_next[cnt, c] = p[c]
        cnt += 1
    return nxt[:cnt], o_next[:cnt], d_next[:cnt], p_next[:cnt]


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
_SINGULAR, _MAX_ITER = 7, 8


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


@njit(inline="always", **_JIT)
def _spawn_aim1(x0, g, d, target, eps):
    """tracer.spawn of x0 (normal g) towards d, and the unit direction from there to target."""
    side = 1.0 if _dot(d, g) >= 0 else -1.0
    on = _add(x0, _mul(eps * side, g))
    return on, _normalize(_sub(target, on))


@njit(**_JIT)
def spawn_aim(x0, ng0, d, target, eps):
    """tracer.spawn of x0 towards d, and the unit direction from that origin to target."""
    M = x0.shape[0]
    o = np.zeros((M, 3))
    dirs = np.zeros((M, 3))
    for i in range(M):
        on, w = _spawn_aim1(_v(x0, i, 0), _v(ng0, i, 0), _v(d, i, 0), _v(target, i, 0), eps)
        for c in range(3):
            o[i, c] = on[c]
            dirs[i, c] = w[c]
    return o, dirs


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


_DROP, _CONVERGED, _PROPOSE = 0, 1, 2


@njit(**_JIT)
def _iterate_rows(slots, has_new, last_it, nF, nI, nstatus, nout, ul_new, cfg, lane, state, scratch, outputs):
    """One Newton iteration of the lanes slots[m] (rows m with slots[m] >= 0; has_new[m]: row m
    of the proposal chain nF/nI/nstatus/nout and ul_new is that lane's last proposal, to accept
    or reject; last_it[m]: its last iteration): the acceptance (_lane_update), the convergence
    test, MAX_ITER at the last iteration, the small mutation (_lane_newton), SMBS's trigger and
    large mutation (_lane_trigger, _lane_large), the singular test, and the proposal's ray
    (_spawn_aim1). Writes per row what (_DROP, _CONVERGED or _PROPOSE) and, for a proposal, its
    ray's offset origin and direction, large or not, its trigger. The settings, lane inputs and
    state (cfg, lane, state: tuples, see walk.newton_walk), the work arrays (scratch:
    _lane_scratch) and the outputs (what, ray origins, directions, large, trigger: _row_outputs)
    are unpacked once, before the loop, and borrowed (_borrowed): not inlined, so that its caller
    holds every array it uses."""
    nF, nI, nstatus, nout, ul_new, slots, has_new, last_it = _borrowed((nF, nI, nstatus, nout, ul_new, slots,
                                                                        has_new, last_it))
    (hv, kinds, smbs, tir_on, backlit_on, slow_on, tir_rejected, backlit_at, tau, slow_run, min_beta,
     threshold, max_step, eps, max_halvings) = _borrowed(cfg)
    x0, ng0, ly, lys, lyt, directional, etas, large_ok, obj_lo, obj_hi = _borrowed(lane)
    F, I, out_dir, err, front, valid, beta, lscale, pending, slow_n, outcome, converged, mutations = _borrowed(state)
    C, A, B, D, rhs, Li, Y, X = _borrowed(scratch)
    what, o_out, d_out, ul_out, tr_out = _borrowed(outputs)
    for m in range(slots.shape[0]):
        i = slots[m]
        what[m] = _DROP
        if i < 0:
            continue
        if has_new[m]:
            e, f = _lane_mismatch(nF, m, nout, ly, i, directional)
            if not _lane_update(m, i, nF, nI, nstatus, nout, e, f, ul_new[m], smbs, tir_on, slow_on, tir_rejected,
                                tau, slow_run, min_beta, F, I, out_dir, err, front, valid, beta, lscale, pending,
                                slow_n, outcome):
                continue
        if err[i] < threshold and front[i] and valid[i]:
            converged[i] = True
            what[m] = _CONVERGED
            continue
        if last_it[m]:
            outcome[i] = _MAX_ITER
            continue
        ok, p, d = _lane_newton(i, hv, kinds, x0, F, etas, ly, lys, lyt, directional, beta, max_step,
                                C, A, B, D, rhs, Li, Y, X)
        ul = False
        tr = _NONE
        if smbs:
            tr = _lane_trigger(i, kinds, backlit_at, backlit_on, x0, F, ly, directional, pending)
            if tr != _NONE and large_ok[i]:
                dl, okl = _lane_large(i, kinds, x0, F, I, etas, ly, directional, obj_lo, obj_hi, lscale,
                                      max_halvings)
                if okl:
                    ul = True
                    d = dl
                    p = _add(_v(x0, i, 0), dl)
        if not (ok or ul):
            outcome[i] = _SINGULAR
            continue
        mutations[i] += 1
        on, w = _spawn_aim1(_v(x0, i, 0), _v(ng0, i, 0), d, p, eps)
        what[m] = _PROPOSE
        ul_out[m] = ul
        tr_out[m] = tr
        for c in range(3):
            o_out[m, c] = on[c]
            d_out[m, c] = w[c]


@njit(inline="always", **_JIT)
def _row_outputs(M):
    """what, ray origin, ray direction, large, trigger per row (_iterate_rows)."""
    return (np.zeros(M, np.int8), np.zeros((M, 3)), np.zeros((M, 3)), np.zeros(M, np.bool_),
            np.zeros(M, np.int64))


@njit(inline="always", **_JIT)
def _put_ray(rows, o_out, d_out, cnt, lane, on, w):
    """Row cnt of a kernel's rays: the lane, the ray's offset origin and direction."""
    rows[cnt] = lane
    for c in range(3):
        o_out[cnt, c] = on[c]
        d_out[cnt, c] = w[c]


@TypedOnce
@njit(**_JIT)
def walk_iterate(act, has_new, last_it, nF, nI, nstatus, nout, use_large, cfg, lane, state):
    """One Newton iteration of walk.newton_walk for lanes act (_iterate_rows: the acceptance of
    the last proposals, has_new: row m of the proposal chain nF/nI/nstatus/nout and use_large
    belongs to lane act[m]; the convergence test; MAX_ITER at the last iteration, last_it; the
    small and large mutations; the proposal's ray). cfg, lane and state: walk.newton_walk's
    settings, per-lane input and state (tuples, see there). Returns the lanes that propose, their
    rays' offset origins and directions, which proposals are large, and the large mutations per
    trigger (4,)."""
    M = act.shape[0]
    outputs = _row_outputs(M)
    new = np.full(M, has_new)
    # before the first proposals use_large is empty; _iterate_rows reads ul_new[m] only where has_new[m]
    ul_new = use_large if has_new else new
    _iterate_rows(act, new, np.full(M, last_it), nF, nI, nstatus, nout, ul_new, cfg, lane, state,
                  _lane_scratch(cfg[1].shape[0]), outputs)
    what, o_row, d_row, ul_row, tr_row = outputs
    nxt = np.zeros(M, np.int64)
    o_out = np.zeros((M, 3))
    d_out = np.zeros((M, 3))
    ul_out = np.zeros(M, np.bool_)
    counts = np.zeros(4, np.int64)
    cnt = 0
    for m in range(M):
        if what[m] != _PROPOSE:
            continue
        if ul_row[m]:
            counts[tr_row[m]] += 1
        ul_out[cnt] = ul_row[m]
        _put_ray(nxt, o_out, d_out, cnt, act[m], _v(o_row, m, 0), _v(d_row, m, 0))
        cnt += 1
    return nxt[:cnt], o_out[:cnt], d_out[:cnt], ul_out[:cnt], counts


# ------------------------------------------------------------------ the lane pool (Bernoulli trials)
_GOLD = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_SEEDING, _WALKING = 1, 2
_SEED_OBJECT = 6


@njit(inline="always", **_JIT)
def _mix64(z):
    """splitmix64's finaliser (Steele, Lea and Flood 2014)."""
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


@njit(inline="always", **_JIT)
def keyed_uniform(key, a, b, dim):
    """A uniform number in [0, 1) that depends only on (key, a, b, dim): counter-based, so a
    trial's random numbers do not depend on when or on which thread it runs."""
    z = _mix64(np.uint64(key) + _GOLD * np.uint64(a + 1))
    z = _mix64(z + _GOLD * np.uint64(b + 1))
    z = _mix64(z + _GOLD * np.uint64(dim + 1))
    return np.float64(z >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@TypedOnce
@njit(**_JIT)
def pool_advance(rows, nF, nI, nstatus, nout, ul_new, cfg, lane, state, pool, mat_ior, d1, obj1, uniqueness,
                 max_iterations):
    """The lane pool's work on the chains traced last (row m for pool slot rows[m]): a seed chain
    starts its slot's walk (walk.newton_walk's set-up, SEED_OBJECT where it landed off the
    caster it aimed at), a walked one goes through _iterate_rows. Returns the slots that cast next
    (their rays' offset origins and directions, large or not), and the trials that ended:
    (slot, whether it found the solution of its sample (d1, obj1: the first segment's direction
    and the first vertex's object, estimators.same_solution)), and the proposals made."""
    x0, ng0, ly, lys, lyt, directional, etas, large_ok, obj_lo, obj_hi = lane
    F, I, out_dir, err, front, valid, beta, lscale, pending, slow_n, outcome, converged, mutations = state
    phase, it, want_obj, sample, trial = pool
    smbs_tir = cfg[2] and cfg[3]
    M = rows.shape[0]
    k = cfg[1].shape[0]
    slots = rows.copy()  # -1: a seed that ends here
    has_new = np.ones(M, np.bool_)
    last_it = np.zeros(M, np.bool_)
    for m in range(M):
        s = rows[m]
        if phase[s] == _SEEDING:
            has_new[m] = False
            st = nstatus[m]
            if st == _OK and nI[m, 0, OBJ] != want_obj[s]:
                st = _SEED_OBJECT
            _copy_rows(F, s, nF, m)
            _copy_rows(I, s, nI, m)
            for c in range(3):
                out_dir[s, c] = nout[m, c]
            for j in range(k):
                etas[s, j] = mat_ior[I[s, j, MAT]]
            err[s], front[s] = _lane_mismatch(F, s, out_dir, ly, s, directional)
            valid[s] = st == _OK
            beta[s] = 1.0
            lscale[s] = 1.0
            pending[s] = _NONE
            slow_n[s] = 0
            converged[s] = False
            mutations[s] = 0
            outcome[s] = _OK
            walkable = st == _OK or st == _SIDE
            if smbs_tir and st == _TIR and large_ok[s]:  # as newton_walk: a TIR seed mutates first
                pending[s] = _TRIG_TIR
                err[s] = np.inf
                front[s] = False
                walkable = True
            phase[s] = _WALKING
            it[s] = 0
            if not walkable:
                slots[m] = -1
                continue
        last_it[m] = it[s] == max_iterations
    outputs = _row_outputs(M)
    _iterate_rows(slots, has_new, last_it, nF, nI, nstatus, nout, ul_new, cfg, lane, state, _lane_scratch(k),
                  outputs)
    what, o_row, d_row, ul_row, tr_row = outputs
    nxt = np.zeros(M, np.int64)
    o_out = np.zeros((M, 3))
    d_out = np.zeros((M, 3))
    ul_out = np.zeros(M, np.bool_)
    ended = np.zeros(M, np.int64)
    found = np.zeros(M, np.bool_)
    cnt = 0
    n_end = 0
    steps = 0
    for m in range(M):
        s = rows[m]
        if slots[m] >= 0:
            it[s] += 1
            if what[m] == _PROPOSE:
                steps += 1
                ul_out[cnt] = ul_row[m]
                _put_ray(nxt, o_out, d_out, cnt, s, _v(o_row, m, 0), _v(d_row, m, 0))
                cnt += 1
                continue
        ended[n_end] = s
        if what[m] == _CONVERGED:
            d2 = _normalize(_sub(_vk(F, s, 0, P), _v(x0, s, 0)))
            p = sample[s]
            found[n_end] = abs(_dot(d2, _v(d1, p, 0)) - 1.0) < uniqueness and I[s, 0, OBJ] == obj1[p]
        n_end += 1
    return nxt[:cnt], o_out[:cnt], d_out[:cnt], ul_out[:cnt], ended[:n_end], found[:n_end], steps


@TypedOnce
@njit(**_JIT)
def pool_refill(ended, found_end, pool, lane, samples, seeds, key, p0, max_trials, max_parallel, defensive, smbs,
                eps):
    """The lane pool's bookkeeping, on one thread: the trials that ended (slots ended; found_end:
    they found their sample's solution) free their slots and lower their sample's first
    success; then every free slot takes the next trial of a sample that still needs one (trials
    in order per sample; at most max_parallel of a sample at once, and no more than one plus
    half the number of its trials that ended: a sample whose trial t succeeds needs none after
    t, so trials run side by side only for samples that have needed many). A trial's seed ray aims
    at a uniform point on the casters (manifold.Seeder.directions for SMS), its random numbers
    keyed by (key, p0 + sample, trial) (p0: the block's first sample in the batch): whichever
    slot, block or thread runs it, trial t of a sample walks the same way, so each sample's
    first success (and the image) does not depend on the scheduling. New trials take the
    lowest free slots. Returns the slots that cast a seed ray, the rays' offset origins and
    directions."""
    phase, it, want_obj, sample, trial = pool
    x0, ng0, ly, lys, lyt, directional, etas, large_ok, obj_lo, obj_hi = lane
    sx0, sng, sly, first, next_trial, inflight, active, free, cur = samples
    cdf, total, tv, tobj = seeds
    for e in range(ended.shape[0]):
        s = ended[e]
        p = sample[s]
        inflight[p] -= 1
        if found_end[e] and trial[s] < first[p]:
            first[p] = trial[s]
        phase[s] = 0
    # the free slots, lowest first: the busy slots stay packed at the front of the pool's arrays,
    # which stay in cache when few lanes are busy
    n_free = 0
    for s in range(phase.shape[0]):
        if phase[s] == 0:
            free[n_free] = s
            n_free += 1
    rows = np.zeros(n_free, np.int64)
    o_out = np.zeros((n_free, 3))
    d_out = np.zeros((n_free, 3))
    cnt = 0
    while cnt < n_free and cur[0] > 0:
        got = -1
        scanned = 0
        while scanned < cur[0] and cur[0] > 0:
            if cur[1] >= cur[0]:
                cur[1] = 0
            p = active[cur[1]]
            if next_trial[p] >= min(first[p], max_trials):  # needs no more trials, ever
                cur[0] -= 1
                active[cur[1]] = active[cur[0]]
                continue
            cur[1] += 1
            scanned += 1
            if inflight[p] < min(max_parallel, 1 + (next_trial[p] - inflight[p]) // 2):  # 1 + half the trials ended
                got = p
                break
        if got < 0:
            break
        p = got
        s = free[cnt]
        t = next_trial[p]
        next_trial[p] += 1
        inflight[p] += 1
        sample[s], trial[s], phase[s], it[s] = p, t, _SEEDING, 0
        for c in range(3):
            x0[s, c], ng0[s, c], ly[s, c] = sx0[p, c], sng[p, c], sly[p, c]
        u0 = keyed_uniform(key, p0 + p, t, 0)
        u1 = keyed_uniform(key, p0 + p, t, 1)
        u2 = keyed_uniform(key, p0 + p, t, 2)
        tri = min(np.searchsorted(cdf, u0 * total, side="right"), cdf.shape[0] - 1)
        su = math.sqrt(u1)
        b0, b1, b2 = 1 - su, su * (1 - u2), su * u2
        q = (b0 * tv[tri, 0, 0] + b1 * tv[tri, 1, 0] + b2 * tv[tri, 2, 0],
             b0 * tv[tri, 0, 1] + b1 * tv[tri, 1, 1] + b2 * tv[tri, 2, 1],
             b0 * tv[tri, 0, 2] + b1 * tv[tri, 1, 2] + b2 * tv[tri, 2, 2])
        xs = _v(x0, s, 0)
        d = _normalize(_sub(q, xs))
        want_obj[s] = tobj[tri]
        large_ok[s] = keyed_uniform(key, p0 + p, t, 3) >= defensive if smbs else True
        g = _v(ng0, s, 0)
        side = 1.0 if _dot(d, g) >= 0 else -1.0
        on = _add(xs, _mul(eps * side, g))
        _put_ray(rows, o_out, d_out, cnt, s, on, d)
        cnt += 1
    return rows[:cnt], o_out[:cnt], d_out[:cnt]


# ------------------------------------------------------------------ the film
@njit(inline="always", **_JIT)
def _blackman_harris(x, r):
    """film.blackman_harris of one offset (r already at least 0.5)."""
    if not abs(x) <= r:
        return 0.0
    v = 2.0 * math.pi * (x / (2.0 * r) + 0.5)
    h = 0.35875 - 0.48829 * math.cos(v) + 0.14128 * math.cos(2 * v) - 0.01168 * math.cos(3 * v)
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
    samples in order (one thread: the sums' order, and so the image, are fixed)."""
    wx = np.zeros(2 * k + 1)
    for i in range(rx.shape[0]):
        fx = math.floor(rx[i])
        fy = math.floor(ry[i])
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
