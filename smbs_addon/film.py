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

_BH = (0.35875, 0.48829, 0.14128, 0.01168)
MAX_GROUPS = 64  # batch images kept (even); more batches are merged in pairs


def blackman_harris(x: np.ndarray, width: float) -> np.ndarray:
    """1-D filter of Cycles' width convention, normalised to integrate to one."""
    r = max(float(width), 0.5)  # splatting needs a finite support; Cycles' minimum is 0.01
    v = 2.0 * math.pi * (x / (2.0 * r) + 0.5)
    a0, a1, a2, a3 = _BH
    h = a0 - a1 * np.cos(v) + a2 * np.cos(2 * v) - a3 * np.cos(3 * v)
    return np.where(np.abs(x) <= r, h / (a0 * 2.0 * r), 0.0)


class Film:
    """Accumulates RGB splats into B independent batches.

    ``image`` is the mean over batches; ``variance`` the per-pixel variance of
    that mean (from the spread between batches), so the noise estimate is
    honest whatever the estimator's distribution.
    """

    def __init__(self, width: int, height: int, filter_width: float = 1.5,
                 region: tuple | None = None):
        self.W, self.H = int(width), int(height)
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

    def splat(self, rx: np.ndarray, ry: np.ndarray, rgb: np.ndarray) -> None:
        """Add rgb (N,3) at raster positions (rx, ry from top) through the filter."""
        if len(rx) == 0:
            return
        r = self.filter_width
        k = int(math.ceil(r)) + 1
        x0, x1, y0, y1 = self.region
        fx = np.floor(rx).astype(np.int64)
        fy = np.floor(ry).astype(np.int64)
        size = self.H * self.W
        for oy in range(-k, k + 1):
            py = fy + oy
            wy = blackman_harris(py + 0.5 - ry, r)
            for ox in range(-k, k + 1):
                px = fx + ox
                w = wy * blackman_harris(px + 0.5 - rx, r)
                m = (w > 0) & (px >= x0) & (px < x1) & (py >= y0) & (py < y1)
                if not m.any():
                    continue
                idx = py[m] * self.W + px[m]
                wm = w[m]
                for c in range(3):
                    self._cur[:, c] += np.bincount(idx, weights=rgb[m, c] * wm, minlength=size)

    def end_batch(self, t: float = 0.0) -> None:
        """Close the current batch (t: when it ended, seconds into the bake)."""
        self.sum += self._cur
        self.sumsq += self._cur * self._cur
        lum = self._cur.mean(axis=1).reshape(self.H, self.W)
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
        self._cur[:] = 0.0
        self.batches += 1

    @property
    def image(self) -> np.ndarray:
        b = max(self.batches, 1)
        return (self.sum / b).reshape(self.H, self.W, 3)

    @property
    def variance(self) -> np.ndarray:
        """Variance of the mean image per pixel and channel (zero with < 2 batches)."""
        b = self.batches
        if b < 2:
            return np.zeros((self.H, self.W, 3))
        mean = self.sum / b
        var = np.maximum(self.sumsq / b - mean * mean, 0.0) * (b / (b - 1)) / b
        return var.reshape(self.H, self.W, 3)
