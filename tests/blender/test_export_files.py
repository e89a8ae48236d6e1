"""Blender scene -> Scene arrays (smbs_addon.blender: export_scene and the modules it calls) with tiny
scenes built in bpy: whole files and safety: the sample scenes, library links, the Light Paths limits,
the scene left as it was."""
from __future__ import annotations

import math
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from smbs_addon.scene import bump  # noqa: E402
from smbs_addon.scene import arrays as S  # noqa: E402
from testkit import SAMPLE_BLENDS  # noqa: E402
from testkit.blend import (add_camera, add_light, cube_mesh, export, link, mesh_with, node_material,  # noqa: E402
                           obj_tris)

pytestmark = [pytest.mark.bpy, pytest.mark.usefixtures("empty_bpy")]



def test_mirror_sample_blend():
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLE_BLENDS / "mirror.blend"))
    sc, warnings = export()
    assert warnings == []
    assert sc.object_names == ["Floor", "Mirror"] and sc.n_tris == 4
    assert sc.object_caster.tolist() == [False, True]
    assert sc.object_receiver.tolist() == [True, False]
    assert sc.object_smooth.tolist() == [False, True]
    fl, mi = sc.mat_names.index("Floor"), sc.mat_names.index("Mirror")
    assert sc.mat_kind[fl] == S.DIFFUSE and np.allclose(sc.mat_color[fl], 0.8)
    assert sc.mat_kind[mi] == S.CONDUCTOR and sc.mat_fresnel[mi] == S.FRESNEL_NONE
    assert np.allclose(sc.mat_color[mi], 0.9) and sc.mat_roughness[mi] == 0
    v, n = obj_tris(sc, "Mirror")
    a = math.radians(157.5)  # local +Z rotated about Y
    assert np.allclose(n.reshape(-1, 3), [math.sin(a), 0, math.cos(a)], atol=1e-6)
    assert np.allclose(v.reshape(-1, 3).mean(axis=0), [-3, 0, 4])
    assert sc.light_names == ["Light"] and sc.light_type[0] == S.AREA
    assert sc.light_shape[0] == S.DISK and np.allclose(sc.light_size[0], 0.5)
    assert np.allclose(sc.light_color[0], 1000.0) and sc.light_caustics[0]
    assert np.isclose(sc.light_spread[0], math.pi)
    assert np.allclose(sc.light_matrix[0][:3, 3], [-3, 0, 2])
    assert np.allclose(-sc.light_matrix[0][:3, 2], [0, 0, 1], atol=1e-6)  # faces up
    c = sc.camera
    assert c.lens == 35 and (c.width, c.height) == (160, 120) and c.filter_width == 1.5
    assert np.allclose(c.matrix_world[:3, 3], [1.3, -8.5, 6.5])
    fwd = -c.matrix_world[:3, 2]
    to_target = np.array([1.3, 0, 0]) - [1.3, -8.5, 6.5]
    assert np.allclose(fwd, to_target / np.linalg.norm(to_target), atol=1e-6)
    assert np.allclose(sc.world_color, 0)


def test_sample_blends_export_cleanly():
    for name in ("glass_sphere", "water"):
        bpy.ops.wm.open_mainfile(filepath=str(SAMPLE_BLENDS / f"{name}.blend"))
        sc, warnings = export()
        assert warnings == [] and sc.n_tris > 0 and np.any(sc.object_caster)
    # water: a point light and a sun tilted 30 degrees towards -x, ortho camera
    assert sc.light_type.tolist() == [S.POINT, S.SUN]
    assert np.isclose(sc.light_radius[0], 0.05) and not sc.light_soft_falloff[0]
    assert np.allclose(sc.light_color, [[1000] * 3, [3] * 3])
    assert np.allclose(-sc.light_matrix[1][:3, 2], [-0.5, 0, -math.sqrt(3) / 2], atol=1e-6)
    assert sc.camera.type == S.ORTHO and sc.camera.ortho_scale == 2


