"""The brute-force reference: light tracing through specular chains.

It defines the caustic layer: paths light -> (specular)+ -> diffuse receiver ->
camera. Photons leave a light towards the casters (lights.emit), bounce through
perfect mirrors and glass (Fresnel decides reflect or refract at glass, by
Russian roulette on the Fresnel weight), and at the first diffuse vertex are
connected to the camera and splatted through the pixel filter. Unbiased and
unclamped; slow for small caustics, which is what the manifold walks are for.

A diffuse vertex seen by the camera only through glass or a mirror is not
splatted here (the connection to the camera is blocked); see the bake notes.
"""
from __future__ import annotations


import numpy as np

from ..core import embree, lanes
from ..kernels import eye, records
from ..kernels.photons import photon_lanes
from ..kernels.records import (HIST_B, HIST_BENT, HIST_CASTER, HIST_P, HIST_REFL, REC_P, CameraHiding, PhotonBatch,
                               PhotonOut, PhotonRules, Splats)
from ..shading.optics import materials, scatter_rows
from ..shading.microfacet import rough_materials
from .handoff import Handoff, handoff_select, walked_casters
from ..trace.eye import view_tables
from ..scene.light_paths import Limits

MAX_SPECULAR_BOUNCES = 32
PHOTON_SPLIT = 4096  # photons (or records) per thread below which one call is not split


def scatter_specular(scene, rng, w_in, ns, ng, mat, kind, beta, scale_eta=False, adjoint=False):
    """One perfect-specular interaction per lane, as Cycles makes it: the geometric
    normal decides the side (a back-facing hit flips both normals and inverts the IOR);
    a lane whose shading normal faces away from w_in dies; a mirror reflects, glass
    reflects or refracts, chosen in proportion to the lobes' weights
    (optics.specular_weights1), so the lane's weight is the lobe's weight over its
    probability; the new direction must leave on the side the interaction calls for,
    by the geometric and the shading normal alike. w_in points away from the surface.

    scale_eta: multiply refractions by (eta on the w_in side / eta on the other side)^2
    -- the radiance change along an eye path in physical units, and, for photons,
    Cycles' convention (Cycles keeps radiance unscaled, so the flux a photon delivers
    changes by that factor instead).

    adjoint: the lanes carry light (photons), not radiance: with a shading normal the
    BSDF is not symmetric, and the photon's weight takes Veach's correction (thesis
    sec. 5.3) |w_in.ns| |w_out.ng| / (|w_in.ng| |w_out.ns|), so that light tracing
    agrees with the radiance view (Cycles, the walks) on bumpy or normal-mapped casters.

    Returns (new unit directions, new weights, kept lane indices)."""
    n = len(w_in)
    u = np.zeros((n, 3))
    u[:, 0] = rng.random(n)  # the lobe; a rough surface's microfacet normal from two more (a smooth scene draws none)
    if rough_materials(scene).any():
        u[:, 1:] = rng.random((n, 2))
    d, beta, keep = scatter_rows(u, *(np.ascontiguousarray(a, np.float64) for a in (w_in, ns, ng)),
                                 np.ascontiguousarray(mat, np.int64), np.ascontiguousarray(kind, np.int64),
                                 materials(scene), np.ascontiguousarray(beta, np.float64), bool(scale_eta),
                                 bool(adjoint))
    return d, beta, keep


def run_photons(scene, tracer, plan, photons, rng, stats, indirect=False, max_bounces=MAX_SPECULAR_BOUNCES,
                max_iter=None, physical=False, K=0):
    """Photons traced in one kernel call per chunk (photons.photon_lanes: caustic photons, or with
    indirect the ones that also bounce off diffuse surfaces), or per part of it on each thread
    when the chunk runs alone (at low spp a batch is one chunk), their random numbers keyed by
    one draw from rng and the lane. Counts photons and rays in stats. Returns the splat records
    (kernels.REC_* columns), their (lane, specular bounces, material), the hand-off's record of
    each lane's first K specular vertices (hist, h_prim) and the kernel's tally (kernels.PH_*)."""
    n = len(photons.o)
    max_iter = max_bounces + 1 if max_iter is None else max_iter
    f64 = lambda a: np.ascontiguousarray(a, np.float64)  # noqa: E731
    o0, d0, w0 = f64(photons.o), f64(photons.d), f64(photons.w)
    soft = (np.zeros(3), 0.0) if photons.soft_center is None else (f64(photons.soft_center), float(photons.soft_radius))
    lvis = int(photons.visibility)
    lit = np.zeros(0, bool) if photons.lit is None else np.ascontiguousarray(photons.lit, bool)
    unshadowing = np.zeros(0, bool) if photons.unshadowing is None else np.ascontiguousarray(photons.unshadowing,
                                                                                             bool)
    hist, h_prim = np.zeros((n, K, HIST_BENT)), np.zeros((n, K), np.int64)
    tally = np.zeros(records.PH_TALLY, np.int64)
    # a record is a photon's diffuse vertex the camera may see directly (splat_records): none on an object
    # camera rays do not meet (its light seen in a mirror is the eye pass's)
    receivers = plan.receivers if not tracer.hidden.size else plan.receivers & ~tracer.hidden
    args = (tracer.kernel_geometry(plan.casters), np.ascontiguousarray(receivers, bool), materials(scene),
            PhotonRules(bool(indirect), Limits.of(scene).array(), int(max_bounces), int(max_iter), bool(physical)),
            tracer.eps)
    key = int(rng.integers(2**63))

    def part(a, b):
        """Lanes a..b-1 (the arrays cut at b, so lane numbers and their random numbers stay)."""
        cap = max(b - a, max_iter + 1)  # a lane makes at most max_iter records: every call moves on
        recs, ids, tally_p, rays, lane = [], [], np.zeros_like(tally), 0, a
        while lane < b:
            rec, rec_i = np.empty((cap, records.REC_F)), np.empty((cap, 3), np.int64)
            rt = tracer.rays()
            batch = PhotonBatch(o0[:b], d0[:b], w0[:b], *soft, lvis, lit, unshadowing)
            lane, m, counts = photon_lanes(rt, batch, key, lane, *args,
                                           PhotonOut(rec, rec_i, hist[:b], h_prim[:b], tally_p))
            tracer.cast_by_kernel(rt, counts)
            rays += int(counts[embree.KINDS:].sum())
            recs.append(rec[:m])
            ids.append(rec_i[:m])
        return recs, ids, tally_p, rays

    # parts of one call's lanes on the threads (one part inside a chunk that already runs beside
    # others: lanes.run), their records joined in lane order: the records of one call
    recs, ids = [], []
    for r, i, t, rays in lanes.run(part, n, tracer.threads, PHOTON_SPLIT):
        recs += r
        ids += i
        tally += t
        stats["rays_photon"] = stats.get("rays_photon", 0) + rays
    stats["photons"] = stats.get("photons", 0) + int(tally[records.PH_PHOTONS])
    rec, ids = (np.concatenate(recs), np.concatenate(ids)) if len(recs) != 1 else (recs[0], ids[0])
    return rec, ids, hist, h_prim, tally


