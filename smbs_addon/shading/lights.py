"""Light emission in Cycles' conventions, aimed at the caustic casters.

Units (measured against Cycles, see testing-against-cycles.md):
- point / spot: power P watts of a sphere light of radius r (radiance
  P / (4 pi^2 r^2)); a spot is a point light masked by its cone (power is not
  concentrated into the cone);
- area: one-sided radiance P / (pi A) along the light's local -Z;
- sun: strength S is the irradiance on a plane facing the sun;
- world (a constant Background colour): radiance L from every direction, a sun
  whose disc fills the sky (distant_cone);
- mesh (an object's triangles of an Emission shader): radiance L = Color x Strength
  from both sides of every triangle (Cycles' emissive closure is two-sided).

A caustic path starts light -> caster, so photons are only emitted towards the
bounding spheres of the casters ("targets"). Directions are drawn from a
mixture of the cones around the targets and weighted by the mixture's density,
which counts overlapping cones, so the estimate stays unbiased.
"""
from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..scene import arrays as S
from ..scene.geometry import area_points
from ..core.jit import JIT
from ..core.vec3 import frame1
from ..core.vec import concentric_disk, dot
from ..core import embree


@dataclass
class Photons:
    o: np.ndarray  # (N,3) origins
    d: np.ndarray  # (N,3) unit directions
    w: np.ndarray  # (N,3) flux carried by each photon (already divided by N)
    soft_center: np.ndarray | None = None  # soft-falloff point/spot light: its centre and radius;
    soft_radius: float = 0.0  # the first hit's weight takes soft_falloff_factor()
    # the rays that see the light (S.RAY_* bits, its Ray Visibility): the photon's first event, the
    # camera path's last, must cast a ray of such a kind (kernels._photon_rows)
    visibility: int = S.RAY_ALL
    # (O,) bool: the objects the light lights (Light Linking): the photon's first event, the camera
    # path's last before the light, must be on one. None: any
    lit: np.ndarray | None = None
    # (O,) bool: the objects that do not shadow the light (Shadow Linking): the photon's first segment
    # passes them (or meets one at random, where its path could go on from it). None: none
    unshadowing: np.ndarray | None = None


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


class EnvMap:
    """A world's Environment Texture as a light (S.WORLD with Scene.world_map): radiance from an
    equirectangular map in Cycles' convention, measured with Cycles (a map holding each pixel's own
    coordinates, seen along 6 directions, with and without a Mapping node's turn:
    tests/test_world.py): a ray of direction d looks up m = R d (R: Scene.world_map_rotation) at
    u = 0.5 - atan2(m_y, m_x) / 2 pi, v = 1 - acos(m_z) / pi, pixel row 0 at the bottom. Each pixel
    is constant (Cycles interpolates linearly: a pixel's width of blur apart). Directions are drawn
    in proportion to a pixel's luminance x solid angle, then uniformly within it in azimuth and
    cos(theta)."""

    def __init__(self, image, rotation, scale):
        img = np.asarray(image, np.float64) * np.asarray(scale, np.float64)
        self.H, self.W = img.shape[:2]
        self.image = img
        self.R = np.asarray(rotation, np.float64)
        self.z = np.cos(math.pi * (1.0 - np.arange(self.H + 1) / self.H))  # cos(theta) at the rows' edges
        self.omega = (2.0 * math.pi / self.W) * np.diff(self.z)  # a pixel's solid angle, row by row
        p = (img.mean(axis=2) * self.omega[:, None]).ravel()
        self.power = float(p.sum())  # the luminance over the sphere: the most any plane receives
        self.p = p / self.power if self.power > 0 else p
        self.cdf = np.cumsum(self.p)

    def _pixel(self, to_light):
        """(rows, columns) of the pixels the unit directions to_light (N,3) look up."""
        m = np.asarray(to_light, np.float64) @ self.R.T
        u = np.mod(0.5 - np.arctan2(m[:, 1], m[:, 0]) / (2.0 * math.pi), 1.0)
        v = 1.0 - np.arccos(np.clip(m[:, 2], -1.0, 1.0)) / math.pi
        return (np.minimum((v * self.H).astype(np.int64), self.H - 1),
                np.minimum((u * self.W).astype(np.int64), self.W - 1))

    def _lookup(self, to_light):
        j, i = self._pixel(to_light)
        return self.image[j, i], self.p[j * self.W + i] / self.omega[j]

    def radiance(self, to_light) -> np.ndarray:
        """(N,3) radiance arriving from the unit directions to_light (N,3)."""
        return self._lookup(to_light)[0]

    def pdf(self, to_light) -> np.ndarray:
        """(N,) the density of sample() per unit solid angle at the directions to_light."""
        return self._lookup(to_light)[1]

    def value(self, to_light) -> np.ndarray:
        """(N,3) radiance over density of sampled directions (0 where a direction's pixel has none)."""
        L, pdf = self._lookup(to_light)
        return np.divide(L, pdf[:, None], out=np.zeros_like(L), where=pdf[:, None] > 0)

    def sample(self, u1, u2, u3) -> np.ndarray:
        """(N,3) unit directions towards the light, from three (N,) uniforms."""
        k = np.minimum(np.searchsorted(self.cdf, u1 * self.cdf[-1], side="right"), self.cdf.size - 1)
        j, i = np.divmod(k, self.W)
        z = self.z[j] + u2 * (self.z[j + 1] - self.z[j])
        phi = math.pi - 2.0 * math.pi * (i + u3) / self.W
        r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
        return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1) @ self.R  # R^T m, row by row


