"""Scenes of issue 58 (frames, the farm, a layer that stands on its own), built with the bpy module:
the animated sample at a test's size, and a lens over a checker floor."""
from __future__ import annotations

from pathlib import Path

import bpy

from testkit import ROOT
from testkit import blend as B
from testkit import conformance_scenes as C

MOVING_LIGHT = ROOT / "sample_blends" / "moving_light.blend"
MIRROR = ROOT / "sample_blends" / "mirror.blend"


def small_moving_light(path, percentage: int = 25, frames: tuple | None = None) -> Path:
    """sample_blends/moving_light.blend at percentage of its 160 x 120 (25: 40 x 30), saved to path (the
    scene's frame range frames=(first, last) if given)."""
    bpy.ops.wm.open_mainfile(filepath=str(MOVING_LIGHT), load_ui=False)
    sc = bpy.context.scene
    sc.render.resolution_percentage = percentage
    if frames:
        sc.frame_start, sc.frame_end = frames
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return Path(path)


def small_turning_mirror(path, percentage: int = 25) -> Path:
    """sample_blends/mirror.blend at percentage of its 160 x 120, its mirror turning from 157.5 to 150
    degrees about Y over frames 1-24 (linear keys): the caustic, seen directly on the floor, slides
    across it. A scene the light tracer bakes without heavy tails (no caustic is seen through glass)."""
    import math

    bpy.ops.wm.open_mainfile(filepath=str(MIRROR), load_ui=False)
    sc = bpy.context.scene
    sc.render.resolution_percentage = percentage
    B.keys_linear(bpy.data.objects["Mirror"], "rotation_euler", {1: (0.0, math.radians(157.5), 0.0),
                                                                24: (0.0, math.radians(150.0), 0.0)})
    sc.frame_start, sc.frame_end, sc.frame_current = 1, 24, 1
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return Path(path)


def _checker_material(scale=40.0):
    """conformance_scenes' checker (warm 0.8/0.7/0.5 and dark blue) at scale: squares of 10 m / scale."""
    m = C._checker()
    m.node_tree.nodes["Checker Texture"].inputs["Scale"].default_value = scale
    return m


def lens_checker():
    """The conformance suite's lens_area (a biconvex Glass BSDF lens, IOR 1.5, 1.6 m above the floor, a
    0.4 m square light) over a floor of Blender's default material with a Checker Texture of 0.25 m
    squares on its Base Color, the camera close on the caustic's disc (about 0.35 m across), which falls
    across several squares, warm and blue."""
    scene = C._scene("lens_checker")
    v, f = B.grid(10.0, 10.0)
    B.mesh_object(scene, "Floor", v, f, _checker_material(), receiver=True)
    glass = B.material("LensGlass", "glass", (1.0, 1.0, 1.0), ior=1.5)
    v, f = C._lens(1.2, 0.5, 0.01)
    B.mesh_object(scene, "Lens", v, f, glass, smooth=True, location=(0, 0, 1.6), caster=True)
    B.add_light(scene, "Key", "AREA", (0.3, 0.2, 4.0), energy=150.0, shape="SQUARE", size=0.4)
    B.add_camera(scene, (0, -4.0, 3.2), (-0.2, -0.13, 0.0), lens=110)  # framing the caustic's disc
    return scene


def build_lens_checker(folder) -> Path:
    lens_checker()
    path = Path(folder) / "lens_checker.blend"
    B.save(path)
    return path
