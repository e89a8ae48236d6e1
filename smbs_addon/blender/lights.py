"""Light objects -> the builder's lights with Cycles' conventions: power from energy, exposure and
normalisation, colour from temperature and an Emission node, point / spot / area / sun shapes, the
light's Ray Visibility; portals and unsupported types are skipped, warned."""
from __future__ import annotations

import math

import numpy as np

from ..scene import arrays as S
from .camera import orthonormal
from .nodes import Unsupported, constant, shader_node
from .visibility import ray_visibility


def _axis_scale(m: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.asarray(m, float)[:3, :3], axis=0)


def _light_node_factor(light, warn):
    """Colour factor from a light's node tree (Emission node) if it uses nodes."""
    if not getattr(light, "use_nodes", False) or light.node_tree is None:  # not deprecated
        return np.ones(3)
    try:
        node = shader_node(light.node_tree, "OUTPUT_LIGHT")
        if node is None:
            return np.zeros(3)
        if node.type != "EMISSION":
            raise Unsupported(f"node '{node.name}' is not supported")
        return constant(node, "Color") * constant(node, "Strength")
    except Unsupported as e:
        warn(f"light '{light.name}': {e}; its node tree is ignored")
        return np.ones(3)


def export_light(b, name, ob, M, warn):
    lt = ob.data
    orig = lt.original if getattr(lt, "original", None) is not None else lt
    color = np.array(lt.color[:3], float)
    if getattr(lt, "use_temperature", False):
        color = color * np.array(lt.temperature_color[:3], float)
    power = float(lt.energy) * 2.0 ** float(getattr(lt, "exposure", 0.0))
    color = color * _light_node_factor(lt, warn)
    normalize = bool(getattr(lt, "normalize", True))
    caustics = bool(orig.cycles.is_caustics_light)
    Mn = orthonormal(M)
    sc = _axis_scale(M)
    kw = dict(matrix=Mn, color=color, caustics=caustics)
    if lt.type in ("POINT", "SPOT"):
        r = float(lt.shadow_soft_size)
        if not normalize:  # Cycles divides by the sphere area (4 if r = 0) only when normalised
            power *= 4.0 * math.pi * r * r if r > 0 else 4.0
        kw.update(radius=r, soft_falloff=bool(lt.use_soft_falloff))
        if lt.type == "SPOT":
            kw.update(spot_size=float(lt.spot_size), spot_blend=float(lt.spot_blend))
            if abs(sc[0] - sc[1]) > 1e-6 * max(sc[0], sc[1]):
                warn(f"light '{name}': non-uniform scale of a spot cone is ignored")
    elif lt.type == "AREA":
        shape = lt.shape
        sx = float(lt.size)
        sy = float(lt.size_y) if shape in ("RECTANGLE", "ELLIPSE") else sx
        sx, sy = sx * sc[0], sy * sc[1]
        if abs(sx - sy) > 1e-6 * max(sx, sy):  # unequal scale: Cycles stretches the shape
            shape = {"SQUARE": "RECTANGLE", "DISK": "ELLIPSE"}.get(shape, shape)
        else:
            sy = sx if shape in ("SQUARE", "DISK") else sy
        if not normalize:
            power *= sx * sy * (math.pi / 4 if shape in ("DISK", "ELLIPSE") else 1.0)
        kw.update(shape=shape, size=(sx, sy), spread=float(lt.spread))
        if getattr(orig.cycles, "is_portal", False):
            warn(f"light '{name}': portal lights are skipped")
            return
    elif lt.type == "SUN":
        ang = float(lt.angle)
        if not normalize:
            power *= math.pi * math.sin(ang / 2) ** 2 if ang > 0 else 1.0
        kw.update(angle=ang)
    else:
        warn(f"light '{name}': type {lt.type} is not supported; skipped")
        return
    # a light's Ray Visibility (its object's): which rays leaving a mirror or glass (or a diffuse
    # surface, for light that bounces before it meets a caster) see it; camera and shadow rays are in no
    # caustic path of the layer's (the bits stay on)
    b.light(name, lt.type, power=power, visibility=ray_visibility(ob) & S.PATH_RAYS | S.RAY_CAMERA | S.RAY_SHADOW,
            **kw)