def env_map(scene, li: int):
    """Light li's EnvMap: a world with an Environment Texture; None for any other light."""
    if scene.light_type[li] != S.WORLD or not np.asarray(scene.world_map).size:
        return None
    return scene.derived(("env_map", li), lambda: EnvMap(scene.world_map, scene.world_map_rotation,
                                                         scene.light_color[li]))


def distant_cone(scene, li: int):
    """A light at infinity (S.DISTANT) as the cone of directions its light travels along:
    (unit axis, half-angle, strength S), S in a sun's units: radiance S / (2 pi (1 - cos half))
    inside the cone. A world of constant colour is the whole sphere: half pi, S = 4 pi L."""
    color = np.asarray(scene.light_color[li], np.float64)
    if scene.light_type[li] == S.WORLD:
        return np.array([0.0, 0.0, -1.0]), math.pi, 4.0 * math.pi * color
    return light_axis(scene, li), 0.5 * float(scene.light_angle[li]), color


def cone_solid_angle(half: float) -> float:
    """The solid angle 2 pi (1 - cos half) of a cone of half-angle half (distant_cone's); 0 where the
    cone is too narrow for float64 (cos(half) is 1): a delta light, which no ray meets."""
    return 2.0 * math.pi * (1.0 - math.cos(half)) if half > 0 else 0.0


def spot_mask(scene, li: int, d: np.ndarray) -> np.ndarray:
    """Cycles 4.x spot attenuation of directions d leaving the light."""
    axis = light_axis(scene, li)
    cos_half = math.cos(0.5 * scene.light_spot_size[li])
    blend = scene.light_spot_blend[li]
    c = dot(d, axis)
    if blend <= 0 or cos_half >= 1.0:
        return (c > cos_half).astype(float)
    return _smoothstep((c - cos_half) / ((1.0 - cos_half) * blend))


SPREAD_EPS = 1e-6  # radians: a spread this close to 180 degrees is 180 degrees (Blender's default)


# An area light's shape (area_light_shape): its centre, x and y axes, normal (the emission direction),
# half sizes along x and y, area
AreaShape = namedtuple("AreaShape", "cen ex ey nrm hx hy area")

# What photons are emitted towards (the emitters' aim): target spheres (K,4) (centre, radius), the
# cumulative probabilities of picking each, and those probabilities
Targets = namedtuple("Targets", "spheres cdf probs")

# Where the emitters write their photons: origins, unit directions, weights (N,3) each
Emitted = namedtuple("Emitted", "o d w")


