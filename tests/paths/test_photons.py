"""The light tracer's photons, compiled (lights.emit, photons.photon_lanes): the flux they
carry against independent estimates, a mirror's caustic photons against the law of
reflection, and the kernel's bookkeeping (records that do not fit, threads) exact."""
import math

import numpy as np
import pytest

from testkit import scenes
from testkit.checks import TARGETS, hits_spheres, mean_se, uniform_sphere
from smbs_addon import BakeSettings, bake
from smbs_addon.core import embree
from smbs_addon.kernels import eye
from smbs_addon.kernels import photons
from smbs_addon.kernels import records
from smbs_addon.shading import optics
from smbs_addon.paths import photons as reference
from smbs_addon.scene import arrays as S
from smbs_addon.scene.light_paths import Limits
from smbs_addon.scene.builder import SceneBuilder
from smbs_addon.trace.eye import view_tables
from smbs_addon.shading.lights import emit
from smbs_addon.baking.plan import make_plan
from smbs_addon.trace.tracer import Tracer

POWER = 100.0


def _light_scene(kind, **kw):
    b = SceneBuilder("lights")
    b.plane("Floor", (0, 0, 0), 10, b.material("floor", "diffuse"))
    b.light("L", kind, location=(0, 0, 3), target=(0, 0, 0), power=POWER, **kw)
    b.set_camera((0, -6, 5), (0, 0, 0), resolution_x=8, resolution_y=6)
    return b.build()


@pytest.mark.parametrize("kind, kw", [("POINT", dict(radius=0.0)), ("POINT", dict(radius=0.15)),
                                      ("AREA", dict(shape="RECTANGLE", size=(0.8, 0.5))),
                                      ("AREA", dict(shape="DISK", size=0.6)), ("SUN", dict(angle=0.0))])
def test_emitted_flux_is_the_light_s_flux_into_its_targets(kind, kw):
    """The photons' flux summed (each carries flux / pdf / n) against the same flux found by an
    independent estimator: uniform directions on the sphere (point lights: intensity times the
    solid angle of the targets' cones, grown by the light's radius), uniform points on the light
    and cosine directions (area lights: pi L A times the share of them that meet a target),
    uniform points across the targets' discs (suns: irradiance times the discs' union). Within 4
    combined standard errors, each under 1%."""
    scene = _light_scene(kind, **kw)
    ph = emit(scene, 0, TARGETS, 400_000, np.random.default_rng(1))
    assert np.all(np.isfinite(ph.w)) and np.allclose(np.linalg.norm(ph.d, axis=1), 1.0)
    got, got_se = mean_se(ph.w[:, 0] * len(ph.w))
    rng = np.random.default_rng(2)
    n = 2_000_000
    if kind == "POINT":
        grown = TARGETS + np.array([0, 0, 0, kw["radius"]])
        hit = hits_spheres(np.array([0.0, 0.0, 3.0]), uniform_sphere(rng, n), grown)
        x = POWER / (4 * math.pi) * 4 * math.pi * hit
    elif kind == "AREA":
        if kw["shape"] == "DISK":
            r = 0.3 * np.sqrt(rng.random(n))
            phi = 2 * math.pi * rng.random(n)
            xy, area = np.column_stack([r * np.cos(phi), r * np.sin(phi)]), math.pi * 0.3**2
        else:
            xy, area = (rng.random((n, 2)) - 0.5) * [0.8, 0.5], 0.8 * 0.5
        o = np.column_stack([xy, np.full(n, 3.0)])
        u1, u2 = rng.random(n), rng.random(n)
        s = np.sqrt(u1)
        d = np.column_stack([s * np.cos(2 * math.pi * u2), s * np.sin(2 * math.pi * u2), -np.sqrt(1 - u1)])
        assert abs(area - scene.light_size[0].prod() * (math.pi / 4 if kw["shape"] == "DISK" else 1)) < 1e-12
        x = POWER / (math.pi * area) * math.pi * area * hits_spheres(o, d, TARGETS)
    else:  # a sun straight down: the discs' union seen from above
        lo, hi = (TARGETS[:, :2] - TARGETS[:, 3:]).min(0), (TARGETS[:, :2] + TARGETS[:, 3:]).max(0)
        q = lo + (hi - lo) * rng.random((n, 2))
        inside = np.zeros(n, bool)
        for c, r in zip(TARGETS[:, :2], TARGETS[:, 3]):
            inside |= ((q - c) ** 2).sum(1) <= r * r
        x = POWER * np.prod(hi - lo) * inside
    want, want_se = mean_se(x)
    se = math.hypot(got_se, want_se)
    assert se < 0.01 * want
    assert abs(got - want) < 4 * se, (got, want, se)


