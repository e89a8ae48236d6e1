"""Photons splat only at receivers the camera sees directly: where it sees every receiver through
mirrors or glass (a pool seen through its water), the passes that would trace them for nothing do not
run (baking/passes.sees_directly), and no pixel changes."""
import numpy as np
import pytest

from smbs_addon import BakeSettings, bake
from smbs_addon.baking import passes
from testkit import conformance as conf


@pytest.mark.bpy
def test_a_pool_seen_through_its_water_traces_no_photons_after_a_diffuse_bounce(monkeypatch):
    """pool_sun: its camera sees the floor through the water only. The indirect photons (light after
    a diffuse bounce, for receivers seen directly) ran in every batch, 5% of its time, and splatted
    nothing: now they do not run, and the image is the same bit for bit."""
    sc = conf.scene_arrays("pool_sun")
    s = BakeSettings(method="mnee", spp=1, batches=2, seed=1)
    res = bake(sc, s)
    assert set(res.stats["plan"]["seen"].values()) == {"through mirrors or glass"}
    assert "indirect" not in res.stats
    monkeypatch.setattr(passes, "sees_directly", lambda plan: True)
    traced = bake(sc, s)
    st = traced.stats["indirect"]["Sun"]
    assert st["photons"] > 0 and st["splats"] == 0
    assert np.array_equal(res.image, traced.image)
