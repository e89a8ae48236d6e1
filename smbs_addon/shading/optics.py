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

import numpy as np
from numba import njit

from ..scene import arrays as S
from ..core.jit import JIT, LANES
from .microfacet import alphas, distributions, energy_gain1, energy_tables, lambda1, visible_normal1
from .microfacet import dot1 as _dot
from .thinfilm import CUTOFF as _FILM_CUTOFF
from .thinfilm import clip01 as _clip01
from .thinfilm import conductor_film1, dielectric_film1, f82_film1
from .thinfilm import f82 as _f82

_CONDUCTOR, _DIELECTRIC = S.CONDUCTOR, S.DIELECTRIC
_SCHLICK, _REFRACTION_ONLY, _PHYSICAL = S.FRESNEL_SCHLICK, S.REFRACTION_ONLY, S.FRESNEL_CONDUCTOR
_NO_METAL = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
_NO_FILM = (0.0, 0.0)


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


@njit(**JIT)
def fresnel_dielectric1(cos_i, eta):
    """Unpolarised Fresnel reflectance. cos_i = w.n (its sign tells the side); eta =
    n_inside / n_outside with n pointing outside. 1 on total internal reflection."""
    eta_r = 1.0 / eta if cos_i >= 0 else eta  # n_from / n_to
    ci = abs(cos_i)
    if ci > 1.0:
        ci = 1.0
    s2t = eta_r**2 * (1.0 - ci * ci)
    if s2t >= 1.0:
        return 1.0
    x = 1.0 - s2t
    ct = math.sqrt(0.0 if 0.0 >= x else x)  # np.maximum(0, x): NaN stays
    # with n1/n2 = eta_r: rs = (n1 ci - n2 ct)/(n1 ci + n2 ct) = (eta_r ci - ct)/(eta_r ci + ct)
    den_s = eta_r * ci + ct
    den_p = ci + eta_r * ct
    rs = (eta_r * ci - ct) / den_s if den_s > 0 else 1.0
    rp = (ci - eta_r * ct) / den_p if den_p > 0 else 1.0
    return _clip01(0.5 * (rs * rs + rp * rp))


@njit(**JIT)
def fresnel_conductor1(mu, n, k):
    """Unpolarised reflectance of a conductor of complex index n + ik under a medium of index 1 at
    incidence cosine mu in [0, 1] (Cycles' fresnel_conductor_polarized, from Born and Wolf 14.4.1):
    the mean of the s and p reflectances; at mu = 1, ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2), and
    for k = 0 the dielectric Fresnel of index n."""
    nk2 = 2.0 * n * k
    t1 = n * n - k * k - (1.0 - mu * mu)
    t2 = math.sqrt(t1 * t1 + nk2 * nk2)
    u2 = max(0.5 * (t2 + t1), 0.0)
    v2 = max(0.5 * (t2 - t1), 0.0)
    u, v = math.sqrt(u2), math.sqrt(v2)
    den_s = (mu + u) * (mu + u) + v2
    rs = ((mu - u) * (mu - u) + v2) / den_s if den_s != 0.0 else 0.0
    t3, t4 = (n * n - k * k) * mu, nk2 * mu
    den_p = (t3 + u) * (t3 + u) + (t4 + v) * (t4 + v)
    rp = ((t3 - u) * (t3 - u) + (t4 - v) * (t4 - v)) / den_p if den_p != 0.0 else 0.0
    return 0.5 * (rs + rp)


