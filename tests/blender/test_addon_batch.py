"""The batch paths give the same EXR for the same seed, and exit codes a farm can trust.

1. ``blender -b file.blend --python-expr "import bpy; bpy.ops.smbs.bake_caustics()"``:
   the operator in background mode, here through the bpy module;
2. ``blender -c smbs_bake file.blend ...``: the handler registered with
   ``bpy.utils.register_cli_command``, called directly (the bpy module has no ``-c``);
3. ``python -m smbs_addon bake file.blend ...`` in a subprocess.
"""
import importlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from testkit import ROOT  # noqa: E402

MIRROR = ROOT / "sample_blends" / "mirror.blend"
ARGS = ("--method", "smbs", "--spp", "2", "--batches", "2", "--seed", "7")


@pytest.fixture(scope="module")
def small_mirror(tmp_path_factory):
    """sample_blends/mirror.blend at half resolution (80 x 60), saved to a temporary folder."""
    if not MIRROR.is_file():
        pytest.skip(f"{MIRROR} not built (python sample_blends/build.py)")
    path = tmp_path_factory.mktemp("batch") / "mirror.blend"
    bpy.ops.wm.open_mainfile(filepath=str(MIRROR), load_ui=False)
    bpy.context.scene.render.resolution_percentage = 50
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return path


@pytest.fixture
def cli(addon):
    return importlib.import_module(addon.__name__ + ".operators.cli")


def _read(path):
    imageio = importlib.import_module("smbs_caustics.smbs_addon.io.exr")
    return imageio.read_exr(path)


def test_three_batch_paths_give_the_same_pixels(addon, cli, small_mirror, tmp_path):
    # 1. The operator in background mode, settings as on the command line.
    bpy.ops.wm.open_mainfile(filepath=str(small_mirror), load_ui=False)
    s = bpy.context.scene.smbs_caustics
    s.method, s.spp, s.batches, s.seed = "smbs", 2, 2, 7
    s.output_path = str(tmp_path / "operator.exr")
    assert bpy.ops.smbs.bake_caustics() == {'FINISHED'}

    # 2. The registered command's handler.
    assert cli.registered()
    assert cli.smbs_bake([str(small_mirror), *ARGS, "--out", str(tmp_path / "command.exr")]) == 0

    # 3. python -m smbs_addon bake
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.run([sys.executable, "-m", "smbs_addon", "bake", str(small_mirror), *ARGS,
                           "--out", str(tmp_path / "module.exr")],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr

    images = {}
    for name in ("operator", "command", "module"):
        img, meta = _read(tmp_path / f"{name}.exr")
        stats = json.loads((tmp_path / f"{name}.json").read_text())
        assert (meta["method"], meta["spp"], meta["seed"]) == ("smbs", 2, 7), name
        assert stats["resolution"] == [80, 60] and stats["settings"]["seed"] == 7
        images[name] = img
    assert images["operator"].shape == (60, 80, 3) and images["operator"].max() > 0
    assert images["operator"].tobytes() == images["command"].tobytes()
    assert images["operator"].tobytes() == images["module"].tobytes()
    s = json.loads((tmp_path / "operator.json").read_text())["settings"]
    assert s == json.loads((tmp_path / "module.json").read_text())["settings"]


def test_command_exit_codes(addon, cli, small_mirror, tmp_path, capsys):
    out = str(tmp_path / "x.exr")
    assert cli.smbs_bake(["--help"]) == 0
    assert cli.smbs_bake([str(small_mirror), "--spp", "0", "--out", out]) == 2
    assert "--spp" in capsys.readouterr().err
    assert cli.smbs_bake([str(tmp_path / "missing.blend"), "--out", out]) == 3
    assert cli.smbs_bake([str(small_mirror), "--out", str(tmp_path / "no" / "x.exr")]) == 3
    text = tmp_path / "scene.txt"
    text.write_text("not a scene")
    assert cli.smbs_bake([str(text), "--out", out]) == 1
    # A scene that cannot be baked: the message names the object and the problem.
    bpy.ops.wm.open_mainfile(filepath=str(small_mirror), load_ui=False)
    bpy.context.scene.camera = None
    blind = tmp_path / "blind.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blind), copy=True)
    capsys.readouterr()
    assert cli.smbs_bake([str(blind), "--out", out]) == 1
    assert "has no camera" in capsys.readouterr().err
    assert not Path(out).exists()
    # A scene with no caustic is not a failure (a farm must not fail the shot): an all-zero
    # layer, exit 0, and the output says why
    bpy.ops.wm.open_mainfile(filepath=str(small_mirror), load_ui=False)
    bpy.data.objects.remove(bpy.data.objects["Light"])
    dark = tmp_path / "dark.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(dark), copy=True)
    capsys.readouterr()
    assert cli.smbs_bake([str(dark), "--spp", "1", "--out", out]) == 0
    said = capsys.readouterr().out
    assert "Nothing to bake: scene 'Mirror' has no light. The caustic layer is all zero." in said
    assert "nothing to bake: scene 'Mirror' has no light; the caustic layer is all zero" in said
    img = _read(out)[0]
    assert img.shape == (60, 80, 3) and not img.any()
    Path(out).unlink()
    # `bake` may be spelled out, as with python -m smbs_addon
    assert cli.smbs_bake(["bake", str(small_mirror), "--spp", "1", "--batches", "1", "--quiet",
                          "--out", out]) == 0
    assert np.isfinite(_read(out)[0]).all()
