"""What the scene calls for: which lights, casters and receivers can make a
visible caustic, so that no work is spent on the rest.

Cycles' caustic flags (object ``is_caustics_caster`` / ``is_caustics_receiver``,
light ``is_caustics_light``) select the participants. Mode ``AUTO`` honours the
flags of a category (casters, receivers, lights) as soon as any member of it
is flagged, and takes every eligible member otherwise; ``ON`` always honours
them; ``OFF`` ignores them.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..core import lanes
from ..scene import arrays as S
from ..core.errors import SceneError
from ..shading.lights import area_light_shape, emit, env_map, light_axis, light_covers
from .pilot_sets import MET_PATHS, PLAN_MIN_SHARE, VIEW_PHOTONS, kept, share_max, topped_up
from .pilots import (
    PILOT_BOUNCES, PILOT_PHOTONS, PilotSetup, _bounce_pilot, _caster_pilot, _indirect_pilot, camera_look, caustic_irradiance,
    sample_share)
from ..core.random import PILOT_VIEW, light_key, stream


@dataclass
class LightPlan:
    index: int
    name: str
    targets: np.ndarray  # (K,4) caster bounding spheres this light can reach
    caster_objects: list
    caster_names: list = field(default_factory=list)
    key: int = 0  # random streams are keyed by the light's name, not its place in the list
    effects: list = field(default_factory=list)  # (caster, chain letters, receivers, share of pilots)


@dataclass
class Plan:
    casters: np.ndarray  # (O,) bool: casters some light's caustic reaches the camera through
    receivers: np.ndarray  # (O,) bool
    lights: list
    skipped: list = field(default_factory=list)  # (kind, name, reason)
    notes: list = field(default_factory=list)
    # lights that may light a diffuse surface whose light then meets a caster (caustic light
    # through more than one diffuse vertex, indirect.py): planned lights that reach a receiver
    indirect_lights: list = field(default_factory=list)
    scene_sphere: np.ndarray = field(default_factory=lambda: np.zeros((1, 4)))  # (1,4) what takes part
    nothing: str = ""  # why there is no caustic to bake (the layer is all zero), or ""
    flag_casters: np.ndarray | None = None  # (O,) bool: casters by material and flags (before pilots)
    scale: float = 1.0  # a length for tolerances: the diagonal of what takes part
    bounds: tuple = (np.zeros(3), np.zeros(3))  # (lo, hi) of what takes part
    seen: dict = field(default_factory=dict)  # receiver name -> "directly" / "through mirrors or glass"
    cost: dict = field(default_factory=dict)  # rays and seconds the plan took
    indirect_words: list = field(default_factory=list)  # light -> diffuse -> casters -> receivers
    bent: tuple | None = None  # indirect.bent_candidates (kept once found): triangles, cdf, guide
    # whether some pixel's ray meets a mirror or glass first (camera_sees); None: not known (the
    # plan was not traced, or its grid skipped pixels)
    specular_seen: bool | None = None
    # light index -> the share of a light's samples it gets (below 1 for a world whose caustic is
    # dim beside the lamps', sample_share): each estimator takes that share of its samples for the
    # light and weighs them up by as much, so the image's expectation is unchanged
    sample_share: dict = field(default_factory=dict)
    # (O,) bool: the objects whose mirror or glass some pixel's ray meets first (camera_look); None: not
    # known (the plan was not traced, or its grid skipped pixels)
    first_specular: np.ndarray | None = None
    # (O,) bool: casters the plan leaves out of the bake by what it traced (their caustic lands on nothing the
    # camera sees, or too little of it; and those make_plan was told to leave out): a path of the numpy
    # passes that meets one ends there (paths/gather.py, walks/guide._guide_part); None: none
    left_out: np.ndarray | None = None
    # caster name -> {"share_max": the most its left-out caustic can carry of the light the camera sees
    # (about 95%: refine_plan's pilots, the rule of three), "by": that per light, and per light after a
    # diffuse bounce}: the casters the traced plan leaves out
    dropped: dict = field(default_factory=dict)

    def words(self) -> list:
        """The plan in an artist's words, one line per light that bakes, then what is skipped."""
        if self.nothing:
            return [f"Nothing to bake: {self.nothing}. The caustic layer is all zero."]
        lines = []
        for lp in self.lights:
            for caster, shares, recv, flux in lp.effects:
                lines.append(f"{lp.name} -> {caster} ({_chains_words(shares)}) -> {', '.join(recv)}")
            if not lp.effects:  # planned by bounds only (no pilots)
                lines.append(f"{lp.name} -> {', '.join(lp.caster_names)}")
            if lp.index in self.sample_share:
                lines.append(f"{lp.name}: {self.sample_share[lp.index]:.0%} of the samples (its caustic is dim beside "
                             "the lamps', its noise in proportion)")
        lines += self.indirect_words
        lines += [f"{name} skipped: {reason}" for kind, name, reason in self.skipped]
        return lines + list(self.notes)