@njit(inline="always", **JIT)
def specular_weights1(kind, fres, color, rcolor, eta, metal, film, cos_i):
    """Weights (R, T) (3-tuples) of the mirror and refraction lobes of a material for
    incidence cos_i = w_i . n (its sign tells the side; Cycles' conventions):

    - conductor: R = colour (Glossy BSDF), or Cycles' F82-Tint from F0 = colour and B = metal[:3]
      (Schlick where B is 0), or a physical conductor's Fresnel of index metal[:3] + i metal[3:]
      (Metallic BSDF), times the reflection tint (Principled metallic: its Metallic weight m),
      plus (1 - m - metal[3:]) x the dielectric Fresnel of index eta (the coat over the rest; in a
      shader mix of weight w, F82-Tint's metal[3:] = 1 - w and the tint w m, so (1 - m) w); T = 0;
    - glass: R = F * reflection tint, T = (1 - F) * transmission tint, F the dielectric
      Fresnel term (1 under total internal reflection); a Principled glass's Specular Tint c
      (metal[:3] = c - 1, zeros: white) scales F's value at normal incidence, as Cycles' generalized
      Schlick term does (_tinted_glass);
    - Refraction BSDF: R = 0, T = colour, and T = 0 under total internal reflection.

    film = (thickness nm, index) of a thin film over the surface (thinfilm.py; thickness 0: none):
    where thicker than Cycles' cutoff, the Fresnel terms above (a metal's, its coat's, a glass's) are
    the film's iridescent reflectance per channel instead, as Cycles makes them.

    Radiance is not scaled by eta^2 here (Cycles does not); callers that need the
    physical convention scale refractions themselves."""
    zero = (0.0, 0.0, 0.0)
    filmed = film[0] > _FILM_CUTOFF
    if kind == _CONDUCTOR:
        if fres == _SCHLICK or fres == _PHYSICAL:
            mu = min(abs(cos_i), 1.0)
            if filmed:
                f = f82_film1(film[0], film[1], mu, color, metal) if fres == _SCHLICK else \
                    conductor_film1(film[0], film[1], mu, metal)
            elif fres == _SCHLICK:
                s = _clip01(1.0 - abs(cos_i))
                m5 = math.pow(s, 5.0)
                f = (_f82(m5, s, mu, color[0], metal[0]), _f82(m5, s, mu, color[1], metal[1]),
                     _f82(m5, s, mu, color[2], metal[2]))
            else:
                f = (fresnel_conductor1(mu, metal[0], metal[3]), fresnel_conductor1(mu, metal[1], metal[4]),
                     fresnel_conductor1(mu, metal[2], metal[5]))
            # Principled metallic: weighed by Metallic (the reflection tint); what Metallic leaves
            # is under a dielectric coat of index eta, a mirror too
            r = (f[0] * rcolor[0], f[1] * rcolor[1], f[2] * rcolor[2])
            if rcolor[0] < 1.0:
                if filmed:
                    fcs = dielectric_film1(film[0], film[1], abs(cos_i), eta)
                else:
                    fc = fresnel_dielectric1(abs(cos_i), eta)
                    fcs = (fc, fc, fc)
                lost = (metal[3], metal[4], metal[5]) if fres == _SCHLICK else zero  # a mix's other parts' weight
                r = (r[0] + (1.0 - rcolor[0] - lost[0]) * fcs[0], r[1] + (1.0 - rcolor[1] - lost[1]) * fcs[1],
                     r[2] + (1.0 - rcolor[2] - lost[2]) * fcs[2])
            return r, zero
        return color, zero
    if kind == _DIELECTRIC:
        F = fresnel_dielectric1(cos_i, eta)
        if fres == _REFRACTION_ONLY:
            t = 1.0 if F < 1.0 else 0.0
            return (0.0 * rcolor[0], 0.0 * rcolor[1], 0.0 * rcolor[2]), (t * color[0], t * color[1], t * color[2])
        tinted = metal[0] != 0.0 or metal[1] != 0.0 or metal[2] != 0.0
        if filmed or tinted:
            f = dielectric_film1(film[0], film[1], cos_i, eta) if filmed else (F, F, F)
            if tinted:
                f = _tinted_glass(f, eta, metal, filmed)
            return (f[0] * rcolor[0], f[1] * rcolor[1], f[2] * rcolor[2]), \
                ((1.0 - f[0]) * color[0], (1.0 - f[1]) * color[1], (1.0 - f[2]) * color[2])
        t = 1.0 - F
        return (F * rcolor[0], F * rcolor[1], F * rcolor[2]), (t * color[0], t * color[1], t * color[2])
    return zero, zero


@njit(inline="always", **JIT)
def _dielectric_f0(eta):
    """A dielectric's Fresnel reflectance at normal incidence, ((eta - 1) / (eta + 1))^2 (Cycles'
    F0_from_ior; the same for eta and 1 / eta)."""
    return ((eta - 1.0) / (eta + 1.0)) ** 2


