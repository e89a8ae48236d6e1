"""Light emission in Cycles' conventions, aimed at the caustic casters.

Units (measured against Cycles, see testing-against-cycles.md):
- point / spot: power P watts of a sphere light of radius r (radiance
  P / (4 pi^2 r^2)); a spot is a point light masked by its cone (power is not
  concentrated into the cone);
- area: one-sided radiance P / (pi A) along the light's local -Z;
- sun: strength S is the irradiance on a plane facing the sun.

A caustic path starts light -> caster, so photons are only emitted towards the
bounding spheres of the casters ("targets"). Directions are drawn from a
mixture of the cones around the targets and weighted by the mixture's density,
which counts overlapping cones, so the estimate stays unbiased.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import scene as S
from .vec import concentric_disk, cross, dot, frame, normalize, to_world, uniform_cone


@dataclass
class Photons:
    o: np.ndarray  # (N,3) origins
    d: np.ndarray  # (N,3) unit directions
    w: np.ndarray  # (N,3) flux carried by each photon (already divided by N)
    soft_center: np.ndarray | None = None  # soft-falloff point/spot light: its centre and radius;
    soft_radius: float = 0.0  # the first hit's weight takes soft_falloff_factor()


def _smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def soft_falloff_factor(center, radius, x):
    """Cycles' soft falloff (the default for point and spot lights): towards a
    surface point x the light acts as a disk of radius r facing x, and its
    intensity is scaled by d^2 / (d^2 + r^2), d = |x - centre| (measured
    against Cycles, see the issue 2 note)."""
    d2 = dot(x - center, x - center)
    return d2 / (d2 + radius * radius)


def light_axis(scene, li: int) -> np.ndarray:
    """The unit direction light li points along (its local -Z): a spot's cone axis, a sun's light."""
    m = scene.light_matrix[li]
    return -m[:3, 2] / np.linalg.norm(m[:3, 2])


def spot_mask(scene, li: int, d: np.ndarray) -> np.ndarray:
    """Cycles 4.x spot attenuation of directions d leaving the light."""
    axis = light_axis(scene, li)
    cos_half = math.cos(0.5 * scene.light_spot_size[li])
    blend = scene.light_spot_blend[li]
    c = dot(d, axis)
    if blend <= 0 or cos_half >= 1.0:
        return (c > cos_half).astype(float)
    return _smoothstep((c - cos_half) / ((1.0 - cos_half) * blend))


def area_light_shape(scene, li: int):
    """(center, x axis, y axis, normal = emission direction, half sizes, area)."""
    m = scene.light_matrix[li]
    ax = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)
    sx, sy = scene.light_size[li]
    shape = scene.light_shape[li]
    if shape in (S.SQUARE, S.DISK):
        sy = sx
    area = sx * sy if shape in (S.SQUARE, S.RECTANGLE) else math.pi * sx * sy / 4.0
    return m[:3, 3].copy(), ax[:, 0], ax[:, 1], -ax[:, 2], 0.5 * sx, 0.5 * sy, area


def area_light_points(scene, li: int, n: int, rng) -> np.ndarray:
    """Points uniform in area on an area light's square, rectangle, disk or ellipse."""
    cen, ex, ey, _, hx, hy, _ = area_light_shape(scene, li)
    u1, u2 = rng.random(n), rng.random(n)
    if scene.light_shape[li] in (S.DISK, S.ELLIPSE):
        a, b = concentric_disk(u1, u2)
    else:
        a, b = 2 * u1 - 1, 2 * u2 - 1
    return cen + (a * hx)[:, None] * ex + (b * hy)[:, None] * ey


