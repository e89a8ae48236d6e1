"""The two pools of issue 61, the caustic users ask for most: wavy water over a diffuse floor, seen
from above through the water, at 160 x 120, lit by

- ``pool_sun`` : a sun of 4 degrees (strength 3), pool_sun4's water, floor, sun and camera;
- ``pool_hdri``: an environment image alone, a dim sky and a bright disc of 5 degrees (its
  irradiance at normal incidence 3, as the sun's) where pool_sun's sun is.

Both are conformance scenes (testkit/conformance_scenes.py registers them): ``scene_arrays`` exports
them, ``tools/conformance.py reference`` renders their Cycles references. The environment image is
made in numpy (``sky_image``) and written with OpenImageIO (``write_sky``) beside the .blend, then
packed into it.
"""
from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np

WIDTH, HEIGHT = 160, 120
SUN_STRENGTH = 3.0  # W/m^2 at normal incidence, the sun's and the disc's
DISC_DEG = 5.0  # the disc's angular diameter
SKY = (0.05, 0.065, 0.09)  # the dim sky's radiance (x1.5 at the horizon)


def sun_direction():
    """The unit direction towards pool_sun4's sun (its object turned (20, 10, 0) deg, XYZ Euler)."""
    ax, ay = math.radians(20.0), math.radians(10.0)
    d = np.array([0.0, -math.sin(ax), math.cos(ax)])
    return np.array([d[0] * math.cos(ay) + d[2] * math.sin(ay), d[1], -d[0] * math.sin(ay) + d[2] * math.cos(ay)])


def sky_image(width=1024, height=512, direction=None, disc_deg=DISC_DEG, strength=SUN_STRENGTH, sub=4):
    """(height, width, 3) float32, top row first: an equirectangular environment of a dim sky (SKY,
    brighter towards the horizon) and a uniform disc of angular diameter disc_deg around direction
    (default sun_direction) whose irradiance at normal incidence is strength. Cycles' lookup of a
    world direction m: u = 0.5 - atan2(m_y, m_x) / 2 pi, v = acos(m_z) / pi from the top. The disc's
    edge pixels hold their covered share (sub x sub points per pixel)."""
    d = sun_direction() if direction is None else np.asarray(direction, float)
    d = d / np.linalg.norm(d)
    r = math.radians(0.5 * disc_deg)
    radiance = strength / (2 * math.pi * (1 - math.cos(r)))
    jj, ii = np.mgrid[0:height * sub, 0:width * sub]
    u = (ii + 0.5) / (width * sub)
    v = (jj + 0.5) / (height * sub)
    phi = 2 * math.pi * (0.5 - u)
    theta = math.pi * v
    m = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=-1)
    inside = (m @ d) >= math.cos(r)
    cover = inside.reshape(height, sub, width, sub).mean(axis=(1, 3))
    vv = (np.arange(height) + 0.5) / height
    horizon = 1.0 + 0.5 * (1.0 - np.abs(vv - 0.5) * 2)
    img = np.empty((height, width, 3), np.float32)
    for c in range(3):
        img[..., c] = SKY[c] * horizon[:, None] * (1 - cover) + radiance * cover
    return img


def write_sky(path, img):
    """img (top row first) as a float EXR at path, with OpenImageIO."""
    import OpenImageIO as oiio

    out = oiio.ImageOutput.create(str(path))
    if out is None:
        raise RuntimeError(f"cannot write {path}: {oiio.geterror()}")
    out.open(str(path), oiio.ImageSpec(img.shape[1], img.shape[0], 3, oiio.FLOAT))
    out.write_image(np.ascontiguousarray(img, np.float32))
    out.close()


def _pool_common(name):
    """pool_sun4's floor, water and camera at 160 x 120, and no light yet."""
    from testkit import blend as B
    from testkit import conformance_scenes as C

    scene = B.reset()
    scene.name = name
    B.render_settings(scene, WIDTH, HEIGHT)
    B.black_world(scene)
    C._floor(scene, size=8.0)
    water = B.material("Water", "glass", (1.0, 1.0, 1.0), ior=1.33)
    v, f = B.grid(6, 6, 120, 120, C._water_wave)
    B.mesh_object(scene, "Water", v, f, water, smooth=True, location=(0, 0, 1.0), caster=True)
    B.add_camera(scene, (0, 0, 6), (0, 0, 0), lens=80)
    return scene


def pool_sun():
    """pool_sun4 at 160 x 120: wavy water (Glass BSDF 1.33) 1 m over a diffuse floor, a sun of 4 deg."""
    from testkit import blend as B

    scene = _pool_common("pool_sun")
    B.add_light(scene, "Sun", "SUN", (0, 0, 10), (math.radians(20), math.radians(10), 0), energy=SUN_STRENGTH,
                angle=math.radians(4.0))
    return scene


def pool_hdri():
    """pool_sun's water, floor and camera lit by an environment image alone: a dim sky and a disc of
    5 deg where pool_sun's sun is (sky_image), the world flagged for Cycles' shadow caustics."""
    import bpy

    from testkit import blend as B

    scene = _pool_common("pool_hdri")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "pool_sky.exr"
        write_sky(path, sky_image())
        img = bpy.data.images.load(str(path))
        img.pack()
    B.hdri_world(scene, img)
    scene.world.cycles.is_caustics_light = True
    return scene
