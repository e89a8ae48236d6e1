"""Blender scene -> Scene arrays (smbs_addon.blender: export_scene and the modules it calls) with tiny
scenes built in bpy: lights: point, spot, area and sun lamps, mesh lights, Light and Shadow Linking, Ray
Visibility."""
from __future__ import annotations

import math
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from smbs_addon.scene import arrays as S  # noqa: E402
from testkit.blend import add_camera, add_light, export, mesh_with, node_material, one_material  # noqa: E402

pytestmark = [pytest.mark.bpy, pytest.mark.usefixtures("empty_bpy")]


def test_an_emission_object_is_a_mesh_light_of_its_own():
    """Cycles lights the scene with an Emission shader's object (a mesh light): the export makes it a
    light named after the object, of radiance Color x Strength, taking the object's Ray Visibility."""
    add_camera()
    lamp = mesh_with(node_material("Lamp", "ShaderNodeEmission", Color=(1.0, 0.5, 0.25), Strength=7.0), "Softbox")
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
    glass = node_material("Glass", "ShaderNodeBsdfGlass")
    ball, pane, floor, wall = (mesh_with(glass, n) for n in ("Ball", "Pane", "Floor", "Wall"))
    add_light(bpy.context.scene, "Point", "POINT", energy=10.0, caustics=False)
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
    lamp = add_light(bpy.context.scene, "Spot", "SPOT", energy=10.0, caustics=False)
    lamp.light_linking.receiver_collection = inc
    sun = add_light(bpy.context.scene, "Sun", "SUN", energy=1.0, caustics=False)
    sun.light_linking.receiver_collection = exc
    glow = mesh_with(node_material("Lamp", "ShaderNodeEmission", Strength=3.0), "Panel")
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
    glass = node_material("Glass", "ShaderNodeBsdfGlass")
    ball, wall = mesh_with(glass, "Ball"), mesh_with(glass, "Wall")
    lamp = add_light(bpy.context.scene, "Point", "POINT", energy=10.0, caustics=False)
    only = bpy.data.collections.new("OnlyWall")
    only.objects.link(wall)
    lamp.light_linking.blocker_collection = only
    glow = mesh_with(node_material("Lamp", "ShaderNodeEmission", Strength=3.0), "Panel")
    glow.light_linking.blocker_collection = only
    glow.light_linking.receiver_collection = only
    sc, warnings = export()
    assert warnings == []
    for light in ("Point", "Panel"):
        li = sc.light_names.index(light)
        assert sorted(n for n, on in zip(sc.object_names, sc.unshadowing(li)) if not on) == ["Wall"]
    assert _links(sc, "Point") == ["Ball", "Panel", "Wall"] and _links(sc, "Panel") == ["Wall"]
    assert ball.name == "Ball"


def test_ray_visibility_of_objects_and_lights_is_read():
    """Diffuse rays off on a glass (no caustic of it) and shadow rays off (in no caustic path) say nothing;
    the objects' and lights' Ray Visibility is exported as S.RAY_* bits (shadow rays are in no caustic
    path: a light's bits keep them)."""
    ob = mesh_with(node_material("G", "ShaderNodeBsdfGlass"))
    ob.visible_diffuse = False
    ob.visible_shadow = False
    lamp = add_light(bpy.context.scene, "Point", "POINT", energy=10.0, caustics=False)
    lamp.visible_glossy = False
    add_camera()
    sc, warnings = export()
    assert warnings == []
    assert sc.object_visibility.tolist() == [S.RAY_ALL & ~S.RAY_DIFFUSE & ~S.RAY_SHADOW]
    assert sc.light_visibility.tolist() == [S.RAY_ALL & ~S.RAY_GLOSSY]
    assert ob.visible_diffuse is False and lamp.visible_glossy is False  # the user's scene is only read


def test_point_light():
    add_camera()
    add_light(bpy.context.scene, "Point", "POINT", energy=250.0, color=(1.0, 0.5, 0.5), shadow_soft_size=0.1,
              use_soft_falloff=False, caustics=False)
    sc, _ = export()
    assert sc.light_type.tolist() == [S.POINT] and sc.light_names == ["Point"]
    assert np.allclose(sc.light_color[0], [250, 125, 125])
    assert np.isclose(sc.light_radius[0], 0.1) and not sc.light_soft_falloff[0]
    assert np.allclose(sc.light_matrix[0][:3, 3], [0, 0, 3])
    assert not sc.light_caustics[0]


