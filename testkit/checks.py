"""Judging a bake: against an analytic answer, against another bake; and independent Monte Carlo
estimates (rays against spheres) the tests compare the light tracer's photons with."""
from __future__ import annotations

import math

import numpy as np


def check_against(result, expected, region, tol):
    """Mean over the region within tol (relative); the noise (standard error from
    the spread of independent batches) must be small enough to judge."""
    mean, se = result.region_mean(region)
    ref = expected[region].mean()
    assert se < tol * ref / 3, f"too noisy to judge: standard error {se / ref:.2%}"
    assert abs(mean - ref) <= tol * ref, (
        f"mean {mean:.5f} vs analytic {ref:.5f}: off by {(mean - ref) / ref:+.2%} (tolerance {tol:.0%}, "
        f"noise {se / ref:.2%})")
    return (mean - ref) / ref


def against_reference(res, ref, region):
    """A bake against a reference bake of the same scene over region: the relative difference of
    their means, its standard error (relative), and the share of the region's pixels more than 3
    combined standard deviations apart."""
    m, se = res.region_mean(region)
    mr, ser = ref.region_mean(region)
    z = (res.image - ref.image).mean(axis=2)[region] / np.sqrt(
        (res.variance + ref.variance).mean(axis=2)[region] + 1e-30)
    return m / mr - 1, math.hypot(se, ser) / mr, float(np.mean(np.abs(z) > 3))


# two overlapping spheres under a light at (0, 0, 3): (centre x, y, z, radius)
TARGETS = np.array([[0.3, 0.0, 0.5, 0.4], [-0.2, 0.1, 0.6, 0.5]])


def hits_spheres(o, d, spheres):
    """Whether rays o + t d (t > 0) meet any of the spheres."""
    hit = np.zeros(len(d), bool)
    for c, r in zip(spheres[:, :3], spheres[:, 3]):
        oc = o - c
        b = (oc * d).sum(-1)
        disc = b * b - ((oc * oc).sum(-1) - r * r)
        hit |= (disc >= 0) & (-b + np.sqrt(np.maximum(disc, 0)) > 0)
    return hit


def uniform_sphere(rng, n):
    d = rng.standard_normal((n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def mean_se(x):
    """The mean of x and its standard error."""
    return x.mean(), x.std(ddof=1) / math.sqrt(len(x))
