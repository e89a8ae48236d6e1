"""The conformance suite's scenes: small scenes where Cycles is the judge.

    python -m testkit.conformance_scenes OUTDIR [NAME ...]     (default: every scene)

Each scene is built from nothing with the bpy data API (deterministic: the same
bpy gives the same file), at 96 x 72 pixels with a black world (but the world_ scenes,
lit by a world of constant colour) and Cycles set
up for comparing caustics (no clamping, no Filter Glossy, no denoising, enough
bounces). ``SCENES`` says what each one covers; together they cover the
materials (Glass BSDF, Principled glass white and tinted, Refraction BSDF,
Glossy BSDF, Principled metallic, Mix Shaders by a constant and by a Fresnel node; IOR 1.33 and
1.5), the lights (point with and
without soft falloff, spot, square and disk area lights, one of spread 30 degrees, suns of angle 0, 2 and
4 degrees, a world of constant colour and an HDRI turned by a Mapping node), the geometry (flat, wavy, spheres, a lens, bevelled cubes with
internal reflection, a prism, open and closed glass) and how a receiver is seen
(directly, through glass or water, in a mirror).

Floors are diffuse with albedo 0.8 and lit directly where the scene allows, so
Cycles' caustic component (caustics on - off) holds light that crosses more than
one diffuse surface (floor -> glass -> floor, water -> floor -> water -> floor),
as it does in users' scenes. ``tools/conformance.py reference NAME``
renders a scene's reference into ``tests/data/conformance/``.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import bpy

from testkit import blend as B
from testkit.lens import biconvex_lens as _lens
from testkit import pools

WIDTH, HEIGHT = 96, 72


# ----------------------------------------------------------------------------- helpers
def _scene(name):
    scene = B.reset()
    scene.name = name
    B.render_settings(scene, WIDTH, HEIGHT)
    B.black_world(scene)
    return scene


def _floor(scene, size=10.0, albedo=0.8, z=0.0):
    mat = B.material("Floor", "diffuse", (albedo,) * 3)
    v, f = B.grid(size, size)
    return B.mesh_object(scene, "Floor", v, f, mat, location=(0, 0, z), receiver=True)


def principled(name, base=(1.0, 1.0, 1.0), metallic=0.0, transmission=0.0, ior=1.5, roughness=0.0):
    m = bpy.data.materials.new(name)
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*base, 1.0)
    p.inputs["Metallic"].default_value = metallic
    p.inputs["Transmission Weight"].default_value = transmission
    p.inputs["Roughness"].default_value = roughness
    p.inputs["IOR"].default_value = ior
    return m


def _sphere(scene, name, mat, radius, location, segments=96, rings=48):
    v, f = B.uv_sphere(radius, segments, rings)
    return B.mesh_object(scene, name, v, f, mat, smooth=True, location=location, caster=True)


def _box(hx, hy, hz):
    v = [(x, y, z) for x in (-hx, hx) for y in (-hy, hy) for z in (-hz, hz)]
    f = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return v, f


def _bevelled_cube(scene, name, mat, size, location, rotation):
    v, f = _box(size / 2, size / 2, size / 2)
    ob = B.mesh_object(scene, name, v, f, mat, smooth=True, location=location, rotation=rotation,
                       caster=True)
    mod = ob.modifiers.new("Bevel", "BEVEL")
    mod.segments = 6
    mod.width = 0.08 * size
    return ob


def _open_cylinder(radius, height, segments=128):
    verts, faces = [], []
    for s in range(segments):
        ph = 2 * math.pi * s / segments
        verts += [(radius * math.cos(ph), radius * math.sin(ph), 0.0),
                  (radius * math.cos(ph), radius * math.sin(ph), height)]
    for s in range(segments):
        s1 = (s + 1) % segments
        faces.append((2 * s, 2 * s1, 2 * s1 + 1, 2 * s + 1))
    return verts, faces


def _water_wave(x, y):
    return 0.05 * math.sin(2.1 * x + 0.3) * math.cos(1.7 * y) + 0.03 * math.sin(3.3 * (x + 0.5 * y))


def _sheet_wave(x, y):
    return 0.03 * math.sin(4.0 * x) * math.cos(3.0 * y)


# ------------------------------------------------------------------------------ scenes
def lens_area():
    """Biconvex Glass BSDF lens (IOR 1.5) 1.6 m above the floor, 0.4 m square area light."""
    scene = _scene("lens_area")
    _floor(scene)
    glass = B.material("LensGlass", "glass", (1.0, 1.0, 1.0), ior=1.5)
    v, f = _lens(1.2, 0.5, 0.01)
    B.mesh_object(scene, "Lens", v, f, glass, smooth=True, location=(0, 0, 1.6), caster=True)
    B.add_light(scene, "Key", "AREA", (0.3, 0.2, 4.0), energy=150.0, shape="SQUARE", size=0.4)
    B.add_camera(scene, (0, -4.0, 3.2), (0, 0, 0.2), lens=40)
    return scene


def gold_cylinder():
    """Open Principled-metallic gold cylinder on the floor, disk area light from the side."""
    return _ring_of("gold_cylinder", lambda: principled("Gold", base=(1.0, 0.766, 0.336), metallic=1.0))


def _ring_of(name, metal):
    """gold_cylinder's open ring and side light, the ring of material metal() (made once the scene is new)."""
    scene = _scene(name)
    _floor(scene)
    v, f = _open_cylinder(0.6, 0.4)
    B.mesh_object(scene, "Ring", v, f, metal(), smooth=True, caster=True)
    # local -Z towards the ring: from (-2.4, 0, 1.4) aimed at the ring's centre
    B.add_light(scene, "Side", "AREA", (-2.4, 0.3, 1.4), (0.0, math.radians(-58), math.radians(7)),
                energy=300.0, shape="DISK", size=0.5)
    B.add_camera(scene, (0.4, -2.6, 2.6), (0.1, 0, 0.1), lens=35)
    return scene


def metallic_edge_ring():
    """gold_cylinder's ring as a Metallic BSDF in its F82 mode: gold's Base Color, an Edge Tint (0.9, 0.5,
    0.15) that darkens its grazing reflections (Cycles' F82-Tint; the node was 'not supported, treated as
    diffuse' before: no caustic)."""
    return _ring_of("metallic_edge_ring", lambda: B.metallic("EdgeGold", "F82", **{"Roughness": 0.0,
        "Base Color": (1.0, 0.766, 0.336), "Edge Tint": (0.9, 0.5, 0.15)}))


def conductor_ring():
    """gold_cylinder's ring as a Metallic BSDF in its Physical Conductor mode, the node's own index and
    extinction (IOR 2.757 2.513 2.231, Extinction 3.867 3.404 3.009): the Fresnel equations of a conductor."""
    return _ring_of("conductor_ring", lambda: B.metallic("Conductor", "PHYSICAL_CONDUCTOR", **{"Roughness": 0.0,
        "IOR": (2.757, 2.513, 2.231), "Extinction": (3.867, 3.404, 3.009)}))


def film_ring():
    """metallic_edge_ring's ring as a pale Metallic BSDF (F82 mode, Base Color 0.95/0.93/0.88, Edge Tint white)
    under a thin film of 350 nm and index 1.5: Cycles' iridescence (the film over the metal's n and k, which it
    estimates from F0 and F82) colours the ring's caustic."""
    return _ring_of("film_ring", lambda: B.metallic("FilmMetal", "F82", **{"Roughness": 0.0,
        "Base Color": (0.95, 0.93, 0.88), "Edge Tint": (1.0, 1.0, 1.0), "Thin Film Thickness": 350.0,
        "Thin Film IOR": 1.5}))


def _filmed(m, thickness, ior):
    """Material m (its one BSDF node a Principled, Glass or Metallic BSDF) under a thin film."""
    node = next(n for n in m.node_tree.nodes if "Thin Film Thickness" in n.inputs)
    node.inputs["Thin Film Thickness"].default_value = thickness
    node.inputs["Thin Film IOR"].default_value = ior
    return m


def anodized_ring():
    """gold_cylinder's ring as a Metallic BSDF in its Physical Conductor mode (IOR 2.5/2.3/2.1, Extinction
    3.3/3.0/2.7: a grey metal reflecting about half) under a film of 180 nm and index 2.2, as anodised titanium:
    the film turns its reflection violet at normal incidence, other colours towards grazing."""
    return _ring_of("anodized_ring", lambda: B.metallic("Anodized", "PHYSICAL_CONDUCTOR", **{"Roughness": 0.0,
        "IOR": (2.5, 2.3, 2.1), "Extinction": (3.3, 3.0, 2.7), "Thin Film Thickness": 180.0, "Thin Film IOR": 2.2}))


