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

import math
from dataclasses import dataclass

import numpy as np

from ..kernels import embree, compiled as kernels
from ..core import lanes
from ..shading.optics import materials, scatter_rows
from ..shading.microfacet import rough_materials, rough_objects
from ..walks.estimators import concentration
from ..trace.eye import view_tables
from ..scene.light_paths import Limits
from ..scene.geometry import vertex_from_hits

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


def _letters(code, k) -> str:
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
        walked = np.isin(codes, [c for c in np.unique(codes) if _letters(c, k) in handoff.types])
        other[lanes] = ~on | ~walked
    return other


def _handoff_select(scene, tracer, handoff, x0, kb, prim, pts, bary, refl, caster, y):
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
            types = _letters(code, k)
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


def run_photons(scene, tracer, plan, photons, rng, stats, indirect=False, max_bounces=MAX_SPECULAR_BOUNCES,
                max_iter=None, physical=False, K=0):
    """Photons traced in one kernel call per chunk (kernels.photon_lanes: caustic photons, or with
    indirect the ones that also bounce off diffuse surfaces), or per part of it on each thread
    when the chunk runs alone (at low spp a batch is one chunk), their random numbers keyed by
    one draw from rng and the lane. Counts photons and rays in stats. Returns the splat records
    (kernels.REC_* columns), their (lane, specular bounces, material), the hand-off's record of
    each lane's first K specular vertices (hist, h_prim) and the kernel's tally (kernels.PH_*)."""
    n = len(photons.o)
    max_iter = max_bounces + 1 if max_iter is None else max_iter
    f64 = lambda a: np.ascontiguousarray(a, np.float64)  # noqa: E731
    o0, d0, w0 = f64(photons.o), f64(photons.d), f64(photons.w)
    soft = np.zeros(4) if photons.soft_center is None else np.append(photons.soft_center, photons.soft_radius)
    lvis = int(photons.visibility)
    lit = np.zeros(0, bool) if photons.lit is None else np.ascontiguousarray(photons.lit, bool)
    unshadowing = np.zeros(0, bool) if photons.unshadowing is None else np.ascontiguousarray(photons.unshadowing,
                                                                                             bool)
    hist, h_prim = np.zeros((n, K, 7)), np.zeros((n, K), np.int64)
    tally = np.zeros(kernels.PH_TALLY, np.int64)
    # a record is a photon's diffuse vertex the camera may see directly (splat_records): none on an object
    # camera rays do not meet (its light seen in a mirror is the eye pass's)
    receivers = plan.receivers if not tracer.hidden.size else plan.receivers & ~tracer.hidden
    args = (tracer.kernel_geometry(plan.casters), np.ascontiguousarray(receivers, bool), materials(scene),
            Limits.of(scene).array(), int(max_bounces), int(max_iter), bool(physical), tracer.eps)
    key = int(rng.integers(2**63))

    def part(a, b):
        """Lanes a..b-1 (the arrays cut at b, so lane numbers and their random numbers stay)."""
        cap = max(b - a, max_iter + 1)  # a lane makes at most max_iter records: every call moves on
        recs, ids, tally_p, rays, lane = [], [], np.zeros_like(tally), 0, a
        while lane < b:
            rec, rec_i = np.empty((cap, kernels.REC_F)), np.empty((cap, 3), np.int64)
            rt = tracer.rays()
            lane, m, counts = kernels.photon_lanes(rt, bool(indirect), o0[:b], d0[:b], w0[:b], soft, lvis, lit,
                                                   unshadowing, key, lane,
                                                   *args, rec, rec_i, hist[:b], h_prim[:b], tally_p)
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
    stats["photons"] = stats.get("photons", 0) + int(tally[kernels.PH_PHOTONS])
    rec, ids = (np.concatenate(recs), np.concatenate(ids)) if len(recs) != 1 else (recs[0], ids[0])
    return rec, ids, hist, h_prim, tally


