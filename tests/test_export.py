"""Blender scene -> Scene arrays (smbs_addon.blender: export_scene and the modules it calls), with tiny
scenes built in bpy."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
bmesh = pytest.importorskip("bmesh")

from smbs_addon.scene import bump  # noqa: E402
from smbs_addon.scene import arrays as S  # noqa: E402
from smbs_addon.core.errors import SceneError  # noqa: E402
from smbs_addon.blender import cycles_passes  # noqa: E402
from smbs_addon.blender.export import export_scene  # noqa: E402
from smbs_addon.shading.microfacet import distributions  # noqa: E402

pytestmark = pytest.mark.bpy
SAMPLES = Path(__file__).resolve().parent.parent / "sample_blends"


@pytest.fixture(autouse=True)
def fresh():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    yield


# ------------------------------------------------------------------------------ helpers
def scene():
    return bpy.context.scene


def add_camera(location=(0, -10, 0), rotation=(math.pi / 2, 0, 0), **props):
    cam = bpy.data.cameras.new("Cam")
    for k, v in props.items():
        setattr(cam, k, v)
    ob = bpy.data.objects.new("Cam", cam)
    ob.location = location
    ob.rotation_euler = rotation
    scene().collection.objects.link(ob)
    scene().camera = ob
    return ob


def link(ob, collection=None):
    (collection or scene().collection).objects.link(ob)
    return ob


def cube_mesh(name="Cube", size=2.0):
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=size)
    bm.to_mesh(me)
    bm.free()
    return me


def sphere_mesh(name="Sphere", radius=1.0, smooth=True):
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=16, v_segments=8, radius=radius)
    bm.to_mesh(me)
    bm.free()
    for p in me.polygons:
        p.use_smooth = smooth
    return me


def material(name, node_type, **inputs):
    m = bpy.data.materials.new(name)
    nt = m.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    node = nt.nodes.new(node_type)
    for k, v in inputs.items():
        sock = node.inputs[k]
        sock.default_value = (*v, 1.0) if isinstance(v, tuple) and len(v) == 3 else v
    nt.links.new(node.outputs[0], out.inputs["Surface"])
    return m


def mesh_with(mat, name="Thing"):
    me = cube_mesh(name)
    if mat is not None:
        me.materials.append(mat)
    return link(bpy.data.objects.new(name, me))


def export(**kw):
    warnings = []
    sc = export_scene(scene(), warn=warnings.append, **kw)
    return sc, warnings


def obj_tris(sc, name):
    i = sc.object_names.index(name)
    return sc.tri_vertices[sc.tri_object == i], sc.tri_normals[sc.tri_object == i]


def face_normals(v):
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


# ---------------------------------------------------------------------------- geometry
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
    me.materials.append(material("Red", "ShaderNodeBsdfDiffuse", Color=(1.0, 0.0, 0.0)))
    me.materials.append(material("Blue", "ShaderNodeBsdfDiffuse", Color=(0.0, 0.0, 1.0)))
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


# ---------------------------------------------------------------------------- materials
def one_material(mat):
    add_camera()
    mesh_with(mat)
    sc, warnings = export()
    assert len(sc.mat_names) == 1
    return sc, warnings


def test_principled_diffuse():
    sc, w = one_material(material("P", "ShaderNodeBsdfPrincipled", **{
        "Base Color": (0.2, 0.3, 0.4), "Roughness": 0.7}))
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.mat_color[0], [0.2, 0.3, 0.4])
    assert np.isclose(sc.mat_roughness[0], 0.7) and w == []


def test_principled_metallic_is_a_schlick_conductor():
    sc, _ = one_material(material("Gold", "ShaderNodeBsdfPrincipled", **{
        "Base Color": (1.0, 0.8, 0.3), "Metallic": 1.0, "Roughness": 0.1}))
    assert sc.mat_kind[0] == S.CONDUCTOR and sc.mat_fresnel[0] == S.FRESNEL_SCHLICK
    assert np.allclose(sc.mat_color[0], [1.0, 0.8, 0.3]) and np.isclose(sc.mat_roughness[0], 0.1)


def test_a_partly_metallic_or_transmissive_principled_weighs_its_lobe():
    """Cycles weighs a Principled BSDF's metal by Metallic and its glass by (1 - Metallic) x
    Transmission; the lobe that weighs most is the material, at that weight. A metal's rest is a
    dielectric coat (a mirror at Roughness 0) over a diffuse, whose diffuse is said to be left out
    (mirror_alloy, Metallic 0.7: 1.44 of Cycles before, 0.95 with the metal's weight alone)."""
    from smbs_addon.shading.fresnel import fresnel_dielectric, fresnel_schlick, specular_weights

    sc, w = one_material(material("Alloy", "ShaderNodeBsdfPrincipled", **{
        "Base Color": (0.9, 0.6, 0.3), "Metallic": 0.8, "Roughness": 0.0}))
    assert sc.mat_kind[0] == S.CONDUCTOR and np.allclose(sc.mat_reflect_color[0], 0.8)
    assert w == ["material 'Alloy': Principled BSDF Metallic 0.8: the diffuse under its coat (20% of it) "
                 "receives no caustics"]
    cos = np.array([1.0, 0.5, 0.1])
    R, T = specular_weights(sc, np.zeros(3, np.int64), cos)
    m = sc.mat_reflect_color[0]  # the metal's Schlick, the coat's Fresnel (IOR 1.5) over the rest
    np.testing.assert_allclose(R, m * fresnel_schlick(cos, sc.mat_color[0])
                               + (1 - m) * fresnel_dielectric(cos, 1.5)[:, None], rtol=1e-6)
    assert not T.any()


def _metallic_node(name, mode="F82", **inputs):
    """A material whose Surface is a Metallic BSDF (Blender 4.3 on) of fresnel_type mode."""
    m = material(name, "ShaderNodeBsdfMetallic")
    node = next(n for n in m.node_tree.nodes if n.type == "BSDF_METALLIC")
    node.fresnel_type = mode
    for k, v in inputs.items():
        sock = node.inputs[k]
        sock.default_value = (*v, 1.0) if sock.type == "RGBA" and isinstance(v, tuple) else v
    return m


def test_the_metallic_bsdf_is_an_f82_tint_metal():
    """The Metallic BSDF's F82 mode: F0 the Base Color, the Edge Tint scales Cycles' F82 term (its
    reflectance at cos 1/7 is the tint times Schlick's there); its roughness, and nothing warned. It was
    'not supported; treated as diffuse': a gold ring made with it cast no caustic."""
    from smbs_addon.shading.fresnel import fresnel_schlick, specular_weights

    sc, w = one_material(_metallic_node("Gold", **{"Base Color": (0.95, 0.7, 0.3), "Edge Tint": (1.0, 0.6, 0.2),
                                                   "Roughness": 0.0}))
    assert sc.mat_kind[0] == S.CONDUCTOR and sc.mat_fresnel[0] == S.FRESNEL_SCHLICK and w == []
    np.testing.assert_allclose(sc.mat_color[0], [0.95, 0.7, 0.3], rtol=1e-6)
    R, _ = specular_weights(sc, np.zeros(2, np.int64), np.array([1.0, 1.0 / 7.0]))
    np.testing.assert_allclose(R[0], sc.mat_color[0], rtol=1e-12)
    np.testing.assert_allclose(R[1], np.array([1.0, 0.6, 0.2]) * fresnel_schlick(np.array([1.0 / 7.0]),
                                                                                 sc.mat_color[0])[0], rtol=1e-6)
    assert sc.mat_roughness[0] == 0.0


def test_the_metallic_bsdf_as_a_physical_conductor():
    """The Metallic BSDF's Physical Conductor mode: the index n + ik per channel (IOR, Extinction) and the
    Fresnel equations of a conductor; mat_color its head-on reflectance. Its roughness and distribution
    as the node has them; its thin film read (Scene.mat_film), an anisotropy said to be ignored."""
    import dataclasses

    from smbs_addon.shading.fresnel import specular_weights
    from smbs_addon.shading.thinfilm import conductor_film1

    m = _metallic_node("Copper", "PHYSICAL_CONDUCTOR", IOR=(0.27, 0.68, 1.32), Extinction=(3.61, 2.63, 2.29),
                       Roughness=0.3, Anisotropy=0.5, **{"Thin Film Thickness": 300.0})
    next(n for n in m.node_tree.nodes if n.type == "BSDF_METALLIC").distribution = "GGX"
    sc, w = one_material(m)
    assert sc.mat_kind[0] == S.CONDUCTOR and sc.mat_fresnel[0] == S.FRESNEL_CONDUCTOR
    n, k = np.array([0.27, 0.68, 1.32]), np.array([3.61, 2.63, 2.29])
    np.testing.assert_allclose(sc.mat_metal[0], np.concatenate([n, k]), rtol=1e-6)
    head_on = ((n - 1) ** 2 + k ** 2) / ((n + 1) ** 2 + k ** 2)
    np.testing.assert_allclose(sc.mat_color[0], head_on, rtol=1e-5)
    bare = dataclasses.replace(sc, mat_film=np.zeros((0, 2)))
    np.testing.assert_allclose(specular_weights(bare, np.zeros(1, np.int64), np.ones(1))[0][0], head_on, rtol=1e-5)
    np.testing.assert_allclose(sc.mat_film[0], [300.0, 1.33], rtol=1e-6)
    np.testing.assert_allclose(specular_weights(sc, np.zeros(1, np.int64), np.ones(1))[0][0],
                               conductor_film1(300.0, sc.mat_film[0, 1], 1.0, tuple(sc.mat_metal[0])), rtol=1e-12)
    assert np.isclose(sc.mat_roughness[0], 0.3) and distributions(sc)[0] == 0  # GGX
    assert w == ["material 'Copper': the anisotropy of Metallic BSDF 'Metallic BSDF' ignored"]


def test_a_principled_metals_specular_tint_is_its_edge_tint():
    """Cycles gives a Principled BSDF's metal lobe the F82-Tint Fresnel with the Specular Tint as the edge's
    tint (it was silently left out: Schlick alone); its thin film is read, a rough anisotropy said to be
    ignored."""
    import dataclasses

    from smbs_addon.shading.fresnel import fresnel_schlick, specular_weights

    sc, w = one_material(material("Tinted", "ShaderNodeBsdfPrincipled", **{
        "Base Color": (0.9, 0.8, 0.5), "Metallic": 1.0, "Roughness": 0.2, "Specular Tint": (0.4, 0.7, 1.0),
        "Anisotropic": 0.5, "Thin Film Thickness": 250.0}))
    assert sc.mat_film[0, 0] == 250.0
    R, _ = specular_weights(dataclasses.replace(sc, mat_film=np.zeros((0, 2))), np.zeros(1, np.int64),
                            np.array([1.0 / 7.0]))
    np.testing.assert_allclose(R[0], np.array([0.4, 0.7, 1.0]) * fresnel_schlick(np.array([1.0 / 7.0]),
                                                                                 [0.9, 0.8, 0.5])[0], rtol=1e-6)
    assert w == ["material 'Tinted': Principled BSDF anisotropy ignored"]


def test_a_principled_metals_textured_specular_tint_is_left_white():
    """A texture on a metal's Specular Tint cannot be baked: the metal stays a metal (plain Schlick), said so;
    reading the tint must not turn it into a diffuse."""
    m = material("Brushed", "ShaderNodeBsdfPrincipled", **{"Base Color": (0.9, 0.8, 0.5), "Metallic": 1.0})
    nt = m.node_tree
    noise = nt.nodes.new("ShaderNodeTexNoise")
    nt.links.new(noise.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Specular Tint"])
    sc, w = one_material(m)
    assert sc.mat_kind[0] == S.CONDUCTOR and not sc.mat_metal.any()
    assert w == ["material 'Brushed': Principled BSDF specular tint (textured) ignored"]


def _streaky_glass():
    m = material("Streaky", "ShaderNodeBsdfGlass", **{"Thin Film Thickness": 400.0})
    nt = m.node_tree
    nt.links.new(nt.nodes.new("ShaderNodeTexNoise").outputs["Fac"], nt.nodes["Glass BSDF"].inputs["Thin Film Thickness"])
    return m


@pytest.mark.parametrize("make,film,warnings", [
    (lambda: material("Soap", "ShaderNodeBsdfGlass", **{"Thin Film Thickness": 400.0, "Thin Film IOR": 1.4}),
     (400.0, 1.4), []),
    (lambda: material("Thin", "ShaderNodeBsdfGlass", **{"Thin Film Thickness": 0.1}), None, []),
    (_streaky_glass, None, ["material 'Streaky': the thin film of 'Glass BSDF' is driven by nodes (a textured "
                            "thickness or index): its iridescence is not baked"]),
    (lambda: material("Plastic", "ShaderNodeBsdfPrincipled", **{"Thin Film Thickness": 300.0}), None,
     ["material 'Plastic': Principled BSDF thin film (over a diffuse) ignored"])],
    ids=["glass", "at_the_cutoff", "textured", "over_a_diffuse"])
def test_a_thin_film_is_read_where_it_is_baked_and_said_to_be_ignored_elsewhere(make, film, warnings):
    """A Glass BSDF's thin film (Thickness, IOR) goes to Scene.mat_film; one at Cycles' cutoff (0.1 nm) or
    below is none; a textured thickness is not read (no film), and a film over a diffuse Principled's coat
    is said to be ignored."""
    sc, w = one_material(make())
    if film is None:
        assert sc.mat_film.size == 0
    else:
        np.testing.assert_allclose(sc.mat_film[0], film, rtol=1e-6)
    assert w == warnings


def test_a_metal_mixed_with_a_diffuse_keeps_its_fresnel_at_its_weight():
    """A Mix Shader of a metal (weight 0.6) and a diffuse: the metal's reflectance is 0.6 x its own
    Fresnel, F82-Tint or a physical conductor's (its F0 was scaled by the weight too, as a colour is)."""
    from smbs_addon.shading.fresnel import fresnel_dielectric, fresnel_schlick, specular_weights

    cos = np.array([1.0, 0.5, 0.1])
    m = mixed("Half", ("ShaderNodeBsdfMetallic", {"Base Color": (0.9, 0.6, 0.3), "Edge Tint": (1.0, 1.0, 1.0),
                                                  "Roughness": 0.0}), ("ShaderNodeBsdfDiffuse", {}), factor=0.4)
    sc, w = one_material(m)
    R, _ = specular_weights(sc, np.zeros(3, np.int64), cos)
    np.testing.assert_allclose(R, 0.6 * fresnel_schlick(cos, [0.9, 0.6, 0.3]), rtol=1e-6)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    m = mixed("Half", ("ShaderNodeBsdfMetallic", {"Roughness": 0.0}), ("ShaderNodeBsdfDiffuse", {}), factor=0.4)
    node = next(n for n in m.node_tree.nodes if n.type == "BSDF_METALLIC")
    node.fresnel_type = "PHYSICAL_CONDUCTOR"
    node.inputs["Extinction"].default_value = (0.0, 0.0, 0.0)
    node.inputs["IOR"].default_value = (1.5, 1.5, 1.5)
    sc, w = one_material(m)
    R, _ = specular_weights(sc, np.zeros(3, np.int64), cos)
    np.testing.assert_allclose(R, 0.6 * fresnel_dielectric(cos, 1.5)[:, None] * np.ones(3), rtol=1e-6)


def test_a_principled_metal_in_a_mix_weighs_its_coat_by_its_weight():
    """A Principled BSDF of Metallic 0.8 is 0.8 of F82-Tint metal and 0.2 of a dielectric coat; mixed at
    0.6 with a diffuse, Cycles weighs both by 0.6: its reflectance is 0.6 x the unmixed one's at every
    angle (the coat was 1 - 0.8 x 0.6 = 0.52 of the dielectric Fresnel, not 0.2 x 0.6 = 0.12: 2.6 x too
    much at grazing angles)."""
    from smbs_addon.shading.fresnel import specular_weights

    cos = np.array([1.0, 0.5, 0.1, 0.02])
    metal = {"Base Color": (0.9, 0.6, 0.3, 1.0), "Metallic": 0.8, "Roughness": 0.0, "IOR": 1.6}
    sc, _ = one_material(material("Alone", "ShaderNodeBsdfPrincipled", **metal))
    alone, _ = specular_weights(sc, np.zeros(4, np.int64), cos)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc, _ = one_material(mixed("Mixed", ("ShaderNodeBsdfPrincipled", metal), ("ShaderNodeBsdfDiffuse", {}),
                               factor=0.4))
    R, _ = specular_weights(sc, np.zeros(4, np.int64), cos)
    np.testing.assert_allclose(R, 0.6 * alone, rtol=1e-6)  # (the Factor is a float32)


def test_a_partly_transmissive_principled_glass_weighs_both_lobes():
    sc, w = one_material(material("Frost", "ShaderNodeBsdfPrincipled", **{
        "Base Color": (0.81, 1.0, 0.64), "Metallic": 0.1, "Transmission Weight": 0.9, "Roughness": 0.0}))
    assert sc.mat_kind[0] == S.DIELECTRIC
    np.testing.assert_allclose(sc.mat_color[0], np.sqrt([0.81, 1.0, 0.64]) * 0.81, rtol=1e-6)
    np.testing.assert_allclose(sc.mat_reflect_color[0], 0.81, rtol=1e-6)
    assert len(w) == 1 and "glass of weight 0.81" in w[0]


def test_a_principled_glass_specular_tint_scales_its_fresnel_at_normal_incidence():
    """Cycles' Principled glass (generalized_schlick_fresnel, negative exponent): f0 = F0 x Specular Tint (kept
    in [0, 1]) and the dielectric Fresnel F mapped from [F0, 1] onto [f0, 1]: R = f0 at normal incidence,
    1 under total internal reflection, T = (1 - R) sqrt(base). It was ignored (and said so)."""
    from smbs_addon.shading.fresnel import fresnel_dielectric, specular_weights

    sc, w = one_material(material("Tinted", "ShaderNodeBsdfPrincipled", **{
        "Base Color": (0.64, 1.0, 0.81), "Transmission Weight": 1.0, "IOR": 1.5, "Roughness": 0.0,
        "Specular Tint": (2.5, 1.0, 0.2, 1.0)}))
    assert w == [] and sc.mat_kind[0] == S.DIELECTRIC
    np.testing.assert_allclose(sc.mat_metal[0], [1.5, 0.0, -0.8, 0, 0, 0], atol=1e-6)
    F0 = 0.04
    f0 = F0 * np.array([2.5, 1.0, 0.2])
    cos = np.array([1.0, 0.6, 0.05, -0.5])  # the last from inside beyond the critical angle (sin 0.866 x 1.5 > 1)
    R, T = specular_weights(sc, np.zeros(4, np.int64), cos)
    F = fresnel_dielectric(cos, 1.5)
    want = f0 + (1.0 - f0) * np.clip((F[:, None] - F0) / (1.0 - F0), 0.0, 1.0)
    np.testing.assert_allclose(R[0], f0, rtol=1e-5)  # (the tint is a float32)
    np.testing.assert_allclose(R, want, rtol=1e-5)
    np.testing.assert_allclose(R[3], 1.0) and np.testing.assert_allclose(T[3], 0.0)
    np.testing.assert_allclose(T, (1.0 - want) * np.sqrt([0.64, 1.0, 0.81]), rtol=1e-5)
    assert R[1, 1] == F[1]  # a white channel is the plain Fresnel term


def test_a_principled_glass_specular_tint_under_a_thin_film():
    """Under a thin film Cycles scales the film's reflectance f by f0 / F0, the more the nearer f is to F0
    (s = (1 - f) / (1 - F0)); a white tint leaves the film's colours as they are."""
    from smbs_addon.shading.fresnel import specular_weights
    from smbs_addon.shading.thinfilm import dielectric_film1

    tint = np.array([0.3, 1.0, 3.0])
    sc, _ = one_material(material("FilmTint", "ShaderNodeBsdfPrincipled", **{
        "Transmission Weight": 1.0, "IOR": 1.5, "Specular Tint": (*tint, 1.0), "Thin Film Thickness": 300.0,
        "Thin Film IOR": 1.8}))
    F0 = 0.04
    for cos in (1.0, 0.4, -0.9):
        f = np.array(dielectric_film1(300.0, sc.mat_film[0, 1], cos, 1.5))
        s = np.clip((1.0 - f) / (1.0 - F0), 0.0, 1.0)
        R, T = specular_weights(sc, np.zeros(1, np.int64), np.array([cos]))
        np.testing.assert_allclose(R[0], f * (1.0 + (np.float32(tint) * F0 / F0 - 1.0) * s), rtol=1e-6)
        np.testing.assert_allclose(T[0], (1.0 - R[0]) * sc.mat_color[0], rtol=1e-12)  # sqrt(Base Color 0.8)


@pytest.mark.parametrize("second,same", [((2.0, 1.0, 1.0), True), ((1.0, 1.0, 1.0), False)])
def test_glasses_under_different_specular_tints_do_not_add_up(second, same):
    """Two Principled glasses mixed 0.6 / 0.4: under the same tint they are one material (colours summed),
    under different tints the heavier is taken and the other said to be left out."""
    m = bpy.data.materials.new("TwoGlass")
    nt = m.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.4
    for i, tint in enumerate(((2.0, 1.0, 1.0), second)):
        node = nt.nodes.new("ShaderNodeBsdfPrincipled")
        node.inputs["Transmission Weight"].default_value = 1.0
        node.inputs["Specular Tint"].default_value = (*tint, 1.0)
        nt.links.new(node.outputs[0], mix.inputs[1 + i])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    sc, w = one_material(m)
    assert sc.mat_kind[0] == S.DIELECTRIC
    np.testing.assert_allclose(sc.mat_metal[0, :3], [1.0, 0.0, 0.0])
    np.testing.assert_allclose(sc.mat_reflect_color[0], 1.0 if same else 0.6, rtol=1e-6)
    assert (w == []) == same, w


def test_principled_transmission_is_a_dielectric():
    sc, _ = one_material(material("PGlass", "ShaderNodeBsdfPrincipled", **{
        "Base Color": (0.9, 1.0, 0.95), "Transmission Weight": 1.0, "IOR": 1.33,
        "Roughness": 0.0}))
    assert sc.mat_kind[0] == S.DIELECTRIC and np.isclose(sc.mat_ior[0], 1.33)
    # Cycles tints each refraction by the square root of the base colour (once in, once out
    # gives the base colour through a slab); reflections stay white
    assert np.allclose(sc.mat_color[0], np.sqrt([0.9, 1.0, 0.95])) and np.allclose(sc.mat_reflect_color[0], 1)


def test_glass_bsdf_tints_reflection_and_transmission():
    sc, _ = one_material(material("Glass", "ShaderNodeBsdfGlass", Color=(0.5, 0.6, 0.7), IOR=1.5,
                                  Roughness=0.05))
    assert sc.mat_kind[0] == S.DIELECTRIC and np.isclose(sc.mat_ior[0], 1.5)
    assert np.allclose(sc.mat_color[0], [0.5, 0.6, 0.7])
    assert np.allclose(sc.mat_reflect_color[0], [0.5, 0.6, 0.7])
    assert np.isclose(sc.mat_roughness[0], 0.05)


def test_bump_map_correction_is_read_per_material():
    """Cycles' Bump Map Correction (Material > Settings, on by default) is exported per material:
    a glass left at the default keeps it, a mirror with it turned off does not, and a scene with
    one material of each says so material by material."""
    glass = material("Glass", "ShaderNodeBsdfGlass", Color=(1.0, 1.0, 1.0), IOR=1.5)
    mirror = material("Mirror", "ShaderNodeBsdfGlossy", Color=(0.9, 0.9, 0.9), Roughness=0.0)
    assert glass.cycles.use_bump_map_correction  # Blender's default
    mirror.cycles.use_bump_map_correction = False
    mesh_with(glass, "A")
    mesh_with(mirror, "B")
    add_camera()
    sc, _ = export()
    flags = dict(zip(sc.mat_names, sc.mat_bump_correction))
    assert flags["Glass"] and not flags["Mirror"]
    assert not mirror.cycles.use_bump_map_correction and glass.cycles.use_bump_map_correction  # untouched


def test_refraction_bsdf_has_no_reflection():
    sc, _ = one_material(material("Refr", "ShaderNodeBsdfRefraction", Color=(1.0, 1.0, 1.0),
                                  IOR=1.33))
    assert sc.mat_kind[0] == S.DIELECTRIC and np.isclose(sc.mat_ior[0], 1.33)
    assert np.allclose(sc.mat_reflect_color[0], 0) and np.allclose(sc.mat_color[0], 1)


@pytest.mark.parametrize("idname", ["ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic"])
def test_glossy_is_a_plain_conductor(idname):
    sc, _ = one_material(material("Mirror", idname, Color=(0.9, 0.9, 0.9), Roughness=0.0))
    assert sc.mat_kind[0] == S.CONDUCTOR and sc.mat_fresnel[0] == S.FRESNEL_NONE
    assert np.allclose(sc.mat_color[0], 0.9) and sc.mat_roughness[0] == 0


def test_diffuse_bsdf():
    sc, _ = one_material(material("D", "ShaderNodeBsdfDiffuse", Color=(0.1, 0.2, 0.3)))
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.mat_color[0], [0.1, 0.2, 0.3])


def test_emission():
    sc, _ = one_material(material("Lamp", "ShaderNodeEmission", Color=(1.0, 0.5, 0.25),
                                  Strength=7.0))
    assert sc.mat_kind[0] == S.EMITTER and np.isclose(sc.mat_strength[0], 7.0)
    assert np.allclose(sc.mat_color[0], [1.0, 0.5, 0.25])


def test_an_emission_object_is_a_mesh_light_of_its_own():
    """Cycles lights the scene with an Emission shader's object (a mesh light): the export makes it a
    light named after the object, of radiance Color x Strength, taking the object's Ray Visibility."""
    add_camera()
    lamp = mesh_with(material("Lamp", "ShaderNodeEmission", Color=(1.0, 0.5, 0.25), Strength=7.0), "Softbox")
    lamp.visible_glossy = False
    lamp.location = (0.0, 0.0, 3.0)
    sc, warnings = export()
    assert warnings == []
    assert sc.light_names == ["Softbox"] and sc.light_type.tolist() == [S.MESH]
    assert np.allclose(sc.light_color[0], [7.0, 3.5, 1.75])
    assert np.array_equal(sc.tri_light, np.zeros(12, np.int32)) and math.isclose(sc.mesh_light(0)[4], 24.0)
    assert np.allclose(sc.light_matrix[0][:3, 3], [0.0, 0.0, 3.0])
    assert not sc.light_seen_by(0, S.RAY_GLOSSY) and sc.light_seen_by(0, S.RAY_TRANSMISSION)


def _links(sc, light):
    """The names of the objects light `light` lights (Scene.light_links), sorted."""
    li = sc.light_names.index(light)
    return sorted(n for n, on in zip(sc.object_names, sc.lit_by(li)) if on)


def test_light_linking_receivers_are_read_as_blender_resolves_them():
    """A light's receiver collection (Object > Shading > Light Linking) as Blender's depsgraph resolves it:
    once any object is set to Include, only those are lit; with Excludes alone, every object but those;
    an object inside a child collection takes that child's state (the first level's, however deep), the
    collection's own objects theirs, the later (the object's own) where one is met twice. A mesh light
    reads its object's; an unlinked light lights every object; a scene without links keeps none."""
    add_camera()
    glass = material("Glass", "ShaderNodeBsdfGlass")
    ball, pane, floor, wall = (mesh_with(glass, n) for n in ("Ball", "Pane", "Floor", "Wall"))
    add_light("POINT", energy=10.0)
    sc, warnings = export()
    assert warnings == [] and sc.light_links.size == 0
    inc, exc = bpy.data.collections.new("Inc"), bpy.data.collections.new("Exc")
    inner, deeper = bpy.data.collections.new("Inner"), bpy.data.collections.new("Deeper")
    inc.objects.link(ball)
    exc.children.link(inner)
    inner.children.link(deeper)
    deeper.objects.link(pane)
    deeper.objects.link(wall)
    exc.objects.link(wall)  # its own state (Include) after its child collection's (Exclude)
    exc.collection_children[0].light_linking.link_state = "EXCLUDE"
    exc.collection_objects[0].light_linking.link_state = "EXCLUDE"
    lamp = add_light("SPOT", energy=10.0)
    lamp.light_linking.receiver_collection = inc
    sun = add_light("SUN", energy=1.0)
    sun.light_linking.receiver_collection = exc
    glow = mesh_with(material("Lamp", "ShaderNodeEmission", Strength=3.0), "Panel")
    glow.light_linking.receiver_collection = inc
    sc, warnings = export()
    assert warnings == []
    assert _links(sc, "Point") == sorted(sc.object_names)
    assert _links(sc, "Spot") == ["Ball"] == _links(sc, "Panel")
    assert _links(sc, "Sun") == ["Ball", "Floor", "Panel"]  # the wall excluded twice: its own state last
    exc.collection_objects[0].light_linking.link_state = "INCLUDE"
    sc, _ = export()
    assert _links(sc, "Sun") == ["Wall"]


def test_shadow_linking_blockers_are_read_as_the_receivers_are():
    """A light's blocker collection (Shadow Linking) resolves as a receiver collection does, into
    Scene.light_blockers: with the wall set to Include, only the wall shadows the lamp; a mesh light reads
    its object's; nothing is said about either."""
    add_camera()
    glass = material("Glass", "ShaderNodeBsdfGlass")
    ball, wall = mesh_with(glass, "Ball"), mesh_with(glass, "Wall")
    lamp = add_light("POINT", energy=10.0)
    only = bpy.data.collections.new("OnlyWall")
    only.objects.link(wall)
    lamp.light_linking.blocker_collection = only
    glow = mesh_with(material("Lamp", "ShaderNodeEmission", Strength=3.0), "Panel")
    glow.light_linking.blocker_collection = only
    glow.light_linking.receiver_collection = only
    sc, warnings = export()
    assert warnings == []
    for light in ("Point", "Panel"):
        li = sc.light_names.index(light)
        assert sorted(n for n, on in zip(sc.object_names, sc.unshadowing(li)) if not on) == ["Wall"]
    assert _links(sc, "Point") == ["Ball", "Panel", "Wall"] and _links(sc, "Panel") == ["Wall"]
    assert ball.name == "Ball"


def test_unsupported_node_warns_naming_the_material():
    m = material("Foo", "ShaderNodeBsdfTransparent")
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.mat_color[0], 0.8)
    assert warnings == ["material 'Foo': node 'Transparent BSDF' is not supported; "
                        "treated as diffuse (albedo 0.8)"]


