"""Corrupt and hostile inputs on the command line: a .npz whose arrays have the wrong types or
ranges, a truncated one, a folder for a file, samples past counting, a reference of the wrong size,
a scene whose caster is scaled to zero, many lights. Each case checks the exit code and the message,
which names the object, material, light or camera (never an internal array where an owner exists).

Issue 59, defect 6: a material IOR of strings gave a TypeError traceback; a camera resolution of -48
baked a 1 x 36 image and exited 0. The weaker answers: a folder read as "does not exist", --spp 1e20
sat at 0% with no estimate, a reference of the wrong size was found only after every bake, an
object scaled by zero gave a zero layer without saying why, 200 lights cost 100x without a word.
"""
from __future__ import annotations

import re
import zipfile

import numpy as np
import pytest

from testkit import scenes
from testkit.faults import assert_no_traceback, previous_output, run, save_mirror, signal_after, start


@pytest.fixture(scope="module")
def npz(tmp_path_factory):
    return save_mirror(tmp_path_factory.mktemp("inputs") / "mirror.npz")


def _rewrite(src, dst, **arrays):
    data = dict(np.load(src))
    data.update(arrays)
    np.savez(dst, **data)
    return dst


def _error(proc, code):
    assert proc.returncode == code, proc.stderr
    assert_no_traceback(proc)
    lines = [ln for ln in proc.stderr.strip().splitlines() if not ln.startswith("warning:")]
    assert len(lines) == 1, proc.stderr
    return lines[-1]


def test_an_ior_of_text(npz, tmp_path):
    n = len(np.load(npz)["mat_ior"])
    bad = _rewrite(npz, tmp_path / "ior.npz", mat_ior=np.array(["1.5"] * n))
    line = _error(run("bake", bad, "--spp", 1, "--out", tmp_path / "x.exr"), 1)
    assert line == f"smbs_addon: error: {bad}: material 'floor': its IOR must be a number, the file holds text ('1.5')"


def test_a_light_power_of_text(npz, tmp_path):
    bad = _rewrite(npz, tmp_path / "power.npz", light_color=np.array([["a", "b", "c"]]))
    line = _error(run("bake", bad, "--spp", 1, "--out", tmp_path / "x.exr"), 1)
    assert line == f"smbs_addon: error: {bad}: light 'Disk': its power must be a number, the file holds text ('a')"


def test_a_negative_resolution(npz, tmp_path):
    bad = _rewrite(npz, tmp_path / "res.npz", **{"camera.resolution_x": np.asarray(-48)})
    out = tmp_path / "x.exr"
    line = _error(run("bake", bad, "--spp", 1, "--out", out), 1)
    assert line == "smbs_addon: error: camera resolution -48 x 24 at 100%: each must be a whole number, at least 1"
    assert not out.exists()