def film_alloy_mirror():
    """mirror_alloy's Principled mirror (Metallic 0.7, Base Color 0.9) under a film of 400 nm and index 1.4:
    Cycles puts the film over its metal lobe (F82-Tint) and over the dielectric coat of the rest alike."""
    return _mirror_under_bulb("film_alloy_mirror", lambda: _filmed(
        principled("FilmAlloy", base=(0.9, 0.9, 0.9), metallic=0.7), 400.0, 1.4))


def film_ball():
    """sphere_point_soft's bulb over a Glass BSDF ball (IOR 1.5) coated by a thin film of 280 nm and index 2.2
    (a titania-like coat): the film reflects several times the bare glass's share, per channel, at both
    faces (from inside, Cycles takes the film and the air relative to the glass), so less and coloured light
    comes through."""
    return _ball_under_bulb("film_ball", lambda: _filmed(B.material("FilmGlass", "glass", (1.0, 1.0, 1.0), ior=1.5),
                                                          280.0, 2.2))


def spec_tint_ball():
    """sphere_point_soft's bulb over a Principled glass ball (IOR 1.5, white) of Specular Tint 4 / 1 / 0: Cycles
    scales the Fresnel term's value at normal incidence by the tint (0.16 / 0.04 / 0 for red / green / blue,
    towards 1 at grazing), so the ball reflects more red and lets less of it through."""
    def ball():
        m = principled("TintGlass", transmission=1.0, ior=1.5)
        m.node_tree.nodes["Principled BSDF"].inputs["Specular Tint"].default_value = (4.0, 1.0, 0.0, 1.0)
        return m
    return _ball_under_bulb("spec_tint_ball", ball)


def pool_sun4():
    """Wavy water (Glass BSDF, IOR 1.33, smooth 120 x 120 grid of 6 x 6 m) 1 m above the
    floor, sun of strength 3 and angle 4 deg; the camera looks down through the water."""
    return _pool("pool_sun4", lambda: B.material("Water", "glass", (1.0, 1.0, 1.0), ior=1.33))


def _pool(name, water, wave=_water_wave, cells=120, floor=None):
    """pool_sun4 with the water's material water() (made once the scene is new), its surface
    wave(x, y) on a grid of cells x cells; the floor's material floor() (None: diffuse 0.8)."""
    scene = _scene(name)
    if floor is None:
        _floor(scene, size=8.0)
    else:
        v, f = B.grid(8.0, 8.0)
        B.mesh_object(scene, "Floor", v, f, floor(), receiver=True)
    v, f = B.grid(6, 6, cells, cells, wave)
    B.mesh_object(scene, "Water", v, f, water(), smooth=True, location=(0, 0, 1.0), caster=True)
    B.add_light(scene, "Sun", "SUN", (0, 0, 10), (math.radians(20), math.radians(10), 0), energy=3.0,
                angle=math.radians(4.0))
    B.add_camera(scene, (0, 0, 6), (0, 0, 0), lens=80)
    return scene


def rough_pool_sun():
    """pool_sun4's water as a rough Glass BSDF (Roughness 0.15, Multiscatter GGX): the camera sees the floor
    through rough water, where a photon cannot reach it and the caustic at each floor point is gathered."""
    return _pool("rough_pool_sun", lambda: B.material("RoughWater", "glass", (1.0, 1.0, 1.0), roughness=0.15,
                                                      ior=1.33, distribution="MULTI_GGX"))


def bumped_pool_sun():
    """pool_sun4's water flat (one quad), its waves a Bump node (Distance 0.3) on the Glass BSDF's Normal,
    the Height a Noise Texture (Scale 5, Detail 2, the quad's Generated coordinates): the pattern of the
    caustic is the bump's alone."""
    return _pool("bumped_pool_sun", lambda: B.bumped_glass("BumpedWater", 0.3), wave=None, cells=1)


def bumped_slab_sun():
    """A closed slab of bumped glass (a Noise Texture of Scale 2 in Object coordinates under a Bump of
    Distance 0.1; 1.2 x 1.2 x 0.2 m, 2.5 m up) under a sun of 2 degrees, 30 degrees from the zenith: its
    caustic lands beside the slab, where the camera looks down at it. The light leaves the slab through
    its underside, from behind, and Cycles' eye paths meet its top from behind, where Cycles' Bump node
    bends the normal the other way (bump.py)."""
    scene = _scene("bumped_slab_sun")
    _floor(scene, size=10.0)
    v, f = _box(0.6, 0.6, 0.1)
    B.mesh_object(scene, "Slab", v, f, B.bumped_glass("BumpedGlass", 0.1, 2.0, "Object"), smooth=False,
                  location=(0, 0, 2.5), caster=True)
    B.add_light(scene, "Sun", "SUN", (0, 0, 10), (0, math.radians(30), 0), energy=3.0, angle=math.radians(2.0))
    B.add_camera(scene, (-2.4, 0, 4.5), (-1.44, 0, 0), lens=35)
    return scene