def test_an_empty_mix_shader_renders_black():
    sc, warnings = one_material(material("Foo", "ShaderNodeMixShader", Factor=0.5))
    assert sc.mat_kind[0] == S.DIFFUSE and np.all(sc.mat_color[0] == 0)
    assert warnings == ["material 'Foo': its shader mix has no closures (renders black in Cycles); "
                        "treated as black diffuse"]


def mixed(name, first, second, factor=0.5, add=False):
    """A material whose Surface is a Mix Shader (Factor factor) or an Add Shader of two shader nodes,
    each given as (bl_idname, {input: value}) or None (left empty)."""
    m = bpy.data.materials.new(name)
    nt = m.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    mix = nt.nodes.new("ShaderNodeAddShader" if add else "ShaderNodeMixShader")
    if not add:
        mix.inputs["Factor"].default_value = factor
    for sock, spec in zip(mix.inputs[-2:], (first, second)):
        if spec is None:
            continue
        node = nt.nodes.new(spec[0])
        for k, v in spec[1].items():
            node.inputs[k].default_value = (*v, 1.0) if isinstance(v, tuple) and len(v) == 3 else v
        nt.links.new(node.outputs[0], sock)
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    return m


def test_mix_shader_with_constant_factor_one_is_followed():
    m = mixed("Mixed", ("ShaderNodeBsdfDiffuse", {}), ("ShaderNodeBsdfGlass", {}), factor=1.0)
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIELECTRIC and warnings == []
    assert np.all(sc.mat_color[0] == 1.0) and np.all(sc.mat_reflect_color[0] == 1.0)


