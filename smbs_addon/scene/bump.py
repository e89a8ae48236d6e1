"""Bumped mirrors and glass: a Bump node's height field as shading normals on a finer mesh.

Cycles bends a surface's shading normal by its Bump node (svm node_set_bump, world space):
N' = normalize(N - Distance * grad_s(Height)), where grad_s is the height's gradient along the
surface (perpendicular to N), Distance negated by Invert, then normalize(Strength * N' +
(1 - Strength) * N). The walks and the tracers need the normal as a function on the mesh
(geometry.vertex_from_hits interpolates corner normals and differentiates them), so the export
(export.py, the only part that needs Blender: Cycles bakes the Height at the vertices) cuts each
triangle of a bumped object into n x n (``subdivide``), bakes the height at every vertex, and
``bend`` turns it into corner normals: per triangle the gradient of the height's linear
interpolant, per vertex the area-weighted mean over its bumped triangles, per corner Cycles'
formula. Between vertices the normal is then linear, where Cycles' follows the texture: the finer
the mesh (``segments``: about TARGET_TRIANGLES triangles per object), the closer.

A Normal driven by other nodes (a Normal Map node of an image, say) needs no gradient: the export
bakes the node's output, a world-space normal, at every corner of the finer mesh and takes it as
the corner normal. A Bump node cannot be baked that way: a bake's shading points have no ray
differentials, and Cycles' Bump then leaves the normal unbent (hence its Height, and ``bend``).

Seen from behind, Cycles' bump does not flip with the surface (N is the flipped normal, the
gradient term keeps its sign) where the Height reads the position (Object coordinates: a sheet met
from below refracts as from above); where it reads an attribute (Generated, UV) the offsets turn with
the surface and it flips (export._bump_flips); a Normal Map flips. ``bend`` gives both sides' normals
(Scene.tri_normals_back, kept where the bump does not flip: the kernels take them where a ray's
direction runs along the geometric normal).
"""
from __future__ import annotations

import numpy as np

# triangles per bumped object after subdividing: a 6 m pool's two triangles become 256 x 256
# cells of 2.3 cm, resolving a Noise Texture's detail down to ~10 cm
TARGET_TRIANGLES = 1 << 17
# the most triangles all bumped objects of a scene are cut into together, shared by area
BUDGET_TRIANGLES = 1 << 19
MAX_SEGMENTS = 512


def segments(triangles: int, target: int = TARGET_TRIANGLES) -> int:
    """Cuts per edge so that `triangles` become about `target` (1: none)."""
    if triangles <= 0:
        return 1
    return int(min(MAX_SEGMENTS, max(1, round(np.sqrt(target / triangles)))))


def targets(areas, budget: int = BUDGET_TRIANGLES, most: int = TARGET_TRIANGLES) -> np.ndarray:
    """Each bumped object's share of the budget, by its surface area, at most `most` apiece (so
    one pool keeps TARGET_TRIANGLES and twenty glasses share the budget by size)."""
    a = np.maximum(np.asarray(areas, float), 0.0)
    total = a.sum()
    share = a / total * budget if total > 0 else np.full(len(a), budget / max(len(a), 1))
    return np.minimum(share, most).astype(np.int64)


def _lattice(n: int):
    """A triangle's lattice points (i, j), i + j <= n, and its n^2 sub-triangles as indices into
    them, wound as the triangle ((0, 0) -> corner 0, (n, 0) -> corner 1, (0, n) -> corner 2)."""
    pts = [(i, j) for j in range(n + 1) for i in range(n + 1 - j)]
    index = {p: k for k, p in enumerate(pts)}
    tris = []
    for j in range(n):
        for i in range(n - j):
            tris.append((index[(i, j)], index[(i + 1, j)], index[(i, j + 1)]))
            if i + j <= n - 2:
                tris.append((index[(i + 1, j)], index[(i + 1, j + 1)], index[(i, j + 1)]))
    return np.array(pts, np.int64), np.array(tris, np.int64)


