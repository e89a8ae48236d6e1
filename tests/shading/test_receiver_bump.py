"""A bumped diffuse receiver, shaded as Cycles shades it: its normal as the camera's view holds it
(Scene.view_normals, eye.view_bumped, eye.view_normal1) and the shadowing of a bent normal
(optics.bump_shadowing1, Cycles' bump_shadowing_term)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from smbs_addon import BakeSettings, bake
from smbs_addon.kernels import eye
from smbs_addon.scene import arrays as S
from smbs_addon.scene.builder import SceneBuilder
from smbs_addon.trace.camera import CameraModel
from smbs_addon.trace.eye import view_bumped
from smbs_addon.shading.optics import bump_shadowing1
from smbs_addon.trace.tracer import Tracer

UP = (0.0, 0.0, 1.0)


def _unit(v):
    v = np.asarray(v, float)
    return tuple(v / np.linalg.norm(v))


def test_the_shadowing_of_a_bent_normal_is_cycles():
    """bump_shadowing1 against Cycles' bump_shadowing_term worked by hand: 1 where the normal is the
    smooth one (exactly) or without Bump Map Correction; GGX's G1 = 2 / (1 + sqrt(1 + a2 tan^2)) of
    a2 = tan^2(30 deg) / 8 = 1/24 at light 60 degrees off the smooth normal: 0.97056; 0 where the
    light is above the bent normal but below the smooth one."""
    tilted = (math.sin(math.radians(30)), 0.0, math.cos(math.radians(30)))
    wi = (-math.sin(math.radians(60)), 0.0, 0.5)  # 60 degrees off UP, 90 off the tilted normal: not lit
    wi2 = (math.sin(math.radians(60)), 0.0, 0.5)  # 30 degrees off the tilted normal
    assert bump_shadowing1(UP, UP, wi2, True) == 1.0
    assert bump_shadowing1(UP, tilted, wi2, False) == 1.0
    want = 2.0 / (1.0 + math.sqrt(1.0 + (1.0 / 24.0) * 3.0))
    assert bump_shadowing1(UP, tilted, wi2, True) == pytest.approx(want, rel=1e-12)
    assert want == pytest.approx(0.97056, abs=1e-5)
    assert bump_shadowing1(UP, tilted, wi, True) == pytest.approx(want, rel=1e-12)  # the same angle to UP
    below = (math.sin(math.radians(95)), 0.0, math.cos(math.radians(95)))  # under UP's horizon, 65 off tilted
    assert bump_shadowing1(UP, tilted, below, True) == 0.0
    assert bump_shadowing1(UP, tilted, below, False) == 0.0


def _mirror_scene(correction):
    """A sun (angle 0) reflected by a standing mirror onto a floor: every path of the caustic reaches
    the floor from one direction, omega (up and towards the mirror)."""
    b = SceneBuilder("bumped_floor")
    floor = b.material("floor", "diffuse", color=(0.8, 0.8, 0.8), view_bump=True, bump_correction=correction)
    mirror = b.material("mirror", "conductor", color=(0.9, 0.9, 0.9))
    b.plane("Floor", (0, 0, 0), 6.0, floor, receiver=True)
    b.plane("Mirror", (-1.0, 0, 0.8), (1.0, 1.0), mirror, normal=(1, 0, 0), caster=True)  # its caustic in view
    b.light("Sun", "SUN", location=(1, 0, 1), target=(0, 0, 0), power=3.0)
    b.set_camera(location=(-0.2, -0.6, 4.0), target=(-0.2, 0, 0), resolution_x=32, resolution_y=24)
    return b.build()


def _view(scene, normal, s=2):
    """Scene.view_normals / view_points as Cycles would render them (the bumped receiver alone, the
    floor z = 0 of 6 x 6 m): a camera ray through every sub-pixel's centre, where it meets the floor,
    the normal `normal` there."""
    cam = CameraModel(scene.camera)
    rows, cols = np.mgrid[0:cam.H * s, 0:cam.W * s]
    o, d = eye.camera_rays(cam.kernel_params(), (cols.ravel() + 0.5) / s, (rows.ravel() + 0.5) / s)
    p = o - (o[:, 2] / d[:, 2])[:, None] * d
    floor = np.all(np.abs(p[:, :2]) < 3.0, axis=1)
    n = np.where(floor[:, None], np.asarray(normal, float), 0.0)
    p = np.where(floor[:, None], p, 0.0)
    return (n.reshape(cam.H * s, cam.W * s, 3).astype(np.float32), p.reshape(cam.H * s, cam.W * s, 3).astype(np.float32))


OMEGA = np.array(_unit((-1.0, 0.0, 1.0)))  # the reflected sun, from the floor
TILTED = _unit((0.3, 0.2, 1.0))
MIRRORED = slice(1, 8)  # the film's columns where the camera sees the caustic in the mirror


@pytest.mark.parametrize("method", ["reference", "sms", "smbs"])
@pytest.mark.parametrize("correction", [False, True])
def test_a_bumped_floor_takes_the_cosine_of_its_bent_normal(method, correction):
    """Every estimator scales the caustic on a bumped floor by Cycles' factor: the cosine of the bent
    normal over the smooth one's, times the shadowing term with Bump Map Correction. The same seed,
    the same paths (the view draws no random numbers): each pixel changes by exactly that
    factor, the caustic the camera sees in the mirror too (the floor's point is looked up where it
    projects), 0.659 (0.656 with the correction; a tilt of 20 degrees, away from the light)."""
    plain = _mirror_scene(correction)
    bumped = _mirror_scene(correction)
    bumped.view_normals, bumped.view_points = _view(bumped, TILTED)
    bumped.validate()
    want = float(np.dot(TILTED, OMEGA)) / OMEGA[2] * bump_shadowing1(UP, TILTED, tuple(OMEGA), correction)
    assert want == pytest.approx(0.6585 if not correction else 0.6559, abs=5e-4)
    settings = BakeSettings(method=method, spp=4, seed=3, indirect=False)
    a, b = bake(plain, settings), bake(bumped, settings)
    # the walks see the caustic in the mirror too (the light tracer's eye pass cannot meet a sun of angle 0)
    assert (a.image.mean(axis=2) > 0).sum() > 100 and (method == "reference" or a.image[:, MIRRORED].max() > 0)
    np.testing.assert_allclose(b.image, want * a.image, rtol=1e-5, atol=1e-6 * a.image.max())


def test_the_view_is_read_only_where_it_shows_the_receiver_itself():
    """view_bumped reads the view's normal where x0 projects, if the sub-pixel's point is x0's surface;
    off x0's plane, far along it (the view shows another part of it), or where the view's normal is
    zero, x0 keeps its own. The view's normal is turned to the side of x0's (Cycles' faces the
    camera)."""
    sc = _mirror_scene(True)
    sc.view_normals, sc.view_points = _view(sc, TILTED)
    cam = CameraModel(sc.camera)
    rx, ry = np.full(4, 10.3), np.full(4, 12.6)
    o, d = eye.camera_rays(cam.kernel_params(), rx, ry)
    h = Tracer(sc).intersect(o, d)
    assert h.hit.all()
    p, ng, ns = h.p.copy(), h.ng.copy(), h.ns.copy()
    p[1, 2] += 0.01  # off the plane
    p[2, 0] += 1.0  # on it, far: its own sub-pixel is 10 pixels away
    ng[3], ns[3] = -ng[3], -ns[3]  # the normals the other way
    p[2, 0] -= 1.0
    p[2] += 0.4 * np.array([1.0, 0.0, 0.0])
    vp = sc.view_points.copy()
    out = view_bumped(sc, cam, p, ng, ns, np.zeros(4, np.int64))
    np.testing.assert_allclose(out[0], TILTED, atol=1e-6)
    np.testing.assert_array_equal(out[1], ns[1])
    np.testing.assert_allclose(out[2], TILTED, atol=1e-6)  # elsewhere on the floor: its own sub-pixel
    np.testing.assert_allclose(out[3], -np.asarray(TILTED), atol=1e-6)
    sc.view_points[:] = vp + np.array([0.3, 0.0, 0.0], np.float32)  # the view shows the floor elsewhere
    np.testing.assert_array_equal(view_bumped(sc, cam, p[:1], ng[:1], ns[:1], np.zeros(1, np.int64)), ns[:1])
    sc.view_points[:], sc.view_normals[:] = vp, 0.0
    np.testing.assert_array_equal(view_bumped(sc, cam, p[:1], ng[:1], ns[:1], np.zeros(1, np.int64)), ns[:1])


def test_a_view_of_two_sizes_is_refused():
    """Scene.validate: the view's normals and points must be maps of one size."""
    sc = _mirror_scene(True)
    sc.view_normals, sc.view_points = np.zeros((48, 64, 3), np.float32), np.zeros((48, 63, 3), np.float32)
    with pytest.raises(S.SceneError, match="view_normals"):
        sc.validate()