def test_a_glass_mixed_with_a_diffuse_casts_with_its_weight():
    """Mix(Diffuse, Glass) at Factor 0.7: Cycles weighs the glass closure by 0.7 at every vertex, so
    the material is that glass with both colours x 0.7; the diffuse part is left out, said so."""
    m = mixed("Frosted", ("ShaderNodeBsdfDiffuse", {"Color": (0.5, 0.5, 0.5)}),
              ("ShaderNodeBsdfGlass", {"Color": (1.0, 0.9, 0.8), "IOR": 1.45}), factor=0.7)
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIELECTRIC and np.isclose(sc.mat_ior[0], 1.45)
    assert np.allclose(sc.mat_color[0], [0.7, 0.63, 0.56]) and np.allclose(sc.mat_reflect_color[0], [0.7, 0.63, 0.56])
    assert warnings == ["material 'Frosted': its shader mix is taken as its glass part (weight 0.70); left out, "
                        "neither casting nor receiving caustics: 'Diffuse BSDF' (weight 0.30, diffuse)"]


def test_a_diffuse_mixed_with_a_glossy_receives_with_its_weight():
    """Blender's old floor, Mix(Diffuse, Glossy) at 0.25: the receiver is the diffuse at 0.75 (its
    colour, and the layer's diffuse weight, so that the albedo under it stays the Diffuse's)."""
    m = mixed("Floor", ("ShaderNodeBsdfDiffuse", {"Color": (0.8, 0.6, 0.4)}),
              ("ShaderNodeBsdfGlossy", {"Roughness": 0.3}), factor=0.25)
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.mat_color[0], [0.6, 0.45, 0.3])
    assert len(warnings) == 1 and "its diffuse part (weight 0.75)" in warnings[0]
    assert "'Glossy BSDF' (weight 0.25, glossy)" in warnings[0]
    bpy.data.objects.remove(bpy.data.objects["Thing"])
    m = mixed("Default", ("ShaderNodeBsdfPrincipled", {"Base Color": (0.8, 0.6, 0.4)}),
              ("ShaderNodeBsdfGlossy", {"Roughness": 0.3}), factor=0.25)
    sc, _ = one_material(m)
    assert np.allclose(sc.mat_color[0], [0.6, 0.45, 0.3]) and np.isclose(sc.mat_layer[0][3], 0.75)
    assert sc.mat_layer[0][0] > 1.0  # Principled's coat kept, over the albedo 0.8 / 0.6 / 0.4


