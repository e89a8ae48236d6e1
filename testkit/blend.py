"""Building Blender scenes with the bpy data API: the helpers of the tests, of the sample scenes
(sample_blends/build.py) and of the conformance scenes (testkit/conformance_scenes.py), written once.

Needs the bpy module (tests import this after ``pytest.importorskip("bpy")``). Only the data API
is used (no operators but the factory reset and saving), so it runs headless.
"""
from __future__ import annotations

import math

import bpy
import numpy as np
from mathutils import Vector


# ------------------------------------------------------------------------------- the scene
def reset():
    """A factory-fresh, empty Blender session: its scene."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context.scene


def render_settings(scene, width, height):
    """Cycles set up for comparing caustics: no clamping, no Filter Glossy, no denoising, no adaptive
    sampling, enough bounces, Blackman-Harris of width 1.5, the Standard view."""
    scene.render.engine = "CYCLES"
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.render.filter_size = 1.5
    c = scene.cycles
    c.device = "CPU"
    c.samples = 256
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    c.max_bounces = 16
    c.diffuse_bounces = 4
    c.glossy_bounces = 16
    c.transmission_bounces = 16
    c.transparent_max_bounces = 8
    c.pixel_filter_type = "BLACKMAN_HARRIS"
    c.filter_width = 1.5
    c.seed = 0
    c.use_animated_seed = False
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0


def black_world(scene):
    """A new world for the scene, black (colour and Background strength 0)."""
    scene.world = bpy.data.worlds.new("World")
    sky(scene, (0.0, 0.0, 0.0), 0.0)
    return scene.world


def sky(scene, color, strength):
    """The scene's world a constant colour (its colour and its Background node's Color and Strength)."""
    w = scene.world
    w.color = color
    bg = w.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*color, 1.0)
    bg.inputs["Strength"].default_value = strength


def hdri_image(width=256, height=128, sun=(0.0, -0.574, 0.819), sun_sigma=3.0, sun_peak=100.0, turn_deg=40.0):
    """A float image for an Environment Texture: a pale sky (0.15/0.2/0.3, brighter towards the
    horizon) and a warm sun, a Gaussian of sun_sigma pixels, at the pixel that shows the world
    direction sun through a Mapping node turning the view direction turn_deg about Z (the lookup
    Cycles makes, lights.EnvMap: u = 0.5 - atan2(m_y, m_x) / 2 pi, v = 1 - acos(m_z) / pi, rows from
    the bottom); the image is packed into the file."""
    t = math.radians(turn_deg)
    m = (math.cos(t) * sun[0] - math.sin(t) * sun[1], math.sin(t) * sun[0] + math.cos(t) * sun[1], sun[2])
    su = (0.5 - math.atan2(m[1], m[0]) / (2 * math.pi)) % 1.0
    sv = 1.0 - math.acos(max(-1.0, min(1.0, m[2]))) / math.pi
    jj, ii = np.mgrid[0:height, 0:width]
    v = (jj + 0.5) / height
    du = (ii + 0.5) / width - su
    du = (du + 0.5) % 1.0 - 0.5  # around the seam
    r2 = (du * width) ** 2 + ((v - sv) * height) ** 2
    base_sky = (0.15, 0.2, 0.3)
    px = np.zeros((height, width, 4), np.float32)
    glow = np.exp(-0.5 * r2 / sun_sigma ** 2)
    for c, (base, tint) in enumerate(zip(base_sky, (1.0, 0.85, 0.6))):
        px[..., c] = base * (1.0 + 0.5 * (1.0 - np.abs(v - 0.5) * 2)) + sun_peak * tint * glow
    px[..., 3] = 1.0
    img = bpy.data.images.new("Sky", width, height, float_buffer=True, alpha=False)
    img.pixels.foreach_set(px.ravel())
    img.pack()
    return img


def hdri_world(scene, image, turn_deg=0.0, strength=1.0):
    """The scene's world an Environment Texture of image, the view direction turned turn_deg about
    Z by a Mapping node first."""
    nt = scene.world.node_tree
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(turn_deg))
    coords = nt.nodes.new("ShaderNodeTexCoord")
    nt.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    bg = nt.nodes["Background"]
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = strength


def save(path):
    bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=True, check_existing=False)
    print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KiB)")


# ------------------------------------------------------------------------------- materials
def set_input(socket, value):
    """A node input's value; an RGB triple on a colour input gets alpha 1."""
    socket.default_value = (*value, 1.0) if socket.type == "RGBA" and isinstance(value, tuple) and len(value) == 3 \
        else value


