"""How Cycles shades a diffuse receiver that is not plain Lambert: the glossy coat over a
Principled BSDF's diffuse, and a rough diffuse (Oren-Nayar).

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

Then what Cycles' caustics on-minus-off keeps of a path from such a receiver into the glass is
not the diffuse alone but (f_d + f_g) times the diffuse closure's share of Cycles' closure
sampling (coat_factor; the caustics-off render stops only the paths labelled diffuse): 0.93-0.98
of the diffuse on principled_floor, which read 1.028 with the weight alone and 1.010 with both.
A rough diffuse (Diffuse BSDF Roughness, Principled Diffuse Roughness) is Cycles' Oren-Nayar
(oren_nayar_ratio x Lambert), in the same factor; rough_floor read 1.066 as Lambert, 1.007 now.

A is computed here, not read from Cycles' tables: the single-scattering albedo with the
dielectric Fresnel, E_F(mu), from stratified samples of the visible normals (Heitz 2018), times
Kulla and Conty's multiple-scattering gain 1 + F_ms (1 - E) / E as Cycles applies it
(microfacet_ggx_preserve_energy), E the albedo without Fresnel. A is ~0.04-0.13, so a 1% error
in it moves the weight by ~0.1%.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .fresnel import fresnel_dielectric, fresnel_dielectric1
from .microfacet import MU_STEPS, SINGULAR_ALPHA2, lambda_ggx, shadowing, visible_normals
from ..core.jit import JIT, LANES
from ..core.vec3 import add3, dot1, neg3, normalize3

# coat_factor: a diffuse channel whose Lambert term (albedo x (1 - A) x cos / pi) is at most this is
# black; the coat's share over it, glossy / Lambert, would overflow (an albedo of 1e-309, fuzzed)
LAMBERT_FLOOR = 1e-250
_cache: dict = {}  # (ior, roughness, tint) -> (weights, gains), each (MU_STEPS + 1,)


def _albedos(mu: np.ndarray, alpha: float, eta: float) -> tuple[np.ndarray, np.ndarray]:
    """(E_F, E) at each cosine mu: the single-scattering GGX albedo with and without the
    dielectric Fresnel, by stratified visible-normal samples (the same samples for every mu)."""
    hx, hz, wo_x, m = visible_normals(mu, alpha)
    a2 = max(float(alpha), 1e-4) ** 2
    d = hx * wo_x + hz * m
    wi_z = 2.0 * d * hz - m
    up = wi_z > 0
    g2_over_g1 = shadowing(lambda_ggx(m, a2), wi_z, up, a2)
    ef = (fresnel_dielectric(np.abs(d), eta) * g2_over_g1).mean(axis=1)
    e = g2_over_g1.mean(axis=1)
    return ef, e


def _tables(ior: float, roughness: float, tint: float) -> tuple[np.ndarray, np.ndarray]:
    """(weights 1 - tint A(mu), gains 1 + F_ms (1 - E) / E) at mu = 0, 1/MU_STEPS, ..., 1."""
    key = (float(ior), float(roughness), float(tint))
    got = _cache.get(key)
    if got is None:
        mu = np.linspace(0.0, 1.0, MU_STEPS + 1)
        alpha = float(roughness) ** 2
        ef, e = _albedos(mu, alpha, float(ior))
        # hemispherical averages (cosine-weighted) of E and of the Fresnel reflectance
        fine = (np.arange(512) + 0.5) / 512
        e_avg = float(2.0 * np.trapezoid(e * mu, mu)) if hasattr(np, "trapezoid") else \
            float(2.0 * np.trapz(e * mu, mu))
        f_avg = float(2.0 * (fresnel_dielectric(fine, float(ior)) * fine).mean())
        f_ms = f_avg * e_avg / (1.0 - f_avg * (1.0 - e_avg))
        gain = 1.0 + f_ms * (1.0 - e) / np.maximum(e, 1e-6)
        got = (np.clip(1.0 - float(tint) * ef * gain, 0.0, 1.0), gain)
        _cache[key] = got
    return got


def layer_weights(ior: float, roughness: float, tint: float = 1.0) -> np.ndarray:
    """(MU_STEPS + 1,) the diffuse's weight 1 - tint A(mu) at mu = 0, 1/MU_STEPS, ..., 1 under a
    dielectric GGX layer of index ior (> 1) and Principled Roughness roughness (alpha = r^2)."""
    return _tables(ior, roughness, tint)[0]


COLUMNS = 8  # Scene.mat_layer's


def coat(scene) -> np.ndarray:
    """(M, 8) Scene.mat_layer, zeros where it is empty: the glossy coat's index (0: none),
    roughness, tint and weight, the diffuse's own roughness (Oren-Nayar sigma, 0: Lambert), the
    Principled clear coat's weight (0: none), index and roughness."""
    M = len(scene.mat_kind)
    lay = np.asarray(getattr(scene, "mat_layer", np.zeros((0, COLUMNS))), float)
    return np.ascontiguousarray(lay) if lay.shape == (M, COLUMNS) else np.zeros((M, COLUMNS))


