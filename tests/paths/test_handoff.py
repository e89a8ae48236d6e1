"""The photon hand-off: light tracing takes the paths that focus light more than
BakeSettings.handoff times (and whole chain types too faint to be worth walks),
the walks take the rest. Both sides evaluate the same function of the path
(estimators.concentration), so they partition path space and the sum stays
unbiased, with a finite variance where the walks alone have an infinite one.
"""
import math

import numpy as np
import pytest

from testkit import scenes
from smbs_addon import BakeSettings, bake
from smbs_addon.paths import photons as reference
from smbs_addon.scene import arrays as S
from smbs_addon.baking.result import caustic_region
from smbs_addon.trace.camera import CameraModel
from smbs_addon.trace.film import Film
from smbs_addon.shading.lights import emit
from smbs_addon.baking.plan import make_plan
from smbs_addon.trace.tracer import Tracer
from testkit.checks import against_reference as _compare


def _trace(scene, tau, seed=3, n=20000):
    plan = make_plan(scene)
    cam = CameraModel(scene.camera)
    film = Film(cam.W, cam.H, scene.camera.filter_width, cam.region)
    tracer = Tracer(scene)
    lp = plan.lights[0]
    stats = dict.fromkeys(("photons", "rays_photon", "rays_camera", "splats", "truncated",
                           "lost_shading_normal"), 0)
    rng = np.random.default_rng(seed)
    ph = emit(scene, lp.index, lp.targets, n, rng)
    handoff = None if tau is None else reference.Handoff(tau, False)
    reference.trace_photons(scene, tracer, cam, film, plan, ph, rng, stats, handoff=handoff)
    film.end_batch()
    return film.image, stats


def test_flat_mirror_paths_have_concentration_one():
    """A flat mirror does not focus: every path's concentration is 1, so a threshold
    just below 1 hands every photon over and one just above none. (Measured on the
    photons' paths: 1 + 2e-6 .. 1 + 3.4e-5, from the ray origins' spawn offsets; the
    walks' converged paths are exact to 1e-6.)"""
    scene = scenes.mirror_scene(resolution=(40, 30))
    all_img, all_st = _trace(scene, None)
    below_img, below_st = _trace(scene, {"R": 1.0 - 1e-3})
    above_img, above_st = _trace(scene, {"R": 1.0 + 1e-3})
    assert all_st["splats"] > 1000
    # every photon reaching the floor is handed over; the camera connection keeps what it sees
    assert below_st["handoff_paths"] >= below_st["splats"] == all_st["splats"]
    assert np.array_equal(below_img, all_img)  # the same photons, the same random numbers
    assert above_st["handoff_paths"] == 0 and above_img.max() == 0


def test_handoff_only_takes_the_named_chain_types():
    """Photons of chain types the walks do not cover are nobody's: with only TT
    handed over, the glass ball's single reflections (R) are not splatted."""
    scene = scenes.glass_sphere_scene(resolution=(40, 30))
    _, both = _trace(scene, {"R": 0.0, "TT": 0.0})
    _, tt = _trace(scene, {"TT": 0.0})
    _, everything = _trace(scene, None)
    assert 0 < tt["handoff_paths"] < both["handoff_paths"]
    assert 0 < tt["splats"] < both["splats"] <= everything["splats"]


@pytest.fixture(scope="module")
def near_focus():
    """A glass ball whose focus lies just above the floor, under an area light: most
    of the caustic's light arrives along paths near the focus, where G is huge."""
    scene = scenes.glass_sphere_scene(resolution=(64, 48), height=0.85)
    # first-order caustics only: the hand-off is the subject, and the indirect ones add noise
    pick = bake(scene, BakeSettings(method="reference", spp=512, seed=9, indirect=False))
    judge = bake(scene, BakeSettings(method="reference", spp=1024, seed=10, indirect=False))
    return scene, judge, caustic_region(pick.image)