def node_material(name, node_type, color=None, **inputs):
    """A node material whose Surface is one shader node of node_type (a bl_idname), its Color
    (color) and other inputs set."""
    m = bpy.data.materials.new(name)
    nt = m.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    out.location = (300, 0)
    node = nt.nodes.new(node_type)
    if color is not None:
        inputs = {"Color": color, **inputs}
    for k, v in inputs.items():
        set_input(node.inputs[k], v)
    nt.links.new(node.outputs[0], out.inputs["Surface"])
    return m


def surface_node(m):
    """The node linked to material m's Surface."""
    return m.node_tree.nodes["Material Output"].inputs["Surface"].links[0].from_node


BSDFS = {"diffuse": "ShaderNodeBsdfDiffuse", "glossy": "ShaderNodeBsdfGlossy", "glass": "ShaderNodeBsdfGlass"}


def material(name, kind, color=(0.8, 0.8, 0.8), roughness=0.0, ior=1.45, distribution="GGX"):
    """A material of one BSDF of kind 'diffuse', 'glossy' or 'glass' (a glossy's or glass's microfacet
    distribution: distribution), the viewport colour its colour: the sample and conformance scenes'
    materials (node_material makes one node of any type)."""
    inputs = {"Roughness": roughness, **({"IOR": ior} if kind == "glass" else {})}
    m = node_material(name, BSDFS[kind], color, **inputs)
    if kind != "diffuse":
        surface_node(m).distribution = distribution
    m.diffuse_color = (*color, 1.0)
    return m


def metallic(name, mode="F82", **inputs):
    """A material whose Surface is a Metallic BSDF (Blender 4.3 on) of fresnel_type mode, its inputs set."""
    m = node_material(name, "ShaderNodeBsdfMetallic")
    node = surface_node(m)
    node.fresnel_type = mode
    for k, v in inputs.items():
        set_input(node.inputs[k], v)
    return m


def mixed(name, first, second, factor=0.5, add=False, distribution=None):
    """A material whose Surface is a Mix Shader (Factor factor) or an Add Shader of two shader nodes,
    each given as (bl_idname, {input: value}) or None (left empty); distribution: that of every node
    of the two that has one (but a Diffuse BSDF), if given."""
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
            set_input(node.inputs[k], v)
        if distribution is not None and hasattr(node, "distribution") and spec[0] != "ShaderNodeBsdfDiffuse":
            node.distribution = distribution
        nt.links.new(node.outputs[0], sock)
    nt.links.new(mix.outputs[0], out.inputs["Surface"])
    return m


def by_fresnel(m, ior=1.45, layer_weight=False):
    """m's Mix Shader's Factor from a Fresnel node of index ior (or a Layer Weight node's Fresnel of
    Blend 1 - 1/ior): the classic node setups before the Principled BSDF."""
    nt = m.node_tree
    fr = nt.nodes.new("ShaderNodeLayerWeight" if layer_weight else "ShaderNodeFresnel")
    if layer_weight:
        fr.inputs["Blend"].default_value = 1.0 - 1.0 / ior
    else:
        fr.inputs["IOR"].default_value = ior
    nt.links.new(fr.outputs[0], nt.nodes["Mix Shader"].inputs["Factor"])
    return m


def bumped_glass(name, distance, scale=5.0, coords=None, ior=1.33):
    """Waves as artists make them: a Glass BSDF whose Normal is a Bump node (Distance `distance`) of a
    Noise Texture (Scale `scale`, Detail 2, Generated coordinates, or the Texture Coordinate node's
    output `coords`)."""
    m = material(name, "glass", (1.0, 1.0, 1.0), ior=ior)
    nt = m.node_tree
    glass = next(n for n in nt.nodes if n.type == "BSDF_GLASS")
    noise, bump = nt.nodes.new("ShaderNodeTexNoise"), nt.nodes.new("ShaderNodeBump")
    if coords is not None:
        nt.links.new(nt.nodes.new("ShaderNodeTexCoord").outputs[coords], noise.inputs["Vector"])
    noise.inputs["Scale"].default_value = scale
    noise.inputs["Detail"].default_value = 2.0
    bump.inputs["Distance"].default_value = distance
    nt.links.new(noise.outputs["Fac"], bump.inputs["Height"])
    nt.links.new(bump.outputs["Normal"], glass.inputs["Normal"])
    return m


