"""Issue 11: the walks' lanes run split over threads (lanes.py), and their results must not
depend on it: one seed gives the same image bit for bit with 1 or 2 threads, for every walk
method and estimator, with one manifold chunk per batch or several, and with the walks (and
the hand-off's cosine bounces) cut in blocks or not."""
import importlib
import threading

import numpy as np
import pytest

from testkit import scenes
from smbs_addon import BakeSettings, bake

bake_module = importlib.import_module("smbs_addon.baking.passes")  # where the chunk sizes are


def _same(a, b):
    return a.image.tobytes() == b.image.tobytes() and a.variance.tobytes() == b.variance.tobytes()


@pytest.mark.parametrize("make, method, estimator", [
    (lambda: scenes.glass_sphere_scene(resolution=(48, 36)), "sms", "unbiased"),
    (lambda: scenes.glass_sphere_scene(resolution=(48, 36)), "smbs", "unbiased"),
    (lambda: scenes.ring_scene(resolution=(48, 36)), "smbs", "unbiased"),
    (lambda: scenes.ring_scene(resolution=(48, 36)), "sms", "biased"),
    (lambda: scenes.glass_sphere_scene(resolution=(48, 36)), "mnee", "unbiased"),
])
def test_same_seed_same_walks_whatever_the_threads(make, method, estimator, monkeypatch):
    s = dict(method=method, estimator=estimator, spp=2, batches=2, seed=5)
    # small parts, so that these small bakes really split every intersect call made from Python
    monkeypatch.setattr(importlib.import_module("smbs_addon.trace.tracer"), "_MIN_SPLIT", 64)
    # and indirect.handoff_gather (the ball seen through itself, first chunk) in blocks of 16 receivers
    monkeypatch.setattr(importlib.import_module("smbs_addon.paths.gather"), "HANDOFF_LANES", 16 * 64)
    a = bake(make(), BakeSettings(**s, threads=1))
    b = bake(make(), BakeSettings(**s, threads=2))
    assert a.stats["rays"] == b.stats["rays"]
    assert _same(a, b)
    assert a.image.max() > 0
    if method != "mnee" and make().object_smooth.any():  # the hand-off ran (MNEE has none), in blocks
        assert a.stats["eye_pass"]["rays_handoff"] > 4 * 16 * 64
    # several chunks per batch (the eye samples split in pieces of 1000): still the same
    monkeypatch.setattr(bake_module, "WALK_CHUNK", 1000)
    c = bake(make(), BakeSettings(**s, threads=1))
    d = bake(make(), BakeSettings(**s, threads=2))
    assert _same(c, d)
    # the walks in blocks of 128 lanes, the Bernoulli trials in blocks of 8 samples and the
    # hand-off in blocks of 7 receivers, that the threads take in turn (lanes.blocks): the image of
    # the uncut walks (the hand-off's random numbers are keyed by receiver and sample), and the same
    # rays whatever the threads
    monkeypatch.setattr(importlib.import_module("smbs_addon.walks.walk"), "WALK_BLOCK", 128)
    monkeypatch.setattr(importlib.import_module("smbs_addon.walks.trials"), "TRIAL_BLOCK", 8)
    monkeypatch.setattr(importlib.import_module("smbs_addon.paths.gather"), "HANDOFF_LANES", 7 * 64)
    e = bake(make(), BakeSettings(**s, threads=1))
    f = bake(make(), BakeSettings(**s, threads=2))
    assert e.stats["rays"] == f.stats["rays"]
    assert _same(e, f) and _same(e, c)
    # a chunk's receivers in parts of 100 (manifold.ESTIMATE_PART), each its own random stream,
    # that the threads take in turn: another image, the same one whatever the threads
    monkeypatch.setattr(importlib.import_module("smbs_addon.walks.manifold"), "ESTIMATE_PART", 100)
    g = bake(make(), BakeSettings(**s, threads=1))
    h = bake(make(), BakeSettings(**s, threads=2))
    assert g.stats["rays"] == h.stats["rays"] and g.image.max() > 0
    assert _same(g, h) and not _same(g, e)
    # the gather after a diffuse bounce (receivers seen through the ball) in halves from 4 receivers on, that
    # the threads take at once (manifold.GATHER_SPLIT), each its own random stream: the same whatever the threads
    monkeypatch.setattr(importlib.import_module("smbs_addon.walks.manifold"), "GATHER_SPLIT", 4)
    i = bake(make(), BakeSettings(**s, threads=1))
    j = bake(make(), BakeSettings(**s, threads=2))
    assert i.stats["rays"] == j.stats["rays"] and _same(i, j)
    if "sphere" in make().name:  # the ball seen through itself: its floor gathers
        assert i.stats["eye_pass"]["rays_gather"] > 0


