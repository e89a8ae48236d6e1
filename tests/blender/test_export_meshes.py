"""Blender scene -> Scene arrays (smbs_addon.blender: export_scene and the modules it calls) with tiny
scenes built in bpy: meshes and objects: triangles, transforms, normals, UVs, modifiers, instances, what
is skipped, per-face materials and Cycles' caustic flags."""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from smbs_addon.scene import arrays as S  # noqa: E402
from testkit.blend import (add_camera, cube_mesh, export, link, mesh_with, node_material, obj_tris,  # noqa: E402
                           sphere_mesh)

pytestmark = [pytest.mark.bpy, pytest.mark.usefixtures("empty_bpy")]


def face_normals(v):
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def test_cube_has_twelve_triangles_and_outward_flat_normals():
    add_camera()
    link(bpy.data.objects.new("Cube", cube_mesh()))
    sc, warnings = export()
    assert sc.n_tris == 12 and sc.object_names == ["Cube"]
    v, n = obj_tris(sc, "Cube")
    assert np.allclose(np.abs(v), 1.0)
    centroid = v.mean(axis=1)
    fn = face_normals(v)
    assert np.all(np.einsum("ij,ij->i", fn, centroid) > 0)  # winding gives outward normals
    assert np.allclose(n, fn[:, None, :])  # flat: the face normal at all three corners
    assert not sc.object_smooth[0]
    assert sc.mat_names == ["<default diffuse>"] and sc.mat_kind[0] == S.DIFFUSE
    assert np.allclose(sc.mat_color[0], 0.8)
    assert warnings == []


def test_world_transform_is_applied():
    add_camera()
    ob = link(bpy.data.objects.new("Cube", cube_mesh(size=1.0)))
    ob.location = (1.0, 2.0, 3.0)
    ob.rotation_euler = (0.3, -0.4, 1.1)
    ob.scale = (1.0, 2.0, 0.5)
    bpy.context.view_layer.update()
    M = np.array(ob.matrix_world)
    local = np.array([v.co[:] for v in ob.data.vertices])
    expect = local @ M[:3, :3].T + M[:3, 3]
    sc, _ = export()
    v, n = obj_tris(sc, "Cube")
    got = v.reshape(-1, 3)
    d = np.linalg.norm(got[:, None, :] - expect[None, :, :], axis=2).min(axis=1)
    assert d.max() < 1e-6
    assert np.allclose(got.mean(axis=0), [1, 2, 3])
    # normals: unit, outward, perpendicular to the transformed faces
    assert np.allclose(np.linalg.norm(n, axis=2), 1.0)
    assert np.all(np.einsum("ij,ij->i", n[:, 0], v.mean(axis=1) - [1, 2, 3]) > 0)
    e1 = v[:, 1] - v[:, 0]
    assert np.allclose(np.einsum("ij,ij->i", n[:, 0], e1), 0, atol=1e-9)


def test_smooth_normals_use_the_inverse_transpose():
    add_camera()
    ob = link(bpy.data.objects.new("Ball", sphere_mesh(smooth=True)))
    ob.location = (0.0, 0.0, 2.0)
    sc0, _ = export()
    v0, n0 = obj_tris(sc0, "Ball")
    assert sc0.object_smooth[0]
    radial = (v0 - [0, 0, 2]) / np.linalg.norm(v0 - [0, 0, 2], axis=2, keepdims=True)
    assert np.einsum("tci,tci->tc", n0, radial).min() > 0.97  # vertex normals: nearly radial
    assert not np.allclose(n0[:, 0], n0[:, 1])  # interpolated, not per face
    ob.scale = (2.0, 1.0, 1.0)
    sc1, _ = export()
    v1, n1 = obj_tris(sc1, "Ball")
    assert np.allclose(v1 - [0, 0, 2], (v0 - [0, 0, 2]) * [2, 1, 1])
    expect = n0 * [0.5, 1.0, 1.0]  # inverse transpose of diag(2, 1, 1)
    expect /= np.linalg.norm(expect, axis=2, keepdims=True)
    assert np.allclose(n1, expect, atol=1e-6)


