"""The passes a bake runs per batch, each over chunks of lanes with their own random streams: the
light tracer's photons and eye paths, light after a diffuse bounce, the manifold walks, and the
photon hand-off beside the walks. Each adds to the job's film and counters (job.py).
"""
from __future__ import annotations

import math
import time
from collections import defaultdict

import numpy as np

from ..core import lanes
from ..core.random import EYE, HANDOFF, INDIRECT, PHOTONS, SKY, WALKS, light_key
from ..paths import gather as indirect, photons
from ..paths.sky import trace_sky
from ..paths.handoff import Handoff
from ..scene import arrays as S
from ..shading.lights import emit
from ..shading.microfacet import rough_casters
from ..trace.eye import BatchPart
from ..walks.manifold import manifold_chunk
from .pilots import spot_target

CHUNK = 65536  # lanes per chunk (keeps temporaries in cache, see performance-anchors.md)
WALK_CHUNK = 65536  # eye samples per manifold chunk (each fans out to lights x chain types x trials): big
# enough that the walks' kernel and intersect calls see thousands of lanes (8192: 19.1 s, 65536: 16.3 s for
# the glass sphere at 512^2, SMS, bench/throughput.py)


class DeferredFilm:
    """The film as a chunk on a worker thread sees it: reads go to the film, splats are kept
    to be made on the calling thread, in chunk order (threaded_chunks)."""

    def __init__(self, film):
        self._film = film
        self.splats = []

    def __getattr__(self, name):
        return getattr(self._film, name)

    def splat(self, rx, ry, rgb, albedo=None) -> None:
        self.splats.append((rx, ry, rgb, albedo))

    def replay(self, film) -> None:
        """Make the kept splats on film, in the order they came."""
        for args in self.splats:
            film.splat(*args)


def threaded_chunks(job, n_chunks, run_chunk, stats, message=None):
    """run_chunk(c, film, stats) for the chunks c = 0 .. n_chunks-1 of a light-tracing pass, as
    many at a time as there are threads (lanes.blocks), each with its own random stream (the
    caller's, keyed by c), a deferred film and its own counters. Here, in chunk order, their
    splats are made and their counters added: the film is written by one thread, and the image
    is the one chunks run one after the other give, bit for bit. Cancel is checked and
    progress stepped (message: once per chunk) here too."""
    threads = job.tracer.threads
    per = max(1, threads)
    for g0 in range(0, n_chunks, per):
        job.prog.check()
        group = range(g0, min(g0 + per, n_chunks))

        def call(a, b):
            f, st = DeferredFilm(job.film), defaultdict(int)
            run_chunk(group[a], f, st)
            return f, st

        for f, st in lanes.blocks(call, len(group), 1, threads):
            f.replay(job.film)
            lanes.add_stats(stats, st)
            if message:
                job.prog.step(message)


