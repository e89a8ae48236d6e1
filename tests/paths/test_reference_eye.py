"""Caustics seen in a mirror: the eye-side estimator agrees with the direct view.

Scene B adds a second, non-caster mirror (the plane y = -3) and puts the camera
at the mirror image of scene A's camera, so B sees A's floor through the mirror
(the camera matrix is reflected too, so pixel for pixel). Then B = rho2 x A: the light tracer makes A, the
eye-path estimator (camera -> mirror -> floor -> mirror -> light) makes B. First-order
caustics only: with indirect ones, B's side mirror would also light A's floor.
"""
import math

import numpy as np
import pytest

from testkit import scenes
from smbs_addon import BakeSettings, bake
from smbs_addon.baking.result import caustic_region
from smbs_addon.scene.builder import SceneBuilder, look_at

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


def _first_hit_specular_cells(scene, n=300_000, seed=0):
    """Film cells (eye.film_cells' grid) of uniform sample positions over the whole widened film
    whose camera ray meets a mirror or glass first: found by brute force."""
    from smbs_addon.scene import arrays as S
    from smbs_addon.trace.camera import CameraModel
    from smbs_addon.trace.film import Film
    from smbs_addon.trace.tracer import Tracer

    cam = CameraModel(scene.camera)
    film = Film(cam.W, cam.H, scene.camera.filter_width, cam.region)
    x0, x1, y0, y1 = cam.region
    r = int(np.ceil(film.filter_width))
    cw, ch = x1 - x0 + 2 * r, y1 - y0 + 2 * r
    rng = np.random.default_rng(seed)
    cx, cy = rng.integers(0, cw, n), rng.integers(0, ch, n)
    rx, ry = x0 - r + cx + rng.random(n), y0 - r + cy + rng.random(n)
    o, d, tnear = cam.rays(rx, ry)
    tracer = Tracer(scene)
    h = tracer.intersect(o + tnear[:, None] * d, d)
    kind = np.where(h.hit, scene.mat_kind[scene.tri_material[np.maximum(h.prim, 0)]], -1)
    spec = (kind == S.CONDUCTOR) | (kind == S.DIELECTRIC)
    return np.unique((cy * cw + cx)[spec]), cam, film, tracer


def test_eye_cells_hold_every_sample_that_sees_a_mirror_or_glass_first():
    """eye.specular_cells bounds what the camera sees of mirrors and glass: every one of 300k
    uniform sample positions over the widened film whose ray meets one first lies in its cells
    (exact), and on a ball, a ring and a pane the cells are far fewer than the film's; also on a
    ball whose upper half is diffuse (an object partly mirror or glass: the box of its glass)."""
    from smbs_addon.scene import arrays as S
    from smbs_addon.trace.eye import film_cells, specular_cells

    def half_glass(resolution):
        scene = scenes.glass_sphere_scene(resolution=resolution)
        glass = scene.mat_kind[scene.tri_material] == S.DIELECTRIC
        diffuse = scene.tri_material[np.flatnonzero(scene.mat_kind[scene.tri_material] == S.DIFFUSE)[0]]
        upper = glass & (scene.tri_vertices[:, :, 2].mean(axis=1) > np.median(scene.tri_vertices[glass][:, :, 2]))
        scene.tri_material = np.where(upper, diffuse, scene.tri_material)
        return scene

    for make, most in ((scenes.glass_sphere_scene, 0.5), (scenes.ring_scene, 0.8), (scenes.pane_scene, 0.8),
                       (half_glass, 0.5)):
        scene = make(resolution=(64, 48))
        seen, cam, film, tracer = _first_hit_specular_cells(scene)
        cells = specular_cells(scene, tracer, cam, film)
        assert seen.size > 50 and cells.shape == (film_cells(cam, film),)
        assert cells[seen].all(), seen[~cells[seen]]
        assert cells.sum() < most * len(cells), (scene.name, cells.sum(), len(cells))


def test_eye_pass_from_its_cells_is_the_whole_film_s():
    """The light tracer's eye pass traces only the samples of the cells that can see a mirror or
    glass first, and draws the others all the same: the image is the one the whole film's eye
    pass makes, bit for bit, from a third of its eye paths (glass ball; and the lens scene with a
    second glass ball hidden under its floor, whose box the camera's view covers: no sample
    there sees it first)."""
    from smbs_addon.baking import light_tracing  # it holds eye.specular_cells by name
    from testkit.scenes import lens_scene

    for scene in (scenes.glass_sphere_scene(resolution=(64, 48)), lens_scene(True, (64, 48))):
        s = dict(method="reference", spp=64, batches=2, seed=4)
        cells = bake(scene, BakeSettings(**s))
        real = light_tracing.specular_cells
        light_tracing.specular_cells = lambda *a: None
        try:
            whole = bake(scene, BakeSettings(**s))
        finally:
            light_tracing.specular_cells = real
        assert cells.stats["eye_pass"]["eye_splats"] > 30
        assert np.array_equal(cells.image, whole.image) and np.array_equal(cells.variance, whole.variance)
        assert cells.stats["eye_pass"]["eye_splats"] == whole.stats["eye_pass"]["eye_splats"]
        assert cells.stats["eye_pass"]["eye_paths"] < 0.4 * whole.stats["eye_pass"]["eye_paths"]
        ep, whole_ep = cells.stats["eye_pass"], whole.stats["eye_pass"]
        assert ep["cells"] < whole_ep["cells"] == ep["film_cells"]


