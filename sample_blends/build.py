"""Build the sample .blend scenes used by the tests and the Cycles references.

    python sample_blends/build.py [outdir]        (default: this folder)

Uses only the bpy data API (no operators besides the factory reset), so it runs
headless with the ``bpy`` module. Every scene is set up for comparing against
Cycles: caustic flags (caster / receiver / caustics light), a black world, no
clamping, no Filter Glossy, no denoising, no adaptive sampling, enough bounces,
Blackman-Harris filter width 1.5.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import bpy
from mathutils import Vector

HERE = Path(__file__).resolve().parent


# ----------------------------------------------------------------------------- helpers
def reset():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context.scene


def render_settings(scene, width, height):
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
    w = bpy.data.worlds.new("World")
    scene.world = w
    w.color = (0.0, 0.0, 0.0)
    bg = w.node_tree.nodes.get("Background") if w.node_tree else None
    if bg is not None:
        bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        bg.inputs["Strength"].default_value = 0.0
    return w


def hdri_image(width=256, height=128, sun=(0.0, -0.574, 0.819), sun_sigma=3.0, sun_peak=100.0, turn_deg=40.0):
    """A float image for an Environment Texture: a pale sky (0.15/0.2/0.3, brighter towards the
    horizon) and a warm sun, a Gaussian of sun_sigma pixels, at the pixel that shows the world
    direction sun through a Mapping node turning the view direction turn_deg about Z (the lookup
    Cycles makes, lights.EnvMap: u = 0.5 - atan2(m_y, m_x) / 2 pi, v = 1 - acos(m_z) / pi, rows from
    the bottom); the image is packed into the file."""
    import numpy as np

    t = math.radians(turn_deg)
    m = (math.cos(t) * sun[0] - math.sin(t) * sun[1], math.sin(t) * sun[0] + math.cos(t) * sun[1], sun[2])
    su = (0.5 - math.atan2(m[1], m[0]) / (2 * math.pi)) % 1.0
    sv = 1.0 - math.acos(max(-1.0, min(1.0, m[2]))) / math.pi
    jj, ii = np.mgrid[0:height, 0:width]
    v = (jj + 0.5) / height
    du = (ii + 0.5) / width - su
    du = (du + 0.5) % 1.0 - 0.5  # around the seam
    r2 = (du * width) ** 2 + ((v - sv) * height) ** 2
    sky = (0.15, 0.2, 0.3)
    px = np.zeros((height, width, 4), np.float32)
    glow = np.exp(-0.5 * r2 / sun_sigma ** 2)
    for c, (base, tint) in enumerate(zip(sky, (1.0, 0.85, 0.6))):
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


def material(name, kind, color=(0.8, 0.8, 0.8), roughness=0.0, ior=1.45, distribution="GGX"):
    """A node material with a single BSDF linked to the Material Output (a glossy's or glass's
    microfacet distribution: distribution)."""
    m = bpy.data.materials.new(name)
    nt = m.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    out.location = (300, 0)
    node = nt.nodes.new({"diffuse": "ShaderNodeBsdfDiffuse", "glossy": "ShaderNodeBsdfGlossy",
                         "glass": "ShaderNodeBsdfGlass"}[kind])
    node.inputs["Color"].default_value = (*color, 1.0)
    node.inputs["Roughness"].default_value = roughness
    if kind == "glass":
        node.inputs["IOR"].default_value = ior
    if kind != "diffuse":
        node.distribution = distribution
    nt.links.new(node.outputs[0], out.inputs["Surface"])
    m.diffuse_color = (*color, 1.0)
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


def mesh_object(scene, name, verts, faces, mat, smooth=False, location=(0, 0, 0),
                rotation=(0, 0, 0), caster=False, receiver=False):
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(v) for v in verts], [], [tuple(f) for f in faces])
    me.update()
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


def add_light(scene, name, type, location, rotation=(0, 0, 0), energy=100.0, caustics=True, **props):
    lt = bpy.data.lights.new(name, type)
    lt.energy = energy
    for k, v in props.items():
        setattr(lt, k, v)
    lt.cycles.is_caustics_light = caustics
    ob = bpy.data.objects.new(name, lt)
    ob.location = location
    ob.rotation_euler = rotation
    scene.collection.objects.link(ob)
    return ob


def add_camera(scene, location, target, lens=50.0, ortho_scale=None):
    cam = bpy.data.cameras.new("Camera")
    cam.lens = lens
    cam.sensor_fit = "AUTO"
    cam.sensor_width = 36.0
    if ortho_scale is not None:
        cam.type = "ORTHO"
        cam.ortho_scale = ortho_scale
    ob = bpy.data.objects.new("Camera", cam)
    ob.location = location
    direction = Vector(target) - Vector(location)
    ob.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(ob)
    scene.camera = ob
    return ob


def save(path):
    bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=True, check_existing=False)
    print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KiB)")


# ------------------------------------------------------------------------------ scenes
def build_mirror(out):
    """A flat mirror above an upward-facing disk light throws its light down at
    45 degrees onto the floor. The floor is never lit directly (the light faces
    up), and what the caustic sees in the mirror is the unlit floor under the
    light, so Cycles' "caustics on - off" is the caustic alone (no second-order
    diffuse -> mirror -> diffuse light to tell apart)."""
    scene = reset()
    scene.name = "Mirror"
    render_settings(scene, 160, 120)
    black_world(scene)
    floor_mat = material("Floor", "diffuse", (0.8, 0.8, 0.8))
    mirror_mat = material("Mirror", "glossy", (0.9, 0.9, 0.9), roughness=0.0)
    v, f = grid(12, 10)
    mesh_object(scene, "Floor", v, f, floor_mat, location=(0.5, 0, 0), receiver=True)
    # local +Z rotated 157.5 deg about Y -> (0.383, 0, -0.924): up-going light leaves 45 deg down, towards +x
    v, f = grid(1.0, 1.0)
    mesh_object(scene, "Mirror", v, f, mirror_mat, smooth=True, location=(-3, 0, 4),
                rotation=(0, math.radians(157.5), 0), caster=True)
    # local -Z rotated 180 deg about X -> +Z: the light faces up
    add_light(scene, "Light", "AREA", (-3, 0, 2), (math.pi, 0, 0), energy=1000.0,
              shape="DISK", size=0.5, spread=math.pi)
    add_camera(scene, (1.3, -8.5, 6.5), (1.3, 0, 0), lens=35)
    save(out / "mirror.blend")


def _glass_ball_scene(name, height):
    """A floor and a glass ball (radius 0.5, IOR 1.45) whose centre is height above it."""
    scene = reset()
    scene.name = name
    render_settings(scene, 160, 120)
    black_world(scene)
    floor_mat = material("Floor", "diffuse", (0.8, 0.8, 0.8))
    glass = material("Glass", "glass", (1.0, 1.0, 1.0), roughness=0.0, ior=1.45)
    v, f = grid(10, 10)
    mesh_object(scene, "Floor", v, f, floor_mat, receiver=True)
    v, f = uv_sphere(0.5, 64, 32)
    mesh_object(scene, "Sphere", v, f, glass, smooth=True, location=(0, 0, height), caster=True)
    return scene


def build_glass_sphere(out):
    scene = _glass_ball_scene("GlassSphere", 1.0)
    add_light(scene, "Light", "AREA", (0, 0, 4), energy=200.0, shape="SQUARE", size=0.5,
              spread=math.pi)
    add_camera(scene, (0, -4, 3), (0, 0, 0.3), lens=50)
    save(out / "glass_sphere.blend")


def build_glass_spot(out):
    """A glass ball lit by a spot light whose cone is narrower than the ball (seen from
    the light's centre): the floor gets its light through the ball but for a thin
    crescent lit past the ball from the edge of the light (radius 0.3), whose light the
    ball focuses back onto the floor (1.3% of the caustic layer, 30-200 px from the focus)."""
    scene = _glass_ball_scene("GlassSpot", 1.0)
    # the ball subtends 9.6 deg (half-angle) from the light; the cone's half-angle is 8 deg
    add_light(scene, "Spot", "SPOT", (0, 0, 4), energy=2000.0, shadow_soft_size=0.3,
              spot_size=math.radians(16.0), spot_blend=0.0)
    add_camera(scene, (0, -3.2, 2.6), (0, 0, 0.2), lens=50)
    save(out / "glass_spot.blend")


def build_water(out):
    scene = reset()
    scene.name = "Water"
    render_settings(scene, 64, 64)
    black_world(scene)
    floor_mat = material("Floor", "diffuse", (0.8, 0.8, 0.8))
    water = material("Water", "glass", (1.0, 1.0, 1.0), roughness=0.0, ior=1.33)
    v, f = grid(20, 20)
    mesh_object(scene, "Floor", v, f, floor_mat, receiver=True)
    v, f = grid(20, 20)
    mesh_object(scene, "Water", v, f, water, smooth=False, location=(0, 0, 1), caster=True)
    add_light(scene, "Point", "POINT", (0, 0, 4), energy=1000.0, shadow_soft_size=0.05,
              use_soft_falloff=False)
    # a sun's light travels along its local -Z; rotating +30 deg about Y tilts it towards -x
    add_light(scene, "Sun", "SUN", (0, 0, 10), (0, math.radians(30), 0), energy=3.0,
              angle=math.radians(0.5))
    add_camera(scene, (0, 0, 0.9), (0, 0, 0), ortho_scale=2.0)
    save(out / "water.blend")


def _tiled_floor(scene, n=8, size=4.0):
    """A floor of n x n tiles over size x size m, two materials in a checker, a caustics receiver."""
    tile_a = material("TileLight", "diffuse", (0.8, 0.8, 0.8))
    tile_b = material("TileDark", "diffuse", (0.3, 0.45, 0.6))
    v, f = grid(size, size, n, n)
    me = bpy.data.meshes.new("PoolFloor")
    me.from_pydata(v, [], f)
    me.materials.append(tile_a)
    me.materials.append(tile_b)
    for p in me.polygons:
        i, j = p.index % n, p.index // n
        p.material_index = (i + j) % 2
    floor = bpy.data.objects.new("PoolFloor", me)
    floor.cycles.is_caustics_receiver = True
    scene.collection.objects.link(floor)
    return floor


def build_pool(out):
    scene = reset()
    scene.name = "Pool"
    render_settings(scene, 160, 120)
    black_world(scene)
    _tiled_floor(scene)
    water = material("Water", "glass", (1.0, 1.0, 1.0), roughness=0.0, ior=1.33)

    def wave(x, y):
        return 0.03 * math.sin(3.1 * x + 0.4) * math.cos(2.3 * y) + 0.02 * math.sin(4.7 * (x + y))

    v, f = grid(4, 4, 64, 64, wave)
    mesh_object(scene, "WaterSurface", v, f, water, smooth=True, location=(0, 0, 0.6), caster=True)
    add_light(scene, "Sun", "SUN", (0, 0, 10), (math.radians(10), math.radians(15), 0), energy=4.0,
              angle=math.radians(0.5))
    add_camera(scene, (0, -3.2, 3.0), (0, 0, 0), lens=35)
    save(out / "pool.blend")


def build_waves(out):
    """pool.blend's floor and sun under water made the way artists make it: one flat quad whose Glass
    BSDF's Normal is a Bump node over a Noise Texture. The export has Cycles bake the Bump's Height on a
    finer copy of the quad and bends its normals as Cycles' Bump node does (smbs_addon/bump.py)."""
    scene = reset()
    scene.name = "Waves"
    render_settings(scene, 160, 120)
    black_world(scene)
    _tiled_floor(scene)
    v, f = grid(4, 4)
    mesh_object(scene, "WaterSurface", v, f, bumped_glass("BumpedWater", 0.05, scale=10.0), location=(0, 0, 0.6),
                caster=True)
    add_light(scene, "Sun", "SUN", (0, 0, 10), (math.radians(10), math.radians(15), 0), energy=4.0,
              angle=math.radians(0.5))
    add_camera(scene, (0, -3.2, 3.0), (0, 0, 0), lens=35)
    save(out / "waves.blend")


def build_hdri_glass(out):
    """The glass ball resting on the floor under an HDRI (a 512 x 256 float image packed into the file:
    a pale sky and a warm sun of about 3 degrees, 40 degrees up, to the left) turned 120 degrees by a Mapping node:
    no lamp, the world is the light."""
    scene = _glass_ball_scene("HDRIGlass", 0.5)
    hdri_world(scene, hdri_image(512, 256, sun=(-0.74, 0.2, 0.643), sun_sigma=4.0, sun_peak=60.0, turn_deg=120.0),
               turn_deg=120.0)
    add_camera(scene, (0.4, -3.6, 2.4), (0, 0.2, 0.2), lens=45)
    save(out / "hdri_glass.blend")


def build_softbox(out):
    """The glass ball lit by a softbox as artists make one: a 1.2 x 0.8 m plane of an Emission shader
    (Strength 30, warm) up and to the side, turned towards the ball: a mesh light, no lamp."""
    scene = _glass_ball_scene("Softbox", 0.6)
    glow = bpy.data.materials.new("SoftboxGlow")
    nt = glow.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (1.0, 0.92, 0.8, 1.0)
    em.inputs["Strength"].default_value = 30.0
    nt.links.new(em.outputs[0], nt.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    v, f = grid(1.2, 0.8)
    mesh_object(scene, "Softbox", v, f, glow, location=(1.6, -0.6, 2.4),
                rotation=(math.radians(10), math.radians(-40), math.radians(-20)))
    add_camera(scene, (0, -4, 3), (0, 0, 0.3), lens=50)
    save(out / "softbox.blend")


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    out = Path(argv[0]).resolve() if argv else HERE
    out.mkdir(parents=True, exist_ok=True)
    build_mirror(out)
    build_glass_sphere(out)
    build_glass_spot(out)
    build_water(out)
    build_pool(out)
    build_hdri_glass(out)
    build_waves(out)
    build_softbox(out)


if __name__ == "__main__":
    main()
