"""Faults met through Blender: the Bake operator's words on a scene with no light, a linked library
that is missing. (bpy; neither bake traces anything, so no kernel is compiled.)

Issue 59, defect 8: on a scene with no light the Bake operator warned "caster 'Sphere' (not flagged
Cast Shadow Caustics) ... counted twice", though it is flagged. Weaker answer: a missing linked
library read as "no caustic caster"."""
from __future__ import annotations

import json
import math

import pytest

bpy = pytest.importorskip("bpy")

from testkit.blend import node_material as material, plane


def _flagged_scene():
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 24, 16
    floor = plane(scene, "Floor", 10, material("Floor", "ShaderNodeBsdfDiffuse", (0.8,) * 3), (0, 0, 0))
    sphere = plane(scene, "Sphere", 1.5, material("Mirror", "ShaderNodeBsdfGlossy", (0.9,) * 3, Roughness=0.0),
                   (0, 0, 1.5), (0, math.radians(-135), 0))
    sphere.cycles.is_caustics_caster = True
    floor.cycles.is_caustics_receiver = True
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location, cam.rotation_euler = (0, -6, 5), (math.radians(50), 0, 0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    return scene


def test_no_light_gives_no_false_warning(empty_bpy, addon, tmp_path):
    scene = _flagged_scene()
    scene.smbs_caustics.spp, scene.smbs_caustics.output_path = 1, str(tmp_path / "layer.exr")
    reports = []
    assert bpy.ops.smbs.bake_caustics() == {'FINISHED'}
    props = scene.smbs_caustics
    reports = props.bake_warnings + "\n" + props.cycles_note
    assert "not flagged" not in reports and "counted twice" not in reports, reports
    assert props.cycles_note.splitlines() == ["The layer is empty (nothing to bake: scene 'Scene' has no light).",
                                              "Cycles' own caustics are left as they are."]
    assert json.loads(props.last_stats)["nothing_to_bake"] == "scene 'Scene' has no light"
    assert scene.cycles.caustics_reflective and scene.cycles.caustics_refractive  # left alone


def test_an_unflagged_caster_is_still_named(empty_bpy, addon, tmp_path):
    """The warning stays where it is true: a glossy object Cycles' flags leave out, with a light."""
    scene = _flagged_scene()
    other = plane(scene, "Other", 1.0, material("Chrome", "ShaderNodeBsdfGlossy", (0.9,) * 3, Roughness=0.0),
                  (1.5, 0, 1.0), (0, math.radians(-120), 0))
    other.cycles.is_caustics_caster = False
    light = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", 'POINT'))
    light.location = (-2, 0, 1.5)
    scene.collection.objects.link(light)
    light.data.cycles.is_caustics_light = True
    from smbs_caustics.operators import policy
    from smbs_caustics.smbs_addon.baking.plan import make_plan
    from smbs_caustics.smbs_addon.blender.export import export_scene

    data = export_scene(scene)
    cov = policy.coverage(data, make_plan(data, "AUTO"), "AUTO")
    assert cov.left_to_cycles == ["caster 'Other' (not flagged Cast Shadow Caustics)"]


def test_a_missing_linked_library_is_named(empty_bpy, tmp_path):
    from smbs_addon.blender.export import export_scene

    lib, shot = tmp_path / "lib.blend", tmp_path / "shot.blend"
    me = bpy.data.meshes.new("Ball")
    me.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    bpy.context.scene.collection.objects.link(bpy.data.objects.new("Ball", me))
    bpy.ops.wm.save_as_mainfile(filepath=str(lib))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    with bpy.data.libraries.load(str(lib), link=True, relative=True) as (_, dst):
        dst.objects = ["Ball"]
    for ob in dst.objects:
        bpy.context.scene.collection.objects.link(ob)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam
    bpy.ops.wm.save_as_mainfile(filepath=str(shot), relative_remap=True)
    lib.unlink()
    bpy.ops.wm.open_mainfile(filepath=str(shot))
    warnings = []
    export_scene(bpy.context.scene, warn=warnings.append)
    assert (f"linked library '//lib.blend' is missing (no file at {lib}): 'Ball' is an empty placeholder and bakes "
            f"as nothing") in warnings, warnings
