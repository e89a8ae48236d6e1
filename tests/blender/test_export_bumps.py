"""Blender scene -> Scene arrays (smbs_addon.blender: export_scene and the modules it calls) with tiny
scenes built in bpy: bumps: a Bump node on a caster, bumped receivers as the camera sees them, normal
maps, and the bumps Cycles cannot bake."""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from smbs_addon.scene import bump  # noqa: E402
from smbs_addon.scene import arrays as S  # noqa: E402
from smbs_addon.blender import cycles_passes  # noqa: E402
from testkit.blend import add_camera, bumpy, export, link, node_material, obj_tris, one_material  # noqa: E402

pytestmark = [pytest.mark.bpy, pytest.mark.usefixtures("empty_bpy")]


def _height_glass(name, node_type="ShaderNodeBsdfGlass", coords="Object", **inputs):
    """A mirror or glass whose Normal is a Bump node (Distance 0.5, Strength 0.8) of the Height
    0.3 x - 0.2 y^2 in the Texture Coordinate node's coords."""
    m = node_material(name, node_type, **inputs)
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


def _floor_under_camera(m, s_x=40, s_y=30):
    me = bpy.data.meshes.new("Floor")
    me.from_pydata([(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], [], [(0, 1, 2, 3)])
    me.materials.append(m)
    link(bpy.data.objects.new("Floor", me))
    add_camera(location=(0.2, 0.1, 4.0), rotation=(0.1, 0, 0))
    bpy.context.scene.render.resolution_x, bpy.context.scene.render.resolution_y = s_x, s_y


def _render_settings():
    sc = bpy.context.scene
    r = sc.render
    return (r.resolution_x, r.resolution_y, r.resolution_percentage, r.filepath, r.engine, r.use_border,
            sc.cycles.samples, sc.cycles.filter_width, sc.view_layers[0].use_pass_normal)


@pytest.mark.parametrize("node_type", ["ShaderNodeBsdfDiffuse", "ShaderNodeBsdfPrincipled"])
def test_a_bumped_diffuse_receiver_is_exported_as_the_camera_sees_it(node_type):
    """A Bump node on a Diffuse (or a diffuse Principled) BSDF's Normal: the export renders what
    Cycles' camera rays meet (cycles_passes.view_maps: the Normal and Position passes at s x s sub-pixels,
    s = 4 for 40 x 30 pixels): over the floor, unit normals the bumps tilt (up to 10 degrees and
    more), never below the floor; the points on the floor, where our own camera's rays through the
    sub-pixels' centres meet it. Nothing said; the user's scene and render settings as they were."""
    _floor_under_camera(bumpy("Stone", node_type))
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
    _floor_under_camera(bumpy("Stone"))
    before = _blend_data()

    def fails(sc):
        assert sc.name in bpy.data.scenes
        raise RuntimeError("no Cycles here")

    monkeypatch.setattr(cycles_passes, "_view_render", fails)
    sc, warnings = export()
    assert warnings == [f"scene '{bpy.context.scene.name}': the view of its bumped receivers could not be rendered "
                        f"(no Cycles here); the caustic on them is shaded with their unbumped normals"]
    assert _blend_data() == before
    assert sc.mat_view_bump.size == 0 and sc.view_normals.size == 0


def test_a_bumped_diffuse_in_a_mix_is_said():
    """A bump on a Diffuse BSDF inside a shader mix: the view's normal would be the mix's average, so
    the caustic on it is the unbumped surface's; said."""
    m = bumpy("Stone")
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
    m = node_material("Painted", "ShaderNodeBsdfGlossy", Roughness=0.0)
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
    m = node_material(name, node_type, Roughness=0.0)
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
    m = node_material("Hammered", "ShaderNodeBsdfGlossy", Roughness=0.0)
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
