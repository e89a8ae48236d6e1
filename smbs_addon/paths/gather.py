"""Caustic light that meets more than one diffuse surface.

The caustic layer is what Cycles adds when caustics are on: every path camera ->
(specular)* -> diffuse x0 -> ... -> light with at least one specular vertex on
the light's side of x0. The manifold pass and the light tracer's first pass take
the paths with x0 the only diffuse vertex (x0 -> specular+ -> light). This module
takes the rest, the paths with at least one more diffuse vertex: a floor lit
directly that lights a glass ball, which focuses that light back onto the floor
(camera -> floor -> glass -> floor -> light), or water whose caustic on a pool's
floor rises, reflects off the water's underside (total internal reflection) and
lands on the floor again (camera -> water -> floor -> water -> floor -> water ->
sun). On a pool with a floor of albedo 0.8 that is a third of the layer.

Two estimators, split by how the camera sees x0:
- directly: light tracing (``trace_indirect_photons``). Photons leave the lights in every
  direction, bounce off diffuse surfaces (cosine, Russian roulette on the
  albedo) and through specular ones, and splat at each receiver the camera sees
  once their history holds a specular vertex and a diffuse one;
- through mirrors or glass (the camera cannot be reached from x0 by a photon):
  path tracing from x0 (``gather``): cosine bounces through specular chains to
  the next diffuse vertices x1, x2, ..., where direct light counts once a
  specular vertex lies behind, and the caustic at xi (xi -> specular+ -> light)
  is estimated by the caller's ``connect`` (the manifold walks), or, for the
  light tracer, by lights hit after a specular vertex.
Bounces are counted as Cycles counts them, within the scene's Light Paths limits
(bounces.py; without limits, 4 diffuse bounces). The paths are traced in compiled code
(kernels/gather.py); gather_generations.py is their numpy form, path_light.py what they meet.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core import embree, lanes, qmc
from ..kernels.gather import gather_lanes
from ..kernels import handoff, records
from ..shading import optics
from ..scene import arrays as S
from ..scene.light_paths import Limits, ONE_DIFFUSE
from ..trace.eye import BatchPart, Receivers, direct_albedo, eye_receivers
from ..scene.geometry import triangle_areas
from ..shading.lights import area_light_shape
from ..shading.light_samples import light_can_be_hit
from .gather_generations import GatherByGenerations
from .handoff import handoff_select, other_paths, walked_casters
# seen_light: the gathers' light test, here too for its callers
from .path_light import MAX_SPECULAR, albedo, direct_light, seen_light  # noqa: F401
from .photons import MAX_SPECULAR_BOUNCES, run_photons, splat_records
from ..kernels.records import (
    BentTargets, EyePaths, GatherOut, GatherReceivers, GatherRules, HIST_B, HIST_BENT, HIST_CASTER, HIST_F, HIST_P,
    HIST_REFL, HandoffOut, HandoffReceivers, SEG_BETA, SEG_D, SEG_O, SEG_T)

HANDOFF_SAMPLES = 64  # cosine directions per receiver in handoff_gather
# the same where nothing is walked (every caster rough): the gather is then the whole estimator at
# receivers seen through mirrors or glass, and more eye samples beat more directions per receiver.
# Relative RMSE x time, SMBS, 2 seeds, 8 against 64: rough_pool_sun (64 spp) 1.42-1.46 in 3.3-3.7 s
# against 1.10-1.13 in 15.1-16.2 s, 2.7x more efficient; rough_glass_ball (256 spp) 1.2x. Where
# walks run (cube_grey, 32 spp: 0.71-0.83 against 0.56-0.70 in the same time) 64 stays
UNWALKED_SAMPLES = 8
HANDOFF_LANES = 1 << 17  # rays in flight in handoff_gather
# bent_gather's aimed bounces per receiver; its receivers are a share of the eye samples. The
# manifold passes take one receiver in BENT_RECEIVER_SHARE (4 bounces from every receiver made
# SMBS on sample_blends' glass ball 3.3 -> 3.9-4.0 s at 16 spp), the light tracer one eye sample
# in BENT_EYE_SHARE (on cube_grey_reflect at 1024 spp, 4 from every eye sample took 11 of the
# bake's 13.5 s, most of it the eye paths; 16 from one in 16, 2.2 of 4.6 s; on the glass ball of
# sample_blends (256 spp) that doubled the bake for 0.2% of its layer, so 16 from one in 64)
BENT_BOUNCES, BENT_RECEIVER_SHARE, BENT_EYE_SHARE = 16, 16, 64
# specular vertices bent_gather follows: the bent paths are a few % of a layer at most (1.65% on
# cube_grey), and chains longer than 8 carry 0.8-2.0% of a bevelled cube's light (OTHERS_DEPTH);
# each lane keeps a record per vertex (handoff.handoff_lanes' seg and hist)
BENT_DEPTH = 8
# specular vertices handoff_gather follows for the paths no walk takes (chains longer than
# max_chain), as far as the conformance scenes' Cycles settings (16 glossy and transmission
# bounces): of the light a bevelled glass cube brings into the frame, chains of more than 8
# vertices carry 0.8-2.0%, of more than 16 0.3-0.7% (photons, cube_grey and cube_white_rect)
OTHERS_DEPTH = 16


def trace_indirect_photons(scene, tracer, cam, film, plan, photons, rng, stats, physical=False):
    """Light tracing of the layer's paths through two or more diffuse vertices, splatted
    at the receivers the camera sees directly (photons from lights.emit over the whole
    scene, not only towards the casters), within the scene's Light Paths limits
    (photons.photon_lanes, indirect)."""
    lim = Limits.of(scene)
    rec, ids, _, _, _ = run_photons(scene, tracer, plan, photons, rng, stats, indirect=True,
                                    max_iter=MAX_SPECULAR + min(lim.diffuse, 64) + 1, physical=physical)
    splat_records(scene, tracer, cam, film, rec, ids, stats, first_order=False)


@dataclass(frozen=True)
class GatherLights:
    """What gather counts along its paths: direct (lights_direct), hit, count_first, connect and
    others as gather's docstring says."""

    direct: tuple = ()
    hit: tuple = ()
    count_first: bool = False
    connect: object = None
    others: dict | None = None


