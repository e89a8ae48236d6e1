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
from ..shading.lights import env_map, light_axis, light_covers
from ..shading.microfacet import rough_materials
from ..core.random import PILOT_CASTER, PILOT_INDIRECT, PLAN_LOOK, light_key, stream
from ..core.vec import dot


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

    plan = Plan(casters=casters, receivers=receivers, lights=[], skipped=skipped, flag_casters=casters.copy())
    if scene.n_lights == 0:
        plan.nothing = f"scene '{scene.name}' has no light"
    elif not casters.any() and blind:
        plan.nothing = (f"scene '{scene.name}' has no caustic caster: diffuse rays do not see "
                        f"{', '.join(repr(n) for n in blind)} (Ray Visibility), so Cycles shows no caustic of "
                        f"{'it' if len(blind) == 1 else 'them'}")
    elif not casters.any():
        plan.nothing = (f"scene '{scene.name}' has no caustic caster: no object with a glossy or glass "
                        "material" + (" is flagged 'Cast Shadow Caustics'"
                                      if flags != "OFF" and scene.object_caster.any() else ""))
    elif not receivers.any():
        plan.nothing = (f"scene '{scene.name}' has no caustic receiver: no diffuse object"
                        + (" is flagged 'Receive Shadow Caustics'"
                           if flags != "OFF" and scene.object_receiver.any() else ""))
    elif not (scene.camera.clip_start < scene.camera.clip_end):
        plan.nothing = (f"the camera's clip start ({scene.camera.clip_start:g}) is not before its clip end "
                        f"({scene.camera.clip_end:g}): it sees nothing")
    if plan.nothing:
        return _finish(plan, scene)

    spheres = {}
    for o in np.flatnonzero(casters):
        lo, hi = scene.object_bounds(o)
        spheres[o] = _bounding_sphere(lo, hi, scene)
    rec_objs = np.flatnonzero(receivers)
    rec_spheres = [_bounding_sphere(*scene.object_bounds(o), scene) for o in rec_objs]
    use_light_flags = _use_flags(flags, scene.caustic_flags())  # a mesh light has none: it does not count
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
        if scene.light_type[li] == S.MESH and not (scene.mesh_light(li)[4] > 0):
            skipped.append(("light", name, "its emitting faces have no area"))
            continue
        if scene.light_type[li] == S.AREA and not (scene.light_spread[li] > 0):
            skipped.append(("light", name, "spread 0: a beam along its normal, which no estimator here samples"))
            continue
        if _degenerate_axes(scene, li):
            skipped.append(("light", name, "its object is scaled to zero along an axis the light needs "
                                           "(no direction or no area)"))
            continue
        # Light Linking: Cycles asks it of the object a path leaves last before the light: a caustic's
        # last mirror or glass, or the diffuse surface the light lit first (the indirect paths)
        lit = scene.lit_by(li)
        if scene.light_seen_by(li, S.RAY_DIFFUSE) and any(lit[o] and light_covers(scene, li, sp[:3], sp[3])
                                                          for o, sp in zip(rec_objs, rec_spheres)):
            plan.indirect_lights.append(li)  # its light on a receiver may go on to a caster
        if not (scene.light_seen_by(li, S.RAY_GLOSSY) or scene.light_seen_by(li, S.RAY_TRANSMISSION)):
            skipped.append(("light", name, "its Ray Visibility is off for glossy and transmission rays: no ray "
                                           "leaving a mirror or glass meets it"))
            continue
        objs = [o for o, sp in spheres.items() if light_covers(scene, li, sp[:3], sp[3])]
        if not objs:
            skipped.append(("light", name, "reaches no caster"))
            continue
        lit_objs = [o for o in objs if lit[o]]  # a light's caustic starts on a caster it lights
        if not lit_objs:
            skipped.append(("light", name, "its Light Linking lights none of the casters it reaches ("
                            + ", ".join(f"'{scene.object_names[o]}'" for o in objs[:4])
                            + (", ..." if len(objs) > 4 else "") + "): Cycles lights a caustic through the "
                            "mirror or glass the light meets first"))
            continue
        plan.lights.append(LightPlan(li, name, np.array([spheres[o] for o in lit_objs]), lit_objs,
                                     [scene.object_names[o] for o in lit_objs], light_key(name)))
    if not plan.lights and not plan.indirect_lights:  # (a light that lights a receiver may still light a caster)
        plan.nothing = _no_light(plan)
    return _finish(plan, scene)


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


