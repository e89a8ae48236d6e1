"""The command line, ``python -m smbs_addon bake``, run as a subprocess.

Exit codes (module docstring of smbs_addon/__main__.py): 0 done, 1 the scene
cannot be baked, 2 bad arguments, 3 unreadable input or unwritable output.
Errors are one line on stderr: ``smbs_addon: error: <message>``.
"""
import json
import re

import numpy as np
import pytest

from smbs_addon.io.exr import read_exr
from testkit import ROOT, scenes
from testkit.cli import one_error_line, run

MIRROR_BLEND = ROOT / "sample_blends" / "mirror.blend"


@pytest.fixture(scope="module")
def npz(tmp_path_factory):
    path = tmp_path_factory.mktemp("cli") / "mirror.npz"
    scenes.mirror_scene(resolution=(32, 24)).save(path)
    return path


@pytest.fixture(scope="module")
def baked(npz):
    """One bake with --spp 2 and a seed above 2^24 (float32 could not hold it)."""
    out = npz.parent / "first" / "mirror.caustics.exr"
    out.parent.mkdir()
    proc = run("bake", npz, "--method", "reference", "--spp", 2, "--seed", 123456789, "--out", out)
    return proc, out


def test_bake_npz_writes_exr_and_stats(baked):
    proc, out = baked
    assert proc.returncode == 0, proc.stderr
    stats_path = out.with_suffix(".json")
    assert out.is_file() and stats_path.is_file()
    img, meta = read_exr(out)
    assert img.shape == (24, 32, 3) and img.dtype == np.float32
    assert np.all(np.isfinite(img)) and img.max() > 0
    assert meta["method"] == "reference"
    assert meta["spp"] == 2
    assert meta["seed"] == 123456789  # exactly, not rounded to float32
    stats = json.loads(stats_path.read_text())
    for key in ("lights", "rays", "time_s", "noise"):
        assert key in stats, key
    assert stats["resolution"] == [32, 24]
    assert stats["settings"]["spp"] == 2 and stats["settings"]["seed"] == 123456789
    assert set(stats["lights"]) == {"Disk"} and stats["lights"]["Disk"]["photons"] > 0
    assert stats["rays"] > 0 and stats["time_s"] > 0
    assert stats["noise"]["region_pixels"] > 0
    # the header's copy of the statistics is the same JSON
    assert json.loads(meta["stats"])["rays"] == stats["rays"]
    assert re.search(r"^scene 'mirror': reference, 32x24, [0-9.]+ s, [0-9,]+ rays$", proc.stdout, re.M), proc.stdout
    assert re.search(r"^  light 'Disk': [0-9,]+ light paths", proc.stdout, re.M)
    assert f"wrote {out} and {stats_path}" in proc.stdout


def test_same_seed_same_pixels(baked, npz, tmp_path):
    _, first = baked
    again = tmp_path / "again.exr"
    proc = run("bake", npz, "--method", "reference", "--spp", 2, "--seed", 123456789, "--out", again, "--quiet")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == "" and proc.stderr == ""  # --quiet
    a, _ = read_exr(first)
    b, _ = read_exr(again)
    assert a.tobytes() == b.tobytes()
    other = tmp_path / "other.exr"
    assert run("bake", npz, "--method", "reference", "--spp", 2, "--seed", 5, "--out", other, "--quiet").returncode == 0
    assert read_exr(other)[0].tobytes() != a.tobytes()


def test_default_output_names(npz, tmp_path):
    src = tmp_path / "scene.npz"
    src.write_bytes(npz.read_bytes())
    proc = run("bake", src, "--spp", 1, "--quiet")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "scene.caustics.exr").is_file() and (tmp_path / "scene.caustics.json").is_file()


@pytest.mark.parametrize("args,code,words", [
    (["--spp", "0"], 2, ["--spp", "at least 1", "0"]),
    (["--spp", "abc"], 2, ["--spp", "'abc'", "not a whole number"]),
    (["--seed", "-1"], 2, ["--seed", "must not be negative", "-1"]),
    (["--method", "nonsense"], 2, ["--method", "invalid choice", "'nonsense'", "reference"]),
    (["--batches", "0"], 2, ["--batches", "at least 1"]),
    (["--clamp", "-1"], 2, ["--clamp", "0 (off) or a positive luminance", "-1"]),
    (["--clamp", "bright"], 2, ["--clamp", "'bright'", "not a luminance"]),
])
def test_bad_arguments(npz, tmp_path, args, code, words):
    out = tmp_path / "x.exr"
    proc = run("bake", npz, "--out", out, *args)
    assert proc.returncode == code
    line = one_error_line(proc)
    for w in words:
        assert w in line, (w, line)
    assert not out.exists()


def test_no_command_is_a_usage_error():
    proc = run()
    assert proc.returncode == 2
    assert "required" in one_error_line(proc)


def test_missing_input(tmp_path):
    missing = tmp_path / "nope.npz"
    proc = run("bake", missing)
    assert proc.returncode == 3
    assert one_error_line(proc) == f"smbs_addon: error: input '{missing}' does not exist"


