"""The manifest passes Blender's own validator; the built zip holds what it should and installs."""
import importlib.util
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from testkit import ROOT


def _blender_ext():
    """blender_ext.py, the extension validator and builder shipped inside the bpy wheel."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        pytest.skip("the bpy module is not installed")
    for location in spec.submodule_search_locations:
        found = sorted(Path(location).glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
        if found:
            return found[-1]
    pytest.skip("blender_ext.py not found in the bpy module")


def _run(*args):
    proc = subprocess.run([sys.executable, str(_blender_ext()), *args],
                          capture_output=True, text=True, timeout=120)
    return proc.returncode, proc.stdout + proc.stderr


def test_manifest_validates():
    code, output = _run("validate", str(ROOT))
    assert code == 0, output


def test_built_zip_contents(tmp_path):
    code, output = _run("build", "--source-dir", str(ROOT), "--output-dir", str(tmp_path))
    assert code == 0, output
    (zip_path,) = tmp_path.glob("*.zip")
    assert zip_path.name == "smbs_caustics-0.1.0.zip"
    with zipfile.ZipFile(zip_path) as zf:
        names = set(zf.namelist())
    for required in ("__init__.py", "blender_manifest.toml", "smbs_addon/scene/arrays.py",
                     "smbs_addon/blender/composite.py", "operators/bake.py", "ui/panels.py",
                     "ui/properties.py"):
        assert required in names, f"{required} missing from {sorted(names)}"
    excluded = ("tests/", "testkit/", "tools/", "bench/", "farm/", "sample_blends/", ".venv/", ".ci/", ".git/",
                "dist/", "out/", "pyproject.toml", "requirements.txt")
    leaked = sorted(n for n in names if n.startswith(excluded) or "__pycache__" in n
                    or ".egg-info" in n or n.endswith(".pyc"))
    assert not leaked, f"excluded paths in the zip: {leaked}"
    # Anything new at the top level must be a deliberate part of the extension.
    top = {n.split("/")[0] for n in names}
    allowed = {"__init__.py", "blender_manifest.toml", "operators", "smbs_addon", "ui", "wheels",
               "LICENSE", "README.md"}
    assert top <= allowed, f"unexpected files in the zip: {sorted(top - allowed)}"
    # Source only until wheels are bundled.
    assert zip_path.stat().st_size < 1_000_000, f"{zip_path.stat().st_size} bytes"


INSTALL_SCRIPT = """
import importlib, sys
import bpy
ext = "bl_ext.user_default.smbs_caustics"
result = bpy.ops.extensions.package_install_files(
    filepath=sys.argv[1], repo="user_default", enable_on_install=True)
assert result == {'FINISHED'}, result
assert "bake_caustics" in dir(bpy.ops.smbs) and hasattr(bpy.context.scene, "smbs_caustics")
for core in ("blender.export", "baking.bake", "blender.composite", "io.exr", "kernels.walk", "cli.main"):  # relative imports hold inside the zip
    importlib.import_module(ext + ".smbs_addon." + core)
# Prepare Kernels' processes import the installed core under this name, bpy left out
import subprocess
prepare = importlib.import_module(ext + ".smbs_addon.baking.prepare")
check = prepare._IMPORT + "print('PART', prepare.__name__, prepare.__file__, 'bpy' in sys.modules)"
part = subprocess.run(prepare.part_command(check, 0, 2), capture_output=True, text=True, timeout=120)
assert part.stdout.split() == ["PART", ext + ".smbs_addon.baking.prepare", prepare.__file__, "False"], part.stdout + part.stderr
bpy.ops.preferences.addon_disable(module=ext)
assert "bake_caustics" not in dir(bpy.ops.smbs) and not hasattr(bpy.context.scene, "smbs_caustics")
print("INSTALL-OK")
"""


def test_built_zip_installs_and_enables(tmp_path):
    """Blender's own installer takes the zip, enables it as bl_ext.user_default.smbs_caustics
    and disables it cleanly. A fresh process: BLENDER_USER_RESOURCES must be set before bpy loads."""
    dist = tmp_path / "dist"
    dist.mkdir()
    code, output = _run("build", "--source-dir", str(ROOT), "--output-dir", str(dist))
    assert code == 0, output
    (zip_path,) = dist.glob("*.zip")
    env = {**os.environ, "BLENDER_USER_RESOURCES": str(tmp_path / "user")}
    proc = subprocess.run([sys.executable, "-c", INSTALL_SCRIPT, str(zip_path)], env=env,
                          capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert proc.returncode == 0 and "INSTALL-OK" in proc.stdout, proc.stdout + proc.stderr
