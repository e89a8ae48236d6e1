"""Reflection, refraction, Fresnel and the specular scatter of a path, per lane.

Convention: ``w`` points AWAY from the surface (towards where light comes
from or goes to), ``n`` is a unit normal (either side). Results point away from
the surface on the other side of the interaction.

Each function is written once, per lane, compiled with numba (jit.py), and called by the
kernels of the light paths (scatter_rows: the light tracer, the eye pass, the hand-off, the
photon pre-pass) and, through the array wrappers below, by the plan and the estimators.
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from ..core.jit import JIT, LANES
from ..core.vec3 import dot1 as _dot, row3 as _row3
from ..scene import arrays as S
from ..scene.arrays import DIELECTRIC
from .coat import coat, coat_factors, gain_table, spec_table, table
from .energy import cached_energy_tables, energy_gain1
from .fresnel import film, film1, material1, metal, metal1, specular_weights1, surface_tables
from .microfacet import alphas, lambda1, visible_normal1

# The scene's material tables as the kernels read them (materials()), per material: its kind
# (scene.DIFFUSE...), Fresnel model (scene.FRESNEL_*), colour and reflection tint (M,3), IOR (the
# five of fresnel.SurfaceTables); Bump Map Correction (1: on); a Principled coat's tables (coat.py)
# by the eye's cosine (M, MU_STEPS + 1): the diffuse's weight under its glossy coat and clear coat
# (weight), the glossy coat's multiple-scattering gain (gain), the coats themselves (Scene.mat_layer,
# (M, coat.COLUMNS): layer), the diffuse's weight under its glossy coat alone (glossy_weight); each
# glass's absorption (M,3); the rough mirrors' and glass's GGX alpha (0: a perfect one) and
# Multiscatter GGX's factors (microfacet.py, energy.py); a metal's Fresnel beyond its colour (M,6)
# and a thin film (M,2) (fresnel.metal, fresnel.film: (0, .) where the scene has none)
MaterialTables = namedtuple("MaterialTables", "kind fresnel color reflect_color ior bump_correction weight gain "
                                              "layer glossy_weight absorb alpha energy metal film")


# ------------------------------------------------------------------ per lane
@njit(**JIT)
def reflect1(w, n):
    """Mirror w about n: 2 (w.n) n - w."""
    c = 2.0 * _dot(w, n)
    return (c * n[0] - w[0], c * n[1] - w[1], c * n[2] - w[2])


@njit(**JIT)
def refract1(w, n, eta):
    """Refract w through an interface with relative IOR eta = n_inside / n_outside, where n
    points to the outside: (direction, ok); ok False on total internal reflection (the
    direction is then zero, never NaN)."""
    c = _dot(w, n)
    outside = c >= 0
    eta_r = 1.0 / eta if outside else eta  # n_from / n_to
    nn = n if outside else (-n[0], -n[1], -n[2])
    c = abs(c)
    r2 = 1.0 - eta_r**2 * (1.0 - c * c)
    if not r2 > 0.0:
        return (0.0, 0.0, 0.0), False
    r = math.sqrt(r2)
    return (-eta_r * (w[0] - c * nn[0]) - r * nn[0], -eta_r * (w[1] - c * nn[1]) - r * nn[1],
            -eta_r * (w[2] - c * nn[2]) - r * nn[2]), True


@njit(inline="always", **JIT)  # inlined: as a plain njit, LLVM left a call to it in scatter1 (jit.py)
def valid_reflection1(ng, wi, n):
    """Cycles' Bump Map Correction for mirrors and glass (ensure_valid_specular_reflection,
    kernel/closure/bsdf_util.h; Material > Settings > Bump Map Correction, on by default): where
    the mirror image of wi about the shading normal n would leave the surface lower than
    min(0.9 wi.ng, 0.01) above it, n is turned towards ng, in their plane, just far enough to
    put it there. ng faces wi (wi: the unit direction back along the eye's path). Cycles bends
    every smooth-shaded specular closure's normal so, for reflection and refraction alike: the
    light then arrives along the bent normal's mirror image, at that height, whatever wi was
    below it. Returns (the normal to scatter about, whether it was bent)."""
    c = 2.0 * _dot(n, wi)
    iz = _dot(wi, ng)
    thr = min(0.9 * iz, 0.01)
    if c * _dot(n, ng) - iz >= thr:  # ng . reflect1(wi, n)
        return n, False
    nn = _dot(n, ng)
    x = (n[0] - nn * ng[0], n[1] - nn * ng[1], n[2] - nn * ng[2])
    lx = math.sqrt(_dot(x, x))
    x = (x[0] / lx, x[1] / lx, x[2] / lx) if lx > 0 else n
    ix = _dot(wi, x)
    a = ix * ix + iz * iz
    if not a > 0:
        return ng, True
    b = 2.0 * (a + iz * thr)
    disc = math.sqrt(max(b * b - 4.0 * a * (thr + iz) ** 2, 0.0))
    nz2 = 0.25 * (b + disc) / a if ix < 0 else 0.25 * (b - disc) / a
    nx, nz = math.sqrt(max(1.0 - nz2, 0.0)), math.sqrt(max(nz2, 0.0))
    return (nx * x[0] + nz * ng[0], nx * x[1] + nz * ng[1], nx * x[2] + nz * ng[2]), True


@njit(inline="always", **JIT)
def bend1(w, ns, ng):
    """valid_reflection1 after Cycles' flips: the shading normal ns put on the geometric normal
    ng's side, then both turned to the eye direction w's side of the surface (w exactly in its
    plane: never bent). Returns (the shading normal to scatter about, on ng's side; bent)."""
    if _dot(ns, ng) < 0:
        ns = (-ns[0], -ns[1], -ns[2])
    c = _dot(w, ng)
    if c == 0:
        return ns, False
    s = 1.0 if c > 0 else -1.0
    nb, bent = valid_reflection1((s * ng[0], s * ng[1], s * ng[2]), w, (s * ns[0], s * ns[1], s * ns[2]))
    return ((s * nb[0], s * nb[1], s * nb[2]) if bent else ns), bent


@njit(**JIT)
def bump_shadowing1(sn, n, wi, correction):
    """Cycles' bump_shadowing_term (kernel/closure/bsdf.h) of a diffuse closure whose normal n
    (unit) a bump or normal map bent away from the smooth shading normal sn (sd->N), for light
    from wi (unit, away from the surface): 0 where wi lies below sn's hemisphere while above n's
    (or the other way); with Bump Map Correction (correction) the microfacet shadowing of Conty
    Estevez et al. (2019), a GGX G1 of alpha^2 = min(tan^2(angle(sn, n)) / 8, 1) at wi's angle
    to sn; 1 where n is sn (no bump), exactly."""
    if sn[0] == n[0] and sn[1] == n[1] and sn[2] == n[2]:
        return 1.0
    cos_si, cos_sn, cos_ni = _dot(sn, wi), _dot(sn, n), _dot(n, wi)
    if cos_si * cos_sn * cos_ni < 0.0:
        return 0.0
    if not correction:
        return 1.0
    cos_i, cos_d = abs(cos_si), abs(cos_sn)
    if cos_d >= 1.0 or cos_i >= 1.0:
        return 1.0
    if cos_i < 1e-6:
        return 0.0
    alpha2 = min(max(0.125 * (1.0 / (cos_d * cos_d) - 1.0), 0.0), 1.0)
    return 2.0 / (1.0 + math.sqrt(1.0 + alpha2 * max(1.0 / (cos_i * cos_i) - 1.0, 0.0)))


@njit(**LANES)
def scatter1(u, w_in, ns, ng, m, kind_m, mats, beta, scale_eta, adjoint):
    """One specular interaction, as Cycles makes it (reference.scatter_specular): returns (ok, the
    new direction (unit), the new weight, bent). u: three uniform numbers, the first picks the
    lobe, the other two a rough surface's microfacet normal; kind_m: the kind the caller found
    (material m's).

    A rough mirror or glass (mats.alpha, rough.py) scatters about a microfacet normal drawn
    from the normals visible from w_in (rough.visible_normal1), the lobe's weight times
    G2 / G1(w_in) and, for Multiscatter GGX, the energy factor at the eye's direction (mats.energy).

    Bump Map Correction (the material's flag in mats): along an eye path (not adjoint) the
    shading normal is bent as Cycles bends it (valid_reflection1; bent: it was); a photon (adjoint)
    whose eye-side direction Cycles would have scattered about a bent normal dies, with bent
    True: Cycles' eye paths from that direction go elsewhere, so the path is none of Cycles'."""
    zero = (0.0, 0.0, 0.0)
    kind, fres, color, rcolor, eta = material1(mats, m)
    if _dot(ns, ng) < 0:  # a shading normal on the geometric one's side
        ns = (-ns[0], -ns[1], -ns[2])
    cin = _dot(w_in, ng)
    sgn = 1.0 if cin > 0 else (-1.0 if cin < 0 else 0.0)
    correct = mats.bump_correction[m] != 0
    bent = False
    if correct and not adjoint:
        ns, bent = bend1(w_in, ns, ng)
    cs = _dot(w_in, ns)
    front = cs * sgn > 0  # Cycles: N.wi <= 0 after the flip -> no scattering
    alpha = mats.alpha[m]
    nf, cf = ns, cs  # the normal the lobes scatter about: ns, or a microfacet normal about it
    if alpha > 0.0 and front:
        h = visible_normal1(w_in, (sgn * ns[0], sgn * ns[1], sgn * ns[2]), alpha, u[1], u[2])
        nf = (sgn * h[0], sgn * h[1], sgn * h[2])  # on ng's side, as ns
        cf = _dot(w_in, nf)
        front = cf * sgn > 0
    R, T = specular_weights1(kind, fres, color, rcolor, eta, metal1(mats.metal, m), film1(mats.film, m), cf)
    r_lum, t_lum = R[0] + R[1] + R[2], T[0] + T[1] + T[2]
    tot = r_lum + t_lum
    p_r = r_lum / tot if tot > 0 else 0.0
    choose_r = u[0] < p_r
    t_dir, t_ok = refract1(w_in, nf, eta)
    n_out = reflect1(w_in, nf) if choose_r else t_dir
    p_sel = p_r if choose_r else 1.0 - p_r
    W = R if choose_r else T
    den = p_sel if p_sel > 0 else 1.0
    b = (beta[0] * (W[0] / den), beta[1] * (W[1] / den), beta[2] * (W[2] / den))
    if scale_eta and not (choose_r or kind_m != DIELECTRIC):
        ratio = eta if cin < 0 else 1.0 / eta  # eta(w_in side) / eta(other side)
        r2 = ratio**2
        b = (b[0] * r2, b[1] * r2, b[2] * r2)
    cout = _dot(n_out, ng)
    if adjoint:
        num = abs(cs * cout)
        dn = abs(cin * _dot(n_out, ns))
        corr = num / dn if dn > 0 else 0.0
        b = (b[0] * corr, b[1] * corr, b[2] * corr)
    side = (cin * cout > 0) if choose_r else ((cin * cout < 0) and t_ok)
    ln = math.sqrt(_dot(n_out, n_out))
    inv = 1.0 / ln if ln > 0 else 0.0
    d = (n_out[0] * inv, n_out[1] * inv, n_out[2] * inv)
    if alpha > 0.0:
        co = _dot(d, ns)
        # Cycles: a photon's eye-side direction d in front of its shading normal
        side = side and (co * cout > 0 or not adjoint)
        a2 = alpha * alpha
        li = lambda1(cs, a2)
        g = (1.0 + li) / (1.0 + li + lambda1(co, a2))
        eye, ce = (d, co) if adjoint else (w_in, cs)
        k = energy_gain1(mats.energy, m, _dot(eye, ng) > 0, abs(ce))
        b = (b[0] * g * k[0], b[1] * g * k[1], b[2] * g * k[2])
    finite = b[0] == b[0] and b[1] == b[1] and b[2] == b[2]  # numpy's max of a row with a NaN is NaN
    if not (front and side and p_sel > 0 and finite and (b[0] > 0 or b[1] > 0 or b[2] > 0)):
        return False, zero, zero, bent
    if correct and adjoint and bend1(d, ns, ng)[1]:  # would Cycles bend the normal for the eye's direction d?
        return False, zero, zero, True
    return True, d, b, bent


# ------------------------------------------------------------------ over arrays
@njit(**JIT)
def scatter_rows(u, w_in, ns, ng, mat, kind, mats, beta, scale_eta, adjoint):
    """scatter1 per lane (u: (N, 3) uniform numbers): (new directions, new weights, kept lanes)."""
    n = u.shape[0]
    d_out = np.zeros((n, 3))
    b_out = np.zeros((n, 3))
    keep = np.zeros(n, np.int64)
    cnt = 0
    for i in range(n):
        ok, d, b, _ = scatter1(_row3(u, i), _row3(w_in, i), _row3(ns, i), _row3(ng, i), mat[i], kind[i], mats,
                               _row3(beta, i), scale_eta, adjoint)
        if ok:
            keep[cnt] = i
            for c in range(3):
                d_out[cnt, c] = d[c]
                b_out[cnt, c] = b[c]
            cnt += 1
    return d_out[:cnt], b_out[:cnt], keep[:cnt]


@njit(**JIT)
def _bent_rows(wi, ns, ng):
    n = wi.shape[0]
    out = np.zeros(n, np.bool_)
    for i in range(n):
        out[i] = bend1(_row3(wi, i), _row3(ns, i), _row3(ng, i))[1]
    return out


@njit(**JIT)
def _shadowing_rows(sn, n, wi, correction):
    out = np.ones(sn.shape[0])
    for i in range(sn.shape[0]):
        out[i] = bump_shadowing1(_row3(sn, i), _row3(n, i), _row3(wi, i), correction[i])
    return out


def bump_shadowing(scene, mat, sn, n, wi) -> np.ndarray:
    """bump_shadowing1 per row ((N,3) arrays; mat: the diffuse materials, whose Bump Map Correction
    it reads): (N,) factors."""
    (sn, n, wi), shape = _rows3(sn, n, wi)
    corr = np.ascontiguousarray(bump_correction(scene)[np.asarray(mat, np.int64).reshape(-1)], np.bool_)
    return _shadowing_rows(sn, n, wi, corr).reshape(shape)


def bent(wi: np.ndarray, ns: np.ndarray, ng: np.ndarray) -> np.ndarray:
    """Where Cycles' Bump Map Correction bends the shading normal ns for the eye's direction wi
    (unit, (N,3)): bend1 per row, (N,) bool. A path light-side estimators
    make through such a vertex is none of Cycles' (scatter1)."""
    (wi, ns, ng), shape = _rows3(wi, ns, ng)
    return _bent_rows(wi, ns, ng).reshape(shape)


@njit(**JIT)
def _reflect_rows(w, n):
    out = np.zeros(w.shape)
    for i in range(w.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = reflect1(_row3(w, i), _row3(n, i))
    return out


@njit(**JIT)
def _refract_rows(w, n, eta):
    out = np.zeros(w.shape)
    ok = np.zeros(w.shape[0], np.bool_)
    for i in range(w.shape[0]):
        t, ok[i] = refract1(_row3(w, i), _row3(n, i), eta[i])
        out[i, 0], out[i, 1], out[i, 2] = t
    return out, ok


def materials(scene) -> MaterialTables:
    """The scene's material tables as scatter1 and the kernels take them (MaterialTables)."""
    spec = spec_table(scene)
    return MaterialTables(*surface_tables(scene), bump_correction=bump_correction(scene).astype(np.int64),
                          weight=table(scene, spec), gain=gain_table(scene), layer=coat(scene), glossy_weight=spec,
                          absorb=absorption(scene), alpha=alphas(scene), energy=cached_energy_tables(scene),
                          metal=metal(scene), film=film(scene))


def coat_factor(scene, mat, n, w_view, w_light, share=True) -> np.ndarray:
    """(N,3) coat.coat_factor1 of each path: materials mat (N,), shading normals n, unit directions
    w_view (towards the eye) and w_light (towards the light side), (N,3) each."""
    mat = np.ascontiguousarray(mat, np.int64).reshape(-1)
    out = np.ones((len(mat), 3))
    if len(mat):
        n, w_view, w_light = (np.ascontiguousarray(a, np.float64).reshape(-1, 3) for a in (n, w_view, w_light))
        coat_factors(materials(scene), mat, n, w_view, w_light, bool(share), out)
    return out


def absorption(scene) -> np.ndarray:
    """(M,3) each glass's absorption per unit length inside it (Scene.mat_absorb; zeros where the
    scene has none)."""
    a = np.asarray(getattr(scene, "mat_absorb", np.zeros((0, 3))), np.float64)
    return np.ascontiguousarray(a) if a.shape == (len(scene.mat_kind), 3) else np.zeros((len(scene.mat_kind), 3))


def absorbing(scene) -> bool:
    """Does any glass of the scene absorb (Scene.mat_absorb)? Without making absorption's table."""
    a = np.asarray(getattr(scene, "mat_absorb", np.zeros((0, 3))))
    return bool(a.size) and bool(np.any(a > 0))


def inside(scene, mat, kind_is_glass, d_out, ng) -> np.ndarray:
    """(N,) the medium a path enters leaving a vertex along d_out: the vertex's material where it
    is glass and d_out goes into the back of its geometric normal (into the object, or on inside it
    after an internal reflection), else -1 (outside; Cycles' volume stack the same way for closed
    meshes whose normals point out)."""
    return np.where(kind_is_glass & (np.einsum("ij,ij->i", d_out, ng) < 0), mat, -1)


def arriving(scene, medium, mat_hit, hit, d, ng_hit) -> np.ndarray:
    """(N,) the medium of segments along d that end at a hit (hit: bool; mat_hit, ng_hit: its
    material and geometric normal): medium (inside's, where the segment left a glass into it),
    else the glass the segment arrives at from its back (it began inside: a receiver under
    water), else -1 (kernels._absorbed the same)."""
    back = hit & (scene.mat_kind[mat_hit] == S.DIELECTRIC) & (np.einsum("ij,ij->i", d, ng_hit) > 0)
    return np.where(medium >= 0, medium, np.where(back, mat_hit, -1))


def transmittance(scene, medium, length) -> np.ndarray:
    """(N,3) what a path keeps crossing length inside medium (inside's; -1: none): exp(-absorb x
    length)."""
    a = absorption(scene)
    sigma = np.where((medium >= 0)[:, None], a[np.maximum(medium, 0)], 0.0)
    return np.exp(-sigma * np.asarray(length, np.float64)[:, None])


def bump_correction(scene) -> np.ndarray:
    """(M,) bool: the materials whose mirrors and glass Cycles bends at grazing angles
    (Scene.mat_bump_correction; none in a scene that does not say)."""
    f = np.asarray(getattr(scene, "mat_bump_correction", np.zeros(0, bool)), bool)
    return f if f.shape == (len(scene.mat_kind),) else np.zeros(len(scene.mat_kind), bool)


def _rows3(*arrays):
    """(N,3) float64 C arrays of (..., 3) inputs broadcast together, and the leading shape."""
    b = np.broadcast_arrays(*[np.asarray(a, np.float64) for a in arrays])
    shape = b[0].shape[:-1]
    return [np.ascontiguousarray(x.reshape(-1, 3)) for x in b], shape


def reflect(w: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Mirror w about n: 2 (w.n) n - w, over (..., 3) arrays."""
    (w, n), shape = _rows3(w, n)
    return _reflect_rows(w, n).reshape(shape + (3,))


def refract(w: np.ndarray, n: np.ndarray, eta) -> tuple[np.ndarray, np.ndarray]:
    """refract1 over (..., 3) arrays (eta broadcast over the leading shape): (directions, ok)."""
    (w, n), shape = _rows3(w, n)
    eta = np.ascontiguousarray(np.broadcast_to(np.asarray(eta, np.float64), shape).reshape(-1))
    t, ok = _refract_rows(w, n, eta)
    return t.reshape(shape + (3,)), ok.reshape(shape)


