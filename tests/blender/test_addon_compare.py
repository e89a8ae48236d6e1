"""Compare Methods in the panel (operators/compare.py): each chosen method baked for the same
time, the table stored on the scene and drawn by the panel, and nothing else of the scene
changed: no EXR, no layer, Cycles' switches as they were."""
import importlib
import json
import time

import pytest

bpy = pytest.importorskip("bpy")

from testkit.addon import Reports, draw_all, scene_state  # noqa: E402
from testkit.blend import mirror_scene  # noqa: E402


@pytest.fixture
def ops(empty_bpy, addon):
    return (importlib.import_module(addon.__name__ + ".operators.compare"),
            importlib.import_module(addon.__name__ + ".operators.bake"),
            importlib.import_module(addon.__name__ + ".ui.panels"))


def test_compare_operator_fills_the_table_and_changes_nothing_else(ops, tmp_path, capsys):
    _, _, panels = ops
    scene = mirror_scene(32, 24)
    s = scene.smbs_caustics
    s.compare_methods = {"reference", "sms"}
    s.compare_seconds = 1.0
    s.batches, s.seed = 4, 3
    s.output_path = str(tmp_path / "layer.exr")
    before = scene_state(scene)
    assert bpy.ops.smbs.compare_methods() == {'FINISHED'}
    assert scene_state(scene) == before  # compare_report is not part of it
    assert not any(tmp_path.iterdir()), "Compare Methods wrote a file"
    report = json.loads(s.compare_report)
    assert report["seconds"] == 1.0 and report["region_pixels"] > 0
    assert [r["method"] for r in report["rows"]] == ["reference", "sms"]  # the toggles' order
    for r in report["rows"]:
        assert r["batches"] >= 2 and r["error"] > 0 and r["time_for_same_error"] >= 1.0
        assert r["spp"] == r["batches"]  # one sample per pixel per batch, as Stop By Time
    assert min(r["time_for_same_error"] for r in report["rows"]) == 1.0
    heading, rows, last = panels.compare_rows(panels.parse_stats(s.compare_report))
    assert heading.startswith("1 s each") and [r[0] for r in rows] == ["reference", "sms"]
    assert all(r[1].startswith("\u00b1") and r[2].endswith("x time") for r in rows)
    assert last.startswith("Fastest to a given noise: ")
    out = capsys.readouterr().out
    assert "| reference |" in out and "fastest to a given noise" in out


def test_compare_without_a_method_is_refused(ops):
    scene = mirror_scene(16, 12)
    scene.smbs_caustics.compare_methods = set()
    with pytest.raises(RuntimeError, match="choose at least one method"):
        bpy.ops.smbs.compare_methods()
    assert scene.smbs_caustics.compare_report == ""


def test_panel_rows_for_biased_and_empty_reports(ops):
    _, _, panels = ops
    assert panels.compare_rows({}) == ("", [], "")
    assert panels.compare_rows({"nothing_to_bake": "no light reaches a caster"}) == (
        "Nothing to compare", [], "no light reaches a caster")
    report = {"seconds": 5.0, "region_pixels": 120, "rows": [
        {"method": "mnee", "error": 0.01, "time_for_same_error": None, "leaves_out": ["MNEE's bias (one root)"]},
        {"method": "sms", "error": 0.1, "time_for_same_error": 1.0, "leaves_out": [], "heavy_tail": True},
        {"method": "smbs", "error": None, "time_for_same_error": None, "leaves_out": []}]}
    heading, rows, last = panels.compare_rows(report)
    assert heading == "5 s each, over 120 caustic pixels"
    assert rows == [("mnee", "\u00b11.0%", "biased"), ("sms", "\u00b110.0% (heavy tail)", "1.00x time"),
                    ("smbs", "no error bar", "")]
    assert last == ""  # one priced method: nobody to be fastest against


def test_a_cancelled_comparison_changes_nothing(ops, tmp_path):
    """In the interface the comparison runs as a bake does (ModalBake with CompareTask): the
    panel's Cancel stops it at the core's next check and the last report stays."""
    compare, bake, _ = ops
    scene = mirror_scene(48, 32)
    s = scene.smbs_caustics
    s.compare_report = '{"rows": [], "seconds": 1}'
    before = scene_state(scene)
    reports = Reports()
    job = bake.ModalBake(reports, compare.CompareTask(("sms", "smbs"), 600.0))
    assert job.start(bpy.context)
    assert bake.running_bake(scene) is job
    end = time.monotonic() + 60
    while job.status()[0] == 0.0 and time.monotonic() < end:
        time.sleep(0.02)
    fraction, message = job.status()
    assert 0.0 < fraction < 0.5 and message.startswith("sms (1 of 2)")
    job.cancel()
    assert job.step(bpy.context, 'TIMER') == {'CANCELLED'}
    assert reports.of('WARNING') == ["Method comparison cancelled; nothing was changed"]
    assert bake.running_bake(scene) is None
    assert scene_state(scene) == before and s.compare_report == '{"rows": [], "seconds": 1}'


def test_the_panel_draws_the_last_comparison(ops, addon):
    scene = bpy.context.scene
    drawn = []
    draw_all(addon, scene, drawn)
    assert {"compare_methods", "compare_seconds", "smbs.compare_methods"} <= set(drawn)
    assert "Time for Same Noise" not in drawn  # no comparison yet
    scene.smbs_caustics.compare_report = json.dumps({"seconds": 2.0, "region_pixels": 50, "rows": [
        {"method": "reference", "error": 0.02, "time_for_same_error": 1.0, "leaves_out": []},
        {"method": "smbs", "error": 0.05, "time_for_same_error": 6.25, "leaves_out": []}]})
    drawn = []
    draw_all(addon, scene, drawn)
    assert {"2 s each, over 50 caustic pixels", "Time for Same Noise", "reference", "\u00b12.0%", "1.00x time",
            "smbs", "6.25x time", "Fastest to a given noise: reference"} <= set(drawn)