def _normal_map_image(size=256):
    """A tangent-space normal map (a packed float image, Non-Color) of three sine waves over a 6 m square:
    h = sum A sin(2 pi (k_u u + k_v v) + phase) with u, v in 0..1 along +X, +Y, the normal (-dh/dx,
    -dh/dy, 1), each wave's slope up to 0.1-0.2 rad and wavelength 0.4-0.6 m."""
    import numpy as np

    waves = ((10.0, 4.0, 0.012, 0.0), (-3.0, 12.0, 0.010, 1.3), (7.0, -9.0, 0.008, 2.1))
    jj, ii = np.mgrid[0:size, 0:size]
    u, v = (ii + 0.5) / size, (jj + 0.5) / size  # rows from the bottom, as Blender keeps them
    dx = np.zeros((size, size))
    dy = np.zeros((size, size))
    for ku, kv, a, ph in waves:
        c = a * 2 * math.pi * np.cos(2 * math.pi * (ku * u + kv * v) + ph) / 6.0
        dx += c * ku
        dy += c * kv
    n = np.stack([-dx, -dy, np.ones_like(dx)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    px = np.ones((size, size, 4), np.float32)
    px[..., :3] = 0.5 * n + 0.5
    img = bpy.data.images.new("WaterNormals", size, size, float_buffer=True, alpha=False)
    img.colorspace_settings.name = "Non-Color"  # first: set after the pixels, it clears them
    img.pixels.foreach_set(px.ravel())
    img.pack()
    return img


def normal_mapped_pool_sun():
    """bumped_pool_sun's flat water with its waves a Normal Map node (tangent space, the quad's UV map
    running 0 to 1 over it) of a packed image of three sine waves (_normal_map_image) instead of a Bump."""
    def water():
        m = B.material("MappedWater", "glass", (1.0, 1.0, 1.0), ior=1.33)
        nt = m.node_tree
        glass = next(n for n in nt.nodes if n.type == "BSDF_GLASS")
        tex, nm = nt.nodes.new("ShaderNodeTexImage"), nt.nodes.new("ShaderNodeNormalMap")
        tex.image = _normal_map_image()
        nt.links.new(tex.outputs["Color"], nm.inputs["Color"])
        nt.links.new(nm.outputs["Normal"], glass.inputs["Normal"])
        return m
    scene = _pool("normal_mapped_pool_sun", water, wave=None, cells=1)
    me = bpy.data.objects["Water"].data
    uv = me.uv_layers.new(name="UVMap")
    for loop in me.loops:
        x, y, _ = me.vertices[loop.vertex_index].co
        uv.uv[loop.index].vector = (x / 6.0 + 0.5, y / 6.0 + 0.5)
    return scene


def cube_grey():
    """Bevelled (6 segments), smooth-shaded cube of Principled glass (Transmission 1, Base
    Color 0.8, IOR 1.5), tilted 35/20 deg just above the floor, 0.5 m area light."""
    scene = _scene("cube_grey")
    _floor(scene)
    glass = principled("GreyGlass", base=(0.8, 0.8, 0.8), transmission=1.0, ior=1.5)
    _bevelled_cube(scene, "Cube", glass, 1.2, (0, 0, 0.95), (math.radians(35), math.radians(20), 0))
    B.add_light(scene, "Key", "AREA", (0.6, -0.4, 4.0), energy=300.0, shape="SQUARE", size=0.5)
    B.add_camera(scene, (0, -5.5, 4.5), (0, 0, 0.4), lens=40)
    return scene


def cube_grey_diffuse1():
    """cube_grey with Light Paths > Diffuse bounces 1: Cycles then keeps only the caustic of the
    light that meets the glass first, and drops the floor -> glass -> floor light that the cube,
    2 cm above the floor, gathers from around it."""
    scene = cube_grey()
    scene.name = "cube_grey_diffuse1"
    scene.cycles.diffuse_bounces = 1
    return scene


def cube_grey_reflect():
    """cube_grey_diffuse1 with Transmission bounces 0: of the caustic, only the light reflected
    off the cube's outside (R) is left."""
    scene = cube_grey_diffuse1()
    scene.name = "cube_grey_reflect"
    scene.cycles.transmission_bounces = 0
    return scene


def sphere_point_soft():
    """Principled white glass sphere (IOR 1.5) under a point light of radius 0.25 with
    soft falloff (Blender's default)."""
    return _ball_under_bulb("sphere_point_soft", lambda: principled("WhiteGlass", base=(1.0, 1.0, 1.0),
                                                                    transmission=1.0, ior=1.5))


def _ball_under_bulb(name, ball):
    """A ball of material ball() (made once the scene is new) 0.9 m over the floor, under a point light
    of radius 0.25 with soft falloff, seen from above at a slant."""
    scene = _scene(name)
    _floor(scene)
    _sphere(scene, "Ball", ball(), 0.5, (0, 0, 0.9))
    B.add_light(scene, "Bulb", "POINT", (0.4, -0.2, 3.0), energy=600.0, shadow_soft_size=0.25,
                use_soft_falloff=True)
    B.add_camera(scene, (0, -3.6, 2.8), (0, 0, 0.2), lens=40)
    return scene


def tinted_ball():
    """A Glass BSDF ball (IOR 1.5) whose Volume Absorption (Color 0.9/0.6/0.3, Density 1.5: (1 - Color)
    x Density = 0.15/0.6/1.05 per metre) tints the light by its path inside (a chord of up to 1 m),
    under sphere_point_soft's bulb and camera, which sees part of the caustic through the ball."""
    scene = _scene("tinted_ball")
    _floor(scene)
    glass = B.material("TintedGlass", "glass", (1.0, 1.0, 1.0), ior=1.5)
    nt = glass.node_tree
    vol = nt.nodes.new("ShaderNodeVolumeAbsorption")
    vol.inputs["Color"].default_value = (0.9, 0.6, 0.3, 1.0)
    vol.inputs["Density"].default_value = 1.5
    nt.links.new(vol.outputs[0], nt.nodes["Material Output"].inputs["Volume"])
    _sphere(scene, "Ball", glass, 0.5, (0, 0, 0.9))
    B.add_light(scene, "Bulb", "POINT", (0.4, -0.2, 3.0), energy=600.0, shadow_soft_size=0.25,
                use_soft_falloff=True)
    B.add_camera(scene, (0, -3.6, 2.8), (0, 0, 0.2), lens=40)
    return scene


def absorbing_ball_area():
    """A Glass BSDF ball (IOR 1.5, Color 0.8 grey, radius 0.55, smooth UV sphere 96 x 48) whose Volume
    Absorption (Color 0.9/0.55/0.15, Density 1.2: 0.12/0.54/1.02 per metre) tints the light by its path
    inside, its centre 0.95 m over the floor, under two 0.35 m square area lights: one 5 m up, a little off
    the ball's axis, whose focus lies under the ball, and one 40 degrees off it, whose focus lands beside it.
    The camera looks down at the ball: it sees the first focus through the ball (the eye paths refract in
    and out, absorbed on both sides) and the second directly."""
    from mathutils import Vector

    scene = _scene("absorbing_ball_area")
    _floor(scene)
    glass = B.material("AbsorbingGlass", "glass", (0.8, 0.8, 0.8), ior=1.5)
    nt = glass.node_tree
    vol = nt.nodes.new("ShaderNodeVolumeAbsorption")
    vol.inputs["Color"].default_value = (0.9, 0.55, 0.15, 1.0)
    vol.inputs["Density"].default_value = 1.2
    nt.links.new(vol.outputs[0], nt.nodes["Material Output"].inputs["Volume"])
    centre = Vector((0.0, 0.0, 0.95))
    _sphere(scene, "Ball", glass, 0.55, tuple(centre))
    B.add_light(scene, "Key", "AREA", (0.25, 0.15, 5.0), energy=400.0, shape="SQUARE", size=0.35)
    side = centre + 5.0 * Vector((-math.sin(math.radians(40)), 0.0, math.cos(math.radians(40))))
    turn = (centre - side).to_track_quat("-Z", "Y").to_euler()
    B.add_light(scene, "Side", "AREA", tuple(side), tuple(turn), energy=2400.0, shape="SQUARE", size=0.35)
    # on the line from the key light's focus through the ball's centre: the focus fills the ball's view
    B.add_camera(scene, (0.19, 0.125, 3.92), (0.35, 0.0, 0.3), lens=40)
    return scene


def sphere_refraction_spot():
    """Refraction BSDF sphere (tinted, IOR 1.33) under a spot light of radius 0.2."""
    scene = _scene("sphere_refraction_spot")
    _floor(scene)
    mat = B.node_material("Refractor", "ShaderNodeBsdfRefraction", (0.85, 0.9, 1.0), Roughness=0.0, IOR=1.33)
    _sphere(scene, "Ball", mat, 0.45, (0, 0, 0.8))
    B.add_light(scene, "Spot", "SPOT", (-0.5, 0.3, 3.0), (math.radians(-6), math.radians(-9), 0),
                energy=1500.0, shadow_soft_size=0.2, use_soft_falloff=False,
                spot_size=math.radians(50), spot_blend=0.3)
    B.add_camera(scene, (0, -3.4, 2.6), (0, 0, 0.2), lens=40)
    return scene


def _standing_mirror(name, mirror=None):
    """A scene with the floor and a flat mirror standing on it at x = 1.2 (material mirror(), made
    once the scene is new; default Glossy BSDF 0.9)."""
    scene = _scene(name)
    _floor(scene)
    mirror = B.material("Mirror", "glossy", (0.9, 0.9, 0.9)) if mirror is None else mirror()
    v, f = B.grid(1.6, 1.0)
    # local +Z -> -X: the mirror stands at x = 1.2 and faces the light and the camera
    B.mesh_object(scene, "Mirror", v, f, mirror, location=(1.2, 0, 0.55),
                  rotation=(0, math.radians(-90), 0), caster=True)
    return scene


def mirror_point_hard():
    """Flat Glossy BSDF mirror standing on the floor, a point light of radius 0.2 without
    soft falloff; the camera sees the reflected light on the floor directly and in the
    mirror."""
    return _mirror_under_bulb("mirror_point_hard")


def _mirror_under_bulb(name, mirror=None):
    """_standing_mirror under a point light of radius 0.2 without soft falloff, the camera seeing the
    reflected light on the floor directly and in the mirror."""
    scene = _standing_mirror(name, mirror)
    B.add_light(scene, "Bulb", "POINT", (0.5, 0.0, 1.4), energy=400.0, shadow_soft_size=0.2,
                use_soft_falloff=False)
    B.add_camera(scene, (-2.6, -1.3, 1.7), (1.2, 0.1, 0.45), lens=35)
    return scene


def linked_lamps():
    """Light Linking: _standing_mirror with a Glass BSDF ball (IOR 1.5) between the camera and the mirror,
    lit by two lamps. The ball's lamp overhead lights the ball alone (a receiver collection with the ball set
    to Include): the ball's caustic stays, the floor gets no direct light from it (and so none of its light
    comes back through the ball), and none of its light reflects off the mirror, which Cycles asks of the
    mirror, not of the floor. The mirror's lamp, low beside the ball, lights every object but the ball (a
    receiver collection with the ball set to Exclude): its caustic off the mirror stays, the one through
    the ball goes, and its light that the floor sends through the ball stays."""
    scene = _standing_mirror("linked_lamps")
    ball = _sphere(scene, "Ball", B.material("Glass", "glass", (1.0, 1.0, 1.0), ior=1.5), 0.4, (-0.2, 0.1, 0.75))
    over = B.add_light(scene, "BallLamp", "POINT", (0.2, -0.1, 2.8), energy=500.0, shadow_soft_size=0.2,
                       use_soft_falloff=False)
    low = B.add_light(scene, "MirrorLamp", "POINT", (0.5, 0.0, 1.4), energy=400.0, shadow_soft_size=0.2,
                      use_soft_falloff=False)
    only_ball, not_ball = bpy.data.collections.new("OnlyBall"), bpy.data.collections.new("NotBall")
    only_ball.objects.link(ball)
    not_ball.objects.link(ball)
    not_ball.collection_objects[0].light_linking.link_state = "EXCLUDE"
    over.light_linking.receiver_collection = only_ball
    low.light_linking.receiver_collection = not_ball
    B.add_camera(scene, (-2.6, -1.3, 1.7), (0.8, 0.1, 0.3), lens=30)
    return scene


def shadow_linked_ball():
    """Shadow Linking: a Glass BSDF ball (IOR 1.5) under sphere_point_soft's bulb with a grey plate between
    them that does not shadow the bulb (its blocker collection has the plate set to Exclude): Cycles' rays
    to the bulb pass the plate (its "dedicated light" rays), so the ball's caustic and the floor's light
    that comes back through the ball are those without the plate, while the plate still stands in every
    other path."""
    return _unshadowed_ball("shadow_linked_ball", lambda scene: B.add_light(
        scene, "Bulb", "POINT", (0.4, -0.2, 3.0), energy=600.0, shadow_soft_size=0.25, use_soft_falloff=True))


def shadow_linked_glow():
    """shadow_linked_ball with a mesh light for its bulb: a smooth Emission ball of radius 0.25 (Strength 250)
    whose blocker collection leaves the plate out. The rays that reach a mesh light meet its triangles as
    surfaces: past the plate, the light is found again where they lie."""
    def glow(scene):
        v, f = B.uv_sphere(0.25, 32, 16)
        lamp = B.node_material("Lamp", "ShaderNodeEmission", (1.0, 1.0, 1.0), Strength=250.0)
        return B.mesh_object(scene, "Glow", v, f, lamp, smooth=True, location=(0.4, -0.2, 3.0))
    return _unshadowed_ball("shadow_linked_glow", glow)


def _unshadowed_ball(name, lamp):
    """A Glass BSDF ball (IOR 1.5) under the emitter lamp(scene) makes, a grey plate between them that does
    not shadow it (its blocker collection sets the plate to Exclude)."""
    scene = _scene(name)
    _floor(scene)
    _sphere(scene, "Ball", B.material("Glass", "glass", (1.0, 1.0, 1.0), ior=1.5), 0.5, (0, 0, 0.9))
    v, f = B.grid(1.4, 1.4)
    shade = B.mesh_object(scene, "Shade", v, f, B.material("Grey", "diffuse", (0.5, 0.5, 0.5)),
                          location=(0.28, -0.14, 2.3))
    bulb = lamp(scene)
    blockers = bpy.data.collections.new("NotTheShade")
    blockers.objects.link(shade)
    blockers.collection_objects[0].light_linking.link_state = "EXCLUDE"
    bulb.light_linking.blocker_collection = blockers
    B.add_camera(scene, (0, -3.6, 2.8), (0, 0, 0.2), lens=40)
    return scene


def mirror_alloy():
    """mirror_point_hard with a Principled mirror of Metallic 0.7 (Base Color 0.9, Roughness 0): Cycles
    weighs its metal lobe by 0.7 and the dielectric rest, a coat (in our mirror's reflection) over a diffuse
    (which receives no caustic here: the camera sees the floor's caustic light on it in the mirror's
    pixels, where the layer reads 0.80 of Cycles, 1.014 on the floor seen directly; MNEE, 256 spp)."""
    return _mirror_under_bulb("mirror_alloy", lambda: principled("Alloy", base=(0.9, 0.9, 0.9), metallic=0.7))


def rough_mirror():
    """mirror_point_hard's mirror as Blender's default metal: a Principled BSDF of Metallic 1 (Base Color
    0.9) at its default Roughness 0.5; Cycles spreads the reflected light into a soft glow (1.14 of Cycles
    when the layer baked it smooth)."""
    return _mirror_under_bulb("rough_mirror", lambda: principled("DefaultMetal", base=(0.9, 0.9, 0.9),
                                                                 metallic=1.0, roughness=0.5))


def rough_mirror_ggx():
    """rough_mirror with the Principled BSDF's distribution set to GGX: the same metal without Cycles'
    energy compensation (Multiscatter GGX's), the microfacet reflection alone."""
    def metal():
        m = principled("GgxMetal", base=(0.9, 0.9, 0.9), metallic=1.0, roughness=0.5)
        m.node_tree.nodes["Principled BSDF"].distribution = "GGX"
        return m
    return _mirror_under_bulb("rough_mirror_ggx", metal)


def mirror_spread30():
    """mirror_point_hard's mirror lit by a square area light of spread 30 degrees aimed past
    its middle: the soft-box falloff (Cycles' area_light_spread_attenuation) shapes the
    reflected light, and the cone's edge crosses the mirror."""
    from mathutils import Vector

    scene = _standing_mirror("mirror_spread30")
    at, target = Vector((-0.2, -0.4, 1.5)), Vector((1.2, 0.35, 0.75))
    B.add_light(scene, "Softbox", "AREA", tuple(at), (target - at).to_track_quat("-Z", "Y").to_euler(),
                energy=60.0, shape="SQUARE", size=0.5, spread=math.radians(30))
    B.add_camera(scene, (-2.6, -1.3, 1.7), (1.2, 0.1, 0.45), lens=35)
    return scene


def water_flat_sun0():
    """Flat water (Glass BSDF, IOR 1.33, an open plane) 0.5 m above the floor under a sun of
    angle 0; the camera looks down through the water. Path tracing cannot find a
    point-like sun behind glass: the reference is Cycles' MNEE, exact here (one solution)."""
    scene = _scene("water_flat_sun0")
    _floor(scene, size=8.0)
    water = B.material("Water", "glass", (1.0, 1.0, 1.0), ior=1.33)
    v, f = B.grid(6, 6)
    B.mesh_object(scene, "Water", v, f, water, smooth=True, location=(0, 0, 0.5), caster=True)
    B.add_light(scene, "Sun", "SUN", (0, 0, 10), (math.radians(25), 0, 0), energy=2.0, angle=0.0)
    B.add_camera(scene, (0, 0, 5), (0, 0, 0), lens=80)
    return scene


def wavy_mirror_sun2():
    """Wavy Glossy BSDF sheet (tinted) under a sun of angle 2 deg."""
    scene = _scene("wavy_mirror_sun2")
    _floor(scene)
    mat = B.material("WavyMirror", "glossy", (0.95, 0.85, 0.7))
    v, f = B.grid(1.6, 1.6, 64, 64, _sheet_wave)
    # nearly upright, facing +x and tilted 7 deg down
    B.mesh_object(scene, "Sheet", v, f, mat, smooth=True, location=(-0.9, 0, 0.9),
                  rotation=(0, math.radians(97), 0), caster=True)
    # sunlight travels towards -x, 40 deg below the horizon; the sheet sends it back down
    # towards +x, onto the floor in front of it
    B.add_light(scene, "Sun", "SUN", (0, 0, 10), (0, math.radians(50), 0), energy=3.0,
                angle=math.radians(2.0))
    B.add_camera(scene, (0.3, -3.2, 2.4), (-0.3, 0, 0.3), lens=35)
    return scene


def through_glass_disk():
    """A tinted Glass BSDF ball (IOR 1.33) under a disk area light, seen through a pane
    of glass (a closed 3 cm slab, IOR 1.5) standing between it and the camera."""
    scene = _scene("through_glass_disk")
    _floor(scene)
    tinted = B.material("TintedGlass", "glass", (0.95, 0.8, 0.6), ior=1.33)
    _sphere(scene, "Ball", tinted, 0.45, (0, 0, 0.75))
    pane_glass = B.material("Pane", "glass", (1.0, 1.0, 1.0), ior=1.5)
    v, f = _box(1.2, 0.015, 0.7)
    B.mesh_object(scene, "Pane", v, f, pane_glass, location=(0, -1.6, 0.7), caster=True)
    B.add_light(scene, "Key", "AREA", (0.3, 0.4, 3.2), energy=250.0, shape="DISK", size=0.5)
    B.add_camera(scene, (0, -3.4, 1.5), (0, 0, 0.2), lens=40)
    return scene


def prism_tir():
    """A right-angle glass prism (Glass BSDF, IOR 1.5, flat shaded) whose hypotenuse
    reflects by total internal reflection: light enters one leg face, reflects inside
    (T R T) and leaves through the other towards the floor."""
    scene = _scene("prism_tir")
    _floor(scene)
    glass = B.material("PrismGlass", "glass", (1.0, 1.0, 1.0), ior=1.5)
    h, L = 0.35, 0.5  # legs along +x and +z, length 2h; extrusion along y
    v = [(-h, -L, -h), (h, -L, -h), (-h, -L, h), (-h, L, -h), (h, L, -h), (-h, L, h)]
    f = [(0, 2, 1), (3, 4, 5), (0, 1, 4, 3), (0, 3, 5, 2), (1, 2, 5, 4)]
    B.mesh_object(scene, "Prism", v, f, glass, location=(0, 0, 1.0),
                  rotation=(0, math.radians(-20), 0), caster=True)
    # light from above-left: enters through the top leg face, reflects off the hypotenuse
    B.add_light(scene, "Key", "AREA", (-2.0, 0.0, 3.0), (0, math.radians(-35), 0), energy=400.0,
                shape="SQUARE", size=0.4)
    B.add_camera(scene, (0.6, -3.6, 2.8), (0.6, 0, 0.2), lens=35)
    return scene


def cube_white_rect(name="cube_white_rect", base=1.0):
    """Bevelled smooth-shaded cube of Principled white glass (IOR 1.5) under a
    rectangular area light, tilted so that light reflects inside it (T R T, T R R T)."""
    scene = _scene(name)
    _floor(scene)
    glass = principled("ClearGlass" if base == 1.0 else "TintGlass", base=(base, base, base),
                       transmission=1.0, ior=1.5)
    _bevelled_cube(scene, "Cube", glass, 0.9, (0.1, 0, 0.8), (math.radians(20), math.radians(40), 0))
    B.add_light(scene, "Key", "AREA", (-0.5, 0.3, 3.5), (0, math.radians(-10), 0), energy=250.0,
                shape="RECTANGLE", size=0.6, size_y=0.3)
    B.add_camera(scene, (0.2, -4.2, 3.4), (0.1, 0, 0.3), lens=40)
    return scene


def cube_tint_rect():
    """cube_white_rect with Base Color 0.8: the same geometry, light and camera as the white
    cube, so that what differs between the two is the Principled glass's tint alone."""
    return cube_white_rect("cube_tint_rect", base=0.8)


def cube_white_glossy1():
    """cube_white_rect with Light Paths > Glossy bounces 1 (the rest as Blender's defaults: max
    12, diffuse 4, transmission 12): Cycles then drops every caustic path with more than one
    reflection before its last vertex (T R R T, the floor seen through two inner reflections)."""
    scene = cube_white_rect()
    scene.name = "cube_white_glossy1"
    c = scene.cycles
    c.max_bounces, c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces = 12, 4, 1, 12
    return scene


def egg_sun_spot():
    """A glass egg: a smooth sphere scaled (1.4, 0.8, 0.9) and turned (its normals must follow the
    inverse transpose), Glass BSDF tinted, IOR 1.45, under two coloured lights at once: a warm sun
    of angle 6 deg and a blue spot of radius 0.15 with blend 0.5."""
    scene = _scene("egg_sun_spot")
    _floor(scene)
    glass = B.material("EggGlass", "glass", (0.95, 0.9, 0.8), ior=1.45)
    egg = _sphere(scene, "Egg", glass, 0.5, (0, 0, 0.9))
    egg.scale = (1.4, 0.8, 0.9)
    egg.rotation_euler = (math.radians(15), 0, math.radians(30))
    sun = B.add_light(scene, "Sun", "SUN", (0, 0, 10), (math.radians(12), math.radians(-8), 0), energy=2.0,
                      angle=math.radians(6.0))
    sun.data.color = (1.0, 0.85, 0.7)
    spot = B.add_light(scene, "Spot", "SPOT", (1.2, -0.6, 3.2), (math.radians(10), math.radians(20), 0),
                       energy=900.0, shadow_soft_size=0.15, spot_size=math.radians(45), spot_blend=0.5)
    spot.data.color = (0.6, 0.8, 1.0)
    B.add_camera(scene, (0, -3.6, 3.0), (0, 0, 0.2), lens=38)
    return scene


def _slanted_ball(name, floor):
    """sphere_point_soft's glass ball and bulb over a floor of material floor() (made once the
    scene is new), the camera low (the caustic seen at mu ~0.36): for receivers whose shading
    depends on the eye's direction."""
    scene = _scene(name)
    v, f = B.grid(10.0, 10.0)
    B.mesh_object(scene, "Floor", v, f, floor(), receiver=True)
    glass = principled("WhiteGlass", base=(1.0, 1.0, 1.0), transmission=1.0, ior=1.5)
    _sphere(scene, "Ball", glass, 0.5, (0, 0, 0.9))
    B.add_light(scene, "Bulb", "POINT", (0.4, -0.2, 3.0), energy=600.0, shadow_soft_size=0.25)
    B.add_camera(scene, (0, -4.2, 1.6), (0, 0, 0.0), lens=40)
    return scene


def principled_floor():
    """The slanted glass ball over a floor of Blender's default material (Principled BSDF: Base
    Color 0.8, Roughness 0.5, IOR 1.5, Specular IOR Level 0.5), seen at a slant: its glossy coat
    takes its share of the light off the diffuse below, as Cycles layers it."""
    return _slanted_ball("principled_floor", lambda: bpy.data.materials.new("DefaultFloor"))


def _varnished():
    m = bpy.data.materials.new("VarnishedFloor")
    m.node_tree.nodes["Principled BSDF"].inputs["Coat Weight"].default_value = 1.0
    return m


def coated_floor():
    """The slanted glass ball over Blender's default material with a clear coat (Coat Weight 1, Coat
    IOR 1.5, Coat Roughness 0.03): the coat takes its share off everything under it."""
    return _slanted_ball("coated_floor", _varnished)


def rough_floor():
    """The slanted glass ball over a Diffuse BSDF floor of Roughness 1 (Cycles' Oren-Nayar: at this
    slant 0.4-1.5 of Lambert, by where the light comes from)."""
    return _slanted_ball("rough_floor", lambda: B.material("RoughFloor", "diffuse", (0.8,) * 3, roughness=1.0))


def _checker():
    m = bpy.data.materials.new("CheckerFloor")
    nt = m.node_tree
    tex = nt.nodes.new("ShaderNodeTexChecker")
    tex.inputs["Scale"].default_value = 20.0  # squares of 0.5 m on the 10 m floor (Generated coordinates)
    tex.inputs["Color1"].default_value = (0.8, 0.7, 0.5, 1.0)
    tex.inputs["Color2"].default_value = (0.1, 0.15, 0.3, 1.0)
    # shifted so that the caustic's core (x -0.28..-0.06, y 0.06..0.18 m) lies inside one square:
    # its edges at x -0.42 and y -0.15 (a pixel straddling an edge of the texture and the caustic's
    # sharp rim is where the render's per-pixel albedo cannot stand in for the albedo per sample)
    coords, mapping = nt.nodes.new("ShaderNodeTexCoord"), nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Location"].default_value = (0.0421, 0.015, 0.0)
    nt.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    return m


def checker_floor():
    """The slanted glass ball over Blender's default material with a Checker Texture on its Base
    Color (warm 0.8/0.7/0.5 and dark blue squares of 0.5 m, the caustic's core inside one, its rim
    over the next): the caustic takes the texture's colour square by square, through the render's
    Diffuse Color pass."""
    return _slanted_ball("checker_floor", _checker)


def _bumpy_floor():
    """A Diffuse BSDF floor (0.8) whose Normal is a Bump of a Noise Texture: bumps of ~0.1 m, a few across the
    caustic."""
    return B.bumpy("BumpyFloor", color=(0.8,) * 3)


def pool_bumped_floor():
    """pool_sun4 over bumped_floor's floor (a Diffuse BSDF whose Normal is a Bump of a Noise Texture): the
    camera sees the bumps through the water."""
    return _pool("pool_bumped_floor", lambda: B.material("Water", "glass", (1.0, 1.0, 1.0), ior=1.33),
                 floor=_bumpy_floor)


def bumped_floor():
    """The slanted glass ball over a Diffuse BSDF floor (0.8) whose Normal is a Bump node (Distance 0.1)
    of a Noise Texture (Scale 8, Detail 2, Object coordinates): the caustic follows the bumps' shading,
    Cycles' shadowing term of a bent normal included."""
    return _slanted_ball("bumped_floor", _bumpy_floor)


def mix_frosted_ball():
    """sphere_point_soft's ball and bulb with a Mix Shader of a dark Diffuse BSDF (0.2) and a Glass BSDF
    (IOR 1.5) at Factor 0.75: Cycles weighs the glass closure by 0.75 at each vertex (0.56 of the clear
    ball's T T caustic). The diffuse part is dark because it is not ours: light it scatters inside the
    ball and out through its glass adds to Cycles' caustic (2.9% of it with a diffuse of 0.8)."""
    return _ball_under_bulb("mix_frosted_ball", lambda: B.mixed(
        "Frosted", ("ShaderNodeBsdfDiffuse", {"Color": (0.2, 0.2, 0.2)}),
        ("ShaderNodeBsdfGlass", {"Color": (1.0, 1.0, 1.0), "IOR": 1.5, "Roughness": 0.0}), 0.75, distribution="GGX"))


def mix_alloy_mirror():
    """mirror_point_hard's mirror as a Mix Shader (Factor 0.5) of a Principled BSDF of Metallic 0.5 (Base Color
    0.9, Roughness 0) and a dark Diffuse BSDF (0.05): Cycles weighs the metal lobe and its dielectric coat
    alike by the mix's 0.5, so the coat reflects 0.25 of the dielectric Fresnel, not the 0.75 that
    1 - Metallic x 0.5 would give."""
    return _mirror_under_bulb("mix_alloy_mirror", lambda: B.mixed(
        "MixAlloy", ("ShaderNodeBsdfPrincipled", {"Base Color": (0.9, 0.9, 0.9), "Metallic": 0.5, "Roughness": 0.0}),
        ("ShaderNodeBsdfDiffuse", {"Color": (0.05, 0.05, 0.05)}), 0.5, distribution="GGX"))


def mix_floor():
    """The slanted glass ball over a floor of Mix Shader(Diffuse BSDF 0.8, Glossy BSDF white of
    Roughness 0.3) at Factor 0.25, the old way to make a glossy floor: its diffuse weighs 0.75, and
    Cycles samples the glossy closure beside it."""
    return _slanted_ball("mix_floor", lambda: B.mixed(
        "MixFloor", ("ShaderNodeBsdfDiffuse", {"Color": (0.8, 0.8, 0.8)}),
        ("ShaderNodeBsdfGlossy", {"Color": (1.0, 1.0, 1.0), "Roughness": 0.3}), 0.25, distribution="GGX"))


def fresnel_glass_ball():
    """sphere_point_soft's ball and bulb with the old glass: a Mix Shader of a Refraction BSDF (pale green,
    IOR 1.5) and a white Glossy BSDF (Roughness 0) by a Fresnel node of IOR 1.5."""
    return _ball_under_bulb("fresnel_glass_ball", lambda: B.by_fresnel(B.mixed(
        "OldGlass", ("ShaderNodeBsdfRefraction", {"Color": (0.85, 1.0, 0.85), "IOR": 1.5, "Roughness": 0.0}),
        ("ShaderNodeBsdfGlossy", {"Color": (1.0, 1.0, 1.0), "Roughness": 0.0}), 0.5, distribution="GGX"), 1.5))


def rough_glass_ball():
    """sphere_point_soft's ball as the glass one makes of Blender's default material: a Principled BSDF of
    Transmission Weight 1 (IOR 1.5) at its default Roughness 0.5; Cycles blurs its caustic into a glow
    (1.26 of Cycles when the layer baked it smooth)."""
    return _ball_under_bulb("rough_glass_ball", lambda: principled("DefaultGlass", base=(1.0, 1.0, 1.0),
                                                                   transmission=1.0, ior=1.5, roughness=0.5))


def rough_glass_ggx():
    """sphere_point_soft's ball as a Glass BSDF (IOR 1.5) of Roughness 0.3 with the single-scattering GGX
    distribution: the microfacet sampling and shadowing alone, without Cycles' energy compensation."""
    return _ball_under_bulb("rough_glass_ggx", lambda: B.material("GgxGlass", "glass", (1.0, 1.0, 1.0),
                                                                  roughness=0.3, ior=1.5))


def rough_tinted_mirror():
    """mirror_point_hard's mirror as a Glossy BSDF of colour (0.9, 0.6, 0.3), Roughness 0.3, Multiscatter
    GGX: Cycles' energy compensation brightens and saturates a coloured metal's reflection."""
    return _mirror_under_bulb("rough_tinted_mirror", lambda: B.material(
        "TintedGlossy", "glossy", (0.9, 0.6, 0.3), roughness=0.3, distribution="MULTI_GGX"))


def rough_tinted_glass():
    """sphere_point_soft's ball as a coloured Glass BSDF (0.9, 0.6, 0.3; IOR 1.5) of Roughness 0.5, Multiscatter
    GGX: Cycles' energy compensation takes the glass's colour for F_ss, so it restores less of the blue that
    the microfacets lose than of the red."""
    return _ball_under_bulb("rough_tinted_glass", lambda: B.material(
        "TintedRoughGlass", "glass", (0.9, 0.6, 0.3), roughness=0.5, ior=1.5, distribution="MULTI_GGX"))


def fake_shadow_ball():
    """sphere_point_soft's ball with the fake-shadow trick: a Mix Shader of a Glass BSDF (IOR 1.5) and a
    Transparent BSDF by Light Path's Is Shadow Ray (shadow rays pass, every other ray meets the glass)."""
    def trick():
        m = B.mixed("FakeShadows", ("ShaderNodeBsdfGlass", {"Color": (1.0, 1.0, 1.0), "IOR": 1.5, "Roughness": 0.0}),
                 ("ShaderNodeBsdfTransparent", {"Color": (1.0, 1.0, 1.0)}), 0.0, distribution="GGX")
        lp = m.node_tree.nodes.new("ShaderNodeLightPath")
        m.node_tree.links.new(lp.outputs["Is Shadow Ray"], m.node_tree.nodes["Mix Shader"].inputs["Factor"])
        return m
    return _ball_under_bulb("fake_shadow_ball", trick)


def fresnel_floor():
    """The slanted glass ball over the old coated floor: a Mix Shader of a Diffuse BSDF (0.8) and a white
    Glossy BSDF (Roughness 0.2) by a Fresnel node of IOR 1.5 (the diffuse keeps 1 - F towards the eye)."""
    return _slanted_ball("fresnel_floor", lambda: B.by_fresnel(B.mixed(
        "OldFloor", ("ShaderNodeBsdfDiffuse", {"Color": (0.8, 0.8, 0.8)}),
        ("ShaderNodeBsdfGlossy", {"Color": (1.0, 1.0, 1.0), "Roughness": 0.2}), 0.5, distribution="GGX"), 1.5))


def world_ball():
    """sphere_point_soft's ball as Glass BSDF under a pale blue world of constant colour and no lamp:
    the floor under the ball sees the sky through it."""
    scene = _scene("world_ball")
    _floor(scene)
    glass = B.material("Glass", "glass", (1.0, 1.0, 1.0), ior=1.5)
    _sphere(scene, "Ball", glass, 0.5, (0, 0, 0.9))
    B.sky(scene, (0.6, 0.75, 1.0), 1.5)
    B.add_camera(scene, (0, -3.6, 2.8), (0, 0, 0.2), lens=40)
    return scene


def world_mirror_bulb():
    """mirror_point_hard's mirror and bulb under a grey world bright enough to matter (0.4), flagged
    Shadow Caustics as the bulb is: the floor in front of the mirror gets the sky's reflection
    beside the bulb's."""
    scene = mirror_point_hard()
    scene.name = "world_mirror_bulb"
    B.sky(scene, (0.4, 0.4, 0.4), 1.0)
    scene.world.cycles.is_caustics_light = True  # flagged like the bulb (Cycles' flags select the lights)
    return scene


def mesh_light_ball():
    """sphere_point_soft's Glass BSDF ball (IOR 1.5) lit by a mesh light: an Emission plane (0.8 m square,
    Strength 60, tinted) whose normal points up, away from the ball, which sees its back (Cycles' mesh
    lights shine from both sides)."""
    scene = _scene("mesh_light_ball")
    _floor(scene)
    _sphere(scene, "Ball", B.material("Glass", "glass", (1.0, 1.0, 1.0), ior=1.5), 0.5, (0, 0, 0.9))
    v, f = B.grid(0.8, 0.8)
    glow = B.node_material("Glow", "ShaderNodeEmission", (1.0, 0.9, 0.75), Strength=60.0)
    B.mesh_object(scene, "Panel", v, f, glow, location=(0.3, -0.2, 3.0))
    B.add_camera(scene, (0, -3.6, 2.8), (0, 0, 0.2), lens=40)
    return scene


def principled_glow_ball():
    """mesh_light_ball with the panel's material a Principled BSDF (Base Color 0.8, Roughness 0.5) of Emission
    Strength 60, tinted: its faces shine and receive."""
    scene = _scene("principled_glow_ball")
    _floor(scene)
    _sphere(scene, "Ball", B.material("Glass", "glass", (1.0, 1.0, 1.0), ior=1.5), 0.5, (0, 0, 0.9))
    glow = principled("Glow", base=(0.8, 0.8, 0.8), roughness=0.5)
    node = next(n for n in glow.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    node.inputs["Emission Color"].default_value = (1.0, 0.9, 0.75, 1.0)
    node.inputs["Emission Strength"].default_value = 60.0
    v, f = B.grid(0.8, 0.8)
    B.mesh_object(scene, "Panel", v, f, glow, location=(0.3, -0.2, 3.0))
    B.add_camera(scene, (0, -3.6, 2.8), (0, 0, 0.2), lens=40)
    return scene


def mesh_light_mirror():
    """_standing_mirror lit by a closed mesh light: a smooth Emission ball of radius 0.2 (Strength 250: about
    mirror_point_hard's 400 W bulb), the camera seeing the reflected light on the floor directly and in the
    mirror."""
    scene = _standing_mirror("mesh_light_mirror")
    v, f = B.uv_sphere(0.2, 32, 16)
    lamp = B.node_material("Lamp", "ShaderNodeEmission", (1.0, 1.0, 1.0), Strength=250.0)
    B.mesh_object(scene, "Bulb", v, f, lamp, smooth=True, location=(0.5, 0.0, 1.4))
    B.add_camera(scene, (-2.6, -1.3, 1.7), (1.2, 0.1, 0.45), lens=35)
    return scene


def hdri_ball():
    """world_ball's ball and camera under an Environment Texture (a packed float image: a pale sky and
    a Gaussian sun of 3 pixels, 4 degrees, 55 degrees up behind the camera) turned 40 degrees about Z
    by a Mapping node: the sun's caustic lands behind the ball, where the map's lookup puts it."""
    scene = _scene("hdri_ball")
    _floor(scene)
    glass = B.material("Glass", "glass", (1.0, 1.0, 1.0), ior=1.5)
    _sphere(scene, "Ball", glass, 0.5, (0, 0, 0.9))
    B.hdri_world(scene, B.hdri_image(), turn_deg=40.0)
    B.add_camera(scene, (0, -3.6, 2.8), (0, 0, 0.2), lens=40)
    return scene


def ray_visibility():
    """Cycles' Ray Visibility on lights and casters: a glass ball and a standing mirror under a bulb that
    glossy rays do not see (Cycles: the ball's refraction alone, no light off the mirror or the ball's
    outside) and a lamp that transmission rays do not see (the mirror's light and the ball's reflection
    alone), beside a second glass ball that diffuse and shadow rays do not see (no caustic, no shadow:
    the invisible-to-lighting trick). Seen from above at a slant, the mirror's caustic in the frame."""
    scene = _standing_mirror("ray_visibility")
    bulb = B.add_light(scene, "Bulb", "POINT", (0.4, -0.2, 3.0), energy=600.0, shadow_soft_size=0.25,
                       use_soft_falloff=True)
    bulb.visible_glossy = False
    glass = B.material("Glass", "glass", (1.0, 1.0, 1.0), ior=1.5)
    _sphere(scene, "Ball", glass, 0.45, (0, 0, 0.9))
    ghost = _sphere(scene, "Ghost", glass, 0.35, (-1.1, 0.5, 0.6))
    ghost.visible_diffuse = False
    ghost.visible_shadow = False
    lamp = B.add_light(scene, "Lamp", "POINT", (-0.2, -1.0, 1.6), energy=300.0, shadow_soft_size=0.15,
                       use_soft_falloff=False)
    lamp.visible_transmission = False
    B.add_camera(scene, (-1.2, -3.6, 3.2), (0.3, 0.2, 0.2), lens=30)
    return scene


def hidden_kinds():
    """Ray Visibility of objects for the rays after a mirror or glass: mirror_point_hard's mirror and bulb
    with a dark card between them that glossy rays do not meet (the mirror's light passes it; shadow
    rays do meet it: the floor's direct light does not), and a glass ball transmission rays do not
    meet (a refraction's ray passes the ball's own far side: one refraction, then the light)."""
    scene = _mirror_under_bulb("hidden_kinds")
    card = B.material("Card", "diffuse", (0.2, 0.2, 0.2))
    v, f = B.grid(0.5, 0.7)
    ob = B.mesh_object(scene, "Card", v, f, card, location=(0.85, 0.0, 1.15), rotation=(0, math.radians(50), 0))
    ob.visible_glossy = False
    glass = B.material("Glass", "glass", (1.0, 1.0, 1.0), ior=1.5)
    ball = _sphere(scene, "Ball", glass, 0.3, (-0.2, 0.6, 0.55))
    ball.visible_transmission = False
    return scene


def hidden_ball():
    """sphere_point_soft's ball and bulb, the ball hidden from camera rays (Ray Visibility): the camera
    sees the floor past it, the caustic under it directly, where it saw it through the ball; a card hidden
    from camera rays too stands before the camera, out of the light's way."""
    scene = _ball_under_bulb("hidden_ball", lambda: principled("WhiteGlass", base=(1.0, 1.0, 1.0),
                                                               transmission=1.0, ior=1.5))
    bpy.data.objects["Ball"].visible_camera = False
    card = B.material("Card", "diffuse", (0.5, 0.3, 0.2))
    v, f = B.grid(0.9, 0.6)
    ob = B.mesh_object(scene, "Card", v, f, card, location=(-0.35, -2.2, 1.55), rotation=(math.radians(60), 0, 0))
    ob.visible_camera = False
    return scene


SCENES = {
    # name: (builder, what it covers)
    "lens_area": (lens_area, "Glass BSDF 1.5, square area, closed glass (T T), seen directly"),
    "gold_cylinder": (gold_cylinder, "Principled metallic, disk area, curved mirror (R, R R), open"),
    "pool_sun4": (pool_sun4, "Glass BSDF 1.33, sun 4 deg, wavy open water, seen through water"),
    "bumped_pool_sun": (bumped_pool_sun, "pool_sun4's water flat with a Bump node (Noise Texture Height) on the "
                        "Glass BSDF's Normal"),
    "normal_mapped_pool_sun": (normal_mapped_pool_sun, "pool_sun4's water flat with a Normal Map node (a packed "
                               "image of sine waves) on the Glass BSDF's Normal"),
    "bumped_slab_sun": (bumped_slab_sun, "a closed glass slab with a Bump node on its Normal, the light leaving it "
                        "through its back (Cycles' bump does not flip there)"),
    "cube_grey": (cube_grey, "Principled glass Base Color 0.8, bevelled cube, internal reflection"),
    "cube_grey_diffuse1": (cube_grey_diffuse1, "cube_grey with Diffuse bounces 1 (no floor -> glass "
                           "-> floor light)"),
    "cube_grey_reflect": (cube_grey_reflect, "cube_grey with Diffuse bounces 1, Transmission 0 (R "
                          "alone)"),
    "sphere_point_soft": (sphere_point_soft, "Principled glass white, point light with soft falloff"),
    "sphere_refraction_spot": (sphere_refraction_spot, "Refraction BSDF 1.33, spot light"),
    "mirror_point_hard": (mirror_point_hard, "Glossy BSDF flat mirror, point light without soft "
                          "falloff, receiver seen in the mirror"),
    "linked_lamps": (linked_lamps, "Light Linking: a lamp lighting the ball alone and a lamp lighting all but the "
                     "ball, over _standing_mirror and a glass ball (Cycles asks it of the last mirror or glass)"),
    "shadow_linked_ball": (shadow_linked_ball, "Shadow Linking: a plate between a bulb and a glass ball that does not "
                           "shadow the bulb (its blocker collection excludes it)"),
    "mirror_alloy": (mirror_alloy, "mirror_point_hard's mirror as Principled Metallic 0.7 (a partly metallic "
                     "lobe)"),
    "mirror_spread30": (mirror_spread30, "Glossy BSDF flat mirror, square area light of spread 30 "
                        "deg (the soft-box falloff)"),
    "water_flat_sun0": (water_flat_sun0, "flat open water 1.33, sun angle 0 (Cycles MNEE reference)"),
    "wavy_mirror_sun2": (wavy_mirror_sun2, "Glossy BSDF wavy sheet, sun 2 deg"),
    "through_glass_disk": (through_glass_disk, "Glass BSDF tinted 1.33, disk area, seen through glass"),
    "prism_tir": (prism_tir, "Glass BSDF 1.5 prism, flat, total internal reflection (T R T)"),
    "cube_white_rect": (cube_white_rect, "Principled glass white, bevelled cube, rectangle area, "
                        "T R T and T R R T"),
    "cube_tint_rect": (cube_tint_rect, "the white cube's scene with Principled Base Color 0.8 "
                       "(the tint alone)"),
    "cube_white_glossy1": (cube_white_glossy1, "the white cube with Light Paths glossy 1, max 12, "
                           "transmission 12 (bounce limits)"),
    "principled_floor": (principled_floor, "a receiver of Blender's default material (Principled BSDF, "
                         "roughness 0.5) seen at a slant, under a glass ball"),
    "coated_floor": (coated_floor, "principled_floor's floor under a clear coat (Coat Weight 1)"),
    "tinted_ball": (tinted_ball, "Glass BSDF ball with a Volume Absorption (0.15/0.6/1.05 per metre) under a "
                    "point light, part of its caustic seen through it"),
    "absorbing_ball_area": (absorbing_ball_area, "a grey Glass BSDF ball with a Volume Absorption (0.12/0.54/1.02 per "
                            "metre) under two square area lights: one's focus seen through the ball, the other's "
                            "directly"),
    "checker_floor": (checker_floor, "the slanted ball over a Principled floor whose Base Color is a Checker "
                      "Texture (the render's Diffuse Color pass holds the albedo)"),
    "bumped_floor": (bumped_floor, "a Diffuse BSDF receiver whose Normal is a Bump node of a Noise Texture, "
                     "seen at a slant under a glass ball"),
    "pool_bumped_floor": (pool_bumped_floor, "pool_sun4 over a bumped Diffuse BSDF floor, seen through the "
                          "water"),
    "rough_floor": (rough_floor, "a Diffuse BSDF receiver of Roughness 1 (Oren-Nayar) seen at a slant, "
                    "under a glass ball"),
    "egg_sun_spot": (egg_sun_spot, "Glass BSDF tinted 1.45, non-uniformly scaled and turned smooth sphere, "
                     "coloured sun 6 deg and coloured spot with blend together"),
    "world_ball": (world_ball, "a world of constant colour (pale blue) as the only light, through a Glass BSDF "
                   "ball"),
    "world_mirror_bulb": (world_mirror_bulb, "mirror_point_hard with a grey world (0.4): the sky's reflection "
                          "and the bulb's together"),
    "mix_frosted_ball": (mix_frosted_ball, "a Mix Shader of Diffuse and Glass BSDF (Factor 0.75) on a ball: the "
                         "glass casts with its weight"),
    "mix_alloy_mirror": (mix_alloy_mirror, "a Mix Shader (0.5) of a Principled mirror of Metallic 0.5 and a dark "
                         "diffuse: the coat weighed by the mix too"),
    "mix_floor": (mix_floor, "a Mix Shader of Diffuse and Glossy BSDF (Factor 0.25) on the floor, seen at a "
                  "slant under a glass ball"),
    "fresnel_glass_ball": (fresnel_glass_ball, "the old glass: Refraction and Glossy BSDF mixed by a Fresnel "
                           "node, on a ball"),
    "fresnel_floor": (fresnel_floor, "the old coated floor: Diffuse and Glossy BSDF mixed by a Fresnel node, "
                      "seen at a slant under a glass ball"),
    "fake_shadow_ball": (fake_shadow_ball, "the fake-shadow trick: Glass and Transparent BSDF mixed by Light "
                         "Path's Is Shadow Ray, on a ball"),
    "rough_glass_ball": (rough_glass_ball, "a ball of Principled glass at the default Roughness 0.5 (Multiscatter "
                         "GGX: a blurred caustic), part of it seen through the ball"),
    "rough_mirror": (rough_mirror, "mirror_point_hard's mirror as Principled metal at the default Roughness 0.5 "
                     "(Multiscatter GGX)"),
    "rough_mirror_ggx": (rough_mirror_ggx, "rough_mirror's metal with the GGX distribution (single "
                         "scattering, no energy compensation)"),
    "rough_glass_ggx": (rough_glass_ggx, "a Glass BSDF ball of Roughness 0.3, GGX (single scattering) under a "
                        "point light, part of its blurred caustic seen through it"),
    "rough_tinted_glass": (rough_tinted_glass, "a coloured Glass BSDF ball of Roughness 0.5, Multiscatter GGX "
                           "(Cycles' energy compensation by the glass's colour), part of its glow seen through it"),
    "rough_pool_sun": (rough_pool_sun, "pool_sun4's wavy water as a Glass BSDF of Roughness 0.15 (Multiscatter "
                       "GGX), the floor seen through it"),
    "rough_tinted_mirror": (rough_tinted_mirror, "mirror_point_hard's mirror as a coloured Glossy BSDF of "
                            "Roughness 0.3, Multiscatter GGX"),
    "ray_visibility": (ray_visibility, "Ray Visibility: a bulb glossy rays do not see, a lamp transmission rays "
                       "do not see, a glass ball diffuse and shadow rays do not see, beside a ball and a mirror"),
    "hidden_kinds": (hidden_kinds, "Ray Visibility after a mirror or glass: a card glossy rays do not meet "
                     "between a mirror and its bulb, a glass ball transmission rays do not meet"),
    "hidden_ball": (hidden_ball, "Ray Visibility: a glass ball and a card camera rays do not meet, the caustic "
                    "under the ball seen past it"),
    "mesh_light_ball": (mesh_light_ball, "a mesh light (an Emission plane) seen from its back by a Glass BSDF ball"),
    "principled_glow_ball": (principled_glow_ball, "a mesh light of a Principled BSDF's Emission (the panel "
                             "receives too)"),
    "mesh_light_mirror": (mesh_light_mirror, "a closed mesh light (an Emission ball) over a standing Glossy BSDF "
                          "mirror"),
    "metallic_edge_ring": (metallic_edge_ring, "a Metallic BSDF (F82 mode, an Edge Tint) ring under gold_cylinder's "
                           "side light"),
    "conductor_ring": (conductor_ring, "a Metallic BSDF (Physical Conductor mode) ring under gold_cylinder's side "
                       "light"),
    "shadow_linked_glow": (shadow_linked_glow, "Shadow Linking of a mesh light: shadow_linked_ball's plate "
                           "between an Emission ball and the glass ball, not shadowing the glow"),
    "film_ring": (film_ring, "a pale Metallic BSDF (F82 mode) ring under a thin film (350 nm, index 1.5), under "
                  "gold_cylinder's side light"),
    "anodized_ring": (anodized_ring, "a Metallic BSDF (Physical Conductor mode) ring under a thin film (180 nm, "
                      "index 2.2), under gold_cylinder's side light"),
    "film_alloy_mirror": (film_alloy_mirror, "mirror_alloy's Principled mirror (Metallic 0.7) under a thin film "
                          "(400 nm, index 1.4)"),
    "film_ball": (film_ball, "a Glass BSDF ball under a thin film (280 nm, index 2.2), under sphere_point_soft's "
                  "bulb"),
    "spec_tint_ball": (spec_tint_ball, "a Principled glass ball of Specular Tint 4 / 1 / 0, under "
                       "sphere_point_soft's bulb"),
    "hdri_ball": (hdri_ball, "an Environment Texture (a sky and a sun of 4 deg) turned by a Mapping node, "
                  "through a Glass BSDF ball"),
    # issue 61's pools at 160 x 120 (testkit/pools.py)
    "pool_sun": (pools.pool_sun, "pool_sun4 at 160 x 120 (wavy water, sun of 4 deg, seen through the water)"),
    "pool_hdri": (pools.pool_hdri, "pool_sun's water lit by an environment image alone: a dim sky and a "
                  "disc of 5 deg"),
}
# scenes whose reference is Cycles' MNEE (the light cannot be found by path tracing)
MNEE_REFERENCE = {"water_flat_sun0"}


def build(name: str, out: Path) -> Path:
    """Build one scene and save it as OUT/NAME.blend."""
    SCENES[name][0]()
    path = Path(out) / f"{name}.blend"
    B.save(path)
    return path


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if not argv:
        print(__doc__.splitlines()[2].strip())
        return 2
    out = Path(argv[0]).resolve()
    out.mkdir(parents=True, exist_ok=True)
    names = argv[1:] or list(SCENES)
    unknown = [n for n in names if n not in SCENES]
    if unknown:
        print(f"unknown scene(s): {', '.join(unknown)}; known: {', '.join(SCENES)}", file=sys.stderr)
        return 2
    for name in names:
        build(name, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