@pytest.mark.parametrize("make, method", [
    (lambda: scenes.ring_scene(resolution=(48, 36)), "sms"),
    (lambda: scenes.glass_sphere_scene(resolution=(48, 36)), "smbs"),
])
def test_bernoulli_trials_run_exactly_the_trials_each_sample_needs(make, method, monkeypatch):
    """The trials are keyed by (sample, trial) and run one after the other per sample: blocks
    of one sample give the image of the default blocks, and every sample runs exactly the
    trials up to its first success (count = first success + 1), or max_trials if none."""
    trials = importlib.import_module("smbs_addon.walks.trials")
    s = BakeSettings(method=method, spp=2, batches=2, seed=7)
    a = bake(make(), s)
    monkeypatch.setattr(trials, "TRIAL_BLOCK", 1)
    b = bake(make(), s)
    assert a.stats["lights"] and _same(a, b)
    for r in (a, b):
        L = list(r.stats["lights"].values())
        walks = sum(x.get("bernoulli_walks", 0) for x in L)
        counted = sum(x.get("bernoulli_trials", 0) for x in L)
        capped = sum(x.get("capped", 0) for x in L)
        assert walks > 0 and walks == counted - capped


def test_counters_of_a_chunks_parts_add_up_and_its_maxima_stay_maxima(monkeypatch):
    """The parts of a chunk's receivers (manifold.ESTIMATE_PART) count on dicts of their own, added
    to the light's in part order: counts are the parts' sums, the largest Bernoulli count is the
    largest of the parts' (summed, 8 parts would add their maxima), and the light's time is its
    share of the wall time, within the bake's (summed over parts on two threads, the busy time
    would be about twice it)."""
    manifold = importlib.import_module("smbs_addon.walks.manifold")
    lanes = importlib.import_module("smbs_addon.core.lanes")
    monkeypatch.setattr(manifold, "ESTIMATE_PART", 256)
    parts = []
    add = lanes.add_stats

    def spy(into, part):
        # a part's counters (not a photon chunk's, nor a nested dict, nor the sum of a gather block's
        # parts that manifold._gather_after_bounce adds, with their share of the time)
        if "outcomes" in part and "time_s" not in part:
            parts.append(dict(part))
        add(into, part)

    monkeypatch.setattr(lanes, "add_stats", spy)
    res = bake(scenes.glass_sphere_scene(resolution=(48, 36)), BakeSettings(method="sms", spp=4, batches=2, seed=2,
                                                                            threads=2))
    light = res.stats["lights"]["Area"]
    assert len(parts) >= 8
    assert light["walks"] == sum(p["walks"] for p in parts) > 0
    assert light["bernoulli_trials"] == sum(p.get("bernoulli_trials", 0) for p in parts)
    maxima = [p["bernoulli_trials_max"] for p in parts if "bernoulli_trials_max" in p]
    assert len(maxima) >= 8 and light["trials"]["max"] == max(maxima) < sum(maxima)
    assert 0 < light["time_s"] <= res.stats["time_s"]