def test_a_truncated_npz(npz, tmp_path):
    bad = tmp_path / "cut.npz"
    bad.write_bytes(npz.read_bytes()[: npz.stat().st_size // 2])
    line = _error(run("bake", bad, "--spp", 1, "--out", tmp_path / "x.exr"), 1)
    assert line.startswith(f"smbs_addon: error: {bad}: not a readable scene .npz")


def test_an_npz_member_that_is_no_array(npz, tmp_path):
    bad = tmp_path / "member.npz"
    bad.write_bytes(npz.read_bytes())
    with zipfile.ZipFile(bad, "a") as z, pytest.warns(UserWarning):
        z.writestr("mat_ior.npy", b"\x93NUMPY garbage")
    line = _error(run("bake", bad, "--spp", 1, "--out", tmp_path / "x.exr"), 1)
    assert line.startswith(f"smbs_addon: error: {bad}: not a readable scene .npz (")


def test_an_input_folder(tmp_path):
    folder = tmp_path / "shot.npz"
    folder.mkdir()
    line = _error(run("bake", folder, "--out", tmp_path / "x.exr"), 3)
    assert line == f"smbs_addon: error: input '{folder}' is a folder, not a .blend or .npz file"


def test_samples_past_counting_are_refused_with_an_estimate(npz, tmp_path):
    line = _error(run("bake", npz, "--spp", 10 ** 20, "--out", tmp_path / "x.exr", timeout=120), 2)
    assert line.startswith("smbs_addon: error: spp 100000000000000000000 asks for 7.68e+22 samples per light over "
                           "the 32 x 24 pixels, more than a bake counts (2.81e+14); it would take more than ")
    assert line.endswith("years even at 1e+07 samples a second; at most spp 366503875925 here")


def test_keep_partial_needs_a_time_or_noise_rule(npz, tmp_path):
    line = _error(run("bake", npz, "--keep-partial", "--out", tmp_path / "x.exr"), 2)
    assert line.startswith("smbs_addon: error: --keep-partial keeps the whole batches")


def test_a_reference_of_the_wrong_size_is_refused_before_the_bakes(npz, tmp_path):
    ref, _ = previous_output(tmp_path, "ref.exr")  # 32 x 24: the scene's is 32 x 24 too; make it 16 x 12
    from smbs_addon.io.exr import write_exr

    write_exr(ref, np.ones((12, 16, 3)))
    proc = run("compare", npz, "--time", 30, "--methods", "mnee", "--reference", ref)
    line = _error(proc, 1)
    assert line == (f"smbs_addon: error: reference '{ref}' is 16 x 12 pixels, the scene's caustic layer 32 x 24 "
                    f"(camera resolution, its percentage and crop to the render border)")
    assert "[1/1]" not in proc.stderr  # no bake began


def test_a_caster_scaled_to_zero_says_so(tmp_path):
    sc = scenes.mirror_scene(resolution=(32, 24))
    mirror = sc.object_names.index("Mirror")
    tris = sc.tri_object == mirror
    sc.tri_vertices[tris] = sc.tri_vertices[tris].reshape(-1, 3).mean(axis=0)  # scaled by zero about its centre
    sc.save(tmp_path / "zero.npz")
    out = tmp_path / "x.exr"
    proc = run("bake", tmp_path / "zero.npz", "--spp", 1, "--out", out)
    assert proc.returncode == 0, proc.stderr
    assert ("nothing to bake: scene 'mirror' has no caustic caster: 'Mirror' has no area (scaled to zero?); the "
            "caustic layer is all zero") in proc.stdout, proc.stdout
    assert out.exists()


def test_many_lights_say_what_they_cost():
    from smbs_addon.baking.plan import make_plan
    from smbs_addon.scene.builder import SceneBuilder

    b = SceneBuilder("lamps")
    floor = b.material("floor", "diffuse", color=(0.8,) * 3)
    mirror = b.material("mirror", "conductor", color=(0.9,) * 3)
    b.plane("Floor", (0, 0, 0), 10, floor, receiver=True)
    b.plane("Mirror", (0, 0, 1.5), 1.5, mirror, normal=np.array([-1, 0, -1]) / np.sqrt(2), caster=True)
    for i in range(20):
        b.light(f"Lamp{i}", "POINT", location=(-2.0, 0.1 * i, 1.5 + 0.05 * i), power=10.0, radius=0.05)
    b.set_camera((0, -6, 5), (-0.2, 0, 0), lens=35, resolution_x=32, resolution_y=24)
    words = make_plan(b.build(), "OFF").words()
    assert ("20 lights take part: each light's caustic is traced on its own, so the bake costs about 20 times one "
            "light's (a time or noise rule shares its time among them)") in words


def test_a_bake_of_years_says_so_and_stops_on_ctrl_c(npz, tmp_path):
    """--spp 10^10 (under the count's limit): the progress estimates the time at the rate so far and
    warns once it is more than a day; Ctrl-C then stops it cleanly."""
    import signal

    proc = start("bake", npz, "--method", "mnee", "--spp", 10 ** 10, "--out", tmp_path / "x.exr")
    _, stderr = signal_after(proc, signal.SIGINT, "warning: at its rate so far this bake takes about ")
    assert proc.returncode == 130, stderr
    assert_no_traceback(stderr)
    warning = next(ln for ln in stderr.splitlines() if ln.startswith("warning: at its rate"))
    # days or years: the estimate follows this machine's rate, and only "more than a day" is promised
    assert re.fullmatch(r"warning: at its rate so far this bake takes about [0-9.]+ (days|years) more; fewer "
                        r"samples \(--spp\) or a --time or --noise rule end it sooner", warning), warning
    assert not (tmp_path / "x.exr").exists()