def area_light_shape(scene, li: int) -> AreaShape:
    """Area light li's shape (AreaShape)."""
    m = scene.light_matrix[li]
    ax = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)
    sx, sy = scene.light_size[li]
    shape = scene.light_shape[li]
    if shape in (S.SQUARE, S.DISK):
        sy = sx
    area = sx * sy if shape in (S.SQUARE, S.RECTANGLE) else math.pi * sx * sy / 4.0
    return AreaShape(m[:3, 3].copy(), ax[:, 0], ax[:, 1], -ax[:, 2], 0.5 * sx, 0.5 * sy, area)


def has_spread(scene, li: int) -> bool:
    """Does area light li's spread narrow its emission (below 180 degrees)?"""
    return bool(scene.light_spread[li] < math.pi - SPREAD_EPS)


def spread_factor(scene, li: int, cos_t: np.ndarray):
    """Cycles' soft-box spread of area light li (kernel/light/area.h,
    area_light_spread_attenuation; scene/light.cpp): its radiance leaving at angle t from its
    normal is P / (pi A) times max((tan h - tan t) N, 0), h half the spread and N = 1 / (tan h -
    h) (3 / h^3 below h = 0.05, Cycles' Taylor branch), so that the power stays P whatever the
    spread (on the axis at 30 degrees: 43.6x a lambertian light's radiance). 1 at 180 degrees
    (None: nothing to multiply). cos_t: cosine to the emission normal (the emission side > 0)."""
    if not has_spread(scene, li):
        return None
    h = 0.5 * float(scene.light_spread[li])  # > 0: plan.make_plan skips a spread of 0
    norm = 1.0 / (math.tan(h) - h) if h > 0.05 else 3.0 / h**3
    c = np.asarray(cos_t, np.float64)
    tan_t = np.sqrt(np.maximum(0.0, 1.0 - c * c)) / np.maximum(c, 1e-300)
    return np.where(c > 0, np.maximum((math.tan(h) - tan_t) * norm, 0.0), 0.0)


def area_light_points(scene, li: int, n: int, rng) -> np.ndarray:
    """Points uniform in area on an area light's square, rectangle, disk or ellipse."""
    cen, ex, ey, _, hx, hy, _ = area_light_shape(scene, li)
    u1, u2 = rng.random(n), rng.random(n)
    if scene.light_shape[li] in (S.DISK, S.ELLIPSE):
        a, b = concentric_disk(u1, u2)
    else:
        a, b = 2 * u1 - 1, 2 * u2 - 1
    return cen + (a * hx)[:, None] * ex + (b * hy)[:, None] * ey


