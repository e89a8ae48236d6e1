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
from ..shading.lights import env_map, light_covers
from .pilots import (
    PILOT_BOUNCES, PILOT_PHOTONS, _caster_pilot, _indirect_pilot, camera_sees, caustic_irradiance, sample_share)
from ..core.random import light_key


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


def make_plan(scene: S.Scene, flags: str = "AUTO") -> Plan:
    """The plan from materials, Cycles' flags and bounds alone (no tracing). A scene with
    nothing to bake (no light, caster or receiver) gives a plan whose ``nothing`` says why."""
    casters, receivers, skipped, blind, flat = _participants(scene, flags)
    plan = Plan(casters=casters, receivers=receivers, lights=[], skipped=skipped, flag_casters=casters.copy())
    plan.nothing = _nothing_takes_part(scene, plan, flags, blind, flat)
    if plan.nothing:
        return _finish(plan, scene)
    spheres = {o: _bounding_sphere(*scene.object_bounds(o), scene) for o in np.flatnonzero(casters)}
    rec_objs = np.flatnonzero(receivers)
    rec_spheres = [_bounding_sphere(*scene.object_bounds(o), scene) for o in rec_objs]
    use_light_flags = _use_flags(flags, scene.caustic_flags())  # a mesh light has none: it does not count
    for li in range(scene.n_lights):
        if use_light_flags and not scene.light_caustics[li]:
            skipped.append(("light", scene.light_names[li], "not flagged 'Shadow Caustics'"))
            continue
        _plan_light(scene, plan, li, spheres, zip(rec_objs, rec_spheres))
    if not plan.lights and not plan.indirect_lights:  # (a light that lights a receiver may still light a caster)
        plan.nothing = _no_light(plan)
    if len(plan.lights) >= MANY_LIGHTS:
        plan.notes.append(f"{len(plan.lights)} lights take part: each light's caustic is traced on its own, so the "
                          f"bake costs about {len(plan.lights)} times one light's (a time or noise rule shares its "
                          f"time among them)")
    return _finish(plan, scene)


MANY_LIGHTS = 16  # from this many lights the plan says what they cost


def _participants(scene, flags):
    """(casters, receivers: (O,) bool, skipped: the objects left out and why, blind: the casters no
    diffuse ray sees, flat: the objects left out for having no area) from materials, Cycles' flags
    (as flags says), Ray Visibility and the objects' areas."""
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


def _plan_light(scene, plan, li, spheres, receivers) -> None:
    """Add light li to the plan (its casters: those of spheres (object -> bounding sphere) it reaches
    and lights), to its lights after a diffuse bounce where it lights a receiver of receivers ((object,
    sphere) pairs), or to the skipped with the reason."""
    name = scene.light_names[li]
    why = _light_unusable(scene, li)
    if why:
        plan.skipped.append(("light", name, why))
        return
    # Light Linking: Cycles asks it of the object a path leaves last before the light: a caustic's
    # last mirror or glass, or the diffuse surface the light lit first (the indirect paths)
    lit = scene.lit_by(li)
    if scene.light_seen_by(li, S.RAY_DIFFUSE) and any(lit[o] and light_covers(scene, li, sp[:3], sp[3])
                                                      for o, sp in receivers):
        plan.indirect_lights.append(li)  # its light on a receiver may go on to a caster
    if not (scene.light_seen_by(li, S.RAY_GLOSSY) or scene.light_seen_by(li, S.RAY_TRANSMISSION)):
        plan.skipped.append(("light", name, "its Ray Visibility is off for glossy and transmission rays: no ray "
                                            "leaving a mirror or glass meets it"))
        return
    objs = [o for o, sp in spheres.items() if light_covers(scene, li, sp[:3], sp[3])]
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


