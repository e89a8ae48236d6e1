"""Extreme scenes: extents far beyond the caustic's, and the camera's clip range (issue 59).

Defect 5: the same glass ball over a floor of 100 km gave a sixth of its caustic, of 1000 km none: the
tracer's one self-intersection offset followed the whole plan's bounds (every diffuse surface's:
plan._finish), 0.77 m at 100 km for a ball of radius 0.5, 7.7 m at 1000 km, where every triangle of
the ball was also taken for degenerate. Now it takes at most EPS_OF_CASTER of the smallest caster's
size, and more point by point where float32 needs it (Tracer.set_extent, kernels.chain.offset1).
Defect 7: with clip_end 0.5 Cycles renders black; the walks' eye paths (kernels/eye._eye_rows) traced
the camera ray with no far limit and added the light seen through the glass.
"""
from __future__ import annotations

import numpy as np
import pytest

from testkit import scenes
from smbs_addon import BakeSettings, bake
from smbs_addon.baking.plan import make_plan
from smbs_addon.trace.tracer import Tracer


def _ball_over_a_floor(size_m: float):
    sc = scenes.glass_sphere_scene(resolution=(32, 24))
    floor = sc.tri_object == sc.object_names.index("Floor")
    sc.tri_vertices[floor] *= size_m / 10.0
    sc.validate()
    return sc


@pytest.mark.parametrize("size_m", [1e5, 1e6])
def test_a_huge_floor_keeps_the_balls_tolerances(size_m):
    """The offset a ray leaving the ball takes, and which of its triangles count, do not depend on how far
    the floor reaches: as on a 10 m floor, an offset far below the ball's size and no triangle lost."""
    small, huge = _ball_over_a_floor(10.0), _ball_over_a_floor(size_m)
    out = []
    for sc in (small, huge):
        plan = make_plan(sc, "OFF")
        tracer = Tracer(sc, threads=1)
        tracer.set_extent(*plan.bounds, plan.casters)
        ball = sc.tri_object == sc.object_names.index("Ball")
        out.append((tracer.eps, int(tracer.degenerate[ball].sum())))
    (eps_small, lost_small), (eps_huge, lost_huge) = out
    assert lost_small == 0 and lost_huge == 0
    assert eps_huge < 1e-3 * 0.5, f"an offset of {eps_huge:.3g} m off a ball of radius 0.5 m"


def test_clip_end_before_the_glass_shows_nothing():
    sc = scenes.glass_sphere_scene(resolution=(32, 24))
    sc.camera.clip_end = 0.5  # the ball is 3.6 m from the camera: Cycles renders black
    res = bake(sc, BakeSettings(method="sms", spp=2, batches=2, pilots=256))
    assert float(np.max(res.image)) == 0.0


@pytest.mark.parametrize("method", ["auto", "smbs"])
def test_a_huge_floor_bakes_the_balls_caustic_as_a_small_one(method):
    """End to end, through the plan's pilots (their tolerances per view: Tracer.with_extent) and auto's
    pilot bakes (their own tracer): the ball's caustic on a floor of 1000 km is the one on a floor of 10 m.
    The two floors differ in the floor's float32 coordinates only where the camera does not look, so the
    sums agree to noise (measured 1120 against 1150 at 64 x 48, 4 spp); before, the 1000 km floor's was 0."""
    sums = []
    for size_m in (10.0, 1e6):
        res = bake(_ball_over_a_floor(size_m), BakeSettings(method=method, spp=2, batches=2, pilots=512, seed=1))
        sums.append(float(res.image.sum()))
    small, huge = sums
    assert small > 0 and abs(huge - small) < 0.15 * small, sums
