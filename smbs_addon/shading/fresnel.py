"""Fresnel: how much a mirror or glass reflects and transmits, per lane and over arrays.

The dielectric and conductor Fresnel terms, Cycles' F82-Tint metal, a Principled glass's Specular
Tint, thin films (thinfilm.py), and the lobe weights of each material kind (specular_weights1),
compiled once (jit.py); the array forms below call the compiled ones.
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from ..core.jit import JIT
from ..core.vec3 import row3 as _row3
from ..scene import arrays as S
from .thinfilm import (
    CUTOFF as _FILM_CUTOFF, clip01 as _clip01, conductor_film1, dielectric_film1, f82 as _f82, f82_film1)
from ..scene.arrays import CONDUCTOR, DIELECTRIC, FRESNEL_CONDUCTOR, FRESNEL_SCHLICK, REFRACTION_ONLY

# The tables specular_weights1 reads (surface_tables; the first five of optics.MaterialTables, by the
# same names): per material its kind (scene.DIFFUSE...), Fresnel model (scene.FRESNEL_*), colour and
# reflection tint (M,3), IOR
SurfaceTables = namedtuple("SurfaceTables", "kind fresnel color reflect_color ior")


_NO_METAL = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


_NO_FILM = (0.0, 0.0)


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
      Schlick term does (tinted_glass);
    - Refraction BSDF: R = 0, T = colour, and T = 0 under total internal reflection.

    film = (thickness nm, index) of a thin film over the surface (thinfilm.py; thickness 0: none):
    where thicker than Cycles' cutoff, the Fresnel terms above (a metal's, its coat's, a glass's) are
    the film's iridescent reflectance per channel instead, as Cycles makes them.

    Radiance is not scaled by eta^2 here (Cycles does not); callers that need the
    physical convention scale refractions themselves."""
    zero = (0.0, 0.0, 0.0)
    filmed = film[0] > _FILM_CUTOFF
    if kind == CONDUCTOR:
        if fres == FRESNEL_SCHLICK or fres == FRESNEL_CONDUCTOR:
            mu = min(abs(cos_i), 1.0)
            if filmed:
                f = f82_film1(film[0], film[1], mu, color, metal) if fres == FRESNEL_SCHLICK else \
                    conductor_film1(film[0], film[1], mu, metal)
            elif fres == FRESNEL_SCHLICK:
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
                lost = (metal[3], metal[4], metal[5]) if fres == FRESNEL_SCHLICK else zero  # a mix's other parts' weight
                r = (r[0] + (1.0 - rcolor[0] - lost[0]) * fcs[0], r[1] + (1.0 - rcolor[1] - lost[1]) * fcs[1],
                     r[2] + (1.0 - rcolor[2] - lost[2]) * fcs[2])
            return r, zero
        return color, zero
    if kind == DIELECTRIC:
        F = fresnel_dielectric1(cos_i, eta)
        if fres == REFRACTION_ONLY:
            t = 1.0 if F < 1.0 else 0.0
            return (0.0 * rcolor[0], 0.0 * rcolor[1], 0.0 * rcolor[2]), (t * color[0], t * color[1], t * color[2])
        tinted = metal[0] != 0.0 or metal[1] != 0.0 or metal[2] != 0.0
        if filmed or tinted:
            f = dielectric_film1(film[0], film[1], cos_i, eta) if filmed else (F, F, F)
            if tinted:
                f = tinted_glass(f, eta, metal, filmed)
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
    """tinted_glass of one channel: f its reflectance, tint its Specular Tint, all_one whether every
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
def tinted_glass(f, eta, metal, filmed):
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
def metal1(metal, m):
    """Material m's row of a metal's Fresnel (Scene.mat_metal; none: an empty table) as a 6-tuple."""
    if metal.shape[0] == 0:
        return _NO_METAL
    return (metal[m, 0], metal[m, 1], metal[m, 2], metal[m, 3], metal[m, 4], metal[m, 5])


@njit(**JIT)
def film1(films, m):
    """Material m's thin film (Scene.mat_film: thickness nm, index; none: an empty table) as a 2-tuple."""
    if films.shape[0] == 0:
        return _NO_FILM
    return (films[m, 0], films[m, 1])


@njit(**JIT)
def material1(mats, m):
    """Material m's (kind, Fresnel model, colour, reflection tint, IOR) from the scene's tables
    mats (SurfaceTables, or optics.MaterialTables: their fields of those names)."""
    return mats.kind[m], mats.fresnel[m], _row3(mats.color, m), _row3(mats.reflect_color, m), mats.ior[m]


@njit(**JIT)
def _weights_rows(mat, mats, metal, films, cos_i):
    n = mat.shape[0]
    R = np.zeros((n, 3))
    T = np.zeros((n, 3))
    for i in range(n):
        kind, fres, color, rcolor, eta = material1(mats, mat[i])
        r, t = specular_weights1(kind, fres, color, rcolor, eta, metal1(metal, mat[i]), film1(films, mat[i]),
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


def surface_tables(scene) -> SurfaceTables:
    """What specular_weights1 reads (SurfaceTables; optics.materials' first five, alone for
    specular_weights, which rough.energy_tables calls)."""
    return SurfaceTables(np.ascontiguousarray(scene.mat_kind, np.int64), np.ascontiguousarray(scene.mat_fresnel, np.int64),
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
    mats = SurfaceTables(np.full(n, CONDUCTOR, np.int64), np.full(n, FRESNEL_SCHLICK, np.int64), f0, np.ones((n, 3)),
                         np.ones(n))
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
    return _weights_rows(np.ascontiguousarray(mat, np.int64), surface_tables(scene), metal(scene), film(scene),
                         np.ascontiguousarray(cos_i, np.float64))


def has_reflection(scene, mat) -> bool:
    """Can material mat reflect specularly at all (a mirror, or glass with a reflection tint)?"""
    if scene.mat_kind[mat] == S.CONDUCTOR:
        return bool(np.any(scene.mat_color[mat] > 0))
    if scene.mat_kind[mat] == S.DIELECTRIC:
        return scene.mat_fresnel[mat] != S.REFRACTION_ONLY and bool(np.any(scene.mat_reflect_color[mat] > 0))
    return False