def test_flat_sphere_uses_face_normals():
    add_camera()
    link(bpy.data.objects.new("Ball", sphere_mesh(smooth=False)))
    sc, _ = export()
    v, n = obj_tris(sc, "Ball")
    assert not sc.object_smooth[0]
    assert np.allclose(n, face_normals(v)[:, None, :], atol=1e-6)
    assert not np.allclose(n[:, 0], n[:, 1]) or np.allclose(n[:, 0], n[:, 2])


def test_mixed_smooth_and_flat_faces():
    add_camera()
    me = sphere_mesh(smooth=True)
    me.polygons[0].use_smooth = False
    link(bpy.data.objects.new("Ball", me))
    sc, _ = export()
    v, n = obj_tris(sc, "Ball")
    fn = face_normals(v)
    flat = np.all(np.isclose(n, fn[:, None, :], atol=1e-6), axis=(1, 2))
    assert 1 <= flat.sum() <= 2  # the one flat face (a triangle at the pole, or a quad)
    assert sc.object_smooth[0]


def test_negative_scale_keeps_winding_consistent_with_normals():
    add_camera()
    ob = link(bpy.data.objects.new("Cube", cube_mesh()))
    ob.scale = (-1.0, 1.0, 1.0)
    sc, _ = export()
    v, n = obj_tris(sc, "Cube")
    fn = face_normals(v)
    assert np.all(np.einsum("ij,ij->i", fn, v.mean(axis=1)) > 0)
    assert np.allclose(n, fn[:, None, :])


def test_uvs_come_from_the_active_layer():
    add_camera()
    me = cube_mesh()
    me.uv_layers.new(name="Other")
    layer = me.uv_layers.new(name="XY")
    me.uv_layers.active = layer
    for loop in me.loops:  # uv = the corner's vertex (x + 10, y)
        co = me.vertices[loop.vertex_index].co
        layer.uv[loop.index].vector = (co.x + 10.0, co.y)
    ob = link(bpy.data.objects.new("Cube", me))
    ob.location = (0, 0, 4)
    sc, _ = export()
    assert sc.tri_uvs.shape == (12, 3, 2)
    assert np.allclose(sc.tri_uvs[..., 0], sc.tri_vertices[..., 0] + 10.0)
    assert np.allclose(sc.tri_uvs[..., 1], sc.tri_vertices[..., 1])


def test_no_uv_layer_gives_default_uvs():
    add_camera()
    link(bpy.data.objects.new("Cube", cube_mesh()))
    sc, _ = export()
    assert np.allclose(sc.tri_uvs, [[0, 0], [1, 0], [0, 1]])


@pytest.mark.parametrize("kind,expected", [("SUBSURF", 6 * 4 * 2), ("ARRAY", 3 * 12)])
def test_modifiers_are_applied(kind, expected):
    add_camera()
    ob = link(bpy.data.objects.new("Cube", cube_mesh()))
    mod = ob.modifiers.new("Mod", kind)
    if kind == "SUBSURF":
        mod.levels = mod.render_levels = 1
    else:
        mod.count = 3
    n_polys = len(ob.data.polygons)
    sc, warnings = export()
    assert sc.n_tris == expected
    assert len(ob.data.polygons) == n_polys  # the original mesh is untouched
    assert warnings == []


def test_subdivision_viewport_level_differs_from_render_level_warns():
    add_camera()
    ob = link(bpy.data.objects.new("Cube", cube_mesh()))
    mod = ob.modifiers.new("Subdivision", "SUBSURF")
    mod.levels, mod.render_levels = 1, 2
    sc, warnings = export()
    assert sc.n_tris == 48
    assert any("'Cube'" in w and "render level 2" in w for w in warnings)


