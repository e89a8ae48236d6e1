"""What the scene calls for: which lights, casters and receivers can make a
visible caustic, so that no work is spent on the rest.

Cycles' caustic flags (object ``is_caustics_caster`` / ``is_caustics_receiver``,
light ``is_caustics_light``) select the participants. Mode ``AUTO`` honours the
flags of a category (casters, receivers, lights) as soon as any member of it
is flagged, and takes every eligible member otherwise; ``ON`` always honours
them; ``OFF`` ignores them.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import scene as S
from .errors import SceneError
from .lights import light_covers


@dataclass
class LightPlan:
    index: int
    name: str
    targets: np.ndarray  # (K,4) caster bounding spheres this light can reach
    caster_objects: list


@dataclass
class Plan:
    casters: np.ndarray  # (O,) bool
    receivers: np.ndarray  # (O,) bool
    lights: list
    skipped: list = field(default_factory=list)  # (kind, name, reason)
    notes: list = field(default_factory=list)
    # lights that may light a diffuse surface whose light then meets a caster (caustic light
    # through more than one diffuse vertex, indirect.py): any planned light with power
    indirect_lights: list = field(default_factory=list)
    scene_sphere: np.ndarray = field(default_factory=lambda: np.zeros((1, 4)))  # (1,4) the whole scene


def _bounding_sphere(lo, hi, scene) -> np.ndarray:
    """(4,) centre and radius of the sphere around a box (never of radius 0)."""
    return np.concatenate([(lo + hi) / 2, [max(np.linalg.norm(hi - lo) / 2, 1e-9 * scene.scale)]])


def _use_flags(mode: str, flags: np.ndarray) -> bool:
    if mode == "ON":
        return True
    if mode == "OFF":
        return False
    if mode == "AUTO":
        return bool(flags.any())
    raise SceneError(f"use_cycles_flags must be AUTO, ON or OFF, not '{mode}'")


def make_plan(scene: S.Scene, flags: str = "AUTO") -> Plan:
    O = len(scene.object_names)
    kind = scene.mat_kind[scene.tri_material] if scene.n_tris else np.zeros(0, np.int32)
    specular_tri = (kind == S.CONDUCTOR) | (kind == S.DIELECTRIC)
    diffuse_tri = kind == S.DIFFUSE
    has_spec = np.bincount(scene.tri_object[specular_tri], minlength=O) > 0
    has_diff = np.bincount(scene.tri_object[diffuse_tri], minlength=O) > 0
    skipped = []

    casters = has_spec.copy()
    if _use_flags(flags, scene.object_caster):
        for o in np.flatnonzero(scene.object_caster & ~has_spec):
            skipped.append(("caster", scene.object_names[o],
                            "flagged as caustic caster but has no glossy or glass material"))
        for o in np.flatnonzero(has_spec & ~scene.object_caster):
            skipped.append(("caster", scene.object_names[o], "not flagged as caustic caster"))
        casters &= scene.object_caster
    receivers = has_diff.copy()
    if _use_flags(flags, scene.object_receiver):
        for o in np.flatnonzero(has_diff & ~scene.object_receiver):
            skipped.append(("receiver", scene.object_names[o], "not flagged as caustic receiver"))
        receivers &= scene.object_receiver

    if scene.n_lights == 0:
        raise SceneError(f"scene '{scene.name}' has no light: there is nothing to cast caustics")
    if not casters.any():
        raise SceneError(f"scene '{scene.name}' has no caustic caster: no object with a glossy "
                         "or glass material" + (" is flagged 'Cast Shadow Caustics'"
                                                if flags != "OFF" and scene.object_caster.any() else ""))
    if not receivers.any():
        raise SceneError(f"scene '{scene.name}' has no caustic receiver: no diffuse object"
                         + (" is flagged 'Receive Shadow Caustics'"
                            if flags != "OFF" and scene.object_receiver.any() else ""))

    spheres = {}
    for o in np.flatnonzero(casters):
        lo, hi = scene.object_bounds(o)
        spheres[o] = _bounding_sphere(lo, hi, scene)
    use_light_flags = _use_flags(flags, scene.light_caustics)
    lights = []
    indirect = []
    for li in range(scene.n_lights):
        name = scene.light_names[li]
        if use_light_flags and not scene.light_caustics[li]:
            skipped.append(("light", name, "not flagged 'Shadow Caustics'"))
            continue
        if not (scene.light_color[li].max() > 0):
            skipped.append(("light", name, "zero power"))
            continue
        if scene.light_type[li] == S.AREA and not (scene.light_size[li].min() > 0):
            skipped.append(("light", name, "zero size"))
            continue
        indirect.append(li)
        objs = [o for o, sp in spheres.items() if light_covers(scene, li, sp[:3], sp[3])]
        if not objs:
            skipped.append(("light", name, "reaches no caustic caster"))
            continue
        lights.append(LightPlan(li, name, np.array([spheres[o] for o in objs]), objs))
    if not lights:
        reasons = "; ".join(f"'{n}': {r}" for k, n, r in skipped if k == "light")
        raise SceneError(f"scene '{scene.name}': no light can cast caustics ({reasons})")
    sphere = _bounding_sphere(*scene.bounds(), scene)[None, :]
    return Plan(casters=casters, receivers=receivers, lights=lights, skipped=skipped, indirect_lights=indirect,
                scene_sphere=sphere)