WORDS_MIN_SHARE = 0.01  # chain types carrying less of a caster's caustic are summed up as "rarer"


def _chains_words(shares: dict) -> str:
    """'refraction, 2 vertices' or 'refraction, 2 vertices 93%; reflection 5%; rarer paths 2%'."""
    order = sorted(shares, key=lambda t: (-shares[t], len(t), t))
    main = [t for t in order if shares[t] >= WORDS_MIN_SHARE] or order[:1]
    if len(main) == 1 and shares[main[0]] > 0.995:
        return describe_chain(main[0])
    parts = [f"{describe_chain(t)} {shares[t]:.0%}" for t in main]
    rest = sum(shares[t] for t in order if t not in main)
    if rest > 0:
        parts.append(f"rarer paths {rest:.0%}" if rest >= 0.005 else "rarer paths <1%")
    return "; ".join(parts)


def describe_chain(t: str) -> str:
    """R -> 'reflection', TT -> 'refraction, 2 vertices', TRT -> 'refraction, 3 vertices, 1 internal
    reflection', RR -> '2 reflections'."""
    k, r = len(t), t.count("R")
    if r == k:
        return "reflection" if k == 1 else f"{k} reflections"
    if r == 0:
        return "refraction" if k == 1 else f"refraction, {k} vertices"
    what = "internal reflection" if t[0] == "T" and t[-1] == "T" else "reflection"
    return f"refraction, {k} vertices, {r} {what}{'s' if r > 1 else ''}"


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


def _degenerate_axes(scene: S.Scene, li: int) -> bool:
    """Does light li's matrix lose an axis it needs: the direction (z) of a sun, spot or area
    light, and an area light's x and y, which span its surface?"""
    m = np.asarray(scene.light_matrix[li], float)[:3, :3]
    need = {S.SUN: (2,), S.SPOT: (2,), S.AREA: (0, 1, 2)}.get(int(scene.light_type[li]), ())
    scale = max(float(np.abs(m).max()), 1e-300)
    return any(not (np.linalg.norm(m[:, k]) > 1e-9 * scale) for k in need) or \
        (int(scene.light_type[li]) == S.AREA and S.flat_axes(m))


def make_plan(scene: S.Scene, flags: str = "AUTO", left_out=None) -> Plan:
    """The plan from materials, Cycles' flags and bounds alone (no tracing). A scene with
    nothing to bake (no light, caster or receiver) gives a plan whose ``nothing`` says why.
    left_out: (O,) bool, casters another plan of the scene left out (auto's pilot bakes: those
    of the bake they choose for), skipped here before any pilot."""
    casters, receivers, skipped, blind, flat = _participants(scene, flags, left_out)
    left_out = None if left_out is None else np.asarray(left_out, bool).copy()
    plan = Plan(casters=casters, receivers=receivers, lights=[], skipped=skipped, flag_casters=casters.copy(),
                left_out=left_out)
    plan.nothing = _nothing_takes_part(scene, plan, flags, blind, flat)
    if plan.nothing:
        return _finish(plan, scene)
    boxes = {o: scene.object_bounds(o) for o in np.flatnonzero(casters | receivers)}
    spheres = {o: _bounding_sphere(*boxes[o], scene) for o in np.flatnonzero(casters)}
    rec_objs = np.flatnonzero(receivers)
    rec_spheres = [_bounding_sphere(*boxes[o], scene) for o in rec_objs]
    use_light_flags = _use_flags(flags, scene.caustic_flags())  # a mesh light has none: it does not count
    for li in range(scene.n_lights):
        if use_light_flags and not scene.light_caustics[li]:
            skipped.append(("light", scene.light_names[li], "not flagged 'Shadow Caustics'"))
            continue
        _plan_light(scene, plan, li, (spheres, boxes), zip(rec_objs, rec_spheres))
    if not plan.lights and not plan.indirect_lights:  # (a light that lights a receiver may still light a caster)
        plan.nothing = _no_light(plan)
    if len(plan.lights) >= MANY_LIGHTS:
        plan.notes.append(f"{len(plan.lights)} lights take part: each light's caustic is traced on its own, so the "
                          f"bake costs about {len(plan.lights)} times one light's (a time or noise rule shares its "
                          f"time among them)")
    return _finish(plan, scene)


