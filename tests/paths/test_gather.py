"""indirect.gather for the light tracer (no walks to connect): its paths traced in compiled code
(gather.gather_lanes) against the analytic answer, against the numpy estimator it replaced
(gather(compiled=False)), and the kernel's resumption when its records do not fit."""
from __future__ import annotations

import math

import numpy as np
import pytest

from testkit import scenes
from smbs_addon.core import embree
from smbs_addon.kernels import gather, handoff, records
from smbs_addon.paths import gather as indirect
from smbs_addon.shading import optics
from smbs_addon.scene.light_paths import Limits
from smbs_addon.trace.eye import Receivers
from smbs_addon.baking.plan import make_plan
from smbs_addon.trace.tracer import Tracer

POINTS = np.array([[0.0, 0.0, 0.0], [0.15, 0.1, 0.0], [-0.2, 0.05, 0.0], [0.05, -0.25, 0.0]])


class _Capture:
    """A film that keeps each splat's value per receiver (rx: the receiver's index)."""

    def __init__(self, n):
        self.value = np.zeros((n, 3))

    def splat(self, rx, ry, v, albedo=None):
        np.add.at(self.value, rx.astype(np.int64), v)


def _receivers(scene, points, copies):
    """copies receivers at each floor point, seen from straight above (the floor's material)."""
    n = len(points) * copies
    up = np.tile([0.0, 0.0, 1.0], (n, 1))
    floor = int(scene.tri_material[np.flatnonzero(scene.mat_kind[scene.tri_material] == 0)[0]])
    return Receivers(rx=np.arange(n, dtype=float), ry=np.zeros(n), p=np.repeat(points, copies, axis=0), ng=up, ns=up,
                     w_eye=up.copy(), beta=np.ones((n, 3)), mat=np.full(n, floor), eye_specular=np.ones(n, np.int64),
                     weight=np.ones(n), prior=np.zeros((n, 3), np.int64))


def _gathered(scene, rc, seed, compiled, lights_direct=(), lights_hit=None, casters=True):
    """gather's radiance per receiver and its stats (lights_hit: every light unless given;
    casters False: the plan names no caster)."""
    plan = make_plan(scene)
    if not casters:
        plan.casters[:] = False
    film, st = _Capture(len(rc.p)), {}
    hit = [lp.index for lp in plan.lights] if lights_hit is None else lights_hit
    indirect.gather(scene, Tracer(scene), film, plan, rc, np.random.default_rng(seed), st,
                    indirect.GatherLights(direct=lights_direct, hit=hit, count_first=True), compiled=compiled)
    return film.value, st


def _per_point(value, copies):
    """Mean luminance-free radiance (channel 0) per point and its standard error."""
    v = value[:, 0].reshape(-1, copies)
    return v.mean(axis=1), v.std(axis=1, ddof=1) / math.sqrt(copies)


def test_compiled_gather_is_the_mirror_caustic_seen_from_the_floor():
    """Floor points under the 45-degree mirror, x0's own bounce only (Light Paths: 1 diffuse
    bounce): the radiance the gather finds there is albedo / pi x rho x the irradiance of the
    light's mirror image (a disk of radius 0.6 at height 3.5, facing down; quadrature), within 4
    standard errors of each point's 100,000 paths, compiled and numpy alike, and none where the plan
    names no caster; the compiled paths cast as many rays as the numpy ones within 1%."""
    radius, power = 0.6, 100.0
    scene = scenes.mirror_scene(radius=radius)
    scene.light_paths = np.array([-1, 1, -1, -1])
    copies = 100000
    rc = _receivers(scene, POINTS, copies)
    E = scenes.disk_irradiance(POINTS, center=np.array([0, 0, 3.5]), normal=[0, 0, -1], radius=radius,
                               radiance=power / (math.pi * math.pi * radius**2))
    want = scenes.FLOOR_ALBEDO / math.pi * scenes.MIRROR_RHO * E
    rays = []
    for compiled in (True, False):
        value, st = _gathered(scene, rc, 3, compiled)
        mean, se = _per_point(value, copies)
        assert np.all(se < 0.05 * want)  # the test can resolve a 20% error
        assert np.all(np.abs(mean - want) < 4 * se), (compiled, mean, want, se)
        rays.append(st["rays_gather"])
        # light seen through a mirror that is no planned caster is not the layer's
        assert not _gathered(scene, rc.take(slice(0, 4000)), 3, compiled, casters=False)[0].any()
    assert abs(rays[0] - rays[1]) < 0.01 * rays[1]