def photon_pass(job, b, lp, per_batch, st, stream_kind=PHOTONS, handoff=None, step=True) -> float:
    """per_batch photons of light lp (a plan.PlannedLight) in chunks, each chunk with its own random
    stream: the seconds it took."""
    t_light = time.perf_counter()

    def run_chunk(c, film_c, st_c):
        start = c * CHUNK
        n = min(CHUNK, per_batch - start)
        rng = job.rng(stream_kind, lp.key, b, c)
        ph = emit(job.scene, lp.index, lp.targets, n, rng, job.plan.bounds)
        ph.w *= n / per_batch  # emit() weights by 1/n; a batch averages per_batch photons
        photons.trace_photons(job.scene, job.tracer, job.cam, film_c, job.plan, ph, rng, st_c,
                              physical=job.physical, handoff=handoff)

    threaded_chunks(job, -(-per_batch // CHUNK), run_chunk, st,
                    f"light '{lp.name}', batch {b + 1}/{job.settings.batches}" if step else None)
    return time.perf_counter() - t_light


def indirect_batch(job, b) -> None:
    """Light tracing of the caustic light that meets more than one diffuse surface, for the
    receivers the camera sees directly (indirect.trace_indirect_photons): photons over the whole
    scene, spp per pixel and light."""
    scene, plan, settings = job.scene, job.plan, job.settings
    if not sees_directly(plan):  # they splat at receivers seen directly only (pool_sun: 5% of its time, no splat)
        return
    for li in job.indirect_lights():
        st = job.indirect_stats.setdefault(scene.light_names[li], {"photons": 0, "rays_photon": 0, "rays_camera": 0,
                                                                   "splats": 0, "time_s": 0.0})
        t = time.perf_counter()
        # a narrow spot's photons go into its cone, as many as its cone let through when they were
        # aimed at the whole scene: the same noise, without tracing the masked ones
        target, share = spot_target(scene, li, plan.scene_sphere)
        per_batch = max(1, round(job.per_light * share * plan.sample_share.get(li, 1.0)) // settings.batches)

        def run_chunk(c, film_c, st_c, li=li, target=target, per_batch=per_batch):
            n = min(CHUNK, per_batch - c * CHUNK)
            rng = job.rng(INDIRECT, light_key(scene.light_names[li]), b, c)
            ph = emit(scene, li, target, n, rng, plan.bounds)
            ph.w *= n / per_batch
            indirect.trace_indirect_photons(scene, job.tracer, job.cam, film_c, plan, ph, rng, st_c, physical=job.physical)

        threaded_chunks(job, -(-per_batch // CHUNK), run_chunk, st)
        st["time_s"] += time.perf_counter() - t


def light_tracing_batch(job, b, eye_stats, eye_cells=None) -> None:
    """The light tracer's batch: photons per light, then eye paths for what is seen through
    mirrors and glass, traced from the film cells of the mask eye_cells (None: all)."""
    plan, settings = job.plan, job.settings
    for lp in plan.lights:
        st = job.light_stats[lp.name]
        per_batch = max(1, round(job.per_light * plan.sample_share.get(lp.index, 1.0)) // settings.batches)
        st["time_s"] += photon_pass(job, b, lp, per_batch, st)
    eye_per_batch = job.eye_per_batch() if eye_stats["enabled"] else 0
    t_eye = time.perf_counter()
    light_ids = [lp.index for lp in plan.lights]

    def run_chunk(c, film_c, st_c):
        start = c * CHUNK
        indirect.trace_eye(job.scene, job.tracer, job.cam, film_c, plan, light_ids,
                           (start, min(CHUNK, eye_per_batch - start), eye_per_batch), job.rng(EYE, 0, b, c), st_c,
                           physical=job.physical, lights_direct=job.indirect_lights(), cells=eye_cells)

    threaded_chunks(job, -(-eye_per_batch // CHUNK), run_chunk, eye_stats,
                    f"seen through glass and mirrors, batch {b + 1}/{settings.batches}")
    eye_stats["time_s"] += time.perf_counter() - t_eye
    bent_batch(job, b, eye_stats)


def bent_batch(job, b, eye_stats) -> None:
    """The paths through normals Cycles bends, at receivers seen directly (indirect.trace_bent):
    one eye sample in indirect.BENT_EYE_SHARE, its aimed bounces from each."""
    bent = indirect.bending_lights(job.scene, job.tracer, job.plan)
    if not bent:
        return
    t_bent = time.perf_counter()
    per_batch = max(1, -(-job.eye_per_batch() // indirect.BENT_EYE_SHARE))

    def bent_chunk(c, film_c, st_c):
        start = c * CHUNK
        indirect.trace_bent(job.scene, job.tracer, job.cam, film_c, job.plan, bent, start,
                            min(CHUNK, per_batch - start), per_batch, job.rng(EYE, 1, b, c), st_c,
                            physical=job.physical)

    bent_stats = eye_stats.setdefault("bent", {"time_s": 0.0})
    threaded_chunks(job, -(-per_batch // CHUNK), bent_chunk, bent_stats)
    bent_stats["time_s"] += time.perf_counter() - t_bent


def walks_batch(job, b, walk, eye_stats) -> None:
    """The manifold walks' batch (walk: walking.WalkSetup), chunk by chunk."""
    per_batch = job.eye_per_batch()
    for c, start in enumerate(range(0, per_batch, WALK_CHUNK)):
        job.prog.check()
        n = min(WALK_CHUNK, per_batch - start)
        manifold_chunk(job, walk, start, n, job.rng(WALKS, 0, b, c), eye_stats, job.strata(b))
        job.prog.step(f"{job.settings.method}, batch {b + 1}/{job.settings.batches}")


def sky_batch(job, b, strata=None) -> None:
    """The rest of a split world (job.sky: shading.world_parts.WorldParts), path-traced from the
    receivers of as many eye samples as the walks take (paths.sky.trace_sky), in chunks on the
    threads; counted in job.extra["sky"]. strata: batch b's stratified eye samples (Job.strata) where
    the film keeps replicates."""
    parts = job.sky
    if parts is None:
        return
    t = time.perf_counter()
    per_batch = job.eye_per_batch()
    direct = (parts.light,) if parts.light in job.indirect_lights() else ()

    def run_chunk(c, film_c, st_c):
        start = c * CHUNK
        trace_sky(parts.traced, job.tracer, job.cam, film_c, job.plan, parts.light,
                  BatchPart(start, min(CHUNK, per_batch - start), per_batch), job.rng(SKY, 0, b, c), st_c,
                  physical=job.physical, direct=direct, strata=strata)

    st = job.extra["sky"]
    threaded_chunks(job, -(-per_batch // CHUNK), run_chunk, st)
    st["time_s"] += time.perf_counter() - t


def hands_off(scene, plan, opts, types) -> bool:
    """Whether a manifold bake has a photon hand-off: paths through a rough mirror or glass are the
    photons' whatever opts.handoff (no walk takes them); otherwise where opts.handoff > 0 and
    some chain type is walked."""
    return bool(rough_casters(scene, plan.casters).any()) or (opts.handoff > 0 and bool(types))


def sees_directly(plan) -> bool:
    """Can the camera see a receiver directly, where alone a photon reaches it? False only where the
    plan's look from the camera found every receiver it sees behind mirrors or glass (a pool seen
    through its water: there the photon hand-off traced 150,000 photons per 8 spp and splatted none;
    issue 61)."""
    return not plan.seen or "directly" in plan.seen.values()


def handoff_batch(job, b, walk, light_stats) -> None:
    """The photons' share of a manifold bake: the paths focusing more than opts.handoff,
    and every path of a chain type the guide found too weak to be worth walks; walk.factors:
    {light index: photons per walk sample} (auto's share of the time, default 1). Counted in
    light_stats (per light name)."""
    scene, plan, opts, types, guide = job.scene, job.plan, walk.opts, walk.types, walk.guide
    if not hands_off(scene, plan, opts, types) or not sees_directly(plan):
        return
    tau0 = opts.handoff if opts.handoff > 0 else math.inf
    for lp in plan.lights:
        share = walk.factors.get(lp.index, 1.0) * plan.sample_share.get(lp.index, 1.0)
        per_batch = max(1, int(job.per_light * share) // job.settings.batches)
        st = light_stats[lp.name]
        hs = st.setdefault("handoff", dict.fromkeys(("photons", "rays_photon", "rays_camera", "splats",
                                                     "handoff_paths", "truncated", "lost_shading_normal"), 0))
        tau = {t: 0.0 if guide is not None and guide.is_weak(lp.index, t) else tau0 for t in types}
        # the photons also take every path the walks cannot (a chain type they do not walk), so
        # that nothing the camera sees directly is dropped
        handoff = Handoff(tau, bool(scene.light_type[lp.index] in S.DISTANT), others=True)
        st["time_s"] += photon_pass(job, b, lp, per_batch, hs, HANDOFF, handoff, step=False)


def eye_rays(eye_stats: dict) -> int:
    """The eye pass's rays, its bent part's (every method's bent pass counts there) with them."""
    return rays(eye_stats) + rays(eye_stats.get("bent", {}))


def specular_visible(job, cells=None) -> tuple[bool, int]:
    """Does any pixel see a mirror or glass surface first? One ray per pixel, from the pixels of
    the film cells `cells` alone (eye.specular_cells, None: every pixel; every pixel that can see
    one first is in them): (the answer, rays cast). None cast where the plan's look from the
    camera cast the same rays (plan.specular_seen)."""
    scene, cam, plan = job.scene, job.cam, job.plan
    if plan.specular_seen is not None:
        return plan.specular_seen, 0
    if cells is None:
        jj, _, o, d = cam.pixel_rays()
    else:  # cells: the film's grid widened by the filter's reach (eye.film_cells), row by row
        x0, x1, y0, y1 = cam.region
        r = int(np.ceil(job.film.filter_width))
        k = np.flatnonzero(cells)
        jj, ii = k // (x1 - x0 + 2 * r) + (y0 - r), k % (x1 - x0 + 2 * r) + (x0 - r)
        inside = (jj >= y0) & (jj < y1) & (ii >= x0) & (ii < x1)
        jj, ii = jj[inside], ii[inside]
        o, d = cam.centre_rays(jj, ii)
    if jj.size == 0:
        return False, 0
    h = job.tracer.camera_intersect(o, d, cam.clip_far(d))
    kind = scene.mat_kind[scene.tri_material[h.prim[h.hit]]]
    return bool(np.any((kind == S.CONDUCTOR) | (kind == S.DIELECTRIC))), int(jj.size)


def rays(st: dict) -> int:
    """All rays a statistics dict counts (its rays_* entries)."""
    return sum(v for k, v in st.items() if k.startswith("rays_"))
