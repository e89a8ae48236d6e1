"""The film: Cycles' Blackman-Harris pixel filter, splatting, and a per-pixel
noise estimate from independent batches.

Cycles samples sub-pixel offsets from a separable Blackman-Harris window whose
table is built with ``width *= 2`` (intern/cycles/scene/film.cpp), so a filter
width w has support [-w, w] pixels on each axis. A pixel's value is
integral h(x - c) L(x) dx with h normalised to one; splatting a light-path
contribution with the same h estimates exactly that.
"""
from __future__ import annotations

import math

import numpy as np

from ..kernels import film
from ..core import lanes
from ..core.vec import channel_mean

SPLAT_SPLIT = 4096  # samples from which a splat's rows are shared over the threads
END_BATCH_PART = 1 << 17  # pixels per thread at least when a batch's sums are added up
MAX_GROUPS = 64  # batch images kept (even); more batches are merged in pairs


def blackman_harris(x: np.ndarray, width: float) -> np.ndarray:
    """1-D filter of Cycles' width convention, normalised to integrate to one (the same formula
    as the splat kernel's, film.blackman_harris)."""
    r = max(float(width), 0.5)  # splatting needs a finite support; Cycles' minimum is 0.01
    return film.blackman_harris(np.asarray(x, np.float64).ravel(), r).reshape(np.shape(x))