def test_block_edges_shrink_towards_the_end_and_cover_every_lane():
    """lanes.block_edges: fixed blocks without a minimum; with one, blocks of an eighth of what
    is left, between the minimum and the size, never growing, every lane in exactly one."""
    from smbs_addon.core import lanes

    assert lanes.block_edges(300, 128) == [0, 128, 256, 300]
    assert lanes.block_edges(0, 128, 8) == [0]
    for n in (1, 7, 9, 1000, 5000, 65536):
        e = lanes.block_edges(n, 128, 8)
        sizes = [b - a for a, b in zip(e, e[1:])]
        assert e[0] == 0 and e[-1] == n and all(s > 0 for s in sizes)
        assert max(sizes) <= 128 and all(s >= 8 for s in sizes[:-1])
        assert all(a >= b for a, b in zip(sizes, sizes[1:-1]))  # the last one may be cut short
    assert lanes.block_edges(5000, 128, 8)[:3] == [0, 128, 256]  # full blocks while an eighth of the rest is more


def test_blocks_run_each_block_once_in_order_and_do_not_split_inside():
    """lanes.blocks: every block once, results in block order whichever thread ran it; inside a
    block, lanes.run gives one part (the block's calls stay on its thread); one block is called
    as it is, so the calls inside it may split."""
    from smbs_addon.core import lanes

    seen = []
    out = lanes.blocks(lambda a, b: seen.append((a, b)) or (a, b, lanes.nested()), 10, 3, 2)
    assert out == [(0, 3, True), (3, 6, True), (6, 9, True), (9, 10, True)]
    assert sorted(seen) == [(0, 3), (3, 6), (6, 9), (9, 10)]
    assert lanes.blocks(lambda a, b: (a, b, lanes.nested()), 10, 20, 2) == [(0, 10, False)]
    assert lanes.blocks(lambda a, b: (a, b), 0, 3, 2) == []
    assert lanes.run(lambda a, b: (a, b), 100, 2, 10) == [(0, 50), (50, 100)]
    inner = lanes.blocks(lambda a, b: lanes.run(lambda c, d: (c, d), 100, 2, 10), 20, 10, 2)
    assert inner == [[(0, 100)], [(0, 100)]]
    assert lanes.blocks(lambda a, b: lanes.nested(), 20, 10, 1) == [False, False]  # one thread: no blocks apart
    # whole: blocks that would run in turn on this thread are one call (one thread, or inside a block)
    assert lanes.blocks(lambda a, b: (a, b), 10, 3, 1, whole=True) == [(0, 10)]
    assert lanes.blocks(lambda a, b: (a, b), 10, 3, 2, whole=True) == [(0, 3), (3, 6), (6, 9), (9, 10)]
    inner = lanes.blocks(lambda a, b: lanes.blocks(lambda c, d: (c, d), 10, 3, 2, whole=True), 20, 10, 2)
    assert inner == [[(0, 10)], [(0, 10)]]


def test_scratch_arrays_are_kept_per_thread_and_name_until_freed():
    """lanes.scratch: the same memory again for the same name on the same thread (shaped as asked,
    grown when too small), other memory on another thread or under another name; free_scratch
    lets every thread's go."""
    from smbs_addon.core import lanes

    a = lanes.scratch("t_a", (4, 3))
    assert a.shape == (4, 3) and a.dtype == np.float64
    a[:] = 7.0
    b = lanes.scratch("t_a", (2, 5))  # smaller: the same buffer
    assert b.shape == (2, 5) and np.shares_memory(a, b) and np.all(b == 7.0)
    assert not np.shares_memory(a, lanes.scratch("t_b", (4, 3)))
    assert lanes.scratch("t_a", (4, 3), np.int64).dtype == np.int64  # another dtype: a new buffer
    big = lanes.scratch("t_a", (100, 3))
    assert big.shape == (100, 3) and lanes.scratch("t_a", (100, 3)).ctypes.data == big.ctypes.data
    both = threading.Barrier(2, timeout=30)  # the two blocks on two threads at once

    def block(i, j):
        both.wait()
        return threading.get_ident(), lanes.scratch("t_a", (100, 3)).ctypes.data

    (t0, p0), (t1, p1) = lanes.blocks(block, 2, 1, 2)
    assert t0 != t1 and p0 != p1 and big.ctypes.data in (p0, p1)  # the calling thread's, and the pool's
    lanes.free_scratch()
    assert not np.shares_memory(big, lanes.scratch("t_a", (100, 3)))
    # a thread that has ended leaves no entry behind once scratch is freed
    done = threading.Thread(target=lambda: lanes.scratch("t_a", (10,)))
    done.start()
    done.join()
    assert any(t() is done for t, _ in lanes._SCRATCH)
    lanes.free_scratch()
    assert not any(t() is done for t, _ in lanes._SCRATCH)
    assert any(t() is threading.current_thread() for t, _ in lanes._SCRATCH)


