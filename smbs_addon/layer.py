"""The glossy layer over a Principled BSDF's diffuse: how much of the light it leaves the diffuse.

Blender's default material, and most floors and walls in users' scenes, is a Principled BSDF:
a diffuse base under a dielectric specular layer (GGX, alpha = Roughness^2, Fresnel of the IOR
as Specular IOR Level and Specular Tint set it). Cycles layers them energy-conservingly: the
diffuse's weight is 1 - A(mu), where A is the layer's directional albedo (multiple scattering
included) for the direction towards the eye, mu the cosine of that direction with the shading
normal (Cycles' closure_layering_weight over bsdf_microfacet_estimate_albedo). A caustic on
such a floor is the diffuse's: at a slant A reaches 0.1 (Roughness 0.5, IOR 1.5), which our
layer did not take off (principled_floor: 1.15 of Cycles).

The weight is tabulated per material at MU_STEPS + 1 cosines, linear between them: where a
diffuse vertex meets the eye's direction (eye.eye_receivers, the gathers' later diffuse
vertices, the light tracer's camera splats and diffuse bounces), its throughput is multiplied by
it. A material without a layer (Diffuse BSDF, or Scene.mat_layer empty) weighs exactly 1.

A is computed here, not read from Cycles' tables: the single-scattering albedo with the
dielectric Fresnel, E_F(mu), from stratified samples of the visible normals (Heitz 2018), times
Kulla and Conty's multiple-scattering gain 1 + F_ms (1 - E) / E as Cycles applies it
(microfacet_ggx_preserve_energy), E the albedo without Fresnel. A is ~0.04-0.13, so a 1% error
in it moves the weight by ~0.1%.
"""
from __future__ import annotations

import math

import numpy as np

MU_STEPS = 64  # the table's cosines: 0, 1/64, ..., 1
_GRID = 64  # stratified visible-normal samples per axis
_cache: dict = {}  # (ior, roughness, tint) -> (MU_STEPS + 1,) weights


