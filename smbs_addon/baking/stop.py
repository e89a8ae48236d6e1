"""When a bake stops: after its batches, at a time budget, or at a noise target (its error bar).
"""
from __future__ import annotations

import math
import time

import numpy as np

from ..core import signals
from ..core.errors import BakeCancelled
from ..core.vec import channel_mean
from . import convergence

NOISE_MIN_BATCHES = 4  # a noise target is checked from this many batches on (a spread of fewer lies)
MAX_BATCHES = 1 << 20  # a stop rule that is never met (a noise target under a heavy tail) ends here


class StopRule:
    """The stop rule: samples (settings.batches batches), time, noise, or time and noise.

    Time: at least two batches, then another one only while it would end nearer the
    budget than stopping now (a batch is predicted to take as long as the last one), so
    the whole bake ends within half a batch of the budget. Noise: from NOISE_MIN_BATCHES
    on, stop once the estimated relative_error is at or below the target.

    The budget is the bake's own work: time spent compiling kernels (watch, a CompileWatch: the
    first bake after installing or updating) is not in it, so that a budget buys the same image
    on its first bake as on later ones (the statistics' time_s holds the whole wall time,
    compile_s what compiling took of it)."""

    def __init__(self, settings, film, t0: float, watch):
        self.s, self.film, self.t0, self.watch = settings, film, t0, watch
        self.reason = "samples"
        self.signal = ""  # the signal that stopped a bake with keep_partial (run_batches)
        self.last_error = math.inf

    def clock(self) -> float:
        """Seconds into the bake, compiling left out: the batches' clock (run_batches)."""
        return time.perf_counter() - self.t0 - self.watch.now()

    def _error(self) -> float:
        groups = self.film.error_luminance
        groups = np.stack(groups) if len(groups) >= 2 else None
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


def run_batches(job, run_batch):
    """run_batch(b) adds batch b to the film's current batch; batches go on until the stop
    rule says enough. Returns (batches done, the stop rule, seconds before the first).

    The batches' clock (the film's batch ends, the seconds before the first, the last batch's
    length the time rule looks ahead by) leaves out the time spent compiling kernels (job.watch:
    a CompileWatch), which later bakes do not pay: the price of more batches is what they cost,
    and a time budget buys what it buys on later bakes (StopRule).

    A signal (core/signals.py) stops the batch under way with BakeCancelled. A time or noise rule
    whose job keeps what it has (job.keep_partial) then drops that batch's splats (film.drop_batch)
    and ends with the batches done, if any (the stop rule's reason "signal"): the image and its
    error bar are those of whole batches."""
    settings, film = job.settings, job.film
    stop = StopRule(settings, film, job.t0, job.watch)
    job.prog.fraction = stop.fraction if settings.time_budget > 0 or settings.noise_target > 0 else None
    t_first = stop.clock()
    b = 0
    partial = job.keep_partial and (settings.time_budget > 0 or settings.noise_target > 0)
    while True:
        begun = stop.clock()
        try:
            run_batch(b)
        except BakeCancelled as e:
            if not (partial and e.signum and b >= 1):
                raise
            signals.acknowledge()  # what follows (the image, its error bar) runs to its end
            film.drop_batch()
            stop.reason, stop.signal = "signal", signals.name(e.signum)
            return b, stop, t_first
        ended = stop.clock()
        film.end_batch(ended)
        b += 1
        if stop(b, ended - begun):
            return b, stop, t_first
