"""Cycles' Light Linking (a light's receiver collection: the objects it lights; Scene.light_links).

Cycles asks it of the object a path leaves last before the light (the path state's mis_ray_object):
of a caustic, the mirror or glass the light comes through last, never the receiver the camera sees;
of light that meets more than one diffuse surface, the diffuse surface the light lit first. Measured on
Cycles 5.0 (conformance scene linked_lamps: a lamp lighting a glass ball alone, a lamp lighting every
object but the ball): ours 1.01 of Cycles with the links followed, 1.81 with them ignored.

Shadow Linking (a light's blocker collection: the objects that shadow it; Scene.light_blockers): Cycles'
rays that reach the light pass the other objects, and a path that meets one goes on from it too.
"""
import numpy as np
import pytest

from smbs_addon import BakeSettings, bake
from smbs_addon.scene import arrays as S
from smbs_addon.scene.builder import SceneBuilder
from smbs_addon.core.errors import SceneError
from smbs_addon.baking.plan import make_plan

METHODS = ("reference", "sms", "smbs", "mnee", "auto")


def _ball_and_mirror(ball_lamp=None, mirror_lamp=None, res=(48, 36)):
    """A glass ball and a standing mirror on a floor; a bulb over the ball and one low beside it, each
    lighting the objects its list names (None: every object)."""
    b = SceneBuilder("linked")
    floor = b.material("floor", "diffuse", color=(0.8,) * 3)
    glass = b.material("glass", "dielectric", ior=1.5)
    mirror = b.material("mirror", "conductor", color=(0.9,) * 3)
    b.plane("Floor", (0, 0, 0), 8, floor, receiver=True)
    b.uv_sphere("Ball", (0, 0, 0.9), 0.5, glass, segments=48, rings=24, caster=True)
    b.plane("Mirror", (1.2, 0, 0.55), (1.0, 1.6), mirror, normal=(-1, 0, 0), caster=True)
    b.light("BallLamp", "POINT", location=(0.4, -0.2, 3.0), power=600, radius=0.25, soft_falloff=True,
            lit=ball_lamp)
    b.light("MirrorLamp", "POINT", location=(0.5, 0.0, 1.4), power=400, radius=0.2, lit=mirror_lamp)
    b.set_camera((-2.6, -1.3, 2.2), (0.6, 0.1, 0.3), lens=30, resolution_x=res[0], resolution_y=res[1])
    return b.build()


def test_the_builder_names_what_a_light_lights():
    sc = _ball_and_mirror(ball_lamp=["Ball"])
    assert sc.light_links.shape == (2, 3)
    assert sc.lit_by(0).tolist() == [False, True, False] and sc.lit_by(1).all()
    assert sc.light_linked(0) and not sc.light_linked(1)
    assert _ball_and_mirror().light_links.size == 0
    with pytest.raises(SceneError, match="light 'BallLamp': its Light Linking names object 'Bowl'"):
        _ball_and_mirror(ball_lamp=["Bowl"])
    sc.light_links = np.ones((2, 2), bool)
    with pytest.raises(SceneError, match=r"'light_links' must be \(2, 3\)"):
        sc.validate()


def test_a_light_that_lights_none_of_its_casters_bakes_no_caustic():
    """Lighting the floor alone, a lamp casts no caustic: the plan skips it and says why (its light that
    the floor sends on to the ball stays: the floor is the last surface before that light)."""
    sc = _ball_and_mirror(ball_lamp=["Floor"], mirror_lamp=["Floor"])
    plan = make_plan(sc)
    assert plan.lights == []
    reasons = {name: why for kind, name, why in plan.skipped}
    assert reasons["BallLamp"].startswith("its Light Linking lights none of the casters it reaches ('Ball'")
    assert sorted(plan.indirect_lights) == [0, 1]
    r = bake(sc, BakeSettings(method="smbs", spp=2, seed=1, indirect=False))
    assert not r.image.any() and r.stats["nothing_to_bake"]
    r = bake(sc, BakeSettings(method="smbs", spp=2, seed=1))
    assert r.image.any() and r.stats["plan"]["words"][:2] == [
        "BallLamp -> diffuse -> Ball, Mirror -> Floor (after a diffuse bounce)",
        "MirrorLamp -> diffuse -> Ball, Mirror -> Floor (after a diffuse bounce)"]


@pytest.mark.parametrize("method", METHODS)
def test_lamps_that_light_the_floor_alone_bake_its_light_through_the_casters(method):
    """No lamp lights a caster, so the plan has no light of its own; what the floor sends on through the
    ball and off the mirror is all the layer holds (each method bakes it: the light tracer's photons,
    the walks at the diffuse vertices after the floor's bounce)."""
    sc = _ball_and_mirror(ball_lamp=["Floor"], mirror_lamp=["Floor"], res=(32, 24))
    r = bake(sc, BakeSettings(method=method, spp=4, seed=1))
    assert np.isfinite(r.image).all() and r.image.any() and r.stats["lights"] == {}


