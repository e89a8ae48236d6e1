"""An EXR that stands on its own (issue 58): where the caustic falls on a textured receiver seen
directly, the command line's R, G, B hold it whole (per unit albedo times the Diffuse Color pass Cycles
renders for the bake), so that a compositor outside Blender needs nothing else. A biconvex glass lens
over a checker floor (testkit/motion_scenes.lens_checker: the caustic's disc over two warm and two blue
squares), against Cycles' caustics on - off: tests/data/cycles_lens_checker_* (8192 spp in two halves,
made by ``python tools/cycles_reference.py lens_checker.blend --spp 8192 --out
tests/data/cycles_lens_checker`` on the scene testkit.motion_scenes.build_lens_checker saves)."""
import json
import math

import numpy as np
import pytest

from smbs_addon.baking.convergence import caustic_region
from smbs_addon.io.exr import read_channels
from testkit import ROOT
from testkit.cli import run
from testkit.cycles import read_exr_rgb

DATA = ROOT / "tests" / "data"


def _cycles():
    on_a, on_b, off_a, off_b = (read_exr_rgb(DATA / f"cycles_lens_checker_{t}.exr")
                                for t in ("on_a", "on_b", "off_a", "off_b"))
    return on_a - off_a, on_b - off_b


def test_the_cli_rgb_holds_the_whole_caustic_on_a_checker(tmp_path):
    pytest.importorskip("bpy")
    from testkit.motion_scenes import build_lens_checker

    blend = build_lens_checker(tmp_path)
    out = tmp_path / "lens.exr"
    proc = run("bake", blend, "--method", "reference", "--spp", 256, "--seed", 1, "--out", out, timeout=300)
    assert proc.returncode == 0, proc.stderr
    ch, meta = read_channels(out)
    ours = np.stack([ch[c] for c in "RGB"], axis=-1).astype(np.float64)
    stats = json.loads(out.with_suffix(".json").read_text())
    assert stats["rgb"] == "complete" and stats["textured_share"] > 0.9
    se_ours = stats["noise"]["std_error_of_mean"] / stats["noise"]["mean"]
    a, b = _cycles()
    assert a.shape == ours.shape
    found = {}
    for name, pick in (("luminance", lambda x: x.mean(axis=2)), ("R", lambda x: x[..., 0]), ("G", lambda x: x[..., 1]),
                       ("B", lambda x: x[..., 2])):
        ratios, ses = [], []
        var_half = (pick(a) - pick(b)) ** 2 / 2.0  # Cycles' pixels are independent
        for sel, judged in ((a, b), (b, a)):  # the region picked on one half, the mean taken on the other
            region = caustic_region(sel.mean(axis=2))
            m_ref = pick(judged)[region].mean()
            ratios.append(pick(ours)[region].mean() / m_ref)
            ses.append(math.sqrt(var_half[region].sum()) / region.sum() / m_ref)
        ratio, sigma = np.mean(ratios), math.hypot(np.mean(ses) / math.sqrt(2), se_ours)
        found[name] = (round(float(ratio), 4), round(float(sigma), 4))
        assert abs(ratio - 1) <= 0.03 + 3 * sigma, found
    print(found)
    # without the albedo, R, G, B held none of it (the per-albedo channels alone carried it)
    per = np.stack([ch[f"per_albedo_{c}"] for c in "RGB"], axis=-1)
    assert per.max() > 0 and ours.sum() > 0.1 * per.sum()
