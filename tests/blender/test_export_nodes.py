"""Blender scene -> Scene arrays (smbs_addon.blender: export_scene and the modules it calls) with tiny
scenes built in bpy: node trees: mixes and adds of shaders, the classic Fresnel mixes, constants and
linked inputs, textured colours, volumes, what is said to be unread."""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from smbs_addon.scene import arrays as S  # noqa: E402
from testkit.blend import add_camera, by_fresnel, export, mesh_with, mixed, node_material, one_material  # noqa: E402

pytestmark = [pytest.mark.bpy, pytest.mark.usefixtures("empty_bpy")]


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
    sc, _ = one_material(node_material("Alone", "ShaderNodeBsdfPrincipled", **metal))
    alone, _ = specular_weights(sc, np.zeros(4, np.int64), cos)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc, _ = one_material(mixed("Mixed", ("ShaderNodeBsdfPrincipled", metal), ("ShaderNodeBsdfDiffuse", {}),
                               factor=0.4))
    R, _ = specular_weights(sc, np.zeros(4, np.int64), cos)
    np.testing.assert_allclose(R, 0.6 * alone, rtol=1e-6)  # (the Factor is a float32)


def test_unsupported_node_warns_naming_the_material():
    m = node_material("Foo", "ShaderNodeBsdfTransparent")
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.mat_color[0], 0.8)
    assert warnings == ["material 'Foo': node 'Transparent BSDF' is not supported; "
                        "treated as diffuse (albedo 0.8)"]


def test_an_empty_mix_shader_renders_black():
    sc, warnings = one_material(node_material("Foo", "ShaderNodeMixShader", Factor=0.5))
    assert sc.mat_kind[0] == S.DIFFUSE and np.all(sc.mat_color[0] == 0)
    assert warnings == ["material 'Foo': its shader mix has no closures (renders black in Cycles); "
                        "treated as black diffuse"]


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


@pytest.mark.parametrize("layer_weight", [False, True])
def test_the_old_glass_of_refraction_and_glossy_by_fresnel_is_a_glass(layer_weight):
    """Mix(Refraction, Glossy) by a Fresnel node of the same index: Cycles weighs the refraction by 1 - F
    and the reflection by F, as a Glass BSDF does, each lobe with its own colour."""
    m = by_fresnel(mixed("OldGlass", ("ShaderNodeBsdfRefraction", {"Color": (0.9, 1.0, 0.9), "IOR": 1.45}),
                          ("ShaderNodeBsdfGlossy", {"Color": (1.0, 1.0, 1.0), "Roughness": 0.0})),
                    layer_weight=layer_weight)
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIELECTRIC and sc.mat_fresnel[0] == S.FRESNEL_NONE and warnings == []
    assert np.isclose(sc.mat_ior[0], 1.45) and np.allclose(sc.mat_color[0], [0.9, 1.0, 0.9])
    assert np.allclose(sc.mat_reflect_color[0], 1.0)


def test_the_old_glass_with_another_fresnel_index_warns():
    m = by_fresnel(mixed("OldGlass", ("ShaderNodeBsdfRefraction", {"IOR": 1.5, "Roughness": 0.0}),
                          ("ShaderNodeBsdfGlossy", {"Roughness": 0.0})), ior=1.33)
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIELECTRIC and np.isclose(sc.mat_ior[0], 1.5)
    assert len(warnings) == 1 and "of index 1.33, its refraction of 1.5" in warnings[0]


def test_a_diffuse_under_a_glossy_by_fresnel_keeps_one_minus_fresnel():
    """Mix(Diffuse, Glossy) by a Fresnel node: the diffuse's weight towards the eye is 1 - F(mu), which
    is layer.py's table for a coat of that index at Roughness 0."""
    from smbs_addon.shading import coat as layer
    from smbs_addon.shading.fresnel import fresnel_dielectric
    m = by_fresnel(mixed("OldFloor", ("ShaderNodeBsdfDiffuse", {"Color": (0.5, 0.6, 0.7)}),
                          ("ShaderNodeBsdfGlossy", {"Roughness": 0.2})), ior=1.5)
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.mat_color[0], [0.5, 0.6, 0.7])
    assert np.allclose(sc.mat_layer[0], [1.5, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0])
    mu = np.linspace(0.0, 1.0, layer.MU_STEPS + 1)[1:]
    assert np.allclose(layer.table(sc)[0, 1:], 1.0 - fresnel_dielectric(mu, 1.5), atol=1e-4)
    assert len(warnings) == 1 and "Glossy part 'Glossy BSDF'" in warnings[0]


def test_a_fresnel_mix_of_other_shaders_is_named():
    m = by_fresnel(mixed("Odd", ("ShaderNodeBsdfGlossy", {}), ("ShaderNodeBsdfRefraction", {})))
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
    m = node_material("Textured", "ShaderNodeBsdfGlass")
    tex = m.node_tree.nodes.new("ShaderNodeTexChecker")
    m.node_tree.links.new(tex.outputs["Color"], m.node_tree.nodes["Glass BSDF"].inputs["Color"])
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.mat_color[0], 0.8)
    assert len(warnings) == 1 and warnings[0].startswith("material 'Textured': input 'Color'")
    assert "'Checker Texture'" in warnings[0] and warnings[0].endswith("(albedo 0.8)")


def _textured(name, shader, socket, texture):
    m = node_material(name, shader)
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
    m = _with_volume(node_material("Wine", "ShaderNodeBsdfGlass"), "ShaderNodeVolumeAbsorption",
                     Color=(0.9, 0.3, 0.1, 1.0), Density=2.5)
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIELECTRIC and warnings == []
    np.testing.assert_allclose(sc.mat_absorb[0], [0.25, 1.75, 2.25], rtol=1e-6)  # float32 sockets


@pytest.mark.parametrize("surface,volume,why", [
    ("ShaderNodeBsdfGlass", "ShaderNodeVolumeScatter", "only Volume Absorption is supported"),
    ("ShaderNodeBsdfGlossy", "ShaderNodeVolumeAbsorption", "only a glass's volume is ours")])
def test_other_volumes_are_said_to_be_ignored(surface, volume, why):
    sc, warnings = one_material(_with_volume(node_material("Smoke", surface, Roughness=0.0), volume))
    assert not np.any(sc.mat_absorb)
    assert len(warnings) == 1 and warnings[0].startswith("material 'Smoke': its Volume (") and why in warnings[0]


def test_holdout_and_shadow_catcher_are_said_to_be_unread():
    """The Ray Visibility is read (nothing to say of it); a shadow catcher is not."""
    ob = mesh_with(node_material("D", "ShaderNodeBsdfDiffuse"))
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


def test_a_textured_metal_is_still_a_diffuse_stand_in():
    m, _ = _textured("Brass", "ShaderNodeBsdfPrincipled", "Base Color", "ShaderNodeTexNoise")
    m.node_tree.nodes["Principled BSDF"].inputs["Metallic"].default_value = 1.0
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIFFUSE and not np.any(sc.mat_textured) and np.allclose(sc.mat_color[0], 0.8)
    assert len(warnings) == 1 and "diffuse surfaces only" in warnings[0]


def test_rgb_and_value_nodes_count_as_constants():
    m = node_material("Const", "ShaderNodeBsdfGlass")
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
