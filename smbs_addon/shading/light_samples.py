"""A chain's light end: a sample on a light (a point with tangents, or a direction for a sun or the
world), its emission at a solution, and which lights a ray can hit at all.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.vec import cross, dot, frame, normalize, to_world, uniform_cone
from ..scene import arrays as S
from .lights import (area_light_points, cone_solid_angle, distant_cone, env_map, has_spread, mesh_light_points,
                     soft_falloff_factor, spot_mask, spread_factor)


@dataclass
class LightEnd:
    """The fixed end of a chain: a point y with tangents, or a direction."""

    directional: bool
    y: np.ndarray  # (N,3) point, or unit direction towards the light when directional
    ys: np.ndarray  # (N,3) tangent 1 (orthonormal)
    yt: np.ndarray  # (N,3) tangent 2

    def take(self, idx) -> "LightEnd":
        return LightEnd(self.directional, self.y[idx], self.ys[idx], self.yt[idx])


def sphere_cap(scene, li, lo, hi):
    """The part of a sphere light (point or spot with a radius) that can shine on
    anything in the box [lo, hi] (every caster): (unit axis, cos of the half-angle),
    or None for the whole sphere. A point y = c + r u faces a point x only if
    (x - c).u > r; over a ball of radius R around the box's centre at distance d that
    needs u.axis > (r - R) / d, so outside this cap every sample contributes nothing."""
    if scene.light_type[li] not in (S.POINT, S.SPOT):
        return None
    r = float(scene.light_radius[li])
    c = scene.light_matrix[li][:3, 3]
    cen = 0.5 * (lo + hi)
    R = 0.5 * float(np.linalg.norm(hi - lo))
    d = float(np.linalg.norm(cen - c))
    if r <= 0 or d <= 0 or not np.all(np.isfinite([R, d])):
        return None
    cos_t = (r - R) / d
    if not (-1.0 < cos_t < 1.0):
        return None
    return (cen - c) / d, cos_t


def sample_light(scene, li, n, rng, cap=None) -> LightEnd:
    """One light sample per lane: a point on the light (uniform in area; on a sphere
    light, uniform over ``cap`` when given), or a sun's or the world's direction (uniform in
    its cone; the world's is the whole sphere, or as bright as its map, lights.EnvMap).
    Tangents are set at the solution."""
    typ = scene.light_type[li]
    m = scene.light_matrix[li]
    z = np.zeros((n, 3))
    env = env_map(scene, li)
    if typ in S.DISTANT and env is not None:
        return LightEnd(True, env.sample(rng.random(n), rng.random(n), rng.random(n)), z, z.copy())
    if typ in S.DISTANT:
        axis, half, _ = distant_cone(scene, li)
        to_sun = np.broadcast_to(-axis, (n, 3)).copy()
        if half > 0:
            s, t = frame(to_sun)
            to_sun = to_world(uniform_cone(rng.random(n), rng.random(n), math.cos(half)), s, t, to_sun)
        return LightEnd(True, to_sun, z, z.copy())
    if typ == S.AREA:
        return LightEnd(False, area_light_points(scene, li, n, rng), z, z.copy())
    if typ == S.MESH:  # its tangents are its triangle's, known now
        y, ng = mesh_light_points(scene, li, n, rng)
        ys, yt = frame(ng)
        return LightEnd(False, y, ys, yt)
    c = m[:3, 3]
    r = float(scene.light_radius[li])
    if r > 0:
        if cap is None:
            zc = 1.0 - 2.0 * rng.random(n)
        else:
            zc = 1.0 - (1.0 - cap[1]) * rng.random(n)
        phi = 2 * math.pi * rng.random(n)
        rr = np.sqrt(np.maximum(0.0, 1 - zc * zc))
        u = np.stack([rr * np.cos(phi), rr * np.sin(phi), zc], -1)
        if cap is not None:
            axis = np.broadcast_to(cap[0], (n, 3))
            s, t = frame(axis)
            u = to_world(u, s, t, axis)
        return LightEnd(False, c + r * u, z, z.copy())
    return LightEnd(False, np.broadcast_to(c, (n, 3)).copy(), z, z.copy())


def light_can_be_hit(scene, li) -> bool:
    """Whether a ray can hit light li: an area light, a sun with an angle, a point or spot
    light with a radius, a mesh light (delta lights can only be connected to, by the walks)."""
    typ = scene.light_type[li]
    if typ == S.AREA:
        return True
    if typ == S.MESH:  # as a surface (lights.light_radiance)
        return True
    if typ in S.DISTANT:  # a cone too narrow for float64 is a delta light (light_radiance)
        return cone_solid_angle(distant_cone(scene, li)[1]) > 0
    return bool(scene.light_radius[li] > 0)


def light_end_at_solution(scene, li, light: LightEnd, xk):
    """Tangents of the light end at the solution (for the geometric term) and
    the emission factor L_e / p per lane, zero where the light does not face xk."""
    typ = scene.light_type[li]
    color = scene.light_color[li]
    n = len(xk)
    if typ in S.DISTANT:  # L / p over the cone of directions: the strength, or the map's L / p
        ys, yt = frame(light.y)
        env = env_map(scene, li)
        if env is not None:
            return LightEnd(True, light.y, ys, yt), env.value(light.y)
        return LightEnd(True, light.y, ys, yt), np.broadcast_to(distant_cone(scene, li)[2], (n, 3)).copy()
    m = scene.light_matrix[li]
    if typ == S.MESH:  # (L) / (1 / A) from both sides, the tangents those sample_light drew
        nrm = cross(light.ys, light.yt)
        facing = dot(xk - light.y, nrm) != 0
        e = np.where(facing[:, None], color * scene.mesh_light(li)[4], 0.0)
        return LightEnd(False, light.y, light.ys, light.yt), e
    if typ == S.AREA:
        ax = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)
        nrm = -ax[:, 2]
        facing = dot(xk - light.y, nrm) > 0
        ys = np.broadcast_to(ax[:, 0], (n, 3)).copy()
        yt = np.broadcast_to(ax[:, 1], (n, 3)).copy()
        e = np.where(facing[:, None], color / math.pi, 0.0)  # (P / (pi A)) / (1 / A)
        if has_spread(scene, li):  # Cycles' soft-box spread, along the light's last segment
            e = e * spread_factor(scene, li, dot(normalize(xk - light.y), nrm))[:, None]
        return LightEnd(False, light.y, ys, yt), e
    r = float(scene.light_radius[li])
    c = m[:3, 3]
    if r > 0:
        nrm = normalize(light.y - c)
        facing = dot(xk - light.y, nrm) > 0
        e = np.where(facing[:, None], color / math.pi, 0.0)  # (P / (4 pi^2 r^2)) / (1 / (4 pi r^2))
    else:
        nrm = normalize(xk - c)  # a point light: the tangent plane faces the chain
        e = np.broadcast_to(color / (4.0 * math.pi), (n, 3)).copy()  # intensity, per unit dA_perp
    ys, yt = frame(nrm)
    if typ == S.SPOT:  # Cycles masks the ray leaving the light's point, not its centre (the light tracer too)
        e = e * spot_mask(scene, li, normalize(xk - light.y))[:, None]
    if r > 0 and scene.light_soft_falloff[li]:
        e = e * soft_falloff_factor(c, r, xk)[:, None]
    return LightEnd(False, light.y, ys, yt), e