@pytest.mark.parametrize("tau", [2.0, 8.0])
def test_walks_plus_photons_match_the_reference_near_a_focus(near_focus, tau):
    """The sum does not depend on where the line is drawn, and matches the light
    tracer within 3% (measured: walks alone are -24% +- 7% and +7% +- 29% at this
    sample count, their infinite-variance tail)."""
    scene, ref, region = near_focus
    res = bake(scene, BakeSettings(method="smbs", spp=16, seed=1, handoff=tau, indirect=False))
    st = res.stats["lights"]["Area"]
    assert st["handoff"]["handoff_paths"] > 0 and st["handed_off"] > 0
    rel, noise, beyond = _compare(res, ref, region)
    assert noise < 0.025, f"too noisy to judge: {noise:.2%}"  # measured 2.3% (tau 8)
    assert abs(rel) < 0.03 + 2 * noise, f"hand-off {tau}: {rel:+.2%} against the reference (noise {noise:.2%})"


def test_faint_chain_types_are_left_to_photons(near_focus):
    """The ball's reflection (R) is a faint glow next to its refracted focus (TT): the
    guide leaves it to the photons, so no receiver seen directly walks an R chain; so are the
    internal reflections that stay faint (a sphere's T R R T), never the focus itself."""
    scene, ref, region = near_focus
    res = bake(scene, BakeSettings(method="smbs", spp=8, seed=2))
    left = res.stats["guide"]["left_to_photons"]
    assert "Area: R" in left and "Area: TT" not in left
    st = res.stats["lights"]["Area"]
    assert st["weak_skips"] > 0
    peak = res.stats["guide"]["peak_share"]["Area"]
    assert peak["TT"] == 1.0
    assert all(peak[name.split(": ")[1]] < 0.05 for name in left), peak


def test_handoff_off_walks_everything():
    scene = scenes.glass_sphere_scene(resolution=(32, 24), height=0.85)
    res = bake(scene, BakeSettings(method="smbs", spp=1, seed=1, handoff=0.0))
    st = res.stats["lights"]["Area"]
    assert "handoff" not in st and "handed_off" not in st and "weak_skips" not in st
    assert res.stats["guide"]["left_to_photons"] == []
    assert math.isfinite(res.image.sum())


def test_seen_handoff_starts_with_the_first_chunk_where_a_caster_is_smooth():
    """Receivers seen through glass hand their focusing paths to cosine sampling from x0
    (indirect.handoff_gather). Where a light's caster is smooth-shaded (it can focus) that
    starts with the bake's first chunk: one chunk (1 spp of 32 x 24) already casts hand-off rays
    through the glass ball. It used to wait for an earlier chunk's walks to meet a focus, and a
    first chunk's fold path carried a quarter of a 2 spp bake's T T energy on a ball seen
    through a pane. Through flat faces a path's concentration is constant (never a fold): the
    pane alone never hands off focusing paths (exact count of chunks), though the floor is seen
    through it (its hand-off rays, if any, are the paths no walk takes: see
    test_paths_no_walk_takes_count_through_glass)."""
    from smbs_addon.walks.manifold import can_focus

    ball = scenes.glass_sphere_scene(resolution=(32, 24), height=0.9)
    res = bake(ball, BakeSettings(method="sms", spp=1, batches=1, seed=1))
    assert res.stats["lights"]["Area"]["walks_seen"] > 0
    assert res.stats["eye_pass"]["rays_handoff"] > 0
    assert res.stats["lights"]["Area"]["seen_handoff_chunks"] == 1
    pane = scenes.pane_scene()
    res = bake(pane, BakeSettings(method="sms", spp=1, batches=1, seed=1))
    assert res.stats["lights"]["Key"]["walks_seen"] > 0
    assert res.stats["lights"]["Key"].get("seen_handoff_chunks", 0) == 0
    assert res.stats["eye_pass"].get("handoff_paths", 0) == 0
    plan = make_plan(pane)
    assert [can_focus(pane, lp) for lp in plan.lights] == [False]
    assert [can_focus(ball, lp) for lp in make_plan(ball).lights] == [True]


