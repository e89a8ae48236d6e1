"""Nothing counted twice: who renders which caustic, the layer or Cycles.

The layer holds every path camera -> (mirror or glass)* -> diffuse -> (mirror or
glass)+ -> light for the casters, receivers and lights of the bake's plan.
Cycles renders the same paths itself unless its Light Paths > Caustics switches
(``caustics_reflective``, ``caustics_refractive``) are off; with them off it
drops glossy and transmission after a diffuse bounce, which also switches its
shadow caustics (MNEE) off. Those switches are global, so:

- the plan covers every caster, receiver and light of the scene (a world of
  constant colour is one of its lights, an object with an emitting material a mesh
  light; a world too faint to show through mirrors and glass is named as dropped
  instead, see coverage): a bake turns both switches off,
  remembering how they were; Remove Caustic Layer puts them back;
- otherwise Cycles is left as it is, and the note says what is counted where.

The user's caster / receiver / light flags are never changed.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


# A world of constant colour whose caustic can be at most this share of the layer's (its mean over
# the caustic region) does not keep Cycles' caustics on: see coverage
WORLD_NEGLIGIBLE = 0.01


@dataclass
class Coverage:
    covered: bool
    casters: list = field(default_factory=list)  # names in the layer
    receivers: list = field(default_factory=list)
    lights: list = field(default_factory=list)
    left_to_cycles: list = field(default_factory=list)  # what only Cycles renders, with why
    dropped: list = field(default_factory=list)  # what neither renders once Cycles' are off, too faint to see
    unread: list = field(default_factory=list)  # what neither renders once Cycles' are off: the layer cannot read it
    nothing: str | None = None  # the bake had nothing to bake (why): the layer is empty, Cycles is left alone


def _names(names, mask):
    return [names[i] for i in np.flatnonzero(mask)]


def _short(names, most=4):
    quoted = [f"'{n}'" for n in names]
    return ", ".join(quoted) if len(quoted) <= most else ", ".join(quoted[:most]) + f" and {len(quoted) - most} more"


def coverage(data, plan, flags_mode: str, blender_lights=(), layer_mean=None, skipped=(),
             world_unread=None, nothing=None) -> Coverage:
    """What the layer covers, from the exported scene ``data`` and its ``plan``.

    blender_lights: (name, is_portal) of the scene's renderable light objects,
    to find lights the export could not represent. layer_mean: the bake's mean over its
    caustic region (stats["noise"]["mean"]), to judge a world the bake left out (_world).
    skipped: what the bake skipped (stats["skipped"], dicts of kind, name and reason), from its
    traced plan: a world its pilots found too faint is dropped, not a light of the layer.
    world_unread: the name of a world whose node setup the export could not read (black to the
    layer): its caustics are named as rendered by neither once Cycles' are off, as before the
    layer had a world light (keeping Cycles' on for it would count every lamp's caustic twice).
    nothing: the bake's nothing_to_bake (why its layer is empty): nothing is counted twice, and
    Cycles is left as it is.

    A caster or receiver is left to Cycles only where Cycles' flags leave it out of the layer (the
    flags in use, the object not flagged): one out of the plan for another reason (no light reaches
    it, diffuse rays do not see it, no light at all) has no caustic in Cycles either.
    """
    from ..smbs_addon.scene import arrays as S
    from ..smbs_addon.baking.plan import FAINT

    O = len(data.object_names)
    kind = data.mat_kind[data.tri_material] if data.n_tris else np.zeros(0, np.int32)
    has_spec = np.bincount(data.tri_object[(kind == S.CONDUCTOR) | (kind == S.DIELECTRIC)], minlength=O) > 0
    has_diff = np.bincount(data.tri_object[kind == S.DIFFUSE], minlength=O) > 0
    if nothing:
        return Coverage(covered=False, nothing=nothing)
    left = []
    if flags_mode == "ON" or (flags_mode == "AUTO" and bool(np.any(data.object_caster))):
        for name in _names(data.object_names, has_spec & ~data.object_caster.astype(bool)):
            left.append(f"caster '{name}' (not flagged Cast Shadow Caustics)")
    if flags_mode == "ON" or (flags_mode == "AUTO" and bool(np.any(data.object_receiver))):
        for name in _names(data.object_names, has_diff & ~data.object_receiver.astype(bool)):
            left.append(f"receiver '{name}' (not flagged Receive Shadow Caustics)")

    faint = {x["name"]: x["reason"] for x in skipped if x["kind"] == "light" and x["reason"].startswith(FAINT)}
    planned = {lp.index for lp in plan.lights} | set(plan.indirect_lights)
    light_flags_used = flags_mode == "ON" or (flags_mode == "AUTO" and bool(np.any(data.caustic_flags())))
    dropped = []
    for li, name in enumerate(data.light_names):
        if (li in planned and name not in faint) or not (data.light_color[li].max() > 0):
            continue  # in the layer, or dark
        if data.light_type[li] == S.WORLD:
            if name in faint or light_flags_used:
                _world(data, li, faint.get(name), layer_mean, left, dropped)
            continue  # otherwise its caustic lands on nothing the camera sees
        if light_flags_used and not data.light_caustics[li]:
            left.append(f"light '{name}' (not flagged Shadow Caustics)")
        # a lit light outside the plan otherwise reaches no caster: it makes no caustic
    exported = set(data.light_names)
    for name, portal in blender_lights:
        if portal:
            continue
        if not any(e == name or e.endswith("/" + name) or e.startswith(name + ".") for e in exported):
            left.append(f"light '{name}' (a kind the layer cannot bake)")


    return Coverage(covered=not left,
                    casters=_names(data.object_names, plan.casters),
                    receivers=_names(data.object_names, plan.receivers),
                    lights=[lp.name for lp in plan.lights if lp.name not in faint],
                    left_to_cycles=left, dropped=dropped,
                    unread=[] if world_unread is None else [f"world '{world_unread}' through mirrors and glass"])


def _world(data, li, faint, layer_mean, left, dropped):
    """coverage's words for a world (a light of the layer, S.WORLD) the bake left out: too faint
    by the plan's pilots (faint: the plan's reason), or not flagged. An unflagged world makes no
    caustic brighter than its radiance L (a map's brightest pixel's) x the brightest diffuse
    colour (radiance is conserved along mirrors and glass, so a receiver lit by the whole sky
    through them sends at most that); where that is at most WORLD_NEGLIGIBLE of layer_mean
    (Blender's default grey world under a lamp), it is dropped rather than keeping Cycles'
    caustics on, which would count the layer's twice."""
    from ..smbs_addon.scene import arrays as S
    from ..smbs_addon.baking.plan import FAINT

    name = data.light_names[li]
    if faint is not None:  # "its caustic is too faint to show (at most 0.4% of the lamps' caustic)"
        dropped.append(f"world '{name}' through mirrors and glass ({faint[len(FAINT):].strip(' ()')})")
        return
    diffuse = data.mat_color[data.mat_kind == S.DIFFUSE]
    peak = float(data.light_color[li].max()) * (float(data.world_map.max()) if data.world_map.size else 1.0)
    bound = peak * float(np.max(diffuse, initial=0.0))
    if layer_mean is not None and layer_mean > 0 and bound <= WORLD_NEGLIGIBLE * layer_mean:
        dropped.append(f"world '{name}' through mirrors and glass (at most {bound / layer_mean:.1%} of the "
                       "layer's caustic)")
    else:
        left.append(f"world '{name}' (not flagged Shadow Caustics)")


def mnee_active(bpy_scene) -> bool:
    """Does Cycles switch on its shadow caustics (a flagged caster, receiver and light)?"""
    obs = [ob for ob in bpy_scene.objects if not ob.hide_render]
    caster = any(ob.cycles.is_caustics_caster for ob in obs if ob.type != 'LIGHT')
    receiver = any(ob.cycles.is_caustics_receiver for ob in obs if ob.type != 'LIGHT')
    world = bpy_scene.world
    light = any(ob.data.cycles.is_caustics_light for ob in obs if ob.type == 'LIGHT') or bool(
        world is not None and getattr(world.cycles, "is_caustics_light", False))
    return caster and receiver and light


def _switches(bpy_scene):
    c = bpy_scene.cycles
    return bool(c.caustics_reflective), bool(c.caustics_refractive)


def restore_cycles(bpy_scene, props) -> bool:
    """Put Cycles' caustic switches back as they were before a bake turned them off."""
    if not props.cycles_kept_out:
        return False
    c = bpy_scene.cycles
    c.caustics_reflective = props.saved_caustics_reflective
    c.caustics_refractive = props.saved_caustics_refractive
    props.cycles_kept_out = False
    return True


def update_cycles(bpy_scene, props, cov: Coverage) -> tuple[bool, list[str]]:
    """Apply the policy after a bake. Returns (Cycles' caustics are off, note lines).

    The lines are also stored in ``props.cycles_note`` for the panel.
    """
    layer = (f"The layer holds the caustics of {_short(cov.casters)} on {_short(cov.receivers)} "
             f"from {_short(cov.lights)}.")
    if cov.nothing:
        restore_cycles(bpy_scene, props)
        lines = [f"The layer is empty (nothing to bake: {cov.nothing}).",
                 "Cycles' own caustics are left as they are."]
        props.cycles_note = "\n".join(lines)
        return False, lines
    if cov.covered and props.keep_out_of_cycles:
        if not props.cycles_kept_out:  # remember the user's switches once, before the first change
            props.saved_caustics_reflective, props.saved_caustics_refractive = _switches(bpy_scene)
            props.cycles_kept_out = True
        bpy_scene.cycles.caustics_reflective = False
        bpy_scene.cycles.caustics_refractive = False
        lines = [layer,
                 "Cycles' own caustics are off (Light Paths > Caustics), so none is counted twice. "
                 "Remove Caustic Layer turns them back on.",
                 "Neither renders light that meets mirrors or glass after a diffuse bounce and then "
                 "lights another diffuse surface (diffuse light through mirrors and glass)."]
        if cov.dropped:
            lines.append("Too faint to see, rendered by neither: " + "; ".join(cov.dropped) + ".")
        if cov.unread:
            lines.append("A node setup the layer cannot read (see the warnings), rendered by neither: "
                         + "; ".join(cov.unread) + ".")
        kept_out = True
    else:
        restore_cycles(bpy_scene, props)
        refl, refr = _switches(bpy_scene)
        lines = [layer]
        if cov.left_to_cycles:
            lines.append("Only Cycles renders the caustics of: " + "; ".join(cov.left_to_cycles) + ".")
        if not (refl or refr):
            if cov.left_to_cycles:
                lines.append("Cycles' own caustics are off (Light Paths > Caustics), so those are "
                             "rendered by neither.")
        elif mnee_active(bpy_scene):
            lines.append("Cycles' shadow caustics (MNEE) are on: Cycles also renders the refractive "
                         "caustics of flagged glass on flagged receivers (counted twice with the layer) "
                         "and drops its path-traced caustics of flagged casters.")
        else:
            lines.append("Cycles' own caustics are on: it also path traces the caustics of the layer's "
                         "casters (counted twice).")
        if refl or refr:
            if not props.keep_out_of_cycles:
                lines.append("Keep Out of Cycles is off: Cycles' caustic switches are left alone.")
            elif cov.left_to_cycles:
                lines.append("To keep the layer's paths out of Cycles, let the bake cover everything "
                             "above (flag it, or set Cycles Flags to Off).")
        kept_out = False
    props.cycles_note = "\n".join(lines)
    return kept_out, lines
