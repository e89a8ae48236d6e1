"""How strongly a specular chain focuses light: the generalised geometric term of a path and its
concentration. The walks' estimators weigh a solution by the first; the manifold pass and the photon
hand-off split path space between them by the second, evaluated on the same paths.
"""
from __future__ import annotations

import numpy as np

from ..core.vec import dot, frame, normalize
from ..kernels.records import chain_kinds
from ..kernels.newton import chain_solve
from ..scene.geometry import packed_floats
from ..shading.light_samples import LightEnd


def geometric_term(types, x0, verts, etas, light_end: LightEnd):
    """|d w0 / d A_y| (or d w0 / d w_y for a sun) at converged chains, and ok."""
    # constraints.blocks + block_solve with the right-hand side -D_k, per lane in one kernel
    F = packed_floats(verts)
    X1, oks = chain_solve(1, False, chain_kinds(types), x0, F, np.stack(np.broadcast_arrays(*etas), 1), light_end.y,
                          light_end.ys, light_end.yt, light_end.directional)
    det = X1[:, 0, 0] * X1[:, 1, 1] - X1[:, 0, 1] * X1[:, 1, 0]
    d01 = verts[0].p - x0
    r2 = dot(d01, d01)
    cos1 = np.abs(dot(d01, verts[0].ng)) / np.sqrt(np.maximum(r2, 1e-300))
    g = cos1 / np.maximum(r2, 1e-300) * np.abs(det)
    ok = oks & np.isfinite(g)
    return np.where(ok, g, 0.0), ok


def concentration(types, x0, verts, etas, y, directional):
    """How strongly the chain focuses light onto x0, a function of the path alone:
    G of the path with its light end taken as a point at y (tangent plane facing
    the chain) times the squared unfolded length, |d w0 / d w_y| for a sun. An
    unfocused chain (a flat mirror) gives 1; it grows without bound at a fold.
    The manifold pass and the photon hand-off both evaluate it, on the same
    paths, so a threshold on it partitions path space exactly between them."""
    n = len(x0)
    if directional:
        ys, yt = frame(y)
        g, ok = geometric_term(types, x0, verts, etas, LightEnd(True, y, ys, yt))
        return np.where(ok, g, np.inf)
    last = verts[len(types) - 1].p
    ys, yt = frame(normalize(last - y))
    g, ok = geometric_term(types, x0, verts, etas, LightEnd(False, y, ys, yt))
    length = np.zeros(n)
    prev = x0
    for v in verts:
        d = v.p - prev
        length += np.sqrt(dot(d, d))
        prev = v.p
    d = y - prev
    length += np.sqrt(dot(d, d))
    return np.where(ok, g * length**2, np.inf)