def gather(scene, tracer, film, plan, rc: Receivers, rng, stats, lights: GatherLights, physical=False,
           compiled=True):
    """Path tracing from receivers x0 (seen through mirrors or glass) for the layer's paths
    with more diffuse vertices; splats the radiance found at the eye samples' film positions.

    Generations of diffuse vertices x0, x1, x2, ...: from each, one cosine bounce (Russian
    roulette on the albedo) through specular vertices to the next diffuse vertex, where
    - direct light of lights_direct counts once a specular vertex on a caster lies
      between x0 and there;
    - connect(receivers) -> (M,3), the caller's estimate of the caustic at planned
      receivers (x_i -> specular+ -> light, throughput included: the manifold walks), counts
      always; without connect, lights_hit seen right after a specular vertex on a caster
      count instead (the light tracer's way), x0's own caustic only when count_first;
    - with connect, others (light index -> reference.Handoff, those of others=True) adds the
      paths x_i -> specular+ -> light (i >= 1) no walk takes (reference.other_paths: a chain
      type not walked, longer than the longest walked, or through a specular vertex that is no
      walked caster, such as a rough one), the lights hit on them, as handoff_gather adds them
      at x0: the walks' estimate at x_i leaves exactly those out.
    Every path keeps to the scene's Light Paths limits as Cycles counts them (bounces.py:
    the events before the last one, from the camera, rc.prior before x0).

    The paths are traced in compiled code (_traced_gather without connect, _connected_gather with it),
    unless compiled is False (the same estimator in numpy, per bounce, for the tests) or others
    has paths no walk takes to add along the way (gather_generations.GatherByGenerations)."""
    if len(rc.p) == 0:
        return
    splat_gathered(scene, film, rc, gather_radiance(scene, tracer, plan, rc, rng, stats, lights, physical, compiled),
                   stats)