def subdivide(tv: np.ndarray, co: np.ndarray, normals: np.ndarray, uvs, n: int):
    """Cut every triangle into n x n.

    tv: (T, 3) vertex ids into co (V, 3); normals: (T, 3, 3) corner normals; uvs: (T, 3, 2) or
    None. Returns (co2 (V2, 3), tv2 (T n^2, 3), normals2 (T n^2, 3, 3), uvs2 or None, parent
    (T n^2,) the triangle each came from). A point on an edge is made once, from the edge's
    lower vertex id, so triangles that share an edge share its points bit for bit (embree's
    watertight test needs them equal); corner normals and uvs are interpolated in their triangle.
    """
    tv = np.asarray(tv, np.int64)
    co = np.asarray(co, float)
    T, V = len(tv), len(co)
    if n <= 1 or T == 0:
        return co, tv, np.asarray(normals, float), uvs, np.arange(T)
    pts, sub = _lattice(n)
    i, j = pts[:, 0], pts[:, 1]
    L = len(pts)
    # edges (a, b) with a < b, each with n - 1 points
    ends = np.stack([tv[:, [0, 1]], tv[:, [1, 2]], tv[:, [0, 2]]], axis=1)  # (T, 3, 2): from, to
    lo, hi = ends.min(axis=2), ends.max(axis=2)
    keys = lo * V + hi
    uniq, inv = np.unique(keys.ravel(), return_inverse=True)
    inv = inv.reshape(T, 3)
    E = len(uniq)
    ea, eb = uniq // V, uniq % V
    k = np.arange(1, n)[None, :, None] / n
    edge_pts = (co[ea][:, None, :] + (co[eb] - co[ea])[:, None, :] * k).reshape(-1, 3)
    # each lattice point's id: a corner, an edge point or an interior point
    ids = np.empty((T, L), np.int64)
    corner = {(0, 0): 0, (n, 0): 1, (0, n): 2}
    for p, c in corner.items():
        ids[:, np.flatnonzero((i == p[0]) & (j == p[1]))[0]] = tv[:, c]
    # edge 0 (corners 0 -> 1): j == 0, step i from corner 0; edge 1 (1 -> 2): i + j == n, step j
    # from corner 1; edge 2 (0 -> 2): i == 0, step j from corner 0
    for e, (mask, step) in enumerate((((j == 0) & (i > 0) & (i < n), i),
                                      ((i + j == n) & (j > 0) & (j < n), j),
                                      ((i == 0) & (j > 0) & (j < n), j))):
        cols = np.flatnonzero(mask)
        s = step[cols][None, :]  # steps from the edge's `from` corner
        forward = (ends[:, e, 0] < ends[:, e, 1])[:, None]
        kk = np.where(forward, s, n - s)  # steps from the lower vertex id
        ids[:, cols] = V + inv[:, e][:, None] * (n - 1) + (kk - 1)
    inner = np.flatnonzero((i > 0) & (j > 0) & (i + j < n))
    base = V + E * (n - 1)
    ids[:, inner] = base + np.arange(T)[:, None] * len(inner) + np.arange(len(inner))[None, :]
    bary = np.stack([(n - i - j) / n, i / n, j / n], axis=1)  # (L, 3)
    tri_pts = co[tv]  # (T, 3, 3)
    inner_pts = np.einsum("lc,tcx->tlx", bary[inner], tri_pts).reshape(-1, 3)
    co2 = np.concatenate([co, edge_pts, inner_pts])
    tv2 = ids[:, sub].reshape(-1, 3)
    nb = np.einsum("lc,tcx->tlx", bary, np.asarray(normals, float))  # (T, L, 3)
    normals2 = nb[:, sub].reshape(-1, 3, 3)
    uvs2 = None
    if uvs is not None:
        ub = np.einsum("lc,tcx->tlx", bary, np.asarray(uvs, float))
        uvs2 = ub[:, sub].reshape(-1, 3, 2)
    parent = np.repeat(np.arange(T), len(sub))
    return co2, tv2, normals2, uvs2, parent


def bend(v: np.ndarray, n: np.ndarray, tv: np.ndarray, heights: np.ndarray, distance: np.ndarray,
         strength: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cycles' Bump node on corner normals.

    v: (T, 3, 3) world corners; n: (T, 3, 3) unit shading normals; tv: (T, 3) vertex ids into
    heights (V,); distance, strength: (T,) the Bump node's Distance (negated where Invert) and
    Strength per triangle (strength 0: not bumped). Returns the bent unit corner normals seen from
    the front, and those a ray meets from behind: Cycles bends the flipped N by the same gradient
    term there, normalize(-N - Distance grad H) = -normalize(N + Distance grad H), the front's
    bend mirrored about N (as an outward normal, 2 (N'.N) N - N', Strength's mix included).
    """
    tv = np.asarray(tv, np.int64)
    h = np.asarray(heights, float)[tv]  # (T, 3)
    e1, e2 = v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]
    a11, a12, a22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
    det = a11 * a22 - a12 * a12
    bumped = (np.asarray(strength, float) > 0) & (det > 1e-30 * np.maximum(a11 * a22, 1e-300))
    inv = np.divide(1.0, det, out=np.zeros_like(det), where=bumped)
    d1, d2 = h[:, 1] - h[:, 0], h[:, 2] - h[:, 0]
    alpha = (a22 * d1 - a12 * d2) * inv
    beta = (a11 * d2 - a12 * d1) * inv
    g = alpha[:, None] * e1 + beta[:, None] * e2  # the height's gradient in the triangle's plane
    area = 0.5 * np.sqrt(np.maximum(det, 0.0)) * bumped
    V = len(heights)
    G = np.zeros((V, 3))
    W = np.zeros(V)
    for c in range(3):
        np.add.at(G, tv[:, c], g * area[:, None])
        np.add.at(W, tv[:, c], area)
    G = np.divide(G, W[:, None], out=np.zeros_like(G), where=W[:, None] > 0)
    gc = G[tv]  # (T, 3, 3) per corner
    gc -= (gc * n).sum(-1, keepdims=True) * n  # along the surface (perpendicular to N)
    d = np.asarray(distance, float)[:, None, None]
    s = np.clip(np.asarray(strength, float), 0.0, None)[:, None, None]
    nb = n - d * gc
    nb = _unit(nb, n)
    nb = _unit(s * nb + (1.0 - s) * n, n)
    front = np.where(bumped[:, None, None], nb, n)
    back = _unit(2.0 * (front * n).sum(-1, keepdims=True) * n - front, n)
    return front, np.where(bumped[:, None, None], back, n)


def _unit(x: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    ln = np.linalg.norm(x, axis=-1, keepdims=True)
    return np.where(ln > 0, x / np.where(ln > 0, ln, 1.0), fallback)
