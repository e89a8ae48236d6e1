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

Multiscatter GGX's energy compensation is energy.py's. The numpy forms here (lambda_ggx, shadowing,
visible_normals) serve the tables of energy.py and coat.py, which integrate over the visible normals.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..core.jit import JIT
from ..core.vec3 import dot1, frame1
from ..scene import arrays as S

# a smoother mirror or glass (alpha^2 = Roughness^4 at most this: Roughness 0.0178) is baked as a perfect one, so
# the walks take it. Cycles' own threshold (BSDF_ROUGHNESS_SQ_THRESH) is 2e-10, Roughness 0.0038; between the two
# its lobe is under alpha = 3.2e-4 rad wide (1.6 mm at 5 m) and a mirror's GGX albedo over 0.99999 down to mu 0.05
SINGULAR_ALPHA2 = 1e-7
GGX, MULTI_GGX = 0, 1  # Scene.mat_distribution (a scene without it: Multiscatter GGX, Blender's default)
_TAU = 2.0 * math.pi


@njit(**JIT)
def lambda1(cos, a2):
    """Smith's Lambda of GGX (alpha^2 = a2) for a direction of cosine cos with the normal (either
    sign)."""
    c2 = cos * cos
    if not c2 > 0.0:
        return 1e30
    t = a2 * (1.0 / c2 - 1.0)
    return 0.5 * (math.sqrt(1.0 + (t if t > 0.0 else 0.0)) - 1.0)


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


MU_STEPS = 64  # the table's cosines: 0, 1/64, ..., 1


_GRID = 64  # stratified visible-normal samples per axis


def lambda_ggx(cos, a2):
    """Smith's Lambda of GGX (alpha^2 = a2) for directions of cosine cos (> 0)."""
    c2 = np.maximum(cos * cos, 1e-12)
    return 0.5 * (np.sqrt(1.0 + a2 * np.maximum(1.0 / c2 - 1.0, 0.0)) - 1.0)


def shadowing(lam_in, cos_out, ok, a2):
    """Smith's height-correlated G2 over the masking G1 of the sampling direction, (1 + L_in) /
    (1 + L_in + L_out), where ok (a lobe leaving on its side), else 0: what a visible-normal sample
    keeps (lam_in: lambda_ggx of the sampling direction; cos_out: the new direction's cosine)."""
    return np.where(ok, (1.0 + lam_in) / (1.0 + lam_in + lambda_ggx(np.where(ok, cos_out, 1.0), a2)), 0.0)


def visible_normals(mu: np.ndarray, alpha: float, grid: int = _GRID, jitter=None):
    """Stratified samples (grid^2, the same for every mu) of GGX's visible normals (Heitz 2018) for
    directions w of cosines mu in the x-z plane: (hx, hz) of the normals (K, S) and (wx, wz) of the
    directions (K, 1); the normals' y parts are not needed by the albedos. jitter: (2, grid^2)
    offsets in [0, 1) within the strata (None: their midpoints)."""
    u = (np.arange(grid) + 0.5) / grid
    u1, u2 = (x.ravel() for x in np.meshgrid(u, u, indexing="ij"))
    if jitter is not None:
        u1, u2 = u1 + (jitter[0] - 0.5) / grid, u2 + (jitter[1] - 0.5) / grid
    # concentric mapping of the unit square onto the disk (Shirley and Chiu)
    a, b = 2.0 * u1 - 1.0, 2.0 * u2 - 1.0
    big = np.abs(a) > np.abs(b)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(big, a, b)
        phi = np.where(big, (math.pi / 4) * b / np.where(a == 0, 1, a),
                       math.pi / 2 - (math.pi / 4) * a / np.where(b == 0, 1, b))
    t1, t2 = r * np.cos(phi), r * np.sin(phi)
    alpha = max(float(alpha), 1e-4)
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
    return hx / hl, hz / hl, wo_x, m
