"""Multiscatter GGX: the energy a rough mirror or glass keeps beyond single scattering.

Cycles' microfacet_ggx_preserve_energy (after Kulla and Conty): the lobe is multiplied by
1 + F_ms (1 - E(mu)) / E(mu), mu the cosine of the eye's direction with the shading normal, E the
single-scattering albedo without Fresnel (for glass: reflection and refraction together, its
Fresnel included, on the side the eye is), and F_ms = F_ss E_avg / (1 - F_ss (1 - E_avg)), F_ss the
lobe's Fresnel averaged over the hemisphere (a mirror's colour, a metal's Schlick term; 1 for glass,
for which the factor is 1 / E). E is computed here by stratified visible-normal samples
(microfacet.visible_normals), not read from Cycles' tables, and tabulated per material at
MU_STEPS + 1 cosines (energy_tables): linear between them in optics.scatter1 (energy_gain1).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..core.jit import JIT
from ..scene import arrays as S
from .fresnel import f82_terms, film, fresnel_dielectric, metal, specular_weights, tinted_glass
from .microfacet import MULTI_GGX, MU_STEPS, alphas, distributions, lambda_ggx, shadowing, visible_normals


@njit(inline="always", **JIT)
def energy_gain1(table, m, outside, mu):
    """Multiscatter GGX's factor (3-tuple) for material m where the eye's direction makes the
    cosine mu (>= 0) with the shading normal, outside (True) or inside a glass: table is
    energy_tables' (M, 2, MU + 1, 3), rows of 1 where there is none."""
    steps = table.shape[2] - 1
    x = mu * steps
    if x > steps:
        x = float(steps)
    if not x > 0.0:
        x = 0.0
    i = int(x)
    if i > steps - 1:
        i = steps - 1
    f = x - i
    side = 0 if outside else 1
    return ((1.0 - f) * table[m, side, i, 0] + f * table[m, side, i + 1, 0],
            (1.0 - f) * table[m, side, i, 1] + f * table[m, side, i + 1, 1],
            (1.0 - f) * table[m, side, i, 2] + f * table[m, side, i + 1, 2])


FINE_GRID = 256  # strata per axis of the visible normals for the energy tables (jittered: ~1e-4)


_CHUNK = 8  # cosines per pass


def fine_mean(mu: np.ndarray, alpha: float, f) -> np.ndarray:
    """(K,) the mean over GGX's visible normals of f(hx, hz, wx, wz) (layer.visible_normals' arrays) for
    each cosine mu: FINE_GRID^2 strata jittered by a fixed generator (the same table every time).
    Midpoints converge as 1 / grid where the integrand jumps (a reflection dipping under the
    surface, total internal reflection): 0.3% high at 64 strata; these are within ~1e-4."""
    jitter = np.random.default_rng(12345).random((2, FINE_GRID * FINE_GRID))
    mu = np.asarray(mu, float)
    out = np.empty(len(mu))
    for a in range(0, len(mu), _CHUNK):
        out[a:a + _CHUNK] = f(*visible_normals(mu[a:a + _CHUNK], alpha, FINE_GRID, jitter)).mean(axis=1)
    return out


def visible_albedo(mu: np.ndarray, alpha: float) -> np.ndarray:
    """E(mu): the single-scattering albedo of a GGX mirror without Fresnel (Cycles' ggx_E)."""
    a2 = max(float(alpha), 1e-4) ** 2

    def reflected(hx, hz, wx, wz):
        rz = 2.0 * (hx * wx + hz * wz) * hz - wz
        return shadowing(lambda_ggx(wz, a2), rz, rz > 0, a2)
    return fine_mean(mu, alpha, reflected)


def glass_albedo(mu: np.ndarray, alpha: float, eta: float) -> np.ndarray:
    """The single-scattering albedo of a GGX glass (reflection and refraction, the dielectric
    Fresnel at the microfacet included; no eta^2 radiance factor, as Cycles) for directions of
    cosine mu on the side from which the other side's index is eta times this one's."""
    a2 = max(float(alpha), 1e-4) ** 2

    def lobes(hx, hz, wx, wz):
        c = hx * wx + hz * wz  # w.h (> 0 for a visible normal)
        F = fresnel_dielectric(np.abs(c), eta)
        li = lambda_ggx(wz, a2)
        rz = 2.0 * c * hz - wz
        er = 1.0 / eta
        s2 = er * er * (1.0 - c * c)
        tz = -er * wz + (er * c - np.sqrt(np.maximum(1.0 - s2, 0.0))) * hz
        return F * shadowing(li, rz, rz > 0, a2) + (1.0 - F) * shadowing(li, tz, (s2 < 1.0) & (tz < 0), a2)
    return fine_mean(mu, alpha, lobes)