def _table(lay, k: int, cols=(0, 1, 2), present=None) -> np.ndarray:
    """(M, MU_STEPS + 1) entry k of _tables for each material of coats lay (coat()) whose columns
    cols are (index, roughness, tint) and present (default: the index above 1); rows of 1 elsewhere."""
    t = np.ones((len(lay), MU_STEPS + 1))
    ci, cr, ct = cols
    for m in np.flatnonzero(lay[:, ci] > 1.0 if present is None else present):
        t[m] = _tables(max(lay[m, ci], 1.0 + 1e-6), lay[m, cr], lay[m, ct])[k]
    return t


def spec_table(scene) -> np.ndarray:
    """(M, MU_STEPS + 1): the diffuse's weight under its glossy coat alone (coat_factor's 1 - A)."""
    return _table(coat(scene), 0)


def clearcoat_table(scene) -> np.ndarray:
    """(M, MU_STEPS + 1): the weight a Principled clear coat (Coat Weight c) leaves everything
    under it, 1 - c A_coat(mu); rows of exactly 1 without one."""
    lay = coat(scene)
    return _table(lay, 0, cols=(6, 7, 5), present=lay[:, 5] > 0.0)


def table(scene, spec=None) -> np.ndarray:
    """(M, MU_STEPS + 1) float64: each material's diffuse weight by the eye's cosine, under its
    glossy coat and its clear coat; rows of exactly 1 for materials without either (spec: the
    spec_table already made). Measured on Cycles' planes: Coat Weight 1 (IOR 1.5, Roughness 0.03)
    over the default coat, 0.9240 of Lambert at mu 1 (Cycles 0.9241), 0.7605 at 0.356 (0.7572)."""
    return (spec_table(scene) if spec is None else spec) * clearcoat_table(scene)


def gain_table(scene) -> np.ndarray:
    """(M, MU_STEPS + 1): the coat's multiple-scattering gain by the eye's cosine (1 without one)."""
    return _table(coat(scene), 1)


def has_layers(scene) -> bool:
    """Does any material depart from Lambert (a coat, or a rough diffuse)?"""
    lay = coat(scene)
    return bool(np.any(lay[:, 0] > 1.0) or np.any(lay[:, 4] > 0.0) or np.any(lay[:, 5] > 0.0))


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


@njit(**JIT)
def lambda_clamped1(cos, a2):
    c2 = max(cos * cos, 1e-12)
    return 0.5 * (math.sqrt(1.0 + a2 * max(1.0 / c2 - 1.0, 0.0)) - 1.0)


@njit(**JIT)
def oren_nayar_g1(c):
    """Cycles' bsdf_oren_nayar_G of a cosine c (its Taylor branch below 1e-6)."""
    if c < 1e-6:
        return (math.pi / 2 - 2.0 / 3.0) - c
    sn = math.sqrt(max(1.0 - c * c, 0.0))
    th = math.acos(min(c, 1.0))
    return sn * (th - 2.0 / 3.0 - sn * c) + 2.0 / 3.0 * (sn / c) * (1.0 - sn * sn * sn)


@njit(**JIT)
def oren_nayar_ratio1(sigma, alb, nv, nl, lv):
    """Cycles' Oren-Nayar diffuse (Fujii's, with OpenPBR's multiple scattering) over Lambert's, for
    roughness sigma, one channel's albedo alb, the cosines nv (eye), nl (light) and l.v."""
    sigma = min(max(sigma, 0.0), 1.0)
    a = 1.0 / (math.pi + sigma * (math.pi / 2 - 2.0 / 3.0))
    b = sigma * a
    t = lv - nl * nv
    if t > 0:
        t = t / (max(nl, nv) + 1e-38)
    e_avg = a * math.pi + ((2 * math.pi - 5.6) / 3.0) * b
    al = min(max(alb, 0.0), 1.0)
    e_ms = (1.0 / math.pi) * al * al * (e_avg / (1.0 - e_avg)) / (1.0 - al * (1.0 - e_avg))
    e_l = a * math.pi + b * oren_nayar_g1(nl)
    e_v = a * math.pi + b * oren_nayar_g1(nv)
    return math.pi * (a + b * t + e_ms * (1.0 - e_v) * (1.0 - e_l))


