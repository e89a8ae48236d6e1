"""The world as the layer sees it (``add_world``): a constant Background's colour, or an
equirectangular Environment Texture's pixels (averaged down to WORLD_MAP_WIDTH) and the turn of a
Mapping node; anything else is black, warned (``world_unread`` names such a world for the policy)."""
from __future__ import annotations

import numpy as np

from ..scene import arrays as S
from .nodes import Unsupported, constant, follow, image_linear, is_linked, shader_node, uses_nodes
from .visibility import ray_visibility


def add_world(b, bpy_scene, warn):
    """The scene's world into SceneBuilder b: its colour (b.world_color) and, where it is lit and rays
    leaving mirrors or glass see it (_world_visibility), a light of the layer's: its light through
    mirrors and glass is a caustic too."""
    world, world_map, rotation = _world(bpy_scene, warn)
    b.world_color = world
    lit = world.max() > 0 and (world_map is None or world_map.max() > 0)
    if lit and _world_visibility(bpy_scene.world) & (S.RAY_GLOSSY | S.RAY_TRANSMISSION):
        w = bpy_scene.world
        b.world(world, name=w.name, caustics=bool(getattr(w.cycles, "is_caustics_light", False)),
                image=world_map, rotation=rotation, visibility=_world_visibility(w))


def _world(bpy_scene, warn, pixels=True):
    """The world as the layer sees it: (colour x strength, map, rotation). A constant Background
    gives its colour and no map; an Environment Texture (equirectangular) on its Color, fed the
    view direction or that direction through a Mapping node that turns it, gives the strength
    (as a colour), the image's linear pixels and the turn (Scene.world_map). Anything else is
    black, warned. pixels False: the map is not read (None), only whether it can be."""
    w = bpy_scene.world
    if w is None:
        return np.zeros(3), None, None
    if w.node_tree is None or not uses_nodes(w):
        return np.array(w.color[:3], float), None, None
    try:
        node = shader_node(w.node_tree, "OUTPUT_WORLD")
        if node is None:
            return np.zeros(3), None, None
        if node.type != "BACKGROUND":
            raise Unsupported(f"node '{node.name}' is not supported")
        strength = constant(node, "Strength")
        src = follow(node.inputs["Color"])
        if src is None or src[0].type != "TEX_ENVIRONMENT":
            return constant(node, "Color") * strength, None, None
        image, rotation = _environment(src[0], pixels, lambda message: warn(f"world '{w.name}': {message}"))
        return np.full(3, float(strength)), image, rotation
    except Unsupported as e:
        warn(f"world '{w.name}': {e}; world lighting treated as black")
        return np.zeros(3), None, None


def world_unread(bpy_scene):
    """The name of the scene's world when its node setup is one the layer cannot read (a Sky
    Texture, a node trick: black to the layer, with a warning at export), else None."""
    said = []
    _world(bpy_scene, said.append, pixels=False)
    return bpy_scene.world.name if said else None


def _environment(tex, pixels=True, warn=lambda message: None):
    """(linear pixels (H, W, 3) float32, rotation (3, 3)) of an Environment Texture node, its
    Vector the view direction or that direction through a Mapping node. Cycles looks the map up
    at R (S d) for a Mapping of type Point (no Location), Vector or Normal, at S^-1 R^-1 d for one
    of type Texture, and the lookup does not depend on the length: a uniform S drops out."""
    if tex.projection != "EQUIRECTANGULAR":
        raise Unsupported(f"node '{tex.name}': its {tex.projection.lower().replace('_', ' ')} projection is not "
                           "supported")
    rotation = np.eye(3)
    src = follow(tex.inputs["Vector"])
    if src is not None:
        mp = src[0]
        if mp.type != "MAPPING":
            raise Unsupported(f"node '{mp.name}' on the Environment Texture's Vector is not supported")
        for name in ("Location", "Rotation", "Scale"):
            if name in mp.inputs and is_linked(mp, name):
                raise Unsupported(f"node '{mp.name}': a linked {name} is not supported")
        scale = np.array(mp.inputs["Scale"].default_value[:], float) if "Scale" in mp.inputs else np.ones(3)
        loc = np.array(mp.inputs["Location"].default_value[:], float) if "Location" in mp.inputs else np.zeros(3)
        if not (np.allclose(scale, scale[0]) and scale[0] > 0) or (mp.vector_type in ("POINT", "TEXTURE")
                                                                   and np.any(loc != 0)):
            raise Unsupported(f"node '{mp.name}': only a turn (no Location, the same positive Scale on every "
                               "axis) is supported")
        inner = follow(mp.inputs["Vector"])
        if inner is not None and not (inner[0].type == "TEX_COORD" and inner[1].name == "Generated"):
            raise Unsupported(f"node '{inner[0].name}' on the Mapping's Vector is not supported")
        if "Rotation" in mp.inputs:
            rotation = np.array(mp.inputs["Rotation"].default_value.to_matrix(), float)  # Euler XYZ
        if mp.vector_type == "TEXTURE":
            rotation = rotation.T
    image = image_linear(tex.image, MAX_WORLD_PIXELS, pixels)
    if image is None:
        raise Unsupported(f"node '{tex.name}': its image is missing or larger than {MAX_WORLD_PIXELS} pixels")
    if not pixels:
        return None, rotation
    bad = ~(np.isfinite(image) & (image >= 0))
    if bad.any():  # an HDRI's processing can leave a few (a colour space's conversion)
        image = np.where(bad, np.float32(0.0), image)
        warn(f"image '{tex.image.name}': {int(bad.any(axis=2).sum())} pixels negative or not a number, taken as "
             "black")
    return _averaged_down(image, WORLD_MAP_WIDTH), rotation


MAX_WORLD_PIXELS = 8192 * 4096  # an 8K HDRI: read once (0.5 GB for a moment), then averaged down
WORLD_MAP_WIDTH = 2048  # the layer's map of the world is at most this wide (a sun of 0.5 deg: 3 pixels)


def _averaged_down(image, width):
    """An equirectangular map averaged over blocks to at most `width` pixels across (and the
    height in proportion): the same light, in as many pixels as a caustic needs."""
    h, w = image.shape[:2]
    if w <= width:
        return image
    cols = np.linspace(0, w, width + 1).round().astype(np.int64)
    rows = np.linspace(0, h, max(1, round(h * width / w)) + 1).round().astype(np.int64)
    summed = np.add.reduceat(np.add.reduceat(image.astype(np.float64), rows[:-1], axis=0), cols[:-1], axis=1)
    return (summed / np.outer(np.diff(rows), np.diff(cols))[..., None]).astype(np.float32)


def _world_visibility(w) -> int:
    """The rays that see the world (World > Settings > Ray Visibility) as S.RAY_* bits: a caustic's
    last segment is a ray leaving a mirror (glossy) or glass (transmission); seen by neither, the world
    lights no caustic (Cycles' does not either)."""
    vis = getattr(w, "cycles_visibility", None)
    return S.RAY_ALL if vis is None else ray_visibility(vis, prefix="") | S.RAY_SHADOW