MANY_LIGHTS = 16  # from this many lights the plan says what they cost


def _participants(scene, flags, left_out=None):
    """(casters, receivers: (O,) bool, skipped: the objects left out and why, blind: the casters no
    diffuse ray sees, flat: the objects left out for having no area) from materials, Cycles' flags
    (as flags says), Ray Visibility and the objects' areas; left_out: casters left out before (make_plan)."""
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
    if left_out is not None:
        for o in np.flatnonzero(casters & left_out):
            skipped.append(("caster", scene.object_names[o], "left out by the bake's plan"))
        casters &= ~np.asarray(left_out, bool)
    blind = []
    for o in np.flatnonzero(casters):
        if not scene.object_seen_by(o, S.RAY_DIFFUSE):  # a receiver's bounce never meets it
            skipped.append(("caster", scene.object_names[o], "its Ray Visibility is off for diffuse rays: Cycles "
                                                             "shows no caustic of it"))
            casters[o] = False
            blind.append(scene.object_names[o])
    receivers = has_diff.copy()
    if _use_flags(flags, scene.object_receiver):
        for o in np.flatnonzero(has_diff & ~scene.object_receiver):
            skipped.append(("receiver", scene.object_names[o], "not flagged as caustic receiver"))
        receivers &= scene.object_receiver
    flat = []
    area = _object_areas(scene)
    for o in np.flatnonzero((casters | receivers) & ~(area > 0)):
        what = "caster" if casters[o] else "receiver"
        skipped.append((what, scene.object_names[o], "it has no area (its object is scaled to zero, or its faces are "
                                                     "degenerate), so it can neither bend nor catch light"))
        casters[o] = receivers[o] = False
        flat.append(scene.object_names[o])
    return casters, receivers, skipped, blind, flat


def _object_areas(scene) -> np.ndarray:
    """(O,) each object's surface area (0 for an object without triangles)."""
    v = np.asarray(scene.tri_vertices, float)
    if not len(v):
        return np.zeros(len(scene.object_names))
    tri = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
    return np.bincount(scene.tri_object, weights=tri, minlength=len(scene.object_names))


def _nothing_takes_part(scene, plan, flags, blind, flat=()) -> str | None:
    """Why nothing can be baked before any light is looked at (no light, caster, receiver, or a
    camera that sees nothing), or None."""
    if scene.n_lights == 0:
        return f"scene '{scene.name}' has no light"
    for what, has in (("caster", plan.casters), ("receiver", plan.receivers)):
        gone = [n for n in flat if any(k == what and s == n for k, s, _ in plan.skipped)]
        if not has.any() and gone:
            return (f"scene '{scene.name}' has no caustic {what}: {', '.join(repr(n) for n in gone)} "
                    f"{'has' if len(gone) == 1 else 'have'} no area (scaled to zero?)")
    if not plan.casters.any() and blind:
        return (f"scene '{scene.name}' has no caustic caster: diffuse rays do not see "
                f"{', '.join(repr(n) for n in blind)} (Ray Visibility), so Cycles shows no caustic of "
                f"{'it' if len(blind) == 1 else 'them'}")
    if not plan.casters.any():
        return (f"scene '{scene.name}' has no caustic caster: no object with a glossy or glass "
                "material" + (" is flagged 'Cast Shadow Caustics'"
                              if flags != "OFF" and scene.object_caster.any() else ""))
    if not plan.receivers.any():
        return (f"scene '{scene.name}' has no caustic receiver: no diffuse object"
                + (" is flagged 'Receive Shadow Caustics'" if flags != "OFF" and scene.object_receiver.any() else ""))
    if not (scene.camera.clip_start < scene.camera.clip_end):
        return (f"the camera's clip start ({scene.camera.clip_start:g}) is not before its clip end "
                f"({scene.camera.clip_end:g}): it sees nothing")
    return None


def _light_unusable(scene, li) -> str | None:
    """Why light li can light nothing at all (zero power, size or area, a beam, a degenerate
    transform), or None."""
    if not (scene.light_color[li].max() > 0):
        return "zero power"
    if scene.light_type[li] == S.AREA and not (scene.light_size[li].min() > 0):
        return "zero size"
    if scene.light_type[li] == S.MESH and not (scene.mesh_light(li)[4] > 0):
        return "its emitting faces have no area"
    if scene.light_type[li] == S.AREA and not (scene.light_spread[li] > 0):
        return "spread 0: a beam along its normal, which no estimator here samples"
    if _degenerate_axes(scene, li):
        return "its object is scaled to zero along an axis the light needs (no direction or no area)"
    return None


