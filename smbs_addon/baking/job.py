"""A bake in progress: what its passes share (the scene, the settings, the plan, the camera, the
tracer, the film, the progress and cancel hooks) and the statistics they fill in.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

from ..core import qmc, signals
from ..core.errors import BakeCancelled
from ..core.random import STRATA, stream
from ..trace.eye import film_cells

MEMORY_BUDGET = 8 * 2**30  # bytes the film may take; a bigger resolution is refused before baking


class Progress:
    """The caller's progress(fraction, message) over a bake's steps, and its cancel() check."""

    def __init__(self, total, progress, cancel):
        self.total, self.done, self.progress, self.cancel = max(total, 1), 0, progress, cancel
        self.fraction = None  # stop rules by time or noise: () -> fraction done, instead of the count

    def check(self):
        """Raise BakeCancelled if the caller's cancel() says so or a signal asked for a stop."""
        signals.check()
        if self.cancel is not None and self.cancel():
            raise BakeCancelled("bake cancelled")

    def step(self, message):
        self.done += 1
        if self.progress is not None:
            f = self.done / self.total if self.fraction is None else self.fraction()
            self.progress(min(1.0, f), message)


@dataclass
class Job:
    """One bake of a fixed pipeline. film may be a deferred film (passes.DeferredFilm) for a pass
    that runs beside another (on_film)."""

    scene: object
    settings: object  # settings.BakeSettings
    plan: object  # plan.Plan
    cam: object  # trace.camera.CameraModel
    tracer: object  # trace.tracer.Tracer
    film: object  # trace.film.Film
    t0: float  # when the bake began (time.perf_counter)
    report: object  # progress(fraction, message), or None
    cancel: object  # () -> bool, or None
    watch: object  # core.compiles.CompileWatch: the time compiling takes is not the bake's
    prog: Progress = None
    light_stats: dict = field(default_factory=dict)  # per light name
    indirect_stats: dict = field(default_factory=dict)  # per light name: indirect.trace_indirect_photons' photons
    extra: dict = field(default_factory=dict)  # the statistics beside the lights'
    keep_partial: bool = False  # a time or noise rule stopped by a signal keeps the batches done (stop.py)
    # a world's map split (shading.world_parts.WorldParts): scene is then lit by its bright part, and
    # the rest is path-traced from the receivers (passes.sky_batch); None: not split
    sky: object = None

    def __post_init__(self):
        self.light_stats = self.light_stats or {
            lp.name: {"time_s": 0.0, "casters": [self.scene.object_names[o] for o in lp.caster_objects]}
            for lp in self.plan.lights}
        if self.sky is not None:
            self.extra.setdefault("sky", {"light": self.scene.light_names[self.sky.light],
                                          "bright_share": self.sky.bright_share, "eye_paths": 0, "time_s": 0.0})

    @property
    def per_light(self) -> int:
        """Light paths per light and bake: spp per pixel of the render region."""
        x0, x1, y0, y1 = self.cam.region
        return self.settings.spp * max(0, x1 - x0) * max(0, y1 - y0)

    @property
    def physical(self) -> bool:
        return self.settings.radiance == "physical"

    def indirect_lights(self) -> list:
        """The lights whose caustic after a diffuse bounce this bake traces."""
        return list(self.plan.indirect_lights) if self.settings.indirect else []

    def eye_per_batch(self) -> int:
        """Eye samples per batch: spp per film cell over all batches. Fewer than the cells (spp below
        the batches) is a sparser batch over the whole film (eye.film_samples), not a whole pass:
        1 spp in 8 batches costs 1 spp, not 8."""
        return max(1, film_cells(self.cam, self.film) * self.settings.spp // self.settings.batches)

    def strata(self, b: int):
        """Batch b's stratified eye samples (core.qmc.Strata), or None where the settings draw them
        independently (sampling "independent"): batch b continues replicate b mod batches's
        sequences (film.Film.use_replicates), each replicate scrambled apart."""
        replicates = self.settings.replicates()
        if not replicates:
            return None
        r, k = divmod(b, replicates)[::-1]
        return qmc.Strata(int(self.rng(STRATA, r).integers(2**32)), k)

    def rng(self, *key):
        """The random stream of this bake's seed and key (core.random), and of its shard or frame
        where the settings key streams by them (BakeSettings.stream_suffix)."""
        return stream(self.settings.seed, *key, *self.settings.stream_suffix())

    def on_film(self, film) -> "Job":
        """The same job writing to another film (a pass beside another: passes.DeferredFilm)."""
        return dataclasses.replace(self, film=film)

    def seconds(self) -> float:
        return time.perf_counter() - self.t0