def fresnel_dielectric(cos_i, eta):
    """Unpolarised Fresnel reflectance of a dielectric of relative index eta (> 0) for |cos_i|."""
    c = np.abs(np.asarray(cos_i, float))
    g2 = eta * eta - 1.0 + c * c
    g = np.sqrt(np.maximum(g2, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (g - c) / (g + c)
        b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
        f = 0.5 * a * a * (1.0 + b * b)
    return np.where(g2 > 0, np.nan_to_num(f, nan=1.0), 1.0)


def _lambda(cos, a2):
    """Smith's Lambda of GGX for directions of cosine cos (> 0)."""
    c2 = np.maximum(cos * cos, 1e-12)
    return 0.5 * (np.sqrt(1.0 + a2 * np.maximum(1.0 / c2 - 1.0, 0.0)) - 1.0)


def _albedos(mu: np.ndarray, alpha: float, eta: float) -> tuple[np.ndarray, np.ndarray]:
    """(E_F, E) at each cosine mu: the single-scattering GGX albedo with and without the
    dielectric Fresnel, by stratified visible-normal samples (the same samples for every mu)."""
    u = (np.arange(_GRID) + 0.5) / _GRID
    u1, u2 = (x.ravel() for x in np.meshgrid(u, u, indexing="ij"))
    # concentric mapping of the unit square onto the disk (Shirley and Chiu)
    a, b = 2.0 * u1 - 1.0, 2.0 * u2 - 1.0
    big = np.abs(a) > np.abs(b)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(big, a, b)
        phi = np.where(big, (math.pi / 4) * b / np.where(a == 0, 1, a),
                       math.pi / 2 - (math.pi / 4) * a / np.where(b == 0, 1, b))
    t1, t2 = r * np.cos(phi), r * np.sin(phi)
    alpha = max(float(alpha), 1e-4)
    a2 = alpha * alpha
    m = np.clip(np.asarray(mu, float), 1e-4, 1.0)[:, None]  # (K, 1) against the samples (1, S)
    wo_x = np.sqrt(np.maximum(1.0 - m * m, 0.0))
    # the view stretched to the hemisphere configuration (in the x-z plane: T1 is the y axis)
    vl = np.sqrt(alpha * alpha * wo_x * wo_x + m * m)
    vx, vz = alpha * wo_x / vl, m / vl
    s = 0.5 * (1.0 + vz)
    tt2 = (1.0 - s) * np.sqrt(np.maximum(1.0 - t1 * t1, 0.0)) + s * t2
    tz = np.sqrt(np.maximum(1.0 - t1 * t1 - tt2 * tt2, 0.0))
    # nh = t1 T1 + tt2 T2 + tz vh, with T1 = (0, 1, 0) and T2 = vh x T1 = (-vz, 0, vx)
    nx, ny, nz = -tt2 * vz + tz * vx, t1 + 0.0 * m, tt2 * vx + tz * vz
    hx, hy, hz = alpha * nx, alpha * ny, np.maximum(nz, 0.0)
    hl = np.maximum(np.sqrt(hx * hx + hy * hy + hz * hz), 1e-300)
    hx, hz = hx / hl, hz / hl
    d = hx * wo_x + hz * m
    wi_z = 2.0 * d * hz - m
    up = wi_z > 0
    lo = _lambda(m, a2)
    g2_over_g1 = np.where(up, (1.0 + lo) / (1.0 + lo + _lambda(np.where(up, wi_z, 1.0), a2)), 0.0)
    ef = (fresnel_dielectric(d, eta) * g2_over_g1).mean(axis=1)
    e = g2_over_g1.mean(axis=1)
    return ef, e


def layer_weights(ior: float, roughness: float, tint: float = 1.0) -> np.ndarray:
    """(MU_STEPS + 1,) the diffuse's weight 1 - tint A(mu) at mu = 0, 1/MU_STEPS, ..., 1 under a
    dielectric GGX layer of index ior (> 1) and Principled Roughness roughness (alpha = r^2)."""
    key = (float(ior), float(roughness), float(tint))
    w = _cache.get(key)
    if w is None:
        mu = np.linspace(0.0, 1.0, MU_STEPS + 1)
        alpha = float(roughness) ** 2
        ef, e = _albedos(mu, alpha, float(ior))
        # hemispherical averages (cosine-weighted) of E and of the Fresnel reflectance
        fine = (np.arange(512) + 0.5) / 512
        e_avg = float(2.0 * np.trapezoid(e * mu, mu)) if hasattr(np, "trapezoid") else \
            float(2.0 * np.trapz(e * mu, mu))
        f_avg = float(2.0 * (fresnel_dielectric(fine, float(ior)) * fine).mean())
        f_ms = f_avg * e_avg / (1.0 - f_avg * (1.0 - e_avg))
        a = ef * (1.0 + f_ms * (1.0 - e) / np.maximum(e, 1e-6))
        w = np.clip(1.0 - float(tint) * a, 0.0, 1.0)
        _cache[key] = w
    return w


def table(scene) -> np.ndarray:
    """(M, MU_STEPS + 1) float64: each material's diffuse weight by the eye's cosine; rows of
    exactly 1 for materials without a layer."""
    M = len(scene.mat_kind)
    t = np.ones((M, MU_STEPS + 1))
    lay = np.asarray(getattr(scene, "mat_layer", np.zeros((0, 3))), float)
    if lay.shape == (M, 3):
        for m in np.flatnonzero(lay[:, 0] > 1.0):
            t[m] = layer_weights(lay[m, 0], lay[m, 1], lay[m, 2])
    return t


def has_layers(scene) -> bool:
    lay = np.asarray(getattr(scene, "mat_layer", np.zeros((0, 3))), float)
    return lay.shape == (len(scene.mat_kind), 3) and bool(np.any(lay[:, 0] > 1.0))


def weight(tab: np.ndarray, mat: np.ndarray, cos: np.ndarray) -> np.ndarray:
    """(N,) the weight of materials mat seen at cosines cos (their absolute values), from
    table(scene): linear between the table's cosines (kernels._layer_weight, the same sum)."""
    x = np.minimum(np.abs(np.asarray(cos, float)), 1.0) * MU_STEPS
    i = np.minimum(x.astype(np.int64), MU_STEPS - 1)
    f = x - i
    a, b = tab[mat, i], tab[mat, i + 1]
    return a + (b - a) * f


def ior_from_f0(f0: float) -> float:
    """The index whose normal-incidence reflectance is f0 (0 <= f0 < 1)."""
    s = math.sqrt(min(max(f0, 0.0), 0.999999))
    return (1.0 + s) / (1.0 - s)


def principled_layer(ior: float, level: float, tint) -> tuple[float, float]:
    """(the layer's effective index, its tint's largest channel) for a Principled BSDF of IOR
    ior, Specular IOR Level level (0.5: the IOR's own reflectance; 0: no layer) and Specular
    Tint tint, as Cycles sets the layer's Fresnel up: F0 scaled by 2 level. Index 0: no layer."""
    ior = float(ior)
    if not ior > 0 or not level > 0:
        return 0.0, 0.0
    f0 = ((ior - 1.0) / (ior + 1.0)) ** 2 * 2.0 * float(level)
    if f0 <= 0:
        return 0.0, 0.0
    return ior_from_f0(f0), float(max(np.asarray(tint, float)[:3].max(), 0.0))