def bumpy(name, node_type="ShaderNodeBsdfDiffuse", color=None):
    """A receiver's material whose Normal is a Bump node (Distance 0.1) of a Noise Texture (Scale 8,
    Detail 2, Object coordinates)."""
    m = node_material(name, node_type, color)
    nt = m.node_tree
    noise, bump = nt.nodes.new("ShaderNodeTexNoise"), nt.nodes.new("ShaderNodeBump")
    nt.links.new(nt.nodes.new("ShaderNodeTexCoord").outputs["Object"], noise.inputs["Vector"])
    noise.inputs["Scale"].default_value = 8.0  # bumps of ~0.1 m
    noise.inputs["Detail"].default_value = 2.0
    bump.inputs["Distance"].default_value = 0.1
    nt.links.new(noise.outputs["Fac"], bump.inputs["Height"])
    nt.links.new(bump.outputs["Normal"], surface_node(m).inputs["Normal"])
    return m


# ------------------------------------------------------------------------------- meshes
def link(ob, collection=None):
    """ob linked into collection (default: the context scene's)."""
    (collection or bpy.context.scene.collection).objects.link(ob)
    return ob


def mesh_object(scene, name, verts, faces, mat, smooth=False, location=(0, 0, 0),
                rotation=(0, 0, 0), caster=False, receiver=False):
    """An object of a mesh of verts and faces (material mat, if any) linked into scene, with Cycles'
    caustic caster and receiver flags."""
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(v) for v in verts], [], [tuple(f) for f in faces])
    me.update()
    if mat is not None:
        me.materials.append(mat)
    for p in me.polygons:
        p.use_smooth = smooth
    ob = bpy.data.objects.new(name, me)
    ob.location = location
    ob.rotation_euler = rotation
    ob.cycles.is_caustics_caster = caster
    ob.cycles.is_caustics_receiver = receiver
    scene.collection.objects.link(ob)
    return ob


def grid(size_x, size_y, nx=1, ny=1, height=None):
    """A (nx x ny)-quad grid in the XY plane centred at the origin; height(x, y) -> z."""
    verts, faces = [], []
    for j in range(ny + 1):
        for i in range(nx + 1):
            x = (i / nx - 0.5) * size_x
            y = (j / ny - 0.5) * size_y
            verts.append((x, y, 0.0 if height is None else height(x, y)))
    for j in range(ny):
        for i in range(nx):
            a = j * (nx + 1) + i
            faces.append((a, a + 1, a + nx + 2, a + nx + 1))
    return verts, faces


def plane(scene, name, size, mat, location, rotation=(0, 0, 0)):
    """A size x size square (local +Z up) linked into scene."""
    v, f = grid(size, size)
    return mesh_object(scene, name, v, f, mat, location=location, rotation=rotation)


def uv_sphere(radius, segments, rings):
    verts = [(0.0, 0.0, radius)]
    for r in range(1, rings):
        th = math.pi * r / rings
        for s in range(segments):
            ph = 2 * math.pi * s / segments
            verts.append((radius * math.sin(th) * math.cos(ph),
                          radius * math.sin(th) * math.sin(ph), radius * math.cos(th)))
    verts.append((0.0, 0.0, -radius))
    faces = []
    for s in range(segments):  # top cap
        faces.append((0, 1 + s, 1 + (s + 1) % segments))
    for r in range(rings - 2):
        a0, b0 = 1 + r * segments, 1 + (r + 1) * segments
        for s in range(segments):
            s1 = (s + 1) % segments
            faces.append((a0 + s, b0 + s, b0 + s1, a0 + s1))
    last, base = len(verts) - 1, 1 + (rings - 2) * segments
    for s in range(segments):  # bottom cap
        faces.append((base + (s + 1) % segments, base + s, last))
    return verts, faces


def cube_mesh(name="Cube", size=2.0):
    """A mesh datablock of bmesh's cube."""
    import bmesh

    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=size)
    bm.to_mesh(me)
    bm.free()
    return me


def sphere_mesh(name="Sphere", radius=1.0, smooth=True):
    """A mesh datablock of bmesh's UV sphere (16 x 8)."""
    import bmesh

    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=16, v_segments=8, radius=radius)
    bm.to_mesh(me)
    bm.free()
    for p in me.polygons:
        p.use_smooth = smooth
    return me


