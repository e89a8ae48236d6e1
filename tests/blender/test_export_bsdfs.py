"""Blender scene -> Scene arrays (smbs_addon.blender: export_scene and the modules it calls) with tiny
scenes built in bpy: one shader node at a time: the Principled BSDF (its metal, glass, specular tint,
thin film, coat and diffuse), the Metallic, Glass, Refraction, Glossy, Diffuse and Emission BSDFs, a
rough caster's distribution."""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from smbs_addon.scene import arrays as S  # noqa: E402
from smbs_addon.shading.microfacet import distributions  # noqa: E402
from testkit.blend import add_camera, export, mesh_with, metallic, node_material, one_material  # noqa: E402

pytestmark = [pytest.mark.bpy, pytest.mark.usefixtures("empty_bpy")]


def test_principled_diffuse():
    sc, w = one_material(node_material("P", "ShaderNodeBsdfPrincipled", **{
        "Base Color": (0.2, 0.3, 0.4), "Roughness": 0.7}))
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.mat_color[0], [0.2, 0.3, 0.4])
    assert np.isclose(sc.mat_roughness[0], 0.7) and w == []


def test_principled_metallic_is_a_schlick_conductor():
    sc, _ = one_material(node_material("Gold", "ShaderNodeBsdfPrincipled", **{
        "Base Color": (1.0, 0.8, 0.3), "Metallic": 1.0, "Roughness": 0.1}))
    assert sc.mat_kind[0] == S.CONDUCTOR and sc.mat_fresnel[0] == S.FRESNEL_SCHLICK
    assert np.allclose(sc.mat_color[0], [1.0, 0.8, 0.3]) and np.isclose(sc.mat_roughness[0], 0.1)


