"""A read-only install with no writable home: a farm node, a shared network install. The package
(with the kernels compiled in its own cache, __pycache__) is copied to a folder nobody may write,
HOME is a folder nobody may write, NUMBA_CACHE_DIR is unset; the temporary folder is writable.
Root is kept out of the permission bits by dropping CAP_DAC_OVERRIDE (setpriv).

Issue 59, defect 4: numba found no writable cache folder for any kernel and refused at import
("RuntimeError: cannot cache function 'ray_state': no locator available", a traceback, exit 1),
for ``bake`` and for ``prepare --check``, although the compiled kernels sat in the package's cache.
"""
from __future__ import annotations

import json
import os
import shutil
import stat
import subprocess
from pathlib import Path

import pytest

from testkit.faults import ROOT, assert_no_traceback, env, run, save_mirror

LINE = "smbs_addon: kernels: no writable cache folder (the package's, numba's user cache, NUMBA_CACHE_DIR); " \
       "compiled kernels are kept in "


def _read_only(folder: Path):
    for p in [folder, *folder.rglob("*")]:
        mode = p.stat().st_mode
        p.chmod(mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))


def _writable(folder: Path):
    for p in [folder, *folder.rglob("*")]:
        p.chmod(p.stat().st_mode | stat.S_IWUSR)


@pytest.fixture(scope="module")
def install(tmp_path_factory):
    """(prefix, environment, tmp folder, scene) of a read-only copy of the package."""
    base = tmp_path_factory.mktemp("readonly")
    pkg = base / "install"
    shutil.copytree(ROOT / "smbs_addon", pkg / "smbs_addon")  # copy2: the stamps' times and sizes kept
    home, tmp = base / "home", base / "tmp"
    home.mkdir()
    tmp.mkdir()
    scene = save_mirror(base / "mirror.npz")
    (base / "out").mkdir()
    _read_only(pkg)
    home.chmod(0o555)
    prefix = ()
    if os.geteuid() == 0:
        prefix = ("setpriv", "--bounding-set=-dac_override,-dac_read_search")
        if shutil.which("setpriv") is None or subprocess.run([*prefix, "true"]).returncode != 0:
            pytest.skip("root, and no setpriv to drop CAP_DAC_OVERRIDE")
        probe = subprocess.run([*prefix, "touch", str(pkg / "x")], capture_output=True)
        if probe.returncode == 0:
            pytest.skip("the read-only copy is writable here")
    environ = env(PYTHONPATH=str(pkg), HOME=str(home), TMPDIR=str(tmp), NUMBA_CACHE_DIR=None, XDG_CACHE_HOME=None)
    yield prefix, environ, tmp, scene, pkg
    _writable(pkg)
    home.chmod(0o755)


def test_prepare_check_loads_from_the_read_only_cache(install):
    prefix, environ, tmp, _, pkg = install
    proc = run("prepare", "--check", prefix=prefix, environ=environ, cwd=pkg, timeout=300)
    assert_no_traceback(proc)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "kernels: compiled for this machine; bakes load them from the cache"
    assert proc.stderr.count(LINE) == 1 and f"{LINE}{tmp}/smbs-numba-cache-" in proc.stderr, proc.stderr


def test_a_bake_from_a_read_only_install(install):
    prefix, environ, tmp, scene, pkg = install
    out = scene.parent / "out" / "layer.exr"
    proc = run("bake", scene, "--method", "mnee", "--spp", 1, "--batches", 2, "--pilots", 256, "--out", out,
               prefix=prefix, environ=environ, cwd=pkg, timeout=900)
    assert_no_traceback(proc)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count(LINE) == 1, proc.stderr
    stats = json.loads(out.with_suffix(".json").read_text())
    assert stats["kernels_compiled"] == 0, "the kernels should load from the package's read-only cache"