def test_collection_instances():
    add_camera()
    col = bpy.data.collections.new("Parts")
    inner = bpy.data.objects.new("Part", cube_mesh())
    inner.cycles.is_caustics_caster = True
    col.objects.link(inner)  # not linked to the scene: only reachable through the instances
    for i, x in enumerate((-3.0, 3.0)):
        e = link(bpy.data.objects.new(f"Inst{i}", None))
        e.instance_type = "COLLECTION"
        e.instance_collection = col
        e.location = (x, 0.0, 0.0)
    sc, _ = export()
    assert sc.n_tris == 24
    assert sc.object_names == ["Inst0/Part", "Inst1/Part"]
    assert np.all(sc.object_caster)
    for name, x in (("Inst0/Part", -3.0), ("Inst1/Part", 3.0)):
        v, _ = obj_tris(sc, name)
        assert np.allclose(v.reshape(-1, 3).mean(axis=0), [x, 0, 0])
    assert sc.object_visibility.size == 0
    # Ray Visibility: an instance hides what its object or its instancer hides (Cycles' inheritance)
    bpy.data.objects["Inst1"].visible_camera = False
    inner.visible_diffuse = False
    sc, _ = export()
    assert sc.object_visibility.tolist() == [S.RAY_ALL & ~S.RAY_DIFFUSE, S.RAY_ALL & ~S.RAY_DIFFUSE & ~S.RAY_CAMERA]


def test_linked_duplicates_share_data_but_get_their_own_transform():
    add_camera()
    me = cube_mesh()
    a = link(bpy.data.objects.new("A", me))
    b = link(bpy.data.objects.new("B", me))
    b.location = (0, 0, 5)
    b.modifiers.new("Array", "ARRAY").count = 2
    sc, _ = export()
    assert sc.object_names == ["A", "B"]
    assert len(obj_tris(sc, "A")[0]) == 12 and len(obj_tris(sc, "B")[0]) == 24
    assert np.isclose(obj_tris(sc, "B")[0][..., 2].mean(), 5.0)
    assert a.data is b.data


def test_geometry_nodes_instances():
    add_camera()
    host = link(bpy.data.objects.new("Host", bpy.data.meshes.new("pts")))
    host.data.from_pydata([(0, 0, 5), (2, 0, 5), (4, 0, 5)], [], [])
    ng = bpy.data.node_groups.new("Scatter", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    gi, go = ng.nodes.new("NodeGroupInput"), ng.nodes.new("NodeGroupOutput")
    iop = ng.nodes.new("GeometryNodeInstanceOnPoints")
    cube = ng.nodes.new("GeometryNodeMeshCube")
    ng.links.new(gi.outputs[0], iop.inputs["Points"])
    ng.links.new(cube.outputs["Mesh"], iop.inputs["Instance"])
    ng.links.new(iop.outputs[0], go.inputs[0])
    host.modifiers.new("GN", "NODES").node_group = ng
    sc, _ = export()
    assert sc.n_tris == 36
    centres = sorted(np.round(sc.tri_vertices[sc.tri_object == i].reshape(-1, 3).mean(0), 6)[0]
                     for i in range(len(sc.object_names)))
    assert centres == [0.0, 2.0, 4.0]


def test_hidden_for_render_objects_are_skipped():
    add_camera()
    link(bpy.data.objects.new("Shown", cube_mesh()))
    link(bpy.data.objects.new("Hidden", cube_mesh())).hide_render = True
    sc, _ = export()
    assert sc.object_names == ["Shown"]


def test_per_face_materials():
    add_camera()
    me = cube_mesh()
    me.materials.append(node_material("Red", "ShaderNodeBsdfDiffuse", Color=(1.0, 0.0, 0.0)))
    me.materials.append(node_material("Blue", "ShaderNodeBsdfDiffuse", Color=(0.0, 0.0, 1.0)))
    for p in me.polygons:
        p.material_index = 1 if p.index < 2 else 0
    link(bpy.data.objects.new("Cube", me))
    sc, _ = export()
    names = [sc.mat_names[m] for m in sc.tri_material]
    assert names.count("Blue") == 4 and names.count("Red") == 8
    assert np.allclose(sc.mat_color[sc.mat_names.index("Blue")], [0, 0, 1])


def test_cycles_caustic_flags():
    add_camera()
    a = mesh_with(None, "Caster")
    a.cycles.is_caustics_caster = True
    b = mesh_with(None, "Receiver")
    b.cycles.is_caustics_receiver = True
    mesh_with(None, "Plain")
    sc, _ = export()
    assert sc.object_names == ["Caster", "Receiver", "Plain"]
    assert sc.object_caster.tolist() == [True, False, False]
    assert sc.object_receiver.tolist() == [False, True, False]