def test_light_tracing_chunks_on_threads_give_the_image_of_chunks_in_turn(monkeypatch):
    """The light tracer's chunks (its photons, the eye pass seen through glass, the indirect
    photons; and the manifold bakes' photon hand-off) run as many at a time as there are
    threads, each splatting into a deferred film (passes.threaded_chunks): the splats are made in
    chunk order, so 1 and 2 threads give one image, bit for bit, and the same counts. Chunks of
    500 lanes: a small bake runs several chunks per pass."""
    monkeypatch.setattr(bake_module, "CHUNK", 500)
    ball = lambda: scenes.glass_sphere_scene(resolution=(32, 24))  # noqa: E731
    for method in ("reference", "smbs"):
        s = dict(method=method, spp=4, batches=2, seed=3)
        a = bake(ball(), BakeSettings(**s, threads=1))
        b = bake(ball(), BakeSettings(**s, threads=2))
        assert _same(a, b) and a.image.max() > 0
        assert a.stats["rays"] == b.stats["rays"]
        light = a.stats["lights"]["Area"]
        other = b.stats["lights"]["Area"]
        if method == "reference":
            assert light["photons"] > 2 * 500 and light["photons"] == other["photons"]
            assert a.stats["eye_pass"]["enabled"] is True  # the bake's own flag, untouched by the chunks' counts
        else:
            assert light["handoff"]["photons"] > 2 * 500 and light["handoff"] == other["handoff"]


def test_one_chunks_photons_split_over_threads_give_the_records_of_one_call(monkeypatch):
    """A light-tracing chunk that runs alone (a low-spp batch is one chunk) splits its photons and
    then its records over the threads (reference.run_photons, splat_records: parts of the lanes,
    random numbers keyed by lane, records and splats joined in lane order): the image and the
    counts of one call, bit for bit. (A manifold bake's photon hand-off runs beside its walks
    instead, unsplit: the next test.)"""
    reference = importlib.import_module("smbs_addon.paths.photons")
    ball = lambda: scenes.glass_sphere_scene(resolution=(32, 24))  # noqa: E731
    for method in ("reference",):
        s = dict(method=method, spp=2, batches=1, seed=6)
        monkeypatch.setattr(reference, "PHOTON_SPLIT", 10**9)
        whole = bake(ball(), BakeSettings(**s, threads=2))
        monkeypatch.setattr(reference, "PHOTON_SPLIT", 64)
        calls = []
        run = reference.photon_lanes

        def spy(rt, batch, key, lane0, *a):
            calls.append(lane0)  # the first lane of the call
            return run(rt, batch, key, lane0, *a)

        monkeypatch.setattr(reference, "photon_lanes", spy)
        split = bake(ball(), BakeSettings(**s, threads=2))
        monkeypatch.setattr(reference, "photon_lanes", run)
        assert any(c > 0 for c in calls), "no chunk was split"
        assert _same(whole, split) and whole.image.max() > 0
        assert whole.stats["rays"] == split.stats["rays"]
        a, b = whole.stats["lights"]["Area"], split.stats["lights"]["Area"]
        a, b = (a, b) if method == "reference" else (a["handoff"], b["handoff"])
        assert a["photons"] > 2 * 64 and {k: v for k, v in a.items() if k != "time_s"} == {
            k: v for k, v in b.items() if k != "time_s"}