def test_a_partly_metallic_or_transmissive_principled_weighs_its_lobe():
    """Cycles weighs a Principled BSDF's metal by Metallic and its glass by (1 - Metallic) x
    Transmission; the lobe that weighs most is the material, at that weight. A metal's rest is a
    dielectric coat (a mirror at Roughness 0) over a diffuse, whose diffuse is said to be left out
    (mirror_alloy, Metallic 0.7: 1.44 of Cycles before, 0.95 with the metal's weight alone)."""
    from smbs_addon.shading.fresnel import fresnel_dielectric, fresnel_schlick, specular_weights

    sc, w = one_material(node_material("Alloy", "ShaderNodeBsdfPrincipled", **{
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


def test_the_metallic_bsdf_is_an_f82_tint_metal():
    """The Metallic BSDF's F82 mode: F0 the Base Color, the Edge Tint scales Cycles' F82 term (its
    reflectance at cos 1/7 is the tint times Schlick's there); its roughness, and nothing warned. It was
    'not supported; treated as diffuse': a gold ring made with it cast no caustic."""
    from smbs_addon.shading.fresnel import fresnel_schlick, specular_weights

    sc, w = one_material(metallic("Gold", **{"Base Color": (0.95, 0.7, 0.3), "Edge Tint": (1.0, 0.6, 0.2),
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

    m = metallic("Copper", "PHYSICAL_CONDUCTOR", IOR=(0.27, 0.68, 1.32), Extinction=(3.61, 2.63, 2.29),
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

    sc, w = one_material(node_material("Tinted", "ShaderNodeBsdfPrincipled", **{
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
    m = node_material("Brushed", "ShaderNodeBsdfPrincipled", **{"Base Color": (0.9, 0.8, 0.5), "Metallic": 1.0})
    nt = m.node_tree
    noise = nt.nodes.new("ShaderNodeTexNoise")
    nt.links.new(noise.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Specular Tint"])
    sc, w = one_material(m)
    assert sc.mat_kind[0] == S.CONDUCTOR and not sc.mat_metal.any()
    assert w == ["material 'Brushed': Principled BSDF specular tint (textured) ignored"]


def _streaky_glass():
    m = node_material("Streaky", "ShaderNodeBsdfGlass", **{"Thin Film Thickness": 400.0})
    nt = m.node_tree
    nt.links.new(nt.nodes.new("ShaderNodeTexNoise").outputs["Fac"], nt.nodes["Glass BSDF"].inputs["Thin Film Thickness"])
    return m


@pytest.mark.parametrize("make,film,warnings", [
    (lambda: node_material("Soap", "ShaderNodeBsdfGlass", **{"Thin Film Thickness": 400.0, "Thin Film IOR": 1.4}),
     (400.0, 1.4), []),
    (lambda: node_material("Thin", "ShaderNodeBsdfGlass", **{"Thin Film Thickness": 0.1}), None, []),
    (_streaky_glass, None, ["material 'Streaky': the thin film of 'Glass BSDF' is driven by nodes (a textured "
                            "thickness or index): its iridescence is not baked"]),
    (lambda: node_material("Plastic", "ShaderNodeBsdfPrincipled", **{"Thin Film Thickness": 300.0}), None,
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


def test_a_partly_transmissive_principled_glass_weighs_both_lobes():
    sc, w = one_material(node_material("Frost", "ShaderNodeBsdfPrincipled", **{
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

    sc, w = one_material(node_material("Tinted", "ShaderNodeBsdfPrincipled", **{
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
    sc, _ = one_material(node_material("FilmTint", "ShaderNodeBsdfPrincipled", **{
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
    sc, _ = one_material(node_material("PGlass", "ShaderNodeBsdfPrincipled", **{
        "Base Color": (0.9, 1.0, 0.95), "Transmission Weight": 1.0, "IOR": 1.33,
        "Roughness": 0.0}))
    assert sc.mat_kind[0] == S.DIELECTRIC and np.isclose(sc.mat_ior[0], 1.33)
    # Cycles tints each refraction by the square root of the base colour (once in, once out
    # gives the base colour through a slab); reflections stay white
    assert np.allclose(sc.mat_color[0], np.sqrt([0.9, 1.0, 0.95])) and np.allclose(sc.mat_reflect_color[0], 1)


def test_glass_bsdf_tints_reflection_and_transmission():
    sc, _ = one_material(node_material("Glass", "ShaderNodeBsdfGlass", Color=(0.5, 0.6, 0.7), IOR=1.5,
                                  Roughness=0.05))
    assert sc.mat_kind[0] == S.DIELECTRIC and np.isclose(sc.mat_ior[0], 1.5)
    assert np.allclose(sc.mat_color[0], [0.5, 0.6, 0.7])
    assert np.allclose(sc.mat_reflect_color[0], [0.5, 0.6, 0.7])
    assert np.isclose(sc.mat_roughness[0], 0.05)


def test_bump_map_correction_is_read_per_material():
    """Cycles' Bump Map Correction (Material > Settings, on by default) is exported per material:
    a glass left at the default keeps it, a mirror with it turned off does not, and a scene with
    one material of each says so material by material."""
    glass = node_material("Glass", "ShaderNodeBsdfGlass", Color=(1.0, 1.0, 1.0), IOR=1.5)
    mirror = node_material("Mirror", "ShaderNodeBsdfGlossy", Color=(0.9, 0.9, 0.9), Roughness=0.0)
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
    sc, _ = one_material(node_material("Refr", "ShaderNodeBsdfRefraction", Color=(1.0, 1.0, 1.0),
                                  IOR=1.33))
    assert sc.mat_kind[0] == S.DIELECTRIC and np.isclose(sc.mat_ior[0], 1.33)
    assert np.allclose(sc.mat_reflect_color[0], 0) and np.allclose(sc.mat_color[0], 1)


@pytest.mark.parametrize("idname", ["ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic"])
def test_glossy_is_a_plain_conductor(idname):
    sc, _ = one_material(node_material("Mirror", idname, Color=(0.9, 0.9, 0.9), Roughness=0.0))
    assert sc.mat_kind[0] == S.CONDUCTOR and sc.mat_fresnel[0] == S.FRESNEL_NONE
    assert np.allclose(sc.mat_color[0], 0.9) and sc.mat_roughness[0] == 0


def test_diffuse_bsdf():
    sc, _ = one_material(node_material("D", "ShaderNodeBsdfDiffuse", Color=(0.1, 0.2, 0.3)))
    assert sc.mat_kind[0] == S.DIFFUSE and np.allclose(sc.mat_color[0], [0.1, 0.2, 0.3])


def test_emission():
    sc, _ = one_material(node_material("Lamp", "ShaderNodeEmission", Color=(1.0, 0.5, 0.25),
                                  Strength=7.0))
    assert sc.mat_kind[0] == S.EMITTER and np.isclose(sc.mat_strength[0], 7.0)
    assert np.allclose(sc.mat_color[0], [1.0, 0.5, 0.25])


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
    m = node_material("Frosted", node, Roughness=rough, **kw)
    next(n for n in m.node_tree.nodes if n.type != "OUTPUT_MATERIAL").distribution = dist
    sc, warnings = one_material(m)
    assert sc.mat_kind[0] in (S.DIELECTRIC, S.CONDUCTOR) and np.isclose(sc.mat_roughness[0], rough)
    assert distributions(sc)[0] == expect
    if warned:
        assert len(warnings) == 1 and warnings[0].startswith("material 'Frosted': the ") \
            and "is baked as GGX" in warnings[0], warnings
    else:
        assert warnings == []


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

    sc, w = one_material(node_material("Half", "ShaderNodeBsdfPrincipled", **{
        "Base Color": (0.5, 0.6, 0.7), "Metallic": 0.2, "Transmission Weight": 0.25, "Roughness": 0.3,
        "IOR": 1.4, "Specular IOR Level": 0.25, "Specular Tint": (0.5, 0.9, 0.2, 1.0)}))
    assert sc.mat_kind[0] == S.DIFFUSE and w == []
    assert np.allclose(sc.mat_color[0], np.array([0.5, 0.6, 0.7]) * 0.8 * 0.75, atol=1e-6)
    f0 = ((1.4 - 1.0) / 2.4) ** 2 * 0.5
    assert np.allclose(sc.mat_layer[0], [ior_from_f0(f0), 0.3, 0.9, 0.8 * 0.75, 0.0, 0.0, 1.5, 0.03], atol=1e-6)


def test_rough_diffuse_is_oren_nayar():
    """Cycles shades a Diffuse BSDF of Roughness 1e-5 or more, and a Principled BSDF's Diffuse
    Roughness, by Oren-Nayar (coat.oren_nayar_ratio1): its sigma is mat_layer's last column."""
    sc, w = one_material(node_material("Rough", "ShaderNodeBsdfDiffuse", Color=(0.5, 0.5, 0.5), Roughness=0.6))
    assert sc.mat_kind[0] == S.DIFFUSE and w == []
    assert np.allclose(sc.mat_layer[0], [0.0, 0.0, 0.0, 1.0, 0.6, 0.0, 0.0, 0.0], atol=1e-6)


def test_principled_diffuse_roughness_is_oren_nayar_under_the_coat():
    sc, w = one_material(node_material("RoughP", "ShaderNodeBsdfPrincipled", **{"Diffuse Roughness": 0.4}))
    assert w == [] and np.allclose(sc.mat_layer[0], [1.5, 0.5, 1.0, 1.0, 0.4, 0.0, 1.5, 0.03], atol=1e-6)


def test_principled_clear_coat_over_a_receiver():
    """A Principled clear coat (Coat Weight) over a diffuse receiver takes its share towards the eye
    too (layer.clearcoat_table); a tinted one, or one over metal, is warned about."""
    from smbs_addon.shading import coat as layer

    sc, w = one_material(node_material("Varnish", "ShaderNodeBsdfPrincipled", **{"Coat Weight": 1.0}))
    assert w == [] and np.allclose(sc.mat_layer[0, 5:], [1.0, 1.5, 0.03], atol=1e-6)
    # Cycles' plane under a sun, the default coat under Coat Weight 1 (tests/test_layer.py's way)
    got = layer.weight(layer.table(sc), np.zeros(2, np.int64), np.array([1.0, 0.356]))
    np.testing.assert_allclose(got, [0.9241, 0.7572], rtol=0.005)


def test_a_clear_coat_over_metal_or_tinted_is_said_to_be_ignored():
    sc, w = one_material(node_material("CarPaint", "ShaderNodeBsdfPrincipled", **{
        "Coat Weight": 1.0, "Coat Tint": (0.8, 0.2, 0.2, 1.0)}))
    assert w == ["material 'CarPaint': Principled BSDF coat ignored"] and sc.mat_layer[0, 5] == 0.0


def test_principled_without_specular_has_no_glossy_layer():
    sc, _ = one_material(node_material("Matte", "ShaderNodeBsdfPrincipled", **{"Specular IOR Level": 0.0}))
    assert sc.mat_kind[0] == S.DIFFUSE and sc.mat_layer.shape == (0, 8)  # no layer anywhere


def test_principled_extras_are_reported_as_ignored():
    sc, warnings = one_material(node_material("Glow", "ShaderNodeBsdfPrincipled", **{
        "Emission Strength": 2.0, "Emission Color": (1.0, 1.0, 1.0), "Alpha": 0.5, "Sheen Weight": 0.3}))
    assert sc.mat_kind[0] == S.DIFFUSE and sc.n_lights == 0
    assert warnings == ["material 'Glow': Principled BSDF emission (under a coat or sheen), sheen, alpha ignored"]