class Film:
    """Accumulates RGB splats into B independent batches.

    ``image`` is the mean over batches; ``variance`` the per-pixel variance of
    that mean (from the spread between batches), so the noise estimate is
    honest whatever the estimator's distribution.

    With replicates R (stratified eye samples: core.qmc), batch b belongs to replicate b mod R,
    whose batches continue one stratified sequence per pixel and are not independent of each
    other, while the R replicates are: the variance and the error's groups (error_luminance) then
    come from the spread between the replicates' means.
    """

    def __init__(self, width: int, height: int, filter_width: float = 1.5,
                 region: tuple | None = None, textured: bool = False, threads: int = 1):
        self.W, self.H = int(width), int(height)
        self.threads = max(1, int(threads))  # for large splats (each its own rows) and a batch's sums
        self.filter_width = max(float(filter_width), 0.5)
        self.region = region or (0, self.W, 0, self.H)
        self.sum = np.zeros((self.H * self.W, 3))
        self.sumsq = np.zeros((self.H * self.W, 3))
        self.batches = 0
        self._cur = np.zeros((self.H * self.W, 3))
        # per group of group_size batches, the mean (H,W) float32 luminance and the time its
        # last batch ended: the noise estimate and the convergence fit. A long bake (stop
        # rules by time or noise) merges neighbouring groups in pairs once MAX_GROUPS are kept,
        # so the memory stays bounded; a group not yet full waits in _pending
        self.batch_luminance = []
        self.batch_end = []
        self.group_size = 1
        self._pending, self._pending_n = None, 0
        self.replicates, self._rep_sum, self._rep_n = 0, None, None  # use_replicates
        # with textured receivers (Scene.mat_textured): the splats that fell on them where the camera
        # sees them, as they are and per unit albedo, summed over every batch (BakeResult.per_albedo);
        # the current batch's apart until it ends (drop_batch)
        self.textured = np.zeros((self.H * self.W, 3)) if textured else None
        self.per_albedo = np.zeros((self.H * self.W, 3)) if textured else None
        self._cur_textured = np.zeros((self.H * self.W, 3)) if textured else None
        self._cur_per_albedo = np.zeros((self.H * self.W, 3)) if textured else None

    def splat(self, rx: np.ndarray, ry: np.ndarray, rgb: np.ndarray, albedo: np.ndarray | None = None) -> None:
        """Add rgb (N,3) at raster positions (rx, ry from top) through the filter. albedo (N,3), on
        a film with textured receivers: the albedo each sample's value was multiplied by where it
        fell on one seen directly (the share of its diffuse Cycles' Diffuse Color pass holds), zero
        elsewhere; those samples are also added to the textured part and, divided by it, to the
        per-albedo part."""
        if len(rx) == 0:
            return
        rx, ry = np.ascontiguousarray(rx, np.float64), np.ascontiguousarray(ry, np.float64)
        rgb = np.ascontiguousarray(rgb, np.float64)
        self._splat(self._cur, rx, ry, rgb)
        if albedo is None or self.textured is None:
            return
        on = np.flatnonzero(np.asarray(albedo).max(axis=1) > 0)
        if on.size:
            a, v = np.asarray(albedo, np.float64)[on], rgb[on]
            self._splat(self._cur_textured, rx[on], ry[on], v)
            unit = np.divide(v, a, out=np.zeros_like(v), where=a > 0)
            self._splat(self._cur_per_albedo, rx[on], ry[on], unit)

    def _splat(self, into, rx, ry, rgb) -> None:
        """film.splat into `into`; a splat of SPLAT_SPLIT samples or more on the threads, each
        adding to rows of its own (the same image)."""
        r = self.filter_width
        k = int(math.ceil(r)) + 1
        x0, x1, y0, y1 = self.region
        bands = self.threads if len(rx) >= SPLAT_SPLIT else 1
        edges = [y0 + (y1 - y0) * i // bands for i in range(bands + 1)]

        def band(a, b):
            film.splat(into, self.W, x0, x1, edges[a], edges[b], r, k, rx, ry, rgb)

        lanes.run(band, bands, bands, 1)

    def frame_share(self, rx: np.ndarray, ry: np.ndarray) -> np.ndarray:
        """The share of a splat at (rx, ry) that lands in the render region: the filter's taps
        splat() adds there, summed (a sample in the filter's margin may land wholly outside)."""
        r = self.filter_width
        k = int(math.ceil(r)) + 1
        x0, x1, y0, y1 = self.region
        offs = np.arange(-k, k + 1)

        def axis(v, lo, hi):
            px = np.floor(np.asarray(v, np.float64))[:, None] + offs
            w = blackman_harris(px + 0.5 - np.asarray(v, np.float64)[:, None], r)
            return np.where((px >= lo) & (px < hi), w, 0.0).sum(axis=1)

        return axis(rx, x0, x1) * axis(ry, y0, y1)

    def end_batch(self, t: float = 0.0) -> None:
        """Close the current batch (t: when it ended, seconds into the bake)."""
        lum = np.empty(self.H * self.W)

        def part(a, b):  # pixels a..b-1 (elementwise: the threads' parts give the same bits)
            cur = self._cur[a:b]
            self.sum[a:b] += cur
            self.sumsq[a:b] += cur * cur
            if self._rep_sum is not None:
                self._rep_sum[self.batches % self.replicates, a:b] += cur
            lum[a:b] = channel_mean(cur)
            cur[:] = 0.0
            if self.textured is not None:
                for total, part_cur in ((self.textured, self._cur_textured), (self.per_albedo, self._cur_per_albedo)):
                    total[a:b] += part_cur[a:b]
                    part_cur[a:b] = 0.0

        lanes.run(part, self.H * self.W, self.threads, END_BATCH_PART)
        if self.replicates:
            self._rep_n[self.batches % self.replicates] += 1
        lum = lum.reshape(self.H, self.W)
        self._pending = lum if self._pending is None else self._pending + lum
        self._pending_n += 1
        if self._pending_n == self.group_size:
            self.batch_luminance.append((self._pending / self.group_size).astype(np.float32))
            self.batch_end.append(float(t))
            self._pending, self._pending_n = None, 0
            if len(self.batch_luminance) == MAX_GROUPS:
                g = self.batch_luminance
                self.batch_luminance = [0.5 * (g[i] + g[i + 1]) for i in range(0, len(g), 2)]
                self.batch_end = self.batch_end[1::2]
                self.group_size *= 2
        self.batches += 1

    def drop_batch(self) -> None:
        """Forget the current batch's splats (a bake stopped part way through a batch keeps the
        batches done, whole: baking/stop.run_batches)."""
        for cur in (self._cur, self._cur_textured, self._cur_per_albedo):
            if cur is not None:
                cur[:] = 0.0

    def textured_parts(self):
        """(textured, per_albedo): the means over the batches of splat()'s two parts, (H,W,3)
        each; (None, None) on a film without textured receivers."""
        if self.textured is None:
            return None, None
        b = max(self.batches, 1)
        return tuple((x / b).reshape(self.H, self.W, 3) for x in (self.textured, self.per_albedo))

    @property
    def image(self) -> np.ndarray:
        b = max(self.batches, 1)
        return (self.sum / b).reshape(self.H, self.W, 3)

    def use_replicates(self, replicates: int) -> None:
        """Group the batches into replicates (before the first batch ends)."""
        assert self.batches == 0, "replicates are set before the first batch"
        self.replicates = int(replicates)
        self._rep_sum = np.zeros((self.replicates, self.H * self.W, 3))
        self._rep_n = np.zeros(self.replicates, np.int64)

    def _replicate_means(self) -> np.ndarray:
        """(R', H*W, 3) the means of the replicates that have a batch."""
        have = np.flatnonzero(self._rep_n)
        return self._rep_sum[have] / self._rep_n[have, None, None]

    @property
    def error_luminance(self) -> list:
        """The independent groups the error bar reads, (H,W) float32 luminance each: the
        replicates' means, or without replicates the batches' (batch_luminance)."""
        if not self.replicates:
            return self.batch_luminance
        return [channel_mean(m).reshape(self.H, self.W).astype(np.float32) for m in self._replicate_means()]

    @property
    def variance(self) -> np.ndarray:
        """Variance of the mean image per pixel and channel (zero with < 2 batches, or replicates)."""
        if self.replicates:
            m = self._replicate_means()
            if len(m) < 2:
                return np.zeros((self.H, self.W, 3))
            return (m.var(axis=0, ddof=1) / len(m)).reshape(self.H, self.W, 3)
        b = self.batches
        if b < 2:
            return np.zeros((self.H, self.W, 3))
        mean = self.sum / b
        var = np.maximum(self.sumsq / b - mean * mean, 0.0) * (b / (b - 1)) / b
        return var.reshape(self.H, self.W, 3)
