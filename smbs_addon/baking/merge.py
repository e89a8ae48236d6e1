"""Merging bakes of one frame into one: the shards of a farm (``--shard K/N``), or a finished bake and
more samples baked later (another ``--seed``): ``python -m smbs_addon merge OUT.exr IN.exr ...``.

Each input's EXR carries what a merge needs (io.exr.exr_metadata): the samples per pixel it took, its
batches, its per-pixel ``std`` (the standard deviation of its mean luminance, from the spread of its
batches: convergence.pixel_std), its settings, the scene's digest and the code that made it. The
merge is

- the mean, weighted by samples: x = sum_i w_i x_i, w_i = n_i / sum n (every channel: R, G, B and
  per_albedo_*), which is the mean of all the samples;
- its per-pixel variance, from the inputs' own: std^2 = sum_i w_i^2 std_i^2 (independent inputs:
  their random streams are told apart by seed and shard, and a merge refuses the same stream twice);
- the error bar on the merged image's caustic region, with a bake's definitions
  (convergence.relative_error: sqrt(mean over the region of the variance of each pixel's mean) / the
  region's mean; the region convergence.caustic_region of the merged image). A bake of all the
  inputs' batches at once would estimate each pixel's variance from the spread of all its batches,
  the merge pools the spread within each input: the same in expectation (the inputs' means differ
  only by their noise), with the inputs' degrees of freedom summed less one per input, and exactly
  the variance of the weighted mean where the inputs took different samples. The std channel is
  float32, the one rounding the merge adds (1e-7 relative).

The inputs are summed in a fixed order (by samples, seed, shard and a digest of their pixels), in
float64, so that the same inputs give the same bits in whatever order they are named.
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass

import numpy as np

from ..core.errors import SceneError
from ..core.vec import channel_mean
from .convergence import caustic_region

# settings that may differ between the inputs of one merge (the rest must agree: they change what is
# estimated, not how many samples estimate it)
MERGEABLE = ("seed", "spp", "batches", "time_budget", "noise_target", "shard", "shards", "threads")
NEEDS = ("samples", "code", "stats")


@dataclass
class Part:
    """One input of a merge: its file, channels by name (H, W), header entries and statistics."""

    path: str
    channels: dict
    meta: dict
    stats: dict

    @property
    def samples(self) -> float:
        return float(self.meta["samples"])

    @property
    def streams(self) -> list:
        """[seed, shard] of every bake in it (a merged file's are its inputs')."""
        if "streams" in self.stats:
            return [list(s) for s in self.stats["streams"]]
        s = self.stats["settings"]
        return [[int(s["seed"]), int(s.get("shard", 0))]]

    def digest(self) -> str:
        h = hashlib.sha1()
        for name in sorted(self.channels):
            h.update(name.encode())
            h.update(np.ascontiguousarray(self.channels[name]).tobytes())
        return h.hexdigest()

    def order(self) -> tuple:
        return (self.samples, sorted(self.streams), self.digest())


def part(path, channels: dict, meta: dict) -> Part:
    """A Part from an EXR's channels and header (io.exr.read_channels); SceneError, naming the file,
    where it lacks what a merge needs."""
    missing = [k for k in NEEDS if k not in meta] + [c for c in ("R", "G", "B", "std") if c not in channels]
    if missing:
        raise SceneError(f"'{path}' cannot be merged: it has no {', '.join(missing)} (a bake by an older version, "
                         f"or not a caustic layer)")
    try:
        stats = json.loads(meta["stats"])
    except (TypeError, ValueError):
        raise SceneError(f"'{path}' cannot be merged: its statistics do not read") from None
    if not (float(meta["samples"]) > 0):
        raise SceneError(f"'{path}' cannot be merged: it holds no samples")
    return Part(str(path), channels, meta, stats)


def _settings(p: Part) -> dict:
    return {k: v for k, v in p.stats.get("settings", {}).items() if k not in MERGEABLE}


def check(parts: list) -> None:
    """SceneError naming the files where the inputs cannot be merged: another size or channels, other
    code, other settings or scene, or the same random stream twice."""
    if not parts:
        raise SceneError("nothing to merge")
    first = parts[0]
    shape = first.channels["R"].shape
    for p in parts[1:]:
        why = None
        if sorted(p.channels) != sorted(first.channels) or p.channels["R"].shape != shape:
            why = (f"{p.channels['R'].shape[1]} x {p.channels['R'].shape[0]} with {', '.join(sorted(p.channels))} "
                   f"against {shape[1]} x {shape[0]} with {', '.join(sorted(first.channels))}")
        elif p.meta["code"] != first.meta["code"]:
            why = f"made by other code ({p.meta['code']} against {first.meta['code']}): bake them with one version"
        elif p.meta.get("scene", "") != first.meta.get("scene", ""):
            why = "of another scene (or another frame of it)"
        elif _settings(p) != _settings(first):
            a, b = _settings(p), _settings(first)
            diff = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
            why = "baked with other settings: " + ", ".join(f"{k} {a.get(k)!r} against {b.get(k)!r}" for k in diff)
        if why:
            raise SceneError(f"'{p.path}' cannot be merged with '{first.path}': {why}")
    seen = {}
    for p in parts:
        for s in p.streams:
            key = tuple(s)
            if key in seen:
                raise SceneError(f"'{p.path}' and '{seen[key]}' hold the same samples (seed {s[0]}, "
                                 f"{f'shard {s[1]}' if s[1] else 'not sharded'}): a merge needs independent "
                                 f"bakes (another --seed or --shard)")
            seen[key] = p.path


def merge(parts: list) -> tuple[dict, dict, dict]:
    """(channels, header entries, statistics) of the inputs merged (see the module's notes)."""
    check(parts)
    parts = sorted(parts, key=Part.order)
    total = sum(p.samples for p in parts)
    w = [p.samples / total for p in parts]
    out = {}
    for name in parts[0].channels:
        if name == "std":
            var = sum(wi * wi * p.channels["std"].astype(np.float64) ** 2 for wi, p in zip(w, parts))
            out[name] = np.sqrt(var).astype(np.float32)
        else:
            out[name] = sum(wi * p.channels[name].astype(np.float64) for wi, p in zip(w, parts)).astype(np.float32)
    rgb = np.stack([out[c] for c in "RGB"], axis=-1)
    stats = _stats(parts, w, rgb, out["std"])
    first = parts[0].meta
    meta = {k: first[k] for k in ("method", "code", "scene", "frame", "composite") if k in first}
    meta.update({"spp": int(round(total)), "samples": float(total), "seed": int(stats["settings"]["seed"]),
                 "time_s": stats["time_s"], "rays": stats["rays"], "batches_done": stats["batches_done"],
                 "noise_relative": stats["noise"]["relative_noise"], "merged": len(parts),
                 "settings_key": "merged-" + hashlib.sha1(
                     json.dumps(sorted(str(p.meta.get("settings_key")) for p in parts)).encode()).hexdigest()[:9],
                 "stats": stats})
    for key in ("relative_error", "seconds_to_halve_error"):
        if stats.get(key) is not None:
            meta[key] = float(stats[key])
    return out, meta, stats


def error_bar(rgb: np.ndarray, std: np.ndarray) -> tuple[float | None, dict]:
    """(relative_error, noise) of an image and its per-pixel std, with a bake's definitions
    (convergence.relative_error, result.noise_summary): None where no caustic is in it."""
    lum = channel_mean(rgb.astype(np.float64))
    region = caustic_region(lum)
    if not region.any():
        return 0.0, {"region_pixels": 0, "mean": 0.0, "std_error_of_mean": 0.0, "relative_noise": 0.0,
                     "pixel_rms_noise": 0.0}
    mean = float(lum[region].mean())
    rms = math.sqrt(float((std.astype(np.float64)[region] ** 2).mean()))
    err = rms / mean if mean > 0 else 0.0
    return err, {"region_pixels": int(region.sum()), "mean": mean, "pixel_rms_noise": rms, "relative_noise": err}


def _light_counts(parts: list) -> dict:
    """Per light the counts and seconds, summed over the inputs (rates and means are not)."""
    out = {}
    for p in parts:
        for name, st in p.stats.get("lights", {}).items():
            mine = out.setdefault(name, {})
            for k, v in st.items():
                if isinstance(v, bool) or not isinstance(v, (int, float)):
                    continue
                if isinstance(v, int) or k == "time_s":
                    mine[k] = mine.get(k, 0) + v
    return out


def _stats(parts: list, w: list, rgb: np.ndarray, std: np.ndarray) -> dict:
    err, noise = error_bar(rgb, std)
    noise["std_error_of_mean"] = math.sqrt(sum(wi * wi * p.stats.get("noise", {}).get("std_error_of_mean", 0.0) ** 2
                                               for wi, p in zip(w, parts)))
    spent = sum((p.stats.get("convergence", {}).get("seconds_per_batch") or 0.0) * p.stats.get("batches_done", 0)
                or p.stats.get("time_s", 0.0) for p in parts)
    settings = dict(parts[0].stats["settings"])
    settings.update(spp=int(round(sum(p.samples for p in parts))), shard=0, shards=1,
                    batches=sum(p.stats.get("batches_done", 0) for p in parts))
    leaves = []
    for p in parts:
        leaves += [x for x in p.stats.get("error_leaves_out", []) if x not in leaves]
    return {
        "method": parts[0].stats.get("method"), "settings": settings, "scene": parts[0].stats.get("scene"),
        "resolution": [int(rgb.shape[1]), int(rgb.shape[0])],
        "time_s": sum(p.stats.get("time_s", 0.0) for p in parts), "rays": sum(p.stats.get("rays", 0) for p in parts),
        "samples": sum(p.samples for p in parts), "batches_done": sum(p.stats.get("batches_done", 0) for p in parts),
        "lights": _light_counts(parts), "noise": noise, "relative_error": err, "error_leaves_out": leaves,
        "seconds_to_halve_error": 3.0 * spent if err else 0.0, "stopped_by": "merge", "nothing_to_bake": None,
        "skipped": parts[0].stats.get("skipped", []),
        "streams": sorted(s for p in parts for s in p.streams),
        "merged_from": [{"file": p.path, "samples": p.samples, "streams": p.streams, "weight": wi,
                         "relative_error": p.stats.get("relative_error"), "time_s": p.stats.get("time_s"),
                         "rays": p.stats.get("rays")} for wi, p in zip(w, parts)],
    }