@pytest.mark.parametrize("layered", [False, True])
def test_compiled_gather_lights_later_diffuse_vertices_as_numpy_does(layered):
    """The direct light at later diffuse vertices alone (no light hit counts): from the floor under
    the mirror, cosine bounces that reflect off the mirror onto the floor lit by the light (floor ->
    mirror -> floor -> light, Cycles' default 4 diffuse bounces). The compiled paths' vertex records
    and the numpy estimator, independent random numbers, 100,000 paths each: the same radiance
    within 4 standard errors of the difference, which resolves 1/10 of it (a lost albedo, 25%,
    would show). Layered: the floor under a glossy layer of tint 5 (layer.py; the later vertex
    weighs 1 - 5 A towards the mirror, 0.4-0.8), which both must apply: the radiance falls by
    more than a fifth."""
    scene = scenes.mirror_scene(radius=0.6)
    if layered:
        scene.mat_layer = np.zeros((len(scene.mat_kind), 8))
        scene.mat_layer[scene.mat_kind == 0] = (1.5, 0.5, 5.0, 1.0, 0.0, 0.0, 0.0, 0.0)
    copies = 100000
    rc = _receivers(scene, POINTS[:1], copies)
    lights = [lp.index for lp in make_plan(scene).lights]
    res = {}
    for compiled in (True, False):
        value, st = _gathered(scene, rc, 4, compiled, lights_direct=lights, lights_hit=())
        res[compiled] = _per_point(value, copies)
        assert st["rays_direct"] > 1000
    (m1, s1), (m0, s0) = res[True], res[False]
    assert np.all(np.abs(m1 - m0) < 4 * np.hypot(s1, s0)), (m1, m0, s1, s0)
    assert np.all(np.hypot(s1, s0) < 0.1 * m0)
    if layered:
        scene.mat_layer = np.zeros((0, 8))
        bare, _ = _per_point(_gathered(scene, rc, 4, True, lights_direct=lights, lights_hit=())[0], copies)
        assert np.all(m1 < 0.8 * bare) and np.all(m0 < 0.8 * bare), (m1, m0, bare)


@pytest.mark.parametrize("stratified", [False, True])
def test_compiled_gather_connects_the_walks_where_numpy_does(stratified):
    """With the walks to connect (here a stand-in: a caustic of 1 + 4 x^2 at a later diffuse vertex,
    times its throughput), the compiled paths' connect records and the numpy generations, 100,000
    paths from under the mirror each, independent random numbers: the same radiance within 4 standard
    errors of the difference, which resolves a tenth of it; the vertices the walks see carry the
    events before them and their eye sample's stratified numbers after the bounce."""
    from smbs_addon.core import qmc

    scene = scenes.mirror_scene(radius=0.6)
    copies = 100000
    rc = _receivers(scene, POINTS[:1], copies)
    if stratified:
        rc.strata = np.random.default_rng(9).random((len(rc.p), qmc.PATH_DIMS))
    seen = []

    def connect(sub):
        seen.append(sub)
        return (1.0 + 4.0 * sub.p[:, :1] ** 2) * sub.beta

    res = {}
    for compiled in (True, False):
        plan = make_plan(scene)
        film, st = _Capture(len(rc.p)), {}
        indirect.gather(scene, Tracer(scene), film, plan, rc, np.random.default_rng(3 + compiled), st,
                        indirect.GatherLights(connect=connect), compiled=compiled)
        res[compiled] = _per_point(film.value, copies)
    (m1, s1), (m0, s0) = res[True], res[False]
    assert np.all(np.abs(m1 - m0) < 4 * np.hypot(s1, s0)), (m1, m0, s1, s0)
    assert np.all(np.hypot(s1, s0) < 0.1 * m0)
    for sub in seen:
        assert np.all(sub.prior[:, 0] >= 1) and np.all(sub.eye_specular >= 1)
        assert (sub.strata is None) == (not stratified)


