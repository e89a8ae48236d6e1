"""--method auto (issue 12): per light, a pilot measures light tracing, SMS and SMBS on the
receivers seen directly and on those seen through mirrors or glass, and each effect gets
the cheapest. The pieces partition path space, so auto is unbiased: checked against the
light tracer's image of the same scene within a stated statistical tolerance."""
from __future__ import annotations

import math

import numpy as np
import pytest

from testkit import scenes
from smbs_addon import BakeSettings, bake
from smbs_addon.baking.result import region_mean_error
from smbs_addon.baking.convergence import caustic_region


def _agree(a, b, region, sigmas=4.0, rel=0.03):
    """Region means of two bakes agree within sigmas standard errors (their batches) plus rel."""
    ma, sa = region_mean_error(a.batch_luminance, region)
    mb, sb = region_mean_error(b.batch_luminance, region)
    tol = sigmas * math.hypot(sa, sb) + rel * mb
    assert abs(ma - mb) <= tol, (ma, mb, tol)
    return ma, mb


@pytest.mark.slow
def test_auto_on_the_ring_matches_the_light_tracer():
    """The ring is seen from above: the floor directly, and in the ring's inner wall. auto
    gives the direct receivers to light tracing or the walks and the mirrored view to a walk."""
    scene = scenes.ring_scene(resolution=(48, 36))
    auto = bake(scene, BakeSettings(method="auto", spp=16, batches=8, seed=2))
    ref = bake(scene, BakeSettings(method="reference", spp=256, batches=8, seed=5))
    st = auto.stats["auto"]
    assert set(st["lights"]) == {"Area"}
    choice = st["lights"]["Area"]
    assert choice["walks"] in ("sms", "smbs") and choice["direct"] in ("photons", "sms", "smbs")
    assert set(choice["pilot"]) == {"reference", "sms", "smbs"}
    assert all(v["time_s"] > 0 for v in choice["pilot"].values())
    assert any(w.startswith("auto, Area: ") for w in auto.stats["plan"]["words"])
    # the ring's own mirror image of the floor is there: auto must walk (the light tracer's
    # eye pass serves it in the reference)
    assert st["bake"] == "manifold"
    region = caustic_region(ref.image.mean(axis=2))
    _agree(auto, ref, region)


def test_auto_is_the_default_and_names_its_choice():
    scene = scenes.glass_sphere_scene(resolution=(32, 24))
    res = bake(scene, BakeSettings(spp=2, batches=2, seed=1))
    assert res.stats["method"] == "auto" and res.stats["settings"]["method"] == "auto"
    choice = res.stats["auto"]["lights"]["Area"]
    words = [w for w in res.stats["plan"]["words"] if w.startswith("auto, Area: ")]
    assert words == [f"auto, Area: {choice['why']}"]
    assert np.all(np.isfinite(res.image)) and res.image.max() > 0


def test_pilot_scene_has_one_light_and_a_small_frame():
    from smbs_addon.baking import auto

    scene = scenes.water_scene(light="point", resolution=64)
    scene = __import__("dataclasses").replace(scene, light_color=np.vstack([scene.light_color, [[5.0, 5, 5]]]))
    sub = auto._pilot_scene(scene, 1)
    assert sub.light_color[0].max() == 0 and sub.light_color[1].tolist() == [5.0, 5.0, 5.0]
    assert scene.light_color[0].max() > 0  # the user's scene is not changed
    px = sub.camera.width * sub.camera.height
    assert 0.5 * auto.PILOT_PIXELS <= px <= auto.PILOT_PIXELS


def test_decide_takes_the_cheapest_per_effect():
    from smbs_addon.baking.auto import decide

    def m(ref, sms, smbs):  # (direct, through, all) costs per method
        return {k: dict(zip(("direct", "through", "all"), v)) for k, v in
                (("reference", ref), ("sms", sms), ("smbs", smbs))}

    # light tracing is cheap where seen directly, but its eye pass is dear through the glass
    walk, photons, alone, why = decide(m((1.0, 50.0, 51.0), (8.0, 2.0, 10.0), (6.0, 1.0, 7.0)), True, True)
    assert (walk, photons, alone) == ("smbs", True, False)
    assert why == "light tracing for receivers seen directly (6.0x cheaper than SMBS); SMBS through mirrors and glass"
    # nothing seen through mirrors or glass: light tracing throughout
    walk, photons, alone, why = decide(m((1.0, 0.0, 1.0), (8.0, 0.0, 8.0), (6.0, 0.0, 6.0)), True, False)
    assert (photons, alone) == (True, True) and why == "light tracing throughout (6.0x cheaper than SMBS)"
    # ... but never its eye pass where the caustic is seen through them, however cheap the
    # pilot found it (rare bright paths, which a short pilot underestimates)
    assert decide(m((1.0, 0.1, 1.1), (8.0, 2.0, 10.0), (6.0, 1.0, 7.0)), True, True)[1:3] == (True, False)
    walk, photons, alone, why = decide(m((4.0, 0.0, 4.0), (2.0, 0.0, 3.0), (2.5, 0.0, 6.0)), True, False)
    assert (walk, photons, alone) == ("sms", False, False)
    assert why == "SMS (2.0x cheaper than SMBS, 2.0x cheaper than light tracing where seen directly)"
    # nothing seen directly: the light tracer has nothing it may take
    assert decide(m((0.0, 9.0, 9.0), (0.0, 2.0, 3.0), (0.0, 2.5, 6.0)), False, True)[:3] == ("sms", False, False)
    assert decide(m((0.0, 1.0, 1.0), (0.0, 2.0, 3.0), (0.0, 2.5, 6.0)), False, True)[:3] == ("sms", False, False)
    assert decide(m((1, 1, 1), (1, 1, 1), (1, 1, 1)), True, True, has_caustic=False)[:3] == ("smbs", False, False)


