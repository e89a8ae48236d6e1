"""What the plan's pilot photons found, kept path by path (Pilots), how many a caster gets
(pilot_count, view_reach, topped_up), what the plan keeps of them (kept) and the bound on what it
leaves out (share_max). No ray is traced here: baking/pilots.py traces the pilots, plan.refine_plan
reads these.

A caster the plan leaves out must change nothing it keeps: its pilots' paths leave every sum,
share and receiver list (kept), and a caster catching little of a light's light is piloted with
few photons (pilot_count), then with as many more as bound what leaving it out leaves out
(topped_up, share_max: the rule of three).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

PLAN_MIN_SHARE = 1e-5  # a caster bringing less of the light the camera sees (by the pilots) is left out
# pilot_count: a caster catching at least this share of the light its light sends towards what the camera
# sees gets every pilot photon; one catching less, that many in proportion, at least MIN_PILOTS (a glass ball
# 57 m away under the lens scene's area light catches 2e-5 of it: 64 pilots, not 4096)
PILOT_FULL_SHARE = 0.01
MIN_PILOTS = 64
# a caster given more pilots than this is probed first (pilots._lit_points: shadow rays from this many points
# on it towards the light): where none is unblocked, something nearer hides it from the light (a ball under
# the floor, whose pilots stopped at the floor, 4,096 rays a light), and the plan leaves it out, with the
# bound 3 / HIDDEN_PROBE of the light aimed at it; else its pilots are traced as ever (after those rays)
HIDDEN_PROBE = 256
# more pilots for a caster the plan leaves out, where its first ones cannot bound what that leaves out
# below PLAN_MIN_SHARE (refine_plan's second round), and its pilots after a diffuse bounce (_bounce_pilot):
# up to this share of the pilots (256 of 4096: a glass ball 57 m from the lens scene, 64 first, is then
# bounded at 2.3e-5 of the light the camera sees, for 1,600 more rays)
MORE_PILOTS = 1 / 16
VIEW_PHOTONS = 1024  # photons (no rays: their weights) for a light's flux towards what the camera sees
# pilot paths after a diffuse bounce through a caster (met by the light's pilots onto the diffuse surfaces,
# kept, or aimed at it, _bounce_pilot) that keep it where they bring PLAN_MIN_SHARE: fewer are a chance meeting
MET_PATHS = 3


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


@dataclass
class Pilots:
    """What pilot photons (a light's towards one caster, or after a diffuse bounce) found: n photons
    traced, the flux they carried towards the caster, and per path landing in view: the casters it
    met (per bounce, -1 past its end or off a caster), its chain letters, its receiver, where it
    landed and the flux it brought."""

    n: int
    aimed: float
    paths: np.ndarray  # (K, bounces) int64
    letters: np.ndarray  # (K, bounces) int8
    recv: np.ndarray  # (K,) int64
    at: np.ndarray  # (K, 3)
    w: np.ndarray  # (K,)
    hidden: bool = False  # the light reaches none of HIDDEN_PROBE points on the caster: n is those

    @property
    def landed(self) -> float:
        return float(self.w.sum())

    @property
    def met(self) -> set:
        return {int(x) for x in np.unique(self.paths) if x >= 0}

    def receivers(self, scene) -> list:
        return [scene.object_names[x] for x in np.unique(self.recv)]

    def shares(self) -> dict:
        """Each chain type's share of the flux landing in view."""
        landed = self.landed
        return {t: v / landed for t, v in _chain_flux(self.letters, self.w).items()}

    def through(self, objs: np.ndarray) -> np.ndarray:
        """(K,) bool: the paths meeting one of the objects objs ((O,) bool)."""
        return np.any((self.paths >= 0) & objs[np.maximum(self.paths, 0)], axis=1)

    def without(self, objs: np.ndarray) -> "Pilots":
        """These pilots with the paths meeting one of the objects objs ((O,) bool) left out."""
        keep = ~self.through(objs)
        if keep.all():
            return self
        return dataclasses.replace(self, paths=self.paths[keep], letters=self.letters[keep], recv=self.recv[keep],
                                   at=self.at[keep], w=self.w[keep])

    def add(self, more: "Pilots") -> "Pilots":
        """These pilots and more (the next photons of the same emission), weighed as one set."""
        n = self.n + more.n
        a, b = self.n / n, more.n / n
        return Pilots(n, a * self.aimed + b * more.aimed, np.concatenate([self.paths, more.paths]),
                      np.concatenate([self.letters, more.letters]), np.concatenate([self.recv, more.recv]),
                      np.concatenate([self.at, more.at]), np.concatenate([a * self.w, b * more.w]))

    @staticmethod
    def none(n: int, aimed: float, bounces: int, hidden: bool = False) -> "Pilots":
        return Pilots(n, aimed, np.zeros((0, bounces), np.int64), np.zeros((0, bounces), np.int8),
                      np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0), hidden)


def pilot_count(aimed: float, view: float, pilots: int, reach: float = 1.0) -> int:
    """The pilot photons a caster gets first from a light sending it the flux `aimed` (towards its
    bounding sphere), where the same light sends `view` towards what the camera sees (the receiver
    points its look found): all `pilots` for a caster catching at least PILOT_FULL_SHARE of that,
    fewer in proportion below it, at least MIN_PILOTS (refine_plan adds more where those cannot
    bound what is left out). reach: view_reach, the share of the caster's light that could head
    where the camera looks, against a caster beside it. Every pilot where either flux is unknown (0)."""
    if not (aimed > 0 and view > 0) or pilots <= MIN_PILOTS:
        return int(pilots)
    return int(min(pilots, max(MIN_PILOTS, math.ceil(pilots * aimed * reach / (PILOT_FULL_SHARE * view)))))


