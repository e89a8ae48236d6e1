"""Caustics seen in a mirror: the eye-side estimator agrees with the direct view.

Scene B adds a second, non-caster mirror (the plane y = -3) and puts the camera
at the mirror image of scene A's camera, so B sees A's floor through the mirror
(the camera matrix is reflected too, so pixel for pixel). Then B = rho2 x A: the light tracer makes A, the
eye-path estimator (camera -> mirror -> floor -> mirror -> light) makes B. First-order
caustics only: with indirect ones, B's side mirror would also light A's floor.
"""
import math

import numpy as np

import scenes
from smbs_addon import BakeSettings, bake
from smbs_addon.bake import caustic_region
from smbs_addon.builder import SceneBuilder, look_at

RHO2 = 0.7


def _mirror_scene(with_second_mirror):
    b = SceneBuilder("mirror-in-mirror")
    floor = b.material("floor", "diffuse", color=(0.8,) * 3)
    m1 = b.material("mirror", "conductor", color=(0.9,) * 3)
    b.plane("Floor", (0, 0, 0), 10, floor, receiver=True)
    b.plane("Mirror", (0, 0, 1.5), 1.5, m1, normal=np.array([-1, 0, -1]) / math.sqrt(2), caster=True)
    b.light("Disk", "AREA", location=(-2, 0, 1.5), target=(0, 0, 1.5), power=100, shape="DISK", size=0.5)
    cam = look_at((0, -6, 5), (-0.2, 0, 0))
    if with_second_mirror:
        m2 = b.material("side mirror", "conductor", color=(RHO2,) * 3)
        b.plane("Side mirror", (0, -3, 5), (12, 10.2), m2, normal=(0, 1, 0))
        refl = np.diag([1.0, -1.0, 1.0, 1.0])
        refl[1, 3] = -6.0  # y -> -6 - y: the plane y = -3
        cam = refl @ cam
    b.set_camera(matrix=cam, lens=35, resolution_x=80, resolution_y=60)
    sc = b.build()
    sc.object_caster[:] = [False, True, False][: len(sc.object_names)]
    sc.object_receiver[:] = [True, False, False][: len(sc.object_names)]
    return sc


def test_caustic_seen_in_a_mirror_matches_direct_view():
    a = bake(_mirror_scene(False), BakeSettings(method="reference", spp=64, seed=1, use_cycles_flags="ON", indirect=False))
    b = bake(_mirror_scene(True), BakeSettings(method="reference", spp=1024, seed=2, use_cycles_flags="ON",
                                                indirect=False))
    assert b.stats["eye_pass"]["enabled"] and b.stats["eye_pass"]["eye_splats"] > 1000
    region = caustic_region(a.image)
    region[:, :3] = region[:, -3:] = False
    ma, sa = a.region_mean(region)
    mb, sb = b.region_mean(region)
    ma, sa = RHO2 * ma, RHO2 * sa
    se = math.sqrt(sa**2 + sb**2)
    assert se < 0.03 * ma, f"too noisy to judge: {se / ma:.2%}"
    print(f"eye-through-mirror: {mb:.5f} vs {ma:.5f} ({(mb - ma) / ma:+.2%}, noise {se / ma:.2%})")
    assert abs(mb - ma) < max(4 * se, 0.02 * ma), (
        f"through the mirror {mb:.5f} vs {RHO2} x direct {ma:.5f} ({(mb - ma) / ma:+.2%}, noise {se / ma:.2%})")