def _trace(scene, plan, tracer, ph, key, indirect, cap, max_iter):
    """photons.photon_lanes over every photon, cap records per call: records, tally, rays."""
    n = len(ph.o)
    K = 2
    hist, h_prim = np.zeros((n, K, records.HIST_BENT)), np.zeros((n, K), np.int64)
    tally = np.zeros(records.PH_TALLY, np.int64)
    recs, ids, lane, rays, calls = [], [], 0, 0, 0
    while lane < n:
        rec, rec_i = np.empty((cap, records.REC_F)), np.empty((cap, 3), np.int64)
        batch = records.PhotonBatch(ph.o, ph.d, ph.w, np.zeros(3), 0.0, ph.visibility, np.zeros(0, bool),
                                    np.zeros(0, bool))
        lane, m, counts = photons.photon_lanes(tracer.rays(), batch, key, lane, tracer.kernel_geometry(plan.casters),
                                               plan.receivers, optics.materials(scene),
                                               records.PhotonRules(indirect, Limits.of(scene).array(), 32, max_iter,
                                                                   False),
                                               tracer.eps, records.PhotonOut(rec, rec_i, hist, h_prim, tally))
        recs.append(rec[:m])
        ids.append(rec_i[:m])
        rays += int(counts[embree.KINDS:].sum())
        calls += 1
    return np.concatenate(recs), np.concatenate(ids), tally, rays, calls, hist, h_prim


@pytest.mark.parametrize("indirect", [False, True])
def test_records_that_do_not_fit_are_traced_again_the_same(indirect):
    """A lane whose records would overflow the buffer is left whole for the next call, with its
    rays and tallies taken back: with room for 5 records per call, the records, tallies, rays
    and hand-off history are those of one call with room for all. Caustic photons: a glass ball
    on a floor under an area light; indirect ones: water over a floor under a point light, whose
    photons reach the floor again after the water's underside (several records per photon)."""
    scene = scenes.water_scene("point") if indirect else scenes.glass_sphere_scene(resolution=(32, 24))
    plan = make_plan(scene)
    tracer = Tracer(scene)
    lp = plan.lights[0]
    n = 20000 if indirect else 4000
    ph = emit(scene, lp.index, plan.scene_sphere if indirect else lp.targets, n, np.random.default_rng(7))
    max_iter = 37 if indirect else 33
    big = _trace(scene, plan, tracer, ph, 12345, indirect, n * 8, max_iter)
    small = _trace(scene, plan, tracer, ph, 12345, indirect, 5, max_iter)
    assert big[4] == 1 and small[4] > 50
    assert len(big[0]) > 250
    assert np.array_equal(big[0], small[0]) and np.array_equal(big[1], small[1])
    assert np.array_equal(big[2], small[2]) and big[3] == small[3]
    assert np.array_equal(big[5], small[5]) and np.array_equal(big[6], small[6])
    assert big[2][records.PH_PHOTONS] == n
    if indirect:  # a photon splats at every receiver once it may
        assert len(np.unique(big[1][:, 0])) < len(big[1])