def test_eye_paths_reflect_in_the_mirror_onto_the_floor():
    """eye.eye_receivers (kernels.eye_lanes) against the law of reflection: the camera of scene B
    sees the floor in the side mirror (the plane y = -3); every receiver found after one specular
    vertex lies where the camera ray, reflected at the mirror (from the mirror point offset by
    tracer.eps), meets the floor (1e-9), with the mirror's reflectance as throughput, one glossy
    bounce before it, and the direction back along the reflected ray."""
    from smbs_addon.trace.camera import CameraModel
    from smbs_addon.kernels.records import EyePaths
    from smbs_addon.trace.eye import BatchPart, eye_receivers, film_cells
    from smbs_addon.trace.film import Film
    from smbs_addon.baking.plan import make_plan
    from smbs_addon.trace.tracer import Tracer

    scene = _mirror_scene(True)
    cam = CameraModel(scene.camera)
    film = Film(cam.W, cam.H, scene.camera.filter_width, cam.region)
    tracer = Tracer(scene)
    n = film_cells(cam, film)
    rc = eye_receivers(scene, tracer, cam, film, make_plan(scene, "ON"), BatchPart(0, n, n), np.random.default_rng(3), {},
                       EyePaths(min_specular=1))
    assert len(rc.p) > 1000 and np.all(rc.eye_specular == 1)
    o, d, tnear = cam.rays(rc.rx, rc.ry)
    o = o + tnear[:, None] * d
    t_m = (-3.0 - o[:, 1]) / d[:, 1]
    on_mirror = o + t_m[:, None] * d
    r = d * [1.0, -1.0, 1.0]
    start = on_mirror + tracer.eps * np.array([0.0, 1.0, 0.0])  # tracer.spawn: to the side r leaves on
    floor = start - (start[:, 2] / r[:, 2])[:, None] * r
    assert np.abs(rc.p - floor).max() < 1e-9
    assert np.allclose(rc.beta, RHO2, rtol=1e-12) and np.allclose(rc.w_eye, -r, atol=1e-12)
    assert np.array_equal(rc.prior, np.tile([0, 1, 0], (len(rc.p), 1)))


def test_fewer_eye_samples_than_cells_reach_every_cell_with_unit_weight():
    """eye.film_samples with a batch of fewer samples than film cells (the light tracer's bent
    pass below 512 spp: an eye sample in 64 per batch): sample i falls in the i-th of n_batch
    equal stretches of the cells, weighted by the stretch's length, so a batch's weights add up to
    the cells exactly and every cell is reached. It was the first n_batch cells only, each with
    weight 1: cube_grey_reflect's light tracer read 0.742 +- 0.008 of Cycles over 8 seeds at 256
    spp, where at 512 it read 1.0."""
    from smbs_addon.trace.camera import CameraModel
    from smbs_addon.trace.eye import film_cells, film_samples
    from smbs_addon.trace.film import Film

    sc = scenes.glass_sphere_scene(resolution=(20, 15))
    cam = CameraModel(sc.camera)
    film = Film(cam.W, cam.H, sc.camera.filter_width, cam.region)
    cells = film_cells(cam, film)
    x0, x1, y0, y1 = cam.region
    r = int(np.ceil(film.filter_width))
    cw = x1 - x0 + 2 * r
    n_batch = cells // 3 + 1  # stretches of ~3 cells, not a whole number
    stretch = cells / n_batch
    rng = np.random.default_rng(1)
    per_cell = np.zeros(cells)
    for _ in range(200):
        rx, ry, w, i, _ = film_samples(cam, film, 0, n_batch, n_batch, rng)
        c = (np.floor(ry).astype(int) - (y0 - r)) * cw + (np.floor(rx).astype(int) - (x0 - r))
        assert np.array_equal(i, np.arange(n_batch))
        assert np.all((c >= np.floor(i * stretch)) & (c < np.ceil((i + 1) * stretch)))  # its own stretch
        assert np.allclose(w, stretch) and w.sum() == pytest.approx(cells)
        np.add.at(per_cell, c, w)
    assert per_cell.min() > 0  # every cell, the last ones too
    assert per_cell.mean() / 200 == pytest.approx(1.0)
    # a batch's samples in two pieces: the same stretches, so the same cells
    rx, ry, w, i, _ = film_samples(cam, film, 10, 20, n_batch, rng)
    c = (np.floor(ry).astype(int) - (y0 - r)) * cw + (np.floor(rx).astype(int) - (x0 - r))
    assert np.all((c >= np.floor(i * stretch)) & (c < np.ceil((i + 1) * stretch))) and i[0] == 10
    # as many samples as cells or more: one each in turn, as before
    rx, ry, w, i, _ = film_samples(cam, film, 0, 2 * cells + 5, 2 * cells + 5, rng)
    assert np.allclose(w[:5], 1 / 3) and np.allclose(w[5:cells], 0.5)
