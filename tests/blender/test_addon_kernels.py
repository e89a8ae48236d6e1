"""Prepare Kernels (operators/kernels.py): the core's kernels compiled before the first bake,
in Blender's process (under the name Blender imports the extension by), the scene untouched.

A cold cache is minutes of compiling, so these runs mostly find the kernels compiled (the
addon tests before them baked under the same name); what they check is that the operator makes
prepare's bakes in both of its ways and reports, and that the modal one is a bake-like job."""
import importlib

import pytest

bpy = pytest.importorskip("bpy")

from testkit.addon import Reports, draw_all, run_to_end, scene_state  # noqa: E402
from testkit.blend import mirror_scene  # noqa: E402


@pytest.fixture
def ops(empty_bpy, addon):
    return (importlib.import_module(addon.__name__ + ".operators.kernels"),
            importlib.import_module(addon.__name__ + ".operators.bake"))


def test_prepare_kernels_in_background_reports_and_changes_nothing(ops, capsys):
    kernels, _ = ops
    scene = mirror_scene(16, 12)
    before = scene_state(scene)
    assert bpy.ops.smbs.prepare_kernels() == {'FINISHED'}
    assert scene_state(scene) == before
    out = capsys.readouterr().out
    assert "SMBS Caustics: the kernels were compiled already" in out or "SMBS Caustics: compiled " in out
    assert kernels.message({"kernels": 0, "seconds": 3.0}).endswith("bakes load them from the cache")
    assert kernels.message({"kernels": 31, "seconds": 140.4}) == (
        "SMBS Caustics: compiled 31 kernels in 140 s; bakes on this machine load them from the cache")


def test_the_processes_compile_under_the_extensions_name(ops):
    """prepare's processes import the core as Blender's process does (here smbs_caustics.smbs_addon,
    in Blender bl_ext.<repo>.smbs_caustics.smbs_addon), from the same folder, without running the
    extension's __init__ (it imports bpy): numba's disk cache is kept per name, so kernels compiled
    under another name would not serve the bakes."""
    prep = importlib.import_module(ops[0].__name__.rpartition(".")[0].rpartition(".")[0] + ".smbs_addon.baking.prepare")
    said = []
    out = prep.prepare(jobs=2, say=said.append)
    assert out["jobs"] == 2 and out["as"] == "smbs_caustics.smbs_addon.baking.prepare"
    assert len([x for x in said if x.startswith(("[1/2] bake ", "[2/2] bake "))]) == len(prep.BAKES), said


def test_prepare_kernels_runs_like_a_bake_in_the_interface(ops):
    """The modal way: a worker thread waiting for the processes, with progress ("compiling the
    kernels in 2 processes: i of n bakes done"), one job per scene at a time, ended by the timer
    with a report; Esc stops it like a bake (the processes killed)."""
    kernels, bake_op = ops
    scene = mirror_scene(16, 12)
    before = scene_state(scene)
    reports = Reports()
    job = bake_op.ModalBake(reports, kernels.PrepareTask())
    assert job.start(bpy.context)
    assert bake_op.running_bake(scene) is job and not bpy.ops.smbs.bake_caustics.poll()
    result, texts = run_to_end(job, 900)
    assert result == {'FINISHED'}, reports
    assert all(t.startswith("SMBS Caustics: Kernel preparation: ") for t in texts if t), texts
    assert reports.of('INFO') and reports.of('INFO')[0].startswith("SMBS Caustics: ")
    assert bake_op.running_bake(scene) is None and scene_state(scene) == before

    cancelled = bake_op.ModalBake(Reports(), kernels.PrepareTask())
    assert cancelled.start(bpy.context)
    assert cancelled.step(bpy.context, 'ESC', 'PRESS') == {'CANCELLED'}
    assert bake_op.running_bake(scene) is None and scene_state(scene) == before


def test_the_panel_says_whether_the_kernels_are_compiled(ops, addon, monkeypatch):
    """The Advanced panel says above Prepare Kernels whether the kernels are compiled for this
    machine (prepare.ready, under the extension's name: compiled once Prepare Kernels has run),
    and says nothing where it cannot tell. The answer is read once per STATE_RECHECK_S (panels
    redraw often) and afresh after Prepare Kernels."""
    kernels, _ = ops
    panels = addon.ui.panels
    prep = importlib.import_module(addon.__name__ + ".smbs_addon.baking.prepare")
    labels = {panels.KERNELS_READY, panels.KERNELS_NOT_READY}
    kernels.state()  # an answer kept from before ...
    assert bpy.ops.smbs.prepare_kernels() == {'FINISHED'}  # ... forgotten here
    assert prep.ready() is True
    for answer, want in ((True, panels.KERNELS_READY), (False, panels.KERNELS_NOT_READY), (None, None)):
        calls = []
        if answer is not True:
            monkeypatch.setattr(prep, "ready", lambda a=answer: calls.append(a) or a)
            kernels.forget_state()
        drawn = []
        for _ in range(3):
            draw_all(addon, bpy.context.scene, drawn)
        assert labels & set(drawn) == ({want} if want else set()), drawn
        assert "smbs.prepare_kernels" in drawn
        assert len(calls) == (0 if answer is True else 1)  # read once, not once per draw
