"""The anchored unbiased estimator (issue 61; estimators._anchored): on a chain of one vertex under a
distant light, one walk per sample from the straight line to the light finds a solution s* at weight
one, and the random walks with their Bernoulli trials count only the other solutions. Its mean must be
plain SMBS's (both unbiased) where the other solutions carry real light, and the trials must mostly
vanish, since a random walk that finds s* again needs none.
"""
import math

import numpy as np
import pytest

from smbs_addon import BakeSettings, bake
from smbs_addon.baking.result import caustic_region
from smbs_addon.core.errors import SceneError
from smbs_addon.walks.manifold import _hand_off_seen
from testkit import scenes
from testkit.checks import against_reference


def _light(res):
    return next(iter(res.stats["lights"].values()))


@pytest.fixture(scope="module")
def folded_water():
    """Wavy water focusing above the floor (several solutions per floor point behind the folds):
    plain SMBS and anchored SMBS, 512 spp each."""
    scene = scenes.wavy_water_sun_scene()
    plain = bake(scene, BakeSettings(method="smbs", spp=512, seed=3, batches=16, anchor=False))
    anchored = bake(scene, BakeSettings(method="smbs", spp=512, seed=3, batches=16))
    return plain, anchored


@pytest.mark.slow
def test_anchored_matches_plain_smbs(folded_water):
    plain, anchored = folded_water
    region = caustic_region(plain.image)
    rel, noise, beyond = against_reference(anchored, plain, region)
    assert noise < 0.02, f"too noisy to judge: {noise:.2%}"
    assert abs(rel) < 3 * noise, f"anchored SMBS {rel:+.2%} against plain SMBS (noise {noise:.2%})"
    # batch variances have 15 degrees of freedom: about 1% of pixels beyond 3 sigma
    assert beyond < 0.03, f"{beyond:.1%} of caustic pixels beyond 3 sigma"


@pytest.mark.slow
def test_anchored_counts_the_other_solutions_and_skips_the_trials(folded_water):
    plain, anchored = folded_water
    p, a = _light(plain), _light(anchored)
    assert "anchor_walks" not in p
    assert a["anchor_walks"] == a["walks"]  # one anchor walk per walked sample
    # most random walks find the anchor's solution again: no trials for them
    assert a["anchor_found_again"] > 0.5 * a["successes"]
    # behind the folds the other solutions are there, and counted (their trials ran)
    assert a["bernoulli_lanes"] > 0.05 * a["anchor_successes"]
    assert a["bernoulli_trials"] < 0.3 * p["bernoulli_trials"]


def test_anchor_only_for_distant_lights_and_one_vertex():
    """A point light (water_scene's bulb) is not anchored; its image is as before, bit for bit."""
    scene = scenes.water_scene("point", resolution=16)
    on = bake(scene, BakeSettings(method="smbs", spp=2, seed=1, batches=2))
    off = bake(scene, BakeSettings(method="smbs", spp=2, seed=1, batches=2, anchor=False))
    assert "anchor_walks" not in _light(on)
    assert np.array_equal(on.image, off.image)


def test_anchor_walks_must_be_a_share():
    with pytest.raises(SceneError, match="anchor_walks"):
        BakeSettings(anchor_walks=0.0).validate()


def test_seen_handoff_stops_when_it_brings_little_light(monkeypatch):
    """Under a world, the hand-off at receivers seen through glass stops once it has run and brought
    under SEEN_HANDOFF_SHARE of the light's caustic there (the dim sky near the horizon), however many
    paths it found; it goes on while it brings more."""
    from smbs_addon.walks import manifold

    from smbs_addon.scene import arrays as S

    monkeypatch.setattr(manifold, "handoff_hits", lambda *a: math.inf)
    lp = type("LP", (), {"index": 0, "caster_objects": ()})()
    world = type("Scene", (), {"light_type": np.array([S.WORLD])})()
    st = {"seen_handoff_chunks": 1, "seen_focus": 1, "seen_handoff_paths": 39000, "seen_handoff_energy": 14.0,
          "seen_energy": 70000.0}
    assert not _hand_off_seen(world, lp, st)
    st["seen_handoff_energy"] = 7000.0
    assert _hand_off_seen(world, lp, st)
    # other lights keep the count rule alone (a ball's focus seen through a pane may be faint and still
    # the walks' heavy tail)
    sun = type("Scene", (), {"light_type": np.array([S.SUN])})()
    st["seen_handoff_energy"] = 14.0
    assert _hand_off_seen(sun, lp, st)
