"""The photon hand-off: which light paths the photons take instead of the walks.

A path that focuses light more than the hand-off's threshold (a fold, a focus: concentration), a
path through a chain type the walks do not walk, or through a rough caster, is the photons'; the
two partition path space, so their sum stays unbiased.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..scene.geometry import vertex_from_hits
from .focus import concentration
from ..shading.microfacet import rough_objects


@dataclass
class Handoff:
    """The manifold pass hands the paths that focus more than ``tau`` to the photons.

    Photons then splat only where their chain (read from the receiver's side) is
    one of ``types``, every vertex lies on a planned caster, and the chain's
    concentration exceeds tau: exactly the paths the manifold pass drops
    (manifold.estimate), so the two add up to the whole layer, each where it is
    efficient: the light tracer where light piles up (folds, foci), the walks
    elsewhere."""

    tau: dict  # chain type -> concentration threshold; 0: the whole chain type (a weak one)
    directional: bool  # a sun or the world (S.DISTANT): the light end is the photon's direction
    others: bool = False  # also every path the walks cannot take: a chain type they do not walk
    # (longer than max_chain, or mixing mirrors and glass), or one through a specular vertex that
    # is not a planned caster

    @property
    def types(self):
        return tuple(self.tau)

    @property
    def max_chain(self):
        return max((len(t) for t in self.types), default=0)


def walked_casters(scene, prim, caster):
    """The hand-off's record of which vertices lie on a planned caster (prim: their triangles,
    caster: the photon kernel's flags), less the rough ones: no walk takes a path through a rough
    mirror or glass (rough.walk_casters), so other_paths gives it to the photons."""
    rough = rough_objects(scene)
    if not rough.any():
        return caster
    return caster & ~rough[scene.tri_object[np.maximum(prim, 0)]]


def _chain_codes(refl, lanes, k):
    """Chain letters as codes (bit j: 1 for an R at vertex j from the receiver's side) of the
    lanes' first k vertices in history order (light side first)."""
    codes = np.zeros(lanes.size, np.int64)
    for j in range(k):
        codes = codes * 2 + refl[lanes, k - 1 - j]
    return codes


def chain_letters(code, k) -> str:
    return "".join("R" if (code >> (k - 1 - j)) & 1 else "T" for j in range(k))


def other_paths(handoff, kb, refl, caster):
    """Which paths (kb bounces; history per bounce, light side first) no walk takes: longer
    than the longest walked type, through a specular vertex that is no planned caster, or of
    a chain type not walked."""
    other = kb > handoff.max_chain
    for k in np.unique(kb[(kb >= 1) & (kb <= handoff.max_chain)]):
        lanes = np.flatnonzero(kb == k)
        on = np.all(caster[lanes, :k], axis=1)
        codes = _chain_codes(refl, lanes, k)
        walked = np.isin(codes, [c for c in np.unique(codes) if chain_letters(c, k) in handoff.types])
        other[lanes] = ~on | ~walked
    return other


def handoff_select(scene, tracer, handoff, x0, kb, prim, pts, bary, refl, caster, y):
    """Which photons arriving at x0 after kb bounces (history per bounce, light side
    first) carry a handed-off path."""
    take = np.zeros(len(x0), bool)
    if handoff.others:
        take |= other_paths(handoff, kb, refl, caster)
    K = handoff.max_chain
    ok = (kb >= 1) & (kb <= K) & ~take
    for k in np.unique(kb[ok]):
        lanes = np.flatnonzero(ok & (kb == k))
        lanes = lanes[np.all(caster[lanes, :k], axis=1)]
        # chain letters from the receiver's side: the photon's last bounce comes first
        codes = _chain_codes(refl, lanes, k)
        for code in np.unique(codes):
            types = chain_letters(code, k)
            if types not in handoff.types:
                continue
            g = lanes[codes == code]
            tau = handoff.tau[types]
            if tau == math.inf:  # a walked type none of whose paths is handed off
                continue
            if tau <= 0:
                take[g] = True
                continue
            # vertex m of the photon's path (light side first) as the walks meet it, from the eye's
            # side: coming from m + 1, or from x0 (the same normals, so the same concentration)
            verts = [vertex_from_hits(scene, tracer, prim[g, m], pts[g, m], bary[g, m],
                                      pts[g, m] - (pts[g, m + 1] if m < k - 1 else x0[g]))
                     for m in range(k - 1, -1, -1)]
            etas = [scene.mat_ior[v.mat] for v in verts]
            c = concentration(types, x0[g], verts, etas, y[g], handoff.directional)
            take[g[c > tau]] = True
    return take


# At receivers seen through mirrors or glass the hand-off goes to cosine sampling, weaker than
# light tracing: only paths focusing more than this (the default hand-off) go there
SEEN_HANDOFF_MIN = 4.0