def mesh_light_points(scene, li: int, n: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """Points uniform in area on MESH light li's triangles, and their unit geometric normals."""
    _, tv, ng, cdf, total = scene.mesh_light(li)
    y, j = area_points(tv, cdf, total, n, rng)
    return y, ng[j]


def shadow_tmax(scene, li: int, y, ys, yt, o, d, dist, eps):
    """How far the shadow ray o + t d towards light li's point y (dist from the vertex o was
    spawned from) may look: dist less eps, and for a mesh light, whose y lies on a triangle of
    the scene (tangents ys, yt), short of where the ray meets that triangle's plane: the ray
    runs eps off the line to y, and at normal incidence dist less eps is that plane to float32's
    precision."""
    tmax = dist * (1 - 1e-7) - eps
    if scene.light_type[li] != S.MESH:
        return tmax
    n = np.cross(ys, yt)
    den = dot(d, n)
    tp = np.divide(dot(y - o, n), den, out=np.full(len(o), np.inf), where=np.abs(den) > 1e-12)
    return np.minimum(tmax, tp * (1 - 1e-6) - eps)


# ------------------------------------------------------------------ emission, per photon
@njit(inline="always", **JIT)
def _around(x, y, z, axis):
    """The local direction (x, y, z) about a unit axis (vec.to_world in vec.frame's frame)."""
    s, t = frame1(axis)
    return (x * s[0] + y * t[0] + z * axis[0], x * s[1] + y * t[1] + z * axis[1], x * s[2] + y * t[2] + z * axis[2])


@njit(**JIT)
def _in_cone(u1, u2, cos_max, axis):
    """vec.uniform_cone about axis."""
    z = 1.0 - u1 * (1.0 - cos_max)
    r = math.sqrt(max(0.0, 1.0 - z * z))
    phi = 2.0 * math.pi * u2
    return _around(r * math.cos(phi), r * math.sin(phi), z, axis)


@njit(**JIT)
def _disk1(u1, u2):
    """vec.concentric_disk of one pair."""
    a, b = 2.0 * u1 - 1.0, 2.0 * u2 - 1.0
    if a == 0.0 and b == 0.0:
        return 0.0, 0.0
    if abs(a) > abs(b):
        r, phi = a, (math.pi / 4) * (b / a)
    else:
        r, phi = b, (math.pi / 2) - (math.pi / 4) * (a / b)
    return r * math.cos(phi), r * math.sin(phi)


@njit(**JIT)
def _pick(cdf, u):
    """The mixture component u picks (cdf: cumulative probabilities)."""
    return min(np.searchsorted(cdf, u * cdf[-1], side="right"), cdf.shape[0] - 1)


@njit(**JIT)
def _cone(o, targets, j, grow):
    """Light leaving o towards target sphere j (grown by grow): (unit axis, cos of the cone's
    half-angle (-1: o inside the sphere), its solid angle)."""
    v = (targets[j, 0] - o[0], targets[j, 1] - o[1], targets[j, 2] - o[2])
    dist = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    rad = targets[j, 3] + grow
    sin_a = min(max(rad / dist, 0.0), 2.0) if dist > 0 else 2.0
    cos_max = -1.0 if sin_a >= 1.0 else math.sqrt(max(0.0, 1.0 - sin_a * sin_a))
    axis = (v[0] / dist, v[1] / dist, v[2] / dist) if dist > 0 else (0.0, 0.0, 1.0)
    return axis, cos_max, 2.0 * math.pi * (1.0 - cos_max)


@njit(inline="always", **JIT)
def _cone_mixture1(u0, u1, u2, o, targets, cdf, probs, grow):
    """A direction from o towards a mixture of target spheres (component picked by u0 with
    probabilities probs), and the mixture's density in solid angle: every cone that holds the
    direction counts, so overlapping cones keep the estimate unbiased."""
    axis, cos_max, _ = _cone(o, targets, _pick(cdf, u0), grow)
    d = _in_cone(u1, u2, cos_max, axis)
    pdf = 0.0
    for j in range(targets.shape[0]):
        a, c, omega = _cone(o, targets, j, grow)
        if c <= -1.0 or d[0] * a[0] + d[1] * a[1] + d[2] * a[2] >= c - 1e-12:
            pdf += probs[j] / omega
    return d, pdf


@njit(**JIT)
def _emit_sphere(u, c, r, intensity, aim, out):
    """Point and spot lights (a sphere of radius r, 0: a point): directions towards the targets
    (aim: Targets) from the centre, origins on the hemisphere facing them; out (Emitted): w is
    flux / n."""
    targets, cdf, probs = aim.spheres, aim.cdf, aim.probs
    o, d, w = out.o, out.d, out.w
    n = u.shape[0]
    for i in range(n):
        oi = (c[0], c[1], c[2])
        di, pdf = _cone_mixture1(u[i, 0], u[i, 1], u[i, 2], oi, targets, cdf, probs, r)
        if r > 0:
            s, t = frame1(di)
            a, b = _disk1(u[i, 3], u[i, 4])
            h = math.sqrt(max(0.0, 1.0 - a * a - b * b))
            oi = (c[0] + r * (a * s[0] + b * t[0] + h * di[0]), c[1] + r * (a * s[1] + b * t[1] + h * di[1]),
                  c[2] + r * (a * s[2] + b * t[2] + h * di[2]))
        for k in range(3):
            o[i, k], d[i, k], w[i, k] = oi[k], di[k], intensity[k] / (pdf * n)


@njit(**JIT)
def _emit_area(u, shape, disk, radiance, aim, out):
    """Area lights (shape: AreaShape; disk: round): origins uniform on the light, directions
    towards the targets (aim: Targets), weighted by the cosine at the light, into out (Emitted)."""
    cen, ex, ey, nrm, hx, hy, area = shape.cen, shape.ex, shape.ey, shape.nrm, shape.hx, shape.hy, shape.area
    targets, cdf, probs = aim.spheres, aim.cdf, aim.probs
    o, d, w = out.o, out.d, out.w
    n = u.shape[0]
    for i in range(n):
        if disk:
            a, b = _disk1(u[i, 3], u[i, 4])
        else:
            a, b = 2.0 * u[i, 3] - 1.0, 2.0 * u[i, 4] - 1.0
        oi = (cen[0] + a * hx * ex[0] + b * hy * ey[0], cen[1] + a * hx * ex[1] + b * hy * ey[1],
              cen[2] + a * hx * ex[2] + b * hy * ey[2])
        di, pdf = _cone_mixture1(u[i, 0], u[i, 1], u[i, 2], oi, targets, cdf, probs, 0.0)
        cos_l = max(0.0, di[0] * nrm[0] + di[1] * nrm[1] + di[2] * nrm[2])
        for k in range(3):
            o[i, k], d[i, k], w[i, k] = oi[k], di[k], radiance[k] * (cos_l * area / (pdf * n))


@njit(**JIT)
def _emit_mesh(u, tv, ng, tri_cdf, total, radiance, eps, aim, out):
    """Mesh lights: origins uniform in area on the triangles (picked by u3 in proportion to their areas
    tri_cdf, u3 used again within the one picked), eps off the surface on the side the photon leaves,
    directions towards the targets (aim: Targets), weighted by the cosine at the light (both sides
    shine), into out (Emitted)."""
    targets, cdf, probs = aim.spheres, aim.cdf, aim.probs
    o, d, w = out.o, out.d, out.w
    n = u.shape[0]
    for i in range(n):
        x = u[i, 3] * total
        j = _pick(tri_cdf, u[i, 3])
        lo = tri_cdf[j - 1] if j > 0 else 0.0
        a = tri_cdf[j] - lo
        r = min(max((x - lo) / a, 0.0), 1.0) if a > 0 else 0.5
        su = math.sqrt(r)
        b1, b2 = u[i, 4] * su, 1.0 - su
        b0 = 1.0 - b1 - b2
        p = (b0 * tv[j, 0, 0] + b1 * tv[j, 1, 0] + b2 * tv[j, 2, 0],
             b0 * tv[j, 0, 1] + b1 * tv[j, 1, 1] + b2 * tv[j, 2, 1],
             b0 * tv[j, 0, 2] + b1 * tv[j, 1, 2] + b2 * tv[j, 2, 2])
        di, pdf = _cone_mixture1(u[i, 0], u[i, 1], u[i, 2], p, targets, cdf, probs, 0.0)
        c = di[0] * ng[j, 0] + di[1] * ng[j, 1] + di[2] * ng[j, 2]
        s = eps if c >= 0 else -eps
        for k in range(3):
            o[i, k], d[i, k] = p[k] + s * ng[j, k], di[k]
            w[i, k] = radiance[k] * (abs(c) * total / (pdf * n)) if pdf > 0 else 0.0


@njit(**JIT)
def _emit_sun(u, axis, half, color, aim, far, out):
    """Suns: directions in the sun's cone, then a point on a disc across one target sphere (aim:
    Targets; picked in proportion to its cross-section), its density counting every disc that holds
    it; the photon starts far behind it. Into out (Emitted)."""
    targets, cdf, probs = aim.spheres, aim.cdf, aim.probs
    o, d, w = out.o, out.d, out.w
    n = u.shape[0]
    ax = (axis[0], axis[1], axis[2])
    for i in range(n):
        di = _in_cone(u[i, 0], u[i, 1], math.cos(half), ax) if half > 0 else ax
        p, pdf = _across_targets(u[i, 2], u[i, 3], u[i, 4], di, targets, cdf, probs)
        for k in range(3):
            o[i, k], d[i, k], w[i, k] = p[k] - far * di[k], di[k], color[k] / (pdf * n)


@njit(**JIT)
def _emit_along(u, dirs, value, aim, far, out):
    """_emit_sun's photons along given directions dirs (N,3) (a world map's), each carrying value
    (N,3) (radiance over the direction's density)."""
    targets, cdf, probs = aim.spheres, aim.cdf, aim.probs
    o, d, w = out.o, out.d, out.w
    n = u.shape[0]
    for i in range(n):
        di = (dirs[i, 0], dirs[i, 1], dirs[i, 2])
        p, pdf = _across_targets(u[i, 2], u[i, 3], u[i, 4], di, targets, cdf, probs)
        for k in range(3):
            o[i, k], d[i, k], w[i, k] = p[k] - far * di[k], di[k], value[i, k] / (pdf * n)


@njit(inline="always", **JIT)
def _across_targets(u2, u3, u4, di, targets, cdf, probs):
    """A point on a disc across one target sphere, facing di (picked by u2 in proportion to the
    discs' areas), and its density per unit area, counting every disc that holds it."""
    j = _pick(cdf, u2)
    s, t = frame1(di)
    a, b = _disk1(u3, u4)
    rk = targets[j, 3]
    p = (targets[j, 0] + rk * (a * s[0] + b * t[0]), targets[j, 1] + rk * (a * s[1] + b * t[1]),
         targets[j, 2] + rk * (a * s[2] + b * t[2]))
    pdf = 0.0
    for m in range(targets.shape[0]):
        rel = (p[0] - targets[m, 0], p[1] - targets[m, 1], p[2] - targets[m, 2])
        along = rel[0] * di[0] + rel[1] * di[1] + rel[2] * di[2]
        perp2 = rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2] - along * along
        if perp2 <= targets[m, 3] ** 2 * (1 + 1e-12):
            pdf += probs[m] / (math.pi * targets[m, 3] ** 2)
    return p, pdf


