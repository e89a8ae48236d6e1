"""The bake: plan the scene, run the caustic pass per light, gather statistics.

Data flows one way: Scene -> plan -> per light (batches x chunks of lanes) ->
film -> image + noise estimate + statistics. Randomness is keyed by
(seed, light, batch, chunk), so one seed gives the same image bit for bit,
whatever the thread count.
"""
from __future__ import annotations

import dataclasses
import math
import time
from collections import defaultdict
from concurrent.futures import wait
from dataclasses import asdict, dataclass, field

import numpy as np

from . import convergence
from ..core import lanes
from ..paths import photons as reference
from ..scene import arrays as S
from ..trace.camera import CameraModel
from ..core.compiles import CompileWatch
from ..core.errors import BakeCancelled, SceneError
from ..trace.film import Film
from ..shading.lights import emit
from .plan import _rng, light_key, make_plan, refine_plan, spot_target
from ..shading.microfacet import rough_casters
from ..trace.tracer import Tracer
from ..core.vec import channel_mean

METHODS = ("auto", "reference", "mnee", "sms", "smbs")
F32_MAX = float(np.finfo(np.float32).max)
# A walk stops within solver_threshold (radians) of its solution, and the Bernoulli trials know
# two walks for the same solution when 1 - cos of their first directions is below uniqueness:
# on the glass sphere (SMS, unbiased, 16 spp) a uniqueness under ~10 x threshold^2 made the
# trials overcount (threshold 1e-3, uniqueness 1e-7: the layer +18%; 1e-4 with 1e-9: +30%;
# 1e-2 with 1e-7: 35x), and any threshold up to 1e-2 was right with a uniqueness to match.
MAX_SOLVER_THRESHOLD = 1e-5
UNIQUENESS_PER_THRESHOLD_SQ = 10.0
ESTIMATORS = ("unbiased", "biased")
CHUNK = 65536  # lanes per chunk (keeps temporaries in cache, see performance-anchors.md)
WALK_CHUNK = 65536  # eye samples per manifold chunk (each fans out to lights x chain types x trials): big
# enough that the walks' kernel and intersect calls see thousands of lanes (8192: 19.1 s, 65536: 16.3 s for
# the glass sphere at 512^2, SMS, bench/throughput.py)
MEMORY_BUDGET = 8 * 2**30  # bytes the film may take; a bigger resolution is refused before baking
NOISE_MIN_BATCHES = 4  # a noise target is checked from this many batches on (a spread of fewer lies)
MAX_BATCHES = 1 << 20  # a stop rule that is never met (a noise target under a heavy tail) ends here


