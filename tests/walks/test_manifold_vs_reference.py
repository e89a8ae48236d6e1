"""Curved casters, where no closed form exists: the manifold walks against the
brute-force light-tracing reference (issue 3).

Unbiased SMS and SMBS must agree with the reference within 3% in mean over
the caustic region (the noise of both must be small enough to judge), and
pixel by pixel within the combined statistical error; the biased estimator
(unique solutions of M walks) may lose energy but never exceed the reference
beyond noise.
"""
import numpy as np
import pytest

from testkit import scenes
from smbs_addon import BakeSettings, bake
from smbs_addon.baking.result import caustic_region
from testkit.checks import against_reference


@pytest.fixture(scope="module")
def sphere():
    scene = scenes.glass_sphere_scene(resolution=(48, 36))
    ref = bake(scene, BakeSettings(method="reference", spp=1024, seed=9))
    return scene, ref, caustic_region(ref.image)


# SMBS's Bernoulli counts have the heavier tail here (large mutations make some
# solutions rarer to re-find: max count ~700 against ~70), so it needs more samples
@pytest.mark.slow
@pytest.mark.parametrize("method,spp", [("sms", 96), ("smbs", 224)])
def test_glass_sphere_unbiased_matches_reference(sphere, method, spp):
    scene, ref, region = sphere
    res = bake(scene, BakeSettings(method=method, spp=spp, seed=1, batches=16))
    # a closed ball also gets its internal reflections; under a light from above, T R T sends
    # its light back up (the pre-pass finds none on the floor), so only T R R T is walked
    assert res.stats["chain_types"] == ["R", "TT", "TRRT"]
    assert res.stats["guide"]["not_walked"] == ["TRT"]
    rel, noise, beyond = against_reference(res, ref, region)
    assert noise < 0.015, f"too noisy to judge: {noise:.2%}"
    assert abs(rel) < 0.03, f"{method}: {rel:+.2%} against the reference (noise {noise:.2%})"
    # batch variances have 7 degrees of freedom: a t-distribution puts ~2% beyond 3
    assert beyond < 0.05, f"{beyond:.1%} of caustic pixels beyond 3 sigma"


@pytest.mark.parametrize("method", ["sms", "smbs"])
def test_glass_sphere_biased_never_exceeds_reference(sphere, method):
    scene, ref, region = sphere
    res = bake(scene, BakeSettings(method=method, estimator="biased", trials=4, spp=16, seed=2))
    rel, noise, _ = against_reference(res, ref, region)
    assert rel < 3 * noise, f"biased {method} above the reference: {rel:+.2%} (noise {noise:.2%})"


def test_ring_plan_includes_double_reflections():
    scene = scenes.ring_scene()
    res = bake(scene, BakeSettings(method="sms", spp=1, seed=1, batches=2))
    assert res.stats["chain_types"] == ["R", "RR"]


def _fold_mask(ref_lum, region, pct=97, grow=2):
    """The caustic's folds (cusp and bright edges): the hottest pixels and their neighbours."""
    hot = ref_lum > np.percentile(ref_lum[region], pct)
    out = hot.copy()
    for dy in range(-grow, grow + 1):
        for dx in range(-grow, grow + 1):
            out |= np.roll(np.roll(hot, dy, 0), dx, 1)
    return out


@pytest.fixture(scope="module")
def ring():
    """The ring with two independent references: the region and the folds are chosen on
    one and the estimates judged against the other (choosing pixels on the image one
    then averages favours its noisy-high pixels; at the folds that made every
    estimator look 8-11% low)."""
    scene = scenes.ring_scene()
    pick = bake(scene, BakeSettings(method="reference", spp=1024, seed=9))
    judge = bake(scene, BakeSettings(method="reference", spp=1024, seed=10))
    region = caustic_region(pick.image)
    fold = region & _fold_mask(pick.image.mean(axis=2), region)
    return scene, judge, region, fold


@pytest.mark.parametrize("method", ["sms", "smbs"])
def test_ring_unbiased_matches_reference(ring, method):
    """The cardioid inside a gold ring (R and RR chains), folds included. Where the
    manifold's Jacobian vanishes (the cusp and the bright edges) G grows without bound
    and the walks' estimate has an infinite-variance tail; the photon hand-off takes
    the paths that focus more than 4x, so the sum is unbiased with a finite variance."""
    scene, ref, region, fold = ring
    res = bake(scene, BakeSettings(method=method, spp=64, seed=1))
    assert res.stats["lights"]["Area"]["handoff"]["handoff_paths"] > 0
    rel, noise, beyond = against_reference(res, ref, region)
    # measured: SMS +0.2% +- 1.7%, SMBS -1.6% +- 1.1% (SMS's Bernoulli counts have the longer tail)
    assert noise < 0.02, f"too noisy to judge: {noise:.2%}"
    assert abs(rel) < 0.03, f"{method}: {rel:+.2%} over the caustic (noise {noise:.2%})"
    assert beyond < 0.05, f"{beyond:.1%} of pixels beyond 3 sigma"
    rel_f, noise_f, _ = against_reference(res, ref, fold)
    assert abs(rel_f) < 3 * noise_f + 0.01, f"{method}: {rel_f:+.2%} on the folds (noise {noise_f:.2%})"


@pytest.mark.slow
def test_normal_mapped_mirror_light_tracer_takes_the_adjoint_correction():
    """A flat sheet whose shading normals lean up to 40 degrees (a normal map sampled at
    the vertices). With shading normals the specular BSDF is not symmetric: light tracing
    must weight each bounce by |w_in.ns| |w_out.ng| / (|w_in.ng| |w_out.ns|) (Veach 5.3)
    to agree with the radiance view the walks (and Cycles) take. Without it the light
    tracer was 37% above SMS here (SMS -27.2% +- 1.3% at 32 spp, 32 x 24); with it, at
    48 spp in 16 batches, seeds 1, 2, 3: -3.3% +- 3.9%, -3.0% +- 2.3%, -3.4% +- 1.8%, and
    +4.5% +- 3.3% at 96 spp. (At 24 spp in 8 batches seed 1 read -13% +- 3.4%: SMS's
    Bernoulli counts are heavy-tailed here, and a short bake mostly misses the rare large
    ones, so it reads low; that was taken for a regression of the side rules for a while.)"""
    scene = scenes.wavy_mirror_scene(resolution=(24, 18), normal_mapped=True)
    kw = dict(indirect=False)  # the first-order caustic is the subject; indirect light adds noise
    pick = bake(scene, BakeSettings(method="reference", spp=256, seed=9, **kw))
    ref = bake(scene, BakeSettings(method="reference", spp=2048, seed=10, batches=16, **kw))
    region = caustic_region(pick.image)
    res = bake(scene, BakeSettings(method="sms", spp=48, seed=1, batches=16, **kw))
    rel, noise, _ = against_reference(res, ref, region)
    assert noise < 0.05, f"too noisy to judge: {noise:.2%}"
    print(f"SMS {rel:+.2%} +- {noise:.2%}")
    assert abs(rel) < 0.03 + 3 * noise, f"SMS {rel:+.2%} against the light tracer (noise {noise:.2%})"
