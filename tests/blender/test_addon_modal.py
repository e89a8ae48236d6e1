"""The interactive bake: a worker thread that touches only numpy, polled by the modal
operator's timer, stopped by Esc or the Cancel button with the scene left as it was.

There is no window in the bpy module (no event loop, no modal handlers), so these
tests drive the operator's state machine (``ModalBake``) with the events the
modal operator would pass it.
"""
import importlib
import time

import pytest

bpy = pytest.importorskip("bpy")

from testkit.addon import LAYER, Reports, layer_images, run_to_end, scene_state  # noqa: E402
from testkit.blend import mirror_scene  # noqa: E402
from testkit.extension import load_extension  # noqa: E402


@pytest.fixture
def bake_op(empty_bpy, addon):
    return importlib.import_module(addon.__name__ + ".operators.bake")


def _long_bake(scene, tmp_path):
    """Settings for a bake that takes far longer than the tests wait."""
    s = scene.smbs_caustics
    s.method, s.spp, s.batches, s.seed = "smbs", 4096, 64, 3
    s.output_path = str(tmp_path / "layer.exr")


def _wait_for_progress(bake, timeout=60.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end and bake.job.status()[0] == 0.0 and not bake.job.done:
        time.sleep(0.02)
    assert not bake.job.done, bake.job.error
    return bake.job.status()


def test_worker_thread_is_cancelled_between_chunks(bake_op, tmp_path):
    """BakeJob runs the core in a thread, reports its progress and stops on cancel()."""
    core = bake_op._core()
    scene = mirror_scene(48, 32)
    _long_bake(scene, tmp_path)
    prep = bake_op.prepare(bpy.context, core)
    job = bake_op.BakeJob(core.bake, prep.data, prep.settings).start()
    end = time.monotonic() + 60
    while job.status()[0] == 0.0 and not job.done and time.monotonic() < end:
        time.sleep(0.02)
    fraction, message = job.status()
    assert 0.0 < fraction < 0.5 and "batch" in message
    t0 = time.monotonic()
    job.cancel()
    assert job.wait(30.0)
    print(f"worker stopped {time.monotonic() - t0:.3f} s after cancel() at {fraction:.1%}")
    assert isinstance(job.error, core.BakeCancelled) and job.result is None


def test_modal_bake_runs_to_the_end(bake_op, tmp_path):
    scene = mirror_scene(24, 16)
    s = scene.smbs_caustics
    s.method, s.spp, s.batches = "reference", 2, 4
    s.output_path = str(tmp_path / "layer.exr")
    reports = Reports()
    bake = bake_op.ModalBake(reports)
    assert bake.start(bpy.context)
    assert bake_op.running_bake(scene) is bake
    assert not bpy.ops.smbs.bake_caustics.poll()  # one bake per scene at a time
    assert bpy.ops.smbs.cancel_bake.poll()
    assert bake.step(bpy.context, 'MOUSEMOVE') == {'PASS_THROUGH'}  # the interface stays live
    result, texts = run_to_end(bake, 120)
    assert result == {'FINISHED'}, reports
    assert any("%" in t and "Esc to cancel" in t for t in texts), texts
    assert bake_op.running_bake(scene) is None and bpy.ops.smbs.bake_caustics.poll()
    assert (tmp_path / "layer.exr").is_file() and (tmp_path / "layer.json").is_file()
    assert [im.name for im in layer_images()] == [LAYER]
    assert "Disk" in s.last_stats
    assert reports.of('INFO') and not reports.of('ERROR')


@pytest.mark.parametrize("how", ["esc", "button"])
def test_modal_bake_cancel_leaves_the_scene_as_it_was(bake_op, tmp_path, how):
    scene = mirror_scene(48, 32)
    _long_bake(scene, tmp_path)
    before = scene_state(scene)
    reports = Reports()
    bake = bake_op.ModalBake(reports)
    assert bake.start(bpy.context)
    assert bake.step(bpy.context, 'TIMER') == {'PASS_THROUGH'}
    _wait_for_progress(bake)
    job = bake.job
    if how == "esc":
        result = bake.step(bpy.context, 'ESC', 'PRESS')
    else:
        assert bpy.ops.smbs.cancel_bake() == {'FINISHED'}
        result = bake.step(bpy.context, 'TIMER')
    assert result == {'CANCELLED'}
    assert job.wait(30.0) and job.result is None
    assert reports.of('WARNING') == ["Caustics bake cancelled; nothing was changed"]
    assert scene_state(scene) == before
    assert not (tmp_path / "layer.exr").exists()
    assert bake_op.running_bake(scene) is None


def test_modal_bake_reports_scene_errors(bake_op, tmp_path):
    """An error found by the core in the worker thread (here: a film too big) reaches the reports."""
    scene = mirror_scene()
    scene.render.resolution_x, scene.render.resolution_y = 16000, 9000
    scene.smbs_caustics.output_path = str(tmp_path / "layer.exr")
    before = scene_state(scene)
    reports = Reports()
    bake = bake_op.ModalBake(reports)
    assert bake.start(bpy.context)
    assert bake.job.wait(60.0)
    assert bake.step(bpy.context, 'TIMER') == {'CANCELLED'}
    (error,) = reports.of('ERROR')
    assert "caustic layer needs about" in error, reports
    assert scene_state(scene) == before and bake_op.running_bake(scene) is None


def test_unregister_stops_a_running_bake(empty_bpy, tmp_path):
    extension = load_extension()
    extension.register()
    try:
        bake_op = importlib.import_module(extension.__name__ + ".operators.bake")
        scene = mirror_scene(48, 32)
        _long_bake(scene, tmp_path)
        bake = bake_op.ModalBake(Reports())
        assert bake.start(bpy.context)
    finally:
        extension.unregister()
    assert bake.job.cancelled and bake.job.wait(30.0)
    assert not bake_op._running