def _cone_probs(origin, targets, grow=0.0):
    """Each target's share of the photons: its cone's solid angle seen from origin."""
    if len(targets) == 1:
        return np.ones(1)
    omega = np.array([_cone(origin, targets, j, grow)[2] for j in range(len(targets))])
    return omega / omega.sum()


def emit(scene, li: int, targets: np.ndarray, n: int, rng: np.random.Generator, extent=None) -> Photons:
    """n photons of light li towards the target spheres (K,4). Weights include 1/n.

    Directions are drawn from a mixture of the cones around the targets (in proportion to their
    solid angles seen from the light's centre) and weighted by the mixture's density.

    extent: (lo, hi) of what takes part (the plan's bounds; None: the whole scene's), which sets a
    mesh light's offset off its own faces (with the light's faces) and how far behind the targets a
    sun's or the world's photons start (extent_tolerances): an object out of the plan changes no
    photon (a far glass ball made the sun's photons start 3x farther, every first hit a few ulps
    apart)."""
    ph = _emit(scene, li, targets, n, rng, extent)
    if scene.light_visibility.size:
        ph.visibility = int(scene.light_visibility[li])
    if scene.light_linked(li):
        ph.lit = scene.lit_by(li)
    ph.unshadowing = scene.unshadowing(li)
    return ph


