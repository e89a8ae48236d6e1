"""Cycles' Ray Visibility on lights and casters (Scene.light_visibility, object_visibility; RAY_* bits).

A ray's kind is the event at the vertex it leaves, from the camera: a caustic path's last ray leaves its
last mirror or glass vertex, a glossy ray after a reflection and a transmission ray after a refraction,
and the light must be visible to it; the ray leaving the receiver is a diffuse ray, and a caster it
does not see casts no caustic. Measured on Cycles 5.0 (conformance scene ray_visibility): a mirror under
a light glossy rays do not see shows no caustic at all, a glass ball under a light transmission rays do
not see keeps only its reflection (0.10 of its caustic), a glass ball diffuse rays do not see none.
"""
import numpy as np
import pytest

from smbs_addon import BakeSettings, bake
from smbs_addon.kernels import photons
from smbs_addon.kernels import records
from smbs_addon.shading import optics
from smbs_addon.scene import arrays as S
from smbs_addon.scene.light_paths import Limits
from smbs_addon.scene.builder import SceneBuilder
from smbs_addon.trace.camera import CameraModel
from smbs_addon.shading.lights import emit, light_radiance
from smbs_addon.baking.plan import make_plan
from smbs_addon.trace.tracer import Tracer

NO_GLOSSY = S.RAY_ALL & ~S.RAY_GLOSSY
NO_TRANSMISSION = S.RAY_ALL & ~S.RAY_TRANSMISSION
METHODS = ("reference", "sms", "smbs", "mnee", "auto")


def _ball_and_mirror(light=S.RAY_ALL, ball=S.RAY_ALL, mirror=True, ball_on=True, res=(48, 36)):
    """A glass ball and a standing mirror on a floor under a bulb of radius 0.1; the camera sees the
    floor directly, through the ball and in the mirror."""
    b = SceneBuilder("visibility")
    floor = b.material("floor", "diffuse", color=(0.8, 0.8, 0.8))
    b.plane("Floor", (0, 0, 0), 6.0, floor, receiver=True)
    if ball_on:
        b.uv_sphere("Ball", (0.3, 0, 0.6), 0.35, b.material("glass", "dielectric", ior=1.5), segments=32, rings=16,
                    caster=True, visibility=ball)
    if mirror:
        b.plane("Mirror", (-1.0, 0, 0.6), (0.8, 1.2), b.material("mirror", "conductor", color=(0.9, 0.9, 0.9)),
                normal=(1, 0, 0.2), caster=True)
    b.light("Bulb", "POINT", location=(0.3, 0.0, 2.5), power=300.0, radius=0.1, visibility=light)
    b.set_camera(location=(0.6, -3.0, 2.5), target=(-0.3, 0, 0.3), resolution_x=res[0], resolution_y=res[1])
    return b.build()


def test_builder_keeps_visibility_only_where_some_ray_misses():
    sc = _ball_and_mirror()
    assert sc.object_visibility.size == 0 and sc.light_visibility.size == 0  # every ray: nothing stored
    assert sc.light_seen_by(0, S.RAY_GLOSSY) and sc.object_seen_by(0, S.RAY_DIFFUSE) and sc.chain_lit(0, "TRT")
    sc = _ball_and_mirror(light=NO_GLOSSY, ball=S.RAY_ALL & ~S.RAY_DIFFUSE)
    assert sc.light_visibility.tolist() == [NO_GLOSSY]
    assert sc.object_visibility.tolist() == [S.RAY_ALL, S.RAY_ALL & ~S.RAY_DIFFUSE, S.RAY_ALL]
    assert not sc.chain_lit(0, "R") and not sc.chain_lit(0, "TRR") and sc.chain_lit(0, "RT")
    sc.object_visibility = np.array([S.RAY_ALL, 32, 0])
    with pytest.raises(S.SceneError, match="object_visibility"):
        sc.validate()