def _ball_under(light, size, resolution=(32, 24)):
    """glass_sphere_scene's ball (0.9 up) and camera under a sun of angle `size` degrees, straight down,
    or a point light of radius `size` 4 m up."""
    from smbs_addon.scene.builder import SceneBuilder

    b = SceneBuilder("ball under a " + light)
    b.plane("Floor", (0, 0, 0), 10, b.material("floor", "diffuse", color=(scenes.FLOOR_ALBEDO,) * 3))
    b.uv_sphere("Ball", (0, 0, 0.9), 0.5, b.material("glass", "dielectric", color=(1, 1, 1), ior=1.5))
    if light == "sun":
        b.light("Sun", "SUN", location=(0, 0, 10), target=(0, 0, 0), power=3.0, angle=math.radians(size))
    else:
        b.light("Bulb", "POINT", location=(0, 0, 4.0), power=1000.0, radius=size)
    b.set_camera((0, -2.0, 3.0), (0, 0, 0.0), lens=35, resolution_x=resolution[0], resolution_y=resolution[1])
    return b.build()


def test_a_light_too_small_for_cosine_sampling_is_walked_at_seen_receivers():
    """handoff_gather's 64 cosine directions from a receiver seen through glass find a sun of 0.5
    degrees, at the hand-off's least concentration (4), 0.005 times (bumped water under such a sun:
    10 paths where the walks met 1,796, each a firefly); one of 4 degrees 0.31 times; a bulb of 1 cm
    radius 2.6 m above the ball's box 0.004 times, one of 30 cm 3.4. The small lights' focusing paths
    stay with the walks from the first chunk on (exact counts); the large ones' first chunk hands them
    off, as an area light's does."""
    from smbs_addon.walks import manifold
    from smbs_addon.paths.gather import HANDOFF_SAMPLES

    def hits(sc):
        (lp,) = make_plan(sc).lights
        return manifold.handoff_hits(sc, lp.index, lp.caster_objects)

    small, large = _ball_under("sun", 0.5), _ball_under("sun", 4.0)
    omega = 2 * math.pi * (1 - math.cos(math.radians(0.25)))
    assert math.isclose(hits(small), HANDOFF_SAMPLES * 4 * omega / math.pi, rel_tol=1e-12)
    tiny, soft = _ball_under("point", 0.01), _ball_under("point", 0.3)
    d = 4.0 - 1.4  # the bulb to the top of the ball's box
    omega = 2 * math.pi * (1 - math.sqrt(1 - (0.3 / d) ** 2))
    assert math.isclose(hits(soft), HANDOFF_SAMPLES * 4 * omega / math.pi, rel_tol=1e-3)
    assert max(hits(small), hits(tiny)) < manifold.SEEN_HANDOFF_HITS < min(hits(large), hits(soft))
    world = scenes.world_mirror_scene()
    assert world.light_type.tolist() == [S.WORLD] and hits(world) == math.inf
    for sc, chunks in ((small, 0), (large, 1), (tiny, 0), (soft, 1)):
        name = make_plan(sc).lights[0].name
        st = bake(sc, BakeSettings(method="sms", spp=1, batches=1, seed=1)).stats["lights"][name]
        assert st["walks_seen"] > 0 and st.get("seen_handoff_chunks", 0) == chunks, (name, chunks)


def test_seen_handoff_stops_where_its_gather_finds_fewer_focusing_paths_than_the_walks():
    """The rule, chunk by chunk, from the light's statistics so far: before any hand-off, a first chunk
    where the caster can focus, or once walks met a focusing path; after one, on while it found such
    paths, until the walks have met 16 and the gather fewer than half as many (the bumped water under
    a 0.5-degree sun, were it not walked: about 1 gathered to 225 walked per chunk)."""
    from smbs_addon.walks import manifold

    ball = scenes.glass_sphere_scene(resolution=(32, 24))
    (lp,) = make_plan(ball).lights
    assert (manifold.SEEN_HANDOFF_RATIO, manifold.SEEN_HANDOFF_EVIDENCE) == (0.5, 16)
    ran = {"walks": 10, "seen_handoff_chunks": 2}
    for st, want in (({}, True), ({"walks": 10}, False), ({"walks": 10, "seen_focus": 3}, True),
                     ({"walks": 10, "seen_handoff_chunks": 1}, False),
                     ({**ran, "seen_handoff_paths": 101}, True),
                     ({**ran, "seen_focus": 12, "seen_handoff_paths": 0}, True),  # too few to tell
                     ({**ran, "seen_focus": 16, "seen_handoff_paths": 7}, False),
                     ({**ran, "seen_focus": 16, "seen_handoff_paths": 8}, True),
                     ({**ran, "seen_focus": 225, "seen_handoff_paths": 1}, False),
                     ({"walks": 10, "seen_focus": 225, "seen_handoff_paths": 1}, True),  # it has not run yet
                     # auto's anchor alone walks from the straight line only: those walks tell as well (they
                     # once did not, and the pool under a sun handed off in every chunk, 80% of its time)
                     ({"anchor_walks": 10}, False),
                     ({"anchor_walks": 10, "seen_handoff_chunks": 1}, False),
                     ({"anchor_walks": 10, "seen_focus": 3}, True)):
        assert manifold._hand_off_seen(ball, lp, st) is want, st


