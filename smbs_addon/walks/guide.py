"""Where can caustics land? A cheap photon pre-pass that steers the walks.

Before the manifold pass, a few photons per light are traced through the
specular chains (the same sampler as the reference) and the screen tiles their
first diffuse hit projects to are marked, per light and per chain type. A
receiver in an unmarked tile is walked only with probability Q (and weighted by
1/Q, Russian roulette), so the estimate stays unbiased while most walks that
could never converge (receivers outside every caustic) are never started.
Both the marks and the receivers are keyed by where the receiver point itself
projects (the photons' hits are projected without asking whether the camera sees
them), so a receiver seen through mirrors or glass is looked up at its own
projection, not at the pixel it shows up in: the floor seen through a glass ball
is walked where photons reached that floor. Receivers that project outside the
marked tiles (behind the camera, off screen) are always walked.
"""
from __future__ import annotations

import math

import numpy as np

from ..scene import arrays as S
from ..scene.light_paths import Limits, ONE_DIFFUSE, specular_kind
from ..core.vec import box
from ..shading.lights import area_light_shape, distant_cone, emit
from ..shading.optics import absorbing, arriving, inside, transmittance
from ..paths.photons import scatter_specular
from ..shading.microfacet import rough_objects
from ..core import lanes

TILE = 4  # pixels per tile side
Q = 0.125  # walk probability in tiles no photon reached
# A chain type is left to the photons (bake's hand-off) when it brings less than WEAK_SHARE of a
# light's flux onto the receivers in frame, or when its brightest tile gets less than WEAK_PEAK of
# the brightest tile of any chain type of that light: a faint glow, whose noise hardly shows, for
# which light tracing costs a fraction of the walks (e.g. a glass ball's reflection, next to its
# refracted focus). Tiles are compared averaged over 3 x 3 tiles (PEAK_RADIUS): the brightest
# single tile of a faint, wide glow is the one its few photons happened to crowd, and decided the
# glass ball's reflection by the random stream (peak 0.023-0.091 over seeds 1-8, 512 x 512;
# averaged, 0.006-0.012).
WEAK_SHARE = 0.02
WEAK_PEAK = 0.05
PEAK_RADIUS = 1


def _code(types: str) -> int:
    c = 0
    for ch in types:
        c = c * 3 + (1 if ch == "R" else 2)
    return c


