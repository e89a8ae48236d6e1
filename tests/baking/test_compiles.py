"""What compiling the kernels costs a bake (smbs_addon/compiles.py): the first bake after
installing or updating compiles, later ones load from the cache. The time is counted once per
outermost compile, reported while it runs, and left out of the price of more batches."""
import numpy as np
from numba import njit

from smbs_addon import BakeSettings, bake
from smbs_addon.cli.report import summary_lines
from smbs_addon.baking.bake import _Reporter
from smbs_addon.core.compiles import CompileWatch

from testkit import scenes


def _fresh_kernel():
    """A kernel nobody has compiled (no cache), calling a helper that compiles inside it."""

    @njit
    def helper(x):
        s = 0.0
        for i in range(10):
            s += np.sin(x * i) / (i + 1.0)
        return s

    @njit
    def kernel(x):
        return helper(x) + helper(2.0 * x)

    return kernel


class _CompilingProgress(list):
    """A progress callback that keeps the messages and compiles a fresh kernel at its second
    call (between two chunks of the first batch, while the bake's watch is on)."""

    def __init__(self):
        super().__init__()
        self.kernel = _fresh_kernel()

    def __call__(self, fraction, message=""):
        self.append(message)
        if len(self) == 2:
            self.kernel(1.0)


def test_watch_counts_each_outermost_compile_once():
    kernel = _fresh_kernel()
    calls = []
    with CompileWatch(on_start=lambda: calls.append("start"), on_end=lambda: calls.append("end")) as watch:
        kernel(1.0)
        assert (watch.kernels, calls) == (1, ["start", "end"])  # the helper compiled inside it
        first = watch.seconds
        assert first > 0.0
        kernel(3.0)  # compiled: no compile
        assert (watch.kernels, watch.seconds, watch.now()) == (1, first, first)
        kernel(np.float32(1.0))  # a new signature compiles again
        assert watch.kernels == 2 and watch.seconds > first
    kernel(np.int64(2))  # after the watch: not counted
    assert watch.kernels == 2 and calls == ["start", "end"] * 2


def test_reporter_says_compiling_and_gives_the_message_back():
    said = []
    report = _Reporter(lambda f, m="": said.append((f, m)))
    report(0.25, "light 'Key': walks")
    report.compiling()
    report.compiled()
    assert said == [(0.25, "light 'Key': walks"), (0.25, _Reporter.COMPILING), (0.25, "light 'Key': walks")]
    _Reporter(None).compiling()  # no callback: nothing to say, nothing raised


def test_a_bake_that_compiles_says_so_and_leaves_it_out_of_the_batches_clock():
    """A kernel compiled in the middle of a bake (here by its progress callback, between two
    chunks of the first batch): progress says the bake is compiling, stats count it, and the
    batches' clock (the film's batch ends, from which the price of more batches is measured)
    does not: the last batch ends before time_s - compile_s, which it could not if the compile,
    inside the first batch, were on that clock."""
    said = progress = _CompilingProgress()
    sc = scenes.glass_sphere_scene(resolution=(48, 36))
    warm = bake(sc, BakeSettings(method="reference", spp=2, batches=2, seed=4))  # the bake's own kernels
    res = bake(sc, BakeSettings(method="reference", spp=2, batches=2, seed=4), progress=progress)
    st = res.stats
    assert _Reporter.COMPILING in said and said[said.index(_Reporter.COMPILING) + 1] == said[1]
    assert st["kernels_compiled"] == 1 and st["compile_s"] > 0.0
    assert st["convergence"]["last_batch_end_s"] <= st["time_s"] - st["compile_s"]
    assert st["convergence"]["setup_s"] < st["convergence"]["last_batch_end_s"]
    line = [x for x in summary_lines(st) if "compiling" in x]
    assert line == [f"  of which compiling the kernels for this machine: {st['compile_s']:.1f} s (1 kernel; "
                    "once after installing or updating, later bakes load them from the cache)"]
    again = bake(sc, BakeSettings(method="reference", spp=2, batches=2, seed=4))
    assert again.stats["compile_s"] == 0.0 and again.stats["kernels_compiled"] == 0
    assert not [x for x in summary_lines(again.stats) if "compiling" in x]
    np.testing.assert_array_equal(again.image, res.image)  # compiling changes nothing in the image
    np.testing.assert_array_equal(warm.image, res.image)


def test_a_time_budget_is_spent_baking_not_compiling():
    """Stop By Time on a first bake: the budget's seconds go to batches; compiling (here a kernel
    compiled inside the first batch) comes on top, as compile_s, so the image is what the budget
    buys on later bakes."""
    progress = _CompilingProgress()
    sc = scenes.glass_sphere_scene(resolution=(48, 36))
    bake(sc, BakeSettings(method="reference", spp=1, batches=1, seed=4))  # the bake's own kernels
    res = bake(sc, BakeSettings(method="reference", spp=1, batches=1, seed=4, time_budget=1.0), progress=progress)
    st = res.stats
    assert st["stopped_by"] == "time" and st["kernels_compiled"] == 1 and st["compile_s"] > 0.0
    assert st["time_s"] - st["compile_s"] >= 0.9, (st["time_s"], st["compile_s"])


def test_compare_gives_a_method_that_compiles_its_seconds_and_says_so():
    """Equal time stays equal when the first method's bake compiles (here a kernel compiled in its
    first batch): its row's time and budget leave the compiling out, and the table says so."""
    import dataclasses

    from smbs_addon.baking.compare import compare, table_lines

    bake_progress = _CompilingProgress()
    sc = scenes.glass_sphere_scene(resolution=(48, 36))
    settings = BakeSettings(method="reference", spp=2, batches=2, seed=4)
    for m in ("reference", "smbs"):
        bake(sc, dataclasses.replace(settings, method=m))  # the bakes' own kernels
    rep = compare(sc, ["reference", "smbs"], 0.5, dataclasses.replace(settings, spp=2), bake_progress=bake_progress)
    first, second = rep["rows"]
    # (how long the compiling took is the machine's: 0.09 s once on a fresh clone's CI)
    assert first["compile_s"] > 0.0 and second["compile_s"] == 0.0
    st = rep["results"]["reference"].stats
    assert first["time_s"] == st["time_s"] - st["compile_s"]
    assert first["time_s"] >= 0.5 * 0.9  # the budget went to baking
    assert (f"reference also compiled kernels for {first['compile_s']:.1f} s (the first bake after installing or "
            "updating), left out of its time and of its budget") in table_lines(rep)