def _plan_light(scene, plan, li, shapes, receivers) -> None:
    """Add light li to the plan (its casters: those of shapes' spheres (object -> bounding sphere) it
    reaches (_reaches, with shapes' boxes: object -> (lo, hi)) and lights), to its lights after a
    diffuse bounce where it lights a receiver of receivers ((object, sphere) pairs), or to the skipped
    with the reason."""
    spheres, boxes = shapes
    name = scene.light_names[li]
    why = _light_unusable(scene, li)
    if why:
        plan.skipped.append(("light", name, why))
        return
    # Light Linking: Cycles asks it of the object a path leaves last before the light: a caustic's
    # last mirror or glass, or the diffuse surface the light lit first (the indirect paths)
    lit = scene.lit_by(li)
    if scene.light_seen_by(li, S.RAY_DIFFUSE) and any(lit[o] and _reaches(scene, li, sp, boxes[o])
                                                      for o, sp in receivers):
        plan.indirect_lights.append(li)  # its light on a receiver may go on to a caster
    if not (scene.light_seen_by(li, S.RAY_GLOSSY) or scene.light_seen_by(li, S.RAY_TRANSMISSION)):
        plan.skipped.append(("light", name, "its Ray Visibility is off for glossy and transmission rays: no ray "
                                            "leaving a mirror or glass meets it"))
        return
    objs = [o for o, sp in spheres.items() if _reaches(scene, li, sp, boxes[o])]
    if not objs:
        plan.skipped.append(("light", name, "reaches no caster"))
        return
    lit_objs = [o for o in objs if lit[o]]  # a light's caustic starts on a caster it lights
    if not lit_objs:
        plan.skipped.append(("light", name, "its Light Linking lights none of the casters it reaches ("
                             + ", ".join(f"'{scene.object_names[o]}'" for o in objs[:4])
                             + (", ..." if len(objs) > 4 else "") + "): Cycles lights a caustic through the "
                             "mirror or glass the light meets first"))
        return
    plan.lights.append(LightPlan(li, name, np.array([spheres[o] for o in lit_objs]), lit_objs,
                                 [scene.object_names[o] for o in lit_objs], light_key(name)))


def _reaches(scene: S.Scene, li: int, sphere: np.ndarray, box) -> bool:
    """Can light li reach an object of bounding sphere `sphere` (4,) and box (lo, hi) at all?
    lights.light_covers on the sphere, and the box not wholly behind what the light faces: an area
    light shines on the side of its plane its normal points to, a spot narrower than a half sphere
    into the half space before it (from its sphere). A floor's bounding sphere (a 20 m floor's
    reaches 14 m up) took a spot 9 m above it aimed at the sky, and an area light over everything
    facing up, for lights whose light meets the floor: pilots that met nothing."""
    if not light_covers(scene, li, sphere[:3], sphere[3]):
        return False
    typ = scene.light_type[li]
    lo, hi = (np.asarray(x, float) for x in box)
    corners = np.array([[(lo, hi)[a][0], (lo, hi)[b][1], (lo, hi)[c][2]] for a in (0, 1) for b in (0, 1)
                        for c in (0, 1)])
    if typ == S.AREA:
        cen, _, _, nrm = area_light_shape(scene, li)[:4]
        return bool(np.any((corners - cen) @ nrm > 0))
    if typ == S.SPOT and 0.5 * float(scene.light_spot_size[li]) < 0.5 * math.pi:
        c = scene.light_matrix[li][:3, 3]
        return bool(np.any((corners - c) @ light_axis(scene, li) >= -float(scene.light_radius[li])))
    return True


def _no_light(plan: Plan) -> str:
    """Plan.nothing where no light is left, with the reasons each was skipped."""
    return "no light can cast caustics ({})".format("; ".join(f"'{n}': {r}" for k, n, r in plan.skipped
                                                             if k == "light"))


def _bounds_over(scene: S.Scene, objs):
    """(lo, hi) around the objects objs, or None for none."""
    b = [scene.object_bounds(o) for o in objs]
    return (np.min([x[0] for x in b], axis=0), np.max([x[1] for x in b], axis=0)) if b else None


