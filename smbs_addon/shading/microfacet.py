"""Rough mirrors and glass: the GGX microfacet scatter of a light path, as Cycles makes it.

A glass or mirror whose alpha^2 (alpha = Roughness^2) is above Cycles' 1e-7 is a microfacet
surface in Cycles (bsdf_microfacet.h): a path meets it, a microfacet normal h is sampled from
GGX's distribution of the normals visible from the incoming direction (Heitz 2018, "Sampling the
GGX Distribution of Visible Normals"), and the path reflects or refracts about h as about a
smooth surface's normal, the lobe picked by the Fresnel term at h. What the path keeps is then
the smooth lobe's weight times Smith's height-correlated shadowing over the masking of the
sampling direction, G2 / G1 = (1 + L(w_in)) / (1 + L(w_in) + L(w_out)), L Smith's Lambda of GGX.

That weight is symmetric in the two directions up to the refraction's (eta_from / eta_to)^2,
which optics.scatter1 handles as for a smooth glass, so photons (adjoint) sample h from their
own incoming direction too.

Multiscatter GGX (Blender's default distribution for the Principled, Glass and Glossy BSDF)
adds what single scattering loses (Cycles' microfacet_ggx_preserve_energy, after Kulla and
Conty): the lobe is multiplied by 1 + F_ms (1 - E(mu)) / E(mu), mu the cosine of the eye's
direction with the shading normal, E the single-scattering albedo without Fresnel (for glass:
reflection and refraction together, its Fresnel included, on the side the eye is), and
F_ms = F_ss E_avg / (1 - F_ss (1 - E_avg)), F_ss the lobe's Fresnel averaged over the
hemisphere (a mirror's colour, a metal's Schlick term; 1 for glass, for which the factor is
1 / E). E is computed here by stratified visible-normal samples (layer.visible_normals), not
read from Cycles' tables, and tabulated per material at MU_STEPS + 1 cosines
(energy_tables): linear between them in scatter1 (energy_gain1).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..scene import arrays as S
from ..core.jit import JIT

# a smoother mirror or glass (alpha^2 = Roughness^4 at most this: Roughness 0.0178) is baked as a perfect one, so
# the walks take it. Cycles' own threshold (BSDF_ROUGHNESS_SQ_THRESH) is 2e-10, Roughness 0.0038; between the two
# its lobe is under alpha = 3.2e-4 rad wide (1.6 mm at 5 m) and a mirror's GGX albedo over 0.99999 down to mu 0.05
SINGULAR_ALPHA2 = 1e-7
GGX, MULTI_GGX = 0, 1  # Scene.mat_distribution (a scene without it: Multiscatter GGX, Blender's default)
_TAU = 2.0 * math.pi


@njit(**JIT)
def dot1(a, b):
    """The dot product of two 3-tuples (optics and kernels call this one: LLVM inlines it)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(**JIT)
def lambda1(cos, a2):
    """Smith's Lambda of GGX (alpha^2 = a2) for a direction of cosine cos with the normal (either
    sign)."""
    c2 = cos * cos
    if not c2 > 0.0:
        return 1e30
    t = a2 * (1.0 / c2 - 1.0)
    return 0.5 * (math.sqrt(1.0 + (t if t > 0.0 else 0.0)) - 1.0)


@njit(**JIT)
def frame1(n):
    """Two unit tangents completing the unit n to an orthonormal frame (Duff et al. 2017)."""
    s = 1.0 if n[2] >= 0.0 else -1.0
    a = -1.0 / (s + n[2])
    b = n[0] * n[1] * a
    return (1.0 + s * n[0] * n[0] * a, s * b, -s * n[0]), (b, s + n[1] * n[1] * a, -n[1])


@njit(inline="always", **JIT)
def visible_normal1(w, n, alpha, u1, u2):
    """A microfacet normal of GGX (alpha) about the unit n, drawn from the normals visible from the
    unit w (w.n > 0) with the uniform numbers u1, u2 (Heitz 2018): a unit vector on n's side."""
    t, bt = frame1(n)
    vx, vy, vz = alpha * dot1(w, t), alpha * dot1(w, bt), dot1(w, n)
    lv = math.sqrt(vx * vx + vy * vy + vz * vz)
    vx, vy, vz = vx / lv, vy / lv, vz / lv
    lensq = vx * vx + vy * vy
    if lensq > 1e-14:
        inv = 1.0 / math.sqrt(lensq)
        t1 = (-vy * inv, vx * inv, 0.0)
    else:
        t1 = (1.0, 0.0, 0.0)
    t2 = (vy * t1[2] - vz * t1[1], vz * t1[0] - vx * t1[2], vx * t1[1] - vy * t1[0])
    r = math.sqrt(u1)
    phi = _TAU * u2
    p1, p2 = r * math.cos(phi), r * math.sin(phi)
    s = 0.5 * (1.0 + vz)
    q = 1.0 - p1 * p1
    p2 = (1.0 - s) * math.sqrt(q if q > 0.0 else 0.0) + s * p2
    q = 1.0 - p1 * p1 - p2 * p2
    p3 = math.sqrt(q if q > 0.0 else 0.0)
    hx = alpha * (p1 * t1[0] + p2 * t2[0] + p3 * vx)
    hy = alpha * (p1 * t1[1] + p2 * t2[1] + p3 * vy)
    hz = p1 * t1[2] + p2 * t2[2] + p3 * vz
    hz = hz if hz > 0.0 else 0.0
    lh = math.sqrt(hx * hx + hy * hy + hz * hz)
    if not lh > 0.0:
        return n
    hx, hy, hz = hx / lh, hy / lh, hz / lh
    return (hx * t[0] + hy * bt[0] + hz * n[0], hx * t[1] + hy * bt[1] + hz * n[1],
            hx * t[2] + hy * bt[2] + hz * n[2])


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


