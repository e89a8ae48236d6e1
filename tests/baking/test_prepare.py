"""python -m smbs_addon prepare: the kernels compiled before the first bake (smbs_addon/prepare.py).

What it saves is measured in bench/ (a cold cache is minutes of compiling, too long for a test);
here: its bakes run and are shared out between processes exactly, and the command reports."""
import subprocess
import sys

import numpy as np

from smbs_addon.baking import prepare
from smbs_addon.baking.settings import BakeSettings
from smbs_addon.baking.bake import bake

from testkit import ROOT


def test_parts_share_out_every_bake_once():
    for n in (1, 2, 3, len(prepare.BAKES), len(prepare.BAKES) + 2):
        got = [b for i in range(n) for b in prepare.bakes(i, n)]
        assert sorted(map(repr, got)) == sorted(map(repr, prepare.BAKES))
        assert len(got) == len(prepare.BAKES)
    assert prepare.bakes(0, 2)[0] != prepare.bakes(1, 2)[0]  # each part starts with a different bake


def test_the_scenes_have_caustics_from_every_light():
    """The scenes use what bakes use: all four light types (and a world of an image, whose photons
    leave along the map's directions: lights._emit_along, which the sample scene hdri_glass compiled
    after prepare), a mirror and a glass each casting, and the bakes find a caustic (so the walks,
    photons and their kernels do run)."""
    from smbs_addon.scene import arrays as S

    for name in ("plain", "textured"):
        sc = prepare.scene(name)
        world = [S.WORLD] if name == "textured" else []
        assert sorted(sc.light_type.tolist()) == [0, 1, 2, 3] + world
        assert (sc.world_map.size > 0) == (name == "textured")
        assert (sc.mat_textured.any() if sc.mat_textured.size else False) == (name == "textured")
        res = bake(sc, BakeSettings(method="smbs", spp=1, batches=2, seed=1, pilots=256))
        assert res.stats["walks"] > 0 and res.stats["successes"] > 0
        assert {"R", "TT"} <= set(res.stats["chain_types"])
        assert np.isfinite(res.image).all() and res.image.mean() > 0


def test_prepare_command_in_two_processes():
    out = subprocess.run([sys.executable, "-m", "smbs_addon", "prepare", "--jobs", "2"], cwd=ROOT,
                         capture_output=True, text=True, timeout=1800)
    assert out.returncode == 0, out.stderr + out.stdout
    last = out.stdout.strip().splitlines()[-1]
    assert last.startswith("prepared: ") and "(2 processes); bakes on this machine load them from the cache" in last
    lines = [x for x in out.stdout.splitlines() if x.startswith(("[1/2] bake ", "[2/2] bake "))]
    assert len(lines) == len(prepare.BAKES)  # a line per bake, from both parts


def test_check_says_whether_the_kernels_are_compiled(tmp_path, monkeypatch):
    """prepare --check / prepare.ready(): 0 and "compiled" here (the suite has baked by now, and
    prepare above compiled what it had not); 1 and "not compiled" for a copy of the package in
    another folder (its own, empty cache: nothing compiled there), without compiling anything; None
    (no telling) where numba's cache is not where ready() looks."""
    import shutil

    def check(cwd):
        return subprocess.run([sys.executable, "-m", "smbs_addon", "prepare", "--check"], cwd=cwd,
                              capture_output=True, text=True, timeout=300)

    here = check(ROOT)
    assert here.returncode == 0 and here.stdout.startswith("kernels: compiled for this machine"), here
    shutil.copytree(ROOT / "smbs_addon", tmp_path / "smbs_addon", ignore=shutil.ignore_patterns("__pycache__"))
    copy = check(tmp_path)
    assert copy.returncode == 1 and copy.stdout.startswith("kernels: not compiled"), copy
    assert sorted(p.name for p in (tmp_path / "smbs_addon").rglob("__pycache__/*.nb*")) == []
    assert prepare.ready() is True
    monkeypatch.setattr(prepare, "KERNELS", ("no_such_kernel",))
    assert prepare.ready() is None