def test_spot_light_and_exposure():
    add_camera()
    ob = add_light(bpy.context.scene, "Spot", "SPOT", energy=100.0, exposure=1.0, spot_size=math.radians(60),
                   spot_blend=0.3, shadow_soft_size=0.2, caustics=False)
    ob.data.cycles.is_caustics_light = True
    sc, _ = export()
    assert sc.light_type[0] == S.SPOT and np.allclose(sc.light_color[0], 200.0)
    assert np.isclose(sc.light_spot_size[0], math.radians(60))
    assert np.isclose(sc.light_spot_blend[0], 0.3) and sc.light_soft_falloff[0]
    assert sc.light_caustics[0]


def test_area_light_size_takes_object_scale():
    add_camera()
    add_light(bpy.context.scene, "Area", "AREA", rotation=(0.2, 0.0, 0.5), scale=(2.0, 3.0, 4.0), energy=50.0,
              shape="RECTANGLE", size=0.5, size_y=0.25, spread=math.radians(90), caustics=False)
    add_light(bpy.context.scene, "Area", "AREA", scale=(2.0, 2.0, 1.0), energy=10.0, shape="DISK",
              size=0.5, caustics=False).name = "Disk"
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
    add_light(bpy.context.scene, "Area", "AREA", scale=(1.0, 2.0, 1.0), shape="SQUARE", size=0.5, energy=10.0,
              caustics=False)
    sc, _ = export()
    assert sc.light_shape[0] == S.RECTANGLE and np.allclose(sc.light_size[0], [0.5, 1.0])


def test_unnormalized_area_light_power_scales_with_area():
    add_camera()
    add_light(bpy.context.scene, "Area", "AREA", energy=10.0, shape="SQUARE", size=2.0, normalize=False, caustics=False)
    sc, _ = export()
    assert np.allclose(sc.light_color[0], 40.0)  # Cycles: strength not divided by area 4 m^2


def test_sun_light():
    add_camera()
    add_light(bpy.context.scene, "Sun", "SUN", rotation=(0, math.radians(30), 0), energy=3.0, angle=math.radians(0.5),
              caustics=False)
    sc, _ = export()
    assert sc.light_type[0] == S.SUN and np.allclose(sc.light_color[0], 3.0)
    assert np.isclose(sc.light_angle[0], math.radians(0.5))
    d = -sc.light_matrix[0][:3, 2]  # travel direction: local -Z
    assert np.allclose(d, [-0.5, 0, -math.sqrt(3) / 2])


def test_light_node_tree_emission_scales_the_light():
    add_camera()
    ob = add_light(bpy.context.scene, "Point", "POINT", energy=10.0, caustics=False)
    ob.data.use_nodes = True
    em = ob.data.node_tree.nodes["Emission"]
    em.inputs["Strength"].default_value = 3.0
    em.inputs["Color"].default_value = (1.0, 0.5, 1.0, 1.0)
    sc, warnings = export()
    assert np.allclose(sc.light_color[0], [30, 15, 30]) and warnings == []
    ob.data.use_nodes = False
    sc, _ = export()
    assert np.allclose(sc.light_color[0], 10)


def test_principled_emission_makes_a_mesh_light_of_the_receiver():
    """A Principled BSDF's Emission Color x Strength: its faces shine as a mesh light (Cycles adds the
    emission to the BSDF), and the surface stays what its BSDF makes it; in a Mix Shader the emission
    counts by the part's weight."""
    sc, warnings = one_material(node_material("Glow", "ShaderNodeBsdfPrincipled", **{
        "Emission Strength": 2.0, "Emission Color": (1.0, 0.5, 0.25)}))
    assert warnings == [] and sc.mat_kind[0] == S.DIFFUSE
    assert sc.light_names == ["Thing"] and sc.light_type.tolist() == [S.MESH]
    assert np.allclose(sc.light_color[0], [2.0, 1.0, 0.5]) and np.allclose(sc.mat_emission[0], [2.0, 1.0, 0.5])
    bpy.ops.wm.read_factory_settings(use_empty=True)
    m = node_material("Half", "ShaderNodeMixShader", Fac=0.75)
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
    m = node_material("Sign", "ShaderNodeMixShader", Fac=0.25)  # 0.75 diffuse, 0.25 an Emission node
    nt = m.node_tree
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = 8.0
    nt.links.new(nt.nodes.new("ShaderNodeBsdfDiffuse").outputs[0], nt.nodes["Mix Shader"].inputs[1])
    nt.links.new(em.outputs[0], nt.nodes["Mix Shader"].inputs[2])
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.light_color[0], 2.0) and warnings == []
