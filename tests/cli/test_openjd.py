"""The farm's job (issue 58): farm/openjd/smbs_caustics.yaml, an Open Job Description template (the job
format AWS Deadline Cloud and other farm managers run), run here as a farm would, with ``openjd run``
(openjd-cli, requirements.txt): a step of frame x shard bakes, a merge step after it. Its merged frames
agree with a plain range bake of the same samples within their error bars."""
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from smbs_addon.baking.convergence import caustic_region
from smbs_addon.io.exr import read_channels, read_header
from smbs_addon.io.sequence import frame_path
from testkit import ROOT
from testkit.cli import run

TEMPLATE = ROOT / "farm" / "openjd" / "smbs_caustics.yaml"


def _openjd():
    """The openjd command: beside this Python (the .venv of setup.sh), on PATH, or SMBS_OPENJD."""
    for cand in (os.environ.get("SMBS_OPENJD"), str(Path(sys.executable).parent / "openjd"), shutil.which("openjd")):
        if cand and Path(cand).is_file():
            return cand
    pytest.skip("openjd-cli is not installed (pip install -r requirements.txt)")


def _openjd_run(*args, timeout=600):
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([_openjd(), *map(str, args)], env=env, capture_output=True, text=True, timeout=timeout)


def test_the_template_is_valid():
    proc = _openjd_run("check", TEMPLATE)
    assert proc.returncode == 0 and "passes validation" in proc.stdout, proc.stdout + proc.stderr


def test_the_job_runs_and_its_merged_frames_match_a_range_bake(tmp_path):
    pytest.importorskip("bpy")
    from testkit.motion_scenes import small_turning_mirror

    blend = small_turning_mirror(tmp_path / "mirror.blend")  # the light tracer bakes it without heavy tails
    out = tmp_path / "farm"
    proc = _openjd_run("run", TEMPLATE, "--step", "MergeShards", "--run-dependencies",
                       "-p", f"BlendFile={blend}", "-p", f"OutputDir={out}", "-p", "Frames=1-2", "-p", "Shards=2",
                       "-p", "StopValue=32", "-p", "Method=reference", "-p", "Seed=1", "-p", f"SmbsCommand={sys.executable} -m smbs_addon")
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "Session ended successfully" in proc.stdout and "Chunks run: 6" in proc.stdout, proc.stdout[-2000:]
    plain = tmp_path / "plain_####.exr"
    proc = run("bake", blend, "--frames", "1-2", "--spp", 32, "--method", "reference", "--seed", 1, "--out", plain, "--quiet", timeout=300)
    assert proc.returncode == 0, proc.stderr
    for f in (1, 2):
        assert sorted(p.name for p in (out / "shards").glob(f"*_{f:04d}.exr")) == [f"s1_caustics_{f:04d}.exr",
                                                                                  f"s2_caustics_{f:04d}.exr"]
        farm, meta = read_channels(frame_path(out / "caustics_####.exr", f))
        ref, _ = read_channels(frame_path(plain, f))
        assert meta["samples"] == 32 and meta["merged"] == 2 and meta["frame"] == f
        a, b = (json.loads(p.with_suffix(".json").read_text())
                for p in (frame_path(out / "caustics_####.exr", f), frame_path(plain, f)))
        lum = lambda c: (c["R"] + c["G"] + c["B"]) / 3  # noqa: E731
        region = caustic_region(lum(ref))
        se = math.hypot(a["noise"]["std_error_of_mean"], b["noise"]["std_error_of_mean"])
        assert abs(lum(farm)[region].mean() - lum(ref)[region].mean()) < 3 * se + 1e-9, (f, se)
        assert a["relative_error"] == pytest.approx(b["relative_error"], rel=0.2)
        assert np.isfinite(farm["std"]).all() and read_header(frame_path(plain, f))["samples"] == 32