def _finish(plan: Plan, scene: S.Scene) -> Plan:
    """Bounds, scale and the indirect pass's target sphere over what takes part (the planned
    casters and every diffuse surface), so that an object outside the plan changes no tolerance."""
    if plan.nothing:
        plan.lights, plan.indirect_lights = [], []
        plan.casters = np.zeros_like(plan.casters)
    O = len(scene.object_names)
    kind = scene.mat_kind[scene.tri_material] if scene.n_tris else np.zeros(0, np.int32)
    has_diff = np.bincount(scene.tri_object[kind == S.DIFFUSE], minlength=O) > 0
    lo, hi = _bounds_over(scene, np.flatnonzero(plan.casters | plan.receivers | has_diff)) or scene.bounds()
    plan.bounds = (lo, hi)
    d = float(np.linalg.norm(hi - lo))
    plan.scale = d if d > 0 else 1.0
    plan.scene_sphere = _bounding_sphere(lo, hi, scene)[None, :]
    return plan


# A world whose caustic can be at most this share of the lamps' (caustic_irradiance) is left out: it
# would cost a share of a light's bake (sample_share) for a change the eye cannot see. Lamps are never
# dropped for being faint: a user put them there.
WORLD_MIN_SHARE = 0.01
FAINT = "its caustic is too faint to show"


def refine_plan(plan: Plan, scene: S.Scene, tracer, cam, seed: int = 0, pilots: int = PILOT_PHOTONS,
                max_bounces: int = PILOT_BOUNCES, indirect: bool = True) -> Plan:
    """The traced part of the plan: which receivers the camera sees, and per light, by up to
    ``pilots`` pilot photons per caster, the casters whose caustic lands where the camera sees
    it, the chain types on the way and the receivers. Casters no pilot photon of a light brings
    into view are left out for that light (a light left with none is skipped), so they cost
    nothing and change no random number. pilots = 0: bounds only.

    Pilots in proportion: a caster catching little of a light (pilot_sets.pilot_count: against the
    light the camera's view gets) is piloted with fewer photons first, then, if it lands too little
    to be kept, with as many more as bound what leaving it out leaves out below PLAN_MIN_SHARE of
    the light the camera sees (topped_up), within MORE_PILOTS of ``pilots``; one the light cannot
    reach (pilots._lit_points: none of HIDDEN_PROBE points on it lit) is left out on that probe. A
    caustic carrying less than about 3 / n of the light reaching a caster (n its pilots) into view
    may be missed: with no pilot landing, that share is below 3 / n at 95% confidence. A world's
    pilots are traced once the lamps' say it is not too faint to show. A caster out of every
    light's plan may still be met after a diffuse bounce: pilots from the lit diffuse surfaces
    towards it (_bounce_pilot) bound that share; above PLAN_MIN_SHARE it is kept for those paths,
    else the words and plan.dropped say what was left out, at most.

    Nothing the plan leaves out changes what it keeps: the look from the camera and the pilots
    through a diffuse bounce are traced with the tolerances of the diffuse surfaces, each caster's
    pilots with those and the caster's own (Tracer.with_extent, lights.emit's extent), and the sums
    and the cells the plan's thresholds read (the light the camera sees, the lamps' caustic
    irradiance) are over what it keeps."""
    t0 = time.perf_counter()
    if not indirect:  # the bake leaves out caustics after a diffuse bounce
        plan.indirect_lights = []
        if not plan.lights and not plan.nothing:  # every light was planned for those alone
            plan.nothing = _no_light(plan)
            _finish(plan, scene)
    has_diff = np.unique(scene.tri_object[scene.mat_kind[scene.tri_material] == S.DIFFUSE])
    dif = _bounds_over(scene, has_diff)
    core = dif or _bounds_over(scene, np.flatnonzero(plan.casters | plan.receivers)) or scene.bounds()
    look = tracer.with_extent(*core, plan.casters)
    direct, through, sides, rays, plan.specular_seen, view, plan.first_specular = camera_look(
        scene, look, cam, plan, scale=float(np.linalg.norm(core[1] - core[0])) or 1.0)
    for o in np.flatnonzero(plan.receivers):
        if direct[o] or through[o, 0, 0] <= through[o, 1, 0]:
            plan.seen[scene.object_names[o]] = "directly" if direct[o] else "through mirrors or glass"
    photons = 0
    if pilots > 0 and (plan.lights or plan.indirect_lights):
        run = _PilotRun(PilotSetup(scene, cam, plan, (direct, through, sides), seed, pilots, max_bounces), tracer,
                        look, core, dif, view)
        worlds = {li for li in [lp.index for lp in plan.lights] + plan.indirect_lights
                  if scene.light_type[li] == S.WORLD}
        run.pilot(lambda li: li not in worlds)  # the lamps first: they say whether a world shows
        faint = _faint_worlds(scene, plan, _lamps_caustic(scene, plan, run.found, run.indirect, has_diff))
        run.pilot(lambda li: li in worlds and li not in faint)
        k = kept(plan.flag_casters, run.found, run.indirect)
        # shares against the light the camera sees; where nothing kept brings any, against all the pilots
        # brought (a mirror whose light after a bounce is the whole caustic, met by one path of its light's)
        ref = k.total if k.total > 0 else k.total0
        used = np.zeros_like(plan.casters)
        dropped = {}  # caster -> {light (or light after a diffuse bounce): its share at most}
        no_direct = _keep_casters(scene, plan, k, faint, ref, used, dropped)
        ind = _keep_indirect(plan, k.indirect, faint, used)
        _bounce_casters(run, faint, ref, ind, used, dropped)
        _indirect_words(scene, plan, ind)
        _skip_words(scene, plan, faint, no_direct, used, dropped)
        out = plan.casters & ~used
        if out.any():
            plan.left_out = out if plan.left_out is None else plan.left_out | out
        plan.casters = used
        if not plan.lights and not plan.indirect_lights:
            plan.nothing = "no caster's caustic lands on anything the camera sees"
        _finish(plan, scene)
        photons, rays = run.photons, rays + run.rays
    plan.cost = {"rays": int(rays), "pilot_photons": int(photons), "time_s": time.perf_counter() - t0}
    return plan


