"""SMBS's large mutation: GetRatio (Algorithm 4) against a plain one-ray-at-a-time reading of it, and
where trigger 2 (back-lit) looks."""
import numpy as np
import pytest

from testkit import scenes
from smbs_addon.walks.walk import MAX_HALVINGS
from testkit.oracles.large_mutation import get_ratio


def _slab_hit(o, d, lo, hi):
    t0, t1 = 0.0, np.inf
    for i in range(3):
        if d[i] == 0.0:
            if not (lo[i] <= o[i] <= hi[i]):
                return False
            continue
        a, b = (lo[i] - o[i]) / d[i], (hi[i] - o[i]) / d[i]
        t0, t1 = max(t0, min(a, b)), min(t1, max(a, b))
    return t1 >= t0


def _get_ratio_one(x0, v1, target, lo, hi, scale):
    a = (1.0 if np.dot(v1, target) < 0 else 0.5) * scale
    for _ in range(MAX_HALVINGS + 1):
        d = a * target + (1 - a) * v1
        n = np.linalg.norm(d)
        if n > 0 and _slab_hit(x0, d / n, lo, hi):
            return a
        a *= 0.5
    return 0.0


def test_get_ratio_matches_the_algorithm_ray_by_ray():
    rng = np.random.default_rng(7)
    n = 4000
    x0 = rng.uniform(-3, 3, (n, 3))
    lo = rng.uniform(-1, 0, (n, 3))
    hi = lo + rng.uniform(0.05, 1.5, (n, 3))
    centre = 0.5 * (lo + hi)
    v1 = centre - x0 + rng.normal(0, 0.3, (n, 3))  # roughly towards the box, as a walk's x1 is
    v1 /= np.linalg.norm(v1, axis=1, keepdims=True)
    target = rng.normal(size=(n, 3))
    target /= np.linalg.norm(target, axis=1, keepdims=True)
    target[:50] = -v1[:50]  # opposite directions: the mix can vanish
    target[50:60] = v1[50:60]
    scale = np.where(rng.random(n) < 0.3, 0.5 ** rng.integers(1, 4, n), 1.0)
    got = get_ratio(x0, v1, target, lo, hi, scale)
    want = np.array([_get_ratio_one(x0[i], v1[i], target[i], lo[i], hi[i], scale[i]) for i in range(n)])
    assert np.array_equal(got, want)
    # every outcome occurs: full weight, halved, and given up (a = 0)
    assert (got == 1.0).any() and ((got > 0) & (got < 0.5)).any() and (got == 0).any()


def _converged_chains(scene, types, n=4000, seed=5):
    """Plain SMS walks of one chain type from floor points in front of the pane; the lanes
    that converged (valid specular paths), with their receivers and light ends."""
    from smbs_addon.walks.walk import WalkConfig, newton_walk

    rng = np.random.default_rng(seed)
    x0 = np.c_[rng.uniform(-1.0, 1.0, n), rng.uniform(-2.5, -0.2, n), np.zeros(n)]
    ctx, ng0, light, chain = scenes.seed_chains(scene, types, x0, rng)
    res = newton_walk(ctx, WalkConfig(), types, x0, ng0, light, chain)
    conv = np.flatnonzero(res.converged)
    return x0[conv], res.chain.take(conv), light.take(conv)


def test_back_lit_trigger_at_the_last_vertex_never_fires_on_a_valid_path():
    """Trigger 2 (back-lit) reads the light's side of a chain vertex. At the vertex the light
    meets, a valid path always has the light where the interaction sends it: the test there
    fires on exactly 0 of the converged SMS paths. At x1 (the paper's x2) it reads the light
    against x0, which only a chain of one vertex ties together: light reflected off a pane's
    back face (T R T) enters and leaves by the front face, and the test fires on every such
    valid path (on a pane seen behind a glass ball it cut SMBS's T R T success from SMS's 0.49
    to 0.055). By default the trigger looks at chains of one vertex only."""
    from smbs_addon.walks.walk import WalkConfig, backlit

    scene = scenes.pane_scene()
    x0, chain, light = _converged_chains(scene, "TRT")
    assert len(x0) > 500, len(x0)
    assert backlit(WalkConfig(backlit_vertex="last"), "TRT", x0, chain, light).sum() == 0
    assert backlit(WalkConfig(backlit_vertex="first"), "TRT", x0, chain, light).all()
    assert not backlit(WalkConfig(), "TRT", x0, chain, light).any()  # "single": off for 2+ vertices
    with pytest.raises(ValueError, match="backlit_vertex"):
        backlit(WalkConfig(backlit_vertex="middle"), "TRT", x0, chain, light)


def test_back_lit_trigger_on_one_vertex_reads_the_light_against_x0():
    """A chain of one vertex: the default ("single") is the paper's test. A mirror's
    reflection fires where x0 and the light are on different sides; a refraction where on
    the same side (four hand-made lanes)."""
    from smbs_addon.shading.light_samples import LightEnd
    from smbs_addon.kernels.records import NF, NS, P
    from smbs_addon.walks.walk import Chain, WalkConfig, backlit

    F = np.zeros((4, 1, NF))
    F[:, 0, P:P + 3] = 0.0
    F[:, 0, NS:NS + 3] = [0.0, 0.0, 1.0]
    x0 = np.array([[0, 0, 1.0], [0, 0, -1.0], [0, 0, 1.0], [0, 0, -1.0]])
    ly = np.tile([1.0, 0.0, 2.0], (4, 1))  # above the surface
    light = LightEnd(False, ly, np.zeros((4, 3)), np.zeros((4, 3)))
    chain = Chain(F, np.zeros((4, 1, 3), np.int64), np.zeros(4, np.int64), np.zeros((4, 3)))
    assert backlit(WalkConfig(), "R", x0, chain, light).tolist() == [False, True, False, True]
    assert backlit(WalkConfig(), "T", x0, chain, light).tolist() == [True, False, True, False]
