"""Merging bakes of one frame (issue 58): ``bake --shard K/N`` bakes an independent share of a frame's
samples, ``merge OUT IN...`` puts them together weighted by their samples, with the std channel, the
statistics and the error bar combined (smbs_addon/baking/merge.py); the same refines a finished bake."""
import json
import math

import numpy as np
import pytest

from smbs_addon.baking import merge
from smbs_addon.baking.convergence import caustic_region
from smbs_addon.baking.settings import BakeSettings, shard_of
from smbs_addon.core.errors import SceneError
from smbs_addon.io.exr import read_channels, read_header
from testkit import scenes
from testkit.cli import one_error_line, run

ARGS = ("--method", "reference", "--seed", 3)


@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    """The mirror at 64 x 48: one bake of 16 spp, and its four shards of 4 spp."""
    folder = tmp_path_factory.mktemp("merge")
    npz = folder / "mirror.npz"
    scenes.mirror_scene(resolution=(64, 48)).save(npz)
    proc = run("bake", npz, *ARGS, "--spp", 16, "--out", folder / "whole.exr", "--quiet")
    assert proc.returncode == 0, proc.stderr
    for k in range(1, 5):
        proc = run("bake", npz, *ARGS, "--spp", 16, "--shard", f"{k}/4", "--out", folder / f"shard{k}.exr", "--quiet")
        assert proc.returncode == 0, proc.stderr
    return folder, npz


def _lum(channels):
    return (channels["R"].astype(np.float64) + channels["G"] + channels["B"]) / 3


def test_shards_share_the_samples_and_key_their_own_streams():
    s = BakeSettings(spp=10, noise_target=0.0)
    assert [shard_of(s, k, 4).spp for k in range(1, 5)] == [2, 3, 2, 3]
    assert shard_of(BakeSettings(spp=8, noise_target=0.04), 2, 4).noise_target == pytest.approx(0.08)
    assert shard_of(s, 2, 4).stream_suffix() != shard_of(s, 3, 4).stream_suffix() and s.stream_suffix() == ()
    with pytest.raises(SceneError, match="cannot be shared by 4 shards"):
        shard_of(BakeSettings(spp=3), 1, 4)


def test_four_shards_merged_agree_with_one_bake_and_in_any_order(baked):
    folder, _ = baked
    names = [str(folder / f"shard{k}.exr") for k in range(1, 5)]
    for k in range(1, 5):
        assert read_header(names[k - 1])["shard"] == f"{k}/4" and read_header(names[k - 1])["samples"] == 4
    proc = run("merge", folder / "merged.exr", *names)
    assert proc.returncode == 0, proc.stderr
    assert "merged 4 bakes (16 samples per pixel, 32 batches)" in proc.stdout
    proc = run("merge", folder / "again.exr", *reversed(names), "--quiet")
    assert proc.returncode == 0 and proc.stdout == ""
    merged, meta = read_channels(folder / "merged.exr")
    again, _ = read_channels(folder / "again.exr")
    assert all(merged[k].tobytes() == again[k].tobytes() for k in merged)  # order-independent, bit for bit
    whole, whole_meta = read_channels(folder / "whole.exr")
    stats = json.loads((folder / "merged.json").read_text())
    whole_stats = json.loads((folder / "whole.json").read_text())
    # the mean over the caustic region within 3 sigma of the one bake's
    region = caustic_region(_lum(whole))
    m_merged, m_whole = _lum(merged)[region].mean(), _lum(whole)[region].mean()
    se = math.hypot(stats["noise"]["std_error_of_mean"], whole_stats["noise"]["std_error_of_mean"])
    assert abs(m_merged - m_whole) < 3 * se, (m_merged, m_whole, se)
    # the error bar within 10% of the one bake's, and consistent with a bake's own definition
    assert stats["relative_error"] == pytest.approx(whole_stats["relative_error"], rel=0.10)
    err, _ = merge.error_bar(np.stack([whole[c] for c in "RGB"], -1), whole["std"])
    assert err == pytest.approx(whole_stats["relative_error"], rel=1e-4)
    assert meta["samples"] == 16 and stats["batches_done"] == 32 and len(stats["streams"]) == 4


def test_a_finished_bake_refined_by_more_samples(baked):
    """Bake more later (another seed), merge: the error bar falls as 1 / sqrt(the samples)."""
    folder, npz = baked
    proc = run("bake", npz, *ARGS[:2], "--seed", 4, "--spp", 48, "--out", folder / "more.exr", "--quiet")
    assert proc.returncode == 0, proc.stderr
    proc = run("merge", folder / "refined.exr", folder / "whole.exr", folder / "more.exr", "--quiet")
    assert proc.returncode == 0, proc.stderr
    before = json.loads((folder / "whole.json").read_text())["relative_error"]
    after = json.loads((folder / "refined.json").read_text())["relative_error"]
    assert after == pytest.approx(before / 2, rel=0.15), (before, after)  # 16 -> 64 samples


def test_what_cannot_be_merged_is_refused(baked, tmp_path):
    folder, npz = baked
    proc = run("merge", tmp_path / "x.exr", folder / "shard1.exr", folder / "shard1.exr")
    assert proc.returncode == 1 and "hold the same samples (seed 3, shard 1)" in one_error_line(proc)
    proc = run("bake", npz, "--method", "sms", "--seed", 9, "--spp", 4, "--out", tmp_path / "sms.exr", "--quiet")
    assert proc.returncode == 0, proc.stderr
    proc = run("merge", tmp_path / "x.exr", folder / "shard1.exr", tmp_path / "sms.exr")
    assert proc.returncode == 1 and "baked with other settings: method 'sms' against 'reference'" in one_error_line(proc)
    proc = run("merge", tmp_path / "x.exr", folder / "shard1.exr", tmp_path / "none*.exr")
    assert proc.returncode == 3 and "no file matches" in one_error_line(proc)
    assert not (tmp_path / "x.exr").exists()