def test_the_waves_sample_exports_its_bumps():
    """waves.blend: a flat quad of water whose Glass BSDF's Normal is a Bump of a Noise Texture (Generated
    coordinates: the bumps flip with the surface, so no normals from behind). The quad is cut into
    bump.TARGET_TRIANGLES triangles whose normals the bump tilts (up to ~10 degrees, 3 in the median),
    said nowhere, as a bump the export bakes."""
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLE_BLENDS / "waves.blend"))
    sc, warnings = export()
    assert warnings == []
    v, n = obj_tris(sc, "WaterSurface")
    assert len(v) == bump.TARGET_TRIANGLES and np.allclose(v[..., 2], 0.6)
    tilt = np.degrees(np.arccos(np.clip(n[..., 2], -1.0, 1.0)))
    assert 1.5 < np.median(tilt) < 6.0 and 6.0 < tilt.max() < 20.0, (np.median(tilt), tilt.max())
    assert sc.tri_normals_back.shape == (0, 3, 3)
    assert len(obj_tris(sc, "PoolFloor")[0]) == 128


def test_export_does_not_change_the_scene():
    add_camera()
    ob = link(bpy.data.objects.new("Cube", cube_mesh()))
    ob.modifiers.new("Subdivision", "SUBSURF").levels = 1
    ob.data.materials.append(node_material("Foo", "ShaderNodeMixShader"))
    add_light(bpy.context.scene, "Area", "AREA", scale=(2, 2, 2), energy=10.0, caustics=False)
    col = bpy.data.collections.new("Parts")
    col.objects.link(bpy.data.objects.new("Part", cube_mesh("PartMesh")))
    e = link(bpy.data.objects.new("Inst", None))
    e.instance_type, e.instance_collection = "COLLECTION", col

    def snapshot():
        return dict(
            counts={k: len(getattr(bpy.data, k)) for k in (
                "objects", "meshes", "materials", "lights", "cameras", "collections", "images",
                "node_groups", "worlds")},
            verts=len(ob.data.vertices), mods=[m.name for m in ob.modifiers],
            matrix=[tuple(r) for r in ob.matrix_world], light_scale=tuple(bpy.data.objects["Area"].scale),
            nodes=len(bpy.data.materials["Foo"].node_tree.nodes), is_dirty=bpy.data.is_dirty)

    before = snapshot()
    export()
    export()
    assert snapshot() == before


def test_library_linked_objects_are_exported(tmp_path):
    lib = tmp_path / "lib.blend"
    ob = link(bpy.data.objects.new("LibCube", cube_mesh("LibCubeMesh")))
    ob.location = (0, 0, 7)
    ob.cycles.is_caustics_caster = True
    ob.data.materials.append(node_material("LibGlass", "ShaderNodeBsdfGlass", IOR=1.5))
    bpy.ops.wm.save_as_mainfile(filepath=str(lib))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    with bpy.data.libraries.load(str(lib), link=True) as (src, dst):
        dst.objects = ["LibCube"]
    linked = dst.objects[0]
    assert linked.library is not None
    link(linked)
    add_camera()
    sc, warnings = export()
    assert sc.object_names == ["LibCube"] and sc.n_tris == 12 and sc.object_caster[0]
    assert np.isclose(sc.tri_vertices[..., 2].mean(), 7.0)
    assert sc.mat_kind[0] == S.DIELECTRIC and warnings == []


def test_light_paths_bounce_limits():
    """Cycles' Light Paths > Max Bounces go with the scene (bounces.py applies them): Blender's
    defaults are 12 in all, 4 diffuse, 4 glossy, 12 transmission."""
    add_camera()
    mesh_with(None)
    sc, _ = export()
    assert sc.light_paths.tolist() == [12, 4, 4, 12]
    c = bpy.context.scene.cycles
    c.max_bounces, c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces = 8, 2, 1, 6
    sc, _ = export()
    assert sc.light_paths.tolist() == [8, 2, 1, 6]