def test_mirror_photons_reflect_onto_the_floor():
    """Photons of a disk light on a flat 45-degree mirror: every record lies where the mirrored
    ray (from the mirror point offset by tracer.eps) meets the floor (to 1e-9), carries the
    photon's flux times the mirror's reflectance (the shading normal is the geometric one: no
    adjoint correction), after 1 bounce; and there is one record for every photon whose first
    hit is the mirror and whose reflection meets the floor."""
    scene = scenes.mirror_scene(resolution=(40, 30))
    plan = make_plan(scene)
    tracer = Tracer(scene)
    lp = plan.lights[0]
    ph = emit(scene, lp.index, lp.targets, 20000, np.random.default_rng(3))
    stats = {}
    rec, ids, hist, h_prim, tally = reference.run_photons(scene, tracer, plan, ph, np.random.default_rng(4), stats)
    n_m = np.array([-1.0, 0.0, -1.0]) / math.sqrt(2)
    o, d = ph.o[ids[:, 0]], ph.d[ids[:, 0]]
    t_m = ((np.array([0.0, 0.0, 1.5]) - o) @ n_m) / (d @ n_m)
    on_mirror = o + t_m[:, None] * d
    r = d - 2 * (d @ n_m)[:, None] * n_m
    start = on_mirror + tracer.eps * np.sign(r @ n_m)[:, None] * n_m  # tracer.spawn's offset
    floor = start - (start[:, 2] / r[:, 2])[:, None] * r
    assert len(rec) > 5000
    assert np.abs(rec[:, records.REC_P:records.REC_P + 3] - floor).max() < 1e-9
    assert np.allclose(rec[:, records.REC_BETA:records.REC_BETA + 3], ph.w[ids[:, 0]] * scenes.MIRROR_RHO,
                       rtol=1e-12, atol=0)
    assert np.allclose(rec[:, records.REC_W:records.REC_W + 3], -r, atol=1e-12)
    assert np.all(ids[:, 1] == 1) and len(np.unique(ids[:, 0])) == len(ids)
    # every photon that meets the mirror first and reflects onto the floor splats, no other
    h = tracer.intersect(ph.o, ph.d)
    first_mirror = h.hit & (scene.tri_object[np.maximum(h.prim, 0)] == scene.object_names.index("Mirror"))
    dm = ph.d[first_mirror]
    rm = dm - 2 * (dm @ n_m)[:, None] * n_m
    pm = h.p[first_mirror]
    land = pm - (pm[:, 2] / rm[:, 2])[:, None] * rm
    onto = (rm[:, 2] < 0) & (np.abs(land[:, :2]).max(axis=1) < 5.0)
    assert np.array_equal(np.sort(ids[:, 0]), np.flatnonzero(first_mirror)[onto])
    assert stats["photons"] == 20000 and tally[records.PH_LOST] == 0


def test_light_tracer_same_image_whatever_the_threads():
    """The light tracer's photons and eye paths on one and on two threads: the same image, bit
    for bit, and the same rays (glass ball: caustic, indirect and seen-through-glass passes)."""
    s = dict(method="reference", spp=4, batches=2, seed=3)
    a = bake(scenes.glass_sphere_scene(resolution=(48, 36)), BakeSettings(**s, threads=1))
    b = bake(scenes.glass_sphere_scene(resolution=(48, 36)), BakeSettings(**s, threads=2))
    assert a.image.max() > 0 and a.stats["indirect"]
    assert a.stats["rays"] == b.stats["rays"]
    assert np.array_equal(a.image, b.image) and np.array_equal(a.variance, b.variance)


def _splat_to_camera_numpy(tracer, cam, margin, y, ng, ns, w_in, beta, albedo, under_layer):
    """The camera connection as reference.splat_to_camera made it in numpy (camera.CameraModel's
    towards and importance, tracer.spawn and occluded), for eye.camera_splats to be held to:
    (raster x, raster y, value) of the splats, and the shadow rays cast."""
    rx, ry, to_cam, tmax, cos_axis, dist, valid = cam.towards(y, margin)
    ci_g, co_g = (w_in * ng).sum(1), (to_cam * ng).sum(1)
    ci_s = (w_in * ns).sum(1)
    valid &= (ci_g * co_g > 0) & (ci_s * np.sign(ci_g) > 0)
    idx = np.flatnonzero(valid)
    o = tracer.spawn(y[idx], ng[idx], to_cam[idx])
    blocked = tracer.occluded(o, to_cam[idx], tmax[idx] - tracer.eps)
    rays = idx.size
    idx = idx[~blocked]
    corr = np.abs(ci_s[idx]) / np.maximum(np.abs(ci_g[idx]), 1e-12)
    imp = cam.importance(cos_axis[idx], dist[idx], co_g[idx])
    glossy = under_layer(idx, to_cam[idx], ns[idx], w_in[idx])  # what a Principled coat leaves the caustic
    return rx[idx], ry[idx], beta[idx] * (albedo[idx] / math.pi) * (corr * imp)[:, None] * glossy, rays