@njit(**JIT)
def _tinted1(f, F0, tint, filmed, all_one):
    """_tinted_glass of one channel: f its reflectance, tint its Specular Tint, all_one whether every
    channel's f is 1."""
    f0 = _clip01(F0 * max(tint, 0.0))
    if filmed:
        if F0 > 1e-5 and not all_one:
            # kept at 1 at most: a tint far above white can scale f past 1, where Cycles' transmission
            # (1 - F) turns negative
            return _clip01(f * (1.0 + (f0 / F0 - 1.0) * _clip01((f - 1.0) / (F0 - 1.0))))
        return f
    s = _clip01((f - F0) / (1.0 - F0)) if F0 < 1.0 else 1.0
    return f0 + (1.0 - f0) * s


@njit(**JIT)
def _tinted_glass(f, eta, metal, filmed):
    """A Principled glass's reflectance per channel under its Specular Tint c = 1 + metal[:3]
    (Cycles' generalized_schlick_fresnel with a negative exponent, bsdf_microfacet.h): f0 = F0 c (kept
    in [0, 1]), F0 the glass's reflectance at normal incidence; the plain Fresnel f is mapped from
    [F0, 1] onto [f0, 1]. Under a thin film (filmed), whose f may fall below F0, Cycles scales f by
    f0 / F0 instead, the more the nearer f is to F0 (kept at 1 at most here: Cycles lets it pass 1)."""
    F0 = _dielectric_f0(eta)
    one = filmed and f[0] == 1.0 and f[1] == 1.0 and f[2] == 1.0
    return (_tinted1(f[0], F0, 1.0 + metal[0], filmed, one), _tinted1(f[1], F0, 1.0 + metal[1], filmed, one),
            _tinted1(f[2], F0, 1.0 + metal[2], filmed, one))


@njit(**JIT)
def _row3(a, i):
    return (a[i, 0], a[i, 1], a[i, 2])


@njit(**JIT)
def _metal1(metal, m):
    """Material m's row of a metal's Fresnel (Scene.mat_metal; none: an empty table) as a 6-tuple."""
    if metal.shape[0] == 0:
        return _NO_METAL
    return (metal[m, 0], metal[m, 1], metal[m, 2], metal[m, 3], metal[m, 4], metal[m, 5])


@njit(**JIT)
def _film1(films, m):
    """Material m's thin film (Scene.mat_film: thickness nm, index; none: an empty table) as a 2-tuple."""
    if films.shape[0] == 0:
        return _NO_FILM
    return (films[m, 0], films[m, 1])


@njit(**JIT)
def _material(mats, m):
    """Material m's (kind, Fresnel model, colour, reflection tint, IOR) from the scene's tables
    mats = (mat_kind, mat_fresnel, mat_color, mat_reflect_color, mat_ior, bump correction, then
    layer.py's tables): materials()."""
    kind, fres, color, rcolor, ior = mats[0], mats[1], mats[2], mats[3], mats[4]
    return kind[m], fres[m], _row3(color, m), _row3(rcolor, m), ior[m]