def gather_radiance(scene, tracer, plan, rc: Receivers, rng, stats, lights: GatherLights, physical=False,
                    compiled=True) -> np.ndarray:
    """gather's radiance (n,3) at the receivers rc (times their eye paths' throughput), not splatted."""
    if len(rc.p) == 0:
        return np.zeros((0, 3))
    if lights.connect is None and compiled:
        return _traced_gather(scene, tracer, plan, rc, rng, stats, lights.direct, physical, lights.hit,
                              lights.count_first)
    if compiled and not any(ho.others for ho in (lights.others or {}).values()):
        return _connected_gather(scene, tracer, plan, rc, rng, stats, lights.direct, physical, lights.connect)
    others = lights.others if lights.connect else None
    return GatherByGenerations(scene, tracer, plan, rc, rng, stats, physical, others).run(
        lights.direct, lights.connect, lights.hit, lights.count_first)


def splat_gathered(scene, film, rc: Receivers, radiance, stats):
    """Splat the radiance gathered at the receivers rc (gather_radiance) at their film positions."""
    hit = np.flatnonzero(radiance.max(axis=1) > 0)
    if hit.size:
        film.splat(rc.rx[hit], rc.ry[hit], radiance[hit] * rc.weight[hit, None], direct_albedo(scene, rc, hit))
        stats["eye_splats"] = stats.get("eye_splats", 0) + int(hit.size)


def _gather_records(scene, tracer, plan, rc: Receivers, rng, stats, physical, want: tuple, count_first=False):
    """The records of gather's paths from the receivers rc, traced in kernel calls (gather.gather_lanes,
    their random numbers keyed by one draw from rng and the receiver's index; x0's own bounce stratified
    where rc is): want = (segments, vertices, connect records) which to write. Returns (seg, seg_i, vx,
    vx_i, cx, cx_i)."""
    n = len(rc.p)
    lim = Limits.of(scene)
    want_seg, want_vx, want_cx = (bool(w) for w in want)
    f64 = lambda a: np.ascontiguousarray(a, np.float64)  # noqa: E731
    u0 = np.zeros((0, 2)) if rc.strata is None else f64(rc.strata[:, qmc.BOUNCE])
    ends = np.zeros(len(scene.object_names), bool) if plan.left_out is None else np.asarray(plan.left_out, bool)
    args = (GatherReceivers(f64(rc.p), f64(rc.ng), f64(rc.ns), f64(rc.w_eye), f64(rc.beta),
                            np.ascontiguousarray(rc.mat, np.int64), np.ascontiguousarray(rc.prior, np.int64), u0),
            tracer.kernel_geometry(plan.casters), optics.materials(scene),
            GatherRules(lim.array(), MAX_SPECULAR, bool(physical), bool(count_first), want_seg, want_vx, want_cx,
                        np.ascontiguousarray(plan.receivers, bool), np.ascontiguousarray(ends)), tracer.eps)
    key = int(rng.integers(2**63))
    # a lane records at most MAX_SPECULAR segments and one vertex per diffuse vertex: every call moves on
    cap = max(n, (int(lim.diffuse) + 2) * (MAX_SPECULAR + 2))
    n_seg, n_vx, n_cx = (cap if want_seg else 0), (cap if want_vx else 0), (cap if want_cx else 0)
    parts, lane = [], 0
    while lane < n:
        seg, seg_i = np.empty((n_seg, records.SEG_F)), np.empty(n_seg, np.int64)
        vx, vx_i = np.empty((n_vx, records.VX_F)), np.empty(n_vx, np.int64)
        cx, cx_i = np.empty((n_cx, records.CX_F)), np.empty(n_cx, np.int64)
        rt = tracer.rays()
        lane, ms, mv, mc, counts = gather_lanes(rt, key, lane, *args, GatherOut(seg, seg_i, vx, vx_i, cx, cx_i))
        tracer.cast_by_kernel(rt, counts)
        stats["rays_gather"] = stats.get("rays_gather", 0) + int(counts[embree.KINDS:].sum())
        parts.append((seg[:ms], seg_i[:ms], vx[:mv], vx_i[:mv], cx[:mc], cx_i[:mc]))
    return tuple(np.concatenate([p[k] for p in parts]) for k in range(6))