def test_gather_lanes_leaves_a_lane_whole_when_its_records_do_not_fit():
    """gather.gather_lanes with room for 40 records a call gives, call after call, exactly the
    records, lanes and ray counts of one call with room for all: a lane whose records would not fit
    is traced again whole in the next call (its random numbers are keyed by lane and event)."""
    scene = scenes.mirror_scene(radius=0.6)
    rc = _receivers(scene, POINTS, 2000)
    plan = make_plan(scene)
    tracer = Tracer(scene)
    n = len(rc.p)
    args = (records.GatherReceivers(rc.p, rc.ng, rc.ns, rc.w_eye, rc.beta, rc.mat.astype(np.int64), rc.prior, np.zeros((0, 2))),
            tracer.kernel_geometry(plan.casters), optics.materials(scene),
            records.GatherRules(Limits.of(scene).array(), indirect.MAX_SPECULAR, False, True, True, True, True,
                                np.asarray(plan.receivers, bool), np.zeros(len(scene.object_names), bool)), tracer.eps)

    def run(cap):
        out, lane, rays = [], 0, 0
        while lane < n:
            seg, seg_i = np.empty((cap, records.SEG_F)), np.empty(cap, np.int64)
            vx, vx_i = np.empty((cap, records.VX_F)), np.empty(cap, np.int64)
            cx, cx_i = np.empty((cap, records.CX_F)), np.empty(cap, np.int64)
            lane, ms, mv, mc, counts = gather.gather_lanes(tracer.rays(), 77, lane, *args,
                                                           records.GatherOut(seg, seg_i, vx, vx_i, cx, cx_i))
            rays += int(counts[embree.KINDS:].sum())
            out.append((seg[:ms], seg_i[:ms], vx[:mv], vx_i[:mv], cx[:mc], cx_i[:mc]))
        return [np.concatenate([o[k] for o in out]) for k in range(6)], rays, len(out)

    whole, rays, calls = run(10 * n)
    assert calls == 1 and len(whole[0]) > 400 and len(whole[2]) > 400 and len(whole[4]) > 400
    parts, rays_parts, calls_parts = run(40)
    assert calls_parts > 20
    assert rays_parts == rays
    for a, b in zip(whole, parts):
        np.testing.assert_array_equal(a, b)


