"""A glass's Volume Absorption (Scene.mat_absorb): light crossing a length d inside the glass
keeps exp(-absorb d), on every path every method traces (photons, eye paths, walks' chains,
the hand-off's and gathers' paths)."""
from __future__ import annotations

import numpy as np
import pytest

from smbs_addon import BakeSettings, bake
from smbs_addon.scene import arrays as S
from smbs_addon.scene.builder import SceneBuilder

SIGMA = np.array([0.5, 2.0, 5.0])  # per metre
THICK = 0.2


def slab_scene(absorb, camera="side", resolution=(32, 24)):
    """A horizontal glass slab (2 x 2 x THICK m, its faces wound outwards) 1 m above a floor, a
    small bulb 3 m above it: the light crosses the slab almost straight down (the floor under
    its middle sees it within 8 degrees of the normal). The camera looks at the floor under the
    slab from the side (no eye ray through the glass) or from above through it."""
    b = SceneBuilder("slab")
    floor = b.material("floor", "diffuse", color=(0.8, 0.8, 0.8))
    glass = b.material("glass", "dielectric", color=(1, 1, 1), ior=1.5, absorb=absorb)
    b.plane("Floor", (0, 0, 0), 10, floor)
    lo, hi = np.array([-1.0, -1.0, 1.0]), np.array([1.0, 1.0, 1.0 + THICK])
    v = np.array([[(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    faces = [(0, 2, 6, 4), (1, 5, 7, 3), (0, 4, 5, 1), (2, 3, 7, 6), (0, 1, 3, 2), (4, 6, 7, 5)]
    b.mesh("Slab", v, faces, glass, caster=True)
    b.light("Bulb", "POINT", location=(0.0, 0.0, 4.2), power=300.0, radius=0.05)
    if camera == "side":
        b.set_camera((0.0, -3.5, 0.55), (0.0, 0.0, 0.0), lens=30, resolution_x=resolution[0],
                     resolution_y=resolution[1])
    else:
        b.set_camera((0.0, -0.6, 4.0), (0.0, 0.0, 0.0), lens=35, resolution_x=resolution[0],
                     resolution_y=resolution[1])
    return b.build()


def test_the_slab_is_wound_outwards():
    sc = slab_scene(SIGMA)
    slab = sc.tri_object == sc.object_names.index("Slab")
    tv = sc.tri_vertices[slab]
    n = np.cross(tv[:, 1] - tv[:, 0], tv[:, 2] - tv[:, 0])
    out = tv.mean(axis=1) - np.array([0.0, 0.0, 1.0 + THICK / 2])
    assert np.all((n * out).sum(axis=1) > 0)
    assert sc.mat_absorb.shape == (2, 3) and np.allclose(sc.mat_absorb[sc.mat_kind == S.DIELECTRIC], SIGMA)


def _region_ratio(scene, a, b):
    """(ours, expected): the tinted bake's caustic over the clear one's, per channel, over the
    caustic region; expected from each pixel's floor point: exp(-absorb THICK / cos theta_t) for
    the light's way through the slab, and for the eye's where its ray crosses the slab, weighted
    by the clear bake's pixels."""
    from smbs_addon.trace.camera import CameraModel

    lum = a.image.mean(axis=2)
    H, W = lum.shape
    ys, xs = np.mgrid[0:H, 0:W]
    o, d = CameraModel(scene.camera).rays(xs.ravel() + 0.5, ys.ravel() + 0.5)[:2]
    q = o - ((o[:, 2] - (1.0 + THICK / 2)) / d[:, 2])[:, None] * d  # the eye ray at the slab's height
    eye = ((np.abs(q[:, 0]) < 1.0) & (np.abs(q[:, 1]) < 1.0)).reshape(H, W)
    # pixels two or more from where the eye's view crosses the slab's edge (the pixel filter mixes there)
    same = np.ones((H, W), bool)
    for dy in range(-2, 3):
        for dx in range(-2, 3):
            same &= np.roll(eye, (dy, dx), axis=(0, 1)) == eye
    region = (lum > 0.2 * np.percentile(lum, 99.5)) & same
    assert region.sum() > 30
    sel = region.ravel()
    o, d, eye = o[sel], d[sel], eye.ravel()[sel]
    p = o - (o[:, 2] / d[:, 2])[:, None] * d  # on the floor
    sin_i = np.hypot(p[:, 0], p[:, 1]) / np.linalg.norm(p - [0.0, 0.0, 4.0], axis=1)
    length = THICK / np.sqrt(1.0 - (sin_i / 1.5) ** 2)
    sin_e = np.hypot(d[:, 0], d[:, 1]) / np.linalg.norm(d, axis=1)
    length = length + np.where(eye, THICK / np.sqrt(1.0 - (sin_e / 1.5) ** 2), 0.0)
    w = a.image[region]
    want = (w * np.exp(-SIGMA[None] * length[:, None])).sum(axis=0) / w.sum(axis=0)
    return b.image[region].sum(axis=0) / w.sum(axis=0), want


@pytest.mark.parametrize("method,spp", [("reference", 64), ("sms", 2), ("smbs", 2), ("mnee", 2)])
def test_light_through_the_slab_keeps_exp_minus_absorb_d(method, spp):
    """The same bake (same seed: the same paths) with and without absorption: the caustic under
    the slab keeps exp(-absorb x THICK / cos theta_t) pixel by pixel (0.5%; the paths reflected
    inside the slab, longer, add well under that). Indirect caustics left out: light bounced off
    the floor back through the slab crosses it again (3% of the layer here, with 2-3 crossings)."""
    settings = BakeSettings(method=method, spp=spp, seed=3, indirect=False)
    clear, tinted = bake(slab_scene(0.0), settings), bake(slab_scene(SIGMA), settings)
    ours, want = _region_ratio(slab_scene(0.0), clear, tinted)
    assert np.all(want < np.exp(-SIGMA * THICK))  # the slant of the light counts
    np.testing.assert_allclose(ours, want, rtol=0.005)


def test_seen_through_the_slab_the_eye_path_absorbs_too():
    """From above, the caustic is mostly seen through the slab: the eye's segment in it absorbs
    as well, pixel by pixel where the eye ray crosses it (1%)."""
    settings = BakeSettings(method="sms", spp=4, seed=5, indirect=False)  # a bulb seen through glass: walks
    clear, tinted = bake(slab_scene(0.0, "above"), settings), bake(slab_scene(SIGMA, "above"), settings)
    ours, want = _region_ratio(slab_scene(0.0, "above"), clear, tinted)
    assert np.all(want < np.exp(-1.5 * SIGMA * THICK))  # most of it seen through the slab
    np.testing.assert_allclose(ours, want, rtol=0.01)


def _pool(absorb, light="point", above=False, resolution=24):
    """scenes.water_scene (flat water at z = 1 over the floor, its normal up) with absorbing
    water; the camera under the surface (its rays never cross it) or 3 m above it, looking
    straight down through it; a small bulb 3 m above the water, or a 2 m square area light."""
    from smbs_addon.scene import arrays as S_

    sc = scenes_water(light, resolution)
    if absorb is not None:
        sc.mat_absorb = np.zeros((len(sc.mat_kind), 3))
        sc.mat_absorb[sc.mat_kind == S_.DIELECTRIC] = absorb
    if above:
        sc.camera.matrix_world = sc.camera.matrix_world.copy()
        sc.camera.matrix_world[2, 3] = 3.0
    return sc


def scenes_water(light, resolution):
    from testkit import scenes

    if light == "point":
        return scenes.water_scene("point", size=8.0, resolution=resolution)
    b = SceneBuilder("pool")
    floor = b.material("floor", "diffuse", color=(0.8, 0.8, 0.8))
    water = b.material("water", "dielectric", color=(1, 1, 1), ior=1.33)
    b.plane("Floor", (0, 0, 0), 20, floor)
    b.plane("Water", (0, 0, 1), 8.0, water)
    b.light("Panel", "AREA", location=(0, 0, 4), target=(0, 0, 0), power=3000.0, size=2.0)
    b.set_camera((0, 0, 0.9), (0, 0, 0), type=1, ortho_scale=2.0, resolution_x=resolution,
                 resolution_y=resolution, clip_start=0.01)
    return b.build()


WATER = np.array([0.1, 0.4, 1.0])  # per metre


def _water_expected(scene, image, eye_crossing):
    """The absorbed over the clear layer, expected: each pixel's floor point (x, y) under the
    1 m of water, lit through it by the bulb 3 m above the surface (the angle in the water from
    Snell's law, solved along the horizontal distance), and seen through it from above (straight
    down: 1 m more), weighted by the clear layer."""
    from smbs_addon.trace.camera import CameraModel

    H, W = image.shape[:2]
    ys, xs = np.mgrid[0:H, 0:W]
    o, d = CameraModel(scene.camera).rays(xs.ravel() + 0.5, ys.ravel() + 0.5)[:2]
    p = o - (o[:, 2] / d[:, 2])[:, None] * d
    r = np.hypot(p[:, 0], p[:, 1])
    lo, hi = np.zeros_like(r), np.full_like(r, np.pi / 2 - 1e-6)
    for _ in range(60):  # 3 tan(i) + tan(t) = r, sin(t) = sin(i) / 1.33
        mid = 0.5 * (lo + hi)
        t = np.arcsin(np.sin(mid) / 1.33)
        far = 3.0 * np.tan(mid) + np.tan(t) > r
        hi, lo = np.where(far, mid, hi), np.where(far, lo, mid)
    length = 1.0 / np.cos(np.arcsin(np.sin(lo) / 1.33)) + (1.0 if eye_crossing else 0.0)
    w = image.reshape(-1, 3)
    return (w * np.exp(-WATER[None] * length[:, None])).sum(axis=0) / w.sum(axis=0)


@pytest.mark.parametrize("method,spp,above", [("reference", 16, False), ("sms", 1, False), ("mnee", 1, False),
                                              ("sms", 1, True)])
def test_a_pool_absorbs_on_the_way_down_and_up(method, spp, above):
    """A receiver under absorbing water: the light's way down through 1 m of it (the walks'
    segment from x0 up to the surface, the photons' after the surface), and, seen from above,
    the eye's way through it too."""
    settings = BakeSettings(method=method, spp=spp, seed=2, indirect=False)
    clear, tinted = bake(_pool(None, above=above), settings), bake(_pool(WATER, above=above), settings)
    want = _water_expected(_pool(None, above=above), clear.image, above)
    ours = tinted.image.reshape(-1, 3).sum(axis=0) / clear.image.reshape(-1, 3).sum(axis=0)
    np.testing.assert_allclose(ours, want, rtol=0.004)


def test_light_gathered_from_under_the_water_is_absorbed_on_its_way_up():
    """The light tracer's eye pass from above: camera, surface, floor, then cosine paths from the
    floor up through the water to the area light (kernels.gather_lanes: the segment from the
    floor to the surface lies inside, known only as it arrives at the surface's back)."""
    settings = BakeSettings(method="reference", spp=64, seed=4, indirect=False)
    clear, tinted = _pool(None, "area", above=True, resolution=12), _pool(WATER, "area", above=True, resolution=12)
    for sc in (clear, tinted):  # one diffuse bounce (Light Paths): no light reflected under the surface
        sc.light_paths = np.array([12, 1, 4, 12], np.int64)  # from the floor again (3 m of water and more)
    clear, tinted = bake(clear, settings), bake(tinted, settings)
    ours = tinted.image.reshape(-1, 3).sum(axis=0) / clear.image.reshape(-1, 3).sum(axis=0)
    # down from the camera: 1 m; up towards a 2 m panel 3 m above the surface: 1.0-1.1 m
    assert np.all(ours < np.exp(-WATER * 2.0) * 1.001) and np.all(ours > np.exp(-WATER * 2.12))