def _cone_mixture(origin, targets, n, rng, grow=0.0):
    """Directions from origin(s) towards a mixture of target spheres.

    origin: (3,) or (n,3); targets: (K,4) centre+radius; grow widens every
    sphere (for sphere lights). Returns directions (n,3) and their mixture
    density (n,) in solid angle."""
    o = np.broadcast_to(np.asarray(origin, float), (n, 3))
    K = len(targets)
    cen, rad = targets[:, :3], targets[:, 3] + grow
    # cone half-angle cosines per (lane, target)
    dist = np.sqrt(((cen[None, :, :] - o[:, None, :]) ** 2).sum(-1))  # (n,K)
    sin_a = np.clip(np.divide(rad[None, :], dist, out=np.full_like(dist, 2.0), where=dist > 0), 0, 2)
    full = sin_a >= 1.0
    cos_max = np.where(full, -1.0, np.sqrt(np.maximum(0.0, 1.0 - sin_a**2)))
    omega = 2.0 * math.pi * (1.0 - cos_max)  # (n,K)
    probs = np.full(K, 1.0 / K)
    if K > 1:  # prefer large cones (as seen from the first origin)
        probs = omega[0] / omega[0].sum()
    k = rng.choice(K, size=n, p=probs) if K > 1 else np.zeros(n, np.int64)
    u1, u2 = rng.random(n), rng.random(n)
    axis = normalize(cen[k] - o)
    axis = np.where((dist[np.arange(n), k] > 0)[:, None], axis, np.array([0.0, 0.0, 1.0]))
    s, t = frame(axis)
    d = to_world(uniform_cone(u1, u2, cos_max[np.arange(n), k]), s, t, axis)
    # mixture density: sum over cones containing d
    to_c = normalize(cen[None, :, :] - o[:, None, :])
    inside = (dot(d[:, None, :], to_c) >= cos_max - 1e-12) | full
    pdf = (inside * (probs[None, :] / omega)).sum(1)
    return d, pdf


def emit(scene, li: int, targets: np.ndarray, n: int, rng: np.random.Generator) -> Photons:
    """n photons of light li towards the target spheres (K,4). Weights include 1/n."""
    typ = scene.light_type[li]
    color = scene.light_color[li]
    m = scene.light_matrix[li]
    c = m[:3, 3]
    if typ in (S.POINT, S.SPOT):
        r = float(scene.light_radius[li])
        d, pdf = _cone_mixture(c, targets, n, rng, grow=r)
        if r > 0:
            s, t = frame(d)
            a, b = concentric_disk(rng.random(n), rng.random(n))
            h = np.sqrt(np.maximum(0.0, 1.0 - a * a - b * b))
            o = c + r * (a[:, None] * s + b[:, None] * t + h[:, None] * d)
        else:
            o = np.broadcast_to(c, (n, 3)).copy()
        intensity = color / (4.0 * math.pi)  # W/sr for the whole sphere, = L pi r^2
        w = intensity[None, :] / (pdf * n)[:, None]
        if typ == S.SPOT:
            w = w * spot_mask(scene, li, d)[:, None]
        if scene.light_soft_falloff[li] and r > 0:
            return Photons(o, d, w, soft_center=c.copy(), soft_radius=r)
        return Photons(o, d, w)
    if typ == S.AREA:
        cen, ex, ey, nrm, hx, hy, area = area_light_shape(scene, li)
        o = area_light_points(scene, li, n, rng)
        d, pdf = _cone_mixture(o, targets, n, rng)
        cos_l = np.maximum(0.0, dot(d, nrm))
        radiance = color / (math.pi * area)
        w = radiance[None, :] * (cos_l * area / (pdf * n))[:, None]
        return Photons(o, d, w)
    if typ == S.SUN:
        axis = light_axis(scene, li)
        half = 0.5 * float(scene.light_angle[li])
        if half > 0:
            s, t = frame(np.broadcast_to(axis, (n, 3)))
            d = to_world(uniform_cone(rng.random(n), rng.random(n), math.cos(half)), s, t,
                         np.broadcast_to(axis, (n, 3)))
        else:
            d = np.broadcast_to(axis, (n, 3)).copy()
        K = len(targets)
        area_k = math.pi * targets[:, 3] ** 2
        probs = area_k / area_k.sum()
        k = rng.choice(K, size=n, p=probs) if K > 1 else np.zeros(n, np.int64)
        s, t = frame(d)
        a, b = concentric_disk(rng.random(n), rng.random(n))
        rk = targets[k, 3]
        p_plane = targets[k, :3] + rk[:, None] * (a[:, None] * s + b[:, None] * t)
        # density of that point in the plane perpendicular to d: all discs containing it
        rel = p_plane[:, None, :] - targets[None, :, :3]
        along = dot(rel, d[:, None, :])
        perp2 = dot(rel, rel) - along**2
        inside = perp2 <= targets[None, :, 3] ** 2 * (1 + 1e-12)
        pdf = (inside * (probs / area_k)[None, :]).sum(1)
        far = 2.0 * (scene.scale + float(np.abs(targets[:, :3]).max()))
        o = p_plane - far * d
        w = color[None, :] / (pdf * n)[:, None]
        return Photons(o, d, w)
    raise ValueError(f"light '{scene.light_names[li]}': unknown type {typ}")