def splat_records(scene, tracer, cam, film, rec, ids, stats, first_order=True):
    """Connect run_photons' records (diffuse vertices with the direction the photon arrived from
    and its flux) to the camera and splat flux x BSDF x importance, in one kernel call
    (kernels.camera_splats, the shadow rays cast there), or one per part on each thread as
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
        rays, m, counts = kernels.camera_splats(rt, cam_p, float(film.filter_width), rec[a:b], mat[a:b], mats,
                                                bool(first_order), tracer.eps, textured, view,
                                                (tracer.ng, scene.tri_object, tracer.hid), rx[a:b], ry[a:b],
                                                val[a:b], alb[a:b] if textured.size else alb)
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
    stats["truncated"] += int(tally[kernels.PH_TRUNCATED])
    stats["lost_shading_normal"] += int(tally[kernels.PH_LOST])
    if tally[kernels.PH_BEYOND]:  # photons whose events no longer fit can splat nowhere
        stats["beyond_light_paths"] = stats.get("beyond_light_paths", 0) + int(tally[kernels.PH_BEYOND])
    if handoff is not None and len(rec):
        ln = ids[:, 0]
        y_end = -photons.d[ln] if handoff.directional else photons.o[ln]
        h = hist[ln]
        take = _handoff_select(scene, tracer, handoff, rec[:, 0:3], ids[:, 1], h_prim[ln], h[:, :, 0:3],
                               h[:, :, 3:5], h[:, :, 5].astype(np.int64),
                               walked_casters(scene, h_prim[ln], h[:, :, 6] > 0), y_end)
        rec, ids = rec[take], ids[take]
        stats["handoff_paths"] = stats.get("handoff_paths", 0) + int(take.sum())
    splat_records(scene, tracer, cam, film, rec, ids, stats)


def trace_eye(scene, tracer, cam, film, plan, light_indices, start, n, n_batch, rng, stats,
              max_bounces=MAX_SPECULAR_BOUNCES, physical=False, lights_direct=(), cells=None):
    """Caustics seen through mirrors or glass: camera -> (specular)+ -> diffuse receiver
    x0 -> ... -> light, by path tracing from the eye.

    The light tracer cannot connect such x0 to the camera (the connection passes a
    delta BSDF), so this estimator covers exactly the paths whose eye chain has at
    least one specular vertex; together they partition the caustic layer. From x0,
    cosine-sampled paths must find a finite light right after a specular vertex on a
    caster (x0's own caustic, or that of a later diffuse vertex), or light a later
    diffuse vertex directly once a specular vertex lies behind (indirect.gather):
    unbiased, noisy for small lights, blind to point lights of radius 0 and suns of
    angle 0. cells: a mask over the film cells whose samples are traced (eye.specular_cells:
    those that can see a mirror or glass first; None: all)."""
    from ..trace.eye import eye_receivers
    from .gather import gather

    rc = eye_receivers(scene, tracer, cam, film, plan, start, n, n_batch, rng, stats, min_specular=1,
                       max_bounces=max_bounces, scale_eta=physical, cells=cells)
    gather(scene, tracer, film, plan, rc, rng, stats, lights_direct, physical=physical,
           lights_hit=light_indices, count_first=True)


def trace_bent(scene, tracer, cam, film, plan, lights, start, n, n_batch, rng, stats, physical=False):
    """The light tracer's share of the paths through a vertex Cycles' Bump Map Correction bends
    (indirect.bent_gather) at receivers the camera sees directly, where photons splat (no photon
    makes such a path; at receivers seen through mirrors and glass trace_eye's gather finds
    them): eye samples start..start+n of the batch to their first surface, kept where it is a
    diffuse receiver seen directly."""
    from ..trace.eye import eye_receivers
    from .gather import bent_gather

    rc = eye_receivers(scene, tracer, cam, film, plan, start, n, n_batch, rng, stats, min_specular=0,
                       scale_eta=physical)
    bent_gather(scene, tracer, film, plan, rc.take(np.flatnonzero(rc.eye_specular == 0)), rng, stats, lights,
                physical=physical)