# ------------------------------------------------------------------ the traced part of the plan
PILOT_PHOTONS = 4096  # per light and caster
PILOT_BOUNCES = 8  # specular bounces a pilot photon follows
PLAN_MIN_SHARE = 1e-5  # a caster bringing less of the light the camera sees (by the pilots) is left out
# A world whose caustic can be at most this share of the lamps' (caustic_irradiance) is left out: it
# would cost a share of a light's bake (sample_share) for a change the eye cannot see. Lamps are never
# dropped for being faint: a user put them there.
WORLD_MIN_SHARE = 0.01
CELLS = 64  # caustic_irradiance's cells: this many across the diagonal of what takes part
FAINT = "its caustic is too faint to show"
CAMERA_RAYS = 1 << 18  # at most this many rays for what the camera sees (a grid over the frame)


def _surfaces(scene, tracer, o, d, camera=False, passable=None):
    """Trace rays (camera: the camera's own, Tracer.camera_intersect; passable: past the objects it marks,
    Tracer.intersect_past): (hits, indices of the rays that hit, their object, material and kind)."""
    h = tracer.camera_intersect(o, d) if camera else tracer.intersect_past(o, d, 0, passable)
    i = np.flatnonzero(h.hit)
    mat = scene.tri_material[h.prim[i]]
    return h, i, scene.tri_object[h.prim[i]], mat, scene.mat_kind[mat]


def camera_sees(scene, tracer, cam, plan, max_bounces=PILOT_BOUNCES):
    """Receivers the camera sees directly and through mirrors or glass: one ray per pixel
    (a grid of at most CAMERA_RAYS over a larger frame), split at glass into its reflection
    and its refraction. Returns (direct (O,) bool, through (O,2,3): per receiver the box of
    the points seen through mirrors or glass, padded (empty: lo > hi), sides (O,) the sides
    of them seen (1 front, 2 back, by the geometric normal), rays, specular: whether a mirror
    or glass is what some pixel sees first, None where the grid skips pixels).

    The rays are traced in parts of SEES_PART that the threads take in turn (_sees_part); what
    they find is merged by or, min and max, so the result is the one of a single part (but in a
    maze of glass, where each part keeps its own regular subset of its rays)."""
    direct, through, sides = _nothing_seen(len(scene.object_names))
    x0, x1, y0, y1 = cam.region
    w, h = max(0, x1 - x0), max(0, y1 - y0)
    if w * h == 0 or scene.n_tris == 0:
        return direct, through, sides, 0, False
    step = max(1, math.ceil(math.sqrt(w * h / CAMERA_RAYS)))
    _, _, o, d = cam.pixel_rays(step)
    n = len(o)

    def part(a, b):
        return _sees_part(scene, tracer, plan, o[a:b], d[a:b], max_bounces, 4 * CAMERA_RAYS * (b - a) // max(n, 1),
                          stream(0, PLAN_LOOK, a))

    rays, specular = 0, False
    for p_direct, p_through, p_sides, p_rays, p_specular in lanes.blocks(part, n, SEES_PART, tracer.threads):
        specular |= p_specular
        direct |= p_direct
        np.minimum(through[:, 0], p_through[:, 0], out=through[:, 0])
        np.maximum(through[:, 1], p_through[:, 1], out=through[:, 1])
        sides |= p_sides
        rays += p_rays
    # the samples are a pixel apart: pad each box by a tenth of its size and 2% of the scene
    seen = through[:, 0, 0] <= through[:, 1, 0]
    pad = 0.1 * np.linalg.norm(through[:, 1] - through[:, 0], axis=1) + 0.02 * plan.scale
    through[seen, 0] -= pad[seen, None]
    through[seen, 1] += pad[seen, None]
    return direct, through, sides, rays, (specular if step == 1 else None)


SEES_PART = 1 << 16  # camera rays per part of camera_sees


def _nothing_seen(n_objects: int):
    """camera_sees' answer before any ray: (direct, through (empty boxes: lo > hi), sides)."""
    through = np.empty((n_objects, 2, 3))
    through[:, 0], through[:, 1] = np.inf, -np.inf
    return np.zeros(n_objects, bool), through, np.zeros(n_objects, np.int64)