def light_covers(scene, li: int, center: np.ndarray, radius: float) -> bool:
    """Can light li reach any point of the sphere (center, radius) at all?"""
    typ = scene.light_type[li]
    m = scene.light_matrix[li]
    if typ == S.SPOT:
        axis = light_axis(scene, li)
        v = center - m[:3, 3]
        dist = float(np.linalg.norm(v))
        r = radius + float(scene.light_radius[li])
        if dist <= r:
            return True
        ang = math.acos(np.clip(np.dot(v / dist, axis), -1, 1)) - math.asin(min(1.0, r / dist))
        return ang < 0.5 * scene.light_spot_size[li]
    if typ == S.AREA:
        cen, ex, ey, nrm, hx, hy, _ = area_light_shape(scene, li)
        reach = float(np.dot(center - cen, nrm)) + radius
        return reach > 0
    return True


def _sphere_hit(o, d, c, r):
    """Nearest positive t where rays o + t d (unit d) enter the sphere (c, r); inf on a miss."""
    oc = o - c
    b = dot(oc, d)
    cc = dot(oc, oc) - r * r
    disc = b * b - cc
    ok = disc >= 0
    sq = np.sqrt(np.where(ok, disc, 0.0))
    t0, t1 = -b - sq, -b + sq
    t = np.where(t0 > 0, t0, t1)
    return np.where(ok & (t > 0) & (cc > 0), t, np.inf)


def light_radiance(scene, li: int, o: np.ndarray, d: np.ndarray, escaped: np.ndarray | None = None):
    """Radiance a ray o + t d sees from light li, and the distance (inf if the ray
    misses it). escaped marks rays that left the scene (needed for the sun).
    Point lights of radius 0 cannot be hit (delta lights)."""
    n = len(o)
    L = np.zeros((n, 3))
    t = np.full(n, np.inf)
    typ = scene.light_type[li]
    color = scene.light_color[li]
    m = scene.light_matrix[li]
    if typ in (S.POINT, S.SPOT):
        r = float(scene.light_radius[li])
        if r <= 0:
            return L, t
        t = _sphere_hit(o, d, m[:3, 3], r)
        val = color / (4.0 * math.pi**2 * r * r)
        L = np.where(np.isfinite(t)[:, None], val, 0.0)
        if scene.light_soft_falloff[li]:
            L = L * soft_falloff_factor(m[:3, 3], r, o)[:, None]
        if typ == S.SPOT:
            L = L * spot_mask(scene, li, -d)[:, None]
        return L, t
    if typ == S.AREA:
        cen, ex, ey, nrm, hx, hy, area = area_light_shape(scene, li)
        den = dot(d, nrm)
        front = den < 0
        tt = np.divide(dot(cen - o, nrm), den, out=np.full(n, -1.0), where=front)
        q = o + tt[:, None] * d - cen
        a, b = dot(q, ex) / hx, dot(q, ey) / hy
        if scene.light_shape[li] in (S.DISK, S.ELLIPSE):
            inside = a * a + b * b <= 1.0
        else:
            inside = (np.abs(a) <= 1.0) & (np.abs(b) <= 1.0)
        hit = front & (tt > 0) & inside
        t = np.where(hit, tt, np.inf)
        L = np.where(hit[:, None], color / (math.pi * area), 0.0)
        return L, t
    if typ == S.SUN and escaped is not None:
        half = 0.5 * float(scene.light_angle[li])
        if half <= 0:
            return L, t
        axis = light_axis(scene, li)
        inside = escaped & (dot(-d, axis) >= math.cos(half))
        omega = 2.0 * math.pi * (1.0 - math.cos(half))
        L = np.where(inside[:, None], color / omega, 0.0)
        t = np.where(inside, 1e30, np.inf)
    return L, t
