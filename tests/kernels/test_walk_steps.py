"""How a walk steps and when it gives up: BakeSettings.first_step (the first small step's share of
the Newton step) and stall_stop (walks without large mutations stop when four steps shrank the
mismatch by less than 10%), against a plain reading of the rule over each lane's own
trajectory, and the unbiased estimator's image with and without them."""
import dataclasses

import numpy as np
import pytest

from testkit import scenes
from smbs_addon import BakeSettings, bake
from smbs_addon.core.errors import SceneError


def _walks(types="TT", n=3000, seed=4):
    """Seed chains of the glass ball from floor points around it, as SMS walks them."""
    scene = scenes.glass_sphere_scene(resolution=(32, 32))
    rng = np.random.default_rng(seed)
    r, a = rng.uniform(0.0, 2.0, n), rng.uniform(0, 2 * np.pi, n)
    x0 = np.c_[r * np.cos(a), r * np.sin(a), np.zeros(n)]
    ctx, ng0, light, chain = scenes.seed_chains(scene, types, x0, rng)
    return ctx, x0, ng0, light, chain


def test_a_stalled_walk_stops_at_the_first_step_that_shrank_four_by_less_than_a_tenth():
    """The stall rule read off each lane's trajectory without it (the mismatch after m steps:
    the walk cut at max_iterations = m): a lane stops ("stalled") at the first step s >= 6 whose
    mismatch is above 0.9 times that of step s - 4, and only there; every other lane walks
    exactly as without the rule (outcome, steps, chain)."""
    from smbs_addon.walks.walk import STALL, WalkConfig, end_mismatch, newton_walk
    from smbs_addon.kernels.records import STALLED

    ctx, x0, ng0, light, chain = _walks()
    base = WalkConfig(beta0=0.125)
    E = []
    for m in range(base.max_iterations + 1):
        r = newton_walk(ctx, dataclasses.replace(base, max_iterations=m), "TT", x0, ng0, light, chain)
        E.append(end_mismatch(r.chain, light)[0])
    E = np.array(E)
    ref = newton_walk(ctx, base, "TT", x0, ng0, light, chain)
    got = newton_walk(ctx, dataclasses.replace(base, **STALL), "TT", x0, ng0, light, chain)
    walked = ref.mutations > 0
    with np.errstate(invalid="ignore"):
        slow = np.zeros_like(E, bool)
        slow[6:] = E[6:] > 0.9 * E[2:-4]
    first = np.where(slow.any(axis=0), slow.argmax(axis=0), 99)
    stalled = got.outcome == STALLED
    assert not (stalled & ~walked).any()
    assert np.array_equal(got.mutations[stalled], first[stalled])
    assert np.all(first[stalled] <= ref.mutations[stalled])
    assert stalled[walked & (first < ref.mutations)].all()
    same = ~stalled
    assert np.all(first[same & walked] >= ref.mutations[same & walked])
    assert np.array_equal(got.outcome[same], ref.outcome[same])
    assert np.array_equal(got.mutations[same], ref.mutations[same])
    assert np.array_equal(got.chain.F[same], ref.chain.F[same])
    # the rule bites, and costs few successes: on this ball a tenth of the walks stall and
    # fewer than 3% of those that converge without it are lost
    assert stalled.mean() > 0.1, stalled.mean()
    lost = (ref.converged & stalled).sum() / ref.converged.sum()
    assert 0 < lost < 0.03, lost


