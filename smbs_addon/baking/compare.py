"""Equal time on the user's own scene: which method reaches the lowest error in the same seconds.

``compare`` bakes a scene once per method under the time rule (the same budget, the same seed)
and measures every bake over one region of pixels, so that their numbers can be set side by
side: the caustic region of the mean of all the bakes (convergence.caustic_region), or of a
reference image when one is given.

- ``error``: relative RMS noise per pixel over that region, from the spread between each
  bake's batches (convergence.relative_error): noise only. A biased bake (MNEE, the biased
  estimator, a clamp, the Bernoulli trials' cap) lists what it leaves out (``leaves_out``).
- ``time_for_same_error``: error^2 x seconds of the method over the least of them among the
  methods whose error is all noise (the noise variance of a mean falls as 1 / time): 1.0 for
  the fastest, 2.5 for a method that needs 2.5 times as long for the same error. None where
  there is no error bar (fewer than two batches) or where a bias hides from it.
- Against a reference (the caustic layer alone: a long bake of ours, or Cycles' caustics
  on minus off): ``rmse``, the relative RMS error per pixel against it (the reference's
  own noise taken out where its EXR has our ``std`` channel), and ``ratio``, our mean over
  the region over the reference's, with its standard error from our batches: a bias shows
  here, where the error bar cannot see it.

The core of ``python -m smbs_addon compare``; no bpy here.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import convergence
from ..core.errors import SceneError
from ..io.exr import read_exr
from ..trace.camera import CameraModel
from .bake import bake


@dataclasses.dataclass
class Reference:
    """A caustic layer to judge against: luminance (H, W) and, if known, each pixel's
    variance of that luminance (the reference's own noise, taken out of the RMSE)."""
    luminance: np.ndarray
    variance: np.ndarray | None = None
    name: str = "reference"

    @classmethod
    def from_exr(cls, path) -> "Reference":

        img, _ = read_exr(path)
        if img.ndim != 3 or img.shape[2] < 3:
            raise SceneError(f"reference '{path}': expected an RGB image, it has {img.shape[-1]} channel(s)")
        lum = img[..., :3].astype(np.float64).mean(axis=2)
        if not np.all(np.isfinite(lum)):
            raise SceneError(f"reference '{path}' has pixels that are not finite numbers")
        try:
            std, _ = read_exr(path, channel="std")
            var = std.astype(np.float64) ** 2
        except SceneError:  # not one of our bakes: its noise stays in the RMSE
            var = None
        return cls(lum, var, str(path))


def layer_shape(scene) -> tuple[int, int]:
    """(height, width) of the caustic layer a bake of scene makes: the camera's resolution times its
    percentage, cropped to the render border where the camera crops to it (result._film_images)."""
    cam = CameraModel(scene.camera)
    if scene.camera.use_border and scene.camera.use_crop_to_border:
        x0, x1, y0, y1 = cam.region
        return y1 - y0, x1 - x0
    return cam.H, cam.W


def _rmse(lum: np.ndarray, ref: Reference, region: np.ndarray) -> float:
    mse = float(((lum - ref.luminance)[region] ** 2).mean())
    if ref.variance is not None:
        mse -= float(ref.variance[region].mean())
    mean = float(ref.luminance[region].mean())
    return math.sqrt(max(mse, 0.0)) / mean if mean > 0 else math.inf


def compare(scene, methods, seconds: float, settings, reference: Reference | None = None, progress=None,
            cancel=None, bake_progress=None) -> dict:
    """Bake scene with each of methods for seconds (settings: the rest of the bake's settings;
    its spp is the samples per batch times its batches, as the time rule takes it) and set the
    bakes side by side (see the module's notes). progress(i, method) is called before each;
    bake_progress(fraction, message) as the bakes go (the fraction of the whole comparison);
    cancel() returning True stops the bake under way (BakeCancelled, as bake).

    Returns {"region_pixels", "region_from", "seconds", "rows": [one dict per method, in the
    order given], "results": {method: BakeResult}}, and "nothing_to_bake" (why) for a scene
    with no caustic (its rows empty)."""
    if not methods:
        raise SceneError("compare: no method to compare")
    if len(set(methods)) != len(methods):
        raise SceneError(f"compare: a method is listed twice ({', '.join(methods)})")
    if reference is not None:  # before any bake, not after all of them
        h, w = layer_shape(scene)
        if reference.luminance.shape != (h, w):
            rh, rw = reference.luminance.shape
            raise SceneError(f"reference '{reference.name}' is {rw} x {rh} pixels, the scene's caustic layer "
                             f"{w} x {h} (camera resolution, its percentage and crop to the render border)")
    results = {}
    for i, m in enumerate(methods):
        if progress is not None:
            progress(i, m)
        s = dataclasses.replace(settings, method=m, time_budget=float(seconds), noise_target=0.0)
        results[m] = bake(scene, s, progress=_one_of(bake_progress, i, m, len(methods)), cancel=cancel)
        why = results[m].stats.get("nothing_to_bake")
        if why:  # the plan is the same for every method
            return {"region_pixels": 0, "region_from": "bakes", "seconds": float(seconds), "rows": [],
                    "results": results, "nothing_to_bake": why}
    shape = next(iter(results.values())).image.shape[:2]
    if reference is not None and reference.luminance.shape != shape:
        h, w = reference.luminance.shape
        raise SceneError(f"reference '{reference.name}' is {w} x {h} pixels, the bakes {shape[1]} x {shape[0]}")
    if reference is not None:
        region, source = convergence.caustic_region(reference.luminance), "reference"
    else:
        mean = sum(r.image.astype(np.float64).mean(axis=2) for r in results.values()) / len(results)
        region, source = convergence.caustic_region(mean), "bakes"
    rows = []
    for m, r in results.items():
        st = r.stats
        err = convergence.relative_error(r.batch_luminance, region) if region.any() else 0.0
        # the bake's own time: a first bake's compiling (compile_s) is paid once, not by the method
        row = {"method": m, "time_s": st["time_s"] - st.get("compile_s", 0.0), "compile_s": st.get("compile_s", 0.0),
               "batches": st.get("batches_done", 0),
               "spp": st.get("batches_done", 0) * settings.spp / settings.batches,
               "rays": st["rays"], "success_rate": st.get("success_rate"),
               "error": err if math.isfinite(err) else None,
               "seconds_to_halve_error": st.get("seconds_to_halve_error"),
               "leaves_out": list(st.get("error_leaves_out", [])), "heavy_tail": bool(st.get("convergence", {}).get("heavy_tail"))}
        if reference is not None and region.any():
            lum = r.image.astype(np.float64).mean(axis=2)
            mean, se = r.region_mean(region)
            ref_mean = float(reference.luminance[region].mean())
            row["rmse"] = _rmse(lum, reference, region)
            row["ratio"] = mean / ref_mean if ref_mean > 0 else None
            row["ratio_se"] = se / ref_mean if ref_mean > 0 and math.isfinite(se) else None
        rows.append(row)
    cost = {row["method"]: row["error"] ** 2 * row["time_s"] for row in rows
            if row["error"] is not None and not row["leaves_out"]}
    best = min(cost.values(), default=0.0)
    for row in rows:
        c = cost.get(row["method"])
        row["time_for_same_error"] = c / best if c is not None and best > 0 else None
    return {"region_pixels": int(region.sum()), "region_from": source, "seconds": float(seconds),
            "rows": rows, "results": results}


def _one_of(progress, i, method, n):
    """Bake i of n's progress(fraction, message) as progress of the whole comparison."""
    if progress is None:
        return None

    def step(fraction, message=""):
        progress((i + min(max(float(fraction), 0.0), 1.0)) / n,
                 f"{method} ({i + 1} of {n})" + (f": {message}" if message else ""))
    return step


def _pct(x) -> str:
    return "" if x is None else f"{x:.1%}"


def table_lines(report: dict) -> list[str]:
    """The comparison as a markdown table, and what it means, in words."""
    if report.get("nothing_to_bake"):
        return [f"nothing to bake: {report['nothing_to_bake']}"]
    rows = report["rows"]
    judged = any("rmse" in r for r in rows)
    head = ["method", "wall s", "spp", "rays", "success", "error (noise)", "time for same error"]
    if judged:
        head += ["RMSE vs reference", "mean / reference"]
    out = [f"equal time: {report['seconds']:g} s per method, measured over {report['region_pixels']} caustic pixels "
           f"(the region of the {report['region_from']})", "",
           "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        same = f"{r['time_for_same_error']:.2f}x" if r["time_for_same_error"] is not None else (
            "biased: " + "; ".join(x.split(" (")[0] for x in r["leaves_out"]) if r["leaves_out"] else "")
        cells = [r["method"], f"{r['time_s']:.1f}", f"{r['spp']:g}", f"{r['rays']:,}", _pct(r["success_rate"]),
                 "" if r["error"] is None else f"+-{r['error']:.1%}" + (" (heavy tail)" if r["heavy_tail"] else ""),
                 same]
        if judged:
            ratio = "" if r.get("ratio") is None else f"{r['ratio']:.3f}" + (
                f" +- {r['ratio_se']:.3f}" if r.get("ratio_se") is not None else "")
            cells += ["" if r.get("rmse") is None else f"{r['rmse']:.1%}", ratio]
        out.append("| " + " | ".join(cells) + " |")
    fast = [r for r in rows if r["time_for_same_error"] is not None]
    if len(fast) >= 2:
        best = min(fast, key=lambda r: r["time_for_same_error"])
        nxt = sorted(r["time_for_same_error"] for r in fast)[1]
        out += ["", f"fastest to a given noise: {best['method']} ({nxt:.2f}x less time than the next)"]
    if any(r["heavy_tail"] for r in rows):
        out.append("heavy tail: rare bright paths were still turning up; that method's error is optimistic")
    for r in rows:
        if r.get("compile_s"):
            out.append(f"{r['method']} also compiled kernels for {r['compile_s']:.1f} s (the first bake after "
                       f"installing or updating), left out of its time and of its budget")
    return out


def json_report(report: dict) -> dict:
    """The report without the bakes' images (for a JSON file)."""
    return {k: v for k, v in report.items() if k != "results"}