def test_segments_near_keeps_every_segment_that_meets_a_light():
    """handoff.segments_near, the hand-off's pre-test (indirect._light_shapes): every segment that
    lights.light_radiance finds meeting a light (beyond: wherever it lies) is kept, for a point of
    radius 0.1 with soft falloff, a spot, a square, a rectangle whose axes are sheared (the light
    test reads them as they are), a disk, an ellipse and a mesh light (the sphere about its box); a
    point of radius 0 is met by none, and keeps none. Segments from random origins in the room,
    three in four aimed at points scattered 0.3 about a light (on it, past its edges), one in four in
    random directions: the exact test finds 20 or more per light, and the pre-test keeps no more
    than 5 times those that meet the light at all (a spot's beyond its cone), under half of all.
    A light at infinity keeps them all."""
    from smbs_addon.shading import lights as L
    from smbs_addon.scene import arrays as S
    from smbs_addon.scene.builder import SceneBuilder, look_at

    b = SceneBuilder("lights")
    grey = b.material("Grey", "diffuse", color=(0.8, 0.8, 0.8))
    glow = b.material("Glow", "emitter", color=(1, 1, 1), strength=5.0)
    b.plane("Floor", (0, 0, 0), 8, grey, receiver=True)
    b.plane("Panel", (1.0, -1.0, 2.5), 0.6, glow, normal=(0.3, 0, -1))
    b.light("Bulb", "POINT", location=(-1, 1, 2), radius=0.1, soft_falloff=True)
    b.light("Dot", "POINT", location=(0, 0, 2), radius=0.0)
    b.light("Spot", "SPOT", location=(1, 1, 2.2), target=(0, 0, 0), radius=0.2)
    b.light("Square", "AREA", location=(-1, -1, 2.5), target=(0, 0, 0), size=0.5)
    m = look_at((0.5, 0.0, 3.0), (0.0, 0.2, 0.0))
    m[:3, 0] = 1.3 * m[:3, 0] + 0.6 * m[:3, 1]  # x axis leaning towards y
    b.light("Rect", "AREA", matrix=m, shape="RECTANGLE", size=(0.8, 0.3))
    b.light("Disk", "AREA", location=(-2, 0, 1.5), target=(0, 0, 1.5), shape="DISK", size=0.4)
    b.light("Ellipse", "AREA", location=(2, 0, 1.5), target=(0, 0.3, 0.5), shape="ELLIPSE", size=(0.7, 0.2))
    b.set_camera((0, -4, 2), (0, 0, 0.5), resolution_x=16, resolution_y=12)
    b.light("Sun", "SUN", angle=0.1)
    scene = b.build()
    sun = int(np.flatnonzero(scene.light_type == S.SUN)[0])
    everything = np.zeros((50, 2), bool)
    seg_n = np.array([0, 1, 2, 2, 1] * 10)
    handoff.segments_near(np.ones((50, 2, 10)), seg_n, indirect._light_shapes(scene, (1, sun), 1e-6), everything)
    assert np.array_equal(everything, seg_n[:, None] > np.arange(2))  # a sun: every segment, none past them
    rng = np.random.default_rng(11)
    lights = tuple(li for li in range(len(scene.light_type)) if li != sun)
    assert sorted(scene.light_type[list(lights)].tolist()) == sorted([S.POINT, S.POINT, S.SPOT] + [S.AREA] * 4 + [S.MESH])
    shapes = indirect._light_shapes(scene, lights, 1e-6)
    n, K = 40_000, 2
    o = rng.uniform((-3, -3, 0.05), (3, 3, 3.5), (n * K, 3))
    aim = np.empty_like(o)
    for j, li in enumerate(np.asarray(lights)[np.arange(n * K) % len(lights)]):
        c = scene.light_matrix[li][:3, 3] if scene.light_type[li] != S.MESH else np.array([1.0, -1.0, 2.5])
        aim[j] = c + rng.normal(0, 0.3, 3)
    d = aim - o
    d[::4] = rng.normal(size=(len(d[::4]), 3))  # a quarter in random directions
    d /= np.linalg.norm(d, axis=1)[:, None]
    seg = np.zeros((n, K, 10))
    seg[:, :, 0:3], seg[:, :, 3:6] = o.reshape(n, K, 3), d.reshape(n, K, 3)
    seg_n = rng.integers(0, K + 1, n)
    near = np.zeros((n, K), bool)
    handoff.segments_near(seg, seg_n, shapes, near)
    met_any = np.zeros((n, K), bool)
    for j, li in enumerate(lights):
        met, geom = np.zeros((n, K), bool), np.zeros((n, K), bool)  # lit, and met at all (a spot's cone)
        for k in range(K):
            Lk, t = L.light_radiance(scene, li, seg[:, k, 0:3], seg[:, k, 3:6], beyond=True)
            geom[:, k] = np.isfinite(t) & (seg_n > k)
            met[:, k] = geom[:, k] & (Lk.max(axis=1) > 0)
        alone = np.zeros((n, K), bool)
        handoff.segments_near(seg, seg_n, shapes[j:j + 1], alone)
        assert not (met & ~alone).any(), scene.light_names[li]
        name = scene.light_names[li]
        if name == "Dot":
            assert met.sum() == 0 and alone.sum() == 0
        else:  # found by the exact test, and not many more kept than it finds
            assert met.sum() > 20 and alone.sum() < 5 * geom.sum() + 200, (name, met.sum(), geom.sum(), alone.sum())
        met_any |= met
    assert not (met_any & ~near).any() and near.sum() < 0.5 * (seg_n[:, None] > np.arange(K)).sum()
    assert not near[seg_n[:, None] <= np.arange(K)].any()  # nothing past a lane's segments
