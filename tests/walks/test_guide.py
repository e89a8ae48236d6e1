"""The photon pre-pass's guide (smbs_addon/guide.py): where walks start for sure and where
only by Russian roulette (probability Q, weighted 1/Q, so the estimate stays unbiased)."""
import numpy as np

from testkit import scenes
from smbs_addon import BakeSettings, bake
from smbs_addon.trace.camera import CameraModel
from smbs_addon.walks.guide import Q, TILE, Guide


def _guide_with_one_tile():
    """A guide for a 64 x 48 frame whose only marked tile holds raster (30, 20)."""
    cam = CameraModel(scenes.glass_sphere_scene(resolution=(64, 48)).camera)
    x0, x1, y0, y1 = cam.region
    g = Guide(cam, {}, {})
    m = np.zeros(((y1 - y0 + 2 * TILE) // TILE + 2, (x1 - x0 + 2 * TILE) // TILE + 2), bool)
    m[int((20 - g.ty0) // TILE), int((30 - g.tx0) // TILE)] = True
    g.masks[(0, "TT")] = m
    return cam, g


def _point_at(cam, rx, ry, depth=2.0):
    o, d, _ = cam.rays(np.array([rx]), np.array([ry]))
    return o + depth * d


def test_receivers_seen_through_glass_are_looked_up_where_they_are():
    """A receiver seen directly is looked up at its pixel. One seen through mirrors or glass
    is looked up where its own point projects: walked for sure there when photons marked
    it, by roulette when they did not, whatever pixel shows it; and always walked when
    the point projects where the pre-pass did not look (behind the camera)."""
    cam, g = _guide_with_one_tile()
    marked, unmarked = _point_at(cam, 30.5, 20.5), _point_at(cam, 10.5, 40.5)
    behind = cam.origin - 3.0 * (marked - cam.origin)
    pts = np.concatenate([marked, unmarked, marked, unmarked, behind, marked])
    rx = np.array([30.5, 30.5, 10.5, 30.5, 30.5, 10.5])  # the pixels showing them
    ry = np.array([20.5, 20.5, 40.5, 20.5, 20.5, 40.5])
    spec = np.array([0, 0, 0, 1, 1, 2])
    q = g.keep_probability(0, "TT", rx, ry, spec, pts)
    assert q.tolist() == [1.0, 1.0, Q, Q, 1.0, 1.0]
    # without the points, those seen through glass are always walked
    assert g.keep_probability(0, "TT", rx, ry, spec).tolist() == [1.0, 1.0, Q, 1.0, 1.0, 1.0]
    assert g.keep_probability(0, "R", rx, ry, spec, pts).tolist() == [1.0] * 6  # no mask: no guide


def test_guide_skips_walks_seen_through_glass_without_changing_the_mean():
    """The floor seen through a glass ball: with the guide, walks through the ball start
    by roulette where no photon landed, and the caustic seen through the ball keeps its
    mean (guided against unguided, within 3 combined standard errors)."""
    scene = scenes.glass_sphere_scene(resolution=(40, 30), height=0.9)
    runs = {}
    for guide in (True, False):
        runs[guide] = bake(scene, BakeSettings(method="sms", spp=8, batches=8, seed=4, guide=guide))
    st = runs[True].stats["lights"]["Area"]
    assert st["guided_skips_seen"] > 0
    assert "guided_skips_seen" not in runs[False].stats["lights"]["Area"]
    from smbs_addon.baking import auto
    from smbs_addon.baking.plan import make_plan
    from smbs_addon.trace.tracer import Tracer
    cam = CameraModel(scene.camera)
    seen = ~auto._direct_pixels(scene, Tracer(scene), cam, make_plan(scene))
    means = []
    for res in runs.values():
        b = res.batch_luminance[:, seen].mean(axis=1)
        means.append((b.mean(), b.std(ddof=1) / np.sqrt(len(b))))
    (m1, s1), (m0, s0) = means
    assert m0 > 0
    assert abs(m1 - m0) < 3 * np.hypot(s1, s0), (m1, m0, s1, s0)


def test_a_faint_wide_glow_is_weak_on_every_random_stream():
    """The glass ball's reflection (R) is a wide glow under 1% of its refracted focus (TT),
    tile for tile, averaged over 3 x 3 tiles. Its brightest single tile read 0.023-0.091 of the
    focus's over seeds 1-8 at 512 x 512 (few photons per tile: the tile they happened to crowd),
    so the noise decided whether the walks or the photons served it (walks 390k against 227k
    on one 1-spp bake). Averaged, it reads 0.006-0.012: weak on every seed, with room to spare."""
    from smbs_addon.baking.engine import trace_plan
    from smbs_addon.core.random import stream
    from smbs_addon.walks.guide import WEAK_PEAK, build_guide, photon_budget
    from smbs_addon.walks.manifold import chain_types
    from smbs_addon.baking.plan import make_plan

    scene = scenes.glass_sphere_scene(resolution=(512, 384))
    settings = BakeSettings(method="sms", spp=1, seed=1)
    plan, cam = make_plan(scene, settings.use_cycles_flags), CameraModel(scene.camera)
    tracer = trace_plan(plan, scene, settings, cam)
    types = chain_types(scene, plan, settings.manifold_options())
    assert "R" in types and "TT" in types
    peaks = []
    for seed in range(1, 5):
        _, stats, weak = build_guide(scene, tracer, cam, plan, types, stream(seed, 3, 0), photon_budget(cam))
        peak = stats["peak_share"]["Area"]
        assert peak["TT"] == 1.0 and (0, "TT") not in weak
        assert (0, "R") in weak
        peaks.append(peak["R"])
    assert max(peaks) < WEAK_PEAK / 2, peaks