def test_parts_of_one_kind_add_up_exactly():
    """Two glasses of one index and roughness mixed: one glass of the weighted colours, nothing left
    out; two diffuse under an Add Shader: their colours summed; nested mixes multiply their factors."""
    m = mixed("TwoGlass", ("ShaderNodeBsdfGlass", {"Color": (1.0, 0.0, 0.0)}),
              ("ShaderNodeBsdfGlass", {"Color": (0.0, 0.0, 1.0)}), factor=0.25)
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIELECTRIC and np.allclose(sc.mat_color[0], [0.75, 0.0, 0.25]) and warnings == []
    bpy.data.objects.remove(bpy.data.objects["Thing"])
    m = mixed("Sum", ("ShaderNodeBsdfDiffuse", {"Color": (0.1, 0.2, 0.3)}),
              ("ShaderNodeBsdfDiffuse", {"Color": (0.3, 0.2, 0.1)}), add=True)
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.mat_color[0], 0.4) and warnings == []
    bpy.data.objects.remove(bpy.data.objects["Thing"])
    m = mixed("Nested", ("ShaderNodeBsdfTransparent", {}), None, factor=0.5)
    nt = m.node_tree
    mix2 = nt.nodes.new("ShaderNodeMixShader")
    mix2.inputs["Factor"].default_value = 0.8
    g1, g2 = nt.nodes.new("ShaderNodeBsdfGlossy"), nt.nodes.new("ShaderNodeBsdfGlass")
    nt.links.new(g1.outputs[0], mix2.inputs[1])
    nt.links.new(g2.outputs[0], mix2.inputs[2])
    nt.links.new(mix2.outputs[0], nt.nodes["Mix Shader"].inputs[2])
    sc, warnings = one_material(m)
    # Mix(Transparent, Mix(Glossy, Glass, 0.8), 0.5): the glass weighs 0.4, the glossy 0.1
    assert sc.mat_kind[0] == S.DIELECTRIC and np.allclose(sc.mat_color[0], 0.4)
    assert len(warnings) == 1 and "its glass part (weight 0.40)" in warnings[0]
    assert "(weight 0.10, glossy)" in warnings[0] and "'Transparent BSDF' (weight 0.50, node " in warnings[0]


def _by_fresnel(m, ior=1.45, layer_weight=False):
    nt = m.node_tree
    fr = nt.nodes.new("ShaderNodeLayerWeight" if layer_weight else "ShaderNodeFresnel")
    if layer_weight:
        fr.inputs["Blend"].default_value = 1.0 - 1.0 / ior
    else:
        fr.inputs["IOR"].default_value = ior
    nt.links.new(fr.outputs[0], nt.nodes["Mix Shader"].inputs["Factor"])
    return m


@pytest.mark.parametrize("layer_weight", [False, True])
def test_the_old_glass_of_refraction_and_glossy_by_fresnel_is_a_glass(layer_weight):
    """Mix(Refraction, Glossy) by a Fresnel node of the same index: Cycles weighs the refraction by 1 - F
    and the reflection by F, as a Glass BSDF does, each lobe with its own colour."""
    m = _by_fresnel(mixed("OldGlass", ("ShaderNodeBsdfRefraction", {"Color": (0.9, 1.0, 0.9), "IOR": 1.45}),
                          ("ShaderNodeBsdfGlossy", {"Color": (1.0, 1.0, 1.0), "Roughness": 0.0})),
                    layer_weight=layer_weight)
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIELECTRIC and sc.mat_fresnel[0] == S.FRESNEL_NONE and warnings == []
    assert np.isclose(sc.mat_ior[0], 1.45) and np.allclose(sc.mat_color[0], [0.9, 1.0, 0.9])
    assert np.allclose(sc.mat_reflect_color[0], 1.0)


def test_the_old_glass_with_another_fresnel_index_warns():
    m = _by_fresnel(mixed("OldGlass", ("ShaderNodeBsdfRefraction", {"IOR": 1.5, "Roughness": 0.0}),
                          ("ShaderNodeBsdfGlossy", {"Roughness": 0.0})), ior=1.33)
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIELECTRIC and np.isclose(sc.mat_ior[0], 1.5)
    assert len(warnings) == 1 and "of index 1.33, its refraction of 1.5" in warnings[0]


def test_a_diffuse_under_a_glossy_by_fresnel_keeps_one_minus_fresnel():
    """Mix(Diffuse, Glossy) by a Fresnel node: the diffuse's weight towards the eye is 1 - F(mu), which
    is layer.py's table for a coat of that index at Roughness 0."""
    from smbs_addon.shading import coat as layer
    from smbs_addon.shading.fresnel import fresnel_dielectric
    m = _by_fresnel(mixed("OldFloor", ("ShaderNodeBsdfDiffuse", {"Color": (0.5, 0.6, 0.7)}),
                          ("ShaderNodeBsdfGlossy", {"Roughness": 0.2})), ior=1.5)
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.mat_color[0], [0.5, 0.6, 0.7])
    assert np.allclose(sc.mat_layer[0], [1.5, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0])
    mu = np.linspace(0.0, 1.0, layer.MU_STEPS + 1)[1:]
    assert np.allclose(layer.table(sc)[0, 1:], 1.0 - fresnel_dielectric(mu, 1.5), atol=1e-4)
    assert len(warnings) == 1 and "Glossy part 'Glossy BSDF'" in warnings[0]


def test_a_fresnel_mix_of_other_shaders_is_named():
    m = _by_fresnel(mixed("Odd", ("ShaderNodeBsdfGlossy", {}), ("ShaderNodeBsdfRefraction", {})))
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.mat_color[0], 0.8)
    assert len(warnings) == 1 and "the Factor of Mix Shader 'Mix Shader' is a Fresnel" in warnings[0]


def test_the_fake_shadow_trick_is_the_glass():
    """Mix(Glass, Transparent) by Light Path's Is Shadow Ray: every ray of a caustic path is a non-shadow
    ray in Cycles, so the material is the glass, exactly, and nothing is said."""
    m = mixed("FakeShadows", ("ShaderNodeBsdfGlass", {"Roughness": 0.0, "IOR": 1.45}),
              ("ShaderNodeBsdfTransparent", {}))
    lp = m.node_tree.nodes.new("ShaderNodeLightPath")
    m.node_tree.links.new(lp.outputs["Is Shadow Ray"], m.node_tree.nodes["Mix Shader"].inputs["Factor"])
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIELECTRIC and np.isclose(sc.mat_ior[0], 1.45) and np.all(sc.mat_color[0] == 1.0)
    assert warnings == []


def test_a_mix_factor_driven_by_a_node_is_named():
    m = mixed("Fresnel", ("ShaderNodeBsdfDiffuse", {}), ("ShaderNodeBsdfGlossy", {}))
    fr = m.node_tree.nodes.new("ShaderNodeLayerWeight")
    m.node_tree.links.new(fr.outputs["Facing"], m.node_tree.nodes["Mix Shader"].inputs["Factor"])
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.mat_color[0], 0.8)
    assert len(warnings) == 1 and "driven by node 'Layer Weight'" in warnings[0]
    assert "a Mix Shader's Factor must be a constant" in warnings[0]


def test_linked_input_where_a_constant_is_needed_warns():
    m = material("Textured", "ShaderNodeBsdfGlass")
    tex = m.node_tree.nodes.new("ShaderNodeTexChecker")
    m.node_tree.links.new(tex.outputs["Color"], m.node_tree.nodes["Glass BSDF"].inputs["Color"])
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.mat_color[0], 0.8)
    assert len(warnings) == 1 and warnings[0].startswith("material 'Textured': input 'Color'")
    assert "'Checker Texture'" in warnings[0] and warnings[0].endswith("(albedo 0.8)")


def _textured(name, shader, socket, texture):
    m = material(name, shader)
    nt = m.node_tree
    tex = nt.nodes.new(texture)
    bsdf = next(n for n in nt.nodes if n.bl_idname == shader)
    nt.links.new(tex.outputs["Color"], bsdf.inputs[socket])
    return m, tex


def test_a_textured_diffuse_colour_is_a_textured_receiver():
    """A texture on a Diffuse BSDF's Color or a Principled Base Color: a receiver marked textured
    (the render's Diffuse Color pass will hold its albedo where the camera sees it), its stand-in
    colour the mean of a Checker Texture's two colours, else 0.8; said once, naming the material."""
    m, tex = _textured("Checker", "ShaderNodeBsdfDiffuse", "Color", "ShaderNodeTexChecker")
    tex.inputs["Color1"].default_value = (0.9, 0.6, 0.3, 1.0)
    tex.inputs["Color2"].default_value = (0.1, 0.2, 0.3, 1.0)
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIFFUSE and sc.mat_textured.tolist() == [True]
    np.testing.assert_allclose(sc.mat_color[0], [0.5, 0.4, 0.3])
    assert len(warnings) == 1 and warnings[0].startswith("material 'Checker': its colour is a texture")
    assert "Diffuse Color pass" in warnings[0] and warnings[0].endswith("albedo 0.4")


def test_a_textured_principled_base_colour_keeps_its_layers():
    m, _ = _textured("Wood", "ShaderNodeBsdfPrincipled", "Base Color", "ShaderNodeTexImage")
    m.node_tree.nodes["Principled BSDF"].inputs["Metallic"].default_value = 0.25
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIFFUSE and sc.mat_textured.tolist() == [True]
    np.testing.assert_allclose(sc.mat_color[0], 0.8 * 0.75)  # the stand-in, times what Metallic leaves
    assert sc.mat_layer[0, 0] > 1.0 and np.isclose(sc.mat_layer[0, 3], 0.75)  # under its glossy coat
    assert len(warnings) == 1 and "its colour is a texture" in warnings[0]


@pytest.mark.parametrize("is_float", [False, True])
def test_an_image_textures_stand_in_is_its_mean_linear_colour(is_float):
    """Its stand-in (seen through glass, in light it passes on) is the image's mean colour as
    Cycles reads it: an 8-bit sRGB image through the sRGB curve, a float image as it is."""
    m, tex = _textured("Wood", "ShaderNodeBsdfDiffuse", "Color", "ShaderNodeTexImage")
    img = bpy.data.images.new("WoodGrain", 4, 2, float_buffer=is_float)
    img.pixels.foreach_set(np.array([[0.2, 0.4, 0.6, 1.0], [0.8, 0.6, 0.1, 1.0]] * 4, np.float32).ravel())
    tex.image = img
    sc, warnings = one_material(m)
    px = np.empty(32, np.float32)
    img.pixels.foreach_get(px)  # as stored (8 bits: rounded)
    rgb = px.reshape(-1, 4)[:, :3].astype(float)
    want = rgb.mean(axis=0) if is_float else (((rgb + 0.055) / 1.055) ** 2.4).mean(axis=0)
    assert sc.mat_textured.tolist() == [True]
    np.testing.assert_allclose(sc.mat_color[0], want, rtol=1e-6)
    if not is_float:
        np.testing.assert_allclose(want, [0.318, 0.226, 0.164], atol=0.002)  # not the encoded 0.5, 0.5, 0.35