@pytest.mark.parametrize("name", ["glass_sphere", "water_ortho", "glass_sphere_principled_floor",
                                  "glass_sphere_rough_floor"])
def test_camera_splats_are_the_numpy_connection(name):
    """eye.camera_splats (the light tracer's records connected to the camera, the shadow rays
    cast in the kernel) against the same connection made in numpy from CameraModel.towards and
    importance: the same splats (raster positions to 1e-9 pixel, values to 1e-12 relative), the
    same shadow rays, on a perspective camera (the glass ball's caustic, some of it hidden by the ball),
    an orthographic one under water (records in the filter's margin count), and the ball's floor
    under a Principled BSDF's glossy coat (layer.weight towards the camera, optics.coat_factor) or
    rough (Oren-Nayar)."""
    from smbs_addon.shading import coat as layer
    from smbs_addon.trace.camera import CameraModel

    scene = scenes.water_scene("point") if name == "water_ortho" else scenes.glass_sphere_scene(resolution=(32, 24))
    if name.endswith("_floor"):  # a Principled coat; a rough (Oren-Nayar) diffuse
        scene.mat_layer = np.zeros((len(scene.mat_kind), 8))
        scene.mat_layer[scene.mat_kind == S.DIFFUSE] = (1.5, 0.5, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0) if "principled" in name else \
            (0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0)
    tab = layer.table(scene)
    plan = make_plan(scene)
    tracer = Tracer(scene)
    cam = CameraModel(scene.camera)
    lp = plan.lights[0]
    ph = emit(scene, lp.index, lp.targets, 40000, np.random.default_rng(5))
    rec, ids, *_ = reference.run_photons(scene, tracer, plan, ph, np.random.default_rng(6), {})
    assert len(rec) > 1000
    margin = scene.camera.filter_width
    col = lambda k: rec[:, k:k + 3]  # noqa: E731
    want = _splat_to_camera_numpy(tracer, cam, margin, col(records.REC_P), col(records.REC_NG), col(records.REC_NS),
                                  col(records.REC_W), col(records.REC_BETA), scene.mat_color[ids[:, 2]],
                                  lambda idx, to_cam, ns, w: layer.weight(tab, ids[idx, 2], (to_cam * ns).sum(1))[:, None]
                                  * optics.coat_factor(scene, ids[idx, 2], ns, to_cam, w))
    n = len(rec)
    rx, ry, val, alb = np.empty(n), np.empty(n), np.empty((n, 3)), np.full((n, 3), np.nan)
    textured = scene.mat_kind == S.DIFFUSE  # every receiver textured: each splat's albedo written beside it
    rays, m, _ = eye.camera_splats(tracer.rays(), cam.kernel_params(), float(margin), rec, ids[:, 2].copy(),
                                       optics.materials(scene), True, tracer.eps, textured, view_tables(scene, cam),
                                       records.CameraHiding(tracer.ng, scene.tri_object, tracer.hid),
                                       records.Splats(rx, ry, val, alb))
    assert 100 < m <= rays <= n and rays == want[3]
    floor = scene.mat_color[scene.mat_kind == S.DIFFUSE].max(axis=0)
    if "principled" in name:  # the albedo under the coat, towards the camera: less than the colour
        assert np.all((alb[:m] > 0.5 * floor) & (alb[:m] < floor))
    else:
        np.testing.assert_array_equal(alb[:m], np.broadcast_to(floor, (m, 3)))
    np.testing.assert_allclose(rx[:m], want[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(ry[:m], want[1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(val[:m], want[2], rtol=1e-12, atol=0)
    x0, x1, y0, y1 = cam.region
    if name == "glass_sphere":  # the ball hides some records from the camera
        assert m < rays
    else:  # the caustic covers the floor: records in the filter's margin splat too
        assert np.any((rx[:m] < x0) | (rx[:m] >= x1) | (ry[:m] < y0) | (ry[:m] >= y1))