def _sees_part(scene, tracer, plan, o, d, max_bounces, cap, rng):
    """camera_sees for the rays o, d: (direct, through (unpadded), sides, rays cast, whether a
    mirror or glass is the first hit of one of them); past cap rays at a bounce, a regular subset
    of them goes on. rng: the rough surfaces' directions (drawn only where the rays meet one)."""
    from ..shading.optics import reflect, refract

    direct, through, sides = _nothing_seen(len(scene.object_names))
    rays, specular = 0, False
    for depth in range(max_bounces + 1):
        if len(o) == 0:
            break
        hit, i, obj, mat, kind = _surfaces(scene, tracer, o, d, camera=depth == 0)
        rays += len(o)
        r = np.flatnonzero((kind == S.DIFFUSE) & plan.receivers[obj])
        if depth == 0:
            direct[np.unique(obj[r])] = True
        else:
            np.minimum.at(through[:, 0], obj[r], hit.p[i[r]])
            np.maximum.at(through[:, 1], obj[r], hit.p[i[r]])
            front = dot(d[i[r]], hit.ng[i[r]]) < 0
            np.bitwise_or.at(sides, obj[r], np.where(front, 1, 2))
        spec = np.flatnonzero((kind == S.CONDUCTOR) | (kind == S.DIELECTRIC))  # any mirror or glass, as the eye
        specular |= depth == 0 and spec.size > 0
        if spec.size == 0 or depth == max_bounces:
            break
        j = i[spec]
        p, ng, ns, w_in = hit.p[j], hit.ng[j], hit.ns[j], -d[j]
        m = mat[spec]
        rough = _rough_lanes(scene, m)
        if rough is not None:  # what the eye sees in a rough mirror or glass: the perfect one's and one sampled
            jr = j[rough]
            _, rd, _, _, kept = _rough_scatter(scene, tracer, rng, hit.p[jr], hit.ng[jr], hit.ns[jr], -d[jr],
                                                m[rough], adjoint=False)
        refl = scene.mat_fresnel[m] != S.REFRACTION_ONLY
        glass = scene.mat_kind[m] == S.DIELECTRIC
        d_r = reflect(w_in[refl], ns[refl])
        d_t, ok = refract(w_in[glass], ns[glass], scene.mat_ior[m[glass]])
        no = np.concatenate([p[refl], p[glass][ok]])
        nd = np.concatenate([d_r, d_t[ok]])
        nn = np.concatenate([ng[refl], ng[glass][ok]])
        if rough is not None:
            no, nd, nn = (np.concatenate([no, hit.p[jr[kept]]]), np.concatenate([nd, rd]),
                          np.concatenate([nn, hit.ng[jr[kept]]]))
        if len(nd) > max(cap, 1):  # a maze of glass: keep a regular subset
            keep = np.arange(0, len(nd), math.ceil(len(nd) / max(cap, 1)))
            no, nd, nn = no[keep], nd[keep], nn[keep]
        o, d = tracer.spawn(no, nn, nd), nd
    return direct, through, sides, rays, specular


def _sees_point(scene, tracer, cam, p, ng, w_in):
    """Does the camera see the lit side of each point p (lit from w_in, pointing away)?"""
    rx, ry, to_cam, tmax, cos_axis, dist, valid = cam.towards(p, max(cam.cam.filter_width, 0.5))
    valid &= dot(w_in, ng) * dot(to_cam, ng) > 0
    idx = np.flatnonzero(valid)
    if idx.size:
        blocked = tracer.camera_occluded(tracer.spawn(p[idx], ng[idx], to_cam[idx]), to_cam[idx],
                                         tmax[idx] - tracer.eps)
        valid[idx[blocked]] = False
    return valid, int(idx.size)


def _rough_lanes(scene, m):
    """(N,) bool: the lanes of materials m on a rough mirror or glass, or None where there is none."""
    rough = rough_materials(scene)[m]
    return rough if rough.any() else None