def test_first_step_scales_the_first_newton_step():
    """first_step is beta at a walk's start. A step moves x1 in its tangent plane to p = x1 +
    beta * (Newton step) and re-traces the chain along the ray from x0 (spawned off the floor)
    through p; so where the ray meets x1's tangent plane is p again. Two walks of one step from
    the same seeds, beta 1 and 1/8, on lanes where both steps were accepted: the tangent-plane
    points' offsets from x1 are in the ratio 1/8 (1e-6)."""
    from smbs_addon.kernels.records import P, S, T
    from smbs_addon.walks.walk import WalkConfig, newton_walk

    ctx, x0, ng0, light, chain = _walks(n=2000)
    one = dict(max_iterations=1, max_step=1e9)
    x1 = chain.F[:, 0, P:P + 3]
    n1 = np.cross(chain.F[:, 0, S:S + 3], chain.F[:, 0, T:T + 3])
    origin = x0 + ctx.tracer.eps * ng0

    def in_plane(res):
        d = res.chain.F[:, 0, P:P + 3] - origin
        with np.errstate(invalid="ignore", divide="ignore"):  # lanes whose seed failed: zeros
            t = np.sum((x1 - origin) * n1, axis=1) / np.sum(d * n1, axis=1)
        return origin + t[:, None] * d - x1

    full = newton_walk(ctx, WalkConfig(beta0=1.0, **one), "TT", x0, ng0, light, chain)
    eighth = newton_walk(ctx, WalkConfig(beta0=0.125, **one), "TT", x0, ng0, light, chain)
    o1, o8 = in_plane(full), in_plane(eighth)
    moved = (np.linalg.norm(o1, axis=1) > 1e-3) & (np.linalg.norm(o8, axis=1) > 1e-4)
    assert moved.sum() > 100, moved.sum()
    np.testing.assert_allclose(o8[moved], 0.125 * o1[moved], rtol=1e-6, atol=1e-9)


def test_mnee_and_the_biased_estimator_keep_the_published_walk_and_bad_first_steps_are_refused():
    from smbs_addon.walks.walk import STALL

    for method in ("sms", "smbs"):
        w = BakeSettings(method=method).manifold_options().walk
        assert (w.beta0, w.stall_window, w.stall_factor, w.stall_from) == (0.125, *STALL.values())
        w = BakeSettings(method=method, first_step=1.0, stall_stop=False).manifold_options().walk
        assert (w.beta0, w.stall_window) == (1.0, 0)
    w = BakeSettings(method="mnee", first_step=0.5).manifold_options().walk
    assert (w.beta0, w.stall_window) == (1.0, 0)
    w = BakeSettings(method="sms", estimator="biased").manifold_options().walk
    assert (w.beta0, w.stall_window) == (1.0, 0)
    for bad in (0.0, -0.5, 1.5, float("nan")):
        with pytest.raises(SceneError, match="first_step"):
            BakeSettings(first_step=bad).validate()


@pytest.mark.parametrize("method", ["sms", "smbs"])
def test_the_unbiased_image_does_not_depend_on_how_walks_step(method):
    """The unbiased estimator's Bernoulli trials walk by the same rules as its primary walks,
    so first_step and stall_stop change its noise and cost, not its mean: the glass ball's
    caustic (the brightest 5% of pixels of the published walk's image) agrees within 3 of the
    two bakes' combined standard errors (their batches' spread), while the new walk takes fewer
    Newton steps per success."""
    scene = scenes.glass_sphere_scene(resolution=(48, 48))
    runs = {}
    for name, extra in (("published", dict(first_step=1.0, stall_stop=False)), ("default", {})):
        r = bake(scene, BakeSettings(method=method, spp=64, batches=8, seed=3, **extra))
        runs[name] = r
    lum = {k: r.batch_luminance for k, r in runs.items()}
    img = lum["published"].mean(axis=0)
    region = img >= np.quantile(img, 0.95)
    means = {k: v[:, region].mean(axis=1) for k, v in lum.items()}  # one mean per batch
    m = {k: v.mean() for k, v in means.items()}
    se = {k: v.std(ddof=1) / np.sqrt(len(v)) for k, v in means.items()}
    assert abs(m["default"] - m["published"]) < 3 * np.hypot(se["default"], se["published"]), (m, se)
    steps = {k: r.stats["mutations_per_success"] for k, r in runs.items()}
    assert steps["default"] < 0.9 * steps["published"], steps