def test_seen_handoff_goes_on_where_its_own_first_chunk_found_focusing_paths(monkeypatch):
    """After the first chunk, receivers seen through glass keep handing off where an earlier
    chunk found focusing paths there, by its walks (seen_focus) or by the hand-off itself
    (seen_handoff_paths): on the disk seen through a pane the first chunk's hand-off took 101
    paths where its walks met none, and the second chunk, without the hand-off, walked the
    fold. A mechanism test: the walks are made blind to focusing (their concentration reads
    0), and the hand-off's threshold is brought down to every path (the floor seen through
    this ball hardly ever sees the light through it), so only the hand-off's own evidence can
    keep it on: exact counts of handoff_gather calls that hand off focusing paths, one per chunk
    (that sees the floor through the ball), and one in all once the hand-off is made blind too."""
    import importlib

    bake_module = importlib.import_module("smbs_addon.baking.passes")
    indirect = importlib.import_module("smbs_addon.paths.gather")
    manifold = importlib.import_module("smbs_addon.walks.manifold")
    monkeypatch.setattr(bake_module, "WALK_CHUNK", 32 * 24)  # 4 spp: 4 chunks or more
    estimators = importlib.import_module("smbs_addon.walks.estimators")
    for module in (manifold, estimators):  # each holds the threshold by name
        monkeypatch.setattr(module, "SEEN_HANDOFF_MIN", 0.0)
    monkeypatch.setattr(manifold, "SEEN_HANDOFF_HITS", 0.0)  # at concentration 0 no light is large enough
    monkeypatch.setattr(estimators, "concentration", lambda types, x0, *a: np.zeros(len(x0)))
    calls = []
    gather = indirect.handoff_gather

    def counted(*a, **k):
        if any(math.isfinite(t) for h in a[7].values() for t in h.tau.values()):  # a focus hand-off
            calls.append(len(a[4].p))
        return gather(*a, **k)

    monkeypatch.setattr(manifold, "handoff_gather", counted)  # (manifold holds it by name)
    chunks = []  # per chunk: does it have receivers seen through the ball?
    eye_receivers = manifold.eye_receivers

    def seen_chunks(*a, **k):
        rc = eye_receivers(*a, **k)
        chunks.append(bool((rc.eye_specular > 0).any()))
        return rc

    monkeypatch.setattr(manifold, "eye_receivers", seen_chunks)
    ball = scenes.glass_sphere_scene(resolution=(32, 24), height=1.2)
    # seed 2: its first chunk's hand-off finds paths (seeds 2-5 do since the hand-off's paths are
    # compiled, with their own random numbers; seed 1 did before)
    s = BakeSettings(method="sms", spp=4, batches=1, seed=2, handoff=1e-9)
    st = bake(ball, s).stats["lights"]["Area"]
    assert st["seen_focus"] == 0 and st["seen_handoff_paths"] > 0
    assert sum(chunks) >= 4 and len(calls) == sum(chunks)
    calls.clear()
    monkeypatch.setattr(importlib.import_module("smbs_addon.paths.handoff"), "concentration",
                        lambda types, x0, *a: np.zeros(len(x0)))  # the hand-off's (handoff_select)
    st = bake(ball, s).stats["lights"]["Area"]
    assert st["seen_focus"] == 0 and st["seen_handoff_paths"] == 0
    assert len(calls) == 1