def _rough_scatter(scene, tracer, rng, p, ng, ns, w_in, m, adjoint):
    """A rough mirror's or glass's scattering for the plan's rays (w_in pointing away from the
    surface): one lobe and one microfacet normal drawn per lane, as the bake draws them
    (reference.scatter_specular), where a smooth surface's two lobes are followed both. A rough
    reflection reaches where the perfect one cannot: a floor lit by a bulb sends light up into a
    rough standing mirror, which sends some of it down onto the floor again. Returns the new
    lanes' (origins, directions, weights (luminance-like mean), letters 1 R / 2 T, the lanes kept)."""
    from ..paths.photons import scatter_specular

    beta = np.ones((len(w_in), 3))
    d, b, keep = scatter_specular(scene, rng, w_in, ns, ng, m, scene.mat_kind[m], beta, adjoint=adjoint)
    letter = np.where(dot(d, ng[keep]) * dot(w_in[keep], ng[keep]) > 0, 1, 2).astype(np.int8)
    return tracer.spawn(p[keep], ng[keep], d), d, b.mean(axis=1), letter, keep


def _pilot(scene, tracer, cam, plan, ph, direct, through, sides, rng, max_bounces, target):
    """Follow pilot photons from caster ``target`` (the photons whose first hit is on it)
    through mirrors and glass (glass: both ways while the lanes stay few, else one way at
    random; a rough one: one sampled way, _rough_scatter) to their first diffuse surface.
    Returns, per photon path that lands where the camera sees it: the casters it met (K, max_bounces) object
    ids (-1 past its end), its chain letters, the receiver, the flux it carries
    (luminance, through the Fresnel weights) and where it lands; and the rays cast. target None: photons
    leaving a diffuse surface (ph.o is on it), the first specular hit on any caster."""
    from ..shading.optics import reflect, refract
    from ..shading.fresnel import specular_weights

    n0 = len(ph.o)
    keep = ph.w.max(axis=1) > 0
    o, d = ph.o[keep], ph.d[keep]
    w = ph.w[keep].mean(axis=1)  # the flux a lane carries (its photon's, times Fresnel weights)
    if target is None:
        target = np.flatnonzero(plan.flag_casters)
    hist = np.full((len(o), max_bounces), -1, np.int64)
    letters = np.zeros((len(o), max_bounces), np.int8)  # 1 R, 2 T
    out = []
    rays = 0
    for depth in range(max_bounces + 1):
        if len(o) == 0:
            break
        # a photon's first segment passes what does not shadow its light (Shadow Linking)
        h, i, obj, mat, kind = _surfaces(scene, tracer, o, d, passable=ph.unshadowing if depth == 0 else None)
        rays += len(o)
        land = np.flatnonzero((kind == S.DIFFUSE) & plan.receivers[obj] & (depth > 0))
        if land.size:
            li_ = i[land]
            box = through[obj[land]]
            pl = h.p[li_]
            side = np.where(dot(d[li_], h.ng[li_]) < 0, 1, 2)
            seen = np.all((box[:, 0] <= pl) & (pl <= box[:, 1]), axis=1) & (sides[obj[land]] & side > 0)
            check = np.flatnonzero(~seen & direct[obj[land]])
            if check.size:
                v, r = _sees_point(scene, tracer, cam, h.p[li_[check]], h.ng[li_[check]], -d[li_[check]])
                rays += r
                seen[check] = v
            out.append((hist[li_[seen]], letters[li_[seen]], obj[land[seen]], w[li_[seen]], pl[seen]))
        spec = (kind == S.CONDUCTOR) | (kind == S.DIELECTRIC)
        spec &= np.isin(obj, target) if depth == 0 else True  # the pilots of caster target: paths from it
        sp = np.flatnonzero(spec)
        if sp.size == 0 or depth == max_bounces:
            break
        j = i[sp]
        p, ng, ns, w_in, m = h.p[j], h.ng[j], h.ns[j], -d[j], mat[sp]
        hist[j, depth] = np.where(plan.flag_casters[obj[sp]], obj[sp], -1)
        rough = _rough_lanes(scene, m)
        if rough is not None:  # rough mirrors and glass: one sampled microfacet scattering each
            jr, j = j[rough], j[~rough]
            ro, rd, rw, letter, kept = _rough_scatter(scene, tracer, rng, h.p[jr], h.ng[jr], h.ns[jr], -d[jr],
                                                      m[rough], adjoint=True)
            p, ng, ns, w_in, m = p[~rough], ng[~rough], ns[~rough], w_in[~rough], m[~rough]
            rw *= w[jr[kept]]
            rh, rlet = hist[jr[kept]], letters[jr[kept]].copy()
            rlet[:, depth] = letter
        wr, wt = specular_weights(scene, m, dot(w_in, ns))
        wr, wt = wr.mean(axis=1), wt.mean(axis=1)
        d_t, ok = refract(w_in, ns, np.where(scene.mat_kind[m] == S.DIELECTRIC, scene.mat_ior[m], 1.0))
        refl = wr > 0
        ok &= wt > 0
        if 2 * len(j) > 8 * n0:  # too many lanes: where both lobes are open, go one way at random
            both = refl & ok
            coin = rng.random(len(j)) < 0.5
            refl &= ~(both & coin)
            ok &= ~(both & ~coin)
            wr, wt = np.where(both, 2 * wr, wr), np.where(both, 2 * wt, wt)
        wj = w[j]
        hj = hist[j]
        lr, lt = letters[j].copy(), letters[j].copy()
        lr[:, depth], lt[:, depth] = 1, 2
        d = np.concatenate([reflect(w_in[refl], ns[refl]), d_t[ok]])
        o = tracer.spawn(np.concatenate([p[refl], p[ok]]), np.concatenate([ng[refl], ng[ok]]), d)
        w = np.concatenate([(wj * wr)[refl], (wj * wt)[ok]])
        hist = np.concatenate([hj[refl], hj[ok]])
        letters = np.concatenate([lr[refl], lt[ok]])
        if rough is not None:
            o, d, w = np.concatenate([o, ro]), np.concatenate([d, rd]), np.concatenate([w, rw])
            hist, letters = np.concatenate([hist, rh]), np.concatenate([letters, rlet])
    if out:
        return tuple(np.concatenate(x) for x in zip(*out)) + (rays,)
    return (np.zeros((0, max_bounces), np.int64), np.zeros((0, max_bounces), np.int8), np.zeros(0, np.int64),
            np.zeros(0), np.zeros((0, 3)), rays)


