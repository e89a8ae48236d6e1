"""A bake's settings: the method, the samples and the stop rule, the walks' solver, and their checks.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from dataclasses import dataclass

import numpy as np

from ..core.errors import SceneError
from ..core.random import FRAME_TAG, SHARD_TAG, frame_key
from ..walks.manifold import ManifoldOptions
from ..walks.walk import STALL, WalkConfig

METHODS = ("auto", "reference", "mnee", "sms", "smbs")
# A walk stops within solver_threshold (radians) of its solution, and the Bernoulli trials know
# two walks for the same solution when 1 - cos of their first directions is below uniqueness:
# on the glass sphere (SMS, unbiased, 16 spp) a uniqueness under ~10 x threshold^2 made the
# trials overcount (threshold 1e-3, uniqueness 1e-7: the layer +18%; 1e-4 with 1e-9: +30%;
# 1e-2 with 1e-7: 35x), and any threshold up to 1e-2 was right with a uniqueness to match.
MAX_SOLVER_THRESHOLD = 1e-5
UNIQUENESS_PER_THRESHOLD_SQ = 10.0
ESTIMATORS = ("unbiased", "biased")
# frames of a range: the random streams the same for every frame ("fixed": the noise of a still part
# of the picture stays still), or keyed by the frame ("frame"); bench/results/flicker.md measured both
SEEDINGS = ("fixed", "frame")
# the walks' eye samples: each film cell's jitter and light samples a scrambled Sobol' sequence over the
# bake (core.qmc), or independent uniforms; bench/results/pools.md measured both
SAMPLINGS = ("stratified", "independent")
DEFAULT_SEEDING = "fixed"
# what the image does not depend on: a file baked with other values of these is the same bake
NOT_THE_IMAGE = ("threads",)


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
    anchor: bool = True  # unbiased SMS, SMBS, one refraction (water, a window) under a sun or a world: one
    # walk per sample from the straight line to the light finds a solution at weight one, the random walks
    # and their Bernoulli trials only the others (estimators._anchored)
    anchor_walks: float = 1.0  # the share of samples that also walk from random seeds (weight 1/share)
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
    frame: int | None = None  # the scene's frame (a .blend exported at it); None: not said
    seeding: str = DEFAULT_SEEDING  # "frame": the random streams keyed by frame as well (SEEDINGS)
    shard: int = 0  # 1..shards: this bake is shard K of N of a frame's samples, its streams keyed by K
    # (baking/shards.py); 0: the whole bake
    shards: int = 1
    sampling: str = "stratified"  # the walks' eye samples (SAMPLINGS): stratified per film cell, or independent
    world_split: bool = True  # a world's map with a bright, compact part (a sun's disc) and a dim rest (a
    # sky): the walks take the bright part, path tracing from the receivers the rest (shading/world_parts.py);
    # not for the light tracer (method "reference")

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
        if not (0.0 < self.anchor_walks <= 1.0):
            raise SceneError(f"anchor_walks must be a share in (0, 1], not {self.anchor_walks}")
        if not (self.clamp_g >= 0):
            raise SceneError(f"clamp_g must be 0 (off) or a positive luminance, not {self.clamp_g}")
        if self.sampling not in SAMPLINGS:
            raise SceneError(f"sampling must be one of {', '.join(SAMPLINGS)}, not '{self.sampling}'")
        if self.seeding not in SEEDINGS:
            raise SceneError(f"seeding must be one of {', '.join(SEEDINGS)}, not '{self.seeding}'")
        if not (isinstance(self.shards, (int, np.integer)) and self.shards >= 1
                and isinstance(self.shard, (int, np.integer)) and 0 <= self.shard <= self.shards
                and (self.shard >= 1 or self.shards == 1)):
            raise SceneError(f"shard {self.shard} of {self.shards}: a shard is K of N with 1 <= K <= N "
                             f"(0 of 1: not sharded)")
        for c in self.chains:
            if not c or set(c) - {"R", "T"}:
                raise SceneError(f"chain type '{c}' must be a string of R (reflect) and T (refract)")

    def replicates(self) -> int:
        """The independent replicates a walks bake groups its batches into (trace/film.Film.use_replicates):
        its batches with stratified samples, 0 (the batches themselves) with independent ones."""
        return self.batches if self.sampling == "stratified" else 0

    def image_key(self) -> str:
        """16 hex digits of what the image depends on of these settings (all but NOT_THE_IMAGE): a
        frame's EXR records it, and a second run of a range skips a frame whose EXR says the same."""
        d = {k: v for k, v in dataclasses.asdict(self).items() if k not in NOT_THE_IMAGE}
        return hashlib.sha1(json.dumps(d, sort_keys=True, default=str).encode()).hexdigest()[:16]

    def stream_suffix(self) -> tuple:
        """What the bake's random streams add to their keys (core.random): nothing for a whole bake
        of one frame, so that its pixels stay what they were; (SHARD_TAG, K) for shard K; (FRAME_TAG,
        frame) with seeding "frame"."""
        out = ()
        if self.shard:
            out += (SHARD_TAG, int(self.shard))
        if self.seeding == "frame" and self.frame is not None:
            out += (FRAME_TAG, frame_key(self.frame))
        return out

    def manifold_options(self, method: str | None = None):
        """The walks' options; method overrides settings.method (auto: per light)."""
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
                               handoff=0.0 if self.method == "mnee" else float(self.handoff),
                               anchor=bool(self.anchor), anchor_walks=float(self.anchor_walks))


def shard_of(settings: BakeSettings, k: int, n: int) -> BakeSettings:
    """Shard k of n of a bake (k in 1..n): streams keyed by k (stream_suffix); by samples, its share of
    spp (spp x k // n - spp x (k - 1) // n: the shares add up to spp); by time, the same time; by noise,
    the target times sqrt(n), so that n shards merged reach about the target. SceneError where spp
    leaves a shard no sample."""
    if not (1 <= k <= n):
        raise SceneError(f"shard {k}/{n}: K must lie between 1 and N")
    rule = settings.time_budget > 0 or settings.noise_target > 0
    spp = settings.spp if rule else settings.spp * k // n - settings.spp * (k - 1) // n
    if spp < 1:
        raise SceneError(f"spp {settings.spp} cannot be shared by {n} shards: each needs a sample per pixel at least")
    out = dataclasses.replace(settings, shard=int(k), shards=int(n), spp=int(spp),
                              noise_target=settings.noise_target * math.sqrt(n))
    out.validate()
    return out