def _with_volume(m, node_type, **inputs):
    nt = m.node_tree
    vol = nt.nodes.new(node_type)
    for k, v in inputs.items():
        vol.inputs[k].default_value = v
    nt.links.new(vol.outputs[0], nt.nodes["Material Output"].inputs["Volume"])
    return m


def test_a_glass_volume_absorption_is_its_absorption():
    """Cycles absorbs (1 - Color) x Density per unit length inside the glass."""
    m = _with_volume(material("Wine", "ShaderNodeBsdfGlass"), "ShaderNodeVolumeAbsorption",
                     Color=(0.9, 0.3, 0.1, 1.0), Density=2.5)
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIELECTRIC and warnings == []
    np.testing.assert_allclose(sc.mat_absorb[0], [0.25, 1.75, 2.25], rtol=1e-6)  # float32 sockets


@pytest.mark.parametrize("surface,volume,why", [
    ("ShaderNodeBsdfGlass", "ShaderNodeVolumeScatter", "only Volume Absorption is supported"),
    ("ShaderNodeBsdfGlossy", "ShaderNodeVolumeAbsorption", "only a glass's volume is ours")])
def test_other_volumes_are_said_to_be_ignored(surface, volume, why):
    sc, warnings = one_material(_with_volume(material("Smoke", surface, Roughness=0.0), volume))
    assert not np.any(sc.mat_absorb)
    assert len(warnings) == 1 and warnings[0].startswith("material 'Smoke': its Volume (") and why in warnings[0]


@pytest.mark.parametrize("node,dist,rough,expect,warned", [
    ("ShaderNodeBsdfGlass", "MULTI_GGX", 0.2, 1, False), ("ShaderNodeBsdfGlass", "GGX", 0.2, 0, False),
    ("ShaderNodeBsdfGlossy", "MULTI_GGX", 0.5, 1, False), ("ShaderNodeBsdfGlossy", "BECKMANN", 0.5, 0, True),
    ("ShaderNodeBsdfGlossy", "ASHIKHMIN_SHIRLEY", 0.0, 0, False), ("ShaderNodeBsdfRefraction", "BECKMANN", 0.3, 0, True),
    ("ShaderNodeBsdfPrincipled", "GGX", 0.5, 0, False), ("ShaderNodeBsdfPrincipled", "MULTI_GGX", 0.5, 1, False)])
def test_a_rough_caster_keeps_its_roughness_and_distribution(node, dist, rough, expect, warned):
    """A rough glass or mirror is baked rough (rough.py): its Roughness and its distribution are read,
    Multiscatter GGX (Blender's default) or GGX; Beckmann and Ashikhmin-Shirley are baked as GGX, said
    where the surface is rough (alpha^2 = Roughness^4 above Cycles' 1e-7)."""
    kw = {"Metallic": 1.0} if node == "ShaderNodeBsdfPrincipled" else {}
    m = material("Frosted", node, Roughness=rough, **kw)
    next(n for n in m.node_tree.nodes if n.type != "OUTPUT_MATERIAL").distribution = dist
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] in (S.DIELECTRIC, S.CONDUCTOR) and np.isclose(sc.mat_roughness[0], rough)
    assert distributions(sc)[0] == expect
    if warned:
        assert len(warnings) == 1 and warnings[0].startswith("material 'Frosted': the ") \
            and "is baked as GGX" in warnings[0], warnings
    else:
        assert warnings == []


def _height_glass(name, node_type="ShaderNodeBsdfGlass", coords="Object", **inputs):
    """A mirror or glass whose Normal is a Bump node (Distance 0.5, Strength 0.8) of the Height
    0.3 x - 0.2 y^2 in the Texture Coordinate node's coords."""
    m = material(name, node_type, **inputs)
    nt = m.node_tree
    bsdf = next(n for n in nt.nodes if n.type != "OUTPUT_MATERIAL")
    bump, tc, sep = (nt.nodes.new(t) for t in ("ShaderNodeBump", "ShaderNodeTexCoord", "ShaderNodeSeparateXYZ"))
    sq, fma = nt.nodes.new("ShaderNodeMath"), nt.nodes.new("ShaderNodeMath")
    sq.operation, fma.operation = "MULTIPLY", "MULTIPLY_ADD"
    nt.links.new(tc.outputs[coords], sep.inputs[0])
    nt.links.new(sep.outputs["Y"], sq.inputs[0])
    nt.links.new(sep.outputs["Y"], sq.inputs[1])
    nt.links.new(sq.outputs[0], fma.inputs[0])
    fma.inputs[1].default_value = -0.2
    lin = nt.nodes.new("ShaderNodeMath")
    lin.operation = "MULTIPLY"
    lin.inputs[1].default_value = 0.3
    nt.links.new(sep.outputs["X"], lin.inputs[0])
    nt.links.new(lin.outputs[0], fma.inputs[2])
    nt.links.new(fma.outputs[0], bump.inputs["Height"])
    nt.links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])
    bump.inputs["Distance"].default_value = 0.5
    bump.inputs["Strength"].default_value = 0.8
    return m


def _blend_data():
    return {k: sorted(x.name for x in getattr(bpy.data, k)) for k in ("scenes", "objects", "meshes", "materials")}


@pytest.mark.parametrize("node_type,inputs,coords", [("ShaderNodeBsdfGlass", {}, "Object"),
                                                     ("ShaderNodeBsdfPrincipled", {"Metallic": 1.0}, "Object"),
                                                     ("ShaderNodeBsdfGlass", {}, "Generated")])
def test_a_bump_node_on_a_caster_bends_its_normals_as_cycles_does(node_type, inputs, coords):
    """A Bump node on a glass's or a mirror's Normal (bump.py): Cycles bakes its Height at the
    vertices of a finer copy of the mesh, in a scene of its own; the exported corner normals are
    Cycles' normalize(N - Distance grad H), mixed by Strength, the gradient in world space (the
    object is stretched 2x along X, so H's slope along world X is halved; Generated coordinates
    run 0 to 1 over the mesh's box, halving both slopes again). The user's scene and material are
    as they were."""
    m = _height_glass("Bumped", node_type, coords, **inputs)
    me = bpy.data.meshes.new("Quad")
    me.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    me.materials.append(m)
    ob = link(bpy.data.objects.new("Water", me))
    ob.location, ob.scale = (0, 0, 1), (2, 1, 1)
    add_camera()
    before = _blend_data()
    nodes, links = len(m.node_tree.nodes), len(m.node_tree.links)
    sc, warnings = export()
    assert warnings == []
    assert _blend_data() == before and (len(m.node_tree.nodes), len(m.node_tree.links)) == (nodes, links)
    v, n = obj_tris(sc, "Water")
    assert len(v) == bump.TARGET_TRIANGLES
    p = v.reshape(-1, 3)
    if coords == "Object":
        grad = np.stack([np.full(len(p), 0.3 / 2), -0.4 * p[:, 1], np.zeros(len(p))], 1)
    else:  # x_gen = (x_obj + 1) / 2
        grad = np.stack([np.full(len(p), 0.3 / 4), -0.4 * (p[:, 1] + 1) / 2 / 2, np.zeros(len(p))], 1)
    Z = np.array([0.0, 0.0, 1.0])
    want = Z - 0.5 * grad
    want /= np.linalg.norm(want, axis=1, keepdims=True)
    want = 0.8 * want + 0.2 * Z
    want /= np.linalg.norm(want, axis=1, keepdims=True)
    err = np.linalg.norm(n.reshape(-1, 3) - want, axis=1)
    inner = (np.abs(p[:, 0]) < 1.99) & (np.abs(p[:, 1]) < 0.99)
    # float32 heights and positions inside; at the border the vertex gradient is one-sided
    assert err[inner].max() < 1e-3 and err.max() < 5e-3, (err[inner].max(), err.max())
    assert np.degrees(np.arccos(n[..., 2].min())) > (8.0 if coords == "Object" else 4.0)  # the bump's tilt
    assert sc.object_smooth[sc.object_names.index("Water")]
    if coords == "Generated":  # an attribute: Cycles' bump flips with the surface (bump_nodes._bump_flips)
        assert sc.tri_normals_back.shape == (0, 3, 3)
        return
    # the position: met from behind, Cycles bends the flipped normal -Z by the same term (bump.bend)
    behind = -Z - 0.5 * grad
    behind /= np.linalg.norm(behind, axis=1, keepdims=True)
    behind = 0.8 * behind - 0.2 * Z
    behind /= -np.linalg.norm(behind, axis=1, keepdims=True)  # as an outward normal
    back = sc.tri_normals_back[sc.tri_object == sc.object_names.index("Water")].reshape(-1, 3)
    assert np.linalg.norm(back - behind, axis=1)[inner].max() < 1e-3


def test_a_bump_cycles_cannot_bake_leaves_the_surface_unbumped_and_the_scene_as_it_was(monkeypatch):
    """Where Cycles' bake fails, the caustic is the unbumped surface's, said once, and everything the
    bake had made (a scene, an object, a mesh, a copied material) is removed again."""
    m = _height_glass("Bumped")
    me = bpy.data.meshes.new("Quad")
    me.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    me.materials.append(m)
    link(bpy.data.objects.new("Water", me))
    add_camera()
    before = _blend_data()

    def fails():
        assert set(_blend_data()["scenes"]) - set(before["scenes"])  # it fails with its scene made
        raise RuntimeError("no Cycles here")

    monkeypatch.setattr(cycles_passes, "_emission_bake", fails)
    sc, warnings = export()
    assert warnings == ["object 'Water': the bumps of its Normal could not be baked (no Cycles here); its "
                        "caustic is baked from the unbumped surface"]
    assert _blend_data() == before
    v, n = obj_tris(sc, "Water")
    assert len(v) == 2 and np.allclose(n, [0.0, 0.0, 1.0])


def _bumpy(name, node_type="ShaderNodeBsdfDiffuse"):
    """A receiver's material whose Normal is a Bump node (Distance 0.1) of a Noise Texture (Scale 8,
    Object coordinates)."""
    m = material(name, node_type)
    nt = m.node_tree
    noise, b = nt.nodes.new("ShaderNodeTexNoise"), nt.nodes.new("ShaderNodeBump")
    nt.links.new(nt.nodes.new("ShaderNodeTexCoord").outputs["Object"], noise.inputs["Vector"])
    noise.inputs["Scale"].default_value = 8.0
    b.inputs["Distance"].default_value = 0.1
    nt.links.new(noise.outputs["Fac"], b.inputs["Height"])
    bsdf = next(n for n in nt.nodes if n.type.startswith("BSDF"))
    nt.links.new(b.outputs["Normal"], bsdf.inputs["Normal"])
    return m