@dataclass
class BakeSettings:
    method: str = "auto"  # auto (per light and effect, the cheapest of the next three, by a pilot: auto.py),
    # reference (light tracing), mnee, sms, smbs
    spp: int = 16  # reference: light paths per pixel and light; manifold: eye samples per pixel
    seed: int = 0
    batches: int = 8  # independent batches for the noise estimate
    threads: int = 0  # 0: all cores
    use_cycles_flags: str = "AUTO"  # AUTO, ON, OFF
    radiance: str = "cycles"  # cycles: like Cycles, no eta^2 radiance change at refractions; physical: with it
    guide: bool = True  # photon pre-pass: walk rarely (Russian roulette) where no caustic lands
    time_budget: float = 0.0  # seconds; > 0: keep adding batches (of spp / batches each) until the
    # whole bake (plan, pre-pass, walks) has taken this long, within half a batch
    noise_target: float = 0.0  # > 0: keep adding batches until the estimated relative_error is below
    # it (after at least NOISE_MIN_BATCHES); with a time_budget too, whichever comes first
    estimator: str = "unbiased"  # manifold methods: unbiased (Bernoulli trials) or biased (unique solutions)
    trials: int = 4  # biased estimator: walks per receiver, light and chain type
    max_trials: int = 10000  # unbiased estimator: cap on the Bernoulli count
    max_iterations: int = 20
    first_step: float = 0.125  # unbiased SMS, SMBS: the share of the full Newton step a walk's first
    # small step takes (doubled on acceptance, halved on rejection); 1: the walk as published.
    # MNEE and the biased estimator (whose energy depends on what a walk finds): always 1
    stall_stop: bool = True  # unbiased SMS, SMBS: a walk that cannot mutate large gives up when its
    # last 4 steps shrank the mismatch by less than 10% (outcome "stalled"; walk.STALL). MNEE and
    # the biased estimator: never
    solver_threshold: float = 1e-6  # radians, scale-free
    uniqueness: float = 1e-7
    tau: float = 0.85  # SMBS slow-progress threshold
    large_mutation_tir: bool = True
    large_mutation_backlit: bool = True
    large_mutation_slow: bool = True
    max_chain: int = 4
    chains: tuple = ()  # explicit chain types ("R", "TT", ...); empty: what the scene calls for
    clamp_g: float = 0.0  # manifold methods: cap on one solution's luminance (RGB mean), biased; 0: off.
    # What it cuts is in the statistics per light: 'clamped' solutions, 'clamped_energy' (image units)
    indirect: bool = True  # caustic light that meets more than one diffuse surface (floor -> glass ->
    # floor; a pool's floor -> water's underside -> floor), as Cycles counts it (indirect.py)
    pilots: int = 4096  # plan: pilot photons per light and caster that find where its caustic lands;
    # a caster whose pilots land on nothing the camera sees is not baked for that light. 0: bounds only
    handoff: float = 4.0  # manifold methods: paths that focus light more than this many times (folds,
    # foci) are left to a light-tracing pass of spp photons per pixel and light, which is efficient
    # exactly there; the two partition path space, so the sum stays unbiased. 0: walks only

    def validate(self) -> None:
        if self.method not in METHODS:
            raise SceneError(f"unknown method '{self.method}' (choose from {', '.join(METHODS)})")
        if self.radiance not in ("cycles", "physical"):
            raise SceneError(f"radiance must be 'cycles' or 'physical', not '{self.radiance}'")
        if self.estimator not in ESTIMATORS:
            raise SceneError(f"unknown estimator '{self.estimator}' (choose from {', '.join(ESTIMATORS)})")
        for name in ("spp", "batches", "trials", "max_trials", "max_iterations", "max_chain"):
            v = getattr(self, name)
            if not (isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v >= 1):
                raise SceneError(f"{name} must be a positive whole number, not {v!r}")
        if self.seed < 0:
            raise SceneError(f"seed must not be negative, not {self.seed}")
        if not (self.time_budget >= 0 and math.isfinite(self.time_budget)):
            raise SceneError(f"time_budget must be a non-negative number of seconds, not {self.time_budget}")
        if not (self.noise_target >= 0 and math.isfinite(self.noise_target)):
            raise SceneError(f"noise_target must be 0 (off) or a positive relative error such as 0.05, "
                             f"not {self.noise_target}")
        if not (0 < self.first_step <= 1):
            raise SceneError(f"first_step must lie in (0, 1], not {self.first_step}")
        if not (0 < self.tau < 1):
            raise SceneError(f"tau must lie between 0 and 1, not {self.tau}")
        if not (self.solver_threshold > 0 and self.uniqueness > 0):
            raise SceneError("solver_threshold and uniqueness must be positive")
        if not (self.solver_threshold <= MAX_SOLVER_THRESHOLD):
            raise SceneError(f"solver_threshold {self.solver_threshold:g} is above {MAX_SOLVER_THRESHOLD:g} "
                             f"radians: a walk would stop that far from its solution (Newton's steps converge "
                             f"fast, so a tighter threshold costs an iteration or two)")
        if not (self.uniqueness >= UNIQUENESS_PER_THRESHOLD_SQ * self.solver_threshold ** 2 * (1 - 1e-9)):
            raise SceneError(f"uniqueness {self.uniqueness:g} is too strict for solver_threshold "
                             f"{self.solver_threshold:g}: two walks to one solution end up to that angle apart, "
                             f"and the Bernoulli trials would not know them for the same and count on (at "
                             f"least {UNIQUENESS_PER_THRESHOLD_SQ:g} x the threshold squared: "
                             f"{UNIQUENESS_PER_THRESHOLD_SQ * self.solver_threshold ** 2:.2g})")
        if not (isinstance(self.pilots, (int, np.integer)) and not isinstance(self.pilots, bool)
                and self.pilots >= 0):
            raise SceneError(f"pilots must be 0 (bounds only) or a positive whole number, not {self.pilots!r}")
        if not (self.handoff >= 0 and math.isfinite(self.handoff)):
            raise SceneError(f"handoff must be 0 (off) or a positive concentration, not {self.handoff}")
        if not (self.clamp_g >= 0):
            raise SceneError(f"clamp_g must be 0 (off) or a positive luminance, not {self.clamp_g}")
        for c in self.chains:
            if not c or set(c) - {"R", "T"}:
                raise SceneError(f"chain type '{c}' must be a string of R (reflect) and T (refract)")

    def manifold_options(self, method: str | None = None):
        """The walks' options; method overrides settings.method (auto: per light)."""
        from ..walks.manifold import ManifoldOptions
        from ..walks.walk import STALL, WalkConfig

        method = method or ("smbs" if self.method == "auto" else self.method)
        self = dataclasses.replace(self, method=method)

        mnee = self.method == "mnee"
        # first_step and stall_stop change what a walk finds, so only where the Bernoulli trials
        # weigh each solution by 1/p do they leave the mean alone
        counted = not mnee and self.estimator == "unbiased"
        walk = WalkConfig(form="hv" if mnee else "ad", max_iterations=self.max_iterations,
                          threshold=self.solver_threshold, smbs=self.method == "smbs",
                          tir=self.large_mutation_tir, backlit=self.large_mutation_backlit,
                          slow=self.large_mutation_slow, tau=self.tau,
                          beta0=float(self.first_step) if counted else 1.0,
                          **(STALL if self.stall_stop and counted else {}))
        return ManifoldOptions(method=self.method, estimator=self.estimator, trials=self.trials,
                               max_trials=self.max_trials, uniqueness=self.uniqueness,
                               chains=tuple(self.chains), max_chain=self.max_chain, walk=walk,
                               physical=self.radiance == "physical", clamp_g=float(self.clamp_g),
                               handoff=0.0 if self.method == "mnee" else float(self.handoff))


@dataclass
class BakeResult:
    image: np.ndarray  # (H,W,3) float32, top row first
    variance: np.ndarray  # (H,W,3) float32, variance of the image estimate
    stats: dict = field(default_factory=dict)
    batch_luminance: np.ndarray | None = None  # (B,H,W) float32, one image per independent batch
    # (or per group of equal batches, film.MAX_GROUPS at most)
    std: np.ndarray | None = None  # (H,W) float32, standard deviation of each pixel's mean luminance
    # Receivers whose colour is a texture (Scene.mat_textured), where the camera sees them
    # directly: Cycles' Diffuse Color pass has their albedo, the bake assumed a constant one.
    # textured: the part of image that fell there; per_albedo: the same divided by the albedo the
    # bake assumed (sample by sample). The layer to add over a render is layer() + per_albedo x
    # the render's Diffuse Color pass. Both None where the scene has no textured receiver.
    textured: np.ndarray | None = None  # (H,W,3) float32
    per_albedo: np.ndarray | None = None  # (H,W,3) float32

    def layer(self) -> np.ndarray:
        """What is added over a render as it is: image, less its textured part (if any), which
        per_albedo x the render's Diffuse Color pass replaces."""
        return self.image if self.textured is None else self.image - self.textured

    def region_mean(self, region: np.ndarray) -> tuple[float, float]:
        """Mean luminance over a pixel mask and its standard error, from the spread
        of the independent batches' region means (honest whatever the sampling)."""
        return region_mean_error(self.batch_luminance, region)


def region_mean_error(batch_luminance, region) -> tuple[float, float]:
    means = np.array([b[region].mean() for b in batch_luminance], dtype=float)
    b = len(means)
    se = float(means.std(ddof=1) / math.sqrt(b)) if b > 1 else float("inf")
    return float(means.mean()), se


def caustic_region(image: np.ndarray, frac: float = 0.05) -> np.ndarray:
    """Pixels where the caustic is clearly non-zero: luminance above frac of its 99.5th percentile."""
    return convergence.caustic_region(channel_mean(image), frac)