def _direct_at_vertices(scene, tracer, vx, vx_i, lights_direct, rng, stats, radiance) -> None:
    """The direct light of lights_direct at gather's vertex records (VX_*), added to radiance per lane."""
    if not len(vx):
        return
    c = lambda k: vx[:, k:k + 3]  # noqa: E731
    vx_obj = vx[:, records.VX_OBJ].astype(np.int64)
    for li in lights_direct:
        rad = direct_light(scene, tracer, li, c(records.VX_P), c(records.VX_NG), c(records.VX_NS),
                           c(records.VX_W), rng, stats, vx_obj)
        np.add.at(radiance, vx_i, c(records.VX_BETA) * rad)


def _connected_gather(scene, tracer, plan, rc: Receivers, rng, stats, lights_direct, physical, connect):
    """gather's radiance (n,3) with the walks to connect and no paths no walk takes to add: the paths
    traced in kernel calls (_gather_records), then at every later diffuse vertex on a planned receiver
    the walks' caustic (connect, one call for them all) and lights_direct's direct light, as
    GatherByGenerations finds them generation by generation."""
    n = len(rc.p)
    _, _, vx, vx_i, cx, cx_i = _gather_records(scene, tracer, plan, rc, rng, stats, physical,
                                               (False, bool(lights_direct), True))
    radiance = np.zeros((n, 3))
    _direct_at_vertices(scene, tracer, vx, vx_i, lights_direct, rng, stats, radiance)
    if len(cx):
        c = lambda k: cx[:, k:k + 3]  # noqa: E731
        sub = Receivers(rx=rc.rx[cx_i], ry=rc.ry[cx_i], p=c(records.CX_P), ng=c(records.CX_NG), ns=c(records.CX_NS),
                        w_eye=c(records.CX_W), beta=c(records.CX_BETA), mat=cx[:, records.CX_MAT].astype(np.int64),
                        eye_specular=np.maximum(rc.eye_specular[cx_i], 1), weight=rc.weight[cx_i],
                        prior=c(records.CX_CNT).astype(np.int64),
                        strata=None if rc.strata is None else qmc.after_bounce(rc.strata[cx_i]))
        np.add.at(radiance, cx_i, connect(sub))
    return radiance


def _traced_gather(scene, tracer, plan, rc: Receivers, rng, stats, lights_direct, physical, lights_hit, count_first):
    """gather's radiance (n,3) at the receivers without walks to connect (the light tracer's):
    the paths traced in kernel calls (_gather_records), the lights on the segments it records and
    the direct light at the vertices it records found here, as gather finds them."""

    n = len(rc.p)
    hit_lights = [li for li in lights_hit if light_can_be_hit(scene, li)]
    seg, seg_i, vx, vx_i, _, _ = _gather_records(scene, tracer, plan, rc, rng, stats, physical,
                                                 (hit_lights, lights_direct, False), count_first)
    radiance = np.zeros((n, 3))
    if len(seg):
        o, d, surf_t = seg[:, records.SEG_O:records.SEG_O + 3], seg[:, records.SEG_D:records.SEG_D + 3], \
            seg[:, records.SEG_T]
        beta, refl = seg[:, records.SEG_BETA:records.SEG_BETA + 3], seg[:, records.SEG_REFL] > 0
        seg_obj = seg[:, records.SEG_OBJ].astype(np.int64)
        for li in hit_lights:  # every light in front of the next surface (seen_light)
            seen, L, tl = seen_light(scene, tracer, li, o, d, refl, surf_t, seg_obj)
            seen = np.flatnonzero(seen)
            np.add.at(radiance, seg_i[seen], beta[seen] * L[seen])
    _direct_at_vertices(scene, tracer, vx, vx_i, lights_direct, rng, stats, radiance)
    return radiance


@dataclass(frozen=True)
class HandoffRays:
    """How handoff_gather traces: samples cosine directions per receiver (or aimed: bent); bent: only
    the paths through a normal Cycles' Bump Map Correction bends (bent_gather), their first bounce
    aimed at the triangles that bend (aim) or cosine-sampled."""

    samples: int = HANDOFF_SAMPLES
    bent: bool = False
    aim: bool = True


