"""Differential geometry at specular vertices, in orthonormal tangent coordinates.

A vertex lies on a triangle; it moves in the triangle's plane along two
orthonormal tangents (s, t). The shading normal n varies with position
(interpolated corner normals); dn_s and dn_t are its derivatives along s and t.
Orthonormal tangents make area elements agree between the Newton solve and the
generalised geometric term (no separate re-parameterisation needed).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.vec import cross, dot, normalize


@dataclass
class Vertex:
    """Structure of arrays for one chain vertex over N lanes."""

    p: np.ndarray  # (N,3)
    ng: np.ndarray  # (N,3) unit geometric normal
    n: np.ndarray  # (N,3) unit shading normal
    s: np.ndarray  # (N,3) unit tangent in the triangle plane
    t: np.ndarray  # (N,3) ng x s
    dn_s: np.ndarray  # (N,3) d n / d s
    dn_t: np.ndarray  # (N,3) d n / d t
    prim: np.ndarray  # (N,)
    obj: np.ndarray  # (N,)
    mat: np.ndarray  # (N,)

    def take(self, idx) -> "Vertex":
        return Vertex(*(getattr(self, f)[idx] for f in self.__dataclass_fields__))


def triangle_areas(v: np.ndarray) -> np.ndarray:
    """(T,) areas of triangles v (T,3,3): what a uniform pick over them weights by (manifold.Seeder's
    seeds, indirect.bent_candidates' aimed points)."""
    return 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)


def area_points(v: np.ndarray, cdf: np.ndarray, total: float, n: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """n points uniform in area over triangles v (T,3,3) whose areas' cumulative sum is cdf (total its
    last entry): (points (n,3), the triangle of each). Draws the pick, then the two barycentric numbers."""
    t = np.minimum(np.searchsorted(cdf, rng.random(n) * total, side="right"), len(cdf) - 1)
    u1, u2 = rng.random(n), rng.random(n)
    su = np.sqrt(u1)
    b0, b1, b2 = 1 - su, su * (1 - u2), su * u2
    return b0[:, None] * v[t, 0] + b1[:, None] * v[t, 1] + b2[:, None] * v[t, 2], t


def vertex_from_hits(scene, tracer, prim: np.ndarray, p: np.ndarray, b: np.ndarray, d=None) -> Vertex:
    """The walk's vertex (kernels._lane_vertex's record) at points p (barycentrics b) of triangles
    prim, met by rays of direction d (None: from the front; a bumped surface met from behind has
    other corner normals, Tracer.ns_corner)."""
    v = tracer.v[prim]
    e1, e2 = v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]
    ng = tracer.ng[prim]
    s = normalize(e1)
    t = cross(ng, s)
    c = tracer.ns_corner[prim]
    if c.shape[1] == 6:  # kernels._corners
        back = np.zeros(len(prim), bool) if d is None else dot(d, ng) > 0
        c = np.where(back[:, None, None], c[:, 3:], c[:, :3])
    b0 = 1.0 - b[:, 0] - b[:, 1]
    nraw = b0[:, None] * c[:, 0] + b[:, 0:1] * c[:, 1] + b[:, 1:2] * c[:, 2]
    ln = np.sqrt(dot(nraw, nraw))
    good = ln > 1e-3
    n = np.where(good[:, None], nraw / np.where(good, ln, 1.0)[:, None], ng)
    # barycentric derivatives along s and t: solve [e1 e2] (alpha, beta) = w in the plane
    g11, g12, g22 = dot(e1, e1), dot(e1, e2), dot(e2, e2)
    det = g11 * g22 - g12 * g12
    inv = np.divide(1.0, det, out=np.zeros_like(det), where=det > 1e-300)
    dn1, dn2 = c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]

    def dn_along(w):
        r1, r2 = dot(w, e1), dot(w, e2)
        alpha = (g22 * r1 - g12 * r2) * inv
        beta = (g11 * r2 - g12 * r1) * inv
        dN = alpha[:, None] * dn1 + beta[:, None] * dn2
        out = (dN - dot(dN, n)[:, None] * n) / np.where(good, ln, 1.0)[:, None]
        return np.where(good[:, None], out, 0.0)

    return Vertex(p=p, ng=ng, n=n, s=s, t=t, dn_s=dn_along(s), dn_t=dn_along(t), prim=prim,
                  obj=scene.tri_object[prim], mat=scene.tri_material[prim])


# packed chains (kernels.py): F (N,k,21) float64 holds p, ng, n, s, t, dn_s, dn_t of each
# vertex, I (N,k,3) int64 prim, obj, mat; a Vertex is then a view of one column j
FLOAT_FIELDS = ("p", "ng", "n", "s", "t", "dn_s", "dn_t")
INT_FIELDS = ("prim", "obj", "mat")


def vertex_view(F: np.ndarray, I: np.ndarray, j: int) -> Vertex:
    """Vertex j of a packed chain, as views (writing to it writes to F and I)."""
    return Vertex(*(F[:, j, 3 * c:3 * c + 3] for c in range(len(FLOAT_FIELDS))),
                  *(I[:, j, c] for c in range(len(INT_FIELDS))))


def packed_floats(verts: list) -> np.ndarray:
    """F of a list of Vertex, read-only: the packed chain itself (no copy) when the vertices are
    vertex_view's columns 0..k-1 of one C-contiguous F, as a Chain's are; else pack's copy."""
    F = verts[0].p.base
    k, width = len(verts), 3 * len(FLOAT_FIELDS)
    if not (isinstance(F, np.ndarray) and F.dtype == np.float64 and F.ndim == 3 and F.shape[1:] == (k, width)
            and F.flags.c_contiguous):
        return pack(verts)[0]
    for j, v in enumerate(verts):
        for c, f in enumerate(FLOAT_FIELDS):
            a = getattr(v, f)
            if (a.base is not F or a.shape != (F.shape[0], 3) or a.strides != (F.strides[0], 8)
                    or a.ctypes.data != F.ctypes.data + (j * width + 3 * c) * 8):
                return pack(verts)[0]
    return F


def pack(verts: list) -> tuple[np.ndarray, np.ndarray]:
    """F, I of a list of Vertex (the inverse of vertex_view)."""
    n, k = len(verts[0].p), len(verts)
    F = np.empty((n, k, 3 * len(FLOAT_FIELDS)))
    I = np.empty((n, k, len(INT_FIELDS)), np.int64)
    for j, v in enumerate(verts):
        for c, f in enumerate(FLOAT_FIELDS):
            F[:, j, 3 * c:3 * c + 3] = getattr(v, f)
        for c, f in enumerate(INT_FIELDS):
            I[:, j, c] = getattr(v, f)
    return F, I