def noise_summary(image: np.ndarray, variance: np.ndarray, batch_luminance=None, region=None) -> dict:
    """The noise over the caustic region (caustic_region(image) unless the caller has it)."""
    region = caustic_region(image) if region is None else region
    if not region.any():
        return {"region_pixels": 0, "mean": 0.0, "std_error_of_mean": 0.0, "relative_noise": 0.0,
                "pixel_rms_noise": 0.0}
    lum = channel_mean(image)[region]
    var = channel_mean(variance)[region]  # variance of the channel mean (conservative: /3 ignored)
    mean = float(lum.mean())
    se = region_mean_error(batch_luminance, region)[1] if batch_luminance is not None else float("nan")
    return {
        "region_pixels": int(region.sum()),
        "mean": mean,
        # from the spread of the batches' region means: pixels are correlated by the filter
        # and by stratification, so the per-pixel variances cannot simply be summed
        "std_error_of_mean": se if math.isfinite(se) else 0.0,
        "pixel_rms_noise": float(math.sqrt(var.mean())),
        "relative_noise": float(math.sqrt(var.mean()) / mean) if mean > 0 else 0.0,
    }


def bias_left_out(settings: BakeSettings, light_stats: dict) -> list[str]:
    """What makes this bake's mean differ from the truth beyond its noise, which the error bar
    (relative_error, from the spread between batches) cannot see: short phrases, none for an
    unbiased bake. The share of the layer a cap cost is at least what it reports."""
    out = []
    if settings.method == "mnee":
        out.append("MNEE's bias (one walk per point, no Bernoulli weights)")
    elif settings.method != "reference" and settings.estimator == "biased":
        out.append(f"the biased estimator's bias ({settings.trials} walks per point)")
    if any(st.get("clamped", 0) > 0 for st in light_stats.values()):
        out.append(f"the clamp's bias (clamp_g {settings.clamp_g:g})")
    capped = sum(st.get("trials", {}).get("capped_share_min", 0.0) for st in light_stats.values())
    if any(st.get("trials", {}).get("capped", 0) > 0 for st in light_stats.values()):
        out.append(f"the Bernoulli trials' cap (at least {capped:.1%} of the layer)")
    return out


def _finite_or_none(x: float):
    return float(x) if math.isfinite(x) else None  # JSON has no infinity