def test_a_light_plans_only_the_casters_it_lights():
    plan = make_plan(_ball_and_mirror(mirror_lamp=["Mirror", "Floor"]))
    by_name = {lp.name: lp.caster_names for lp in plan.lights}
    assert by_name == {"BallLamp": ["Ball", "Mirror"], "MirrorLamp": ["Mirror"]}


@pytest.mark.parametrize("method", METHODS)
def test_the_receiver_the_camera_sees_is_not_asked(method):
    """Light that meets one diffuse surface (indirect off): a lamp lighting the casters alone (not the
    floor that shows their caustics) bakes the same image, bit for bit, as an unlinked lamp."""
    s = BakeSettings(method=method, spp=4, seed=3, indirect=False)
    both = ["Ball", "Mirror"]
    a = bake(_ball_and_mirror(res=(32, 24)), s).image
    b = bake(_ball_and_mirror(ball_lamp=both, mirror_lamp=both, res=(32, 24)), s).image
    assert a.any() and np.array_equal(a, b)


def _total(r):
    """The image's sum and its standard error over the bake's independent batches."""
    per = r.batch_luminance.reshape(len(r.batch_luminance), -1).sum(axis=1)
    return per.mean(), per.std(ddof=1) / np.sqrt(len(per)) if len(per) > 1 else 0.0  # one: nothing baked


@pytest.mark.parametrize("method", ["reference", "smbs"])
def test_links_that_part_the_objects_part_the_caustic(method):
    """Every path's last object before the light is lit under exactly one of two links that part the
    objects (the ball; the floor and the mirror), so their two layers add up to the unlinked one, indirect
    light included. Seed 2, 48 x 36: the light tracer at 64 spp 1157 + 348 = 1505 against 1510 (-0.2
    sigma), SMBS at 32 spp 1155 + 359 = 1514 against 1524 (-0.5 sigma); a layer that ignored the links
    would be near 2 x 1510. Within 4.5 standard errors of the three batch means (8 batches each)."""
    spp = 64 if method == "reference" else 32
    s = BakeSettings(method=method, spp=spp, seed=2)
    whole = _total(bake(_ball_and_mirror(), s))
    ball = _total(bake(_ball_and_mirror(["Ball"], ["Ball"]), s))
    rest = _total(bake(_ball_and_mirror(["Floor", "Mirror"], ["Floor", "Mirror"]), s))
    se = np.sqrt(whole[1] ** 2 + ball[1] ** 2 + rest[1] ** 2)
    assert 0.2 * whole[0] < ball[0] and 0.1 * whole[0] < rest[0]
    assert abs(ball[0] + rest[0] - whole[0]) < 4.5 * se, (ball, rest, whole)
    assert se < 0.03 * whole[0]


# ----------------------------------------------------------------------------- Shadow Linking
def _shaded_ball(plate=True, unshadowing=False, res=(32, 24)):
    """A glass ball on a floor under a bulb, a grey plate between them (above the camera, out of its
    view) that shades the ball and most of the floor; unshadowing: the bulb's blocker collection leaves
    the plate out (Shadow Linking)."""
    b = SceneBuilder("shadow linked")
    floor = b.material("floor", "diffuse", color=(0.8,) * 3)
    b.plane("Floor", (0, 0, 0), 8, floor, receiver=True)
    b.uv_sphere("Ball", (0, 0, 0.9), 0.5, b.material("glass", "dielectric", ior=1.5), segments=48, rings=24,
                caster=True)
    if plate:
        b.plane("Plate", (0.1, -0.05, 4.0), 1.6, b.material("grey", "diffuse", color=(0.5,) * 3))
    b.light("Bulb", "POINT", location=(0.4, -0.2, 5.0), power=1500, radius=0.25,
            blockers=["Floor", "Ball"] if unshadowing else None)
    b.set_camera((0, -3.6, 2.8), (0, 0, 0.2), lens=40, resolution_x=res[0], resolution_y=res[1])
    return b.build()


def test_the_builder_names_what_shadows_a_light():
    sc = _shaded_ball(unshadowing=True)
    assert sc.light_blockers.shape == (1, 3) and sc.unshadowing(0).tolist() == [False, False, True]
    assert _shaded_ball().unshadowing(0) is None and _shaded_ball().light_blockers.size == 0
    with pytest.raises(SceneError, match="light 'Lamp': its Shadow Linking names object 'Bowl'"):
        b = SceneBuilder()
        b.light("Lamp", "POINT", location=(0, 0, 1), blockers=["Bowl"])
        b.build()


@pytest.mark.parametrize("method", ["reference", "smbs"])
def test_an_object_that_does_not_shadow_the_light_is_passed_by_its_light(method):
    """Cycles' rays to a light pass an object its blocker collection leaves out: the ball's caustic under
    a plate that does not shadow the bulb is the caustic without the plate (the plate lies out of the
    camera's view and off every path but the light's), within 4.5 standard errors of the two batch
    means; the plate shadowing it takes nearly all of it. Seed 4, 32 x 24, 64 spp."""
    s = BakeSettings(method=method, spp=64, seed=4)
    free = _total(bake(_shaded_ball(plate=False), s))
    passed = _total(bake(_shaded_ball(unshadowing=True), s))
    shaded = _total(bake(_shaded_ball(), s))
    assert abs(passed[0] - free[0]) < 4.5 * np.hypot(passed[1], free[1]), (passed, free)
    assert free[1] < 0.05 * free[0] and shaded[0] < 0.05 * free[0], (free, shaded)