def handoff_gather(scene, tracer, film, plan, rc: Receivers, rng, stats, handoffs: dict, physical=False,
                   rays: HandoffRays = HandoffRays(), found: dict | None = None):
    """The hand-off for receivers seen through mirrors or glass (rc), where no photon can
    reach the camera: one cosine bounce from x0 through up to K specular vertices, counting
    a light hit only when reference.handoff_select gives that path to the photons (its
    chain a walked type on casters, focusing more than tau). The manifold pass drops
    exactly those paths at these receivers, so the two add up; near a focus, where the
    walks' estimate is heavy-tailed, the light seen from x0 through the caster is large
    and cosine sampling finds it easily.

    With a Handoff's ``others``, the paths no walk takes (a chain type not walked, longer than
    the longest walked, or through a specular vertex that is no planned caster; up to
    OTHERS_DEPTH vertices) count too, as the photons take them at receivers seen directly.

    handoffs: light index -> reference.Handoff; rays.samples:
    cosine directions per receiver (rays are cheap next to the walks they replace, and a
    focus's light is a small target); found: light index -> paths taken, added to.

    rays.bent (bent_gather): instead, every path through a specular vertex whose normal Cycles' Bump
    Map Correction bent (optics.valid_reflection1) counts, and nothing else (handoffs: light index
    -> None; aim: its first bounce towards the triangles that bend, False: cosine, every bent path).
    Without bent such paths never count here: neither photons nor walks make them, so they are
    bent_gather's alone."""
    n = len(rc.p)
    if n == 0 or not handoffs:
        return
    # blocks of receivers (bounded memory: HANDOFF_LANES rays in flight per thread) taken by the
    # threads in turn, each path's random numbers keyed by one draw, its receiver and its sample
    # (handoff.handoff_lanes), each block with its own counters, added in block order: the image
    # does not depend on the thread count
    key = int(rng.integers(2**63))

    def block(a, b):
        st, per_light = {}, {}
        rad = _handoff_block(scene, tracer, plan, rc.take(slice(a, b)), key, a, st, handoffs, physical, rays,
                             per_light)
        return rad, st, per_light

    # receivers per block: HANDOFF_LANES rays in flight at up to 4 specular vertices (each lane
    # keeps a record per vertex), fewer when the paths no walk takes are followed further
    per_block = max(1, HANDOFF_LANES // rays.samples * 4 // max(4, _handoff_depth(handoffs)))
    parts = lanes.blocks(block, n, per_block, tracer.threads)
    radiance = np.concatenate([p[0] for p in parts])
    for _, st, per_light in parts:
        lanes.add_stats(stats, st)
        if found is not None:
            for li, v in per_light.items():
                found[li] = found.get(li, 0) + v
    hit = np.flatnonzero(radiance.max(axis=1) > 0)
    if hit.size:
        film.splat(rc.rx[hit], rc.ry[hit], radiance[hit] * rc.weight[hit, None], direct_albedo(scene, rc, hit))


def _light_shapes(scene, lights: tuple, eps: float):
    """handoff.segments_near's rows for these lights, spheres widened by a millionth and eps (the
    tracer's offset); a light at infinity keeps every segment (NEAR_ALL)."""
    rows = np.zeros((len(lights), records.NEAR_F))
    for row, li in zip(rows, lights):
        typ, m = scene.light_type[li], scene.light_matrix[li]
        if typ in S.DISTANT:
            row[0] = records.NEAR_ALL
        elif typ in (S.POINT, S.SPOT):
            r = float(scene.light_radius[li])
            if r * r > 0:
                row[:5] = (records.NEAR_SPHERE, *m[:3, 3], r * (1 + 1e-6) + eps)
            else:
                row[0] = records.NEAR_NONE  # lights.light_radiance: never met
        elif typ == S.AREA:
            cen, ex, ey, nrm, hx, hy, _ = area_light_shape(scene, li)
            disk = scene.light_shape[li] in (S.DISK, S.ELLIPSE)
            row[:] = (records.NEAR_DISK if disk else records.NEAR_RECT, *cen, *ex, *ey, *nrm, hx, hy)
        else:  # a mesh light: the sphere about its triangles' box
            tv = scene.mesh_light(li)[1].reshape(-1, 3)
            lo, hi = tv.min(axis=0), tv.max(axis=0)
            row[:5] = (records.NEAR_SPHERE, *(0.5 * (lo + hi)), 0.5 * np.linalg.norm(hi - lo) * (1 + 1e-6) + eps)
    return rows


def _handoff_depth(handoffs: dict) -> int:
    """Specular vertices handoff_gather follows: the longest walked chain, or OTHERS_DEPTH where
    it takes the paths no walk takes (Handoff.others), BENT_DEPTH for the bent ones (None)."""
    return max(BENT_DEPTH if h is None else max(h.max_chain, OTHERS_DEPTH) if h.others else h.max_chain
               for h in handoffs.values())


def bending_lights(scene, tracer, plan) -> list:
    """The planned lights whose caustics can pass a bent specular vertex (bent_gather): a ray can
    hit them, and some triangle can bend (bent_candidates; flat faces never do: their shading
    normal is the geometric one). Empty: nothing to do."""
    if not len(bent_candidates(scene, tracer, plan)[0]):
        return []

    return [lp.index for lp in plan.lights if light_can_be_hit(scene, lp.index)]


def bent_candidates(scene, tracer, plan):
    """The triangles whose normals Cycles' Bump Map Correction can bend (on planned casters, the
    material's flag on, shading normals that differ from the geometric one), their cumulative
    areas and its guide table (handoff.cdf_pick): bent_gather aims its first bounce at points
    uniform over them. Kept on the plan."""
    if plan.bent is not None:
        return plan.bent
    corr = optics.bump_correction(scene)
    ok = np.asarray(plan.casters, bool)[scene.tri_object] & corr[scene.tri_material]
    ok &= np.abs(np.einsum("tkc,tc->tk", tracer.ns_corner, tracer.ng)).min(axis=1) < 1.0 - 1e-12
    cand = np.flatnonzero(ok).astype(np.int64)
    area = triangle_areas(tracer.v[cand])
    if cand.size and area.sum() > 0:
        cdf = np.cumsum(area)
        cached = (cand, cdf, handoff.guide_table(cdf))
    else:
        cached = (np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.int64))
    plan.bent = cached
    return cached