PLAN_MIN_SHARE = 1e-5  # a caster bringing less of the light the camera sees (by the pilots) is left out
# A world whose caustic can be at most this share of the lamps' (caustic_irradiance) is left out: it
# would cost a share of a light's bake (sample_share) for a change the eye cannot see. Lamps are never
# dropped for being faint: a user put them there.
WORLD_MIN_SHARE = 0.01
FAINT = "its caustic is too faint to show"


def refine_plan(plan: Plan, scene: S.Scene, tracer, cam, seed: int = 0, pilots: int = PILOT_PHOTONS,
                max_bounces: int = PILOT_BOUNCES, indirect: bool = True) -> Plan:
    """The traced part of the plan: which receivers the camera sees, and per light, by
    ``pilots`` pilot photons per caster, the casters whose caustic lands where the camera
    sees it, the chain types on the way and the receivers. Casters no pilot photon of a
    light brings into view are left out for that light (a light left with none is
    skipped), so they cost nothing and change no random number. pilots = 0: bounds only.

    A caustic carrying less than about 3 / pilots of the light reaching a caster into view
    may be missed: with no pilot landing, that share is below 3 / pilots at 95% confidence."""
    t0 = time.perf_counter()
    if not indirect:  # the bake leaves out caustics after a diffuse bounce
        plan.indirect_lights = []
        if not plan.lights and not plan.nothing:  # every light was planned for those alone
            plan.nothing = _no_light(plan)
            _finish(plan, scene)
    direct, through, sides, rays, plan.specular_seen = camera_sees(scene, tracer, cam, plan)
    for o in np.flatnonzero(plan.receivers):
        if direct[o] or through[o, 0, 0] <= through[o, 1, 0]:
            plan.seen[scene.object_names[o]] = "directly" if direct[o] else "through mirrors or glass"
    photons = 0
    if pilots > 0 and (plan.lights or plan.indirect_lights):
        found, landed, photons, pilot_rays = _run_pilots(plan, scene, tracer, cam, (direct, through, sides), seed,
                                                         pilots, max_bounces)
        rays += pilot_rays
        total = sum(f[2] for per in found for f in per.values()) + sum(v[0] for v in landed.values())
        faint = _faint_worlds(scene, plan, found)
        used = np.zeros_like(plan.casters)
        no_direct = _keep_casters(scene, plan, found, faint, total, pilots, used)
        _keep_indirect(scene, plan, landed, faint, used)
        _skip_words(scene, plan, faint, no_direct, used)
        plan.casters = used
        if not plan.lights and not plan.indirect_lights:
            plan.nothing = "no caster's caustic lands on anything the camera sees"
        _finish(plan, scene)
    plan.cost = {"rays": int(rays), "pilot_photons": int(photons), "time_s": time.perf_counter() - t0}
    return plan


