"""The world as a light (S.WORLD): a constant colour, or an Environment Texture (lights.EnvMap).

The map's lookup is Cycles' (measured with Cycles: a map holding each pixel's own coordinates,
seen along eight directions, with and without a Mapping node's turn); its directions are drawn
as bright as the map; the photons carry the flux an independent estimate finds; the sky
reflected in a standing mirror matches its closed form, and only from the half of the sky the
mirror can show.
"""
import math

import numpy as np
import pytest

from testkit import scenes
from smbs_addon import BakeSettings, bake
from smbs_addon.scene.builder import SceneBuilder
from smbs_addon.shading.lights import EnvMap, emit
from testkit.checks import TARGETS, check_against, hits_spheres, mean_se, uniform_sphere
from testkit.scenes import pixel_floor_points

H, W = 32, 64


def _coords():
    jj, ii = np.mgrid[0:H, 0:W]
    return (ii + 0.5) / W, (jj + 0.5) / H


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def _turn_z(deg):
    t = math.radians(deg)
    return np.array([[math.cos(t), -math.sin(t), 0], [math.sin(t), math.cos(t), 0], [0, 0, 1.0]])


def _turn_x(deg):
    t = math.radians(deg)
    return np.array([[1.0, 0, 0], [0, math.cos(t), -math.sin(t)], [0, math.sin(t), math.cos(t)]])


# Cycles' answers: the (u, v) of the pixel a 64 x 32 map shows along each direction (a camera of
# 5000 mm looking along it, the map holding each pixel's own coordinates, Closest interpolation, no
# denoising); then u with the view direction turned 90 degrees about Z by a Mapping node (Rotation
# (0, 0, 90)), and v turned 30 degrees about X
CYCLES = [((0.3, 0.8, 0.2), 0.3047, 0.5781, 0.0547, 0.7344), ((-0.7, 0.2, -0.4), 0.0391, 0.3281, 0.7891, 0.3906),
          ((0.5, -0.6, 0.6), 0.6328, 0.7031, 0.3828, 0.5781), ((-0.2, -0.9, 0.1), 0.7891, 0.5469, 0.5391, 0.3594),
          ((0.9, 0.1, -0.8), 0.4766, 0.2656, 0.2266, 0.3281), ((0.05, 0.1, 0.99), 0.3203, 0.9531, 0.0703, 0.8594)]


def test_the_map_is_looked_up_as_cycles_does():
    u, v = _coords()
    img = np.stack([u, v, np.ones_like(u)], -1)
    env, turned_z, turned_x = (EnvMap(img, R, np.ones(3)) for R in (np.eye(3), _turn_z(90.0), _turn_x(30.0)))
    for d, cu, cv, zu, xv in CYCLES:
        d = _unit(d)[None]
        assert tuple(env.radiance(d)[0, :2]) == pytest.approx((cu, cv), abs=1e-4), d
        assert turned_z.radiance(d)[0, 0] == pytest.approx(zu, abs=1e-4), d
        assert turned_x.radiance(d)[0, 1] == pytest.approx(xv, abs=1e-4), d


def test_directions_are_drawn_as_bright_as_the_map():
    """Each pixel gets its share (luminance x solid angle) of 400,000 directions within 5 standard
    errors, every direction lands in the pixel it was drawn in, and the density pdf() gives is
    that share over the pixel's solid angle (it integrates to 1 over the sphere)."""
    rng = np.random.default_rng(4)
    img = rng.random((H, W, 3)) ** 4 * 10.0
    img[:, :5] = 0.0  # black columns: never drawn
    env = EnvMap(img, _turn_z(30.0), np.array([1.0, 0.5, 2.0]))
    n = 400_000
    d = env.sample(rng.random(n), rng.random(n), rng.random(n))
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0)
    j, i = env._pixel(d)
    counts = np.bincount(j * W + i, minlength=H * W)
    share = env.p
    assert counts[share == 0].sum() == 0
    se = np.sqrt(n * share * (1 - share))
    assert np.all(np.abs(counts - n * share) <= 5 * se + 1)
    omega = np.repeat(env.omega, W)
    assert (env.pdf(d) * omega[j * W + i] == pytest.approx(share[j * W + i]))
    assert float((share / omega * omega).sum()) == pytest.approx(1.0)
    assert float(omega.sum()) == pytest.approx(4 * math.pi)