def test_plan_leaves_out_what_no_caustic_ray_sees():
    """A caster diffuse rays do not see, a light neither glossy nor transmission rays see: skipped,
    saying why; a light diffuse rays do not see lights no diffuse surface on the way to a caster."""
    plan = make_plan(_ball_and_mirror(ball=S.RAY_ALL & ~S.RAY_DIFFUSE))
    assert plan.casters.tolist() == [False, False, True]
    assert ("caster", "Ball", "its Ray Visibility is off for diffuse rays: Cycles shows no caustic of it") \
        in plan.skipped
    # its light on the floor still meets the ball (light -> floor -> ball -> floor: the floor's diffuse ray
    # meets it), which is all it bakes; without that, nothing
    plan = make_plan(_ball_and_mirror(light=S.RAY_ALL & ~S.RAY_GLOSSY & ~S.RAY_TRANSMISSION))
    assert plan.lights == [] and plan.indirect_lights == [0] and not plan.nothing
    assert plan.skipped[-1][2].startswith("its Ray Visibility is off for glossy and transmission rays")
    plan = make_plan(_ball_and_mirror(light=S.RAY_CAMERA | S.RAY_SHADOW))
    assert plan.nothing.startswith("no light can cast caustics") and "glossy and transmission rays" in plan.nothing
    assert make_plan(_ball_and_mirror()).indirect_lights == [0]
    assert make_plan(_ball_and_mirror(light=S.RAY_ALL & ~S.RAY_DIFFUSE)).indirect_lights == []


def test_light_radiance_passes_the_rays_the_light_does_not_see():
    sc = _ball_and_mirror(light=NO_GLOSSY)
    o = np.array([[0.3, 0.0, 1.0]] * 4)
    d = np.array([[0.0, 0.0, 1.0]] * 4)
    refl = np.array([True, False, True, False])
    L0, t0 = light_radiance(sc, 0, o, d)
    assert np.all(L0 > 0) and np.all(np.isfinite(t0))
    L, t = light_radiance(sc, 0, o, d, refl=refl)
    assert np.array_equal(L[~refl], L0[~refl]) and np.array_equal(t[~refl], t0[~refl])
    assert np.all(L[refl] == 0) and np.all(np.isinf(t[refl]))


def _photons(scene, lvis, key=99):
    plan = make_plan(_ball_and_mirror())  # the same plan whatever the light's visibility
    tracer = Tracer(scene)
    lp = plan.lights[0]
    ph = emit(scene, lp.index, lp.targets, 20000, np.random.default_rng(5))
    n, K = len(ph.o), 2
    rec, rec_i = np.empty((n * 8, records.REC_F)), np.empty((n * 8, 3), np.int64)
    hist, h_prim = np.zeros((n, K, records.HIST_BENT)), np.zeros((n, K), np.int64)
    tally = np.zeros(records.PH_TALLY, np.int64)
    batch = records.PhotonBatch(ph.o, ph.d, ph.w, np.zeros(3), 0.0, lvis, np.zeros(0, bool), np.zeros(0, bool))
    _, m, _ = photons.photon_lanes(tracer.rays(), batch, key, 0, tracer.kernel_geometry(plan.casters), plan.receivers,
                                   optics.materials(scene), records.PhotonRules(False, Limits.of(scene).array(), 32, 33,
                                                                                False),
                                   tracer.eps, records.PhotonOut(rec, rec_i, hist, h_prim, tally))
    return rec[:m], rec_i[:m], hist


def test_photons_split_by_their_first_event_exactly():
    """Photons (the same keyed random numbers) of a light glossy rays do not see and of one
    transmission rays do not see: together, exactly the records of a light every ray sees, split by
    whether the photon's first event (the camera path's last) reflected."""
    sc = _ball_and_mirror()
    full, ids, hist = _photons(sc, S.RAY_ALL)
    first_r = hist[ids[:, 0], 0, 5] > 0
    assert 1000 < first_r.sum() < len(full) - 1000  # both kinds, many of each
    no_g, ids_g, _ = _photons(sc, NO_GLOSSY)
    no_t, ids_t, _ = _photons(sc, NO_TRANSMISSION)
    assert np.array_equal(no_g, full[~first_r]) and np.array_equal(ids_g, ids[~first_r])
    assert np.array_equal(no_t, full[first_r]) and np.array_equal(ids_t, ids[first_r])
    assert len(_photons(sc, S.RAY_ALL & ~S.RAY_GLOSSY & ~S.RAY_TRANSMISSION)[0]) == 0


