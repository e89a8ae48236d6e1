"""tools/build_extension.py builds the linux-x64 zip with the embreex, OpenImageIO, numba and
llvmlite wheels; Blender's installer takes it into a temporary user folder, and the installed
extension bakes a sample scene with the bundled packages (the venv's copies are hidden from it).

If the wheels cannot be downloaded (no network), the zip is built without them and the
bake imports the venv's packages; the test says so in its output.

The installed copy bakes with the light tracer: its kernels (embree's calls from numba, the
specular scatter) compile from an empty cache in about a minute; the walks' kernels, the same
source, would add two more (they are baked under the extension's name by the add-on tests).
"""
import os
import subprocess
import sys
import zipfile

import pytest

from testkit import ROOT

MIRROR = ROOT / "sample_blends" / "mirror.blend"
EXIT_DOWNLOAD = 4

INSTALL_AND_BAKE = r'''
import importlib.abc, importlib.machinery, json, os, sys
user, zip_path, out, bundled = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4] == "1"
site = os.path.join(user, "extensions", ".local", "lib",
                    f"python{sys.version_info.major}.{sys.version_info.minor}", "site-packages")

class OnlyBundled(importlib.abc.MetaPathFinder):
    """embreex, OpenImageIO, numba and llvmlite come from the extension's wheels, never from the venv."""
    def find_spec(self, name, path, target=None):
        if name in ("embreex", "OpenImageIO", "numba", "llvmlite"):
            spec = importlib.machinery.PathFinder.find_spec(name, [site])
            if spec is None:
                raise ModuleNotFoundError(f"{name} is not in the extension's wheels ({site})")
            return spec
        return None

if bundled:
    sys.meta_path.insert(0, OnlyBundled())
import bpy
ext = "bl_ext.user_default.smbs_caustics"
assert bpy.ops.extensions.package_install_files(
    filepath=zip_path, repo="user_default", enable_on_install=True) == {'FINISHED'}
assert ext in sys.modules and "bake_caustics" in dir(bpy.ops.smbs)
bpy.ops.wm.open_mainfile(filepath=sys.argv[5], load_ui=False)
scene = bpy.context.scene
scene.render.resolution_percentage = 50
s = scene.smbs_caustics
s.method, s.spp, s.batches, s.seed, s.output_path = "reference", 1, 2, 1, out
assert bpy.ops.smbs.bake_caustics() == {'FINISHED'}
import embreex, OpenImageIO, numba, llvmlite
print("MODULES", json.dumps({m.__name__: m.__file__ for m in (embreex, OpenImageIO, numba, llvmlite)}))
print("CORE", sys.modules[ext + ".smbs_addon.baking.bake"].__file__)
print("PACKAGE-OK")
'''


def _build(*args, out_dir):
    return subprocess.run([sys.executable, str(ROOT / "tools" / "build_extension.py"), "--platform",
                           "linux-x64", "--output-dir", str(out_dir), *args],
                          capture_output=True, text=True, timeout=600)


@pytest.mark.slow
def test_built_linux_zip_installs_and_bakes(tmp_path):
    pytest.importorskip("bpy")
    if not MIRROR.is_file():
        pytest.skip(f"{MIRROR} not built (python sample_blends/build.py)")
    dist = tmp_path / "dist"
    proc = _build(out_dir=dist)
    bundled = proc.returncode == 0
    if proc.returncode == EXIT_DOWNLOAD:
        print("wheels could not be downloaded; building without them:\n" + proc.stderr)
        proc = _build("--no-wheels", out_dir=dist)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    (zip_path,) = dist.glob("*.zip")
    with zipfile.ZipFile(zip_path) as zf:
        names = set(zf.namelist())
        manifest = zf.read("blender_manifest.toml").decode()
    wheels = sorted(n for n in names if n.startswith("wheels/"))
    if bundled:
        assert zip_path.name == "smbs_caustics-0.1.0-linux_x64.zip"
        assert [w.split("-")[0] for w in wheels] == ["wheels/embreex", "wheels/llvmlite", "wheels/numba",
                                                      "wheels/openimageio"]
        assert all("manylinux" in w and "cp311" in w for w in wheels)
        assert 'platforms = ["linux-x64"]' in manifest and 'blender_version_max = "5.1.0"' in manifest
    assert not any("numpy" in n for n in names)
    assert "operators/bake.py" in names and "smbs_addon/baking/bake.py" in names

    user = tmp_path / "user"
    out = tmp_path / "baked.exr"
    env = {**os.environ, "BLENDER_USER_RESOURCES": str(user)}
    proc = subprocess.run([sys.executable, "-c", INSTALL_AND_BAKE, str(user), str(zip_path), str(out),
                           "1" if bundled else "0", str(MIRROR)],
                          env=env, capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert proc.returncode == 0 and "PACKAGE-OK" in proc.stdout, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert out.is_file() and out.with_suffix(".json").is_file()
    core = next(line.split(" ", 1)[1] for line in proc.stdout.splitlines() if line.startswith("CORE "))
    assert core.startswith(str(user)), core  # the installed copy baked, not this checkout
    modules = next(line for line in proc.stdout.splitlines() if line.startswith("MODULES "))
    if bundled:
        assert modules.count(str(user)) == 4, modules  # every package from the bundled wheels
    print(("bundled wheels: " if bundled else "no wheels bundled, venv packages: ") + modules)
