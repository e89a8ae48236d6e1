"""A world's Environment Texture in two parts, each baked the way it is cheap (issue 61): the bright,
compact part (a sun's disc in a sky) for the walks, the rest (the sky: dim and broad) for path tracing
from the receivers.

Why: under water the sky's light reaches the floor along directions near the water's folds, where a
walk's solution is rare and its contribution huge (pool_hdri at 64 spp: the sky held 10% of the light
the walks brought and 79% of their variance, and MNEE, which finds one solution, left out 46% of it),
while a cosine bounce from the floor that leaves through the water meets the sky at once, its
radiance bounded. A sun's disc is the other way round: the walks find it, a bounce almost never. The
caustic layer is linear in the light, so the two parts' layers add up to the world's, each part
complete: a bake walks the scene with the bright part alone and path-traces the one with the rest.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..scene import arrays as S
from .lights import env_map

# a pixel of the map brighter than this many times the map's mean radiance (its power over the
# sphere / 4 pi) is the walks': a sun's disc (pool_hdri: 1,500x) and what a cosine bounce would meet
# too rarely; a dim sky (pool_hdri: under 0.4x) and clouds are path-traced
BRIGHT_CONTRAST = 10.0
# each part holds at least this share of the map's power, or the world is not split (a map all sky
# or all sun is baked as one part, by the walks as before)
MIN_PART_SHARE = 0.01


@dataclass(frozen=True)
class WorldParts:
    """A world light's map in two parts: the scene lit by each, the same in all else."""

    light: int  # the world light's index
    walked: object  # scene.arrays.Scene with the map's bright part alone (the rest black)
    traced: object  # ... with the rest alone (the bright part black)
    bright_share: float  # the bright part's share of the map's power (luminance x solid angle)
    solid_angle: float  # the bright part's solid angle, steradians

    def words(self, name: str) -> str:
        """What the plan says of the split."""
        deg = math.degrees(2.0 * math.acos(max(-1.0, 1.0 - self.solid_angle / (2.0 * math.pi))))
        return (f"{name}: its map's bright part ({self.solid_angle:.3g} sr, a disc of {deg:.2g} deg; "
                f"{self.bright_share:.0%} of its light) by the walks, the rest ({1 - self.bright_share:.0%}, "
                f"a sky) traced from the receivers")


def bright_pixels(scene, li: int) -> np.ndarray | None:
    """(H, W) bool: the pixels of world light li's map brighter than BRIGHT_CONTRAST times its mean
    radiance; None where li has no map or the map is black."""
    env = env_map(scene, li)
    if env is None or env.power <= 0:
        return None
    mean_radiance = env.power / (4.0 * math.pi)
    return env.image.mean(axis=2) > BRIGHT_CONTRAST * mean_radiance


def split_world(scene) -> WorldParts | None:
    """The scene's world light's map split (WorldParts), where its bright part and the rest each hold
    at least MIN_PART_SHARE of its power; else None (no world with a map, or one part all of it)."""
    worlds = np.flatnonzero(np.asarray(scene.light_type) == S.WORLD)
    if len(worlds) != 1:
        return None
    li = int(worlds[0])
    bright = bright_pixels(scene, li)
    if bright is None:
        return None
    env = env_map(scene, li)
    share = float(env.p.reshape(bright.shape)[bright].sum())  # EnvMap.p: each pixel's share of the power
    if not (MIN_PART_SHARE <= share <= 1.0 - MIN_PART_SHARE):
        return None
    m = np.asarray(scene.world_map)
    zero = np.zeros((), m.dtype)
    walked = dataclasses.replace(scene, world_map=np.where(bright[..., None], m, zero))
    traced = dataclasses.replace(scene, world_map=np.where(bright[..., None], zero, m))
    solid = float(np.broadcast_to(env.omega[:, None], bright.shape)[bright].sum())
    return WorldParts(li, walked, traced, share, solid)