@njit(**LANES)
def coat_factor1(mats, m, n, w_view, w_light, share):
    """What Cycles' caustics on-minus-off keeps of a light path leaving material m's diffuse receiver
    towards w_light (the caustic's first vertex), relative to a Lambert diffuse of its colour, per
    channel (mats: optics.materials; n the shading normal; w_view towards the eye; unit 3-tuples).

    - Under a Principled coat, Cycles samples the closures by their sample weights (diffuse: its
      colour x (1 - A); the coat: A), weighs a sampled direction by every closure's eval over
      their combined pdf and labels the path by the closure it picked. With caustics off a path
      labelled diffuse stops at the glass, one labelled glossy goes on, in both renders. So the
      layer holds (f_d + f_g) x P_d p_d / (P_d p_d + P_g p_g) of such a direction: ~0.98 of the
      diffuse for light from above a floor seen at mu 0.36 (principled_floor), less along the
      coat's lobe. A coat so smooth that Cycles makes it a perfect mirror takes no share.
    - A rough diffuse (Diffuse BSDF Roughness, Principled Diffuse Roughness) is Cycles'
      Oren-Nayar: f_d is that (oren_nayar_ratio1 x Lambert).
    (1, 1, 1) exactly for a Lambert diffuse without a coat. share False: a receiver the eye reaches
    after a diffuse bounce, where Cycles' caustics-off render has stopped the path already whatever
    it samples: all of f_d + f_g counts. The array form: coat_factors, optics.coat_factor."""
    lay = mats.layer
    eta, rough, tint, wgt, sigma = lay[m, 0], lay[m, 1], lay[m, 2], lay[m, 3], lay[m, 4]
    a2 = rough ** 4
    coated = eta > 1.0 and a2 > SINGULAR_ALPHA2 and wgt > 0.0
    if not (coated or sigma > 0.0):
        return 1.0, 1.0, 1.0
    nv = dot1(n, w_view)
    nn = neg3(n) if nv < 0 else n
    mu_o = min(max(abs(nv), 1e-6), 1.0)
    mu_i = dot1(nn, w_light)
    if not mu_i > 1e-9:
        return 1.0, 1.0, 1.0
    if not wgt > 0.0:
        wgt = 1.0
    col = mats.color
    b0, b1, b2 = col[m, 0] / wgt, col[m, 1] / wgt, col[m, 2] / wgt
    one_minus_a = table_weight1(mats.glossy_weight, m, mu_o)  # the glossy coat's alone: a clear coat scales all alike
    sw_d = (b0 + b1 + b2) / 3.0 * one_minus_a
    if not sw_d > 0:
        return 1.0, 1.0, 1.0
    r0 = r1 = r2 = 1.0
    if sigma > 0.0:
        lv = dot1(w_view, w_light)
        r0, r1, r2 = (oren_nayar_ratio1(sigma, b0, mu_o, mu_i, lv), oren_nayar_ratio1(sigma, b1, mu_o, mu_i, lv),
                      oren_nayar_ratio1(sigma, b2, mu_o, mu_i, lv))
    eval_g = 0.0
    s = 1.0
    if coated:
        h = normalize3(add3(w_view, w_light))
        c_nh = dot1(h, nn)
        d = a2 / (math.pi * (1.0 + (a2 - 1.0) * c_nh * c_nh) ** 2)
        lam_o = lambda_clamped1(mu_o, a2)
        g2 = 1.0 / (1.0 + lam_o + lambda_clamped1(mu_i, a2))
        eval_g = table_weight1(mats.gain, m, mu_o) * fresnel_dielectric1(dot1(h, w_view), eta) * tint * d * g2 / (4.0 * mu_o)
        if share:
            pdf_g = d / (4.0 * mu_o * (1.0 + lam_o))
            pdf_d = mu_i / math.pi
            p_d = sw_d / max(sw_d + (1.0 - one_minus_a), 1e-300)
            s = p_d * pdf_d / max(p_d * pdf_d + (1.0 - p_d) * pdf_g, 1e-300)
    e_d = one_minus_a * mu_i / math.pi
    # a channel whose Lambert term is below LAMBERT_FLOOR is black (the coat's share over it
    # would overflow: a colour of 1e-309 made an infinite caustic)
    k0 = s * (r0 + eval_g / (b0 * e_d)) if b0 * e_d > LAMBERT_FLOOR else 1.0
    k1 = s * (r1 + eval_g / (b1 * e_d)) if b1 * e_d > LAMBERT_FLOOR else 1.0
    k2 = s * (r2 + eval_g / (b2 * e_d)) if b2 * e_d > LAMBERT_FLOOR else 1.0
    return k0, k1, k2



@njit(**LANES)
def coat_factors(mats, mat, n, w_view, w_light, share, out):
    """coat_factor1 over arrays: out (N,3) for the paths of materials mat (N,), shading normals n,
    unit directions w_view (towards the eye) and w_light (towards the light side), all (N,3)."""
    for i in range(len(mat)):
        out[i, 0], out[i, 1], out[i, 2] = coat_factor1(mats, mat[i], (n[i, 0], n[i, 1], n[i, 2]),
                                                       (w_view[i, 0], w_view[i, 1], w_view[i, 2]),
                                                       (w_light[i, 0], w_light[i, 1], w_light[i, 2]), share)

@njit(**JIT)
def table_weight1(tab, m, mu):
    """layer.weight for one vertex: material m's entry of tab (one of layer.py's tables,
    optics.MaterialTables' weight, gain or glossy_weight) at the eye's cosine mu; exactly 1 in a row of ones."""
    x = min(abs(mu), 1.0) * MU_STEPS
    i = min(int(x), MU_STEPS - 1)
    f = x - i
    a = tab[m, i]
    return a + (tab[m, i + 1] - a) * f
