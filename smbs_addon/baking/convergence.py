"""What a bake's accuracy is, and what more of it would cost.

Every bake is made of independent batches (film.Film), so the spread between them
measures the noise honestly whatever the estimator's distribution, the pixel filter's
correlation or the stratification (those change how batches vary, and the spread
sees it). From the batches, kept with the time at which each ended:

- ``relative_error``: the relative RMS error per pixel of the layer over its caustic
  region, sqrt(mean over the region of each pixel's variance of the mean) / (the
  region's mean). Noise only: the bias of a biased estimator is not in it.
- ``seconds_to_halve_error``: the extra baking time to halve it, from this bake's own
  convergence in time (``convergence``): what a batch costs, measured, and how the
  variance falls with the number of batches; a start-up cost (plan, tracer, photon
  pre-pass) is paid once, which is why 1/sqrt(t) of the whole time would mislead.
- ``pixel_std``: each pixel's standard deviation of the mean luminance (the EXR's
  ``std`` channel).
"""
from __future__ import annotations

import math

import numpy as np
from ..core.vec import box

MIN_FIT_POINTS = 3  # prefix variances (k = 2..G) needed for the log-log fit
HEAVY_TAIL = 1.5  # error(all) / (error(first half) / sqrt 2) above this: the variance is still growing


def box5(x: np.ndarray) -> np.ndarray:
    """(H,W) -> the mean over each pixel's 5x5 neighbourhood (edges repeated)."""
    return box(x, 2)


def caustic_region(lum: np.ndarray, frac: float = 0.05, blur: bool = True) -> np.ndarray:
    """Pixels where the caustic is clearly non-zero: its luminance averaged over 5x5 pixels
    (box5) above frac of that average's 99.5th percentile.

    Averaged, because the region is picked from the same noisy image that is then measured
    over it: a pixel picked by its own value is there because it came out high, so the
    region's mean comes out high and the relative error low. On the mirror (SMS, 1 spp in 8
    batches, seeds 1-4) our mean over a region picked pixel by pixel was 1.42-1.48x Cycles'
    there and relative_error read 0.73-0.80 of the true error; picked on the 5x5 average,
    which 25 pixels' noise hardly moves, 0.96-1.02 (at 2 and 8 spp 0.95-1.01, against
    0.88-0.99). It is also the conformance judge's region (tools/conformance.region_of).
    blur False: pixel by pixel (auto's pilot, on a frame of 40 x 30 pixels)."""
    if not lum.size:
        return np.zeros(lum.shape, bool)
    s = box5(lum) if blur else lum
    top = float(np.percentile(s, 99.5))
    return s > frac * top if top > 0 else np.zeros(lum.shape, bool)


def _prefix_variances(groups: np.ndarray) -> np.ndarray:
    """(B, P) luminances of B batches at P pixels -> (B-1,) the pixels' mean variance of the
    mean of the first k batches, k = 2..B (running sums: one pass, one row at a time: the (B, P)
    cumulative sums cost 2.3x as much at 512 x 512, for the same numbers bit for bit)."""
    g = groups.astype(np.float64)
    s, s2, out = np.zeros(g.shape[1]), np.zeros(g.shape[1]), np.empty(max(len(g) - 1, 0))
    for i in range(len(g)):
        s += g[i]
        s2 += g[i] * g[i]
        if i:
            k = float(i + 1)
            mean = s / k
            var = np.maximum(s2 / k - mean * mean, 0.0) * k / (k - 1)  # unbiased sample variance
            out[i - 1] = (var / k).mean()
    return out


def _var_of_mean(groups: np.ndarray) -> np.ndarray:
    """(B, ...) batch values -> each element's variance of their mean (B >= 2)."""
    return groups.astype(np.float64).var(axis=0, ddof=1) / len(groups)


def relative_error(groups: np.ndarray, region: np.ndarray) -> float:
    """Relative RMS noise of the mean image over region; groups (B,H,W) batch luminances
    (inf with fewer than two batches: no spread, no estimate; 0 without a caustic)."""
    if not region.any():
        return 0.0
    if len(groups) < 2:
        return math.inf
    px = groups[:, region]
    mean = float(px.mean())
    if mean <= 0:
        return 0.0
    return math.sqrt(float(_var_of_mean(px).mean())) / mean


def pixel_std(groups: np.ndarray) -> np.ndarray:
    """(H,W) float32 standard deviation of each pixel's mean luminance (zero with < 2 batches)."""
    if len(groups) < 2:
        return np.zeros(groups.shape[1:], np.float32)
    return np.sqrt(_var_of_mean(groups)).astype(np.float32)


def convergence(groups: np.ndarray, ends: np.ndarray, start: float, region: np.ndarray, batches: int) -> dict:
    """How this bake's error falls with time, and the extra time to halve it.

    groups (G,H,W): batch luminances (each the mean of batches / G batches), the last
    batch of group g ending ends[g] seconds into the bake; start: when the first batch
    began (what came before, plan and pre-pass, is paid once); batches: how many.

    The prediction: independent batches make the variance of their mean fall as 1 /
    batches, so halving the error takes four times the batches; what they cost is
    measured: the seconds per batch over the later half of the bake (the first batches
    may pay for caches and the walks' hand-off decisions). Measured too, and reported:
    alpha_fit, the exponent of a log-log fit of the variance of the first k groups'
    mean against the time they took, and heavy_tail, set when the error of the whole
    bake is larger than the first half's / sqrt(2) by more than 1.5 times: rare bright
    paths still raise the variance as they turn up, and the prediction is optimistic.
    seconds_to_halve_error is None when fewer than two batches leave nothing to measure."""
    g = len(groups)
    out = {"seconds_to_halve_error": None, "seconds_per_batch": None, "alpha_fit": None, "heavy_tail": False}
    if g < 2 or not region.any():
        return out
    ends = np.asarray(ends, float)
    per_group = batches / g
    half = g // 2
    if g >= 4:
        cost = (ends[-1] - ends[half - 1]) / ((g - half) * per_group)
    else:
        cost = (ends[-1] - start) / batches
    out["seconds_per_batch"] = float(max(cost, 0.0))
    v = _prefix_variances(groups[:, region])  # k = 2..G
    out["seconds_to_halve_error"] = 3.0 * batches * out["seconds_per_batch"] if v[-1] > 0 else 0.0
    t = ends[1:] - start
    ok = (v > 0) & (t > 0)
    if ok.sum() >= MIN_FIT_POINTS:
        x, y = np.log(t[ok]), np.log(v[ok])
        xm, ym = x.mean(), y.mean()
        sxx = ((x - xm) ** 2).sum()
        if sxx > 0:
            out["alpha_fit"] = float(-0.5 * ((x - xm) * (y - ym)).sum() / sxx)
    if g >= 4 and v[half - 2] > 0:
        # error(all) against error(first half) / sqrt(2): 1 when the variance falls as it should
        out["heavy_tail"] = bool(math.sqrt(v[-1] / v[half - 2]) * math.sqrt(g / half) > HEAVY_TAIL)
    return out
