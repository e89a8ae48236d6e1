"""Curved casters, where no closed form exists: the manifold walks against the
brute-force light-tracing reference (issue 3).

Unbiased SMS and SMBS must agree with the reference within 3% in mean over
the caustic region (the noise of both must be small enough to judge), and
pixel by pixel within the combined statistical error; the biased estimator
(unique solutions of M walks) may lose energy but never exceed the reference
beyond noise.
"""
import math

import numpy as np
import pytest

import scenes
from smbs_addon import BakeSettings, bake
from smbs_addon.bake import caustic_region


@pytest.fixture(scope="module")
def sphere():
    scene = scenes.glass_sphere_scene(resolution=(48, 36))
    ref = bake(scene, BakeSettings(method="reference", spp=1024, seed=9))
    return scene, ref, caustic_region(ref.image)


def _compare(res, ref, region):
    m, se = res.region_mean(region)
    mr, ser = ref.region_mean(region)
    z = (res.image - ref.image).mean(axis=2)[region] / np.sqrt(
        (res.variance + ref.variance).mean(axis=2)[region] + 1e-30)
    return m / mr - 1, math.hypot(se, ser) / mr, float(np.mean(np.abs(z) > 3))


@pytest.mark.parametrize("method", ["sms", "smbs"])
def test_glass_sphere_unbiased_matches_reference(sphere, method):
    scene, ref, region = sphere
    res = bake(scene, BakeSettings(method=method, spp=64, seed=1))
    assert res.stats["chain_types"] == ["R", "TT"]
    rel, noise, beyond = _compare(res, ref, region)
    assert noise < 0.015, f"too noisy to judge: {noise:.2%}"
    assert abs(rel) < 0.03, f"{method}: {rel:+.2%} against the reference (noise {noise:.2%})"
    # batch variances have 7 degrees of freedom: a t-distribution puts ~2% beyond 3
    assert beyond < 0.05, f"{beyond:.1%} of caustic pixels beyond 3 sigma"


@pytest.mark.parametrize("method", ["sms", "smbs"])
def test_glass_sphere_biased_never_exceeds_reference(sphere, method):
    scene, ref, region = sphere
    res = bake(scene, BakeSettings(method=method, estimator="biased", trials=4, spp=16, seed=2))
    rel, noise, _ = _compare(res, ref, region)
    assert rel < 3 * noise, f"biased {method} above the reference: {rel:+.2%} (noise {noise:.2%})"


def test_ring_plan_includes_double_reflections():
    scene = scenes.ring_scene()
    res = bake(scene, BakeSettings(method="sms", spp=1, seed=1, batches=2))
    assert res.stats["chain_types"] == ["R", "RR"]


@pytest.mark.xfail(strict=True, reason="open: the ring's cardioid comes out 5-8% below the reference "
                   "near the far wall; see the issue 3 note")
def test_ring_unbiased_matches_reference():
    scene = scenes.ring_scene()
    ref = bake(scene, BakeSettings(method="reference", spp=512, seed=9))
    region = caustic_region(ref.image)
    res = bake(scene, BakeSettings(method="sms", spp=32, seed=1))
    rel, noise, _ = _compare(res, ref, region)
    assert noise < 0.015 and abs(rel) < 0.03, f"{rel:+.2%} (noise {noise:.2%})"