@pytest.mark.parametrize("method", METHODS)
def test_a_mirror_under_a_light_glossy_rays_do_not_see_casts_nothing(method):
    """Every estimator, the floor seen directly and in the mirror: all zero, where the same light seen
    by every ray makes a caustic in both (the test can fail)."""
    cfg = BakeSettings(method=method, spp=2, seed=3, batches=2)
    sc = _ball_and_mirror(ball_on=False)
    lit = bake(sc, cfg).image.max(axis=2)
    in_mirror = _sees_mirror(sc)
    assert lit[~in_mirror].max() > 0 and lit[in_mirror].max() > 0
    r = bake(_ball_and_mirror(light=NO_GLOSSY, ball_on=False), cfg)
    assert r.image.max() == 0.0


def _sees_mirror(sc):
    """(H, W) bool: the pixels whose centre's camera ray meets the mirror first."""
    cam = CameraModel(sc.camera)
    H, W = sc.camera.height, sc.camera.width
    yy, xx = (a.ravel() + 0.5 for a in np.mgrid[0:H, 0:W].astype(float))
    o, d, tnear = cam.rays(xx, yy)
    h = Tracer(sc).intersect(o + tnear[:, None] * d, d)
    return (h.hit & (sc.tri_object[np.maximum(h.prim, 0)] == sc.object_names.index("Mirror"))).reshape(H, W)


def _total(r):
    lum = r.batch_luminance.sum(axis=(1, 2))
    return lum.mean(), lum.std(ddof=1) / np.sqrt(len(lum))


@pytest.mark.parametrize("method, spp", [("reference", 48), ("sms", 8)])
def test_reflections_and_refractions_add_up_to_the_light_every_ray_sees(method, spp):
    """The ball and the mirror under a light glossy rays do not see (the refractions' caustic) and under
    one transmission rays do not see (the reflections'): their images add up to the image of the light
    every ray sees, within 4 standard errors of the three bakes' independent batches."""
    sums = {}
    for vis in (S.RAY_ALL, NO_GLOSSY, NO_TRANSMISSION):
        sums[vis] = _total(bake(_ball_and_mirror(light=vis), BakeSettings(method=method, spp=spp, seed=vis,
                                                                          batches=8)))
    (m_all, s_all), (m_t, s_t), (m_r, s_r) = sums[S.RAY_ALL], sums[NO_GLOSSY], sums[NO_TRANSMISSION]
    assert m_t > 0.2 * m_all and m_r > 0.2 * m_all  # both parts matter in this scene
    assert abs(m_t + m_r - m_all) < 4 * np.sqrt(s_all ** 2 + s_t ** 2 + s_r ** 2), (m_t, m_r, m_all)


def test_a_ball_diffuse_rays_do_not_see_casts_no_caustic():
    """The ball alone, diffuse rays blind to it: nothing to bake (the plan says why)."""
    r = bake(_ball_and_mirror(ball=S.RAY_ALL & ~S.RAY_DIFFUSE, mirror=False), BakeSettings(method="sms", spp=1))
    assert r.image.max() == 0.0
    assert r.stats["plan"]["words"] == ["Nothing to bake: scene 'visibility' has no caustic caster: diffuse rays do "
                                        "not see 'Ball' (Ray Visibility), so Cycles shows no caustic of it. The "
                                        "caustic layer is all zero."]


@pytest.mark.parametrize("method", ["reference", "sms"])
def test_a_world_seen_by_glossy_rays_alone_lights_its_mirror_the_same(method):
    """A world mirrored onto the floor (scenes.world_mirror_scene): leaving out transmission rays, which
    no path of a mirror casts, gives the same image bit for bit; leaving out glossy rays, no caustic."""
    from testkit import scenes

    cfg = BakeSettings(method=method, spp=2, seed=4)
    sc = scenes.world_mirror_scene(resolution=(24, 18))
    assert sc.light_type.tolist() == [S.WORLD]
    every = bake(sc, cfg).image
    assert every.max() > 0
    sc.light_visibility = np.array([NO_TRANSMISSION])
    assert np.array_equal(bake(sc, cfg).image, every)
    sc.light_visibility = np.array([NO_GLOSSY])
    assert bake(sc, cfg).image.max() == 0.0