MIN_SAMPLE_SHARE = 1.0 / 16.0


def sample_share(ratio: float) -> float:
    """The share of a light's samples for a world whose caustic can be at most `ratio` of the lamps'
    (caustic_irradiance): sqrt(ratio), from 1/16 to 1. Samples in proportion to each light's noise
    (Neyman) would give it `ratio`; its own noise per sample is the larger (its directions fill the
    sphere), so the root. Blender's default grey beside the glass ball's area light: ratio 0.033,
    0.18 of the samples."""
    return float(min(1.0, max(MIN_SAMPLE_SHARE, math.sqrt(max(ratio, 0.0)))))


def caustic_irradiance(at: np.ndarray, w: np.ndarray, scale: float) -> float:
    """The irradiance of a caustic over its bright part, from pilot photons landing at ``at`` (K,3)
    with flux ``w`` (K,): their flux summed in cubes of side scale / CELLS, the mean over the cubes
    holding more than 5% of the fullest one's (as convergence.caustic_region picks pixels), per
    unit area. Cubes wider than the caustic's focus dilute it, so it errs low: a world compared
    with it is left out only when its caustic is surely faint. 0 for no photon."""
    if not len(at):
        return 0.0
    h = scale / CELLS
    _, inv = np.unique(np.floor(at / h).astype(np.int64), axis=0, return_inverse=True)
    cell = np.bincount(inv.ravel(), weights=w)
    bright = cell > 0.05 * cell.max()
    return float(cell[bright].sum() / (bright.sum() * h * h))


def chain_letters(row) -> str:
    """Chain letters of one pilot path, the receiver's side first (the walks' order)."""
    return "".join("R" if c == 1 else "T" for c in row[::-1] if c)


def _chain_flux(letters: np.ndarray, w: np.ndarray) -> dict:
    """{chain letters: flux} of pilot paths (letters (K, bounces) as _pilot gives them, w (K,)
    their flux), the chains in the order they first appear. Each chain's flux is added up in the
    paths' order, one path after the other (np.bincount), as a loop over the paths would."""
    if not len(letters):
        return {}
    rows, first, inv = np.unique(letters, axis=0, return_index=True, return_inverse=True)
    flux = np.bincount(inv.ravel(), weights=w, minlength=len(rows))
    return {chain_letters(rows[u]): float(flux[u]) for u in np.argsort(first, kind="stable")}