def test_handoff_kernel_paths_are_the_numpy_steps():
    """handoff.handoff_lanes (handoff_gather's paths, compiled) against the steps it stands for,
    each done apart in numpy from the same uniform numbers: the cosine bounce off the receiver
    (vec.frame / cosine_hemisphere / to_world, Russian roulette on the albedo), tracer.spawn and
    tracer.intersect, the specular scatter (optics.scatter_rows), and the segment after the first
    specular vertex (origin, direction, distance, throughput) and that vertex's record, to 1e-9;
    the same lanes alive. Glass sphere under an area light: receivers on the floor, K = 2. The
    uniform numbers are the kernel's own (keyed_uniform of the receiver, sample and dimension)."""
    from smbs_addon.core import embree
    from smbs_addon.kernels import handoff
    from smbs_addon.kernels import keyed, records
    from smbs_addon.shading import optics
    from smbs_addon.core.vec import cosine_hemisphere, dot, frame, to_world

    scene = scenes.glass_sphere_scene(resolution=(16, 12))
    plan = make_plan(scene)
    tracer = Tracer(scene)
    rng = np.random.default_rng(5)
    n, samples, K = 40, 64, 2
    x0 = np.column_stack([rng.uniform(-0.6, 0.6, n), rng.uniform(-0.6, 0.6, n), np.zeros(n)])
    h0 = tracer.intersect(x0 + [0.0, 0.0, 1e-3], np.tile([0.0, 0.0, -1.0], (n, 1)))
    assert h0.hit.all()
    x0, ng, ns = h0.p, h0.ng, h0.ns
    w0 = np.tile([0.0, 0.0, 1.0], (n, 1))
    beta0 = np.full((n, 3), 1.0 / samples)
    alb = scene.mat_color[scene.tri_material[h0.prim]]
    m = n * samples
    key, a0 = 12345, 7  # lane l: sample l % samples of receiver a0 + l // samples
    u = np.array([[keyed.keyed_uniform(key, a0 + lane // samples, lane % samples, j) for j in range(3 + K)]
                  for lane in range(m)])
    seg, seg_n = np.zeros((m, K, records.SEG_BETA + 3)), np.zeros(m, np.int64)
    hist, h_prim = np.zeros((m, K, records.HIST_F)), np.zeros((m, K), np.int64)
    rt = tracer.rays()
    receivers = records.HandoffReceivers(x0, ng, ns, ns, w0, beta0, alb, scene.tri_material[h0.prim].astype(np.int64))
    counts = handoff.handoff_lanes(rt, key, a0, samples, K, receivers, tracer.kernel_geometry(plan.casters),
                                   optics.materials(scene), False, tracer.eps,
                                   records.HandoffOut(seg, seg_n, hist, h_prim),
                                   records.BentTargets(np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.int64)))
    # numpy, step by step
    i = np.arange(m) // samples
    side = np.where(dot(w0[i], ng[i]) >= 0, 1.0, -1.0)[:, None]
    nn = ns[i] * side
    s, t = frame(nn)
    d = to_world(cosine_hemisphere(u[:, 0], u[:, 1]), s, t, nn)
    q = np.clip(alb[i].max(axis=1), 0.0, 1.0)
    live = (u[:, 2] < q) & (dot(d, ng[i] * side) > 0) & (dot(w0[i], nn) > 0)
    beta = beta0[i] * alb[i] / q[:, None]
    h = tracer.intersect(tracer.spawn(x0[i], ng[i], d), d)
    kind = np.where(h.hit, scene.mat_kind[scene.tri_material[np.maximum(h.prim, 0)]], -1)
    spec = np.flatnonzero(live & ((kind == 1) | (kind == 2)))
    u3 = np.zeros((spec.size, 3))
    u3[:, 0] = u[spec, 3]
    d1, b1, keep = optics.scatter_rows(u3, -d[spec], h.ns[spec], h.ng[spec],
                                       scene.tri_material[h.prim[spec]], kind[spec], optics.materials(scene),
                                       beta[spec], False, False)
    lanes_1 = spec[keep]
    p1 = h.p[lanes_1]
    o1 = tracer.spawn(p1, h.ng[lanes_1], d1)
    h1 = tracer.intersect(o1, d1)
    assert np.array_equal(np.flatnonzero(seg_n >= 1), lanes_1) and lanes_1.size > 200
    got = seg[lanes_1, 0]
    assert np.allclose(got[:, 0:3], o1, atol=1e-9) and np.allclose(got[:, 3:6], d1, atol=1e-9)
    assert np.allclose(got[:, 7:10], b1, rtol=1e-9)
    assert np.array_equal(np.isfinite(got[:, 6]), h1.hit)
    assert np.allclose(got[h1.hit, 6], h1.t[h1.hit], rtol=1e-9)
    assert np.array_equal(h_prim[lanes_1, 0], h.prim[lanes_1])
    assert np.allclose(hist[lanes_1, 0, 0:3], p1, atol=1e-12) and np.allclose(hist[lanes_1, 0, 3:5], h.b[lanes_1])
    refl = (dot(d[lanes_1], h.ns[lanes_1]) * dot(d1, h.ns[lanes_1]) < 0)
    assert np.array_equal(hist[lanes_1, 0, 5] > 0, refl) and refl.any() and (~refl).any()
    assert np.all(hist[lanes_1, 0, 6] == 1.0)  # the sphere is the caster
    # every live lane cast its first ray, every lane with a segment one more per segment
    assert counts[embree.KINDS:].sum() == live.sum() + seg_n.sum()


def test_paths_no_walk_takes_count_through_glass():
    """At receivers seen through glass the hand-off's cosine paths also take the paths no walk
    takes (Handoff.others: a chain type not walked, longer than the longest walked, or through a
    specular vertex that is no planned caster), as the photons do at receivers seen directly; on
    a bevelled cube's floor seen through it, chains of 5 and more vertices carry 8% of the light.
    Exact partition on the same random numbers, floor seen through a glass ball with T T the only
    walked type: (the others) + (every T T path) = (every path), and the others are not empty."""
    from smbs_addon.paths import gather as indirect
    from smbs_addon.trace.eye import BatchPart, eye_receivers

    ball = scenes.glass_sphere_scene(resolution=(32, 24), height=0.9)
    plan = make_plan(ball)
    cam = CameraModel(ball.camera)
    tracer = Tracer(ball)
    rng = np.random.default_rng(5)
    film = Film(cam.W, cam.H, ball.camera.filter_width, cam.region)
    rc = eye_receivers(ball, tracer, cam, film, plan, BatchPart(0, 4 * cam.W * cam.H, 4 * cam.W * cam.H), rng, {})
    rc = rc.take(np.flatnonzero(rc.eye_specular > 0))
    assert len(rc.p) > 100
    long = "T" + "R" * (indirect.OTHERS_DEPTH - 2) + "T"  # walked, never handed off: depth OTHERS_DEPTH throughout
    li = plan.lights[0].index
    images, stats = [], []
    for tau, others in (({"TT": math.inf}, True), ({"TT": 0.0, long: math.inf}, False), ({"TT": 0.0}, True)):
        f = Film(cam.W, cam.H, ball.camera.filter_width, cam.region)
        st = {}
        indirect.handoff_gather(ball, tracer, f, plan, rc, np.random.default_rng(9), st,
                                {li: reference.Handoff(tau, False, others=others)})
        f.end_batch()
        images.append(f.image)
        stats.append(st)
    other, tt, every = images
    assert stats[0]["other_paths"] > 0 and stats[0].get("handoff_paths", 0) == 0
    assert stats[1]["handoff_paths"] > 0 and stats[1].get("other_paths", 0) == 0
    assert (stats[2]["other_paths"], stats[2]["handoff_paths"]) == (stats[0]["other_paths"], stats[1]["handoff_paths"])
    assert other.sum() > 0.01 * every.sum()
    np.testing.assert_allclose(other + tt, every, rtol=1e-9, atol=1e-12 * every.max())
