"""Faults of the outputs: a full disk or a file size limit, an output no rename may replace, a folder
that cannot take a file. Each case checks the exit code, the message (its stable part) and that
nothing was lost: the previous EXR's and statistics' bytes, no temporary file beside them.

Issue 59, defect 1: with ``ulimit -f 4`` OpenImageIO's open, write and close all report success
(Python ignores SIGXFSZ: the write is cut short silently), and the 4 KB temporary was renamed over
the previous EXR; the bake exited 0 or 3 with "[Errno 27] File too large" and no file named."""
from __future__ import annotations

import errno
import json
import resource
import subprocess

import numpy as np
import pytest

from testkit.faults import assert_no_traceback, assert_nothing_lost, previous_output, run, save_mirror, temporaries

BAKE = ("--method", "mnee", "--spp", 1, "--batches", 2, "--pilots", 256, "--quiet")


@pytest.fixture(scope="module")
def npz(tmp_path_factory):
    return save_mirror(tmp_path_factory.mktemp("outputs") / "mirror.npz")


def _limit(nbytes):
    return lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (nbytes, nbytes))


def test_a_file_size_limit_keeps_the_previous_exr(npz, tmp_path):
    """Defect 1: the file size limit cuts the new EXR short; the old one stays, byte for byte."""
    out, before = previous_output(tmp_path)
    json_before = out.with_suffix(".json").read_bytes()
    proc = run("bake", npz, *BAKE, "--seed", 3, "--out", out, preexec_fn=_limit(4096))
    assert proc.returncode == 3, proc.stderr
    assert_no_traceback(proc)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith(f"smbs_addon: error: cannot write '{out}': the file size limit of this process "
                               f"(ulimit -f: 4096 bytes) cut it short; the previous file is unchanged; the result "
                               f"could not be kept elsewhere either ("), lines[0]
    assert_nothing_lost(out, before, json_before)


def test_a_failing_statistics_write_keeps_the_previous_exr_too(tmp_path, monkeypatch):
    """The EXR is written whole, the statistics JSON fails (File too large): neither previous file is
    replaced (both are written and read back before either replaces anything); the message names the
    JSON and the cause."""
    from smbs_addon.core.errors import WriteError
    from smbs_addon.io import exr

    out, before = previous_output(tmp_path)
    json_before = out.with_suffix(".json").read_bytes()

    def too_large(tmp):
        raise OSError(errno.EFBIG, "File too large", str(tmp))

    with pytest.raises(WriteError) as e:
        exr.save_outputs([(out, exr.exr_writer(np.ones((24, 32, 3)))), (out.with_suffix(".json"), too_large)])
    assert str(e.value).startswith(f"cannot write '{out.with_suffix('.json')}': [Errno 27] File too large; the "
                                   f"previous file is unchanged; the result could not be kept elsewhere either (")
    assert_nothing_lost(out, before, json_before)


def test_a_full_disk_keeps_the_result_in_the_temporary_folder(tmp_path, monkeypatch):
    """No space beside the output (simulated: the writer fails there with ENOSPC): the previous files
    stay, and the result is written whole into a folder of the temporary folder the message names."""
    from smbs_addon.core.errors import WriteError
    from smbs_addon.io import exr

    out, before = previous_output(tmp_path)
    json_before = out.with_suffix(".json").read_bytes()
    layer = np.random.default_rng(1).random((24, 32, 3)).astype(np.float32)
    real = exr.exr_writer(layer, {"method": "new"})

    def full_beside_the_output(tmp):
        if tmp.parent == out.parent:
            raise OSError(errno.ENOSPC, "No space left on device")
        real(tmp)

    rescue = tmp_path / "tmp"
    rescue.mkdir()
    monkeypatch.setattr(exr.tempfile, "tempdir", str(rescue))
    with pytest.raises(WriteError) as e:
        exr.save_outputs([(out, full_beside_the_output), (out.with_suffix(".json"), exr.json_writer({"new": 1}))])
    kept = next(rescue.iterdir())
    assert str(e.value) == (f"cannot write '{out}': [Errno 28] No space left on device; the previous file is "
                            f"unchanged; the result (layer.exr, layer.json) is kept in {kept}")
    assert_nothing_lost(out, before, json_before)
    img, meta = exr.read_exr(kept / "layer.exr")
    assert np.array_equal(img, layer) and meta["method"] == "new"
    assert json.loads((kept / "layer.json").read_text()) == {"new": 1}


def test_an_immutable_output_is_refused_before_the_bake(npz, tmp_path):
    """An existing output no rename may replace (chattr +i) is refused before anything is baked."""
    out, before = previous_output(tmp_path)
    if subprocess.run(["chattr", "+i", str(out)], capture_output=True).returncode != 0:
        pytest.skip("chattr +i is not allowed here")
    try:
        proc = run("bake", npz, "--method", "mnee", "--spp", 1, "--batches", 2, "--out", out)
    finally:
        subprocess.run(["chattr", "-i", str(out)], check=True)
    assert proc.returncode == 3, proc.stderr
    assert proc.stderr.strip() == f"smbs_addon: error: output '{out}' is immutable (chattr), so it cannot be replaced"
    assert "plan:" not in proc.stdout  # refused before the plan, not after the bake
    assert_nothing_lost(out, before)


def test_an_output_on_proc_is_refused_before_the_bake(npz):
    """/proc: the permission bits say writable to root, the file system says no; asked before the bake."""
    proc = run("bake", npz, "--method", "mnee", "--spp", 1, "--batches", 2, "--out", "/proc/x.exr")
    assert proc.returncode == 3, proc.stderr
    assert proc.stderr.strip().startswith("smbs_addon: error: output folder '/proc' is not writable (")
    assert "plan:" not in proc.stdout


def test_a_failed_write_leaves_no_temporary_in_the_folder(tmp_path, monkeypatch):
    """A writer that fails half way (an interrupt): nothing replaced, nothing left, nothing rescued."""
    from smbs_addon.io import exr

    out, before = previous_output(tmp_path)

    def interrupted(tmp):
        tmp.write_bytes(b"half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        exr.save_outputs([(out, interrupted)])
    assert_nothing_lost(out, before)
    assert temporaries(tmp_path) == []


def test_an_export_under_a_file_size_limit_keeps_the_previous_npz(npz, tmp_path):
    """export: the scene's .npz is written and read back like the bake's outputs."""
    out = tmp_path / "scene.npz"
    out.write_bytes(npz.read_bytes())
    before = out.read_bytes()
    proc = run("export", npz, out, preexec_fn=_limit(8192))
    assert proc.returncode == 3, proc.stderr
    assert_no_traceback(proc)
    assert proc.stderr.strip().startswith(f"smbs_addon: error: cannot write '{out}': the file size limit of this "
                                          f"process (ulimit -f: 8192 bytes) cut it short; the previous file is "
                                          f"unchanged; ")
    assert out.read_bytes() == before and temporaries(tmp_path) == []
