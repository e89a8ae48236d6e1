"""Eye paths: from film samples through mirrors and glass to the first diffuse receiver.

Film positions are stratified: the render region widened by the pixel filter's
radius (so border pixels get their whole filter footprint) is cut into unit
cells, sample i of a batch goes to cell i mod cells at a uniform position in it
(with strata, a cell's positions over the bake a scrambled Sobol' sequence: core.qmc),
and an estimate is splatted through the filter with weight 1 / (samples in its
cell this batch), an unbiased estimate of integral h(x - c) L(x) dx.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from ..scene import arrays as S
from ..shading.coat import has_layers, table as layer_table, weight as layer_weight
from ..core.vec import dot
from ..core import embree, lanes, qmc
from ..kernels import eye, records
from ..kernels.records import EyeOut, EyePaths, REC_BETA, REC_NG, REC_NS, REC_P, REC_W, ViewTables
from ..shading.optics import materials
from .camera import CameraModel

EYE_MIN_PART = 8192  # eye paths per thread below which splitting does not pay (as tracer._MIN_SPLIT)


@dataclass
class Receivers:
    rx: np.ndarray  # (M,) film position of the eye sample
    ry: np.ndarray
    p: np.ndarray  # (M,3) receiver point x0
    ng: np.ndarray
    ns: np.ndarray
    w_eye: np.ndarray  # (M,3) direction from x0 back along the eye path
    # (M,3) eye-path throughput up to x0: x0's BSDF excluded but for the share its coats leave
    # its diffuse towards the eye (layer.table; 1 but under a Principled BSDF's)
    beta: np.ndarray
    mat: np.ndarray  # (M,) material at x0
    eye_specular: np.ndarray  # (M,) specular vertices between the camera and x0
    weight: np.ndarray  # (M,) splat weight of the eye sample
    # (M,3) int: Cycles' diffuse, glossy and transmission bounces the camera's path took before
    # x0 (bounces.Limits; a reflection is glossy, a refraction transmission)
    prior: np.ndarray
    # (M,3) x0's smooth shading normal (Cycles' sd->N), which ns is unless a bump bends it there
    # (view_bumped): the bump's shadowing term reads both (optics.bump_shadowing1); None: ns
    sn: np.ndarray = None
    # (M, qmc.PATH_DIMS) the receiver's sample's stratified uniforms beyond its film position (film_samples
    # with strata; columns qmc.LIGHT, qmc.BOUNCE, qmc.BOUNCE_LIGHT); None: drawn independently
    strata: np.ndarray | None = None

    def __post_init__(self):
        if self.sn is None:
            self.sn = self.ns

    def take(self, idx) -> "Receivers":
        return Receivers(*(None if (v := getattr(self, f)) is None else v[idx] for f in self.__dataclass_fields__))


def view_tables(scene, cam) -> ViewTables:
    """What the kernels read of the bumped receivers' view (eye.view_normal1; ViewTables):
    Scene.mat_view_bump as flags (M,), view_normals, view_points, t (4,): t takes a raster position (x, y) of camera
    model cam to the view's, (t0 x + t1, t2 y + t3), through the view plane (the camera at the
    view's resolution frames it, camera.CameraModel); t0 = 0 where there is no view."""
    flags = np.asarray(scene.mat_view_bump, bool)
    h, w = np.shape(scene.view_normals)[:2]
    if h == 0 or not flags.any():
        z = np.zeros((0, 0, 3), np.float32)
        return ViewTables(np.zeros(len(scene.mat_kind), np.bool_), z, z, np.zeros(4))
    m = CameraModel(replace(cam.cam, resolution_x=w, resolution_y=h, resolution_percentage=100, use_border=False))
    # view plane: fx = xmin + x pix_w, fy = ymin + (H - y) pix_h, in both
    t = np.array([cam.pix_w / m.pix_w, (cam.xmin - m.xmin) / m.pix_w, cam.pix_h / m.pix_h,
                  m.H - (cam.ymin + cam.H * cam.pix_h - m.ymin) / m.pix_h])
    return ViewTables(np.ascontiguousarray(flags), np.ascontiguousarray(scene.view_normals, np.float32),
                      np.ascontiguousarray(scene.view_points, np.float32), t)