@njit(**LANES)
def scatter1(u, w_in, ns, ng, m, kind_m, mats, beta, scale_eta, adjoint):
    """One specular interaction, as Cycles makes it (reference.scatter_specular): returns (ok, the
    new direction (unit), the new weight, bent). u: three uniform numbers, the first picks the
    lobe, the other two a rough surface's microfacet normal; kind_m: the kind the caller found
    (material m's).

    A rough mirror or glass (mats[11]: alpha, rough.py) scatters about a microfacet normal drawn
    from the normals visible from w_in (rough.visible_normal1), the lobe's weight times
    G2 / G1(w_in) and, for Multiscatter GGX, the energy factor at the eye's direction (mats[12]).

    Bump Map Correction (the material's flag in mats): along an eye path (not adjoint) the
    shading normal is bent as Cycles bends it (valid_reflection1; bent: it was); a photon (adjoint)
    whose eye-side direction Cycles would have scattered about a bent normal dies, with bent
    True: Cycles' eye paths from that direction go elsewhere, so the path is none of Cycles'."""
    zero = (0.0, 0.0, 0.0)
    kind, fres, color, rcolor, eta = _material(mats, m)
    if _dot(ns, ng) < 0:  # a shading normal on the geometric one's side
        ns = (-ns[0], -ns[1], -ns[2])
    cin = _dot(w_in, ng)
    sgn = 1.0 if cin > 0 else (-1.0 if cin < 0 else 0.0)
    correct = mats[5][m] != 0
    bent = False
    if correct and not adjoint:
        ns, bent = bend1(w_in, ns, ng)
    cs = _dot(w_in, ns)
    front = cs * sgn > 0  # Cycles: N.wi <= 0 after the flip -> no scattering
    alpha = mats[11][m]
    nf, cf = ns, cs  # the normal the lobes scatter about: ns, or a microfacet normal about it
    if alpha > 0.0 and front:
        h = visible_normal1(w_in, (sgn * ns[0], sgn * ns[1], sgn * ns[2]), alpha, u[1], u[2])
        nf = (sgn * h[0], sgn * h[1], sgn * h[2])  # on ng's side, as ns
        cf = _dot(w_in, nf)
        front = cf * sgn > 0
    R, T = specular_weights1(kind, fres, color, rcolor, eta, _metal1(mats[13], m), _film1(mats[14], m), cf)
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
    if scale_eta and not (choose_r or kind_m != _DIELECTRIC):
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
        k = energy_gain1(mats[12], m, _dot(eye, ng) > 0, abs(ce))
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
def _weights_rows(mat, mats, metal, films, cos_i):
    n = mat.shape[0]
    R = np.zeros((n, 3))
    T = np.zeros((n, 3))
    for i in range(n):
        kind, fres, color, rcolor, eta = _material(mats, mat[i])
        r, t = specular_weights1(kind, fres, color, rcolor, eta, _metal1(metal, mat[i]), _film1(films, mat[i]),
                                 cos_i[i])
        for c in range(3):
            R[i, c], T[i, c] = r[c], t[c]
    return R, T


@njit(**JIT)
def _fresnel_rows(cos_i, eta):
    out = np.zeros(cos_i.shape[0])
    for i in range(cos_i.shape[0]):
        out[i] = fresnel_dielectric1(cos_i[i], eta[i])
    return out


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


def materials(scene) -> tuple:
    """The scene's material tables as scatter1 takes them; then a Principled coat's (layer.py):
    the diffuse's weight and the coat's multiple-scattering gain by the eye's cosine, and the
    coats (Scene.mat_layer), the diffuse's weight under its glossy coat alone (kernels._tab_weight,
    kernels._coat_factor), each glass's absorption; then the rough mirrors' and glass's GGX alpha (0:
    a perfect one) and Multiscatter GGX's factors (rough.py); then the metals' Fresnel beyond their
    colour (metal(): mats[13]), last the thin films (film(): mats[14])."""
    from .coat import coat, gain_table, spec_table, table

    spec = spec_table(scene)
    return _surface_tables(scene) + (bump_correction(scene).astype(np.int64), table(scene, spec), gain_table(scene),
                                     coat(scene), spec, absorption(scene), alphas(scene), _energy(scene), metal(scene),
                                     film(scene))


def _surface_tables(scene) -> tuple:
    """materials()' first five tables, what specular_weights1 reads: kind, Fresnel model, colour,
    reflection tint, IOR (alone for specular_weights, which rough.energy_tables calls)."""
    return (np.ascontiguousarray(scene.mat_kind, np.int64), np.ascontiguousarray(scene.mat_fresnel, np.int64),
            np.ascontiguousarray(scene.mat_color, np.float64), np.ascontiguousarray(scene.mat_reflect_color, np.float64),
            np.ascontiguousarray(scene.mat_ior, np.float64))


def metal(scene) -> np.ndarray:
    """(M,6) Scene.mat_metal, or (0,6) where the scene has none (every metal Schlick or a Glossy BSDF)."""
    a = np.asarray(getattr(scene, "mat_metal", np.zeros((0, 6))), np.float64)
    return np.ascontiguousarray(a) if a.shape == (len(scene.mat_kind), 6) else np.zeros((0, 6))


def film(scene) -> np.ndarray:
    """(M,2) Scene.mat_film, or (0,2) where the scene has none."""
    a = np.asarray(getattr(scene, "mat_film", np.zeros((0, 2))), np.float64)
    return np.ascontiguousarray(a) if a.shape == (len(scene.mat_kind), 2) else np.zeros((0, 2))


