"""Build the sample .blend scenes used by the tests and the Cycles references.

    python sample_blends/build.py [outdir]        (default: this folder)

Uses only the bpy data API (no operators besides the factory reset), so it runs
headless with the ``bpy`` module. Every scene is set up for comparing against
Cycles: caustic flags (caster / receiver / caustics light), a black world, no
clamping, no Filter Glossy, no denoising, no adaptive sampling, enough bounces,
Blackman-Harris filter width 1.5. The helpers are the test-kit's (testkit/blend.py), which the
conformance scenes (testkit/conformance_scenes.py) build with too.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import bpy

from testkit.blend import (add_camera, add_light, black_world, bumped_glass, grid, hdri_image, hdri_world, keys_linear,
                           material, mesh_object, node_material, render_settings, reset, save, uv_sphere)

HERE = Path(__file__).resolve().parent


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
    glow = node_material("SoftboxGlow", "ShaderNodeEmission", (1.0, 0.92, 0.8), Strength=30.0)
    v, f = grid(1.2, 0.8)
    mesh_object(scene, "Softbox", v, f, glow, location=(1.6, -0.6, 2.4),
                rotation=(math.radians(10), math.radians(-40), math.radians(-20)))
    add_camera(scene, (0, -4, 3), (0, 0, 0.3), lens=50)
    save(out / "softbox.blend")


def build_moving_light(out):
    """The glass ball (resting 0.5 above the floor) under a small square light that crosses over it in
    24 frames, from 1.2 m to the left to 1.2 m to the right at 4 m (linear keys): the caustic slides
    across the floor the other way. The animated sample: frame ranges, the farm, flicker."""
    scene = _glass_ball_scene("MovingLight", 0.6)
    light = add_light(scene, "Light", "AREA", (-1.2, 0, 4), energy=200.0, shape="SQUARE", size=0.5, spread=math.pi)
    keys_linear(light, "location", {1: (-1.2, 0.0, 4.0), 24: (1.2, 0.0, 4.0)})
    scene.frame_start, scene.frame_end, scene.frame_current = 1, 24, 1
    add_camera(scene, (0, -4, 3), (0, 0, 0.3), lens=50)
    save(out / "moving_light.blend")


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
    build_moving_light(out)


if __name__ == "__main__":
    main()