def view_bumped(scene, cam, p, ng, ns, mat) -> np.ndarray:
    """x0's shading normals (M,3) as Cycles bends them on a bumped diffuse receiver
    (Scene.mat_view_bump): read from the view of the bumped receivers alone (Scene.view_normals)
    where x0 projects, seen directly or through mirrors and glass alike (eye.view_normal1); ns
    elsewhere: off the frame, and where the view's sub-pixel there is not x0's surface (the receiver
    hides itself, an edge)."""
    view = view_tables(scene, cam)
    flags, vn, vp, t = view.flags, view.normals, view.points, view.t
    if not t[0] > 0 or len(p) == 0:
        return ns
    on = np.flatnonzero(flags[mat])
    rx, ry, to_cam, _, _, dist, valid = cam.towards(np.ascontiguousarray(p[on], np.float64), margin=np.inf)
    on, rx, ry, to_cam, dist = on[valid], rx[valid], ry[valid], to_cam[valid], dist[valid]
    if on.size == 0:
        return ns
    foot = (np.ones(on.size) if cam.ortho else dist) * cam.pix_w
    out = np.array(ns, np.float64)
    bent = np.empty((on.size, 3))
    f64 = lambda a: np.ascontiguousarray(a, np.float64)  # noqa: E731
    eye.view_normal_rows(vn, vp, t, f64(rx), f64(ry), f64(p[on]), f64(ng[on]), f64(ns[on]), f64(to_cam), foot,
                             bent)
    out[on] = bent
    return out


def direct_albedo(scene, rc: Receivers, idx=None) -> np.ndarray | None:
    """Film.splat's albedo for the receivers rc (or rc's rows idx): where x0 is textured
    (Scene.mat_textured) and the camera sees it directly, the albedo its estimate was multiplied
    by, as Cycles' Diffuse Color pass holds it there (its colour times the share its coats leave
    it towards the eye, which beta holds on a camera ray); zero elsewhere. None without textured
    receivers."""
    tex = scene.textured_materials()
    if tex is None:
        return None
    mat, beta, spec = (rc.mat, rc.beta, rc.eye_specular) if idx is None else \
        (rc.mat[idx], rc.beta[idx], rc.eye_specular[idx])
    on = tex[mat] & (spec == 0)
    return np.where(on[:, None], scene.mat_color[mat] * beta, 0.0)


def surface_at(scene, h):
    """(triangle, material, kind) of each hit; misses get triangle 0 and kind -1."""
    prim = np.maximum(h.prim, 0)
    mat = scene.tri_material[prim]
    return prim, mat, np.where(h.hit, scene.mat_kind[mat], -1)


def film_cells(cam, film) -> int:
    x0, x1, y0, y1 = cam.region
    r = int(np.ceil(film.filter_width))
    return (x1 - x0 + 2 * r) * (y1 - y0 + 2 * r)


class FilmSamples(NamedTuple):
    rx: np.ndarray  # (N,) raster positions
    ry: np.ndarray
    weight: np.ndarray  # (N,) splat weights
    sample: np.ndarray  # (N,) the samples' indices in the batch
    strata: np.ndarray | None  # (N, qmc.PATH_DIMS) the path's stratified uniforms (strata given), else None


