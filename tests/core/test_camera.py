"""CameraModel (smbs_addon/camera.py) against Blender itself.

Blender's own projection is ``bpy_extras.object_utils.world_to_camera_view``
(normalised x, y from the bottom left, depth along the view axis). ``mathutils``
works in single precision, so agreement with it can only be asked to float32
accuracy (a few 1e-7 relative); the float64 accuracy of our model is checked
by the round trip ``rays()`` -> ``project()`` instead, to 1e-9.

The test converts bpy cameras to ``scene.Camera`` by hand so it does not depend
on export.py. Border regions are checked against actual (tiny, one-sample)
Cycles renders: the rendered pixels have alpha 1, the rest alpha 0.
"""
import itertools
import math

import numpy as np
import pytest

from smbs_addon.scene import arrays as S
from smbs_addon.trace.camera import CameraModel

bpy = pytest.importorskip("bpy")
from bpy_extras.object_utils import world_to_camera_view  # noqa: E402
from mathutils import Euler, Matrix, Vector  # noqa: E402

pytestmark = pytest.mark.bpy

# float32 arithmetic inside Blender: |ours - blender| <= F32_TOL * (1 + |blender|)
F32_TOL = 2e-6


def _empty_scene_with_camera():
    """An empty Blender session's scene with one camera object, its scene camera: (scene, object)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    ob = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    sc.collection.objects.link(ob)
    sc.camera = ob
    return sc, ob


@pytest.fixture(scope="module")
def blender():
    """An empty Blender session with one camera object (module scoped: cheap tests)."""
    yield _empty_scene_with_camera()
    bpy.ops.wm.read_factory_settings(use_empty=True)


def to_scene_camera(ob, sc) -> S.Camera:
    """bpy camera object + render settings -> scene.Camera, by hand (not export.py)."""
    d, r = ob.data, sc.render
    return S.Camera(
        matrix_world=np.array(ob.matrix_world, float),
        type=S.ORTHO if d.type == "ORTHO" else S.PERSP,
        lens=d.lens, sensor_width=d.sensor_width, sensor_height=d.sensor_height,
        sensor_fit=d.sensor_fit, ortho_scale=d.ortho_scale, shift_x=d.shift_x, shift_y=d.shift_y,
        clip_start=d.clip_start, clip_end=d.clip_end,
        resolution_x=r.resolution_x, resolution_y=r.resolution_y,
        resolution_percentage=r.resolution_percentage,
        pixel_aspect_x=r.pixel_aspect_x, pixel_aspect_y=r.pixel_aspect_y,
        use_border=r.use_border,
        border=(r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y),
        use_crop_to_border=r.use_crop_to_border)


def setup(sc, ob, *, type="PERSP", fit="AUTO", res=(64, 48), percentage=100, aspect=(1.0, 1.0),
          lens=35.0, sensor=(36.0, 20.0), shift=(0.13, -0.21), ortho_scale=7.5,
          loc=(1.5, -3.0, 2.0), rot=(1.1, 0.2, -0.7), scale=(1.0, 1.0, 1.0)):
    d, r = ob.data, sc.render
    d.type, d.sensor_fit, d.lens = type, fit, lens
    d.sensor_width, d.sensor_height = sensor
    d.shift_x, d.shift_y = shift
    d.ortho_scale = ortho_scale
    d.clip_start, d.clip_end = 0.1, 100.0
    r.resolution_x, r.resolution_y = res
    r.resolution_percentage = percentage
    r.pixel_aspect_x, r.pixel_aspect_y = aspect
    r.use_border = False
    ob.matrix_world = Matrix.LocRotScale(Vector(loc), Euler(rot), Vector(scale))
    bpy.context.view_layer.update()
    return CameraModel(to_scene_camera(ob, sc))


def random_points(cm, rng, n=150):
    """World points in front of the camera, exactly representable in float32 (so
    handing them to mathutils loses nothing)."""
    c = np.stack([rng.uniform(-3, 3, n), rng.uniform(-3, 3, n), -rng.uniform(0.5, 20, n)], -1)
    return (cm.origin + c @ cm.axes.T).astype(np.float32).astype(np.float64)


def blender_view(sc, ob, pts):
    return np.array([tuple(world_to_camera_view(sc, ob, Vector(p))) for p in pts])


CASES = list(itertools.product(
    ("PERSP", "ORTHO"), ("AUTO", "HORIZONTAL", "VERTICAL"),
    ((64, 48), (48, 64)),  # landscape, portrait
    ((1.0, 1.0), (1.0, 1.7), (2.0, 1.0)),  # pixel aspect (the second flips AUTO to vertical fit for 64x48)
))


@pytest.mark.parametrize("type,fit,res,aspect", CASES)
def test_project_matches_world_to_camera_view(blender, type, fit, res, aspect):
    sc, ob = blender
    cm = setup(sc, ob, type=type, fit=fit, res=res, aspect=aspect)
    pts = random_points(cm, np.random.default_rng(CASES.index((type, fit, res, aspect))))
    rx, ry, depth, cos, dist, valid = cm.project(pts)
    ref = blender_view(sc, ob, pts)
    ours = np.stack([rx / cm.W, 1.0 - ry / cm.H, depth], -1)
    err = np.abs(ours - ref) / (1.0 + np.abs(ref))
    assert err.max() <= F32_TOL, f"worst disagreement {err.max():.3g} at point {np.argmax(err.max(1))}"
    # a sizeable share of the points is inside the frame, so the test is not vacuous
    inside = (ref[:, 0] > 0) & (ref[:, 0] < 1) & (ref[:, 1] > 0) & (ref[:, 1] < 1)
    assert inside.sum() >= 10


@pytest.mark.parametrize("type", ["PERSP", "ORTHO"])
def test_sheared_camera_under_scaled_parent(blender, type):
    """A camera parented to a rotated, non-uniformly scaled empty has a sheared world
    matrix; Blender (and Cycles) drop the column scale and invert the rest."""
    sc, ob = blender
    setup(sc, ob, type=type)
    parent = bpy.data.objects.new("Parent", None)
    sc.collection.objects.link(parent)
    try:
        ob.parent = parent
        parent.matrix_world = Matrix.LocRotScale(Vector((1, 2, 3)), Euler((0.3, 0.5, 0.1)), Vector((1, 3, 0.5)))
        ob.matrix_basis = Matrix.LocRotScale(Vector((0.5, -1, 2)), Euler((1.0, -0.4, 0.8)), Vector((1, 1, 1)))
        bpy.context.view_layer.update()
        cm = CameraModel(to_scene_camera(ob, sc))
        assert np.abs(cm.axes.T @ cm.axes - np.eye(3)).max() > 0.5  # really sheared
        pts = random_points(cm, np.random.default_rng(3))
        rx, ry, depth, *_ = cm.project(pts)
        ref = blender_view(sc, ob, pts)
        ours = np.stack([rx / cm.W, 1.0 - ry / cm.H, depth], -1)
        assert (np.abs(ours - ref) / (1.0 + np.abs(ref))).max() <= F32_TOL
        # rays are unit, and still invert project; tnear reaches the clip plane
        rng = np.random.default_rng(4)
        qx, qy = rng.uniform(0, cm.W, 200), rng.uniform(0, cm.H, 200)
        o, d, tnear = cm.rays(qx, qy)
        np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=0, atol=1e-14)
        prx, pry, pdepth, *_ = cm.project(o + 3.0 * d)
        np.testing.assert_allclose(prx, qx, rtol=0, atol=1e-9 * cm.W)
        np.testing.assert_allclose(pry, qy, rtol=0, atol=1e-9 * cm.H)
        _, _, dnear, *_ = cm.project(o + tnear[:, None] * d)
        np.testing.assert_allclose(dnear, ob.data.clip_start, rtol=1e-9)
        _kernel_rays_match(cm, qx, qy)
    finally:
        ob.parent = None
        bpy.data.objects.remove(parent)


@pytest.mark.parametrize("percentage,res", [(50, (128, 96)), (25, (96, 160)), (200, (40, 30))])
@pytest.mark.parametrize("type", ["PERSP", "ORTHO"])
def test_resolution_percentage_and_scaled_camera(blender, percentage, res, type):
    """The percentage scales the raster but not the view; object scale is ignored."""
    sc, ob = blender
    cm = setup(sc, ob, type=type, res=res, percentage=percentage, scale=(2.0, 0.5, 3.0),
               shift=(-0.3, 0.05))
    assert (cm.W, cm.H) == (res[0] * percentage // 100, res[1] * percentage // 100)
    pts = random_points(cm, np.random.default_rng(percentage))
    rx, ry, depth, *_ = cm.project(pts)
    ref = blender_view(sc, ob, pts)
    ours = np.stack([rx / cm.W, 1.0 - ry / cm.H, depth], -1)
    assert (np.abs(ours - ref) / (1.0 + np.abs(ref))).max() <= F32_TOL


def test_frame_corners_are_the_sensor(blender):
    """Independent of Blender: a 36 mm sensor, 50 mm lens, horizontal fit, no shift:
    the right edge of the frame at depth 1 is at x = 18/50; shift moves it by
    shift_x * 36/50 (shift is a fraction of the fitted dimension)."""
    sc, ob = blender
    cm = setup(sc, ob, fit="HORIZONTAL", lens=50.0, sensor=(36.0, 24.0), shift=(0.0, 0.0),
               res=(60, 40), loc=(0, 0, 0), rot=(0, 0, 0))
    # camera at the origin looking down -Z: the point (18/50, 12/50, -1) hits the top right corner
    rx, ry, *_ = cm.project(np.array([[18 / 50, 12 / 50, -1.0]]))
    assert rx[0] == pytest.approx(60, rel=1e-12) and ry[0] == pytest.approx(0, abs=1e-12)
    cm = setup(sc, ob, fit="HORIZONTAL", lens=50.0, sensor=(36.0, 24.0), shift=(0.25, 0.5),
               res=(60, 40), loc=(0, 0, 0), rot=(0, 0, 0))
    sx, sy = np.float32(0.25), np.float32(0.5)  # Blender stores shift in float32
    rx, ry, *_ = cm.project(np.array([[18 / 50 + sx * 36 / 50, 12 / 50 + sy * 36 / 50, -1.0]]))
    assert rx[0] == pytest.approx(60, rel=1e-12) and ry[0] == pytest.approx(0, abs=1e-12)


@pytest.mark.parametrize("type,fit,res,aspect", CASES[::5])
def test_rays_invert_project(blender, type, fit, res, aspect):
    """rays(rx, ry) then project() returns to (rx, ry) to float64 accuracy; the
    near-clip distance lands exactly on the clip plane."""
    sc, ob = blender
    cm = setup(sc, ob, type=type, fit=fit, res=res, aspect=aspect, loc=(1234.5, -987.25, 345.0))
    rng = np.random.default_rng(7)
    n = 500
    rx = rng.uniform(-0.5 * cm.W, 1.5 * cm.W, n)
    ry = rng.uniform(-0.5 * cm.H, 1.5 * cm.H, n)
    o, d, tnear = cm.rays(rx, ry)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=0, atol=1e-14)
    s = rng.uniform(0.2, 50.0, n)
    prx, pry, depth, cos, dist, valid = cm.project(o + s[:, None] * d)
    np.testing.assert_allclose(prx, rx, rtol=0, atol=1e-9 * cm.W)
    np.testing.assert_allclose(pry, ry, rtol=0, atol=1e-9 * cm.H)
    # depth grows linearly along the ray; the view axis is -Z (to float32 accuracy of
    # Blender's matrix, whose rotation is orthogonal only to ~1e-7)
    depth1 = cm.project(o + d)[2]
    np.testing.assert_allclose(depth, s * depth1, rtol=1e-12)
    view_axis = -cm.axes[:, 2]
    np.testing.assert_allclose(depth, s * (d @ view_axis), rtol=1e-6)
    if type == "PERSP":
        np.testing.assert_allclose(dist, s, rtol=1e-12)
        np.testing.assert_allclose(cos, depth1, rtol=1e-12)
        np.testing.assert_allclose(o, np.broadcast_to(cm.origin, o.shape), rtol=0, atol=0)
    else:
        np.testing.assert_allclose(d, np.broadcast_to(view_axis, d.shape), rtol=0, atol=1e-15)
        np.testing.assert_allclose(cos, 1.0)
    _, _, dnear, *_ = cm.project(o + tnear[:, None] * d)
    np.testing.assert_allclose(dnear, ob.data.clip_start, rtol=1e-9)
    # the rays end on the far clip plane (Cycles clips camera rays by depth): clip_far from where they start
    _, _, dfar, *_ = cm.project(o + (tnear + cm.clip_far(d))[:, None] * d)
    np.testing.assert_allclose(dfar, ob.data.clip_end, rtol=1e-9)
    _kernel_rays_match(cm, rx, ry)


def _kernel_rays_match(cm, rx, ry):
    """The eye paths' camera rays (eye._camera_ray, from CameraModel.kernel_params) are rays()'s,
    started on the near clip plane, to rounding."""
    from smbs_addon.kernels import eye

    o, d, tnear = cm.rays(rx, ry)
    ko, kd = eye.camera_rays(cm.kernel_params(), rx, ry)
    np.testing.assert_allclose(kd, d, rtol=0, atol=1e-14)
    np.testing.assert_allclose(ko, o + tnear[:, None] * d, rtol=0, atol=1e-12 * (1 + np.abs(o).max()))


@pytest.mark.parametrize("type", ["PERSP", "ORTHO"])
def test_clip_range_validity(blender, type):
    sc, ob = blender
    cm = setup(sc, ob, type=type)
    near, far = cm.cam.clip_start, cm.cam.clip_end
    depths = np.array([-5.0, -near, 0.0, near * (1 - 1e-9), near, near * (1 + 1e-9), 1.0,
                       far * (1 - 1e-9), far, far * (1 + 1e-9), 2 * far])
    expect = np.array([False, False, False, False, True, True, True, True, True, False, False])
    c = np.stack([np.full_like(depths, 0.01), np.full_like(depths, -0.02), -depths], -1)
    rx, ry, depth, cos, dist, valid = cm.project(cm.origin + c @ cm.axes.T)
    np.testing.assert_allclose(depth, depths, rtol=1e-12, atol=1e-12)
    assert valid.tolist() == expect.tolist()
    assert np.all(np.isfinite(rx)) and np.all(np.isfinite(ry))


def test_border_region_without_border_is_full_frame(blender):
    sc, ob = blender
    cm = setup(sc, ob, res=(37, 23))
    assert cm.region == (0, 37, 0, 23)


# Cycles renders: (resolution, percentage, border min_x, max_x, min_y, max_y). The
# borders fall on or near pixel edges where rounding and truncation differ, and
# where float32 products differ from float64 ones (0.7 * 10 is 7 in float32).
BORDERS = [
    ((10, 10), 100, (0.25, 0.65, 0.15, 0.55)),
    ((10, 10), 100, (0.7, 0.9, 0.7, 0.9)),
    ((37, 23), 100, (0.5118216, 0.9504637, 0.1441596, 0.9486495)),
    ((64, 48), 50, (0.3118314, 0.4233265, 0.4091991, 0.8277026)),
    ((50, 50), 100, (0.1, 0.3, 0.5, 0.7)),
]


@pytest.fixture(scope="module")
def cycles_borders(tmp_path_factory):
    """Render each border once with Cycles (1 sample, tiny) and read back which
    pixels it rendered (alpha > 0), top row first."""
    import OpenImageIO as oiio

    sc, ob = _empty_scene_with_camera()
    sc.world = bpy.data.worlds.new("World")
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.samples = 1
    sc.cycles.use_denoising = False
    sc.cycles.use_adaptive_sampling = False
    sc.render.film_transparent = False
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.use_border = True
    out = []
    folder = tmp_path_factory.mktemp("borders")
    for i, (res, pct, border) in enumerate(BORDERS):
        r = sc.render
        r.resolution_x, r.resolution_y = res
        r.resolution_percentage = pct
        r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = border
        r.use_crop_to_border = False
        r.filepath = str(folder / f"border{i}.exr")
        bpy.ops.render.render(write_still=True)
        inp = oiio.ImageInput.open(r.filepath)
        img = np.asarray(inp.read_image(oiio.FLOAT))
        inp.close()
        out.append((to_scene_camera(ob, sc), img[..., 3] > 0))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return out


@pytest.mark.parametrize("i", range(len(BORDERS)))
def test_border_region_matches_cycles(cycles_borders, i):
    cam, rendered = cycles_borders[i]
    cm = CameraModel(cam)
    assert rendered.shape == (cm.H, cm.W)
    x0, x1, y0, y1 = cm.region
    ours = np.zeros((cm.H, cm.W), bool)
    ours[y0:y1, x0:x1] = True
    rows, cols = np.nonzero(rendered)
    assert (x0, x1, y0, y1) == (cols.min(), cols.max() + 1, rows.min(), rows.max() + 1), (
        f"border {cam.border}: ours {cm.region}")
    assert np.array_equal(ours, rendered)


def test_border_truncates_in_single_precision():
    """Blender's edge is int(float32(frac) * size): 0.7 * 10 is exactly 7 in float32
    (6.99999988 in float64), and 0.25 * 10 = 2.5 truncates to 2 (not rounded to 3)."""
    cam = S.Camera(resolution_x=10, resolution_y=20, use_border=True,
                   border=(float(np.float32(0.25)), float(np.float32(0.7)),
                           float(np.float32(0.7)), float(np.float32(0.9))))
    cm = CameraModel(cam)
    assert math.floor(float(np.float32(0.7)) * 10) == 6  # the float64 product would give 6
    assert cm.region == (2, 7, 20 - 18, 20 - 14)