def spot_target(scene, li: int, sphere: np.ndarray) -> tuple[np.ndarray, float]:
    """Where light li's photons aim at a sphere (1,4) that holds what they may light (the
    diffuse surfaces for the plan's pilots, the scene for the bake's photons after a diffuse
    bounce): for a narrow spot, a sphere filling its cone instead, so the photons are not
    masked away. Aimed at the whole diffuse bounding sphere, a 16 deg spot kept 2% of its pilots,
    and a crescent of floor it lights past a glass ball (glass_spot.blend) got none: the plan
    dropped its light through a diffuse bounce, 1.3% of the layer, 5-25% of it 30-200 px from
    the focus.

    Returns (the target, the share of the photons aimed at the sphere that the spot lets
    through at most: the solid angle of the new aim over the old one's, 1 where unchanged)."""
    if scene.light_type[li] != S.SPOT:
        return sphere, 1.0
    c = scene.light_matrix[li][:3, 3]
    axis = light_axis(scene, li)
    dist = float(np.linalg.norm(sphere[0, :3] - c))
    half = 0.5 * float(scene.light_spot_size[li])  # the cone masks directions (lights.spot_mask)
    if not (dist > 0 and half < math.radians(60.0)):
        return sphere, 1.0
    target = np.concatenate([c + dist * axis, [dist * math.sin(half)]])[None, :]
    r = float(scene.light_radius[li])  # lights.emit widens each aim by the light's radius

    def solid_angle(radius):
        s = (radius + r) / dist
        return 4.0 * math.pi if s >= 1.0 else 2.0 * math.pi * (1.0 - math.sqrt(1.0 - s * s))

    return target, min(1.0, solid_angle(target[0, 3]) / solid_angle(float(sphere[0, 3])))


def _caster_pilot(scene, tracer, cam, plan, seen, seed, lp, k, pilots, max_bounces):
    """refine_plan's pilots of light lp's k-th caster: (photons, rays, None where none of its
    caustic lands in view, else (chain shares, receiver names, flux, casters met, where the
    pilots land, their flux))."""
    from ..shading.lights import emit

    o = lp.caster_objects[k]
    rng = stream(seed, PILOT_CASTER, lp.key, light_key(scene.object_names[o]))
    ph = emit(scene, lp.index, lp.targets[k:k + 1], pilots, rng)
    hist, letters, recv, wgt, at, r = _pilot(scene, tracer, cam, plan, ph, *seen, rng, max_bounces, o)
    first = hist[:, 0] == o
    flux = float(wgt[first].sum())
    if not flux > 0:
        return pilots, r, None
    chains = _chain_flux(letters[first], wgt[first])
    return pilots, r, ({t: v / flux for t, v in chains.items()},
                       [scene.object_names[x] for x in np.unique(recv[first])], flux,
                       {int(x) for x in np.unique(hist[first]) if x >= 0}, at[first], wgt[first])


