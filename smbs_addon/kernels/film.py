"""The film's pixel filter (Cycles' Blackman-Harris) and its splats.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..core.jit import JIT


# ------------------------------------------------------------------ the film
@njit(**JIT)
def _blackman_harris(x, r):
    """film.blackman_harris of one offset (r already at least 0.5)."""
    if not abs(x) <= r:
        return 0.0
    c = math.cos(2.0 * math.pi * (x / (2.0 * r) + 0.5))
    c2 = 2.0 * c * c - 1.0  # cos 2v
    c3 = c * (2.0 * c2 - 1.0)  # cos 3v = 4 c^3 - 3 c
    h = 0.35875 - 0.48829 * c + 0.14128 * c2 - 0.01168 * c3
    return h / (0.35875 * 2.0 * r)


@njit(**JIT)
def blackman_harris(x, r):
    """Cycles' Blackman-Harris window of half-width r (>= 0.5) at offsets x, normalised to one."""
    out = np.zeros(x.shape[0])
    for i in range(x.shape[0]):
        out[i] = _blackman_harris(x[i], r)
    return out


@njit(**JIT)
def splat(cur, W, x0, x1, y0, y1, r, k, rx, ry, rgb):
    """film.Film.splat's loop: every sample through the (2k+1)^2 filter taps into cur (H*W, 3),
    samples in order, on the rows y0 <= y < y1 and columns x0 <= x < x1 alone (each pixel's sums
    in the samples' order, whoever adds them: threads given rows of their own make the image one
    thread makes, bit for bit)."""
    wx = np.zeros(2 * k + 1)
    for i in range(rx.shape[0]):
        fx = math.floor(rx[i])
        fy = math.floor(ry[i])
        if fy + k < y0 or fy - k >= y1:
            continue  # no tap on these rows
        for ox in range(-k, k + 1):
            wx[ox + k] = _blackman_harris(fx + ox + 0.5 - rx[i], r)
        for oy in range(-k, k + 1):
            py = fy + oy
            if py < y0 or py >= y1:
                continue
            wy = _blackman_harris(py + 0.5 - ry[i], r)
            if wy == 0.0:
                continue
            for ox in range(-k, k + 1):
                px = fx + ox
                w = wy * wx[ox + k]
                if not (w > 0) or px < x0 or px >= x1:
                    continue
                idx = int(py) * W + int(px)
                for c in range(3):
                    cur[idx, c] += rgb[i, c] * w
