"""The gather after a diffuse bounce in numpy, one diffuse bounce and its specular chain at a time
(gather.gather_radiance's form where the paths no walk takes are added along the way: a rough
caster's, a chain type not walked; and the tests' second estimator beside the compiled one).
"""
from __future__ import annotations

import numpy as np

from ..core import qmc
from ..shading import coat as layer, optics
from ..scene import arrays as S
from ..scene.light_paths import GLOSSY_EVENTS, Limits, ONE_DIFFUSE, specular_kind
from ..trace.eye import Receivers, surface_at
from ..shading.microfacet import walk_casters
from ..core.vec import dot
from .handoff import chain_letters
from .path_light import MAX_SPECULAR, albedo, diffuse_bounce, direct_light, seen_light
from .photons import scatter_specular


class GatherByGenerations:
    """gather's generations in numpy, one diffuse bounce and its specular chain at a time: what
    the walks' connect needs at every diffuse vertex (a Python callback), and the tests' second
    form of _traced_gather's compiled paths."""

    def __init__(self, scene, tracer, plan, rc, rng, stats, physical, others):
        self.scene, self.tracer, self.plan, self.rc, self.rng, self.stats = scene, tracer, plan, rc, rng, stats
        self.physical = physical
        self.lim = Limits.of(scene)
        self.radiance = np.zeros((len(rc.p), 3))
        self.others = {li: ho for li, ho in (others or {}).items() if ho.others}
        self.walked = walk_casters(scene, plan.casters) if self.others else None  # objects a walk takes
        self.absorbing = optics.absorbing(scene)

    def run(self, lights_direct, connect, lights_hit, count_first) -> np.ndarray:
        """The radiance (n,3) gathered at each receiver."""
        rc = self.rc
        n = len(rc.p)
        # the frontier: diffuse vertices to bounce from, with the events before them
        front = dict(lane=np.arange(n), p=rc.p, ng=rc.ng, ns=rc.ns, w=rc.w_eye, beta=rc.beta, mat=rc.mat,
                     cnt=rc.prior, has_s=np.zeros(n, bool), depth=np.zeros(n, np.int64))
        while len(front["lane"]):
            nxt = self._generation(front, lights_direct, connect, lights_hit, count_first)
            if not nxt:
                break
            front = {key: np.concatenate([g[key] for g in nxt]) for key in nxt[0]}
        return self.radiance

    def _generation(self, f, lights_direct, connect, lights_hit, count_first) -> list:
        """One diffuse bounce from the frontier f and the specular chain after it: the next
        frontier's parts (one per specular bounce that met diffuse vertices)."""
        scene, lim = self.scene, self.lim
        # a diffuse bounce is never a caustic path's last event: it must fit the limits
        go = np.flatnonzero(lim.fits(f["cnt"] + ONE_DIFFUSE))
        first = np.flatnonzero(f["depth"][go] == 0)  # bounces off x0: stratified where its sample is
        strat = None if self.rc.strata is None else (first, self.rc.strata[f["lane"][go[first]], qmc.BOUNCE])
        d, beta, k = diffuse_bounce(self.rng, f["w"][go], f["ng"][go], f["ns"][go], f["beta"][go],
                                     albedo(scene, f["mat"][go]), False, strat)
        sel = go[k]
        x0 = np.flatnonzero(f["depth"][sel] == 0)
        if x0.size and layer.has_layers(scene):  # x0 under a Principled coat (kernels/gather.py's gather_rows the same)
            beta[x0] = beta[x0] * optics.coat_factor(scene, f["mat"][sel[x0]], f["ns"][sel[x0]], f["w"][sel[x0]],
                                                     d[x0])
        cnt = f["cnt"][sel] + ONE_DIFFUSE  # every event so far
        m = len(sel)
        path = dict(lane=f["lane"][sel], beta=beta, has_s=f["has_s"][sel], depth=f["depth"][sel], d=d, cnt=cnt,
                    before=cnt.copy(),  # the events before the latest
                    last_caster=np.zeros(m, bool),
                    last_obj=np.full(m, -1),  # the latest specular vertex's object (Light Linking's)
                    last_refl=np.zeros(m, bool),  # the latest specular event a reflection (a glossy ray leaves it)
                    medium=np.full(m, -1),  # inside a glass (its material) or not
                    # the chain since the latest diffuse vertex: its letters (bit 1: R, the first vertex
                    # the highest, as reference._chain_codes) and whether every vertex is on a walked caster
                    code=np.zeros(m, np.int64), on=np.ones(m, bool))
        o = self.tracer.spawn(f["p"][sel], f["ng"][sel], d)
        nxt = []
        for bounce in range(MAX_SPECULAR + 1):
            if len(path["lane"]) == 0:
                break
            h, prim, hmat, kind = self._segment(path, o, bounce, connect, lights_hit, count_first)
            diff = np.flatnonzero(kind == S.DIFFUSE)
            if diff.size:  # the next diffuse vertex
                nxt.append(self._diffuse_vertex(path, h, prim, hmat, diff, lights_direct, connect))
            spec = np.flatnonzero((kind == S.CONDUCTOR) | (kind == S.DIELECTRIC))
            if spec.size == 0 or bounce == MAX_SPECULAR:
                break
            path, o = self._specular(path, h, prim, hmat, kind, spec)
        return nxt

    def _segment(self, path, o, bounce, connect, lights_hit, count_first):
        """The segment from o along path["d"] to its next surface: the lights on it (others', and
        lights_hit's without connect), the absorption across it. Returns (hits, their prims,
        materials and kinds)."""
        scene, lim, lane, beta, d = self.scene, self.lim, path["lane"], path["beta"], path["d"]
        # past what the ray's kind does not meet: the diffuse bounce's, then the latest event's
        h = self.tracer.intersect_past(o, d, S.RAY_DIFFUSE if bounce == 0 else
                                       np.where(path["last_refl"], S.RAY_GLOSSY, S.RAY_TRANSMISSION))
        self.stats["rays_gather"] = self.stats.get("rays_gather", 0) + len(o)
        if self.others and bounce > 0:
            _count_others(scene, self.tracer, self.others, (o, d, h), path, bounce,
                          (path["depth"] >= 1) & lim.fits(path["before"]), self.radiance, self.stats)
        if connect is None and bounce > 0 and len(lights_hit):
            # Cycles' lights are transparent (shade_light adds the emission and the path
            # goes on): every light in front of the next surface counts, not the nearest
            surf_t = np.where(h.hit, h.t, np.inf)
            seen_l = np.zeros((len(o), 3))
            for li in lights_hit:
                seen, L, tl = seen_light(scene, self.tracer, li, o, d, path["last_refl"], surf_t, path["last_obj"])
                seen_l += np.where(seen[:, None], L, 0.0)
            count = np.flatnonzero(path["last_caster"] & ((path["depth"] >= 1) | count_first)
                                   & (seen_l.max(axis=1) > 0) & lim.fits(path["before"]))
            np.add.at(self.radiance, lane[count], beta[count] * seen_l[count])
        prim, hmat, kind = surface_at(scene, h)
        if self.plan.left_out is not None:
            # a path meeting a caster the plan left out ends there, as it ends where it meets nothing (its
            # light is that caster's caustic, which the plan bounds and drops): lanes going on from it
            # drew random numbers that every later lane's draws moved by
            kind = np.where(h.hit & self.plan.left_out[scene.tri_object[prim]], -1, kind)
        if self.absorbing:  # the segment just crossed, inside a glass's volume (absorption.absorbed1)
            seg_medium = optics.arriving(scene, path["medium"], hmat, h.hit, d, h.ng)
            path["beta"] = beta * optics.transmittance(scene, seg_medium, np.where(h.hit, h.t, 0.0))
        return h, prim, hmat, kind

    def _diffuse_vertex(self, path, h, prim, hmat, diff, lights_direct, connect) -> dict:
        """The diffuse vertices the segments met (rows diff): their direct light, the walks' caustic
        there (connect), and their part of the next frontier."""
        scene, rc, lim, d = self.scene, self.rc, self.lim, path["d"]
        g = dict(lane=path["lane"][diff], p=h.p[diff], ng=h.ng[diff], ns=h.ns[diff], w=-d[diff],
                 beta=path["beta"][diff], mat=hmat[diff], has_s=path["has_s"][diff], depth=path["depth"][diff] + 1,
                 cnt=path["cnt"][diff])
        if layer.has_layers(scene):  # its diffuse under its glossy layer, towards w (as eye_receivers)
            g["beta"] = g["beta"] * layer.weight(layer.table(scene), g["mat"], dot(g["w"], g["ns"]))[:, None]
        alb = albedo(scene, g["mat"])
        lit = np.flatnonzero(g["has_s"] & lim.fits(g["cnt"]))  # direct light: every event before fits
        for li in lights_direct:
            if lit.size:
                rad = direct_light(scene, self.tracer, li, g["p"][lit], g["ng"][lit], g["ns"][lit], g["w"][lit],
                                   self.rng, self.stats, scene.tri_object[prim[diff[lit]]])
                np.add.at(self.radiance, g["lane"][lit], g["beta"][lit] * alb[lit] * rad)
        if connect is not None:
            rec = np.flatnonzero(self.plan.receivers[scene.tri_object[prim[diff]]] & lim.fits(g["cnt"] + ONE_DIFFUSE))
            if rec.size:
                ln = g["lane"][rec]
                sub = Receivers(rx=rc.rx[ln], ry=rc.ry[ln], p=g["p"][rec], ng=g["ng"][rec], ns=g["ns"][rec],
                                w_eye=g["w"][rec], beta=g["beta"][rec], mat=g["mat"][rec],
                                eye_specular=np.maximum(rc.eye_specular[ln], 1), weight=rc.weight[ln],
                                prior=g["cnt"][rec],
                                strata=None if rc.strata is None else qmc.after_bounce(rc.strata[ln]))
                np.add.at(self.radiance, ln, connect(sub))
        return g

    def _specular(self, path, h, prim, hmat, kind, spec):
        """Scatter the paths at the specular vertices (rows spec): the paths that go on and the
        origins of their next segments."""
        scene, d = self.scene, path["d"]
        d_in = d[spec]
        dd, bb, keep = scatter_specular(scene, self.rng, -d[spec], h.ns[spec], h.ng[spec], hmat[spec], kind[spec],
                                        path["beta"][spec], scale_eta=self.physical)
        sk = spec[keep]
        last_obj = scene.tri_object[prim[sk]]
        last_caster = self.plan.casters[last_obj]
        kinds = specular_kind(d_in[keep], dd, h.ng[sk])
        new = dict(lane=path["lane"][sk], beta=bb, has_s=path["has_s"][sk] | last_caster, depth=path["depth"][sk],
                   d=dd, last_obj=last_obj, last_caster=last_caster, last_refl=kinds == GLOSSY_EVENTS)
        if self.others:
            new["code"] = path["code"][sk] * 2 + new["last_refl"]
            new["on"] = path["on"][sk] & self.walked[scene.tri_object[prim[sk]]]
        if self.absorbing:
            new["medium"] = optics.inside(scene, hmat[sk], kind[sk] == S.DIELECTRIC, dd, h.ng[sk])
        new["before"] = path["cnt"][sk]
        cnt = new["before"].copy()
        cnt[np.arange(len(sk)), kinds] += 1
        new["cnt"] = cnt
        # a path whose events before the latest no longer fit cannot fit later
        alive = np.flatnonzero(self.lim.fits(new["before"]))
        if alive.size < len(new["lane"]):
            new = {key: v[alive] for key, v in new.items()}
            sk = sk[alive]
        for key in ("code", "on", "medium"):  # kept only where they are used (others, absorbing)
            new.setdefault(key, None)
        return new, self.tracer.spawn(h.p[sk], h.ng[sk], new["d"])


def _count_others(scene, tracer, others, segments, path, k, ok, radiance, stats):
    """gather's paths no walk takes: the lights of others (light index -> Handoff) seen on the
    segments (o, d, hits h) of the paths (lane, beta, chain code, on walked casters, last_obj: the
    object of the vertex each segment leaves, for the lights' Light Linking) after k specular
    vertices, where ok, added to radiance per lane."""
    o, d, h = segments
    lane, beta, code, on = path["lane"], path["beta"], path["code"], path["on"]
    surf_t = np.where(h.hit, h.t, np.inf)
    for li, ho in others.items():
        walked = [c for c in np.unique(code) if chain_letters(c, k) in ho.types]  # as reference.other_paths
        other = ok & (~on | ~np.isin(code, walked))
        if not other.any():
            continue
        refl = (code & 1) == 1  # the latest vertex's letter
        seen, L, tl = seen_light(scene, tracer, li, o, d, refl, surf_t, path["last_obj"])
        seen = np.flatnonzero(other & seen)
        np.add.at(radiance, lane[seen], beta[seen] * L[seen])
        stats["other_paths_later"] = stats.get("other_paths_later", 0) + int(seen.size)