def splat_records(scene, tracer, cam, film, rec, ids, stats, first_order=True):
    """Connect run_photons' records (diffuse vertices with the direction the photon arrived from
    and its flux) to the camera and splat flux x BSDF x importance, in one kernel call
    (eye.camera_splats, the shadow rays cast there), or one per part on each thread as
    run_photons, splatted in record order."""
    n = len(rec)
    if n == 0:
        return
    rx, ry, val = np.empty(n), np.empty(n), np.empty((n, 3))
    cam_p, rec = cam.kernel_params(), np.ascontiguousarray(rec, np.float64)
    mat, mats = np.ascontiguousarray(ids[:, 2], np.int64), materials(scene)
    # textured receivers: each splat's albedo (Film.splat); every splat here is seen directly
    textured = scene.textured_materials()
    textured = np.zeros(0, bool) if textured is None else np.ascontiguousarray(textured)
    alb = np.zeros((n if textured.size else 0, 3))
    view = view_tables(scene, cam)

    def part(a, b):  # records a..b-1, their splats packed from a on
        rt = tracer.rays()
        rays, m, counts = eye.camera_splats(rt, cam_p, float(film.filter_width), rec[a:b], mat[a:b], mats,
                                            bool(first_order), tracer.eps, textured, view,
                                            CameraHiding(tracer.ng, scene.tri_object, tracer.hid),
                                            Splats(rx[a:b], ry[a:b], val[a:b], alb[a:b] if textured.size else alb))
        tracer.cast_by_kernel(rt, counts)
        return a, m, rays

    parts = lanes.run(part, n, tracer.threads, PHOTON_SPLIT)
    stats["rays_camera"] += sum(int(rays) for _, _, rays in parts)
    m = sum(int(p[1]) for p in parts)
    keep = slice(0, m) if len(parts) == 1 else np.concatenate([np.arange(a, a + k) for a, k, _ in parts])
    if m:
        film.splat(rx[keep], ry[keep], val[keep], alb[keep] if textured.size else None)
        stats["splats"] += m


def trace_photons(scene, tracer, cam, film, plan, photons, rng, stats, max_bounces=MAX_SPECULAR_BOUNCES,
                  physical=False, handoff: Handoff | None = None):
    """Follow photons through specular chains and splat at the first diffuse vertex
    (with a hand-off: only the paths it names)."""
    K = 0
    if handoff is not None:  # per photon: each bounce's triangle, barycentrics, kind, caster flag
        K = handoff.max_chain
        if not handoff.others:
            max_bounces = min(max_bounces, K)
    rec, ids, hist, h_prim, tally = run_photons(scene, tracer, plan, photons, rng, stats, max_bounces=max_bounces,
                                                physical=physical, K=K)
    stats["truncated"] += int(tally[records.PH_TRUNCATED])
    stats["lost_shading_normal"] += int(tally[records.PH_LOST])
    if tally[records.PH_BEYOND]:  # photons whose events no longer fit can splat nowhere
        stats["beyond_light_paths"] = stats.get("beyond_light_paths", 0) + int(tally[records.PH_BEYOND])
    if handoff is not None and len(rec):
        ln = ids[:, 0]
        y_end = -photons.d[ln] if handoff.directional else photons.o[ln]
        h = hist[ln]
        take = handoff_select(scene, tracer, handoff, rec[:, REC_P:REC_P + 3], ids[:, 1], h_prim[ln],
                               h[:, :, HIST_P:HIST_P + 3], h[:, :, HIST_B:HIST_B + 2], h[:, :, HIST_REFL].astype(np.int64),
                               walked_casters(scene, h_prim[ln], h[:, :, HIST_CASTER] > 0), y_end)
        rec, ids = rec[take], ids[take]
        stats["handoff_paths"] = stats.get("handoff_paths", 0) + int(take.sum())
    splat_records(scene, tracer, cam, film, rec, ids, stats)