def extent_tolerances(scene, extent=None, li=None) -> tuple[float, float]:
    """(the self-intersection offset, the length) of geometry within extent ((lo, hi); None: the
    whole scene's bounds), with mesh light li's own faces if li is one: scene.offset_eps and the
    extent's diagonal (1 for none), as Scene.scale gives them for the whole scene."""
    lo, hi = scene.bounds() if extent is None else (np.asarray(extent[0], float), np.asarray(extent[1], float))
    if li is not None and extent is not None and scene.light_type[li] == S.MESH:
        tv = scene.mesh_light(li)[1].reshape(-1, 3)
        if len(tv):
            lo, hi = np.minimum(lo, tv.min(axis=0)), np.maximum(hi, tv.max(axis=0))
    d = float(np.linalg.norm(hi - lo))
    return S.offset_eps(lo, hi), (d if d > 0 else 1.0)


def _emit(scene, li, targets, n, rng, extent=None) -> Photons:
    typ = scene.light_type[li]
    color = np.asarray(scene.light_color[li], np.float64)
    m = scene.light_matrix[li]
    c = np.ascontiguousarray(m[:3, 3], np.float64)
    targets = np.ascontiguousarray(targets, np.float64).reshape(-1, 4)
    u = rng.random((n, 5))
    o, d, w = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    out = Emitted(o, d, w)
    if typ in (S.POINT, S.SPOT):
        r = float(scene.light_radius[li])
        probs = _cone_probs(c, targets, r)
        _emit_sphere(u, c, r, color / (4.0 * math.pi), Targets(targets, np.cumsum(probs), probs), out)  # W/sr = L pi r^2
        if typ == S.SPOT:
            w *= spot_mask(scene, li, d)[:, None]
        if scene.light_soft_falloff[li] and r > 0:
            return Photons(o, d, w, soft_center=c.copy(), soft_radius=r)
        return Photons(o, d, w)
    if typ == S.AREA:
        cen, ex, ey, nrm, hx, hy, area = area_light_shape(scene, li)
        probs = _cone_probs(cen, targets)
        f64 = lambda a: np.ascontiguousarray(a, np.float64)  # noqa: E731
        _emit_area(u, AreaShape(f64(cen), f64(ex), f64(ey), f64(nrm), float(hx), float(hy), float(area)),
                   bool(scene.light_shape[li] in (S.DISK, S.ELLIPSE)), color / (math.pi * area),
                   Targets(targets, np.cumsum(probs), probs), out)
        if has_spread(scene, li):
            w *= spread_factor(scene, li, dot(d, nrm))[:, None]
        return Photons(o, d, w)
    if typ == S.MESH:
        _, tv, ng, tri_cdf, total = scene.mesh_light(li)
        probs = _cone_probs(c, targets)
        eps = extent_tolerances(scene, extent, li)[0]
        _emit_mesh(u, tv, ng, tri_cdf, total, color, eps, Targets(targets, np.cumsum(probs), probs), out)
        return Photons(o, d, w)
    if typ in S.DISTANT:
        area_k = math.pi * targets[:, 3] ** 2
        probs = area_k / area_k.sum()
        far = 2.0 * (extent_tolerances(scene, extent)[1] + float(np.abs(targets[:, :3]).max()))
        env = env_map(scene, li)
        if env is not None:  # towards the light from the map, then along -that
            to_light = env.sample(u[:, 0], u[:, 1], rng.random(n))
            value = env.value(to_light)
            _emit_along(u, np.ascontiguousarray(-to_light), np.ascontiguousarray(value),
                        Targets(targets, np.cumsum(probs), probs), far, out)
            return Photons(o, d, w)
        axis, half, strength = distant_cone(scene, li)
        _emit_sun(u, np.ascontiguousarray(axis, np.float64), half, strength, Targets(targets, np.cumsum(probs), probs),
                  far, out)
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
        if reach <= 0:
            return False
        h = 0.5 * float(scene.light_spread[li])
        if h >= 0.5 * math.pi - 1e-9:
            return True
        # a spread: the light leaves every point of the light within h of its normal; the sphere
        # is out of reach when it lies wholly beyond that cone widened by the light's half diagonal
        v = center - cen
        side = float(np.linalg.norm(v - np.dot(v, nrm) * nrm))
        return side - radius - math.hypot(hx, hy) <= math.tan(h) * reach
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


