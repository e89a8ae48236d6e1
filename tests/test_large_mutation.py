"""SMBS's GetRatio (Algorithm 4) against a plain one-ray-at-a-time reading of it."""
import numpy as np

from smbs_addon.large_mutation import MAX_HALVINGS, get_ratio


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