def _run_pilots(plan, scene, tracer, cam, seen, seed, pilots, max_bounces):
    """Every light's pilots per caster, then each indirect light's (caustics through a diffuse bounce
    first, light -> diffuse -> caster -> ... -> seen; indirect.py): tasks the threads take in turn,
    each with its own random stream; their answers are read in task order. Returns (per light
    {caster: (shares, receivers, flux, casters met, ...)}, {indirect light: (flux, casters met,
    receivers)}, photons, rays)."""
    tasks = [(i, lp, k, o) for i, lp in enumerate(plan.lights) for k, o in enumerate(lp.caster_objects)]
    tasks += [(None, None, li, None) for li in plan.indirect_lights]
    n_ind = max(64, pilots // 2)
    dif = _bounds_over(scene, np.unique(scene.tri_object[scene.mat_kind[scene.tri_material] == S.DIFFUSE]))
    dif_sphere = _bounding_sphere(*dif, scene)[None, :] if dif else plan.scene_sphere

    def task(a, _b):
        _, lp, k, _ = tasks[a]
        if lp is None:
            return _indirect_pilot(scene, tracer, cam, plan, seen, seed, k, n_ind, dif_sphere, max_bounces)
        return _caster_pilot(scene, tracer, cam, plan, seen, seed, lp, k, pilots, max_bounces)

    found = [{} for _ in plan.lights]  # per light: {caster: (shares, receivers, flux, casters met)}
    landed, photons, rays = {}, 0, 0
    for (i, _, k, o), (n, r, out) in zip(tasks, lanes.blocks(task, len(tasks), 1, tracer.threads)):
        photons += n
        rays += r
        if out is not None and i is None:
            landed[k] = out
        elif out is not None:
            found[i][o] = out
    return found, landed, photons, rays


def _faint_worlds(scene, plan, found) -> dict:
    """The worlds too faint to show: {light index: their brightest caustic / the lamps'}; a world
    bright enough but well below the lamps gets its share of samples (plan.sample_share)."""
    lamps = [f for lp, per in zip(plan.lights, found) if scene.light_type[lp.index] != S.WORLD
             for f in per.values()]
    lamps_E = caustic_irradiance(np.concatenate([f[4] for f in lamps]) if lamps else np.zeros((0, 3)),
                                 np.concatenate([f[5] for f in lamps]) if lamps else np.zeros(0), plan.scale)
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


def _keep_casters(scene, plan, found, faint, total, pilots, used) -> list:
    """Each light keeps the casters whose pilots landed in view with a share of the light the camera
    sees above PLAN_MIN_SHARE (marked in used); the notes say why the others went. Returns the
    lights left with no direct caustic."""
    kept_lights, no_direct = [], []
    for lp, per in zip(plan.lights, found):
        if lp.index in faint:
            continue
        lp_casters, effects = set(), []
        for o in lp.caster_objects:
            name = scene.object_names[o]
            if o not in per:
                plan.notes.append(f"{name} skipped for {lp.name}: its direct caustic lands on nothing the "
                                  f"camera sees (0 of {pilots} pilot photons)")
                continue
            shares, recv_names, flux, met = per[o][:4]
            if flux < PLAN_MIN_SHARE * total:
                plan.notes.append(f"{name} skipped for {lp.name}: {FAINT} "
                                  f"({flux / total:.1e} of the light the camera sees)")
                continue
            effects.append((name, shares, recv_names, flux / total))
            lp_casters |= met
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


def _keep_indirect(scene, plan, landed, faint, used) -> None:
    """The lights after a diffuse bounce that keep their place: any pilot landing keeps one (these
    pilots start at the first diffuse hit straight from the light, so they undercount light that
    meets glass first: a pool's floor under water); their casters are marked in used."""
    keep = []
    for li in plan.indirect_lights:
        if li in faint or li not in landed:
            continue
        keep.append(li)
        met = sorted(landed[li][1])
        used[met] = True
        plan.indirect_words.append(
            f"{scene.light_names[li]} -> diffuse -> {', '.join(scene.object_names[o] for o in met)} -> "
            f"{', '.join(landed[li][2])} (after a diffuse bounce)")
    plan.indirect_lights = keep


def _skip_words(scene, plan, faint, no_direct, used) -> None:
    """The plan's skipped lines for what the pilots left out: faint worlds, lights whose caustic lands
    on nothing seen, and casters out of every light's plan (one line each, replacing their notes)."""
    for li, share in faint.items():
        plan.skipped.append(("light", scene.light_names[li], f"{FAINT} (at most {share:.1%} of the lamps' "
                             "caustic)"))
    for lp in no_direct:
        if lp.index not in plan.indirect_lights:
            plan.skipped.append(("light", lp.name, "its caustics land on nothing the camera sees"))
    for o in np.flatnonzero(plan.casters & ~used):  # out of every light's plan: one line for it
        name = scene.object_names[o]
        why = [n for n in plan.notes if n.startswith(name + " skipped for ")]
        plan.skipped.append(("caster", name, FAINT if any(FAINT in n for n in why) else
                             "its caustic lands on nothing the camera sees"))
        plan.notes = [n for n in plan.notes if n not in why]