def test_a_pilots_smaller_frame_reads_the_same_view():
    """auto's pilots bake the scene at a smaller resolution (auto._pilot_scene): eye.view_tables takes
    their raster positions to the view's through the view plane, so a point of the floor reads the
    same sub-pixel at 32 x 24 and at 12 x 9 pixels."""
    import dataclasses

    from smbs_addon.trace.eye import view_tables

    sc = _mirror_scene(True)
    sc.view_normals, sc.view_points = _view(sc, TILTED)
    full = CameraModel(sc.camera)
    small = CameraModel(dataclasses.replace(sc.camera, resolution_percentage=40))
    assert (small.W, small.H) == (12, 9)
    p = np.array([[0.3, 0.2, 0.0], [-0.5, -0.4, 0.0], [0.9, 0.6, 0.0]])
    for cam in (full, small):
        rx, ry = cam.project(p)[:2]
        t = view_tables(sc, cam).t
        col, row = np.floor(t[0] * rx + t[1]).astype(int), np.floor(t[2] * ry + t[3]).astype(int)
        np.testing.assert_allclose(sc.view_points[row, col], p, atol=0.06)  # within a sub-pixel's footprint
    np.testing.assert_allclose(view_tables(sc, full).t, [2.0, 0.0, 2.0, 0.0], atol=1e-9)
