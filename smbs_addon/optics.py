"""Reflection, refraction and Fresnel on (N,3) direction arrays.

Convention: ``w`` points AWAY from the surface (towards where light comes
from or goes to), ``n`` is a unit normal (either side). Results point away from
the surface on the other side of the interaction.
"""
from __future__ import annotations

import numpy as np

from . import scene as S
from .vec import dot


def reflect(w: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Mirror w about n: 2 (w.n) n - w."""
    return 2.0 * dot(w, n)[..., None] * n - w


def refract(w: np.ndarray, n: np.ndarray, eta) -> tuple[np.ndarray, np.ndarray]:
    """Refract w through an interface with relative IOR eta = n_inside / n_outside,
    where n points to the outside. Returns (direction, ok); ok is False on total
    internal reflection (the direction is then zero, never NaN)."""
    eta = np.asarray(eta, float)
    c = dot(w, n)
    outside = c >= 0
    eta_r = np.where(outside, 1.0 / eta, eta)  # n_from / n_to
    nn = np.where(outside[..., None], n, -n)
    c = np.abs(c)
    r2 = 1.0 - eta_r**2 * (1.0 - c * c)
    ok = r2 > 0.0
    r = np.sqrt(np.where(ok, r2, 0.0))
    t = -eta_r[..., None] * (w - c[..., None] * nn) - r[..., None] * nn
    return np.where(ok[..., None], t, 0.0), ok


def fresnel_dielectric(cos_i: np.ndarray, eta) -> np.ndarray:
    """Unpolarised Fresnel reflectance. cos_i = w.n (sign tells the side);
    eta = n_inside / n_outside with n pointing outside. 1 on total internal reflection."""
    eta = np.asarray(eta, float)
    cos_i = np.asarray(cos_i, float)
    outside = cos_i >= 0
    eta_r = np.where(outside, 1.0 / eta, eta)  # n_from / n_to
    ci = np.minimum(np.abs(cos_i), 1.0)
    s2t = eta_r**2 * (1.0 - ci * ci)
    tir = s2t >= 1.0
    ct = np.sqrt(np.maximum(0.0, 1.0 - s2t))
    # with n1/n2 = eta_r: rs = (n1 ci - n2 ct)/(n1 ci + n2 ct) = (eta_r ci - ct)/(eta_r ci + ct)
    den_s = eta_r * ci + ct
    den_p = ci + eta_r * ct
    rs = np.divide(eta_r * ci - ct, den_s, out=np.ones_like(ci), where=den_s > 0)
    rp = np.divide(ci - eta_r * ct, den_p, out=np.ones_like(ci), where=den_p > 0)
    f = 0.5 * (rs * rs + rp * rp)
    return np.where(tir, 1.0, np.clip(f, 0.0, 1.0))


def fresnel_schlick(cos_i: np.ndarray, f0: np.ndarray) -> np.ndarray:
    """Schlick's approximation, (N,) cosines and (N,3) or (3,) F0 -> (N,3)."""
    m = np.clip(1.0 - np.abs(cos_i), 0.0, 1.0)[..., None]
    return f0 + (1.0 - f0) * m**5


def specular_weights(scene, mat: np.ndarray, cos_i: np.ndarray):
    """Weights (R, T), each (N,3), of the mirror and refraction lobes of materials mat
    for incidence cos_i = w_i . n (its sign tells the side; Cycles' conventions):

    - conductor: R = colour (Glossy BSDF) or Schlick from F0 = colour (Principled
      metallic); T = 0;
    - glass: R = F * reflection tint, T = (1 - F) * transmission tint, F the dielectric
      Fresnel term (1 under total internal reflection);
    - Refraction BSDF: R = 0, T = colour, and T = 0 under total internal reflection.

    Radiance is not scaled by eta^2 here (Cycles does not); callers that need the
    physical convention scale refractions themselves."""
    kind = scene.mat_kind[mat]
    color = scene.mat_color[mat]
    fres = scene.mat_fresnel[mat]
    n = len(mat)
    R = np.zeros((n, 3))
    T = np.zeros((n, 3))
    cond = kind == S.CONDUCTOR
    if cond.any():
        c = np.flatnonzero(cond)
        R[c] = np.where((fres[c] == S.FRESNEL_SCHLICK)[:, None], fresnel_schlick(cos_i[c], color[c]), color[c])
    diel = kind == S.DIELECTRIC
    if diel.any():
        d = np.flatnonzero(diel)
        F = fresnel_dielectric(cos_i[d], scene.mat_ior[mat[d]])
        only_t = fres[d] == S.REFRACTION_ONLY
        R[d] = np.where(only_t, 0.0, F)[:, None] * scene.mat_reflect_color[mat[d]]
        T[d] = np.where(only_t, (F < 1.0).astype(float), 1.0 - F)[:, None] * color[d]
    return R, T


def has_reflection(scene, mat) -> bool:
    """Can material mat reflect specularly at all (a mirror, or glass with a reflection tint)?"""
    if scene.mat_kind[mat] == S.CONDUCTOR:
        return bool(np.any(scene.mat_color[mat] > 0))
    if scene.mat_kind[mat] == S.DIELECTRIC:
        return scene.mat_fresnel[mat] != S.REFRACTION_ONLY and bool(np.any(scene.mat_reflect_color[mat] > 0))
    return False
