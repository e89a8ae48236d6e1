"""Bake Frame Range in Blender (issue 58): the frames one after another, Cancel keeping the frames
done and writing nothing of the frame under way, the layer an image sequence in the compositor (a
render of frame 2 composites frame 2's layer), and Bake Caustics on one frame of it replacing only
that frame. Driven as test_addon_modal.py drives the modal bake (the bpy module has no window)."""
import importlib
import math
import time

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from testkit.addon import LAYER, Reports, run_to_end  # noqa: E402
from testkit.blend import keys_linear, mirror_scene  # noqa: E402
from testkit.faults import temporaries  # noqa: E402


@pytest.fixture
def ops(empty_bpy, addon):
    return (importlib.import_module(addon.__name__ + ".operators.frames"),
            importlib.import_module(addon.__name__ + ".smbs_addon.io.exr"))


def _moving_mirror(tmp_path):
    """The test kit's mirror at 24 x 16, its light sliding 0.3 m a frame over frames 1-3 (the spot on the
    floor moves), saved, the layer's Output in tmp_path."""
    scene = mirror_scene(width=24, height=16)
    keys_linear(bpy.data.objects["Disk"], "location", {1: (-2.0, 0.0, 1.5), 3: (-2.0, 0.6, 1.5)})
    scene.frame_start, scene.frame_end = 1, 3
    scene.frame_set(2)
    s = scene.smbs_caustics
    s.method, s.spp, s.batches, s.seed, s.use_cycles_flags = "reference", 2, 2, 1, "OFF"
    s.output_path = "//layer.exr"
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "moving.blend"))
    return bpy.context.scene


def _frame_files(tmp_path):
    return sorted(p.name for p in tmp_path.glob("layer_*.exr"))


def test_cancel_after_the_first_frame_keeps_it(ops, tmp_path):
    frames, _ = ops
    running_bake = importlib.import_module(frames.__package__ + ".bake").running_bake
    scene = _moving_mirror(tmp_path)
    reports = Reports()
    rb = frames.RangeBake(reports)
    assert rb.start(bpy.context) and rb.frames == [1, 2, 3]
    assert running_bake(scene) is rb and not bpy.ops.smbs.bake_frame_range.poll()
    end = time.monotonic() + 120
    while not rb.done and time.monotonic() < end:  # the first frame, quick
        assert rb.step(bpy.context, 'TIMER') == {'PASS_THROUGH'}, reports
        time.sleep(0.01)
    assert rb.done == [1] and rb.job is not None
    rb.cancel()  # the panel's Cancel, while frame 2 bakes (a frame is written on the main thread only)
    assert rb.step(bpy.context, 'TIMER') == {'CANCELLED'}
    assert any("cancelled: frames 1-1 kept; frame 2 was not written" in m for m in reports.of('WARNING')), reports
    assert _frame_files(tmp_path) == ["layer_0001.exr"] and temporaries(tmp_path) == []
    assert (tmp_path / "layer_0001.json").is_file() and not (tmp_path / "layer_0002.json").exists()
    assert scene.frame_current == 2 and running_bake(scene) is None
    img = bpy.data.images[LAYER]
    assert img.source == 'SEQUENCE' and (img["smbs_caustics_sequence"]["first"], img["smbs_caustics_sequence"]["last"]) == (1, 1)


def _render(scene, path, compositing):
    scene.render.use_compositing = compositing
    scene.render.filepath = str(path)
    s = scene.render.image_settings
    s.file_format, s.color_depth, s.color_mode = "OPEN_EXR", "32", "RGB"
    bpy.ops.render.render(write_still=True)


