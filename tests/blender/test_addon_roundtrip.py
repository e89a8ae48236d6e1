"""Round trip: open a sample scene, bake, render with Cycles.

The final (composited) image is Cycles' own render, with its caustics kept out,
plus the layer read back from the EXR the bake wrote; Cycles' render really has
the caustic kept out (and has it again once the layer is removed); re-baking
leaves one image, one EXR and one compositor setup.
"""
import importlib
import os

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from testkit import ROOT  # noqa: E402

MIRROR = ROOT / "sample_blends" / "mirror.blend"


def _render(scene, path, compositing):
    r = scene.render
    r.use_compositing = compositing
    r.image_settings.file_format = 'OPEN_EXR'
    r.image_settings.color_depth = '32'
    r.image_settings.color_mode = 'RGB'
    r.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return _read(path)


def _read(path):
    imageio = importlib.import_module("smbs_caustics.smbs_addon.io.exr")
    return imageio.read_exr(path)[0][..., :3]


def _ours(tree):
    return sorted(n.get("smbs_caustics") for n in tree.nodes if n.get("smbs_caustics"))


def test_mirror_round_trip(addon, tmp_path):
    if not MIRROR.is_file():
        pytest.skip(f"{MIRROR} not built (python sample_blends/build.py)")
    bpy.ops.wm.open_mainfile(filepath=str(MIRROR), load_ui=False)
    scene = bpy.context.scene
    scene.render.resolution_percentage = 50  # 80 x 60
    scene.cycles.samples = 16
    scene.render.threads_mode, scene.render.threads = 'FIXED', 2
    # Without caster flags Cycles path traces the mirror's caustic itself (with them it turns on
    # MNEE, which drops it), so keeping it out of Cycles' render is what the bake must do.
    for ob in scene.objects:
        ob.cycles.is_caustics_caster = False
    blend = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    s = scene.smbs_caustics
    s.method, s.spp, s.batches, s.seed = "smbs", 2, 2, 1
    assert s.output_path == "//caustics.exr"  # beside the blend file

    assert bpy.ops.smbs.bake_caustics() == {'FINISHED'}
    assert not scene.cycles.caustics_reflective and not scene.cycles.caustics_refractive
    layer = _read(tmp_path / "caustics.exr")
    assert layer.shape == (60, 80, 3)

    renders = tmp_path / "renders"
    renders.mkdir()
    plain = _render(scene, renders / "plain.exr", compositing=False)
    final = _render(scene, renders / "final.exr", compositing=True)
    assert np.allclose(final, plain + layer, rtol=1e-5, atol=1e-5), np.abs(final - plain - layer).max()

    region = layer.mean(axis=2) > 0.05 * np.percentile(layer.mean(axis=2), 99.5)
    assert region.sum() > 50
    caustic = layer.mean(axis=2)[region].mean()
    kept_out = plain.mean(axis=2)[region].mean()
    assert kept_out < 0.02 * caustic, (kept_out, caustic)  # Cycles' render has no caustic of its own

    # Re-baking twice: one image, one EXR (and its statistics), one compositor setup.
    for _ in range(2):
        assert bpy.ops.smbs.bake_caustics() == {'FINISHED'}
    assert [im.name for im in bpy.data.images if im.get("smbs_caustics")] == ["SMBS Caustics"]
    assert sorted(p.name for p in tmp_path.iterdir() if p.is_file()) == [
        "caustics.exr", "caustics.json", "shot.blend"]
    assert len(bpy.data.node_groups) == 1
    assert _ours(scene.compositing_node_group) == ["add", "image", "output", "render_layers"]
    final = _render(scene, renders / "final2.exr", compositing=True)
    assert np.allclose(final, plain + _read(tmp_path / "caustics.exr"), rtol=1e-5, atol=1e-5)

    # Without the layer, Cycles renders the caustic itself again.
    assert bpy.ops.smbs.remove_caustic_layer() == {'FINISHED'}
    assert scene.cycles.caustics_reflective and scene.cycles.caustics_refractive
    assert scene.compositing_node_group is None
    scene.cycles.samples = 128  # path tracing a small light through a mirror is noisy
    cycles_own = _render(scene, renders / "cycles.exr", compositing=True).mean(axis=2)[region].mean()
    print(f"caustic region: layer {caustic:.4f}, Cycles' own (128 spp) {cycles_own:.4f}, "
          f"kept out {kept_out:.2e}")
    assert cycles_own > 0.5 * caustic
    assert os.path.isfile(tmp_path / "caustics.exr")  # the file stays


def test_cycles_caustic_switches_also_stop_its_shadow_caustics(addon, tmp_path):
    """What the policy relies on: with Light Paths > Caustics off, Cycles' MNEE adds nothing
    (the render is the same with or without caster flags), while with them on it does."""
    glass = ROOT / "sample_blends" / "glass_sphere.blend"
    if not glass.is_file():
        pytest.skip(f"{glass} not built (python sample_blends/build.py)")

    def render(name, switches, casters):
        bpy.ops.wm.open_mainfile(filepath=str(glass), load_ui=False)
        scene = bpy.context.scene
        scene.render.resolution_percentage = 50
        scene.cycles.samples = 8
        scene.render.threads_mode, scene.render.threads = 'FIXED', 2
        scene.cycles.caustics_reflective = scene.cycles.caustics_refractive = switches
        if not casters:
            for ob in scene.objects:
                ob.cycles.is_caustics_caster = False
        return _render(scene, tmp_path / f"{name}.exr", compositing=False)

    off_mnee, off_plain = render("off_mnee", False, True), render("off_plain", False, False)
    assert off_mnee.tobytes() == off_plain.tobytes()
    on_mnee = render("on_mnee", True, True)
    assert on_mnee.sum() > off_mnee.sum() * 1.001  # MNEE's shadow caustic under the sphere