class _PilotRun:
    """The plan's pilots, as tasks the threads take in turn, each with its own random stream; their
    answers are read in task order. found: per light {caster: Pilots}; indirect: {light: Pilots after
    a diffuse bounce}; sources: {light: the diffuse points it lights (the bounce's sources)}; photons
    and rays so far. The look (the camera's rays and the pilots after a diffuse bounce) is traced with
    the diffuse surfaces' tolerances (core), each caster's pilots with those and its own."""

    def __init__(self, setup: PilotSetup, tracer, look, core, dif, view):
        self.setup, self.tracer, self.look, self.core = setup, tracer, look, core
        plan, scene, pilots, seed = setup.plan, setup.scene, setup.pilots, setup.seed
        self.plan, self.scene, self.pilots = plan, scene, pilots
        self.n_ind = max(64, pilots // 2)
        self.dif_sphere = _bounding_sphere(*dif, scene)[None, :] if dif else plan.scene_sphere
        # each light's flux towards what the camera sees (no ray: the weights of photons aimed there)
        self.view_sphere = _bounding_sphere(*view, scene)[None, :] if view[0, 0] <= view[1, 0] else None
        self.view_flux = {lp.index: 0.0 if self.view_sphere is None else
                          float(emit(scene, lp.index, self.view_sphere, VIEW_PHOTONS, stream(seed, PILOT_VIEW, lp.key),
                                     core).w.mean(axis=1).sum()) for lp in plan.lights}
        self.extents = {o: (np.minimum(core[0], scene.object_bounds(o)[0]),
                            np.maximum(core[1], scene.object_bounds(o)[1]))
                        for lp in plan.lights for o in lp.caster_objects}
        self.views = {o: tracer.with_extent(*e, plan.casters) for o, e in self.extents.items()}
        self.found = [{} for _ in plan.lights]
        self.indirect, self.sources = {}, {}
        self.photons, self.rays = 0, 0

    def run(self, tasks) -> None:
        """Pilots of (light's place in plan.lights or None, light plan or light index, caster place,
        photons part or None)."""
        def task(a, _b):
            i, lp, k, part = tasks[a]
            if i is None:
                return _indirect_pilot(self.setup, self.look, lp, self.n_ind, self.dif_sphere, self.core)
            o = lp.caster_objects[k]
            return _caster_pilot(self.setup, self.views[o], lp, k, self.extents[o], self.view_flux[lp.index], part,
                                 self.view_sphere)

        for (i, lp, k, part), (n, r, out) in zip(tasks, lanes.blocks(task, len(tasks), 1, self.tracer.threads)):
            self.photons += n
            self.rays += r
            if i is None:
                self.indirect[lp], self.sources[lp] = out
            else:
                o = lp.caster_objects[k]
                self.found[i][o] = out if part is None else self.found[i][o].add(out)

    def pilot(self, which) -> None:
        """The lights `which` (light indices) picks: every caster's first pilots and the light after a
        diffuse bounce, then more pilots for the casters whose first ones cannot bound what leaving
        them out would leave out."""
        plan = self.plan
        self.run([(i, lp, k, None) for i, lp in enumerate(plan.lights) if which(lp.index)
                  for k in range(len(lp.caster_objects))]
                 + [(None, li, None, None) for li in plan.indirect_lights if which(li)])
        total = kept(plan.flag_casters, self.found, self.indirect).total
        more = []
        for i, lp in enumerate(plan.lights):
            if which(lp.index):
                for k, o in enumerate(lp.caster_objects):
                    p = self.found[i][o]
                    n = topped_up(p, total, self.pilots)
                    if n > p.n:
                        more.append((i, lp, k, (p.n, n)))
        self.run(more)

    def bounce(self, pairs, need) -> list:
        """_bounce_pilot for each (light, caster) of pairs: their Pilots (or None), in order."""
        def task(a, _b):
            li, o = pairs[a]
            return _bounce_pilot(self.setup, self.look, li, o, self.sources[li], need)

        out = []
        for n, r, p in lanes.blocks(task, len(pairs), 1, self.tracer.threads):
            self.photons += n
            self.rays += r
            out.append(p)
        return out


def _faint_worlds(scene, plan, lamps_E) -> dict:
    """The worlds too faint to show beside the lamps' caustic irradiance lamps_E: {light index: their
    brightest caustic / the lamps'}; a world bright enough but well below the lamps gets its share of
    samples (plan.sample_share)."""
    faint = {}
    for li in dict.fromkeys([lp.index for lp in plan.lights] + list(plan.indirect_lights)):
        if scene.light_type[li] == S.WORLD and lamps_E > 0:
            env = env_map(scene, li)  # the most a plane can receive: pi L, or a map's luminance over the sphere
            bound = env.power if env is not None else math.pi * float(np.mean(scene.light_color[li]))
            share = sample_share(bound / lamps_E)
            if bound < WORLD_MIN_SHARE * lamps_E:
                faint[li] = bound / lamps_E
            elif share < 1.0:
                plan.sample_share[li] = share
    return faint


def _lamps_caustic(scene, plan, found, indirect, has_diff) -> float:
    """caustic_irradiance of the lamps' pilots (every light's but the world's) through the casters the
    plan keeps, in cells of a size from what takes part (the diffuse surfaces and those casters): a
    caster left out changes neither (a far glass ball's faint pilots, and its 45 m beyond the floor
    widening the cells 2.5 times, made the lamps' caustic 6x dimmer, and the default grey world that
    was too faint to show took 19% of the samples)."""
    k = kept(plan.flag_casters, found, indirect)
    keep = sorted({o for ow in k.own for o in ow})
    lamps = [p for lp, per, ow in zip(plan.lights, k.found, k.own) if scene.light_type[lp.index] != S.WORLD
             for o, p in per.items() if o in ow]
    objs = np.union1d(np.union1d(np.asarray(keep, np.int64), np.flatnonzero(plan.receivers)),
                      np.asarray(has_diff, np.int64))
    b = _bounds_over(scene, objs)
    d = float(np.linalg.norm(b[1] - b[0])) if b else 0.0
    return caustic_irradiance(np.concatenate([p.at for p in lamps]) if lamps else np.zeros((0, 3)),
                              np.concatenate([p.w for p in lamps]) if lamps else np.zeros(0), d if d > 0 else 1.0)


def _keep_casters(scene, plan, k, faint, ref, used, dropped) -> list:
    """Each light keeps the casters whose own pilots landed in view with a share of the light the camera
    sees above PLAN_MIN_SHARE (k.own; marked in used); the notes say why the others went, and dropped
    ({caster: {light: share at most}}) what they carry at most. Returns the lights left with no direct
    caustic."""
    kept_lights, no_direct = [], []
    for i, (lp, per) in enumerate(zip(plan.lights, k.found)):
        if lp.index in faint:
            continue
        lp_casters, effects = set(), []
        for o in lp.caster_objects:
            name = scene.object_names[o]
            p = per[o]
            if not p.landed > 0:
                plan.notes.append(f"{name} skipped for {lp.name}: " + (
                    f"the light reaches none of {p.n} points on it" if p.hidden else
                    f"its direct caustic lands on nothing the camera sees (0 of {p.n} pilot photons)"))
                dropped.setdefault(o, {})[lp.name] = share_max(p, ref)
                continue
            if o not in k.own[i]:
                plan.notes.append(f"{name} skipped for {lp.name}: {FAINT} "
                                  f"({p.landed / ref:.1e} of the light the camera sees)")
                dropped.setdefault(o, {})[lp.name] = share_max(p, ref)
                continue
            effects.append((name, p.shares(), p.receivers(scene), p.landed / k.total))
            lp_casters |= p.met
        if not lp_casters:
            no_direct.append(lp)
            continue
        objs = sorted(lp_casters)
        sph = [_bounding_sphere(*scene.object_bounds(o), scene) for o in objs]
        kept_lights.append(LightPlan(lp.index, lp.name, np.array(sph), objs,
                                     [scene.object_names[o] for o in objs], lp.key, effects))
        used[objs] = True
    plan.lights = kept_lights
    return no_direct


def _keep_indirect(plan, kept_indirect, faint, used) -> dict:
    """The lights after a diffuse bounce that keep their place: any of their kept pilots landing keeps
    one (these pilots start at the first diffuse hit straight from the light, so they undercount light
    that meets glass first: a pool's floor under water); their casters are marked in used. Returns
    {light: (casters met, receiver objects)}."""
    ind = {}
    for li in plan.indirect_lights:
        if li in faint:  # (never piloted)
            continue
        p = kept_indirect[li]
        if p.landed > 0:
            ind[li] = (set(p.met), [int(x) for x in np.unique(p.recv)])
            used[sorted(p.met)] = True
    return ind


def _bounce_casters(run, faint, ref, ind, used, dropped) -> None:
    """A caster out of every light's plan that a diffuse bounce may still reach (a far ball beside a lit
    floor): pilots from the lit diffuse surfaces towards it (run.bounce), enough to bound its share
    below PLAN_MIN_SHARE when none lands; kept for those paths where at least MET_PATHS of them bring
    that much (added to ind and used), else left out, with the bound in dropped."""
    plan, scene = run.plan, run.scene
    pairs = [(li, o) for o in np.flatnonzero(plan.casters & ~used) for li in plan.indirect_lights
             if li not in faint and run.sources.get(li) is not None]
    if not pairs or not ref > 0:
        return
    for (li, o), p in zip(pairs, run.bounce(pairs, PLAN_MIN_SHARE * ref)):
        if p is None:
            continue
        if len(p.w) >= MET_PATHS and not p.landed < PLAN_MIN_SHARE * ref:  # (one path: a chance, kept())
            met, recv = ind.setdefault(li, (set(), []))
            met.update(p.met)
            recv += [int(x) for x in np.unique(p.recv) if int(x) not in recv]
            used[sorted(p.met)] = True
        else:
            dropped.setdefault(o, {})[f"{scene.light_names[li]} after a diffuse bounce"] = share_max(p, ref)


def _indirect_words(scene, plan, ind) -> None:
    """The lights after a diffuse bounce that stay planned (ind's), and their words."""
    plan.indirect_lights = [li for li in plan.indirect_lights if li in ind]
    for li in plan.indirect_lights:
        met, recv = ind[li]
        plan.indirect_words.append(
            f"{scene.light_names[li]} -> diffuse -> {', '.join(scene.object_names[o] for o in sorted(met))}"
            f" -> {', '.join(scene.object_names[r] for r in recv)} (after a diffuse bounce)")


def _skip_words(scene, plan, faint, no_direct, used, dropped) -> None:
    """The plan's skipped lines for what the pilots left out: faint worlds, lights whose caustic lands
    on nothing seen, and casters out of every light's plan (one line each, replacing their notes, with
    the bound on what they carry: plan.dropped)."""
    for li, share in faint.items():
        plan.skipped.append(("light", scene.light_names[li], f"{FAINT} (at most {share:.1%} of the lamps' "
                             "caustic)"))
    for lp in no_direct:
        if lp.index not in plan.indirect_lights:
            plan.skipped.append(("light", lp.name, "its caustics land on nothing the camera sees"))
    for o in np.flatnonzero(plan.casters & ~used):  # out of every light's plan: one line for it
        name = scene.object_names[o]
        why = [n for n in plan.notes if n.startswith(name + " skipped for ")]
        reason = FAINT if any(FAINT in n for n in why) else "its caustic lands on nothing the camera sees"
        if dropped.get(o):
            at_most = sum(dropped[o].values())
            plan.dropped[name] = {"share_max": at_most, "by": dict(dropped[o])}
            reason += f" (left out: at most {at_most:.1e} of the light the camera sees)"
        plan.skipped.append(("caster", name, reason))
        plan.notes = [n for n in plan.notes if n not in why]