NO_CAMERA = S.RAY_ALL & ~S.RAY_CAMERA


def _hidden_scene(card=True, card_vis=NO_CAMERA, floor_vis=S.RAY_ALL):
    """The ball and the bulb of _ball_and_mirror (no mirror), and a diffuse card between the camera and
    the floor, out of the light's way, that camera rays do not meet (or none)."""
    b = SceneBuilder("hidden")
    floor = b.material("floor", "diffuse", color=(0.8, 0.8, 0.8))
    b.plane("Floor", (0, 0, 0), 6.0, floor, receiver=True, visibility=floor_vis)
    b.uv_sphere("Ball", (0.3, 0, 0.6), 0.35, b.material("glass", "dielectric", ior=1.5), segments=32, rings=16,
                caster=True)
    if card:
        b.plane("Card", (0.25, -1.6, 1.3), (1.2, 0.8), floor, normal=(0, -1, 0.6), visibility=card_vis)
    b.light("Bulb", "POINT", location=(0.3, 0.0, 2.5), power=300.0, radius=0.1)
    b.set_camera(location=(0.3, -3.0, 1.9), target=(0.3, 0, 0.0), resolution_x=40, resolution_y=30)
    return b.build()


def _pixel_rays(sc):
    cam = CameraModel(sc.camera)
    H, W = sc.camera.height, sc.camera.width
    yy, xx = (a.ravel() + 0.5 for a in np.mgrid[0:H, 0:W].astype(float))
    o, d, tnear = cam.rays(xx, yy)
    return o + tnear[:, None] * d, d


def test_camera_rays_pass_what_they_do_not_meet():
    """A card that camera rays do not meet hides half the floor's caustic: the camera's rays pass it
    (Tracer.camera_intersect, the kernels' eye rays) and meet what they meet without the card."""
    sc, bare = _hidden_scene(), _hidden_scene(card=False)
    assert sc.camera_hidden().tolist() == [False, False, True] and bare.camera_hidden().size == 0
    o, d = _pixel_rays(sc)
    on_card = Tracer(sc).intersect(o, d)
    card = sc.object_names.index("Card")
    behind = on_card.hit & (sc.tri_object[np.maximum(on_card.prim, 0)] == card)
    assert 0.2 < behind.mean() < 0.8
    h, want = Tracer(sc).camera_intersect(o, d), Tracer(bare).intersect(o, d)
    assert np.array_equal(h.hit, want.hit)
    assert np.abs(h.p - want.p).max() < 1e-9 and np.array_equal(sc.tri_object[h.prim], bare.tri_object[want.prim])
    # and back, from the floor's points towards the camera: the card stops them, but not camera rays
    t = Tracer(sc)
    floor = np.flatnonzero(want.hit & (bare.tri_object[np.maximum(want.prim, 0)] == 0))
    back = -d[floor]
    start = t.spawn(want.p[floor], want.ng[floor], back)
    dist = np.linalg.norm(o[floor] - want.p[floor], axis=1)
    assert t.occluded(start, back, dist)[behind[floor]].all() and behind[floor].sum() > 100
    assert not t.camera_occluded(start, back, dist).any()


@pytest.mark.parametrize("method", ["reference", "sms"])
def test_a_card_camera_rays_do_not_meet_hides_nothing(method):
    """The same bake with the card (out of the light's way) and without it: the caustic behind the card
    is there, as much (the light tracer's photons reach the camera past the card, the walks' receivers
    are found past it); seen by camera rays, the card hides it."""
    cfg = BakeSettings(method=method, spp=8, seed=2, batches=4)
    img = {k: bake(sc, cfg).image.mean(axis=2) for k, sc in
           (("hidden", _hidden_scene()), ("bare", _hidden_scene(card=False)),
            ("seen", _hidden_scene(card_vis=S.RAY_ALL)))}
    o, d = _pixel_rays(_hidden_scene())
    h = Tracer(_hidden_scene(card_vis=S.RAY_ALL)).intersect(o, d)
    behind = (h.hit & (_hidden_scene().tri_object[np.maximum(h.prim, 0)] == 2)).reshape(img["bare"].shape)
    pad = np.pad(behind, 2)  # 2 pixels inside the card's edge and the frame's, past the pixel filter's reach
    H, W = behind.shape
    inner = np.all([pad[2 + dy:2 + dy + H, 2 + dx:2 + dx + W] for dy in range(-2, 3) for dx in range(-2, 3)], axis=0)
    assert img["bare"][inner].sum() > 0.2 * img["bare"].sum()  # the card covers much of the caustic
    assert img["seen"][inner].max() == 0.0
    assert abs(img["hidden"].sum() / img["bare"].sum() - 1.0) < 0.02, img["hidden"].sum() / img["bare"].sum()
    assert abs(img["hidden"][behind].sum() / img["bare"][behind].sum() - 1.0) < 0.03