def _conformance():
    """testkit/conformance.py (its scenes are built with bpy)."""
    return importlib.import_module("testkit.conformance")


@pytest.mark.parametrize("make, methods", [
    (lambda: scenes.glass_sphere_scene(resolution=(32, 24)), ("reference", "sms", "smbs", "mnee", "auto")),
    (lambda: scenes.ring_scene(resolution=(32, 24)), ("reference", "auto")),
    pytest.param(lambda: _conformance().scene_arrays("cube_grey_reflect"), ("reference", "sms"),
                 marks=pytest.mark.bpy),
], ids=["glass sphere", "ring", "cube_grey_reflect"])
def test_a_bakes_rays_are_every_ray_its_tracers_cast(make, methods, monkeypatch):
    """stats["rays"] (the panel's Rays, the throughput benchmark's count) is every ray the bake's
    tracers cast, exactly: the light tracer's look for mirrors and glass in view (one ray per
    pixel) and auto's pilot bakes (a tracer of their own each) were left out; the pilot's were
    2.7x the rays the glass sphere's auto bake reported. The bent passes (cube_grey_reflect:
    Bump Map Correction) count too."""
    tracer = importlib.import_module("smbs_addon.trace.tracer")
    made = []
    init = tracer.Tracer.__init__

    def spy(self, *a, **k):
        init(self, *a, **k)
        made.append(self)

    monkeypatch.setattr(tracer.Tracer, "__init__", spy)
    for method in methods:
        made.clear()
        res = bake(make(), BakeSettings(method=method, spp=2, batches=2, seed=1))
        cast = sum(t.rays_cast for t in made)
        assert res.stats["rays"] == cast > 0, (method, res.stats["rays"], cast)
        if method == "auto":
            assert len(made) > 1 and res.stats["auto"]["rays"] > 0
        if res.stats["scene"] == "cube_grey_reflect":  # every method's bent pass in the eye pass's "bent" part
            assert res.stats["eye_pass"]["bent"]["rays_bent"] > 0 and "rays_bent" not in res.stats["eye_pass"]


def test_the_photon_hand_off_runs_beside_the_walks_with_the_image_and_counts_of_one_thread(monkeypatch):
    """With two threads a manifold bake's photon hand-off runs on a thread of its own beside each
    batch's walks (lanes.beside: at low spp a batch's photons are one chunk, whose numpy ran on one
    thread while the other waited), its splats made after the walks' and its counters added then:
    the image, the rays and the hand-off's counts of one thread, bit for bit."""
    lanes = importlib.import_module("smbs_addon.core.lanes")
    calls, beside = [], lanes.beside

    def spy(fn):
        calls.append(threading.current_thread().name)
        return beside(fn)

    monkeypatch.setattr(lanes, "beside", spy)
    for make, method in ((lambda: scenes.glass_sphere_scene(resolution=(32, 24)), "sms"),
                         (lambda: scenes.ring_scene(resolution=(32, 24)), "smbs")):
        s = dict(method=method, spp=2, batches=2, seed=6)
        a = bake(make(), BakeSettings(**s, threads=1))
        assert not calls
        b = bake(make(), BakeSettings(**s, threads=2))
        assert len(calls) == 2  # one per batch
        calls.clear()
        assert _same(a, b) and a.image.max() > 0
        assert a.stats["rays"] == b.stats["rays"]
        ha, hb = ([L["handoff"] for L in r.stats["lights"].values()] for r in (a, b))
        assert ha == hb and sum(h["photons"] for h in ha) > 0