# ------------------------------------------------------------------ tables
def alphas(scene) -> np.ndarray:
    """(M,) each material's GGX alpha where it is a rough mirror or glass (alpha^2 above
    SINGULAR_ALPHA2), else 0 (a perfect one; a diffuse's Scene.mat_roughness is its own)."""
    kind = np.asarray(scene.mat_kind)
    a = np.clip(np.asarray(scene.mat_roughness, np.float64), 0.0, 1.0) ** 2
    spec = (kind == S.CONDUCTOR) | (kind == S.DIELECTRIC)
    return np.ascontiguousarray(np.where(spec & (a * a > SINGULAR_ALPHA2), a, 0.0))


def distributions(scene) -> np.ndarray:
    """(M,) Scene.mat_distribution (GGX or MULTI_GGX); Multiscatter GGX where the scene does not say."""
    d = np.asarray(getattr(scene, "mat_distribution", np.zeros(0, np.int64)), np.int64)
    return d if d.shape == (len(scene.mat_kind),) else np.full(len(scene.mat_kind), MULTI_GGX, np.int64)


def rough_materials(scene) -> np.ndarray:
    """(M,) bool: the rough mirrors and glass (alphas above 0)."""
    return alphas(scene) > 0


FINE_GRID = 256  # strata per axis of the visible normals for the energy tables (jittered: ~1e-4)
_CHUNK = 8  # cosines per pass


def fine_mean(mu: np.ndarray, alpha: float, f) -> np.ndarray:
    """(K,) the mean over GGX's visible normals of f(hx, hz, wx, wz) (layer.visible_normals' arrays) for
    each cosine mu: FINE_GRID^2 strata jittered by a fixed generator (the same table every time).
    Midpoints converge as 1 / grid where the integrand jumps (a reflection dipping under the
    surface, total internal reflection): 0.3% high at 64 strata; these are within ~1e-4."""
    from .coat import visible_normals

    jitter = np.random.default_rng(12345).random((2, FINE_GRID * FINE_GRID))
    mu = np.asarray(mu, float)
    out = np.empty(len(mu))
    for a in range(0, len(mu), _CHUNK):
        out[a:a + _CHUNK] = f(*visible_normals(mu[a:a + _CHUNK], alpha, FINE_GRID, jitter)).mean(axis=1)
    return out


def visible_albedo(mu: np.ndarray, alpha: float) -> np.ndarray:
    """E(mu): the single-scattering albedo of a GGX mirror without Fresnel (Cycles' ggx_E)."""
    from .coat import lambda_ggx, shadowing

    a2 = max(float(alpha), 1e-4) ** 2

    def reflected(hx, hz, wx, wz):
        rz = 2.0 * (hx * wx + hz * wz) * hz - wz
        return shadowing(lambda_ggx(wz, a2), rz, rz > 0, a2)
    return fine_mean(mu, alpha, reflected)


def glass_albedo(mu: np.ndarray, alpha: float, eta: float) -> np.ndarray:
    """The single-scattering albedo of a GGX glass (reflection and refraction, the dielectric
    Fresnel at the microfacet included; no eta^2 radiance factor, as Cycles) for directions of
    cosine mu on the side from which the other side's index is eta times this one's."""
    from .coat import lambda_ggx, shadowing
    from .optics import fresnel_dielectric

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
    from .optics import f82_terms

    schlick, scale = f82_terms(f0)
    b = scale * (schlick - f82)
    return np.clip(f0 + (1.0 - f0) / 21.0 - b / 126.0, 0.0, 1.0)


def energy_tables(scene) -> np.ndarray:
    """(M, 2, MU_STEPS + 1, 3): Multiscatter GGX's factor per material, eye outside (0) or inside
    a glass (1), at mu = 0, 1/MU_STEPS, ..., 1 (energy_gain1); ones for the rest (smooth, GGX, a
    Refraction BSDF: Cycles compensates none of these)."""
    from .coat import MU_STEPS
    from .optics import _tinted_glass, fresnel_dielectric, metal, specular_weights

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
                    fss = np.array(_tinted_glass((f, f, f), eta, tuple(float(v) for v in row), False)) \
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


# ------------------------------------------------------------------ who takes a rough surface's paths
def rough_objects(scene) -> np.ndarray:
    """(O,) bool: the objects with a rough mirror or glass on some face, kept by the scene while its
    materials stay the same. The manifold walks leave them out (walk_casters): a walk solves for a
    perfect mirror's or glass's path, which a rough surface does not have; every path through one
    goes to the photons (reference.walked_casters)."""
    rm = rough_materials(scene)
    O = len(scene.object_names)
    if not rm.any() or scene.n_tris == 0:
        return np.zeros(O, bool)
    return scene.derived(("rough_objects", rm.tobytes()),
                         lambda: np.bincount(scene.tri_object[rm[scene.tri_material]], minlength=O) > 0)


def rough_casters(scene, casters: np.ndarray) -> np.ndarray:
    """(O,) bool: the planned casters that are rough (their paths: the photons')."""
    return np.asarray(casters, bool) & rough_objects(scene)


def walk_casters(scene, casters: np.ndarray) -> np.ndarray:
    """(O,) bool: the planned casters the walks take (the smooth ones: rough_objects')."""
    return np.asarray(casters, bool) & ~rough_objects(scene)