@pytest.mark.parametrize("shadows", [False, True])
def test_a_mesh_light_behind_an_object_that_does_not_shadow_it_is_seen_at_its_own_distance(shadows):
    """indirect.seen_light, the gathers' light test: segments rising from (x, 0, 0) meet a plate at
    z = 1, then a 1 m square panel (radiance 5) at z = 3. When the plate does not shadow the panel, every
    segment sees it, at distance 3 exactly (its distance from the point where the path leaves: the
    hand-off places the light's vertex there), with radiance 5; when it does, none does. The panel's
    Light Linking, asked of the object the segments leave, keeps it from a second such object."""
    from smbs_addon.paths import gather as indirect
    from smbs_addon.trace.tracer import Tracer

    b = SceneBuilder("seen")
    glow = b.material("Glow", "emitter", color=(1.0, 1.0, 1.0), strength=5.0)
    grey = b.material("Grey", "diffuse")
    b.plane("Plate", (0, 0, 1.0), 4.0, grey)
    b.plane("Floor", (0, 0, -1.0), 4.0, grey)
    b.plane("Other", (0, 0, -2.0), 4.0, grey)
    b.plane("Panel", (0, 0, 3.0), 1.0, glow, normal=(0, 0, -1), lit=["Floor", "Plate", "Panel"],
            blockers=["Plate"] if shadows else ["Floor"])
    sc = b.build()
    tracer = Tracer(sc)
    n = 7
    o = np.stack([np.linspace(-0.4, 0.4, n), np.zeros(n), np.zeros(n)], axis=1)
    d = np.tile([0.0, 0.0, 1.0], (n, 1))
    surf_t = tracer.intersect(o, d).t
    assert np.allclose(surf_t, 1.0)
    floor, other = sc.object_names.index("Floor"), sc.object_names.index("Other")
    li = 0
    seen, L, tl = indirect.seen_light(sc, tracer, li, o, d, np.zeros(n, bool), surf_t, np.full(n, floor))
    if shadows:
        assert not seen.any()
    else:
        assert seen.all() and np.allclose(tl, 3.0) and np.allclose(L, 5.0)
        seen, _, _ = indirect.seen_light(sc, tracer, li, o, d, np.zeros(n, bool), surf_t, np.full(n, other))
        assert not seen.any()


def test_a_mesh_light_past_an_object_that_does_not_shadow_it_does_not_shadow_itself():
    """Tracer.occluded_past, the walks' shadow rays under Shadow Linking: rays from under a plate that does
    not shadow a glowing ball (a mesh light), towards points of the ball it samples, are blocked where the
    ball hides the point from the ray's origin and nowhere else: as many as without the plate (exactly, for
    these 4000 rays). The rest of a ray past the plate is aimed at the segment's end again; run on by what
    was left of its length, 1046 of the 1749 rays to the front of the ball met its own triangles (the spawn past
    the plate moves the ray off its line; shadow_linked_glow's walks were 0.89 of Cycles)."""
    from smbs_addon.shading.lights import shadow_tmax
    from smbs_addon.shading.light_samples import sample_light
    from smbs_addon.trace.tracer import Tracer

    def scene(plate):
        b = SceneBuilder("glow")
        grey = b.material("Grey", "diffuse")
        if plate:
            b.plane("Plate", (0.1, 0.0, 2.0), 3.0, grey)
        b.plane("Floor", (0, 0, 0), 6.0, grey)
        b.uv_sphere("Glow", (0.3, -0.2, 3.0), 0.25, b.material("Lamp", "emitter", color=(1, 1, 1), strength=50.0),
                    segments=32, rings=16, blockers=["Floor", "Glow"])
        return b.build()

    counts = []
    for plate in (True, False):
        sc = scene(plate)
        tracer = Tracer(sc)
        rng = np.random.default_rng(5)
        n = 4000
        o = np.stack([rng.uniform(-0.5, 0.5, n), rng.uniform(-0.5, 0.5, n), np.full(n, 1.0)], axis=1)
        le = sample_light(sc, 0, n, rng)
        to = le.y - o
        dist = np.linalg.norm(to, axis=1)
        d = to / dist[:, None]
        tmax = shadow_tmax(sc, 0, le.y, le.ys, le.yt, o, d, dist, tracer.eps)
        blocked = tracer.occluded_past(o, d, tmax, S.RAY_SHADOW, sc.unshadowing(0))
        counts.append(int(blocked.sum()))
    assert 0.3 * n < counts[1] < 0.7 * n and counts[0] == counts[1], counts