def _floor_under_camera(m, s_x=40, s_y=30):
    me = bpy.data.meshes.new("Floor")
    me.from_pydata([(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], [], [(0, 1, 2, 3)])
    me.materials.append(m)
    link(bpy.data.objects.new("Floor", me))
    add_camera(location=(0.2, 0.1, 4.0), rotation=(0.1, 0, 0))
    scene().render.resolution_x, scene().render.resolution_y = s_x, s_y


def _render_settings():
    r = scene().render
    return (r.resolution_x, r.resolution_y, r.resolution_percentage, r.filepath, r.engine, r.use_border,
            scene().cycles.samples, scene().cycles.filter_width, scene().view_layers[0].use_pass_normal)


@pytest.mark.parametrize("node_type", ["ShaderNodeBsdfDiffuse", "ShaderNodeBsdfPrincipled"])
def test_a_bumped_diffuse_receiver_is_exported_as_the_camera_sees_it(node_type):
    """A Bump node on a Diffuse (or a diffuse Principled) BSDF's Normal: the export renders what
    Cycles' camera rays meet (cycles_passes.view_maps: the Normal and Position passes at s x s sub-pixels,
    s = 4 for 40 x 30 pixels): over the floor, unit normals the bumps tilt (up to 10 degrees and
    more), never below the floor; the points on the floor, where our own camera's rays through the
    sub-pixels' centres meet it. Nothing said; the user's scene and render settings as they were."""
    _floor_under_camera(_bumpy("Stone", node_type))
    before, settings, images = _blend_data(), _render_settings(), list(bpy.data.images)
    sc, warnings = export()
    assert warnings == []
    assert _blend_data() == before and _render_settings() == settings and list(bpy.data.images) == images
    assert sc.mat_view_bump.tolist() == [True]
    n, p = sc.view_normals.reshape(-1, 3), sc.view_points.reshape(-1, 3)
    assert sc.view_normals.shape == (120, 160, 3) and sc.view_normals.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-5)
    assert n[:, 2].min() > 0 and np.degrees(np.arccos(n[:, 2].min())) > 10.0
    assert np.degrees(np.arccos(n[:, 2].max())) < 0.5  # and some face up
    from smbs_addon.kernels import eye
    from smbs_addon.trace.camera import CameraModel

    cam = CameraModel(sc.camera)
    rows, cols = np.mgrid[0:120, 0:160]
    o, d = eye.camera_rays(cam.kernel_params(), (cols.ravel() + 0.5) / 4, (rows.ravel() + 0.5) / 4)
    t = -o[:, 2] / d[:, 2]
    np.testing.assert_allclose(p, o + t[:, None] * d, atol=1e-4)


def test_a_bumped_receivers_view_cycles_cannot_render_is_said(monkeypatch):
    """Where Cycles cannot render the view, the receiver is shaded unbumped, said once, and the scene
    the export made for it is removed again."""
    _floor_under_camera(_bumpy("Stone"))
    before = _blend_data()

    def fails(sc):
        assert sc.name in bpy.data.scenes
        raise RuntimeError("no Cycles here")

    monkeypatch.setattr(cycles_passes, "_view_render", fails)
    sc, warnings = export()
    assert warnings == [f"scene '{scene().name}': the view of its bumped receivers could not be rendered (no Cycles "
                        f"here); the caustic on them is shaded with their unbumped normals"]
    assert _blend_data() == before
    assert sc.mat_view_bump.size == 0 and sc.view_normals.size == 0


def test_a_bumped_diffuse_in_a_mix_is_said():
    """A bump on a Diffuse BSDF inside a shader mix: the view's normal would be the mix's average, so
    the caustic on it is the unbumped surface's; said."""
    m = _bumpy("Stone")
    nt = m.node_tree
    out, diffuse = nt.nodes["Material Output"], nt.nodes["Diffuse BSDF"]
    mix = nt.nodes.new("ShaderNodeMixShader")
    nt.links.new(diffuse.outputs[0], mix.inputs[1])
    nt.links.new(nt.nodes.new("ShaderNodeBsdfDiffuse").outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    _floor_under_camera(m)
    sc, warnings = export()
    assert warnings == ["material 'Stone': the Normal of 'Diffuse BSDF' is driven by a node (a bump or normal map) "
                        "inside a shader mix: the caustic on it is shaded with the unbumped normal, where Cycles' "
                        "follows the bumps"]
    assert sc.mat_view_bump.size == 0 and sc.view_normals.size == 0


def test_a_bump_inside_a_mix_is_said():
    """A Bump node inside a shader mix (or a Normal Map node, or a linked Displacement, below): the
    layer cannot evaluate them, so the caustic is the unbumped surface's; said, once."""
    m = _height_glass("Mixed")
    nt = m.node_tree
    out, glass = nt.nodes["Material Output"], nt.nodes["Glass BSDF"]
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.0
    nt.links.new(glass.outputs[0], mix.inputs[1])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIELECTRIC and len(sc.tri_vertices) == 12
    assert warnings == ["material 'Mixed': the Normal of 'Glass BSDF' is driven by nodes the export cannot bake (a "
                        "Bump node below another node, a node group, a mesh attribute, a bump inside a shader mix): its "
                        "caustic is baked from the unbumped surface, where Cycles' follows the bumps"]


def test_a_bump_whose_height_reads_a_mesh_attribute_is_said():
    """Cycles' bake of the Height would read the copy's attributes, which the export does not carry over."""
    m = material("Painted", "ShaderNodeBsdfGlossy", Roughness=0.0)
    nt = m.node_tree
    bump = nt.nodes.new("ShaderNodeBump")
    nt.links.new(bump.outputs[0], nt.nodes["Glossy BSDF"].inputs["Normal"])
    nt.links.new(nt.nodes.new("ShaderNodeAttribute").outputs["Fac"], bump.inputs["Height"])
    _, warnings = one_material(m)
    assert len(warnings) == 1 and warnings[0].startswith("material 'Painted': ") \
        and "driven by nodes the export cannot bake" in warnings[0], warnings


@pytest.mark.parametrize("name,node_type,driver,socket,said", [
    ("Nested", "ShaderNodeBsdfGlossy", "ShaderNodeBump", "Bump", "driven by nodes the export cannot bake"),
    ("Displaced", "ShaderNodeBsdfGlass", "ShaderNodeDisplacement", "Material Output", "its Displacement is linked")])
def test_nested_bumps_or_a_displacement_are_said(name, node_type, driver, socket, said):
    """A Bump node whose Normal is another Bump's (Cycles' bake has no differentials), or a linked Displacement."""
    m = material(name, node_type, Roughness=0.0)
    nt = m.node_tree
    if socket == "Bump":
        outer = nt.nodes.new("ShaderNodeBump")
        nt.links.new(outer.outputs[0], nt.nodes["Glossy BSDF"].inputs["Normal"])
        nt.links.new(nt.nodes.new("ShaderNodeTexNoise").outputs[0], outer.inputs["Height"])
    node = outer if socket == "Bump" else nt.nodes[socket]
    nt.links.new(nt.nodes.new(driver).outputs[0], node.inputs["Displacement" if node.type == "OUTPUT_MATERIAL"
                                                              else "Normal"])
    _, warnings = one_material(m)
    assert len(warnings) == 1 and warnings[0].startswith(f"material '{name}': ") and said in warnings[0], warnings


def test_a_normal_map_on_a_mirror_is_baked_as_cycles_evaluates_it():
    """A Normal Map node (tangent space, from the UV map) on a mirror's Normal: Cycles bakes the node's
    output, a world-space normal, at every corner of the finer mesh; the exported corner normals are it.
    A constant colour (0.8, 0.5, 1) tilts the normal towards the tangent (+U, here the object's +X) by
    atan(0.6); the object is turned, and so is the normal."""
    m = material("Hammered", "ShaderNodeBsdfGlossy", Roughness=0.0)
    nt = m.node_tree
    nm, rgb = nt.nodes.new("ShaderNodeNormalMap"), nt.nodes.new("ShaderNodeRGB")
    rgb.outputs[0].default_value = (0.8, 0.5, 1.0, 1.0)
    nt.links.new(rgb.outputs[0], nm.inputs["Color"])
    nt.links.new(nm.outputs[0], nt.nodes["Glossy BSDF"].inputs["Normal"])
    me = bpy.data.meshes.new("Quad")
    me.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    uv = me.uv_layers.new(name="UVMap")
    uv.uv.foreach_set("vector", [0, 0, 1, 0, 1, 1, 0, 1])
    me.materials.append(m)
    ob = link(bpy.data.objects.new("Sheet", me))
    ob.rotation_euler = (0.3, 0.0, 0.5)
    add_camera()
    before = _blend_data()
    sc, warnings = export()
    assert warnings == [] and _blend_data() == before
    v, n = obj_tris(sc, "Sheet")
    assert len(v) == bump.TARGET_TRIANGLES
    R = np.array(ob.matrix_world)[:3, :3]
    want = R @ (np.array([0.6, 0.0, 1.0]) / np.hypot(0.6, 1.0))
    assert np.abs(n - want).max() < 1e-5, np.abs(n - want).max()
    assert sc.tri_normals_back.shape == (0, 3, 3)  # a Normal Map flips with the surface


def test_holdout_and_shadow_catcher_are_said_to_be_unread():
    """The Ray Visibility is read (nothing to say of it); a shadow catcher is not."""
    ob = mesh_with(material("D", "ShaderNodeBsdfDiffuse"))
    ob.visible_camera = False
    ob.visible_shadow = False
    ob.visible_glossy = False
    ob.visible_transmission = False
    ob.is_shadow_catcher = True
    add_camera()
    _, warnings = export()
    assert warnings == ["object 'Thing': a shadow catcher; the caustic on it is composited like any receiver's, not "
                        "into Cycles' shadow catcher pass"]
    assert ob.visible_camera is False and ob.is_shadow_catcher  # the user's scene is only read


def test_ray_visibility_of_objects_and_lights_is_read():
    """Diffuse rays off on a glass (no caustic of it) and shadow rays off (in no caustic path) say nothing;
    the objects' and lights' Ray Visibility is exported as S.RAY_* bits (shadow rays are in no caustic
    path: a light's bits keep them)."""
    ob = mesh_with(material("G", "ShaderNodeBsdfGlass"))
    ob.visible_diffuse = False
    ob.visible_shadow = False
    lamp = add_light("POINT")
    lamp.visible_glossy = False
    add_camera()
    sc, warnings = export()
    assert warnings == []
    assert sc.object_visibility.tolist() == [S.RAY_ALL & ~S.RAY_DIFFUSE & ~S.RAY_SHADOW]
    assert sc.light_visibility.tolist() == [S.RAY_ALL & ~S.RAY_GLOSSY]
    assert ob.visible_diffuse is False and lamp.visible_glossy is False  # the user's scene is only read


def test_a_textured_metal_is_still_a_diffuse_stand_in():
    m, _ = _textured("Brass", "ShaderNodeBsdfPrincipled", "Base Color", "ShaderNodeTexNoise")
    m.node_tree.nodes["Principled BSDF"].inputs["Metallic"].default_value = 1.0
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIFFUSE and not np.any(sc.mat_textured) and np.allclose(sc.mat_color[0], 0.8)
    assert len(warnings) == 1 and "diffuse surfaces only" in warnings[0]


def test_rgb_and_value_nodes_count_as_constants():
    m = material("Const", "ShaderNodeBsdfGlass")
    nt = m.node_tree
    rgb = nt.nodes.new("ShaderNodeRGB")
    rgb.outputs[0].default_value = (0.25, 0.5, 0.75, 1.0)
    val = nt.nodes.new("ShaderNodeValue")
    val.outputs[0].default_value = 1.6
    nt.links.new(rgb.outputs[0], nt.nodes["Glass BSDF"].inputs["Color"])
    nt.links.new(val.outputs[0], nt.nodes["Glass BSDF"].inputs["IOR"])
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIELECTRIC and np.isclose(sc.mat_ior[0], 1.6)
    assert np.allclose(sc.mat_color[0], [0.25, 0.5, 0.75]) and warnings == []


def test_unlinked_surface_is_black():
    m = bpy.data.materials.new("Empty")
    m.node_tree.nodes.clear()
    m.node_tree.nodes.new("ShaderNodeOutputMaterial")
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.mat_color[0], 0)
    assert len(warnings) == 1 and "'Empty'" in warnings[0]