def _indirect_pilot(scene, tracer, cam, plan, seen, seed, li, n_ind, dif_sphere, max_bounces):
    """refine_plan's pilots of light li through a diffuse bounce: n_ind photons onto the diffuse
    surfaces (the sphere dif_sphere), a cosine bounce, then _pilot. (photons, rays, None where
    none lands in view, else (flux, casters met, receiver names))."""
    from ..shading.lights import Photons, emit
    from ..core.vec import cosine_hemisphere, frame, to_world

    rng = stream(seed, PILOT_INDIRECT, light_key(scene.light_names[li]))
    ph = emit(scene, li, spot_target(scene, li, dif_sphere)[0], n_ind, rng)  # onto the diffuse surfaces
    lit = np.flatnonzero(ph.w.max(axis=1) > 0)
    h = tracer.intersect_past(ph.o[lit], ph.d[lit], 0, ph.unshadowing)  # past what does not shadow it
    i = np.flatnonzero(h.hit)
    mat = scene.tri_material[h.prim[i]]
    dif = scene.mat_kind[mat] == S.DIFFUSE
    if ph.lit is not None:  # Light Linking: a diffuse surface the light does not light sends none of it on
        dif &= ph.lit[scene.tri_object[h.prim[i]]]
    dif = np.flatnonzero(dif)
    if dif.size == 0:
        return n_ind, lit.size, None
    j = i[dif]
    ng = h.ng[j] * np.sign(-dot(ph.d[lit[j]], h.ng[j]))[:, None]  # the lit side
    s_, t_ = frame(ng)
    d2 = to_world(cosine_hemisphere(rng.random(j.size), rng.random(j.size)), s_, t_, ng)
    w2 = ph.w[lit[j]] * scene.mat_color[mat[dif]]  # cosine sampling: the albedo
    bounce = Photons(tracer.spawn(h.p[j], ng, d2), d2, w2)
    hist, letters, recv, wgt, _, r = _pilot(scene, tracer, cam, plan, bounce, *seen, rng, max_bounces, None)
    if not wgt.sum() > 0:
        return n_ind, lit.size + r, None
    return n_ind, lit.size + r, (float(wgt.sum()), {int(x) for x in np.unique(hist) if x >= 0},
                                 [scene.object_names[x] for x in np.unique(recv)])


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
        seen = (direct, through, sides)
        # every light's pilots per caster, then each indirect light's (caustics through a diffuse
        # bounce first, light -> diffuse -> caster -> ... -> seen; indirect.py): tasks the threads
        # take in turn, each with its own random stream; their answers are read in task order
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
        indirect = {}
        for (i, _, k, o), (n, r, out) in zip(tasks, lanes.blocks(task, len(tasks), 1, tracer.threads)):
            photons += n
            rays += r
            if out is not None and i is None:
                indirect[k] = out
            elif out is not None:
                found[i][o] = out
        total = sum(f[2] for per in found for f in per.values()) + sum(v[0] for v in indirect.values())
        lamps = [f for lp, per in zip(plan.lights, found) if scene.light_type[lp.index] != S.WORLD
                 for f in per.values()]
        lamps_E = caustic_irradiance(np.concatenate([f[4] for f in lamps]) if lamps else np.zeros((0, 3)),
                                     np.concatenate([f[5] for f in lamps]) if lamps else np.zeros(0), plan.scale)
        faint = {}  # worlds too faint to show: light index -> their brightest caustic / the lamps'
        for li in dict.fromkeys([lp.index for lp in plan.lights] + list(plan.indirect_lights)):
            if scene.light_type[li] == S.WORLD and lamps_E > 0:
                env = env_map(scene, li)  # the most a plane can receive: pi L, or a map's luminance over the sphere
                bound = env.power if env is not None else math.pi * float(np.mean(scene.light_color[li]))
                share = sample_share(bound / lamps_E)
                if bound < WORLD_MIN_SHARE * lamps_E:
                    faint[li] = bound / lamps_E
                elif share < 1.0:
                    plan.sample_share[li] = share
        kept_lights, no_direct = [], []
        used = np.zeros_like(plan.casters)
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
        ind_keep = []
        for li in plan.indirect_lights:
            if li in faint:
                continue
            # any landing keeps it: these pilots start at the first diffuse hit straight from the
            # light, so they undercount light that meets glass first (a pool's floor under water)
            if li in indirect:
                ind_keep.append(li)
                met = sorted(indirect[li][1])
                used[met] = True
                plan.indirect_words.append(
                    f"{scene.light_names[li]} -> diffuse -> {', '.join(scene.object_names[o] for o in met)} -> "
                    f"{', '.join(indirect[li][2])} (after a diffuse bounce)")
        plan.indirect_lights = ind_keep
        for li, share in faint.items():
            plan.skipped.append(("light", scene.light_names[li], f"{FAINT} (at most {share:.1%} of the lamps' "
                                 "caustic)"))
        for lp in no_direct:
            if lp.index not in ind_keep:
                plan.skipped.append(("light", lp.name, "its caustics land on nothing the camera sees"))
        for o in np.flatnonzero(plan.casters & ~used):  # out of every light's plan: one line for it
            name = scene.object_names[o]
            why = [n for n in plan.notes if n.startswith(name + " skipped for ")]
            plan.skipped.append(("caster", name, FAINT if any(FAINT in n for n in why) else
                                 "its caustic lands on nothing the camera sees"))
            plan.notes = [n for n in plan.notes if n not in why]
        plan.lights = kept_lights
        plan.casters = used
        if not plan.lights and not plan.indirect_lights:
            plan.nothing = "no caster's caustic lands on anything the camera sees"
        _finish(plan, scene)
    plan.cost = {"rays": int(rays), "pilot_photons": int(photons), "time_s": time.perf_counter() - t0}
    return plan
