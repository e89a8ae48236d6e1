"""SMBS Caustics render core: numpy arrays in, numpy arrays out.

Public API::

    from smbs_addon import Scene, BakeSettings, bake
    scene = Scene.load("scene.npz")
    result = bake(scene, BakeSettings(method="reference", spp=16, seed=1))
    result.image, result.variance, result.stats

Nothing here imports bpy; only ``export`` (bpy -> Scene) and ``composite``
(image -> Blender) do, and they are imported on demand.
"""
from .baking.result import BakeResult
from .baking.settings import BakeSettings
from .baking.bake import bake
from .core.errors import BakeCancelled, SceneError
from .scene.arrays import Camera, Scene
from .core.version import VERSION as __version__

__all__ = ["Scene", "Camera", "BakeSettings", "BakeResult", "bake", "SceneError", "BakeCancelled"]