def test_photon_factor_is_neyman_allocation():
    """Light tracing for the direct receivers, walks through glass: the light tracer gets
    sqrt(V_d c_w / (V_w c_d)) samples per walk sample, within PHOTON_FACTOR, two digits."""
    from smbs_addon.baking.auto import PHOTON_FACTOR, photon_factor

    def m(v_d, c_d, v_w, c_w, seen=0.25):
        return {"reference": {"var_direct": v_d, "rays": c_d},
                "sms": {"var_through": v_w, "rays": c_w / seen, "walks_seen_share": seen}}

    assert photon_factor(m(4.0, 100.0, 1.0, 400.0), "sms") == 4.0
    assert photon_factor(m(1.0, 400.0, 4.0, 100.0), "sms") == 0.25
    assert photon_factor(m(2.0, 100.0, 1.0, 100.0), "sms") == 1.4  # sqrt 2, two digits
    assert photon_factor(m(1e6, 1.0, 1.0, 1.0), "sms") == PHOTON_FACTOR[1]
    assert photon_factor(m(1.0, 1e6, 1.0, 1.0), "sms") == PHOTON_FACTOR[0]
    assert photon_factor(m(0.0, 100.0, 1.0, 100.0), "sms") == 1.0  # nothing measured: as before
    assert photon_factor(m(1.0, 100.0, 0.0, 100.0), "sms") == PHOTON_FACTOR[1]


def test_auto_shares_samples_between_photons_and_walks():
    """The glass ball seen from the side, the floor directly and through the ball: auto gives
    the direct receivers photon_factor x the photons of one sample per pixel a batch, exactly,
    and its image agrees with the light tracer's."""
    scene = scenes.glass_sphere_scene(resolution=(40, 30), height=0.9)
    res = bake(scene, BakeSettings(method="auto", spp=8, batches=4, seed=3))
    choice = res.stats["auto"]["lights"]["Area"]
    if choice["direct"] != "photons" or res.stats["auto"]["bake"] != "manifold":
        pytest.skip(f"the pilot chose otherwise here: {choice['why']}")
    k = choice["photon_factor"]
    assert k != 1.0 and f"{k:g}x the samples" in choice["why"]
    per_batch = max(1, int(8 * 40 * 30 * k) // 4)  # spp x pixels x k, in 4 batches
    assert res.stats["lights"]["Area"]["handoff"]["photons"] == 4 * per_batch
    ref = bake(scene, BakeSettings(method="reference", spp=128, batches=8, seed=5))
    _agree(res, ref, caustic_region(ref.image.mean(axis=2)))


def test_a_short_time_budget_runs_no_pilot():
    """The time rule counts the pilot (1-3 s per light): under PILOT_MIN_BUDGET_PER_LIGHT
    seconds per light auto bakes SMBS without one, and says so in the plan's words."""
    from smbs_addon.baking.auto import PILOT_MIN_BUDGET_PER_LIGHT, pilot_fits

    assert pilot_fits(0.0, 3) and pilot_fits(20.0, 2) and not pilot_fits(19.9, 2) and not pilot_fits(2.0, 0)
    scene = scenes.glass_sphere_scene(resolution=(32, 24))
    budget = 0.5 * PILOT_MIN_BUDGET_PER_LIGHT
    res = bake(scene, BakeSettings(spp=2, batches=2, seed=1, time_budget=budget))
    st = res.stats["auto"]
    assert st["pilot"] is False and st["lights"] == {} and st["bake"] == "manifold"
    assert f"auto, Area: SMBS (a {budget:g} s budget leaves no time for the pilot, which needs 10 s per light)" \
        in res.stats["plan"]["words"]
    assert res.stats["lights"]["Area"]["walks"] > 0 and np.isfinite(res.image).all()


def test_region_shares_add_up_to_the_whole():
    """auto weighs each region by its pixels: the direct and the mirrored shares of the
    variance (and so of the cost) add up to the whole caustic region's, exactly."""
    from smbs_addon.baking.auto import _cost, _var

    rng = np.random.default_rng(0)
    b = rng.random((4, 6, 8)) * np.linspace(0.1, 3.0, 48).reshape(6, 8)
    region = np.ones((6, 8), bool)
    region[0] = False
    direct = np.zeros((6, 8), bool)
    direct[:, :5] = True
    n = int(region.sum())
    d, t = region & direct, region & ~direct
    assert math.isclose(_var(b, d, n) + _var(b, t, n), _var(b, region, n), rel_tol=1e-12)
    assert math.isclose(_cost(b, d, 7, n) + _cost(b, t, 7, n), _cost(b, region, 7, n), rel_tol=1e-12)
    assert _var(b, np.zeros_like(region), n) == 0.0