def test_a_constant_map_is_a_constant_world():
    """Every direction of a constant map carries 4 pi L (radiance over its density)."""
    env = EnvMap(np.full((H, W, 3), 0.25), np.eye(3), np.array([2.0, 2.0, 2.0]))
    rng = np.random.default_rng(1)
    d = env.sample(rng.random(1000), rng.random(1000), rng.random(1000))
    assert np.allclose(env.value(d), 4 * math.pi * 0.5)
    assert np.allclose(env.radiance(d), 0.5)


def _targets_flux_mc(radiance, targets, rng, n=2_000_000):
    """Flux from the world into the union of the target spheres, independently: uniform directions,
    uniform points on a disc across a sphere holding them all, whether the line meets one."""
    c = targets[:, :3].mean(0)
    R = float(np.max(np.linalg.norm(targets[:, :3] - c, axis=1) + targets[:, 3]))
    to = uniform_sphere(rng, n)  # towards the light
    a = np.where(np.abs(to[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    s = np.cross(to, a)
    s /= np.linalg.norm(s, axis=1, keepdims=True)
    t = np.cross(to, s)
    r, phi = R * np.sqrt(rng.random(n)), 2 * math.pi * rng.random(n)
    p = c + (r * np.cos(phi))[:, None] * s + (r * np.sin(phi))[:, None] * t
    hit = hits_spheres(p + 10 * R * to, -to, targets)
    x = radiance(to)[:, 0] * 4 * math.pi * math.pi * R * R * hit
    return x.mean(), x.std(ddof=1) / math.sqrt(n)


@pytest.mark.parametrize("textured", [False, True])
def test_the_worlds_photons_carry_its_flux_into_the_targets(textured):
    b = SceneBuilder("sky")
    b.plane("Floor", (0, 0, 0), 10, b.material("floor", "diffuse"))
    u, v = _coords()
    img = np.stack([1 + 8 * v ** 3 + np.exp(-((u - 0.3) ** 2 + (v - 0.7) ** 2) / 0.002) * 50] * 3, -1)
    b.world((0.5, 0.5, 0.5), image=img if textured else None, rotation=_turn_z(25.0))
    b.set_camera((0, -6, 5), (0, 0, 0), resolution_x=8, resolution_y=6)
    scene = b.build()
    ph = emit(scene, 0, TARGETS, 400_000, np.random.default_rng(1))
    assert np.all(np.isfinite(ph.w)) and np.allclose(np.linalg.norm(ph.d, axis=1), 1.0)
    got, got_se = mean_se(ph.w[:, 0] * len(ph.w))
    env = EnvMap(img, _turn_z(25.0), np.full(3, 0.5))
    radiance = env.radiance if textured else (lambda d: np.full((len(d), 3), 0.5))
    want, want_se = _targets_flux_mc(radiance, TARGETS, np.random.default_rng(2))
    se = math.hypot(got_se, want_se)
    assert se < 0.01 * want
    assert abs(got - want) < 4 * se, (got, want, se)


def _half_sky(side):
    """A 64 x 32 map of 0.5 on one side of the plane x = 0 (west: x < 0), black on the other."""
    u, _ = _coords()
    west = (u < 0.25) | (u > 0.75)
    return np.where((west if side == "west" else ~west)[..., None], 0.5, 0.0) * np.ones(3)


@pytest.mark.parametrize("method", ["mnee", "smbs"])
def test_the_mirror_shows_the_half_of_the_sky_behind_the_viewer(method):
    """scenes.world_mirror_scene under a map bright on the west (x < 0) alone: the mirror faces
    west, so the floor before it gets all of scenes.world_through_mirror; bright on the east
    alone, nothing (the plan's pilots find no caustic and nothing is baked). Measured (seed 1, 512
    spp): MNEE -0.7%, SMBS -0.8% (noise 0.75-0.85%)."""
    scene = scenes.world_mirror_scene(image=_half_sky("west"))
    pts, ok = pixel_floor_points(scene)
    region = ok & (pts[..., 0] < 0.5)
    expected = np.zeros(region.shape)
    expected[region] = [scenes.world_through_mirror(p) for p in pts[region]]
    res = bake(scene, BakeSettings(method=method, spp=512, seed=1, indirect=False))
    check_against(res, expected, region, tol=0.04)
    east = bake(scenes.world_mirror_scene(image=_half_sky("east")), BakeSettings(method=method, spp=4, seed=1,
                                                                                 indirect=False))
    assert not east.image.any() and east.stats["nothing_to_bake"]
