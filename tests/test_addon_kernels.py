"""Prepare Kernels (operators/kernels.py): the core's kernels compiled before the first bake,
in Blender's process (under the name Blender imports the extension by), the scene untouched.

A cold cache is minutes of compiling, so these runs mostly find the kernels compiled (the
addon tests before them baked under the same name); what they check is that the operator makes
prepare's bakes in both of its ways and reports, and that the modal one is a bake-like job."""
import importlib

import pytest

from test_addon_modal import _Reports, _run_to_end, _scene_state
from test_addon_register import _mirror_scene

bpy = pytest.importorskip("bpy")


@pytest.fixture
def ops(empty_bpy, addon):
    return (importlib.import_module(addon.__name__ + ".operators.kernels"),
            importlib.import_module(addon.__name__ + ".operators.bake"))


def test_prepare_kernels_in_background_reports_and_changes_nothing(ops, capsys):
    kernels, _ = ops
    scene = _mirror_scene(16, 12)
    before = _scene_state(scene)
    assert bpy.ops.smbs.prepare_kernels() == {'FINISHED'}
    assert _scene_state(scene) == before
    out = capsys.readouterr().out
    assert "SMBS Caustics: the kernels were compiled already" in out or "SMBS Caustics: compiled " in out
    assert kernels.message({"kernels": 0, "compile_s": 0.0}).endswith("bakes load them from the cache")
    assert kernels.message({"kernels": 31, "compile_s": 140.4}) == (
        "SMBS Caustics: compiled 31 kernels in 140 s; bakes on this machine load them from the cache")


def test_prepare_kernels_runs_like_a_bake_in_the_interface(ops):
    """The modal way: a worker thread with progress ("compiling the kernels: bake i of n"), one
    job per scene at a time, ended by the timer with a report; Esc stops it like a bake."""
    kernels, bake_op = ops
    scene = _mirror_scene(16, 12)
    before = _scene_state(scene)
    reports = _Reports()
    job = bake_op.ModalBake(reports, kernels.PrepareTask())
    assert job.start(bpy.context)
    assert bake_op.running_bake(scene) is job and not bpy.ops.smbs.bake_caustics.poll()
    result, texts = _run_to_end(job, 900)
    assert result == {'FINISHED'}, reports
    assert all(t.startswith("SMBS Caustics: Kernel preparation: ") for t in texts if t), texts
    assert reports.of('INFO') and reports.of('INFO')[0].startswith("SMBS Caustics: ")
    assert bake_op.running_bake(scene) is None and _scene_state(scene) == before

    cancelled = bake_op.ModalBake(_Reports(), kernels.PrepareTask())
    assert cancelled.start(bpy.context)
    assert cancelled.step(bpy.context, 'ESC', 'PRESS') == {'CANCELLED'}
    assert bake_op.running_bake(scene) is None and _scene_state(scene) == before