def test_default_factory_material_is_principled_diffuse():
    sc, warnings = one_material(bpy.data.materials.new("New"))
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.mat_color[0], 0.8, atol=1e-6)
    # under the glossy layer of Blender's defaults: IOR 1.5, Roughness 0.5, Specular Tint white
    assert np.allclose(sc.mat_layer[0], [1.5, 0.5, 1.0, 1.0, 0.0, 0.0, 1.5, 0.03], atol=1e-6)
    assert warnings == []


def test_principled_diffuse_keeps_what_metallic_transmission_and_its_glossy_layer_leave():
    """Cycles' Principled BSDF weighs its diffuse by (1 - Metallic)(1 - Transmission) under a
    dielectric glossy layer whose reflectance at normal incidence is F0(IOR) x 2 x Specular IOR
    Level, tinted by Specular Tint (layer.principled_layer); Level 0 takes the layer away."""
    from smbs_addon.shading.coat import ior_from_f0

    sc, w = one_material(material("Half", "ShaderNodeBsdfPrincipled", **{
        "Base Color": (0.5, 0.6, 0.7), "Metallic": 0.2, "Transmission Weight": 0.25, "Roughness": 0.3,
        "IOR": 1.4, "Specular IOR Level": 0.25, "Specular Tint": (0.5, 0.9, 0.2, 1.0)}))
    assert sc.mat_kind[0] == S.DIFFUSE and w == []
    assert np.allclose(sc.mat_color[0], np.array([0.5, 0.6, 0.7]) * 0.8 * 0.75, atol=1e-6)
    f0 = ((1.4 - 1.0) / 2.4) ** 2 * 0.5
    assert np.allclose(sc.mat_layer[0], [ior_from_f0(f0), 0.3, 0.9, 0.8 * 0.75, 0.0, 0.0, 1.5, 0.03], atol=1e-6)


def test_rough_diffuse_is_oren_nayar():
    """Cycles shades a Diffuse BSDF of Roughness 1e-5 or more, and a Principled BSDF's Diffuse
    Roughness, by Oren-Nayar (layer.oren_nayar_ratio): its sigma is mat_layer's last column."""
    sc, w = one_material(material("Rough", "ShaderNodeBsdfDiffuse", Color=(0.5, 0.5, 0.5), Roughness=0.6))
    assert sc.mat_kind[0] == S.DIFFUSE and w == []
    assert np.allclose(sc.mat_layer[0], [0.0, 0.0, 0.0, 1.0, 0.6, 0.0, 0.0, 0.0], atol=1e-6)


def test_principled_diffuse_roughness_is_oren_nayar_under_the_coat():
    sc, w = one_material(material("RoughP", "ShaderNodeBsdfPrincipled", **{"Diffuse Roughness": 0.4}))
    assert w == [] and np.allclose(sc.mat_layer[0], [1.5, 0.5, 1.0, 1.0, 0.4, 0.0, 1.5, 0.03], atol=1e-6)


def test_principled_clear_coat_over_a_receiver():
    """A Principled clear coat (Coat Weight) over a diffuse receiver takes its share towards the eye
    too (layer.clearcoat_table); a tinted one, or one over metal, is warned about."""
    from smbs_addon.shading import coat as layer

    sc, w = one_material(material("Varnish", "ShaderNodeBsdfPrincipled", **{"Coat Weight": 1.0}))
    assert w == [] and np.allclose(sc.mat_layer[0, 5:], [1.0, 1.5, 0.03], atol=1e-6)
    # Cycles' plane under a sun, the default coat under Coat Weight 1 (tests/test_layer.py's way)
    got = layer.weight(layer.table(sc), np.zeros(2, np.int64), np.array([1.0, 0.356]))
    np.testing.assert_allclose(got, [0.9241, 0.7572], rtol=0.005)


def test_a_clear_coat_over_metal_or_tinted_is_said_to_be_ignored():
    sc, w = one_material(material("CarPaint", "ShaderNodeBsdfPrincipled", **{
        "Coat Weight": 1.0, "Coat Tint": (0.8, 0.2, 0.2, 1.0)}))
    assert w == ["material 'CarPaint': Principled BSDF coat ignored"] and sc.mat_layer[0, 5] == 0.0


def test_principled_without_specular_has_no_glossy_layer():
    sc, _ = one_material(material("Matte", "ShaderNodeBsdfPrincipled", **{"Specular IOR Level": 0.0}))
    assert sc.mat_kind[0] == S.DIFFUSE and sc.mat_layer.shape == (0, 8)  # no layer anywhere


# ------------------------------------------------------------------------------- lights
def add_light(kind, location=(0, 0, 3), rotation=(0, 0, 0), scale=(1, 1, 1), **props):
    lt = bpy.data.lights.new(kind.title(), kind)
    for k, v in props.items():
        setattr(lt, k, v)
    ob = link(bpy.data.objects.new(kind.title(), lt))
    ob.location, ob.rotation_euler, ob.scale = location, rotation, scale
    return ob


def test_point_light():
    add_camera()
    add_light("POINT", energy=250.0, color=(1.0, 0.5, 0.5), shadow_soft_size=0.1,
              use_soft_falloff=False)
    sc, _ = export()
    assert sc.light_type.tolist() == [S.POINT] and sc.light_names == ["Point"]
    assert np.allclose(sc.light_color[0], [250, 125, 125])
    assert np.isclose(sc.light_radius[0], 0.1) and not sc.light_soft_falloff[0]
    assert np.allclose(sc.light_matrix[0][:3, 3], [0, 0, 3])
    assert not sc.light_caustics[0]


def test_spot_light_and_exposure():
    add_camera()
    ob = add_light("SPOT", energy=100.0, exposure=1.0, spot_size=math.radians(60),
                   spot_blend=0.3, shadow_soft_size=0.2)
    ob.data.cycles.is_caustics_light = True
    sc, _ = export()
    assert sc.light_type[0] == S.SPOT and np.allclose(sc.light_color[0], 200.0)
    assert np.isclose(sc.light_spot_size[0], math.radians(60))
    assert np.isclose(sc.light_spot_blend[0], 0.3) and sc.light_soft_falloff[0]
    assert sc.light_caustics[0]


def test_area_light_size_takes_object_scale():
    add_camera()
    add_light("AREA", rotation=(0.2, 0.0, 0.5), scale=(2.0, 3.0, 4.0), energy=50.0,
              shape="RECTANGLE", size=0.5, size_y=0.25, spread=math.radians(90))
    add_light("AREA", scale=(2.0, 2.0, 1.0), energy=10.0, shape="DISK", size=0.5).name = "Disk"
    sc, _ = export()
    i = sc.light_names.index("Area")
    assert sc.light_type[i] == S.AREA and sc.light_shape[i] == S.RECTANGLE
    assert np.allclose(sc.light_size[i], [1.0, 0.75])
    assert np.allclose(np.linalg.norm(sc.light_matrix[i][:3, :3], axis=0), 1.0)  # scale removed
    R = np.array(bpy.data.objects["Area"].matrix_world.to_3x3().normalized())
    assert np.allclose(sc.light_matrix[i][:3, :3], R)
    assert np.isclose(sc.light_spread[i], math.radians(90)) and np.allclose(sc.light_color[i], 50)
    j = sc.light_names.index("Disk")
    assert sc.light_shape[j] == S.DISK and np.allclose(sc.light_size[j], [1.0, 1.0])


def test_square_area_light_with_unequal_scale_becomes_a_rectangle():
    add_camera()
    add_light("AREA", scale=(1.0, 2.0, 1.0), shape="SQUARE", size=0.5)
    sc, _ = export()
    assert sc.light_shape[0] == S.RECTANGLE and np.allclose(sc.light_size[0], [0.5, 1.0])


def test_unnormalized_area_light_power_scales_with_area():
    add_camera()
    add_light("AREA", energy=10.0, shape="SQUARE", size=2.0, normalize=False)
    sc, _ = export()
    assert np.allclose(sc.light_color[0], 40.0)  # Cycles: strength not divided by area 4 m^2


def test_sun_light():
    add_camera()
    add_light("SUN", rotation=(0, math.radians(30), 0), energy=3.0, angle=math.radians(0.5))
    sc, _ = export()
    assert sc.light_type[0] == S.SUN and np.allclose(sc.light_color[0], 3.0)
    assert np.isclose(sc.light_angle[0], math.radians(0.5))
    d = -sc.light_matrix[0][:3, 2]  # travel direction: local -Z
    assert np.allclose(d, [-0.5, 0, -math.sqrt(3) / 2])


# ------------------------------------------------------------------------------- camera
def test_camera_fields():
    cam_ob = add_camera(location=(1, -5, 2), lens=35.0, sensor_width=32.0, sensor_height=20.0,
                        sensor_fit="HORIZONTAL", shift_x=0.1, shift_y=-0.05,
                        clip_start=0.5, clip_end=50.0)
    cam_ob.scale = (2, 2, 2)
    r = scene().render
    r.resolution_x, r.resolution_y, r.resolution_percentage = 320, 200, 50
    r.pixel_aspect_x, r.pixel_aspect_y = 1.0, 2.0
    r.use_border, r.use_crop_to_border = True, True
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.1, 0.6, 0.2, 0.9
    scene().cycles.filter_width = 2.0
    sc, _ = export()
    c = sc.camera
    assert c.type == S.PERSP and c.lens == 35.0 and c.sensor_fit == "HORIZONTAL"
    assert (c.sensor_width, c.sensor_height) == (32.0, 20.0)
    assert np.isclose(c.shift_x, 0.1) and np.isclose(c.shift_y, -0.05)
    assert (c.clip_start, c.clip_end) == (0.5, 50.0)
    assert (c.resolution_x, c.resolution_y, c.resolution_percentage) == (320, 200, 50)
    assert (c.width, c.height) == (160, 100)
    assert (c.pixel_aspect_x, c.pixel_aspect_y) == (1.0, 2.0)
    assert c.use_border and c.use_crop_to_border
    assert np.allclose(c.border, (0.1, 0.6, 0.2, 0.9))
    assert c.filter_width == 2.0
    assert np.allclose(c.matrix_world[:3, 3], [1, -5, 2])
    assert np.allclose(np.linalg.norm(c.matrix_world[:3, :3], axis=0), 1)  # scale removed
    assert np.allclose(-c.matrix_world[:3, 2], [0, 1, 0], atol=1e-6)  # looks along +y


def test_ortho_camera():
    add_camera(type="ORTHO", ortho_scale=2.5)
    sc, _ = export()
    assert sc.camera.type == S.ORTHO and sc.camera.ortho_scale == 2.5


def test_panoramic_camera_is_an_error():
    add_camera(type="PANO")
    with pytest.raises(SceneError, match=r"^camera 'Cam': panoramic cameras are not supported$"):
        export()


