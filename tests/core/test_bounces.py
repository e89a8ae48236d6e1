"""Cycles' Light Paths bounce limits (smbs_addon/bounces.py), in every estimator.

Cycles renders a caustic path when its scattering events before the last one (counted from
the camera: x0's diffuse bounce, reflections as glossy, refractions as transmission) fit the
scene's Diffuse, Glossy, Transmission and Max bounces. Measured on the conformance cube with
Cycles: Diffuse 0 leaves no caustic at all, Glossy 0 keeps 0.657 of it and Glossy 1 0.861
(tests/test_conformance.py holds our layer to a Cycles reference made with Glossy 1).
"""
import numpy as np
import pytest

from smbs_addon import BakeSettings, bake
from smbs_addon.scene.light_paths import Limits, UNLIMITED
from smbs_addon.scene.arrays import Scene
from testkit import scenes
from testkit.conformance import view_masks


def test_the_last_event_is_free():
    """Exact: the chain's letters are read from the receiver, the last one meets the light."""
    lim = Limits(total=12, diffuse=4, glossy=0, transmission=12)
    assert [bool(lim.chain_fits(t)) for t in ("R", "TT", "TRT", "TRRT", "RR")] == [True, True, False, False, False]
    lim = Limits(total=12, diffuse=4, glossy=1, transmission=12)
    assert [bool(lim.chain_fits(t)) for t in ("TRT", "TRRT", "RR", "RRR")] == [True, False, True, False]
    lim = Limits(total=12, diffuse=4, glossy=4, transmission=0)
    assert [bool(lim.chain_fits(t)) for t in ("T", "R", "TT", "RT")] == [True, True, False, True]
    # the total counts x0's diffuse bounce: with Max 2, T T (diffuse, T, then the free T) fits
    lim = Limits(total=2, diffuse=4, glossy=4, transmission=12)
    assert [bool(lim.chain_fits(t)) for t in ("TT", "TRT")] == [True, False]
    # Diffuse 0: x0's own bounce is not the last event, so no caustic at all
    assert not Limits(total=12, diffuse=0, glossy=4, transmission=12).chain_fits("R")
    # the camera's events before x0 count: through a glass pane (two refractions) T T needs 3
    lim = Limits(total=12, diffuse=4, glossy=4, transmission=2)
    assert bool(lim.chain_fits("TT", 1, 0, 0)) and not bool(lim.chain_fits("TT", 1, 0, 2))


def test_limits_of_a_scene():
    sc = scenes.glass_sphere_scene()
    assert Limits.of(sc) == Limits(total=UNLIMITED, diffuse=4, glossy=UNLIMITED, transmission=UNLIMITED)
    sc.light_paths = np.array([12, 4, 4, 12])
    assert Limits.of(sc) == Limits(12, 4, 4, 12)
    assert Limits.of(sc).words() == "Light Paths: max 12, diffuse 4, glossy 4, transmission 12"


def test_light_paths_are_saved_and_older_files_load(tmp_path):
    sc = scenes.glass_sphere_scene()
    sc.light_paths = np.array([12, 3, 2, 9])
    sc.save(tmp_path / "a.npz")
    assert Scene.load(tmp_path / "a.npz").light_paths.tolist() == [12, 3, 2, 9]
    # a file written before the limits were exported has no such array: no limits
    with np.load(tmp_path / "a.npz") as z:
        data = {k: z[k] for k in z.files if k != "light_paths"}
    np.savez(tmp_path / "old.npz", **data)
    assert Scene.load(tmp_path / "old.npz").light_paths.tolist() == [-1, -1, -1, -1]


@pytest.mark.parametrize("method", ["reference", "sms", "smbs", "mnee", "auto"])
def test_no_diffuse_bounce_no_caustic(method):
    """Exact, every method: with Diffuse bounces 0 the layer is zero (Cycles too), and the
    walks are not even started."""
    sc = scenes.glass_sphere_scene(resolution=(32, 24))
    sc.light_paths = np.array([12, 0, 4, 12])
    res = bake(sc, BakeSettings(method=method, spp=1, seed=1))
    assert res.image.max() == 0.0
    assert res.stats.get("walks", 0) == 0


def test_walks_and_photons_keep_the_same_limits():
    """The ball's floor caustic with Glossy 0: its reflections inside (T R T, T R R T) drop out
    of the walks and of the light tracer alike, and the two still agree (means within 3
    combined standard errors), while the limit takes away a measurable share of either: on the
    floor the camera sees directly, the light tracer with and without the limit on the same
    random numbers (the same photons, but for what the limit cuts) differ by more than 3
    standard errors of their paired batches."""
    sc = scenes.glass_sphere_scene(resolution=(48, 36))
    full = bake(sc, BakeSettings(method="reference", spp=256, seed=2))
    sc.light_paths = np.array([12, 4, 0, 12])
    lt = bake(sc, BakeSettings(method="reference", spp=256, seed=2))
    walks = bake(sc, BakeSettings(method="sms", spp=16, seed=2))
    region = full.image.mean(axis=2) > 0.05 * np.percentile(full.image.mean(axis=2), 99.5)
    m_lt, se_lt = lt.region_mean(region)
    m_w, se_w = walks.region_mean(region)
    assert abs(m_w - m_lt) < 3 * np.hypot(se_lt, se_w), (m_w, m_lt, se_w, se_lt)
    direct = region & view_masks(sc)[0]
    cut = np.array([a[direct].mean() - b[direct].mean() for a, b in zip(full.batch_luminance, lt.batch_luminance)])
    m_cut, se_cut = cut.mean(), cut.std(ddof=1) / np.sqrt(len(cut))
    # measured: 1.4% of the caustic there, 6 standard errors (the few pixels seen through the
    # ball, whose eye paths the limit changes, are not paired: 4 of 145, most of the noise)
    assert m_cut > 3 * se_cut, (m_cut, se_cut, m_lt)
    assert "TRT" not in walks.stats["lights"]["Area"].get("by_chain", {})
    assert ("Light Paths: max 12, diffuse 4, glossy 0, transmission 12: Cycles renders no caustic along TRT, TRRT, "
            "so neither do we") in walks.stats["plan"]["notes"]


def test_the_guide_weighs_only_light_cycles_renders():
    """Exact: the photon pre-pass's shares (which chain types are weak, whether the paths no walk
    takes are worth a pass) count only paths the Light Paths limits let through. The ball's
    light beyond its walked chain types is all internal reflections (T R R R T, ...): a few
    tenths of a percent without limits, none with Glossy 0, where the walked shares are of the
    rendered light alone (they sum to one)."""
    sc = scenes.glass_sphere_scene(resolution=(48, 36))
    free = bake(sc, BakeSettings(method="sms", spp=1, seed=1)).stats["guide"]
    sc.light_paths = np.array([12, 4, 0, 12])
    cut = bake(sc, BakeSettings(method="sms", spp=1, seed=1)).stats["guide"]
    assert free["other_share"]["Area"] > 1e-3
    assert cut["other_share"]["Area"] == 0.0
    assert sorted(cut["flux_share"]["Area"]) == ["R", "TT"]
    assert sum(cut["flux_share"]["Area"].values()) == pytest.approx(1.0, abs=1e-12)