@pytest.mark.parametrize("method", METHODS)
def test_a_floor_camera_rays_do_not_meet_shows_its_caustic_through_glass_alone(method):
    """The floor hidden from camera rays: no caustic where the camera would see it directly (2 pixels
    around the ball's outline aside: the pixel filter); through the ball, transmission rays still see it
    (the walks find its caustic there at 2 spp)."""
    sc = _hidden_scene(card=False, floor_vis=NO_CAMERA)
    img = bake(sc, BakeSettings(method=method, spp=2, seed=1)).image.max(axis=2)
    o, d = _pixel_rays(sc)
    h = Tracer(sc).intersect(o, d)
    ball = (h.hit & (sc.tri_object[np.maximum(h.prim, 0)] == 1)).reshape(img.shape)
    near = np.pad(ball, 2)
    H, W = ball.shape
    near = np.any([near[2 + dy:2 + dy + H, 2 + dx:2 + dx + W] for dy in range(-2, 3) for dx in range(-2, 3)], axis=0)
    assert img[~near].max() == 0.0
    if method in ("sms", "smbs"):
        assert img[ball].max() > 0
    assert bake(_hidden_scene(card=False), BakeSettings(method=method, spp=2, seed=1)).image.max(axis=2)[~near].max() > 0


def _flagged_mirror(flag_vis=None):
    """A standing mirror and a bulb, a dark card between them out of the floor's view of the mirror (or
    none): the mirror's light passes the card where glossy rays do not meet it."""
    b = SceneBuilder("flag")
    floor = b.material("floor", "diffuse", color=(0.8, 0.8, 0.8))
    b.plane("Floor", (0, 0, 0), 6.0, floor, receiver=True)
    b.plane("Mirror", (-1.0, 0, 0.6), (0.8, 1.2), b.material("mirror", "conductor", color=(0.9, 0.9, 0.9)),
            normal=(1, 0, 0.2), caster=True)
    if flag_vis is not None:
        b.plane("Card", (-0.5, 0.0, 1.6), (0.5, 0.8), b.material("card", "diffuse", color=(0.2, 0.2, 0.2)),
                normal=(1, 0, 1), visibility=flag_vis)
    b.light("Bulb", "POINT", location=(0.3, 0.0, 2.5), power=300.0, radius=0.1)
    b.set_camera(location=(0.6, -3.0, 2.5), target=(-0.3, 0, 0.3), resolution_x=40, resolution_y=30)
    return b.build()


@pytest.mark.parametrize("method", ["reference", "sms"])
def test_a_card_glossy_rays_do_not_meet_lets_a_mirror_s_light_past(method):
    """The card, met by every ray, takes much of the mirror's light; glossy rays (the mirror's ray towards
    the bulb) not meeting it, the mirror's caustic is the one without the card, within 4 standard errors
    (the photons pass or meet it at random, weighted 2, and keep what the next vertex's ray allows)."""
    cfg = BakeSettings(method=method, spp=16 if method == "reference" else 4, seed=5, batches=8)
    tot = {k: _total(bake(_flagged_mirror(v), cfg)) for k, v in
           (("bare", None), ("seen", S.RAY_ALL), ("glossy_off", S.RAY_ALL & ~S.RAY_GLOSSY))}
    (m0, s0), (m1, _), (m2, s2) = tot["bare"], tot["seen"], tot["glossy_off"]
    assert m1 < 0.8 * m0, (m1, m0)  # the card matters
    assert abs(m2 - m0) < 4 * np.hypot(s0, s2), (m2, m0, s0, s2)