def photon_budget(cam) -> int:
    x0, x1, y0, y1 = cam.region
    tiles = ((x1 - x0) // TILE + 1) * ((y1 - y0) // TILE + 1)
    return int(min(2_000_000, max(50_000, 16 * tiles)))


class Guide:
    def __init__(self, cam, masks: dict, stats: dict, weak=frozenset()):
        self.cam, self.masks, self.stats = cam, masks, stats
        self.weak = weak  # {(light index, chain type)} whose direct receivers the photons serve
        x0, x1, y0, y1 = cam.region
        self.tx0, self.ty0 = x0 - TILE, y0 - TILE

    def is_weak(self, li, types) -> bool:
        return (li, types) in self.weak

    def keep_probability(self, li, types, rx, ry, eye_specular, points=None):
        """Per receiver: 1 inside the marked tiles (or when not guidable), Q elsewhere.

        rx, ry: the film position of each eye sample; points (M,3): the receiver points,
        needed for those seen through mirrors or glass (eye_specular > 0), which are
        looked up where the point itself projects (always walked without points)."""
        m = self.masks.get((li, types))
        n = len(rx)
        if m is None:
            return np.ones(n)
        rx, ry = np.array(rx, float), np.array(ry, float)
        seen = eye_specular > 0
        known = ~seen
        if points is not None and seen.any():
            px, py, _, _, _, valid = self.cam.project(points[seen])
            rx[seen], ry[seen] = px, py
            known[seen] = valid
        tx = np.floor((rx - self.tx0) / TILE)
        ty = np.floor((ry - self.ty0) / TILE)
        # the tiles a photon can mark (build_guide's `ok`, dilated by one): a point beyond them
        # is somewhere the pre-pass did not look
        inside = known & (tx >= 0) & (ty >= 0) & (tx < m.shape[1]) & (ty < m.shape[0])
        inside &= ~seen | ((tx >= 1) & (ty >= 1) & (tx < m.shape[1] - 1) & (ty < m.shape[0] - 1))
        hit = np.zeros(n, bool)
        i = np.flatnonzero(inside)
        hit[i] = m[ty[i].astype(np.int64), tx[i].astype(np.int64)]
        return np.where(hit | (seen & ~inside), 1.0, Q)


def hidden_in_reach(scene, tracer, plan) -> bool:
    """Does an object whose Ray Visibility leaves out diffuse, glossy or transmission rays lie where
    the pre-pass's photons may meet it? They leave the planned lights for the planned casters and
    go on to the receivers: within the box around what takes part (plan.bounds) and the lights'
    own extent, or, from a sun, in the box's shadow towards the sun (a cylinder widened by the
    sun's angle); from the world, anywhere. The pre-pass traces past no surface, so such an object
    in reach turns it off (bake.py); one out of reach (a glass ball 40 m beyond the floor whose
    Ray Visibility is off for diffuse rays, skipped by the plan) changes nothing it traces, and
    turned it off all the same: every walk unguided, the image another."""
    if not tracer.hid.size:
        return False
    hiding = np.flatnonzero(tracer.hid & S.PATH_RAYS)
    if hiding.size == 0:
        return False
    lo, hi = (np.array(x, float) for x in plan.bounds)
    suns = []
    for lp in plan.lights:
        li = lp.index
        typ = scene.light_type[li]
        if typ == S.WORLD:
            return True
        if typ == S.SUN:
            axis, half, _ = distant_cone(scene, li)
            suns.append((axis, half))
            continue
        if typ == S.MESH:
            pts = scene.mesh_light(li)[1].reshape(-1, 3)
        elif typ == S.AREA:
            cen, ex, ey, _, hx, hy, _ = area_light_shape(scene, li)
            pts = np.array([cen + a * hx * ex + b * hy * ey for a in (-1, 1) for b in (-1, 1)])
        else:
            c, r = scene.light_matrix[li][:3, 3], float(scene.light_radius[li])
            pts = np.array([c - r, c + r])
        lo, hi = np.minimum(lo, pts.min(axis=0)), np.maximum(hi, pts.max(axis=0))
    mid, rad = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2
    for o in hiding:
        olo, ohi = scene.object_bounds(int(o))
        c, r = (olo + ohi) / 2, float(np.linalg.norm(ohi - olo)) / 2
        if np.linalg.norm(np.maximum(0.0, np.maximum(lo - c, c - hi))) <= r:
            return True  # in the box
        for axis, half in suns:  # the photons come along axis: from mid - t axis, t > 0
            v = c - mid
            t = -float(np.dot(v, axis))
            off = float(np.linalg.norm(v + t * axis))
            if t > -(rad + r) and off <= rad + r + math.tan(min(half, 1.5)) * max(t, 0.0):
                return True
    return False


def build_guide(scene, tracer, cam, plan, types_list, rng, photons_per_light, max_bounces=16, check=None):
    """Trace photons_per_light photons per planned light and mark tiles per chain type.
    check() is called between bounces (it raises to cancel).

    A light's photons are traced in parts of GUIDE_PART (_guide_part) that the threads take in
    turn, each from its own random stream (keyed by one draw per light from rng and the part's
    first photon), and added up in part order: the guide does not depend on the thread count."""
    x0, x1, y0, y1 = cam.region
    nx = (x1 - x0 + 2 * TILE) // TILE + 2
    ny = (y1 - y0 + 2 * TILE) // TILE + 2
    masks = {}
    stats = {"photons": 0, "rays": 0, "flux_share": {}, "peak_share": {}, "other_share": {},
             "beyond_max_chain_share": {}}
    weak = set()
    for lp in plan.lights:
        key = int(rng.integers(2**62))

        def part(a, b, lp=lp, key=key):
            return _guide_part(scene, tracer, cam, plan, lp, types_list, np.random.default_rng([key, a]), b - a,
                               photons_per_light, (nx, ny), max_bounces, check)

        parts = lanes.blocks(part, photons_per_light, GUIDE_PART, tracer.threads)
        marks, flux, other = parts[0][0], parts[0][1], parts[0][2]
        for pm, pf, po, _ in parts[1:]:
            for t in types_list:
                marks[t] |= pm[t]
                flux[t] += pf[t]
            other += po
        stats["photons"] += photons_per_light
        stats["rays"] += sum(p[3] for p in parts)
        for t in types_list:
            masks[(lp.index, t)] = marks[t]
        walked = sum(float(f.sum()) for f in flux.values())
        total = walked + other[0]  # shares are of all the light the pre-pass brought into the frame
        smooth = {t: float(box(f, PEAK_RADIUS).max()) for t, f in flux.items()}
        top = max(smooth.values()) if smooth else 0.0
        share = {t: (float(f.sum()) / total if total > 0 else 0.0) for t, f in flux.items()}
        stats["other_share"][lp.name] = other[0] / total if total > 0 else 0.0
        stats["beyond_max_chain_share"][lp.name] = other[1] / total if total > 0 else 0.0
        peak = {t: (v / top if top > 0 else 0.0) for t, v in smooth.items()}
        stats["flux_share"][lp.name] = share
        stats["peak_share"][lp.name] = peak
        weak |= {(lp.index, t) for t in types_list
                 if walked > 0 and (share[t] * total / walked < WEAK_SHARE or peak[t] < WEAK_PEAK)}
    return masks, stats, frozenset(weak)


GUIDE_PART = 32768  # photons per part of build_guide's pre-pass


def _guide_part(scene, tracer, cam, plan, lp, types_list, rng, n, total, tiles, max_bounces, check):
    """n photons of the total of light lp traced through the specular chains: (marks, flux per
    chain type on the (ny, nx) tiles, the flux in frame of other chains [all, longer than the
    longest type], rays cast). Weighed as one of total photons (emit weighs by 1/n)."""
    x0, x1, y0, y1 = cam.region
    nx, ny = tiles
    max_chain = max((len(t) for t in types_list), default=0)
    limits = Limits.of(scene)
    marks = {t: np.zeros((ny, nx), bool) for t in types_list}
    flux = {t: np.zeros((ny, nx)) for t in types_list}  # arriving on receivers in the frame
    ph = emit(scene, lp.index, lp.targets, n, rng, plan.bounds)
    o, d, beta = ph.o, ph.d, ph.w * (n / total)
    sig = np.zeros(len(o), np.int64)  # chain signature in base 3 (R = 1, T = 2), light side first
    length = np.zeros(len(o), np.int64)
    # events as trace_photons counts them: the specular ones but the first (the one next to the
    # light: free under Cycles' Light Paths limits, bounces.py)
    cnt = np.zeros((len(o), 3), np.int64)
    other = np.zeros(2)  # flux in frame of chains not in types_list: [all of them, those longer than max_chain]
    rays = 0
    medium = np.full(len(o), -1)  # inside a glass (its material) or not: its Volume Absorption
    rough = rough_objects(scene)
    via_rough = np.zeros(len(o), bool)  # through a rough mirror or glass: no walk's (the photons')
    absorbs = absorbing(scene)
    for bounce in range(max_bounces + 1):
        if check is not None:
            check()
        if len(o) == 0:
            break
        # the first segment passes what does not shadow the light (Shadow Linking)
        h = tracer.intersect_past(o, d, 0, None if bounce else ph.unshadowing)
        rays += len(o)
        idx = np.flatnonzero(h.hit)
        o, d, beta, sig, length, via_rough = o[idx], d[idx], beta[idx], sig[idx], length[idx], via_rough[idx]
        cnt = cnt[idx]
        prim = h.prim[idx]
        mat = scene.tri_material[prim]
        if absorbs:
            medium = medium[idx]
            seg_medium = arriving(scene, medium, mat, np.ones(len(idx), bool), d, h.ng[idx])
            beta = beta * transmittance(scene, seg_medium, h.t[idx])
        kind = scene.mat_kind[mat]
        obj = scene.tri_object[prim]
        # a planned caster, first one the light lights (Light Linking): a photon meeting a mirror or glass the
        # plan leaves out ends there, as where it meets nothing (no walk takes a path through one; the
        # random numbers its scattering drew moved every later photon's: a glass ball 50 m away, hidden
        # from diffuse rays, met by 37 rays of a bake's pre-pass, changed the walks over a third of it)
        spec = ((kind == S.CONDUCTOR) | (kind == S.DIELECTRIC)) & plan.casters[obj]
        if bounce == 0:
            spec &= True if ph.lit is None else ph.lit[obj]
        diff = np.flatnonzero((kind == S.DIFFUSE) & plan.receivers[obj] & (bounce > 0))
        if diff.size:
            rx, ry, _, _, _, valid = cam.project(h.p[idx][diff])
            tx = np.floor((rx - (x0 - TILE)) / TILE).astype(np.int64)
            ty = np.floor((ry - (y0 - TILE)) / TILE).astype(np.int64)
            ok = valid & (tx >= 1) & (ty >= 1) & (tx < nx - 1) & (ty < ny - 1)
            # only light Cycles renders counts, as a receiver seen directly would get it (x0's
            # diffuse bounce and the chain's events but the last fit the Light Paths limits)
            ok &= limits.fits(cnt[diff] + ONE_DIFFUSE)
            known = np.zeros(diff.size, bool)
            for t in types_list:
                known |= sig[diff] == _code(t[::-1])
            known &= ~via_rough[diff]
            lum = beta[diff].mean(axis=1)
            other[0] += float(lum[ok & ~known].sum())
            other[1] += float(lum[ok & ~known & (length[diff] > max_chain)].sum())
            for t in types_list:
                sel = ok & known & (sig[diff] == _code(t[::-1]))  # photons list vertices from the light
                if sel.any():
                    np.add.at(flux[t], (ty[sel], tx[sel]), beta[diff][sel].mean(axis=1))
                    m = marks[t]
                    for dy in (-1, 0, 1):  # dilate by one tile
                        for dx in (-1, 0, 1):
                            m[ty[sel] + dy, tx[sel] + dx] = True
        si = np.flatnonzero(spec)
        if si.size == 0 or bounce == max_bounces:
            break
        p, ng, ns = h.p[idx][si], h.ng[idx][si], h.ns[idx][si]
        d_new, beta, keep = scatter_specular(scene, rng, -d[si], ns, ng, mat[si], kind[si], beta[si],
                                             adjoint=True)
        letter = specular_kind(d[si][keep], d_new, ng[keep])  # 1 R (glossy), 2 T (transmission)
        sig = sig[si][keep] * 3 + letter
        length = length[si][keep]
        via_rough = via_rough[si][keep] | rough[obj[si][keep]]
        cnt = cnt[si][keep]
        if absorbs:
            medium = inside(scene, mat[si][keep], kind[si][keep] == S.DIELECTRIC, d_new, ng[keep])
        cnt[np.arange(len(letter)), letter] += length > 0
        length = length + 1
        o = tracer.spawn(p[keep], ng[keep], d_new)
        d = d_new
    return marks, flux, other, rays