def test_no_camera_is_an_error():
    scene().name = "Empty Scene"
    mesh_with(None)
    with pytest.raises(SceneError, match=r"^scene 'Empty Scene' has no camera$"):
        export()


# -------------------------------------------------------------------------------- world
def test_world_background_colour_times_strength():
    add_camera()
    w = bpy.data.worlds.new("Sky")
    scene().world = w
    bg = w.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.5, 0.25, 1.0, 1.0)
    bg.inputs["Strength"].default_value = 2.0
    w.cycles.is_caustics_light = True
    sc, warnings = export()
    assert np.allclose(sc.world_color, [1.0, 0.5, 2.0]) and warnings == []
    # a light of the layer's: radiance from every direction, flagged as the world is
    assert sc.light_names == ["Sky"] and sc.light_type.tolist() == [S.WORLD]
    assert np.allclose(sc.light_color[0], [1.0, 0.5, 2.0]) and sc.light_caustics.tolist() == [True]
    assert sc.light_visibility.size == 0  # every ray sees it
    w.cycles_visibility.glossy = False  # World > Settings > Ray Visibility: what Cycles' own world does
    sc, warnings = export()
    assert sc.light_names == ["Sky"] and warnings == []
    assert sc.light_visibility.tolist() == [S.RAY_ALL & ~S.RAY_GLOSSY]  # no caustic through mirrors
    w.cycles_visibility.transmission = False  # no caustic ray sees it: no light
    sc, warnings = export()
    assert sc.light_names == [] and warnings == [] and np.allclose(sc.world_color, [1.0, 0.5, 2.0])
    w.cycles.is_caustics_light = False
    bg.inputs["Strength"].default_value = 0.0  # black: no light
    sc, _ = export()
    assert sc.light_names == [] and np.allclose(sc.world_color, 0)


def test_textured_world_is_black_with_a_warning():
    add_camera()
    w = bpy.data.worlds.new("Sky")
    scene().world = w
    sky = w.node_tree.nodes.new("ShaderNodeTexSky")
    w.node_tree.links.new(sky.outputs[0], w.node_tree.nodes["Background"].inputs["Color"])
    sc, warnings = export()
    assert np.allclose(sc.world_color, 0) and sc.light_names == []
    assert len(warnings) == 1 and warnings[0].startswith("world 'Sky':")
    from smbs_addon.blender.world import world_unread

    assert world_unread(scene()) == "Sky"  # the policy names it (rendered by neither)
    _environment_world(rotation=(0, 0, 30))
    assert world_unread(scene()) is None


def _environment_world(projection="EQUIRECTANGULAR", rotation=None, location=(0, 0, 0), vector_type="POINT"):
    w = bpy.data.worlds.new("Sky")
    scene().world = w
    img = bpy.data.images.new("hdr", 8, 4, float_buffer=True)
    px = np.arange(8 * 4 * 4, dtype=np.float32).reshape(4, 8, 4) / 10.0
    img.pixels.foreach_set(px.ravel())
    nt = w.node_tree
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image, env.projection = img, projection
    nt.links.new(env.outputs["Color"], nt.nodes["Background"].inputs["Color"])
    nt.nodes["Background"].inputs["Strength"].default_value = 3.0
    if rotation is not None:
        mp, tc = nt.nodes.new("ShaderNodeMapping"), nt.nodes.new("ShaderNodeTexCoord")
        mp.vector_type = vector_type
        mp.inputs["Rotation"].default_value = [math.radians(a) for a in rotation]
        mp.inputs["Location"].default_value = location
        nt.links.new(tc.outputs["Generated"], mp.inputs["Vector"])
        nt.links.new(mp.outputs["Vector"], env.inputs["Vector"])
    return px[..., :3]


def test_an_environment_texture_is_the_worlds_map():
    """An equirectangular Environment Texture on the Background's Color is the world light's map
    (Scene.world_map: the linear pixels, rows from the bottom up, as bpy holds them), its Strength
    the light's colour, a Mapping node's turn the lookup's (Texture type: the inverse)."""
    add_camera()
    px = _environment_world(rotation=(10, 20, 30))
    sc, warnings = export()
    assert warnings == [] and sc.light_names == ["Sky"] and sc.light_type.tolist() == [S.WORLD]
    assert np.array_equal(sc.world_map, px) and np.allclose(sc.light_color[0], 3.0)
    from mathutils import Euler
    R = np.array(Euler([math.radians(a) for a in (10, 20, 30)]).to_matrix())
    assert np.allclose(sc.world_map_rotation, R)
    _environment_world(rotation=(10, 20, 30), vector_type="TEXTURE")
    assert np.allclose(export()[0].world_map_rotation, R.T)
    _environment_world()
    sc, warnings = export()
    assert warnings == [] and np.allclose(sc.world_map_rotation, np.eye(3))


def test_a_large_map_is_averaged_down():
    """An HDRI wider than WORLD_MAP_WIDTH is averaged over blocks (uneven where the widths do not
    divide): every block the mean of its pixels, the map's mean kept."""
    from smbs_addon.blender.world import _averaged_down

    rng = np.random.default_rng(3)
    img = rng.random((10, 20, 3)).astype(np.float32)
    small = _averaged_down(img, 4)
    assert small.shape == (2, 4, 3) and small.dtype == np.float32
    assert np.allclose(small[0, 0], img[:5, :5].mean(axis=(0, 1)), atol=1e-6)
    assert np.allclose(small.mean(axis=(0, 1)), img.mean(axis=(0, 1)), atol=1e-6)
    odd = _averaged_down(img, 3)  # columns 0-7, 7-13, 13-20
    assert odd.shape == (2, 3, 3) and np.allclose(odd[1, 1], img[5:, 7:13].mean(axis=(0, 1)), atol=1e-6)
    assert _averaged_down(img, 20) is img


def test_an_hdris_negative_or_nan_pixels_are_black_and_said():
    """A few negative or NaN pixels (left by an HDRI's processing) would make the scene invalid:
    they are taken as black, the rest kept, and the warning names the world and the image."""
    add_camera()
    px = _environment_world()
    img = bpy.data.images["hdr"]
    bad = px.copy()
    bad[1, 2, 0], bad[3, 5, 1] = -0.5, float("nan")
    img.pixels.foreach_set(np.concatenate([bad, np.ones((4, 8, 1), np.float32)], axis=2).ravel())
    sc, warnings = export()
    assert sc.world_map[1, 2, 0] == 0 and sc.world_map[3, 5, 1] == 0
    keep = np.ones(px.shape, bool)
    keep[1, 2, 0] = keep[3, 5, 1] = False
    assert np.array_equal(sc.world_map[keep], px[keep])
    assert warnings == ["world 'Sky': image 'hdr': 2 pixels negative or not a number, taken as black"], warnings


@pytest.mark.parametrize("kw, why", [
    (dict(projection="MIRROR_BALL"), "its mirror ball projection is not supported"),
    (dict(rotation=(0, 0, 45), location=(0, 0, 1)), "only a turn (no Location"),
])
def test_an_environment_the_layer_cannot_read_is_black_with_a_warning(kw, why):
    add_camera()
    _environment_world(**kw)
    sc, warnings = export()
    assert sc.light_names == [] and sc.world_map.size == 0
    assert len(warnings) == 1 and warnings[0].startswith("world 'Sky'") and why in warnings[0], warnings


# -------------------------------------------------------------------- files and safety
def test_mirror_sample_blend():
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLES / "mirror.blend"))
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
        bpy.ops.wm.open_mainfile(filepath=str(SAMPLES / f"{name}.blend"))
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
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLES / "waves.blend"))
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
    ob.data.materials.append(material("Foo", "ShaderNodeMixShader"))
    add_light("AREA", scale=(2, 2, 2))
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


def test_light_node_tree_emission_scales_the_light():
    add_camera()
    ob = add_light("POINT", energy=10.0)
    ob.data.use_nodes = True
    em = ob.data.node_tree.nodes["Emission"]
    em.inputs["Strength"].default_value = 3.0
    em.inputs["Color"].default_value = (1.0, 0.5, 1.0, 1.0)
    sc, warnings = export()
    assert np.allclose(sc.light_color[0], [30, 15, 30]) and warnings == []
    ob.data.use_nodes = False
    sc, _ = export()
    assert np.allclose(sc.light_color[0], 10)


def test_principled_extras_are_reported_as_ignored():
    sc, warnings = one_material(material("Glow", "ShaderNodeBsdfPrincipled", **{
        "Emission Strength": 2.0, "Emission Color": (1.0, 1.0, 1.0), "Alpha": 0.5, "Sheen Weight": 0.3}))
    assert sc.mat_kind[0] == S.DIFFUSE and sc.n_lights == 0
    assert warnings == ["material 'Glow': Principled BSDF emission (under a coat or sheen), sheen, alpha ignored"]


def test_principled_emission_makes_a_mesh_light_of_the_receiver():
    """A Principled BSDF's Emission Color x Strength: its faces shine as a mesh light (Cycles adds the
    emission to the BSDF), and the surface stays what its BSDF makes it; in a Mix Shader the emission
    counts by the part's weight."""
    sc, warnings = one_material(material("Glow", "ShaderNodeBsdfPrincipled", **{
        "Emission Strength": 2.0, "Emission Color": (1.0, 0.5, 0.25)}))
    assert warnings == [] and sc.mat_kind[0] == S.DIFFUSE
    assert sc.light_names == ["Thing"] and sc.light_type.tolist() == [S.MESH]
    assert np.allclose(sc.light_color[0], [2.0, 1.0, 0.5]) and np.allclose(sc.mat_emission[0], [2.0, 1.0, 0.5])
    bpy.ops.wm.read_factory_settings(use_empty=True)
    m = material("Half", "ShaderNodeMixShader", Fac=0.75)
    nt = m.node_tree
    glow = nt.nodes.new("ShaderNodeBsdfPrincipled")
    glow.inputs["Emission Strength"].default_value = 4.0
    glow.inputs["Emission Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    glass = nt.nodes.new("ShaderNodeBsdfGlass")
    mix = nt.nodes["Mix Shader"]
    nt.links.new(glow.outputs[0], mix.inputs[1])
    nt.links.new(glass.outputs[0], mix.inputs[2])
    sc, _ = one_material(m)
    assert sc.mat_kind[0] == S.DIELECTRIC and np.allclose(sc.light_color[0], 1.0)  # (1 - 0.75) x 4
    bpy.ops.wm.read_factory_settings(use_empty=True)
    m = material("Sign", "ShaderNodeMixShader", Fac=0.25)  # 0.75 diffuse, 0.25 an Emission node
    nt = m.node_tree
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = 8.0
    nt.links.new(nt.nodes.new("ShaderNodeBsdfDiffuse").outputs[0], nt.nodes["Mix Shader"].inputs[1])
    nt.links.new(em.outputs[0], nt.nodes["Mix Shader"].inputs[2])
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.light_color[0], 2.0) and warnings == []


def test_library_linked_objects_are_exported(tmp_path):
    lib = tmp_path / "lib.blend"
    ob = link(bpy.data.objects.new("LibCube", cube_mesh("LibCubeMesh")))
    ob.location = (0, 0, 7)
    ob.cycles.is_caustics_caster = True
    ob.data.materials.append(material("LibGlass", "ShaderNodeBsdfGlass", IOR=1.5))
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
    c = scene().cycles
    c.max_bounces, c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces = 8, 2, 1, 6
    sc, _ = export()
    assert sc.light_paths.tolist() == [8, 2, 1, 6]