def view_reach(view_sphere, sphere) -> float:
    """How much of the directions leaving a caster (its bounding sphere (4,)) meet what the camera
    sees (view_sphere (1,4), or None: unknown), against a caster beside it: 1 within twice the view's
    radius (and its own) of the view's centre, else (2 (R + r) / distance)^2, the solid angle's fall.
    A sun or the world lights a far caster as much as a near one; its light heads where the camera
    looks that much less (a glass ball 60 m from a view 4 m across: 0.02)."""
    if view_sphere is None:
        return 1.0
    near = 2.0 * (float(view_sphere[0, 3]) + float(sphere[3]))
    d = float(np.linalg.norm(np.asarray(sphere[:3]) - view_sphere[0, :3]))
    return 1.0 if d <= near else (near / d) ** 2


def share_max(p: Pilots | None, total: float) -> float:
    """An upper bound (about 95%) on the share of the light the camera sees that a caster's
    left-out caustic carries, by its pilots p: what they brought into view, and 3 / n of the flux
    they carried (the rule of three: with none of n landing, the chance of a landing is below 3 / n)."""
    if p is None or not total > 0:
        return 0.0
    return (p.landed + (3.0 * p.aimed / p.n if p.n else 0.0)) / total


def topped_up(p: Pilots, total: float, pilots: int) -> int:
    """The photons a caster's pilots p need in all so that, landing no more than they did, what they
    leave out is bounded below PLAN_MIN_SHARE of total, at most MORE_PILOTS of the pilots (or p.n,
    if more); p.n where they need none (they land enough to be kept, or are enough)."""
    need = PLAN_MIN_SHARE * total - p.landed
    if p.hidden or not need > 0 or not p.aimed > 0 or share_max(p, total) <= PLAN_MIN_SHARE:
        return p.n
    return int(min(max(p.n, math.ceil(MORE_PILOTS * pilots)), math.ceil(3.0 * p.aimed / need)))


def bounce_count(most: float, sent: float, need: float, pilots: int) -> int:
    """The pilots after a diffuse bounce aimed at a left-out caster (pilots._bounce_pilot): enough that
    none landing in view bounds its flux there below `need` (3 / n of `most`, the most the lit points
    can send into it: the rule of three), or as many as pilot_count gives a caster catching `most` of
    the light `sent` on by the lit points, whichever is fewer; from MIN_PILOTS to MORE_PILOTS of the
    pilots."""
    cap = max(MIN_PILOTS, math.ceil(MORE_PILOTS * pilots))
    enough = math.ceil(3.0 * most / need) if need > 0 else cap
    return int(min(cap, max(MIN_PILOTS, min(enough, pilot_count(most, sent, pilots)))))


@dataclass
class Kept:
    """What the plan keeps of its pilots (kept)."""

    own: list  # per light: the casters whose own pilots bring at least PLAN_MIN_SHARE of the light seen
    found: list  # per light {caster: Pilots}, as found
    indirect: dict  # {light: Pilots after a diffuse bounce} without the paths through what is left out
    total: float  # the light the camera sees, summed over what is kept
    total0: float  # and over every pilot


def kept(flag, found, indirect) -> Kept:
    """What the plan keeps of the pilots found (per light {caster: Pilots}) and indirect ({light:
    Pilots after a diffuse bounce}): per light the casters whose own pilots bring at least
    PLAN_MIN_SHARE of the light the camera sees (all of it, first); the indirect pilots without the
    paths that meet a caster kept neither so nor met on those pilots' paths nor on at least MET_PATHS
    of the indirect ones bringing PLAN_MIN_SHARE; the light the camera sees summed over what is kept,
    and over all. A caster far too faint to show changes no sum, no share and no receiver: a glass
    ball 60 m away met by one pilot path after a diffuse bounce was planned ('Disk -> diffuse -> C0,
    X -> Floor'), and that path's flux changed every share; such a caster is judged by its own pilots
    after a bounce (pilots._bounce_pilot)."""
    total0 = sum(p.landed for per in found for p in per.values()) + sum(p.landed for p in indirect.values())
    own = [{o for o, p in per.items() if p.landed > 0 and not p.landed < PLAN_MIN_SHARE * total0} for per in found]
    keep = np.zeros(len(flag), bool)
    for per, ow in zip(found, own):  # a light's casters and those its kept pilots meet on the way (as ever)
        for o, p in per.items():
            if o in ow:
                keep[o] = True
                keep[sorted(p.met)] = True
    via = np.zeros(len(flag))  # the light the pilots after a diffuse bounce bring through each caster
    paths = np.zeros(len(flag), np.int64)  # and on how many paths
    for p in indirect.values():
        for m in p.met:
            one = np.zeros(len(flag), bool)
            one[m] = True
            on = p.through(one)
            via[m] += float(p.w[on].sum())
            paths[m] += int(on.sum())
    keep |= (paths >= MET_PATHS) & ~(via < PLAN_MIN_SHARE * total0)
    out = flag & ~keep
    kept_indirect = {li: p.without(out) for li, p in indirect.items()}
    # summed in the order the pilots ran (the casters' by object, the lights' by light): the order the
    # plan without the left-out casters sums them in, to the bit
    total = (sum(p.landed for per, ow in zip(found, own) for o, p in per.items() if o in ow)
             + sum(p.landed for p in kept_indirect.values()))
    return Kept(own, found, kept_indirect, total, total0)