def film_samples(cam, film, start, n, n_batch, rng, mask=None, strata=None) -> FilmSamples:
    """Samples start..start+n of a batch of n_batch stratified film samples; with mask (bool per
    film cell, film_cells' grid row by row), only those in its cells: the others are drawn all the same, so the samples kept are
    the whole film's, bit for bit. n_batch at least the cells: sample i in cell i % cells (each
    cell's weight 1 / its samples); fewer (the light tracer's bent pass below 512 spp): sample i
    in a cell drawn from the i-th of n_batch equal stretches of the cells, row by row, weighted
    by the stretch's length, so that every cell is sampled (in expectation once per batch), not
    only the first n_batch. strata (core.qmc.Strata), with n_batch at least the cells: each cell's
    jitter, and the path's uniforms (qmc.PATH_DIMS: the light sample's, the first diffuse bounce's and
    its light sample's), from the cell's scrambled Sobol' sequence (qmc), the batch's samples
    continuing it."""
    x0, x1, y0, y1 = cam.region
    r = int(np.ceil(film.filter_width))
    cw = x1 - x0 + 2 * r
    cells = film_cells(cam, film)
    i = np.arange(start, start + n)
    if n_batch >= cells:
        c = i % cells
        per, extra = divmod(n_batch, cells)
        weight = 1.0 / (per + (c < extra))
    else:
        stretch = cells / n_batch
        c = np.minimum(((i + rng.random(n)) * stretch).astype(np.int64), cells - 1)
        weight = np.full(n, stretch)
    if strata is not None and n_batch >= cells:
        u = qmc.cell_points(c, strata.round * (per + (c < extra)) + i // cells, strata.seed)
        jx, jy, path_u = u[:, 0], u[:, 1], u[:, 2:]
    else:
        jx, jy, path_u = rng.random(n), rng.random(n), None
    rx = x0 - r + (c % cw) + jx
    ry = y0 - r + (c // cw) + jy
    if mask is not None:
        keep = mask[c]
        return FilmSamples(rx[keep], ry[keep], weight[keep], i[keep], None if path_u is None else path_u[keep])
    return FilmSamples(rx, ry, weight, i, path_u)


def specular_cells(scene, tracer, cam, film, unseen=None) -> np.ndarray | None:
    """The film cells whose samples can see a mirror or glass first (a mask over film_cells'
    grid, row by row): those the camera's view of the box of each object's specular triangles
    covers (its 8 corners projected, a cell more on every side). A box wholly outside the view
    of the widened film (beyond one of its side planes, before the near or past the far clip
    plane) covers none; None (every cell) where a box in view reaches behind the near clip
    plane, where its projection does not bound it. An eye path that meets a diffuse surface
    first is no caustic seen through mirrors or glass (trace_eye), so the light tracer's eye
    pass traces no other cell's samples: it draws them all the same (film_samples), and its
    image is the whole film's, bit for bit. unseen: (O,) bool, objects (the casters the plan
    left out that no pixel's ray met first: bake.py) whose box covers none where it spans 3
    pixels or more each way, where a ray per pixel would have met them unless something hid
    them (a glass ball under the floor, in view behind it, covered 267 cells of 1419 where 204
    can see a mirror or glass: more eye rays, which moved auto's choice)."""
    x0, x1, y0, y1 = cam.region
    r = int(np.ceil(film.filter_width))
    cw, ch = x1 - x0 + 2 * r, y1 - y0 + 2 * r
    # the widened film on the view plane (camera.CameraModel.rays), a cell more on every side
    fx = cam.xmin + np.array([x0 - r - 1, x1 + r + 1]) * cam.pix_w
    fy = cam.ymin + (cam.H - np.array([y1 + r + 1, y0 - r - 1])) * cam.pix_h
    kind = scene.mat_kind[scene.tri_material]
    spec = np.flatnonzero((kind == S.CONDUCTOR) | (kind == S.DIELECTRIC))
    mask = np.zeros((ch, cw), bool)
    n_objects = len(scene.object_names)
    n_spec = np.bincount(scene.tri_object[spec], minlength=n_objects)
    n_all = np.bincount(scene.tri_object, minlength=n_objects)
    for o in np.flatnonzero(n_spec):
        if n_spec[o] == n_all[o]:  # all mirror or glass: the object's box
            lo, hi = tracer.obj_lo[o], tracer.obj_hi[o]
        else:
            lo, hi = S.column_bounds(tracer.v[spec[scene.tri_object[spec] == o]].reshape(-1, 3))
        corners = np.array([[(lo, hi)[a][0], (lo, hi)[b][1], (lo, hi)[c][2]] for a in (0, 1) for b in (0, 1)
                            for c in (0, 1)])
        c = cam.to_camera(corners)
        depth = -c[:, 2]
        scale = np.ones(8) if cam.ortho else depth  # the view's side planes: x = fx depth (perspective)
        if (np.all(c[:, 0] < fx[0] * scale) or np.all(c[:, 0] > fx[1] * scale) or np.all(c[:, 1] < fy[0] * scale)
                or np.all(c[:, 1] > fy[1] * scale) or np.all(depth < cam.cam.clip_start)
                or np.all(depth > cam.cam.clip_end)):
            continue  # out of view
        if not np.all(depth > cam.cam.clip_start):
            return None
        rx, ry, _, _, _, _ = cam.project(corners)
        if unseen is not None and unseen[o] and rx.max() - rx.min() >= 3 and ry.max() - ry.min() >= 3:
            continue  # a ray per pixel would have met it: hidden (under the floor)
        ax0 = max(0, int(np.floor(rx.min())) - (x0 - r) - 1)
        ax1 = min(cw, int(np.floor(rx.max())) - (x0 - r) + 2)
        ay0 = max(0, int(np.floor(ry.min())) - (y0 - r) - 1)
        ay1 = min(ch, int(np.floor(ry.max())) - (y0 - r) + 2)
        mask[ay0:max(ay0, ay1), ax0:max(ax0, ax1)] = True
    return mask.ravel()


class BatchPart(NamedTuple):
    """Eye samples start..start+n of a batch of n_batch (film_samples)."""
    start: int
    n: int
    n_batch: int


def eye_receivers(scene, tracer, cam, film, plan, part: BatchPart, rng, stats, paths: EyePaths = EyePaths(),
                  cells=None, strata=None) -> Receivers:
    """Trace a part of a batch's eye samples (BatchPart; with cells, a mask over the film cells, only
    those in its cells) to their first diffuse receiver through up to paths.max_bounces mirrors and
    glass (glass by Fresnel choice; paths.scale_eta: radiance in physical units), keeping those with
    at least paths.min_specular specular vertices on the way: one kernel call (eye.eye_lanes), its
    random numbers keyed by one draw from rng and each sample's index in the batch. strata: the
    film samples stratified (film_samples), each receiver keeping its path's uniforms."""
    rx, ry, weight, sample, path_u = film_samples(cam, film, *part, rng, cells, strata)
    key = int(rng.integers(2**63))
    n = len(rx)
    stats["eye_paths"] = stats.get("eye_paths", 0) + n
    params = cam.kernel_params()
    rules = EyePaths(int(paths.max_bounces), int(paths.min_specular), bool(paths.scale_eta))
    args = (key, tracer.kernel_geometry(plan.casters), np.ascontiguousarray(plan.receivers, bool), materials(scene),
            rules, tracer.eps)

    def part(a, b):  # a part of the lanes on a thread (lanes.run), its records in lane order
        rec, rec_i, prior = np.empty((b - a, records.REC_F)), np.empty((b - a, 3), np.int64), \
            np.empty((b - a, 3), np.int64)
        rt = tracer.rays()
        m, counts = eye.eye_lanes(rt, params, rx[a:b], ry[a:b], sample[a:b], *args, EyeOut(rec, rec_i, prior))
        tracer.cast_by_kernel(rt, counts)
        rec_i[:m, 0] += a
        return rec[:m], rec_i[:m], prior[:m], int(counts[embree.KINDS:].sum())

    parts = lanes.run(part, n, tracer.threads, EYE_MIN_PART)
    stats["rays_eye"] = stats.get("rays_eye", 0) + sum(p[3] for p in parts)
    rec, rec_i, prior = (np.concatenate([p[k] for p in parts]) for k in range(3))
    ln = rec_i[:, 0]
    col = lambda k: rec[:, k:k + 3]  # noqa: E731
    beta = col(REC_BETA)
    sn = col(REC_NS)
    ns = view_bumped(scene, cam, col(REC_P), col(REC_NG), sn, rec_i[:, 2])
    if has_layers(scene):  # x0's diffuse under its glossy layer, towards the eye (layer.py)
        beta = beta * layer_weight(layer_table(scene), rec_i[:, 2], dot(col(REC_W), ns))[:, None]
    return Receivers(rx=rx[ln], ry=ry[ln], weight=weight[ln], p=col(REC_P), ng=col(REC_NG), ns=ns,
                     w_eye=col(REC_W), beta=beta, mat=rec_i[:, 2], eye_specular=rec_i[:, 1], prior=prior, sn=sn,
                     strata=None if path_u is None else path_u[ln])