def _eye_per_batch(cam, film, settings) -> int:
    """Eye samples per batch: spp per film cell over all batches. Fewer than the cells (spp below
    the batches) is a sparser batch over the whole film (eye.film_samples), not a whole pass:
    1 spp in 8 batches costs 1 spp, not 8."""
    from ..trace.eye import film_cells

    return max(1, film_cells(cam, film) * settings.spp // settings.batches)


def _specular_visible(scene, tracer, cam, plan, film, cells=None) -> tuple[bool, int]:
    """Does any pixel see a mirror or glass surface first? One ray per pixel, from the pixels of
    the film cells `cells` alone (eye.specular_cells, None: every pixel; every pixel that can see
    one first is in them): (the answer, rays cast). None cast where the plan's look from the
    camera cast the same rays (plan.specular_seen)."""
    if plan.specular_seen is not None:
        return plan.specular_seen, 0
    if cells is None:
        jj, _, o, d = cam.pixel_rays()
    else:  # cells: the film's grid widened by the filter's reach (eye.film_cells), row by row
        x0, x1, y0, y1 = cam.region
        r = int(np.ceil(film.filter_width))
        k = np.flatnonzero(cells)
        jj, ii = k // (x1 - x0 + 2 * r) + (y0 - r), k % (x1 - x0 + 2 * r) + (x0 - r)
        inside = (jj >= y0) & (jj < y1) & (ii >= x0) & (ii < x1)
        jj, ii = jj[inside], ii[inside]
        o, d = cam.centre_rays(jj, ii)
    if jj.size == 0:
        return False, 0
    h = tracer.camera_intersect(o, d)
    kind = scene.mat_kind[scene.tri_material[h.prim[h.hit]]]
    from ..scene import arrays as S
    return bool(np.any((kind == S.CONDUCTOR) | (kind == S.DIELECTRIC))), int(jj.size)


class _Progress:
    def __init__(self, total, progress, cancel):
        self.total, self.done, self.progress, self.cancel = max(total, 1), 0, progress, cancel
        self.fraction = None  # stop rules by time or noise: () -> fraction done, instead of the count

    def check(self):
        if self.cancel is not None and self.cancel():
            raise BakeCancelled("bake cancelled")

    def step(self, message):
        self.done += 1
        if self.progress is not None:
            f = self.done / self.total if self.fraction is None else self.fraction()
            self.progress(min(1.0, f), message)


class _DeferredFilm:
    """The film as a chunk on a worker thread sees it: reads go to the film, splats are kept
    to be made on the calling thread, in chunk order (_threaded_chunks)."""

    def __init__(self, film):
        self._film = film
        self.splats = []

    def __getattr__(self, name):
        return getattr(self._film, name)

    def splat(self, rx, ry, rgb, albedo=None) -> None:
        self.splats.append((rx, ry, rgb, albedo))


def _threaded_chunks(tracer, film, prog, n_chunks, run_chunk, stats, message=None):
    """run_chunk(c, film, stats) for the chunks c = 0 .. n_chunks-1 of a light-tracing pass, as
    many at a time as there are threads (lanes.blocks), each with its own random stream (the
    caller's, keyed by c), a deferred film and its own counters. Here, in chunk order, their
    splats are made and their counters added: the film is written by one thread, and the image
    is the one chunks run one after the other give, bit for bit. Cancel is checked and
    progress stepped (message: once per chunk) here too."""
    per = max(1, tracer.threads)
    for g0 in range(0, n_chunks, per):
        prog.check()
        group = range(g0, min(g0 + per, n_chunks))

        def call(a, b):
            f, st = _DeferredFilm(film), defaultdict(int)
            run_chunk(group[a], f, st)
            return f.splats, st

        for splats, st in lanes.blocks(call, len(group), 1, tracer.threads):
            for args in splats:
                film.splat(*args)
            lanes.add_stats(stats, st)
            if message:
                prog.step(message)


def _photon_pass(b, scene, tracer, cam, film, plan, settings, lp, per_batch, st, prog, stream, handoff=None,
                 step=True):
    """per_batch photons of light lp in chunks, each chunk with its own random stream."""
    t_light = time.perf_counter()

    def run_chunk(c, film_c, st_c):
        start = c * CHUNK
        n = min(CHUNK, per_batch - start)
        rng = _rng(settings.seed, stream, lp.key, b, c)
        ph = emit(scene, lp.index, lp.targets, n, rng)
        ph.w *= n / per_batch  # emit() weights by 1/n; a batch averages per_batch photons
        reference.trace_photons(scene, tracer, cam, film_c, plan, ph, rng, st_c,
                                physical=settings.radiance == "physical", handoff=handoff)

    _threaded_chunks(tracer, film, prog, -(-per_batch // CHUNK), run_chunk, st,
                     f"light '{lp.name}', batch {b + 1}/{settings.batches}" if step else None)
    return time.perf_counter() - t_light


def _indirect_lights(plan, settings):
    return list(plan.indirect_lights) if settings.indirect else []


def _indirect_batch(b, scene, tracer, cam, film, plan, settings, per_light, indirect_stats, prog):
    """Light tracing of the caustic light that meets more than one diffuse surface, for the
    receivers the camera sees directly (indirect.trace_photons): photons over the whole
    scene, spp per pixel and light."""
    from ..paths.gather import trace_photons

    for li in _indirect_lights(plan, settings):
        st = indirect_stats.setdefault(scene.light_names[li], {"photons": 0, "rays_photon": 0, "rays_camera": 0,
                                                                "splats": 0, "time_s": 0.0})
        t = time.perf_counter()
        # a narrow spot's photons go into its cone, as many as its cone let through when they were
        # aimed at the whole scene: the same noise, without tracing the masked ones
        target, share = spot_target(scene, li, plan.scene_sphere)
        per_batch = max(1, round(per_light * share * plan.sample_share.get(li, 1.0)) // settings.batches)

        def run_chunk(c, film_c, st_c, li=li, target=target, per_batch=per_batch):
            n = min(CHUNK, per_batch - c * CHUNK)
            rng = _rng(settings.seed, 5, light_key(scene.light_names[li]), b, c)
            ph = emit(scene, li, target, n, rng)
            ph.w *= n / per_batch
            trace_photons(scene, tracer, cam, film_c, plan, ph, rng, st_c, physical=settings.radiance == "physical")

        _threaded_chunks(tracer, film, prog, -(-per_batch // CHUNK), run_chunk, st)
        st["time_s"] += time.perf_counter() - t


def _reference_batch(b, scene, tracer, cam, film, plan, settings, per_light, light_stats, eye_stats, prog,
                     eye_cells=None):
    """The light tracer's batch: photons per light, then eye paths for what is seen through
    mirrors and glass, traced from the film cells of the mask eye_cells (None: all)."""
    for lp in plan.lights:
        st = light_stats[lp.name]
        per_batch = max(1, round(per_light * plan.sample_share.get(lp.index, 1.0)) // settings.batches)
        st["time_s"] += _photon_pass(b, scene, tracer, cam, film, plan, settings, lp, per_batch, st, prog, 0)
    eye_per_batch = _eye_per_batch(cam, film, settings) if eye_stats["enabled"] else 0
    t_eye = time.perf_counter()
    light_ids = [lp.index for lp in plan.lights]

    def run_chunk(c, film_c, st_c):
        start = c * CHUNK
        reference.trace_eye(scene, tracer, cam, film_c, plan, light_ids, start, min(CHUNK, eye_per_batch - start),
                            eye_per_batch, _rng(settings.seed, 1, 0, b, c), st_c,
                            physical=settings.radiance == "physical", lights_direct=_indirect_lights(plan, settings),
                            cells=eye_cells)

    _threaded_chunks(tracer, film, prog, -(-eye_per_batch // CHUNK), run_chunk, eye_stats,
                     f"seen through glass and mirrors, batch {b + 1}/{settings.batches}")
    eye_stats["time_s"] += time.perf_counter() - t_eye
    from ..paths.gather import BENT_EYE_SHARE, bending_lights

    bent = bending_lights(scene, tracer, plan)
    if bent:  # the paths through normals Cycles bends, at receivers seen directly (reference.trace_bent)
        t_bent = time.perf_counter()
        # one eye sample in indirect.BENT_EYE_SHARE, BENT_BOUNCES aimed bounces from each
        per_batch = max(1, -(-_eye_per_batch(cam, film, settings) // BENT_EYE_SHARE))

        def bent_chunk(c, film_c, st_c):
            start = c * CHUNK
            reference.trace_bent(scene, tracer, cam, film_c, plan, bent, start, min(CHUNK, per_batch - start),
                                 per_batch, _rng(settings.seed, 1, 1, b, c), st_c,
                                 physical=settings.radiance == "physical")

        bent_stats = eye_stats.setdefault("bent", {"time_s": 0.0})
        _threaded_chunks(tracer, film, prog, -(-per_batch // CHUNK), bent_chunk, bent_stats)
        bent_stats["time_s"] += time.perf_counter() - t_bent


def _manifold_batch(b, scene, tracer, cam, film, plan, settings, opts, types, per_batch, light_stats,
                    eye_stats, prog, guide=None, opts_by_light=None):
    from ..walks.manifold import manifold_chunk

    for c, start in enumerate(range(0, per_batch, WALK_CHUNK)):
        prog.check()
        n = min(WALK_CHUNK, per_batch - start)
        manifold_chunk(scene, tracer, cam, film, plan, opts, types, start, n, per_batch,
                       _rng(settings.seed, 2, 0, b, c), light_stats, eye_stats, guide,
                       lights_direct=_indirect_lights(plan, settings), opts_by_light=opts_by_light)
        prog.step(f"{settings.method}, batch {b + 1}/{settings.batches}")


def _hands_off(scene, plan, opts, types) -> bool:
    """Whether a manifold bake has a photon hand-off: paths through a rough mirror or glass are the
    photons' whatever opts.handoff (no walk takes them); otherwise where opts.handoff > 0 and
    some chain type is walked."""
    return bool(rough_casters(scene, plan.casters).any()) or (opts.handoff > 0 and bool(types))


def _handoff_batch(b, scene, tracer, cam, film, plan, settings, opts, types, per_light, light_stats, prog,
                   guide=None, factors=None):
    """The photons' share of a manifold bake: the paths focusing more than opts.handoff,
    and every path of a chain type the guide found too weak to be worth walks; factors:
    {light index: photons per walk sample} (auto's share of the time, default 1)."""
    if not _hands_off(scene, plan, opts, types):
        return
    tau0 = opts.handoff if opts.handoff > 0 else math.inf
    for lp in plan.lights:
        share = (factors or {}).get(lp.index, 1.0) * plan.sample_share.get(lp.index, 1.0)
        per_batch = max(1, int(per_light * share) // settings.batches)
        st = light_stats[lp.name]
        hs = st.setdefault("handoff", dict.fromkeys(("photons", "rays_photon", "rays_camera", "splats",
                                                     "handoff_paths", "truncated", "lost_shading_normal"), 0))
        tau = {t: 0.0 if guide is not None and guide.is_weak(lp.index, t) else tau0 for t in types}
        # the photons also take every path the walks cannot (a chain type they do not walk), so
        # that nothing the camera sees directly is dropped
        handoff = reference.Handoff(tau, bool(scene.light_type[lp.index] in S.DISTANT), others=True)
        st["time_s"] += _photon_pass(b, scene, tracer, cam, film, plan, settings, lp, per_batch, hs, prog, 4,
                                     handoff, step=False)


def _rays(st: dict) -> int:
    """All rays a statistics dict counts (its rays_* entries)."""
    return sum(v for k, v in st.items() if k.startswith("rays_"))


def _eye_rays(eye_stats: dict) -> int:
    """The eye pass's rays, its bent part's (every method's bent pass counts there) with them."""
    return _rays(eye_stats) + _rays(eye_stats.get("bent", {}))


def _summarise_walks(st: dict) -> None:
    for key in ("walks", "successes", "mutations"):  # a light auto leaves to photons walks nowhere
        st.setdefault(key, 0)
    st.setdefault("large_mutations", {})
    walks = st["walks"]
    st["success_rate"] = st.get("successes", 0) / walks if walks else 0.0
    st["mutations_per_path"] = st.get("mutations", 0) / walks if walks else 0.0
    succ = st.get("successes", 0)
    st["mutations_per_success"] = st.get("mutations", 0) / succ if succ else 0.0
    for bc in st.get("by_chain", {}).values():
        bc["success_rate"] = bc["successes"] / bc["walks"] if bc["walks"] else 0.0
        bc["mutations_per_success"] = bc["mutations"] / bc["successes"] if bc["successes"] else 0.0
    n_lanes = st.get("bernoulli_lanes", 0)
    st["trials"] = {"mean": st.get("bernoulli_trials", 0) / n_lanes if n_lanes else 0.0,
                    "max": st.get("bernoulli_trials_max", 0), "capped": st.get("capped", 0)}
    st["rays"] = _rays(st)
    hs = st.get("handoff")
    if hs:
        st["rays"] += hs["rays_photon"] + hs["rays_camera"]


def film_memory(width: int, height: int, batches: int, textured: bool = False) -> int:
    """Bytes the film of a bake needs: per pixel the sum, sum of squares and current batch
    (3 float64 each), the image and variance made from them (float64, then float32), and one
    float32 luminance image per batch (kept, then stacked); with textured receivers, their two
    sums (3 float64 each) and the two float32 images made from them."""
    px = int(width) * int(height)
    extra = px * 2 * 3 * (8 + 4) if textured else 0
    return px * (3 * 3 * 8 + 2 * 3 * 8 + 2 * 3 * 4) + 2 * int(batches) * px * 4 + extra


def check_memory(scene, width: int, height: int, batches: int) -> None:
    """Refuse, before anything is allocated, a film bigger than MEMORY_BUDGET."""
    need = film_memory(width, height, batches, scene.textured_materials() is not None)
    if need > MEMORY_BUDGET:
        raise SceneError(
            f"scene '{scene.name}': a {width} x {height} caustic layer needs about "
            f"{need / 2**30:.1f} GiB for its film ({batches} batches), more than the "
            f"{MEMORY_BUDGET / 2**30:g} GiB limit; lower the resolution (or its percentage) "
            f"or the number of batches")


class _Stop:
    """The stop rule: samples (settings.batches batches), time, noise, or time and noise.

    Time: at least two batches, then another one only while it would end nearer the
    budget than stopping now (a batch is predicted to take as long as the last one), so
    the whole bake ends within half a batch of the budget. Noise: from NOISE_MIN_BATCHES
    on, stop once the estimated relative_error is at or below the target.

    The budget is the bake's own work: time spent compiling kernels (watch, a CompileWatch: the
    first bake after installing or updating) is not in it, so that a budget buys the same image
    on its first bake as on later ones (the statistics' time_s holds the whole wall time,
    compile_s what compiling took of it)."""

    def __init__(self, settings: BakeSettings, film: Film, t0: float, watch):
        self.s, self.film, self.t0, self.watch = settings, film, t0, watch
        self.reason = "samples"
        self.last_error = math.inf

    def clock(self) -> float:
        """Seconds into the bake, compiling left out: the batches' clock (_bake_batches)."""
        return time.perf_counter() - self.t0 - self.watch.now()

    def _error(self) -> float:
        groups = np.stack(self.film.batch_luminance) if len(self.film.batch_luminance) >= 2 else None
        if groups is None:
            return math.inf
        lum = channel_mean(self.film.image)
        return convergence.relative_error(groups, convergence.caustic_region(lum))

    def fraction(self) -> float:
        """Progress of a time or noise rule (noise: error ~ t^-1/2, so (target / error)^2)."""
        f = 0.0
        if self.s.time_budget > 0:
            f = self.clock() / self.s.time_budget
        if self.s.noise_target > 0 and math.isfinite(self.last_error) and self.last_error > 0:
            f = max(f, min(0.99, (self.s.noise_target / self.last_error) ** 2))
        return min(f, 0.99)

    def __call__(self, b: int, last_batch_s: float) -> bool:
        """After b batches (the last took last_batch_s): stop?"""
        s = self.s
        if s.time_budget <= 0 and s.noise_target <= 0:
            return b >= s.batches
        if s.noise_target > 0 and b >= NOISE_MIN_BATCHES:
            self.last_error = self._error()
            if self.last_error <= s.noise_target:
                self.reason = "noise"
                return True
        if s.time_budget > 0 and b >= 2:
            if self.clock() + 0.5 * last_batch_s >= s.time_budget:
                self.reason = "time"
                return True
        if b >= MAX_BATCHES:
            self.reason = "max_batches"
            return True
        return False


def _bake_batches(settings: BakeSettings, film: Film, t0: float, prog: _Progress, run_batch, watch):
    """run_batch(b) adds batch b to the film's current batch; batches go on until the stop
    rule says enough. Returns (batches done, the stop rule, seconds before the first).

    The batches' clock (the film's batch ends, the seconds before the first, the last batch's
    length the time rule looks ahead by) leaves out the time spent compiling kernels (watch:
    a CompileWatch), which later bakes do not pay: the price of more batches is what they cost,
    and a time budget buys what it buys on later bakes (_Stop)."""
    stop = _Stop(settings, film, t0, watch)
    prog.fraction = stop.fraction if settings.time_budget > 0 or settings.noise_target > 0 else None
    t_first = stop.clock()
    b = 0
    while True:
        begun = stop.clock()
        run_batch(b)
        ended = stop.clock()
        film.end_batch(ended)
        b += 1
        if stop(b, ended - begun):
            return b, stop, t_first


def plan_words(scene, settings: BakeSettings | None = None) -> list:
    """The plan of a bake in words, without baking (the panel's Show Plan)."""
    settings = settings or BakeSettings()
    settings.validate()
    scene.validate()
    plan = make_plan(scene, settings.use_cycles_flags)
    if not plan.nothing:
        _trace_plan(plan, scene, settings, CameraModel(scene.camera))
    return plan.words()


def _trace_plan(plan, scene, settings, cam) -> Tracer:
    """The traced part of the plan (plan.refine_plan) with the bake's tracer; the tracer's
    tolerances then follow what takes part, not objects out of the plan."""
    tracer = Tracer(scene, threads=settings.threads or None)
    refine_plan(plan, scene, tracer, cam, settings.seed, settings.pilots, indirect=settings.indirect)
    tracer.set_extent(*plan.bounds)
    return tracer


def _plan_stats(plan) -> dict:
    return {"words": plan.words(), "notes": list(plan.notes), "seen": dict(plan.seen), **plan.cost}


def _nothing_to_bake(scene, settings, plan, cam, t0, on_plan) -> BakeResult:
    """A scene with no caustic to bake: an all-zero layer and the plan saying why."""
    if on_plan is not None:
        on_plan(plan.words())
    x0, x1, y0, y1 = cam.region
    H, W = cam.H, cam.W
    if scene.camera.use_border and scene.camera.use_crop_to_border:
        H, W = max(0, y1 - y0), max(0, x1 - x0)
    zero = np.zeros((H, W, 3), np.float32)
    stats = {
        "method": settings.method, "settings": asdict(settings), "scene": scene.name, "resolution": [W, H],
        "time_s": time.perf_counter() - t0, "rays": int(plan.cost.get("rays", 0)), "lights": {},
        "batches_done": 0, "plan": _plan_stats(plan),
        "skipped": [{"kind": k, "name": n, "reason": r} for k, n, r in plan.skipped],
        "noise": noise_summary(zero, zero), "relative_error": 0.0, "seconds_to_halve_error": 0.0,
        "stopped_by": "nothing_to_bake", "nothing_to_bake": plan.nothing,
    }
    return BakeResult(image=zero, variance=zero.copy(), stats=stats,
                      batch_luminance=np.zeros((1, H, W), np.float32), std=np.zeros((H, W), np.float32))


def _note_bent(scene, tracer, plan) -> None:
    """The plan says where Cycles' Bump Map Correction bends normals (indirect.bent_gather)."""
    from ..paths.gather import bending_lights, bent_candidates

    if not bending_lights(scene, tracer, plan):
        return
    cand = bent_candidates(scene, tracer, plan)[0]
    names = ", ".join(sorted({scene.object_names[o] for o in scene.tri_object[cand]}))
    plan.notes.append(f"{names}: smooth normals that Cycles' Bump Map Correction bends at grazing angles; "
                      "those paths are traced from the receivers")


def bake(scene, settings: BakeSettings | None = None, progress=None, cancel=None, on_plan=None) -> BakeResult:
    """Bake the caustic layer of a Scene.

    progress(fraction, message) is called between chunks; cancel() returning
    True stops the bake with BakeCancelled (nothing is returned or written);
    on_plan(lines) gets the plan in words before any caustic is traced. A scene
    with nothing to bake gives an all-zero layer, stats["nothing_to_bake"] says why.

    The first bake after installing or updating compiles the kernels it uses (compiles.py):
    progress says so while it does, stats["compile_s"] is the time it took (in time_s, not in
    the price of more batches: later bakes load the kernels from the disk cache)."""
    report = _Reporter(progress)
    with CompileWatch(on_start=report.compiling, on_end=report.compiled) as watch:
        try:
            result = _bake(scene, settings, report, cancel, on_plan, watch)
        finally:
            lanes.free_scratch()  # the work arrays the threads kept (lanes.scratch)
    result.stats["compile_s"] = watch.seconds
    result.stats["kernels_compiled"] = watch.kernels
    return result


class _Reporter:
    """The caller's progress(fraction, message), remembering the last call, so that a compile
    (the first bake after installing or updating) can say so and then give the message back."""

    COMPILING = ("compiling the kernels for this machine (once after installing or updating; "
                 "later bakes load them from the cache)")

    def __init__(self, progress):
        self.progress = progress
        self.last = (0.0, "")

    def __call__(self, fraction, message=""):
        self.last = (fraction, message or self.last[1])
        if self.progress is not None:
            self.progress(fraction, message)

    def compiling(self):
        if self.progress is not None:
            self.progress(self.last[0], self.COMPILING)

    def compiled(self):
        if self.progress is not None:
            self.progress(*self.last)


def _bake(scene, settings, progress, cancel, on_plan, watch) -> BakeResult:
    settings = settings or BakeSettings()
    settings.validate()
    scene.validate()
    t0 = time.perf_counter()
    plan = make_plan(scene, settings.use_cycles_flags)
    cam = CameraModel(scene.camera)
    check_memory(scene, cam.W, cam.H, settings.batches)
    if plan.nothing:
        return _nothing_to_bake(scene, settings, plan, cam, t0, on_plan)
    tracer = _trace_plan(plan, scene, settings, cam)
    film = Film(cam.W, cam.H, scene.camera.filter_width, cam.region, textured=scene.textured_materials() is not None,
                threads=tracer.threads)
    _note_bent(scene, tracer, plan)
    if on_plan is not None:
        on_plan(plan.words())
    if plan.nothing:
        return _nothing_to_bake(scene, settings, plan, cam, t0, None)
    method, choices, auto_stats = settings.method, {}, None
    if method == "auto":
        from . import auto

        t_a = time.perf_counter()
        if auto.pilot_fits(settings.time_budget, len(plan.lights)):
            choices = auto.choose(scene, settings, plan, cancel)
            why = {lp.name: choices[lp.index].why for lp in plan.lights}
        else:
            why = {lp.name: f"SMBS (a {settings.time_budget:g} s budget leaves no time for the pilot, which "
                            f"needs {auto.PILOT_MIN_BUDGET_PER_LIGHT:g} s per light)" for lp in plan.lights}
        # light tracing alone where it wins everywhere and no caustic is seen through mirrors or glass
        alone = bool(choices) and all(c.alone or (c.photons_direct and not c.through) for c in choices.values())
        method = "reference" if alone else "manifold"
        auto_stats = {"time_s": time.perf_counter() - t_a, "bake": method, "pilot": bool(choices),
                      "rays": sum(c.rays for c in choices.values()),
                      "lights": {scene.light_names[li]: {"walks": c.walk, "direct": "photons" if c.photons_direct
                                                         else c.walk, "photon_factor": c.photon_factor,
                                                         "why": c.why, "pilot": c.measured}
                                 for li, c in choices.items()}}
        for lp in plan.lights:
            plan.notes.append(f"auto, {lp.name}: {why[lp.name]}")
        if on_plan is not None:
            on_plan([f"auto, {lp.name}: {why[lp.name]}" for lp in plan.lights])
    x0, x1, y0, y1 = cam.region
    n_pix = max(0, x1 - x0) * max(0, y1 - y0)
    per_light = settings.spp * n_pix
    light_stats = {lp.name: {"time_s": 0.0, "casters": [scene.object_names[o] for o in lp.caster_objects]}
                   for lp in plan.lights}
    extra = {} if auto_stats is None else {"auto": auto_stats}
    indirect_stats = {}  # per light: the photons of indirect.trace_photons
    if method == "reference":
        for st in light_stats.values():
            st.update(dict.fromkeys(("photons", "rays_photon", "rays_camera", "splats", "truncated",
                                     "lost_shading_normal"), 0))
        from ..trace.eye import film_cells, specular_cells

        # the film cells that can see a mirror or glass first: the look for one in view casts
        # from their pixels alone, and the eye paths start in them alone
        eye_cells = specular_cells(scene, tracer, cam, film)
        enabled, rays_visible = _specular_visible(scene, tracer, cam, plan, film, eye_cells)
        eye_stats = {"eye_paths": 0, "rays_eye": 0, "rays_visible": rays_visible, "eye_splats": 0, "time_s": 0.0,
                     "enabled": enabled, "film_cells": film_cells(cam, film)}
        eye_cells = eye_cells if enabled else None
        eye_stats["cells"] = eye_stats["film_cells"] if eye_cells is None else int(eye_cells.sum())
        per_batch = max(1, per_light // settings.batches)
        eye_chunks = math.ceil(_eye_per_batch(cam, film, settings) / CHUNK) if eye_stats["enabled"] else 0
        prog = _Progress(settings.batches * (len(plan.lights) * math.ceil(per_batch / CHUNK) + eye_chunks),
                         progress, cancel)

        def run_batch(b):
            _reference_batch(b, scene, tracer, cam, film, plan, settings, per_light, light_stats, eye_stats, prog,
                             eye_cells)
            _indirect_batch(b, scene, tracer, cam, film, plan, settings, per_light, indirect_stats, prog)

        b, stop, t_first = _bake_batches(settings, film, t0, prog, run_batch, watch)
        extra["batches_done"] = b
        rays = (sum(s["rays_photon"] + s["rays_camera"] for s in light_stats.values())
                + _eye_rays(eye_stats) + plan.cost.get("rays", 0))
        extra["eye_pass"] = eye_stats
    else:
        from ..walks.manifold import chain_types

        opts = settings.manifold_options()
        opts_by_light = {li: settings.manifold_options(c.walk) for li, c in choices.items()}
        types = chain_types(scene, plan, opts)
        rough = [scene.object_names[o] for o in np.flatnonzero(rough_casters(scene, plan.casters))]
        if rough:
            plan.notes.append(f"{', '.join(rough)}: rough, so {'its' if len(rough) == 1 else 'their'} caustic comes "
                              f"from the photons (a walk solves for a perfect mirror's or glass's paths)")
        cut = [t for t in chain_types(scene, plan, opts, light_paths=False) if t not in types]
        if cut:
            from ..scene.light_paths import Limits

            plan.notes.append(f"{Limits.of(scene).words()}: Cycles renders no caustic along "
                              f"{', '.join(cut)}, so neither do we")
        eye_stats = {"eye_paths": 0, "rays_eye": 0}
        per_batch = _eye_per_batch(cam, film, settings)
        guide = None
        # the guide's pre-pass traces its photons past no surface: where some object's Ray Visibility leaves
        # out a kind of a path's rays it would miss paths that pass it, and leave their chain types unwalked
        hides = bool(np.any(tracer.hid & S.PATH_RAYS))
        if hides and settings.guide:
            plan.notes.append("the photon pre-pass (the guide) is off: some object's Ray Visibility leaves out "
                              "diffuse, glossy or transmission rays")
        if settings.guide and not hides:
            from ..walks.guide import Guide, build_guide, photon_budget

            t_g = time.perf_counter()
            masks, gstats, weak = build_guide(scene, tracer, cam, plan, types, _rng(settings.seed, 3, 0),
                                              photon_budget(cam), check=_Progress(1, None, cancel).check)
            gstats["time_s"] = time.perf_counter() - t_g
            # chain types that brought no light at all in the pre-pass are not walked (internal
            # reflections a closed glass shape does not produce for these lights)
            lit = [t for t in types if any(sh.get(t, 0.0) > 0 for sh in gstats["flux_share"].values())]
            if lit and len(lit) < len(types):
                gstats["not_walked"] = [t for t in types if t not in lit]
                masks = {k: v for k, v in masks.items() if k[1] in lit}
                weak = frozenset(w for w in weak if w[1] in lit)
                types = lit
            # weak chain types go to the photon hand-off (which the user may turn off: then walk them)
            guide = Guide(cam, masks, gstats, weak if opts.handoff > 0 else frozenset())
            gstats["left_to_photons"] = sorted(f"{scene.light_names[li]}: {t}" for li, t in guide.weak)
            extra["guide"] = gstats
        photon_lights = {(li, t) for li, c in choices.items() if c.photons_direct for t in types}
        if photon_lights and opts.handoff > 0:  # auto: light tracing serves these lights' direct receivers
            if guide is None:
                from ..walks.guide import Guide

                guide = Guide(cam, {}, {})
            guide.weak = frozenset(guide.weak) | photon_lights
        prog = _Progress(settings.batches * math.ceil(per_batch / WALK_CHUNK), progress, cancel)

        factors = {li: c.photon_factor for li, c in choices.items() if c.photons_direct}
        beside = tracer.threads > 1 and not lanes.nested() and _hands_off(scene, plan, opts, types)

        def run_batch(b):
            if not beside:
                _manifold_batch(b, scene, tracer, cam, film, plan, settings, opts, types, per_batch, light_stats,
                                eye_stats, prog, guide, opts_by_light)
                _handoff_batch(b, scene, tracer, cam, film, plan, settings, opts, types, per_light, light_stats,
                               prog, guide, factors)
            else:
                # the photon hand-off beside the walks (lanes.beside): at a few spp a batch's photons are one
                # chunk, whose emission and selection ran on one thread while the others waited. Its splats
                # are made after the walks' and its counters added then: the image and the statistics are
                # those of the two passes in turn
                late, own = _DeferredFilm(film), {lp.name: {"time_s": 0.0} for lp in plan.lights}
                photons = lanes.beside(lambda: _handoff_batch(b, scene, tracer, cam, late, plan, settings, opts,
                                                              types, per_light, own, prog, guide, factors))
                try:
                    _manifold_batch(b, scene, tracer, cam, film, plan, settings, opts, types, per_batch,
                                    light_stats, eye_stats, prog, guide, opts_by_light)
                finally:
                    wait([photons])
                photons.result()
                for args in late.splats:
                    film.splat(*args)
                for name, st in own.items():
                    lanes.add_stats(light_stats[name], st)
            _indirect_batch(b, scene, tracer, cam, film, plan, settings, per_light, indirect_stats, prog)

        b, stop, t_first = _bake_batches(settings, film, t0, prog, run_batch, watch)
        extra["batches_done"] = b
        for st in light_stats.values():
            _summarise_walks(st)
            if settings.clamp_g > 0:  # the clamp's bias, in image units (summed over pixels)
                st["clamped"] = st.get("clamped", 0)
                st["clamped_energy"] = st.get("clamped_energy", 0.0) / b
            st["trials"]["capped_energy_min"] = st.pop("capped_energy_min", 0.0) / b
        rays = (sum(st["rays"] for st in light_stats.values()) + _eye_rays(eye_stats)
                + extra.get("guide", {}).get("rays", 0) + plan.cost.get("rays", 0))
        walks = sum(st.get("walks", 0) for st in light_stats.values())
        extra.update({
            "chain_types": types, "eye_pass": eye_stats, "walks": walks,
            "successes": sum(st.get("successes", 0) for st in light_stats.values()),
            "mutations": sum(st.get("mutations", 0) for st in light_stats.values()),
        })
        extra["success_rate"] = extra["successes"] / walks if walks else 0.0
        extra["mutations_per_path"] = extra["mutations"] / walks if walks else 0.0
        extra["mutations_per_success"] = extra["mutations"] / extra["successes"] if extra["successes"] else 0.0
    if indirect_stats:
        extra["indirect"] = indirect_stats
        rays += sum(st["rays_photon"] + st["rays_camera"] for st in indirect_stats.values())
    rays += extra.get("auto", {}).get("rays", 0)  # the pilot's bakes: the bake's time counts them too
    image = film.image
    variance = film.variance
    if not (np.all(np.isfinite(image)) and np.all(np.isfinite(variance))):
        raise FloatingPointError("non-finite value in the caustic buffer")  # a bug, never user input
    top = float(image.max()) if image.size else 0.0
    if top > F32_MAX:  # Scene.validate bounds powers and colours; a focus can still concentrate them
        bright = scene.light_names[int(np.argmax(scene.light_color.max(axis=1)))] if scene.n_lights else "?"
        raise SceneError(f"scene '{scene.name}': the caustic layer's brightest pixel ({top:.3g}) is beyond what a "
                         f"float32 image holds; lower the lights' power (the brightest: '{bright}')")
    variance = np.minimum(variance, F32_MAX)  # its square can overflow where the image does not
    batch_lum = np.stack(film.batch_luminance)
    if scene.camera.use_border and scene.camera.use_crop_to_border:
        image = image[y0:y1, x0:x1]
        variance = variance[y0:y1, x0:x1]
        batch_lum = batch_lum[:, y0:y1, x0:x1]
    region = caustic_region(image)
    conv = convergence.convergence(batch_lum, np.array(film.batch_end), t_first, region,
                                   film.group_size * len(batch_lum))
    std = convergence.pixel_std(batch_lum)
    elapsed = time.perf_counter() - t0
    layer = float(channel_mean(image).sum())
    for st in light_stats.values():  # the trial cap's bias, at least, as a share of the layer
        if "trials" in st:
            st["trials"]["capped_share_min"] = st["trials"]["capped_energy_min"] / layer if layer > 0 else 0.0
    stats = {
        "method": settings.method,
        "settings": asdict(settings),
        "scene": scene.name,
        "resolution": [int(image.shape[1]), int(image.shape[0])],
        "time_s": elapsed,
        "rays": int(rays),
        "lights": light_stats,
        **extra,
        "skipped": [{"kind": k, "name": n, "reason": r} for k, n, r in plan.skipped],
        "plan": _plan_stats(plan),
        "nothing_to_bake": None,
        "noise": noise_summary(image, variance, batch_lum, region),
        # an error bar and a price (convergence.py): noise only, a biased estimator's bias is not in it
        "relative_error": _finite_or_none(convergence.relative_error(batch_lum, region)),
        "error_leaves_out": bias_left_out(settings, light_stats),
        "seconds_to_halve_error": conv["seconds_to_halve_error"],
        "convergence": {**conv, "setup_s": t_first, "last_batch_end_s": film.batch_end[-1] if film.batch_end else 0.0,
                        "batches_kept": int(len(batch_lum)),
                        "batches_per_kept": film.group_size},
        "stopped_by": stop.reason,
    }
    textured, per_albedo = film.textured_parts()
    if textured is not None:
        stats["textured_share"] = float(channel_mean(textured).sum()) / layer if layer > 0 else 0.0
        textured, per_albedo = textured.astype(np.float32), per_albedo.astype(np.float32)
    return BakeResult(image=image.astype(np.float32), variance=variance.astype(np.float32), stats=stats,
                      batch_luminance=batch_lum, std=std, textured=textured, per_albedo=per_albedo)