def bent_receivers(rc: Receivers, rng, share=BENT_RECEIVER_SHARE) -> Receivers:
    """The manifold passes' receivers for bent_gather: one in `share` at random, its splat weighted
    up by as much. Not every share-th: the eye samples run through the film cells in turn, so on a
    film whose cells are a multiple of 16 (164 x 124 for 160 x 120) every 16th receiver would be
    in the same cells on every pass, and the others would never get the bent light."""
    rb = rc.take(np.flatnonzero(rng.random(len(rc.p)) * share < 1.0))
    rb.weight = rb.weight * share
    return rb


def bent_gather(scene, tracer, film, plan, rc: Receivers, rng, stats, lights, physical=False,
                samples=BENT_BOUNCES, aim=True):
    """The caustic paths whose first specular vertex (from the receiver) has a shading normal
    Cycles' Bump Map Correction bends (optics.valid_reflection1), at receivers rc: the light
    then leaves the bent vertex along a direction only the eye's side determines, so no photon
    and no walk makes them. On a bevelled glass cube 2 cm above the floor, the light reflected
    off its outside at grazing angles doubles in the shadow beside it (conformance scene
    cube_grey_reflect). Traced from x0 (handoff_gather, bent) towards points uniform in area over
    the triangles that can bend (bent_candidates; handoff._toward_triangle): cosine sampling
    found 38 such paths in 22 M rays on that cube. lights: the light indices that count. Paths
    bent only at a later vertex are in no estimator (handoff_gather drops every bent path).
    aim False: cosine sampling instead, every bent path (the tests' independent estimator)."""
    if len(lights):  # bending_lights: only where some triangle can bend
        handoff_gather(scene, tracer, film, plan, rc, rng, stats, dict.fromkeys(lights), physical=physical,
                       rays=HandoffRays(samples, bent=True, aim=aim))


