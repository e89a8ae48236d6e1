"""auto bakes a light's walks by their anchor alone, MNEE's way (biased, one solution per sample at
weight one), only where its pilot bounds the light of the other solutions below ANCHOR_ONLY_BIAS of the
light's caustic, and then says so (plan words, error_leaves_out, with the bound); where the pilot meets
other solutions (water whose waves focus above the floor) it stays unbiased (issue 61)."""
import numpy as np
import pytest

from smbs_addon import BakeSettings, bake
from smbs_addon.baking import auto
from smbs_addon.baking.result import caustic_region
from testkit import scenes
from testkit.checks import against_reference


def _auto(res):
    return next(iter(res.stats["auto"]["lights"].values()))


def test_gentle_water_gets_the_anchor_alone_and_says_so():
    """Waves too gentle to focus before the floor: one solution per floor point."""
    scene = scenes.wavy_water_sun_scene(amplitude=0.01, above=True)
    res = bake(scene, BakeSettings(spp=4, seed=1))
    a = _auto(res)
    assert a["anchor_only"] and a["anchor_bound"] < auto.ANCHOR_ONLY_BIAS
    assert "straight-line walk alone" in a["why"]
    assert any("straight-line walk alone" in w for w in res.stats["plan"]["words"])
    assert any("straight-line walk alone" in w and "%" in w for w in res.stats["error_leaves_out"])
    st = next(iter(res.stats["lights"].values()))
    assert st["anchor_walks"] > 0 and st["walks"] == 0  # no random walk, no trial


def test_folded_water_stays_unbiased():
    """Waves that focus above the floor: the pilot meets the other solutions and measures their light."""
    scene = scenes.wavy_water_sun_scene(amplitude=0.05, above=True)
    res = bake(scene, BakeSettings(spp=4, seed=1))
    a = _auto(res)
    assert not a["anchor_only"] and a["anchor_bound"] > auto.ANCHOR_ONLY_BIAS
    assert res.stats["error_leaves_out"] == []
    st = next(iter(res.stats["lights"].values()))
    assert st["walks"] > 0 and st["bernoulli_lanes"] > 0


@pytest.mark.slow
def test_anchor_alone_within_its_bound_of_unbiased():
    """Where auto takes the anchor alone, its mean is the unbiased SMBS's within noise and the bound."""
    scene = scenes.wavy_water_sun_scene(amplitude=0.01, above=True)
    chosen = bake(scene, BakeSettings(spp=256, seed=2, batches=16))
    assert _auto(chosen)["anchor_only"]
    plain = bake(scene, BakeSettings(method="smbs", spp=256, seed=3, batches=16, anchor=False))
    rel, noise, beyond = against_reference(chosen, plain, caustic_region(plain.image))
    assert noise < 0.01
    assert abs(rel) < 3 * noise + _auto(chosen)["anchor_bound"]
    assert beyond < 0.03


def test_anchor_bias_bound():
    """The bound: the other solutions' share, plus 3 standard errors, plus 3 samples' worth of 10 times the
    anchor's mean light (the rule of three where none was met)."""
    assert auto.anchor_bias({}) is None
    st = {"anchor_walks": 1000, "anchor_energy": 1000.0, "walk_energy": 0.0, "walk_energy_sq": 0.0}
    assert np.isclose(auto.anchor_bias(st), 30.0 / 1000)
    st.update(walk_energy=10.0, walk_energy_sq=100.0)  # one sample of 10 among 1000
    se = np.sqrt(100.0 - 100.0 / 1000)
    assert np.isclose(auto.anchor_bias(st), (10.0 + 3 * (se + 10.0)) / 1010.0)


def test_gather_copies_where_every_light_walks_its_straight_line_alone(monkeypatch):
    """Receivers seen through the water take GATHER_COPIES gathers after a diffuse bounce, each of a
    quarter of their weight, where auto walks every light's straight line alone; one where it walks
    otherwise (exact counts of gather's calls). The copies' mean is the single gather's, within noise."""
    from smbs_addon.walks import manifold

    calls = []
    gather = manifold.gather_radiance

    def counted(*a, **k):
        calls.append(float(a[3].beta.sum()))
        return gather(*a, **k)

    monkeypatch.setattr(manifold, "gather_radiance", counted)
    gentle = scenes.wavy_water_sun_scene(amplitude=0.01, above=True)
    res = bake(gentle, BakeSettings(spp=2, batches=2, seed=1))
    assert _auto(res)["anchor_only"] and manifold.GATHER_COPIES == 4
    assert len(calls) % 4 == 0 and len(calls) > 0
    assert all(c == pytest.approx(calls[i - i % 4]) for i, c in enumerate(calls))  # a quarter each
    calls.clear()
    folded = scenes.wavy_water_sun_scene(amplitude=0.05, above=True)
    res = bake(folded, BakeSettings(spp=2, batches=2, seed=1))
    # one chunk a batch, its receivers too few to split (manifold.GATHER_SPLIT)
    assert not _auto(res)["anchor_only"] and len(calls) == res.stats["batches_done"] * 1
    monkeypatch.setattr(manifold, "gather_radiance", gather)
    four = bake(gentle, BakeSettings(spp=64, seed=2, batches=8))
    monkeypatch.setattr(manifold, "GATHER_COPIES", 1)
    one = bake(gentle, BakeSettings(spp=64, seed=3, batches=8))
    rel, noise, beyond = against_reference(four, one, caustic_region(one.image))
    assert noise < 0.02 and abs(rel) < 3 * noise and beyond < 0.03, (rel, noise, beyond)


def test_a_gather_copy_takes_its_share_of_the_weight_and_shifted_samples():
    """Copy k of 4: a quarter of the weight (the receivers' own untouched), the stratified numbers
    shifted by k / 4 mod 1."""
    from smbs_addon.trace.eye import Receivers
    from smbs_addon.walks.manifold import _gather_copy

    n = 5
    z = np.zeros((n, 3))
    rc = Receivers(rx=np.zeros(n), ry=np.zeros(n), p=z, ng=z, ns=z, w_eye=z, beta=np.ones((n, 3)),
                   mat=np.zeros(n, int), eye_specular=np.ones(n, int), weight=np.ones(n), prior=np.zeros((n, 3), int),
                   strata=np.full((n, 6), 0.9))
    assert _gather_copy(rc, 0, 1) is rc
    c0, c3 = _gather_copy(rc, 0, 4), _gather_copy(rc, 3, 4)
    assert np.all(c0.beta == 0.25) and np.all(rc.beta == 1.0)
    assert np.all(c0.strata == 0.9) and np.allclose(c3.strata, 0.65)
