"""Frame ranges on the command line (issue 58): ``bake IN.blend --frames A-B[:STEP]`` and ``--frame N``
on the animated sample at 40 x 30 (its light crosses over the glass ball, the caustic slides): each
frame written with Blender's # padding and its statistics, a summary for the range (per-frame time,
rays, error bar; totals; flicker), frame N of a range bit for bit frame N baked alone, a second run
skipping what is up to date, a frame that fails named, a signal keeping the frames done."""
import json
import signal

import numpy as np
import pytest

from smbs_addon.baking.convergence import caustic_region
from smbs_addon.io.exr import read_channels, read_header
from smbs_addon.io.sequence import frame_path, parse_frames, summary_path, with_frames
from testkit.cli import run
from testkit.faults import assert_no_traceback, signal_after, start, temporaries

ARGS = ("--spp", 2, "--seed", 5)


def test_frame_specs_and_paths():
    assert parse_frames("1-250:50") == [1, 51, 101, 151, 201] and parse_frames("12") == [12]
    assert parse_frames("-2-1") == [-2, -1, 0, 1]
    for bad in ("1-", "a-b", "5-1", "1-5:0"):
        with pytest.raises(ValueError):
            parse_frames(bad)
    assert frame_path("out/caustics_####.exr", 1).as_posix() == "out/caustics_0001.exr"
    assert frame_path("out/c_##.exr", 12345).as_posix() == "out/c_12345.exr"
    assert with_frames("out/c.exr").as_posix() == "out/c_####.exr"
    assert summary_path("out/caustics_####.exr").as_posix() == "out/caustics_summary.json"


@pytest.fixture(scope="module")
def anim(tmp_path_factory):
    pytest.importorskip("bpy")
    from testkit.motion_scenes import small_moving_light

    return small_moving_light(tmp_path_factory.mktemp("anim") / "moving.blend")


def _pixels(path):
    channels, _ = read_channels(path)
    return {k: v.tobytes() for k, v in channels.items()}