def test_a_range_composites_each_frame_with_its_own_layer(ops, tmp_path):
    frames, exr = ops
    scene = _moving_mirror(tmp_path)
    reports = Reports()
    rb = frames.RangeBake(reports)
    assert rb.start(bpy.context)
    seen = [rb.status()]
    while rb.i < 1:  # progress over the frames: once frame 1 is written, frame 2's bake is under way
        assert rb.step(bpy.context, 'TIMER') == {'PASS_THROUGH'}, reports
        seen.append(rb.status())
        time.sleep(0.01)
    (f1, m1), (f2, m2) = seen[0], seen[-1]
    assert f1 < 1 / 3 and m1.startswith("frame 1 (1/3): ") and 1 / 3 <= f2 < 2 / 3 and m2.startswith("frame 2 (2/3): ")
    result, _ = run_to_end(rb, 300)
    assert result == {'FINISHED'}, reports
    assert _frame_files(tmp_path) == ["layer_0001.exr", "layer_0002.exr", "layer_0003.exr"]
    layers = {f: exr.read_exr(tmp_path / f"layer_{f:04d}.exr")[0] for f in (1, 2, 3)}
    assert not np.array_equal(layers[1], layers[3])  # the spot moved
    assert [exr.read_header(tmp_path / f"layer_{f:04d}.exr")["frame"] for f in (1, 2, 3)] == [1, 2, 3]
    img = bpy.data.images[LAYER]
    assert img.source == 'SEQUENCE' and bpy.path.abspath(img.filepath) == str(tmp_path / "layer_0001.exr")
    (node,) = [n for n in scene.compositing_node_group.nodes if n.get("smbs_caustics") == "image"]
    assert (node.frame_start, node.frame_duration, node.frame_offset) == (1, 3, 0)
    assert scene.frame_current == 2 and any("Frames 1-3 baked" in m for m in reports.of('INFO'))

    # a render of frame 2 composites frame 2's layer: with compositing on, less the render alone
    scene.render.engine = "CYCLES"
    scene.cycles.samples, scene.cycles.use_denoising, scene.cycles.device = 4, False, "CPU"
    scene.frame_set(2)
    _render(scene, tmp_path / "on.exr", True)
    _render(scene, tmp_path / "off.exr", False)
    added = exr.read_exr(tmp_path / "on.exr")[0][..., :3] - exr.read_exr(tmp_path / "off.exr")[0][..., :3]
    assert np.allclose(added, layers[2], atol=1e-4 * max(1.0, float(layers[2].max()))), np.abs(added - layers[2]).max()
    assert not np.allclose(added, layers[1], atol=1e-4 * max(1.0, float(layers[1].max())))

    # Bake Caustics on frame 2 again (another seed): only frame 2's file is replaced, the sequence stays
    stamps = {f: (tmp_path / f"layer_{f:04d}.exr").stat().st_mtime_ns for f in (1, 3)}
    scene.smbs_caustics.seed = 2
    assert bpy.ops.smbs.bake_caustics() == {'FINISHED'}
    assert stamps == {f: (tmp_path / f"layer_{f:04d}.exr").stat().st_mtime_ns for f in (1, 3)}
    again = exr.read_exr(tmp_path / "layer_0002.exr")[0]
    assert not np.array_equal(again, layers[2]) and not (tmp_path / "layer.exr").exists()
    img = bpy.data.images[LAYER]
    assert img.source == 'SEQUENCE' and (img["smbs_caustics_sequence"]["first"], img["smbs_caustics_sequence"]["last"]) == (1, 3)
    assert math.isfinite(float(again.sum()))


def test_in_background_and_the_command_on_the_open_file(ops, addon, tmp_path):
    """blender -b shot.blend --python-expr "bpy.ops.smbs.bake_frame_range()" bakes the range synchronously;
    blender -b shot.blend -c smbs_bake --frames 1-2 bakes the file Blender has open (no input named)."""
    scene = _moving_mirror(tmp_path)
    assert bpy.ops.smbs.bake_frame_range() == {'FINISHED'}
    assert _frame_files(tmp_path) == ["layer_0001.exr", "layer_0002.exr", "layer_0003.exr"]
    assert bpy.data.images[LAYER].source == 'SEQUENCE' and scene.frame_current == 2
    cli = importlib.import_module(addon.__name__ + ".operators.cli")
    out = tmp_path / "cmd_####.exr"
    assert cli.smbs_bake(["--frames", "1-2", "--method", "reference", "--spp", "2", "--out", str(out), "--quiet"]) == 0
    assert sorted(p.name for p in tmp_path.glob("cmd_*.exr")) == ["cmd_0001.exr", "cmd_0002.exr"]
