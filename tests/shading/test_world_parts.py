"""A world's map in two parts (shading.world_parts): the bright, compact part for the walks, the rest
path-traced from the receivers. The split itself (which pixels, what share, both parts adding up to
the map), the path-traced part against a closed form, and a split bake against an unsplit one.
"""
import math

import numpy as np
import pytest

from smbs_addon import BakeSettings, bake
from smbs_addon.shading.world_parts import BRIGHT_CONTRAST, MIN_PART_SHARE, split_world
from testkit import pools, scenes
from testkit.checks import check_against
from testkit.scenes import pixel_floor_points

H, W = 32, 64


def _pixel_of(direction):
    """(row, column) of the W x H map pixel a unit direction looks up (lights.EnvMap, no turn)."""
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    u = (0.5 - math.atan2(d[1], d[0]) / (2 * math.pi)) % 1.0
    v = 1.0 - math.acos(d[2]) / math.pi
    return min(int(v * H), H - 1), min(int(u * W), W - 1)


def _sky_with_sun(sky_side, sun_direction, sun=500.0):
    """scenes.world_mirror_scene's map: 0.5 on one half of the sky (west: x < 0) and black on the
    other, and one pixel of radiance `sun` where sun_direction looks."""
    jj, ii = np.mgrid[0:H, 0:W]
    u = (ii + 0.5) / W
    west = (u < 0.25) | (u > 0.75)
    img = np.where((west if sky_side == "west" else ~west)[..., None], 0.5, 0.0) * np.ones(3)
    img[_pixel_of(sun_direction)] = sun
    return img


def _pool_scene(img):
    """A scene with pool_hdri's kind of map (testkit.pools.sky_image at a small size) as its world."""
    return scenes.world_mirror_scene(image=img)


def test_the_split_takes_the_suns_disc_and_leaves_the_sky():
    img = pools.sky_image(width=256, height=128).astype(np.float64)
    scene = _pool_scene(img)
    scene.validate()
    parts = split_world(scene)
    assert parts is not None
    walked, traced = np.asarray(parts.walked.world_map), np.asarray(parts.traced.world_map)
    assert np.array_equal(walked + traced, img)  # the two parts add up to the map, pixel by pixel
    bright = walked.any(axis=2)
    assert not (bright & traced.any(axis=2)).any()
    # the bright pixels: the disc's, those it covers enough to be BRIGHT_CONTRAST x the mean radiance
    z = np.cos(math.pi * (1.0 - np.arange(129) / 128))
    omega = (2 * math.pi / 256) * np.diff(z)[:, None]
    lum = img.mean(axis=2)
    mean = (lum * omega).sum() / (4 * math.pi)
    disc = pools.sky_image(width=256, height=128, strength=pools.SUN_STRENGTH).mean(axis=2) > max(pools.SKY) * 1.5
    assert np.array_equal(bright, lum > BRIGHT_CONTRAST * mean)
    assert bright.sum() > 0 and not (bright & ~disc).any()
    assert parts.bright_share == pytest.approx((lum * omega)[bright].sum() / (lum * omega).sum(), rel=1e-12)
    # a disc of 5 degrees: 0.006 sr; the pixels it touches a little more
    assert 0.8 * 0.00598 < parts.solid_angle < 2.0 * 0.00598
    assert "5.2 deg" in parts.words("World") or "disc of" in parts.words("World")


@pytest.mark.parametrize("what", ["sky alone", "sun alone", "no map", "a faint sun"])
def test_a_map_of_one_part_is_not_split(what):
    img = _sky_with_sun("west", (1.0, 0.0, 1.0))
    if what == "sky alone":
        img[_pixel_of((1.0, 0.0, 1.0))] = 0.5
    elif what == "sun alone":
        img[img < 1.0] = 0.0
    elif what == "a faint sun":  # bright, but under MIN_PART_SHARE of the power
        img[_pixel_of((1.0, 0.0, 1.0))] = 0.3 * MIN_PART_SHARE * 0.5 * 2 * math.pi / 0.0095
    scene = scenes.world_mirror_scene() if what == "no map" else _pool_scene(img)
    scene.validate()
    assert split_world(scene) is None


def test_the_path_traced_sky_matches_the_closed_form():
    """The sky seen in the mirror (scenes.world_through_mirror) with a sun on the east, which the
    mirror (facing west) cannot show the floor before it: the walks' part (the sun) brings nothing, and
    the path-traced part all of the closed form. Measured (256 spp, SMBS): seed 1 +0.44% (noise 0.71%),
    seed 2 -0.03% (0.49%)."""
    scene = _pool_scene(_sky_with_sun("west", (1.0, 0.0, 1.0)))
    pts, ok = pixel_floor_points(scene)
    region = ok & (pts[..., 0] < 0.5)
    expected = np.zeros(region.shape)
    expected[region] = [scenes.world_through_mirror(p) for p in pts[region]]
    res = bake(scene, BakeSettings(method="smbs", spp=256, seed=1, indirect=False))
    assert res.stats["sky"]["eye_paths"] == res.stats["eye_pass"]["eye_paths"] > 0  # as many eye samples as the walks
    assert any("traced from the receivers" in w for w in res.stats["plan"]["words"])
    check_against(res, expected, region, tol=0.03)


@pytest.mark.parametrize("method", ["mnee", "smbs"])
def test_a_split_bake_is_its_suns_walks_and_its_skys_closed_form(method):
    """A sun the mirror shows the floor, in a sky it shows too: the split bake's layer is the walks' of
    the sun alone (a map of one part: not split) plus the sky's closed form. The sky is 27% of it. Measured (64 spp,
    seeds 1 and 3 for the split): MNEE -0.18% and +0.04% (noise 0.28%, 0.26%), SMBS -0.20% and +0.61%
    (0.40%, 0.39%)."""
    sun = (-1.0, 0.3, 1.2)
    img = _sky_with_sun("west", sun)
    scene = _pool_scene(img)
    pts, ok = pixel_floor_points(scene)
    region = ok & (pts[..., 0] < 0.5)
    sky = np.array([scenes.world_through_mirror(p) for p in pts[region]]).mean()
    split = bake(scene, BakeSettings(method=method, spp=64, seed=1, indirect=False))
    sun_alone = bake(_pool_scene(np.where(img > 1.0, img, 0.0)), BakeSettings(method=method, spp=64, seed=2,
                                                                               indirect=False))
    assert "sky" in split.stats and "sky" not in sun_alone.stats
    (m, se), (m_sun, se_sun) = split.region_mean(region), sun_alone.region_mean(region)
    want = m_sun + sky
    assert sky > 0.2 * want  # both parts weigh
    sigma = math.hypot(se, se_sun) / want
    assert sigma < 0.01 and abs(m / want - 1) < 3 * sigma + 0.005, (m / want, sigma)


def test_a_split_bake_is_the_same_on_one_thread_or_two():
    scene = _pool_scene(_sky_with_sun("west", (-1.0, 0.3, 1.2)))
    one, two = (bake(scene, BakeSettings(method="smbs", spp=8, seed=5, threads=t)) for t in (1, 2))
    assert one.stats["sky"]["eye_paths"] > 0
    assert np.array_equal(one.image, two.image) and np.array_equal(one.variance, two.variance)