def test_text_file_input(tmp_path):
    txt = tmp_path / "scene.txt"
    txt.write_text("not a scene\n")
    proc = run("bake", txt)
    assert proc.returncode == 1
    assert one_error_line(proc) == f"smbs_addon: error: input '{txt}': expected a .blend or .npz file"


def test_unwritable_output_folder(npz):
    proc = run("bake", npz, "--out", "/nonexistent/x.exr")
    assert proc.returncode == 3
    assert one_error_line(proc) == "smbs_addon: error: output folder '/nonexistent' does not exist"
    proc = run("bake", npz, "--stats", "/nonexistent/s.json", "--out", npz.parent / "ok.exr")
    assert proc.returncode == 3
    assert "output folder '/nonexistent' does not exist" in one_error_line(proc)


@pytest.mark.parametrize("damage", ["random", "truncated", "damaged"])
def test_corrupt_npz(npz, tmp_path, damage):
    data = npz.read_bytes()
    bad = tmp_path / "bad.npz"
    if damage == "random":
        bad.write_bytes(np.random.default_rng(0).bytes(2048))
    elif damage == "truncated":
        bad.write_bytes(data[: len(data) // 2])
    else:  # zip directory intact, a compressed member overwritten (zlib error)
        b = bytearray(data)
        b[len(b) // 3:len(b) // 3 + 64] = b"\xff" * 64
        bad.write_bytes(bytes(b))
    proc = run("bake", bad, "--out", tmp_path / "x.exr")
    # a scene file that cannot be read is reported as a scene error (SceneError)
    assert proc.returncode == 1, proc.stderr
    line = one_error_line(proc)
    assert str(bad) in line and "not a readable scene .npz" in line
    assert not (tmp_path / "x.exr").exists()


def test_invalid_scene_values(npz, tmp_path):
    with np.load(npz) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["light_color"] = -arrays["light_color"]
    bad = tmp_path / "negative.npz"
    np.savez_compressed(bad, **arrays)
    proc = run("bake", bad, "--out", tmp_path / "x.exr")
    assert proc.returncode == 1
    assert one_error_line(proc) == "smbs_addon: error: light 'Disk': negative power"


def test_bake_blend(tmp_path):
    if not MIRROR_BLEND.is_file():
        pytest.skip(f"{MIRROR_BLEND} not built (python sample_blends/build.py)")
    pytest.importorskip("bpy")
    out = tmp_path / "mirror.exr"
    proc = run("bake", MIRROR_BLEND, "--spp", 1, "--batches", 2, "--out", out)
    assert proc.returncode == 0, proc.stderr
    img, meta = read_exr(out)
    stats = json.loads(out.with_suffix(".json").read_text())
    assert [img.shape[1], img.shape[0]] == stats["resolution"]
    assert meta["spp"] == 1 and meta["seed"] == 0
    assert img.max() > 0 and np.all(np.isfinite(img))
    assert re.search(r"^scene '.+': auto, \d+x\d+, ", proc.stdout, re.M), proc.stdout
    # the plan, before the bake, and auto's choice in it
    assert re.search(r"^plan:\n  Light -> Mirror \(reflection\) -> Floor\n  auto, Light: ", proc.stdout, re.M), proc.stdout


def test_bake_a_textured_floor_blend(tmp_path):
    """A .blend whose floor's Base Color is a Checker Texture (the conformance suite's
    checker_floor), baked by the command line: it says how much of the layer lies on textured
    receivers, and the EXR stands on its own: R, G, B hold the whole caustic (per unit albedo times the
    Diffuse Color pass Cycles rendered for the bake), and per_albedo_* keep that part for relighting."""
    pytest.importorskip("bpy")
    from testkit import conformance_scenes

    blend = conformance_scenes.build("checker_floor", tmp_path)
    out = tmp_path / "checker.exr"
    proc = run("bake", blend, "--method", "reference", "--spp", 64, "--out", out, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "its colour is a texture" in proc.stderr
    share = re.search(r"^  textured receivers: (\d+)% of the layer", proc.stdout, re.M)
    assert share and 80 <= int(share.group(1)) <= 100, proc.stdout
    assert "in R, G, B times the Diffuse Color pass Cycles rendered for the bake" in proc.stdout
    rgb, meta = read_exr(out)
    assert meta["composite"].startswith("R, G, B: the whole caustic")
    assert json.loads(out.with_suffix(".json").read_text())["rgb"] == "complete"
    per = np.stack([read_exr(out, f"per_albedo_{c}")[0] for c in "RGB"], axis=2)
    assert per.shape == rgb.shape and per.max() > 0
    # the caustic's core lies on a warm square (Base Color 0.8, 0.7, 0.5): the colour channels hold it, tinted
    # so (the Principled BSDF's Diffuse Color pass is the base colour less what its specular layer takes, ~10%)
    core = per.mean(axis=2) > 0.5 * per.mean(axis=2).max()
    ratio = rgb[core].sum(axis=0) / per[core].sum(axis=0) / np.array([0.8, 0.7, 0.5])
    assert np.allclose(ratio, ratio.mean(), rtol=0.03) and 0.8 < ratio.mean() < 1.0, ratio
    std, _ = read_exr(out, "std")
    assert std[core].mean() > 0


def test_error_bar_and_price_in_output_json_and_exr(baked):
    """Every bake says how wrong it is and what half the error would cost, and the EXR
    carries the per-pixel standard deviation as a channel of its own."""
    proc, out = baked
    assert re.search(r"error: \+-\d+\.\d% relative RMS per caustic pixel; halving it would take about", proc.stdout)
    stats = json.loads(out.with_suffix(".json").read_text())
    assert 0 < stats["relative_error"] < 10 and stats["seconds_to_halve_error"] > 0
    _, meta = read_exr(out)
    assert meta["relative_error"] == pytest.approx(stats["relative_error"], rel=1e-6)
    std, _ = read_exr(out, "std")
    assert std.shape == (24, 32) and np.isfinite(std).all() and std.max() > 0


def test_time_and_noise_stop_rules(npz, tmp_path):
    out = tmp_path / "t.exr"
    proc = run("bake", npz, "--method", "reference", "--time", "0.5", "--out", out)
    assert proc.returncode == 0, proc.stderr
    stats = json.loads(out.with_suffix(".json").read_text())
    assert stats["stopped_by"] == "time" and stats["settings"]["time_budget"] == 0.5
    assert stats["settings"]["spp"] == stats["settings"]["batches"]  # one sample per pixel per batch
    proc = run("bake", npz, "--method", "reference", "--noise", "20%", "--time", "60", "--out", out)
    assert proc.returncode == 0, proc.stderr
    stats = json.loads(out.with_suffix(".json").read_text())
    assert stats["stopped_by"] == "noise" and stats["relative_error"] <= 0.2
    assert "stopped by the noise rule" in proc.stdout


def test_clamp_on_the_command_line(npz, tmp_path):
    """--clamp caps each manifold solution's luminance (BakeSettings.clamp_g): what it cut is in the
    statistics per light, and the output says the error bar leaves the clamp's bias out."""
    out = tmp_path / "clamped.exr"
    proc = run("bake", npz, "--method", "sms", "--spp", 2, "--batches", 2, "--clamp", 0.001, "--out", out)
    assert proc.returncode == 0, proc.stderr
    stats = json.loads(out.with_suffix(".json").read_text())
    assert stats["settings"]["clamp_g"] == 0.001
    assert stats["lights"]["Disk"]["clamped"] > 0 and stats["lights"]["Disk"]["clamped_energy"] > 0
    assert "not the clamp's bias (clamp_g 0.001)" in proc.stdout, proc.stdout


@pytest.mark.parametrize("args,needle", [(("--noise", "0"), "positive relative error"),
                                         (("--noise", "abc"), "not a relative error"),
                                         (("--time", "-1"), "positive number of seconds"),
                                         (("--time", "inf"), "positive number of seconds")])
def test_bad_stop_rules_are_refused(npz, args, needle):
    proc = run("bake", npz, *args)
    assert proc.returncode == 2
    assert needle in one_error_line(proc)


def test_compare_prints_an_equal_time_table_and_writes_its_numbers(npz, tmp_path):
    """``compare``: each method for the same seconds, one table (smbs_addon/compare.py; what the
    numbers mean is tested in tests/test_compare.py)."""
    out = tmp_path / "cmp.json"
    proc = run("compare", npz, "--time", 0.2, "--methods", "reference,mnee", "--out", out, "--seed", 4)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0] == "scene 'mirror'" and lines[1].startswith("equal time: 0.2 s per method")
    assert "| method | wall s | spp | rays | success | error (noise) | time for same error |" in lines
    assert next(ln for ln in lines if ln.startswith("| reference |")).endswith("| 1.00x |")
    assert "biased: MNEE's bias" in next(ln for ln in lines if ln.startswith("| mnee |"))
    rep = json.loads(out.read_text())
    assert [r["method"] for r in rep["rows"]] == ["reference", "mnee"]
    assert rep["rows"][0]["time_for_same_error"] == 1.0 and rep["rows"][1]["time_for_same_error"] is None
    assert [ln for ln in proc.stderr.splitlines()] == ["[1/2] reference: 0.2 s", "[2/2] mnee: 0.2 s"]


@pytest.mark.parametrize("args,code,words", [
    (["--methods", "sms,nonsense"], 2, ["--methods", "'sms,nonsense'", "reference"]),
    (["--methods", "sms,sms"], 2, ["--methods", "twice"]),
    (["--time", "0"], 2, ["--time", "positive number of seconds"]),
    (["--time", "1", "--reference", "nowhere.exr"], 3, ["reference 'nowhere.exr' does not exist"]),
])
def test_bad_compare_arguments(npz, args, code, words):
    proc = run("compare", npz, *(args if "--time" in args else ["--time", "1", *args]))
    assert proc.returncode == code
    line = one_error_line(proc)
    for w in words:
        assert w in line, (w, line)


def test_compare_needs_a_time(npz):
    proc = run("compare", npz)
    assert proc.returncode == 2 and "--time" in one_error_line(proc)