def light_radiance(scene, li: int, o: np.ndarray, d: np.ndarray, escaped: np.ndarray | None = None,
                   refl: np.ndarray | None = None, surf_t: np.ndarray | None = None, beyond: bool = False,
                   eps: float | None = None):
    """Radiance a ray o + t d sees from light li, and the distance (inf if the ray
    misses it). escaped marks rays that left the scene (needed for a sun or the world).
    Point lights of radius 0 cannot be hit (delta lights). refl: per ray, whether it leaves a
    reflection (a glossy ray) or a refraction (a transmission ray): where the light's Ray Visibility
    leaves that kind out, the ray passes it (None: every ray sees it). surf_t: where each ray meets
    the scene's first surface (inf: none), which a mesh light needs: its triangles are that surface
    or none of the ray's. beyond: the light as if no surface hid it (every ray escaped; a mesh light's
    triangles wherever they lie, t their distance), for rays whose shadows are found apart (Shadow
    Linking's). eps: the tracer's offset (Tracer.eps, from what takes part), the slack a mesh light's
    triangle may lie past the surface the ray met (None: the whole scene's offset)."""
    if beyond:
        escaped, surf_t = np.ones(len(o), bool), None
    if scene.light_type[li] == S.MESH:
        L, t = _mesh_light_radiance(scene, li, o, d, surf_t, beyond, eps)
    else:
        L, t = _light_radiance(scene, li, o, d, escaped)
    if refl is not None and scene.light_visibility.size:
        seen = np.where(np.asarray(refl, bool), scene.light_seen_by(li, S.RAY_GLOSSY),
                        scene.light_seen_by(li, S.RAY_TRANSMISSION))
        if not seen.all():
            L, t = np.where(seen[:, None], L, 0.0), np.where(seen, t, np.inf)
    return L, t