def _hemisphere_mean(f: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """2 int_0^1 f(mu) mu dmu (the trapezoid rule over the table's cosines), along axis 0."""
    w = np.full(len(mu), mu[1] - mu[0])
    w[0] = w[-1] = 0.5 * (mu[1] - mu[0])
    return 2.0 * np.tensordot(w * mu, f, axes=(0, 0))


def _gain(E: np.ndarray, fss: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """(K, 3) Cycles' 1 + F_ms (1 - E) / E for albedos E (K,) and F_ss (3,)."""
    e = np.maximum(E, 1e-4)
    e_avg = float(_hemisphere_mean(E, mu))
    fms = fss * e_avg / (1.0 - fss * (1.0 - e_avg))
    return 1.0 + fms[None, :] * ((1.0 - e) / e)[:, None]


_cache: dict = {}


def _f82_fit_mean(f0, f82) -> np.ndarray:
    """Cycles' mean Fresnel reflectance of a physical conductor (fresnel_conductor_Fss,
    kernel/closure/bsdf_util.h): the F82 model fitted to its reflectance at normal incidence (f0)
    and at cos = 1/7 (f82), whose mean is F0 + (1 - F0) / 21 - B / 126."""
    schlick, scale = f82_terms(f0)
    b = scale * (schlick - f82)
    return np.clip(f0 + (1.0 - f0) / 21.0 - b / 126.0, 0.0, 1.0)


def energy_tables(scene) -> np.ndarray:
    """(M, 2, MU_STEPS + 1, 3): Multiscatter GGX's factor per material, eye outside (0) or inside
    a glass (1), at mu = 0, 1/MU_STEPS, ..., 1 (energy_gain1); ones for the rest (smooth, GGX, a
    Refraction BSDF: Cycles compensates none of these)."""
    M = len(scene.mat_kind)
    out = np.ones((M, 2, MU_STEPS + 1, 3))
    a, dist = alphas(scene), distributions(scene)
    mu = np.linspace(0.0, 1.0, MU_STEPS + 1)
    for m in np.flatnonzero((a > 0) & (dist == MULTI_GGX)):
        kind, fres = int(scene.mat_kind[m]), int(scene.mat_fresnel[m])
        eta = float(scene.mat_ior[m])
        if kind == S.DIELECTRIC and fres == S.REFRACTION_ONLY:
            continue
        if kind == S.DIELECTRIC:
            # Cycles' F_ss for a glass: its transmission tint (white: the factor is 1 / E, E on the eye's
            # side), or where that is black its reflection tint times the mean Fresnel reflectance
            fss = np.asarray(scene.mat_color[m], np.float64)
            if not fss.any():
                f_mean = _hemisphere_mean(fresnel_dielectric(mu, eta), mu)
                fss = f_mean * scene.mat_reflect_color[m]
                row = metal(scene)[m] if metal(scene).size else np.zeros(6)
                if np.any(row[:3] != 0.0):  # a Principled glass's Specular Tint: F's mean mapped as F is
                    f = float(f_mean)
                    fss = np.array(tinted_glass((f, f, f), eta, tuple(float(v) for v in row), False)) \
                        * scene.mat_reflect_color[m]
            key = ("glass", float(a[m]), eta, tuple(np.round(fss, 12)))
            albedos = lambda m=m, eta=eta: [glass_albedo(mu, a[m], e) for e in (eta, 1.0 / eta)]  # noqa: E731
        else:
            R, _ = specular_weights(scene, np.full(len(mu), m), mu)
            fss = _f82_fit_mean(R[-1], specular_weights(scene, np.array([m]), np.array([1.0 / 7.0]))[0][0]) \
                if fres == S.FRESNEL_CONDUCTOR else _hemisphere_mean(R, mu)
            key = ("mirror", float(a[m]), tuple(np.round(fss, 12)))
            albedos = lambda m=m: [visible_albedo(mu, a[m])]  # noqa: E731  (both sides alike)
        if key not in _cache:
            _cache[key] = np.stack([_gain(E, fss, mu) for E in albedos()])
        out[m] = _cache[key]
    return np.ascontiguousarray(out)


def cached_energy_tables(scene) -> np.ndarray:
    """rough.energy_tables, kept by the scene while its materials stay the same."""
    key = ("energy_tables",) + tuple(np.asarray(getattr(scene, f)).tobytes() for f in (
        "mat_kind", "mat_fresnel", "mat_roughness", "mat_ior", "mat_color", "mat_reflect_color")) + (
        distributions(scene).tobytes(), metal(scene).tobytes(), film(scene).tobytes())
    return scene.derived(key, lambda: energy_tables(scene))