def test_a_range_its_summary_a_frame_alone_and_a_second_run(anim, tmp_path):
    pattern = tmp_path / "c_####.exr"
    proc = run("bake", anim, "--frames", "1-3", *ARGS, "--out", pattern, timeout=600)
    assert proc.returncode == 0, proc.stderr
    for f in (1, 2, 3):
        meta = read_header(frame_path(pattern, f))
        assert meta["frame"] == f and meta["samples"] == 2 and meta["code"] and meta["scene"], meta
        assert json.loads(frame_path(pattern, f).with_suffix(".json").read_text())["settings"]["frame"] == f
    summary = json.loads((tmp_path / "c_summary.json").read_text())
    assert [r["frame"] for r in summary["per_frame"]] == [1, 2, 3]
    assert all(r["status"] == "baked" and r["time_s"] > 0 and r["rays"] > 0 and r["relative_error"] > 0
               for r in summary["per_frame"])
    assert summary["totals"]["baked"] == 3 and summary["totals"]["rays"] == sum(r["rays"] for r in summary["per_frame"])
    fl = summary["flicker"]
    assert fl["pairs"] == 2 and fl["measured"] > 0 and fl["predicted"] > 0
    assert "flicker:" in proc.stdout
    # the caustic moves: the frames differ
    assert _pixels(frame_path(pattern, 1))["R"] != _pixels(frame_path(pattern, 3))["R"]

    # frame 2 alone: the same pixels as frame 2 of the range
    alone = tmp_path / "alone.exr"
    proc = run("bake", anim, "--frame", 2, *ARGS, "--out", alone, "--quiet", timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert _pixels(alone) == _pixels(frame_path(pattern, 2))
    assert read_header(alone)["settings_key"] == read_header(frame_path(pattern, 2))["settings_key"]

    # a second run: every frame up to date, nothing written again
    stamps = {f: frame_path(pattern, f).stat().st_mtime_ns for f in (1, 2, 3)}
    proc = run("bake", anim, "--frames", "1-3", *ARGS, "--out", pattern, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.count("holds this bake already") == 3, proc.stdout
    assert stamps == {f: frame_path(pattern, f).stat().st_mtime_ns for f in (1, 2, 3)}
    summary = json.loads((tmp_path / "c_summary.json").read_text())
    assert summary["totals"]["skipped"] == 3 and summary["flicker"]["pairs"] == 2
    # other settings, or --overwrite: baked again
    proc = run("bake", anim, "--frames", "3-3", "--spp", 2, "--seed", 6, "--out", pattern, timeout=300)
    assert proc.returncode == 0 and "holds another bake (other settings); baking it again" in proc.stdout
    proc = run("bake", anim, "--frames", "3-3", "--spp", 2, "--seed", 6, "--out", pattern, "--overwrite", timeout=300)
    assert proc.returncode == 0 and "holds this bake already" not in proc.stdout


def test_a_frame_that_fails_is_named_and_the_frames_written_are_kept(anim, tmp_path):
    pattern = tmp_path / "c_####.exr"
    frame_path(pattern, 2).mkdir()  # frame 2's output is a folder
    proc = run("bake", anim, "--frames", "1-3", *ARGS, "--out", pattern, timeout=300)
    assert proc.returncode == 3, proc.stderr
    assert_no_traceback(proc)
    assert "smbs_addon: error: frame 2: output " in proc.stderr and "(frames written and kept: 1)" in proc.stderr
    assert frame_path(pattern, 1).is_file() and not frame_path(pattern, 3).exists()
    summary = json.loads((tmp_path / "c_summary.json").read_text())
    assert [(r["frame"], r["status"]) for r in summary["per_frame"]] == [(1, "baked"), (2, "failed")]
    assert summary["totals"]["not_done"] == 1


def test_a_signal_keeps_the_frames_done_and_a_kill_leaves_no_partial_file(anim, tmp_path):
    pattern = tmp_path / "c_####.exr"
    proc = start("bake", anim, "--frames", "1-3", "--time", 4, "--seed", 5, "--out", pattern)
    _, stderr = signal_after(proc, signal.SIGTERM, "frame 2 (2/3)", delay=0.5)
    assert proc.returncode == 143, stderr
    assert_no_traceback(stderr)
    assert "stopped by SIGTERM at frame 2; nothing of it was written (frames written and kept: 1)" in stderr
    assert frame_path(pattern, 1).is_file() and not frame_path(pattern, 2).exists()
    assert temporaries(tmp_path) == []
    assert [r["frame"] for r in json.loads((tmp_path / "c_summary.json").read_text())["per_frame"]] == [1]

    # SIGKILL gives no time to clean up: no frame file is ever partial (a rename puts it in place),
    # and the next run removes what a dead process left beside it, then goes on where it stopped
    proc = start("bake", anim, "--frames", "1-3", "--time", 4, "--seed", 5, "--out", pattern)
    signal_after(proc, signal.SIGKILL, "frame 2 (2/3)", delay=0.5)
    assert not frame_path(pattern, 2).exists()
    stale = tmp_path / ".c_0002.exr.999999999.tmp.exr"
    stale.write_bytes(b"half an EXR")
    proc = run("bake", anim, "--frames", "1-3", "--time", 4, "--seed", 5, "--out", pattern, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "frame 1: " in proc.stdout and "holds this bake already" in proc.stdout
    assert not stale.exists() and temporaries(tmp_path) == []
    assert all(np.isfinite(read_channels(frame_path(pattern, f))[0]["R"]).all() for f in (1, 2, 3))


def test_frames_of_the_sample_are_single_bakes_and_agree_with_the_light_tracer(anim, tmp_path):
    """Frames 1, 12 and 23 of the 24 (--frames 1-24:11) at 40 x 30: frame 12 is frame 12 baked alone bit for
    bit, and each agrees with the light tracer (--method reference, the same frames) within 3 sigma over
    its caustic region. bench/frames_24.py bakes all 24 at 80 x 60 and checks frames 1, 12 and 24 so
    (bench/results/frames_24.md)."""
    pattern, ref = tmp_path / "c_####.exr", tmp_path / "ref_####.exr"
    for args in (("--spp", 8, "--seed", 5, "--out", pattern), ("--method", "reference", "--spp", 32, "--seed", 7, "--out", ref)):
        proc = run("bake", anim, "--frames", "1-24:11", *args, "--quiet", timeout=600)
        assert proc.returncode == 0, proc.stderr
    alone = tmp_path / "alone.exr"
    proc = run("bake", anim, "--frame", 12, "--spp", 8, "--seed", 5, "--out", alone, "--quiet", timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert _pixels(alone) == _pixels(frame_path(pattern, 12))
    lum = lambda c: (c["R"].astype(np.float64) + c["G"] + c["B"]) / 3  # noqa: E731
    for f in (1, 12, 23):
        ours, theirs = (read_channels(frame_path(p, f))[0] for p in (pattern, ref))
        region = caustic_region(lum(theirs))
        se = np.hypot(*(json.loads(frame_path(p, f).with_suffix(".json").read_text())["noise"]["std_error_of_mean"]
                        for p in (pattern, ref)))
        assert region.sum() > 10 and se > 0
        assert abs(lum(ours)[region].mean() - lum(theirs)[region].mean()) < 3 * se, (f, se)