def _energy(scene) -> np.ndarray:
    """rough.energy_tables, kept by the scene while its materials stay the same."""
    key = ("energy_tables",) + tuple(np.asarray(getattr(scene, f)).tobytes() for f in (
        "mat_kind", "mat_fresnel", "mat_roughness", "mat_ior", "mat_color", "mat_reflect_color")) + (
        distributions(scene).tobytes(), metal(scene).tobytes(), film(scene).tobytes())
    return scene.derived(key, lambda: energy_tables(scene))


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


def fresnel_dielectric(cos_i: np.ndarray, eta) -> np.ndarray:
    """fresnel_dielectric1 over arrays (eta broadcast to cos_i's shape)."""
    cos_i = np.asarray(cos_i, np.float64)
    eta = np.broadcast_to(np.asarray(eta, np.float64), cos_i.shape)
    return _fresnel_rows(np.ascontiguousarray(cos_i.reshape(-1)), np.ascontiguousarray(eta.reshape(-1))).reshape(
        cos_i.shape)


def fresnel_schlick(cos_i: np.ndarray, f0: np.ndarray) -> np.ndarray:
    """Schlick's approximation, (N,) cosines and (N,3) or (3,) F0 -> (N,3) (a conductor's R in
    specular_weights1)."""
    cos_i = np.ascontiguousarray(cos_i, np.float64).reshape(-1)
    f0 = np.ascontiguousarray(np.broadcast_to(np.asarray(f0, np.float64), (len(cos_i), 3)))
    n = len(cos_i)
    mats = (np.full(n, _CONDUCTOR, np.int64), np.full(n, _SCHLICK, np.int64), f0, np.ones((n, 3)), np.ones(n))
    return _weights_rows(np.arange(n), mats, np.zeros((0, 6)), np.zeros((0, 2)), cos_i)[0]


def f82_terms(f0):
    """The F82 model's two numbers for F0 f0 (bsdf_util.h, fresnel_f82_B and fresnel_f82tint_B): Schlick's
    reflectance at cos = 1/7, f0 + (1 - f0) f^5 with f = 6/7, and the scale 7 / (f^5 f) that turns a
    shortfall from it there into the term's B."""
    f = 6.0 / 7.0
    f5 = f ** 5
    return f0 + (1.0 - f0) * f5, 7.0 / (f5 * f)


def f82_tint_metal(f0, tint) -> np.ndarray:
    """Scene.mat_metal's row of Cycles' F82-Tint metal of F0 f0 and edge tint tint (each (3,) in [0, 1]):
    B = Schlick(f0, cos = 1/7) x 7 / (f^5 f) x (1 - tint) (f82_terms), then zeros; all zeros where the
    tint is white (plain Schlick, as Cycles sets it)."""
    f0, tint = np.asarray(f0, float), np.asarray(tint, float)
    if np.all(tint == 1.0):
        return np.zeros(6)
    schlick, scale = f82_terms(f0)
    return np.concatenate([schlick * scale * (1.0 - tint), np.zeros(3)])


def conductor_f0(n, k) -> np.ndarray:
    """A physical conductor's reflectance at normal incidence, ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2)
    per channel: its Scene.mat_color (what the plan and the guide take for its brightness)."""
    n, k = np.asarray(n, float), np.asarray(k, float)
    return ((n - 1.0) ** 2 + k ** 2) / np.maximum((n + 1.0) ** 2 + k ** 2, 1e-300)


def specular_weights(scene, mat: np.ndarray, cos_i: np.ndarray):
    """specular_weights1 per lane: (R, T), each (N,3), of materials mat at incidence cos_i."""
    return _weights_rows(np.ascontiguousarray(mat, np.int64), _surface_tables(scene), metal(scene), film(scene),
                         np.ascontiguousarray(cos_i, np.float64))


def has_reflection(scene, mat) -> bool:
    """Can material mat reflect specularly at all (a mirror, or glass with a reflection tint)?"""
    if scene.mat_kind[mat] == S.CONDUCTOR:
        return bool(np.any(scene.mat_color[mat] > 0))
    if scene.mat_kind[mat] == S.DIELECTRIC:
        return scene.mat_fresnel[mat] != S.REFRACTION_ONLY and bool(np.any(scene.mat_reflect_color[mat] > 0))
    return False