def _handoff_block(scene, tracer, plan, rc: Receivers, key, a0, stats, handoffs: dict, physical, rays: HandoffRays,
                   found):
    """handoff_gather's radiance (n,3) at a block of receivers, a0 the first's index (key, a0:
    handoff.handoff_lanes' random numbers); found: light index -> paths taken.
    The paths are traced in one kernel call (handoff.handoff_lanes); the lights seen on their
    segments and the paths taken are found here, per number of specular vertices."""

    n = len(rc.p)
    K = _handoff_depth(handoffs)
    samples, bent, aim = rays.samples, rays.bent, rays.aim
    m = n * samples
    # the kernel writes every entry read below (a lane's first seg_n segments, and the specular
    # vertices before each of them)
    seg, seg_n = lanes.scratch("handoff_seg", (m, K, SEG_BETA + 3)), np.zeros(m, np.int64)
    hist, h_prim = lanes.scratch("handoff_hist", (m, K, HIST_F)), lanes.scratch("handoff_prim", (m, K), np.int64)
    f64 = lambda a: np.ascontiguousarray(a, np.float64)  # noqa: E731
    rt = tracer.rays()
    none = (np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.int64))
    targets = BentTargets(*(bent_candidates(scene, tracer, plan) if bent and aim else none))
    receivers = HandoffReceivers(f64(rc.p), f64(rc.ng), f64(rc.ns), f64(rc.sn), f64(rc.w_eye), f64(rc.beta / samples),
                                 f64(albedo(scene, rc.mat)), np.ascontiguousarray(rc.mat, np.int64))
    counts = handoff.handoff_lanes(rt, key, a0, samples, K, receivers, tracer.kernel_geometry(plan.casters),
                                   optics.materials(scene), bool(physical), tracer.eps,
                                   HandoffOut(seg, seg_n, hist, h_prim), targets)
    tracer.cast_by_kernel(rt, counts)
    name = "bent" if bent else "handoff"
    stats["rays_" + name] = stats.get("rays_" + name, 0) + int(counts[embree.KINDS:].sum())
    radiance = np.zeros((n, 3))
    lim = Limits.of(scene)
    # the segments that can meet one of the lights at all, ahead of the exact tests below (which
    # took a third of the hand-off's time): 1 in 1,300 on the floor seen in a gold ring, 1 in 420
    # on a disk seen through a pane, 1 in 23-26 under a glass ball lit by a lamp or a mesh panel
    near = lanes.scratch("handoff_near", (m, K), np.bool_)
    handoff.segments_near(seg, seg_n, _light_shapes(scene, tuple(handoffs), tracer.eps), near)
    for k in range(K):  # the segments after bounce = k + 1 specular vertices (near: only those a lane has)
        row = np.flatnonzero(near[:, k])
        if row.size == 0:
            continue
        bounce = k + 1
        sk = seg[row, k]
        o, d, surf_t, beta = sk[:, SEG_O:SEG_O + 3], sk[:, SEG_D:SEG_D + 3], sk[:, SEG_T], sk[:, SEG_BETA:SEG_BETA + 3]
        # Light Paths: the camera's events before x0, x0's diffuse bounce and the specular vertices
        # before the last (bounces.py)
        refl = hist[row, :k, HIST_REFL].sum(axis=1) if k else np.zeros(row.size)
        fits = lim.fits(rc.prior[row // samples] + ONE_DIFFUSE + np.stack([np.zeros(row.size), refl, k - refl], axis=1))
        # bent paths are bent_gather's alone (handoff_gather's docstring)
        fits &= (hist[row, :bounce, HIST_BENT].max(axis=1) > 0) == bent
        for li, ho in handoffs.items():  # every light before the surface counts (as in gather)
            refl = hist[row, k, HIST_REFL] > 0
            # Light Linking: of the vertex the light leaves last, the segment's own
            seen, L, tl = seen_light(scene, tracer, li, o, d, refl, surf_t, scene.tri_object[h_prim[row, k]])
            seen = np.flatnonzero(seen & fits)
            if seen.size == 0:
                continue
            if ho is None:
                np.add.at(radiance, row[seen] // samples, beta[seen] * L[seen])
                stats["bent_paths"] = stats.get("bent_paths", 0) + int(seen.size)
                continue
            y = d[seen] if ho.directional else o[seen] + tl[seen, None] * d[seen]
            r = row[seen]
            # handoff_select reads the history light side first: reverse the bounces
            rev = np.arange(bounce)[::-1]
            hr = hist[r][:, rev]
            kb, refl = np.full(seen.size, bounce), hr[:, :, HIST_REFL].astype(np.int64)
            caster = walked_casters(scene, h_prim[r][:, rev], hr[:, :, HIST_CASTER] > 0)
            take = handoff_select(scene, tracer, ho, rc.p[r // samples], kb, h_prim[r][:, rev],
                                   hr[:, :, HIST_P:HIST_P + 3], hr[:, :, HIST_B:HIST_B + 2], refl, caster, y)
            t = seen[take]
            np.add.at(radiance, row[t] // samples, beta[t] * L[t])
            # the focusing paths of walked types (what tells later chunks to hand off) apart from
            # the paths no walk takes
            other = other_paths(ho, kb, refl, caster)[take] if ho.others else np.zeros(t.size, bool)
            stats["handoff_paths"] = stats.get("handoff_paths", 0) + int(t.size - other.sum())
            stats["other_paths"] = stats.get("other_paths", 0) + int(other.sum())
            found[li] = found.get(li, 0) + int(t.size - other.sum())
            # and their light (as splatted), which tells later chunks whether the hand-off is worth its rays
            focus = t[~other]
            found[("energy", li)] = found.get(("energy", li), 0.0) + float(
                ((beta[focus] * L[focus]).mean(axis=1) * rc.weight[row[focus] // samples]).sum())
    return radiance


def trace_eye(scene, tracer, cam, film, plan, light_indices, samples, rng, stats, physical=False, lights_direct=(),
              cells=None):
    """Caustics seen through mirrors or glass: camera -> (specular)+ -> diffuse receiver
    x0 -> ... -> light, by path tracing from the eye.

    The light tracer cannot connect such x0 to the camera (the connection passes a
    delta BSDF), so this estimator covers exactly the paths whose eye chain has at
    least one specular vertex; together they partition the caustic layer. From x0,
    cosine-sampled paths must find a finite light right after a specular vertex on a
    caster (x0's own caustic, or that of a later diffuse vertex), or light a later
    diffuse vertex directly once a specular vertex lies behind (indirect.gather):
    unbiased, noisy for small lights, blind to point lights of radius 0 and suns of
    angle 0. samples: (start, n, n_batch), eye samples start..start+n of a batch of n_batch. cells:
    a mask over the film cells whose samples are traced (eye.specular_cells: those that can see a
    mirror or glass first; None: all)."""
    start, n, n_batch = samples
    rc = eye_receivers(scene, tracer, cam, film, plan, BatchPart(start, n, n_batch), rng, stats,
                       EyePaths(max_bounces=MAX_SPECULAR_BOUNCES, min_specular=1, scale_eta=physical), cells=cells)
    gather(scene, tracer, film, plan, rc, rng, stats, GatherLights(direct=lights_direct, hit=light_indices,
                                                                   count_first=True), physical=physical)


def trace_bent(scene, tracer, cam, film, plan, lights, start, n, n_batch, rng, stats, physical=False):
    """The light tracer's share of the paths through a vertex Cycles' Bump Map Correction bends
    (indirect.bent_gather) at receivers the camera sees directly, where photons splat (no photon
    makes such a path; at receivers seen through mirrors and glass trace_eye's gather finds
    them): eye samples start..start+n of the batch to their first surface, kept where it is a
    diffuse receiver seen directly."""

    rc = eye_receivers(scene, tracer, cam, film, plan, BatchPart(start, n, n_batch), rng, stats,
                       EyePaths(min_specular=0, scale_eta=physical))
    bent_gather(scene, tracer, film, plan, rc.take(np.flatnonzero(rc.eye_specular == 0)), rng, stats, lights,
                physical=physical)
