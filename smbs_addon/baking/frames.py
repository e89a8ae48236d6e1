"""A frame range's summary: per frame its time, rays and error bar, the totals, and the flicker.

Flicker is the change from one frame to the next that noise makes. Between consecutive frames a and
b, over the caustic region of their mean (convergence.caustic_region, as a bake picks its own):

- measured: the RMS of (b - a) over the region, relative to the region's mean luminance;
- predicted: what the two frames' error bars say of independent noise, sqrt(mean over the region of
  std_a^2 + std_b^2) / the region's mean (the EXRs' ``std`` channels).

With random streams keyed by the frame the noise of the two frames is independent and, on a still
scene, measured equals predicted; with the same streams every frame (seeding "fixed", the default)
the noise of a part of the picture that does not change is the same in both frames and measured falls
below predicted. Motion adds to measured what the scene itself changes; bench/flicker.py separates the
two against converged frames. The range's figures are the RMS over its pairs of consecutive frames.
"""
from __future__ import annotations

import math

import numpy as np

from ..core.vec import channel_mean
from .convergence import caustic_region


def flicker(lum_a: np.ndarray, std_a: np.ndarray, lum_b: np.ndarray, std_b: np.ndarray) -> dict | None:
    """{"measured", "predicted", "region_pixels"} between two frames' luminance and std (H, W), None
    where their mean has no caustic."""
    mean = 0.5 * (lum_a.astype(np.float64) + lum_b)
    region = caustic_region(mean)
    if not region.any():
        return None
    m = float(mean[region].mean())
    if m <= 0:
        return None
    d = (lum_b.astype(np.float64) - lum_a)[region]
    var = (std_a.astype(np.float64) ** 2 + std_b.astype(np.float64) ** 2)[region]
    return {"measured": math.sqrt(float((d * d).mean())) / m, "predicted": math.sqrt(float(var.mean())) / m,
            "region_pixels": int(region.sum())}


class RangeSummary:
    """What a range bake did, frame by frame, and the flicker between consecutive frames (frames
    ``step`` apart whose images are known: baked now, or read back from the EXR a second run keeps)."""

    def __init__(self, frames: list, settings: dict, pattern: str, step: int = 1):
        self.frames, self.settings, self.pattern, self.step = list(frames), settings, str(pattern), int(step)
        self.rows = []
        self.pairs = []
        self._last = None  # (frame, luminance, std) of the frame before

    def add(self, frame: int, status: str, file: str, stats: dict | None = None, image=None, std=None,
            error: str | None = None) -> None:
        """A frame done ("baked", "skipped": its EXR was up to date) or "failed" (error: why)."""
        st = stats or {}
        self.rows.append({"frame": int(frame), "status": status, "file": file, "time_s": st.get("time_s"),
                          "rays": st.get("rays"), "relative_error": st.get("relative_error"),
                          "samples": st.get("samples", st.get("settings", {}).get("spp")),
                          "stopped_by": st.get("stopped_by"), **({"error": error} if error else {})})
        if image is None or std is None:
            self._last = None
            return
        lum = channel_mean(np.asarray(image, np.float64))
        last, self._last = self._last, (int(frame), lum, np.asarray(std))
        if last is not None and frame - last[0] == self.step:
            f = flicker(last[1], last[2], lum, std)
            if f is not None:
                self.pairs.append({"frames": [last[0], int(frame)], **f})

    def to_dict(self) -> dict:
        done = [r for r in self.rows if r["status"] in ("baked", "skipped")]
        baked = [r for r in self.rows if r["status"] == "baked"]
        errors = [r["relative_error"] for r in done if r["relative_error"] is not None]
        out = {
            "frames": self.frames, "pattern": self.pattern, "settings": self.settings, "per_frame": self.rows,
            "totals": {"frames": len(self.frames), "baked": len(baked),
                       "skipped": sum(r["status"] == "skipped" for r in self.rows),
                       "failed": sum(r["status"] == "failed" for r in self.rows),
                       "not_done": len(self.frames) - len(self.rows),
                       "time_s": sum(r["time_s"] or 0.0 for r in baked), "rays": sum(r["rays"] or 0 for r in baked),
                       "relative_error_max": max(errors) if errors else None,
                       "relative_error_rms": math.sqrt(sum(e * e for e in errors) / len(errors)) if errors else None},
            "flicker": self.flicker(),
        }
        return out

    def flicker(self) -> dict:
        """The RMS over the pairs of consecutive frames of measured and predicted flicker."""
        if not self.pairs:
            return {"pairs": 0, "measured": None, "predicted": None, "ratio": None, "per_pair": []}
        meas = math.sqrt(sum(p["measured"] ** 2 for p in self.pairs) / len(self.pairs))
        pred = math.sqrt(sum(p["predicted"] ** 2 for p in self.pairs) / len(self.pairs))
        return {"pairs": len(self.pairs), "measured": meas, "predicted": pred,
                "ratio": meas / pred if pred > 0 else None, "per_pair": self.pairs}