def _mesh_light_radiance(scene, li, o, d, surf_t, beyond=False, eps=None):
    """A mesh light's radiance where a ray's first surface (at surf_t) is one of its triangles: met
    again in an embree scene of its triangles alone, no farther than that surface (within float32's
    error); t is then just before that surface, as the callers count a light before it. beyond: where
    the ray meets its triangles at all, t their distance."""
    if beyond:
        surf_t = np.full(len(o), np.inf)
    elif surf_t is None:
        raise ValueError(f"light '{scene.light_names[li]}': a mesh light is met as a surface: give surf_t")
    n = len(o)
    L, t = np.zeros((n, 3)), np.full(n, np.inf)
    surf_t = np.asarray(surf_t, np.float64)
    idx = np.arange(n) if beyond else np.flatnonzero(np.isfinite(surf_t))
    if idx.size == 0:
        return L, t
    own = scene.derived(("mesh_light_embree", int(li)), lambda: embree.Scene(scene.mesh_light(li)[1]))
    prim, tl = np.full(idx.size, -1, np.int64), np.full(idx.size, np.inf)
    embree.cast_rays(embree.rays(own), np.ascontiguousarray(o[idx], np.float64),
                     np.ascontiguousarray(d[idx], np.float64),
                     surf_t[idx] * (1.0 + 1e-5) + (S.offset_eps(*scene.bounds()) if eps is None else eps), False,
                     prim, tl)
    hit = idx[prim >= 0]
    L[hit] = scene.light_color[li]
    t[hit] = tl[prim >= 0] if beyond else surf_t[hit] * (1.0 - 1e-12)
    return L, t


def _light_radiance(scene, li, o, d, escaped):
    n = len(o)
    L = np.zeros((n, 3))
    t = np.full(n, np.inf)
    typ = scene.light_type[li]
    color = scene.light_color[li]
    m = scene.light_matrix[li]
    if typ in (S.POINT, S.SPOT):
        r = float(scene.light_radius[li])
        if not r * r > 0:  # a point (a radius whose square underflows is one too)
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
        if has_spread(scene, li):
            L = L * spread_factor(scene, li, -den)[:, None]
        return L, t
    env = env_map(scene, li)
    if typ in S.DISTANT and escaped is not None and env is not None:
        L = np.where(escaped[:, None], env.radiance(d), 0.0)  # d: towards the sky
        t = np.where(escaped, 1e30, np.inf)
    elif typ in S.DISTANT and escaped is not None:
        axis, half, strength = distant_cone(scene, li)
        omega = cone_solid_angle(half)
        if omega <= 0:  # a delta light, never met
            return L, t
        inside = escaped & ((half >= math.pi) | (dot(-d, axis) >= math.cos(half)))
        L = np.where(inside[:, None], strength / omega, 0.0)
        t = np.where(inside, 1e30, np.inf)
    return L, t