def mesh_with(mat, name="Thing"):
    """A cube object of material mat (None: none) in the context scene."""
    me = cube_mesh(name)
    if mat is not None:
        me.materials.append(mat)
    return link(bpy.data.objects.new(name, me))


# ------------------------------------------------------------------------------- lights and cameras
def add_light(scene, name, kind, location=(0, 0, 3), rotation=(0, 0, 0), energy=100.0, caustics=True,
              scale=(1, 1, 1), **props):
    """A light of kind 'POINT', 'SPOT', 'AREA' or 'SUN' of energy (W; a sun's: W/m^2) and its data's
    properties props, flagged for Cycles' caustics (caustics), linked into scene. Blender's own
    defaults are energy 10 and caustics False."""
    lt = bpy.data.lights.new(name, kind)
    lt.energy = energy
    for k, v in props.items():
        setattr(lt, k, v)
    lt.cycles.is_caustics_light = caustics
    ob = bpy.data.objects.new(name, lt)
    ob.location, ob.rotation_euler, ob.scale = location, rotation, scale
    scene.collection.objects.link(ob)
    return ob


def keys_linear(owner, path, keys):
    """Keyframes of owner's property path ({frame: value}), interpolated linearly between them."""
    edit = bpy.context.preferences.edit
    before = edit.keyframe_new_interpolation_type
    edit.keyframe_new_interpolation_type = "LINEAR"
    try:
        for frame, value in sorted(keys.items()):
            setattr(owner, path, value)
            owner.keyframe_insert(path, frame=frame)
    finally:
        edit.keyframe_new_interpolation_type = before


def add_camera(scene=None, location=(0, -10, 0), target=None, rotation=(math.pi / 2, 0, 0), name="Camera",
               ortho_scale=None, **props):
    """The scene's camera (default: the context scene's), at location, looking at target if given (else
    turned by rotation: by default along +Y), orthographic if ortho_scale is given; its data's
    properties props (lens, sensor_width, type...)."""
    scene = scene or bpy.context.scene
    cam = bpy.data.cameras.new(name)
    for k, v in props.items():
        setattr(cam, k, v)
    if ortho_scale is not None:
        cam.type = "ORTHO"
        cam.ortho_scale = ortho_scale
    ob = bpy.data.objects.new(name, cam)
    ob.location = location
    if target is not None:
        ob.rotation_euler = (Vector(target) - Vector(location)).to_track_quat("-Z", "Y").to_euler()
    else:
        ob.rotation_euler = rotation
    scene.collection.objects.link(ob)
    scene.camera = ob
    return ob


# ------------------------------------------------------------------------------- a whole scene
def mirror_scene(light=True, camera=True, width=24, height=16):
    """testkit.scenes.mirror_scene in Blender: a floor, a mirror tilted 45 degrees and a disk light
    beside it (a bright reflected spot on the floor), in the context scene."""
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    plane(scene, "Floor", 10, node_material("Floor", "ShaderNodeBsdfDiffuse", (0.8,) * 3), (0, 0, 0))
    plane(scene, "Mirror", 1.5, node_material("Mirror", "ShaderNodeBsdfGlossy", (0.9,) * 3, Roughness=0.0),
          (0, 0, 1.5), (0, math.radians(-135), 0))
    if light:
        add_light(scene, "Disk", "AREA", (-2, 0, 1.5), (0, math.radians(-90), 0), energy=100.0, caustics=False,
                  shape="DISK", size=0.5)
    if camera:
        add_camera(scene, (0, -6, 5), rotation=(math.radians(50), 0, 0))
    return scene


# ------------------------------------------------------------------------------- the export
def export(scene=None, **kw):
    """export_scene of the scene (default: the context scene's): (Scene, its warnings)."""
    from smbs_addon.blender.export import export_scene

    warnings = []
    sc = export_scene(scene or bpy.context.scene, warn=warnings.append, **kw)
    return sc, warnings


def obj_tris(sc, name):
    """The exported triangles of object name: (vertices (T,3,3), normals (T,3,3))."""
    i = sc.object_names.index(name)
    return sc.tri_vertices[sc.tri_object == i], sc.tri_normals[sc.tri_object == i]


def one_material(mat):
    """A camera and a cube of material mat, exported: (Scene, warnings), the scene asserted to hold
    one material."""
    add_camera()
    mesh_with(mat)
    sc, warnings = export()
    assert len(sc.mat_names) == 1
    return sc, warnings
