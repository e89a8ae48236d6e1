"""What a bake returns: the layer, its variance and error bar, and the statistics.

finish() turns a job's film and counters into a BakeResult: the image and variance (float32),
the batches' luminance images, the error bar and what halving it would cost (convergence.py), and
the statistics every front end prints (plan words, per-light walks, rays, time).
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from ..core.errors import SceneError
from ..core.vec import channel_mean
from . import convergence
from .settings import BakeSettings

F32_MAX = float(np.finfo(np.float32).max)


@dataclass
class BakeResult:
    image: np.ndarray  # (H,W,3) float32, top row first
    variance: np.ndarray  # (H,W,3) float32, variance of the image estimate
    stats: dict = field(default_factory=dict)
    batch_luminance: np.ndarray | None = None  # (B,H,W) float32, one image per independent group: a batch, or a
    # replicate of batches (stratified eye samples: film.Film.use_replicates)
    # (or per group of equal batches, film.MAX_GROUPS at most)
    std: np.ndarray | None = None  # (H,W) float32, standard deviation of each pixel's mean luminance
    # Receivers whose colour is a texture (Scene.mat_textured), where the camera sees them
    # directly: Cycles' Diffuse Color pass has their albedo, the bake assumed a constant one.
    # textured: the part of image that fell there; per_albedo: the same divided by the albedo the
    # bake assumed (sample by sample). The layer to add over a render is layer() + per_albedo x
    # the render's Diffuse Color pass. Both None where the scene has no textured receiver.
    textured: np.ndarray | None = None  # (H,W,3) float32
    per_albedo: np.ndarray | None = None  # (H,W,3) float32

    def layer(self) -> np.ndarray:
        """What is added over a render as it is: image, less its textured part (if any), which
        per_albedo x the render's Diffuse Color pass replaces."""
        return self.image if self.textured is None else self.image - self.textured

    def region_mean(self, region: np.ndarray) -> tuple[float, float]:
        """Mean luminance over a pixel mask and its standard error, from the spread
        of the independent batches' region means (honest whatever the sampling)."""
        return region_mean_error(self.batch_luminance, region)


def region_mean_error(batch_luminance, region) -> tuple[float, float]:
    means = np.array([b[region].mean() for b in batch_luminance], dtype=float)
    b = len(means)
    se = float(means.std(ddof=1) / math.sqrt(b)) if b > 1 else float("inf")
    return float(means.mean()), se


def caustic_region(image: np.ndarray, frac: float = 0.05) -> np.ndarray:
    """Pixels where the caustic is clearly non-zero: luminance above frac of its 99.5th percentile."""
    return convergence.caustic_region(channel_mean(image), frac)


def noise_summary(image: np.ndarray, variance: np.ndarray, batch_luminance=None, region=None) -> dict:
    """The noise over the caustic region (caustic_region(image) unless the caller has it)."""
    region = caustic_region(image) if region is None else region
    if not region.any():
        return {"region_pixels": 0, "mean": 0.0, "std_error_of_mean": 0.0, "relative_noise": 0.0,
                "pixel_rms_noise": 0.0}
    lum = channel_mean(image)[region]
    var = channel_mean(variance)[region]  # variance of the channel mean (conservative: /3 ignored)
    mean = float(lum.mean())
    se = region_mean_error(batch_luminance, region)[1] if batch_luminance is not None else float("nan")
    return {
        "region_pixels": int(region.sum()),
        "mean": mean,
        # from the spread of the batches' region means: pixels are correlated by the filter
        # and by stratification, so the per-pixel variances cannot simply be summed
        "std_error_of_mean": se if math.isfinite(se) else 0.0,
        "pixel_rms_noise": float(math.sqrt(var.mean())),
        "relative_noise": float(math.sqrt(var.mean()) / mean) if mean > 0 else 0.0,
    }


def bias_left_out(settings: BakeSettings, light_stats: dict) -> list[str]:
    """What makes this bake's mean differ from the truth beyond its noise, which the error bar
    (relative_error, from the spread between batches) cannot see: short phrases, none for an
    unbiased bake. The share of the layer a cap cost is at least what it reports."""
    out = []
    if settings.method == "mnee":
        out.append("MNEE's bias (one walk per point, no Bernoulli weights)")
    elif settings.method != "reference" and settings.estimator == "biased":
        out.append(f"the biased estimator's bias ({settings.trials} walks per point)")
    for name, st in light_stats.items():
        if "anchor_only_bound" in st:
            out.append(f"the bias of {name}'s straight-line walk alone, MNEE's way (auto: its pilot bounds the "
                       f"other solutions' light below {st['anchor_only_bound']:.2%} of the light's caustic)")
    if any(st.get("clamped", 0) > 0 for st in light_stats.values()):
        out.append(f"the clamp's bias (clamp_g {settings.clamp_g:g})")
    capped = sum(st.get("trials", {}).get("capped_share_min", 0.0) for st in light_stats.values())
    if any(st.get("trials", {}).get("capped", 0) > 0 for st in light_stats.values()):
        out.append(f"the Bernoulli trials' cap (at least {capped:.1%} of the layer)")
    return out


def finite_or_none(x: float):
    return float(x) if math.isfinite(x) else None  # JSON has no infinity


def plan_stats(plan) -> dict:
    return {"words": plan.words(), "notes": list(plan.notes), "seen": dict(plan.seen),
            "dropped": dict(plan.dropped), **plan.cost}


def nothing_to_bake(scene, settings, plan, cam, t0, on_plan) -> BakeResult:
    """A scene with no caustic to bake: an all-zero layer and the plan saying why."""
    if on_plan is not None:
        on_plan(plan.words())
    x0, x1, y0, y1 = cam.region
    H, W = cam.H, cam.W
    if scene.camera.use_border and scene.camera.use_crop_to_border:
        H, W = max(0, y1 - y0), max(0, x1 - x0)
    zero = np.zeros((H, W, 3), np.float32)
    stats = {
        "method": settings.method, "settings": asdict(settings), "scene": scene.name, "resolution": [W, H],
        "time_s": time.perf_counter() - t0, "rays": int(plan.cost.get("rays", 0)), "lights": {},
        "batches_done": 0, "plan": plan_stats(plan),
        "skipped": [{"kind": k, "name": n, "reason": r} for k, n, r in plan.skipped],
        "noise": noise_summary(zero, zero), "relative_error": 0.0, "seconds_to_halve_error": 0.0,
        "stopped_by": "nothing_to_bake", "nothing_to_bake": plan.nothing,
    }
    return BakeResult(image=zero, variance=zero.copy(), stats=stats,
                      batch_luminance=np.zeros((1, H, W), np.float32), std=np.zeros((H, W), np.float32))


def finish(job, batches, stop, t_first, rays) -> BakeResult:
    """The job's film and counters as a BakeResult: (batches done, the stop rule, seconds before
    the first batch, rays cast by the passes), the rest from the job."""
    scene, settings, plan, film = job.scene, job.settings, job.plan, job.film
    extra = job.extra
    if job.indirect_stats:
        extra["indirect"] = job.indirect_stats
        rays += sum(st["rays_photon"] + st["rays_camera"] for st in job.indirect_stats.values())
    rays += extra.get("auto", {}).get("rays", 0)  # the pilot's bakes: the bake's time counts them too
    # batch_lum: the batches in time (the convergence fit); groups: the independent ones the error bar
    # reads, the batches themselves or their replicates (film.Film.use_replicates)
    image, variance, batch_lum, groups = _film_images(job)
    region = caustic_region(image)
    conv = convergence.convergence(batch_lum, np.array(film.batch_end), t_first, region,
                                   film.group_size * len(batch_lum))
    std = convergence.pixel_std(groups)
    layer = float(channel_mean(image).sum())
    for st in job.light_stats.values():  # the trial cap's bias, at least, as a share of the layer
        if "trials" in st:
            st["trials"]["capped_share_min"] = st["trials"]["capped_energy_min"] / layer if layer > 0 else 0.0
    stats = {
        "method": settings.method,
        "settings": asdict(settings),
        "scene": scene.name,
        "resolution": [int(image.shape[1]), int(image.shape[0])],
        "time_s": job.seconds(),
        "rays": int(rays),
        "lights": job.light_stats,
        **extra,
        "skipped": [{"kind": k, "name": n, "reason": r} for k, n, r in plan.skipped],
        "plan": plan_stats(plan),
        "nothing_to_bake": None,
        "noise": noise_summary(image, variance, groups, region),
        # an error bar and a price (convergence.py): noise only, a biased estimator's bias is not in it
        "relative_error": finite_or_none(convergence.relative_error(groups, region)),
        "error_leaves_out": bias_left_out(settings, job.light_stats),
        "seconds_to_halve_error": conv["seconds_to_halve_error"],
        "convergence": {**conv, "setup_s": t_first, "last_batch_end_s": film.batch_end[-1] if film.batch_end else 0.0,
                        "batches_kept": int(len(batch_lum)),
                        "batches_per_kept": film.group_size, "replicates": int(film.replicates)},
        "stopped_by": stop.reason,
    }
    if stop.reason == "signal":  # a bake with keep_partial stopped by a signal: the batches done
        stats["signal"] = stop.signal
    textured, per_albedo = film.textured_parts()
    if textured is not None:
        stats["textured_share"] = float(channel_mean(textured).sum()) / layer if layer > 0 else 0.0
        textured, per_albedo = textured.astype(np.float32), per_albedo.astype(np.float32)
    return BakeResult(image=image.astype(np.float32), variance=variance.astype(np.float32), stats=stats,
                      batch_luminance=groups, std=std, textured=textured, per_albedo=per_albedo)


def _film_images(job):
    """The film's image, variance and batches' luminance, checked and cropped to the border."""
    scene, film = job.scene, job.film
    image = film.image
    variance = film.variance
    if not (np.all(np.isfinite(image)) and np.all(np.isfinite(variance))):
        raise FloatingPointError("non-finite value in the caustic buffer")  # a bug, never user input
    top = float(image.max()) if image.size else 0.0
    if top > F32_MAX:  # Scene.validate bounds powers and colours; a focus can still concentrate them
        bright = scene.light_names[int(np.argmax(scene.light_color.max(axis=1)))] if scene.n_lights else "?"
        raise SceneError(f"scene '{scene.name}': the caustic layer's brightest pixel ({top:.3g}) is beyond what a "
                         f"float32 image holds; lower the lights' power (the brightest: '{bright}')")
    variance = np.minimum(variance, F32_MAX)  # its square can overflow where the image does not
    batch_lum = np.stack(film.batch_luminance)
    groups = batch_lum if not film.replicates else np.stack(film.error_luminance)
    if scene.camera.use_border and scene.camera.use_crop_to_border:
        x0, x1, y0, y1 = job.cam.region
        image = image[y0:y1, x0:x1]
        variance = variance[y0:y1, x0:x1]
        batch_lum = batch_lum[:, y0:y1, x0:x1]
        groups = groups[:, y0:y1, x0:x1]
    return image, variance, batch_lum, groups


def complete_layer(result: BakeResult, albedo) -> tuple[np.ndarray, np.ndarray | None]:
    """(R, G, B, std) of the whole caustic: layer() + per_albedo x albedo, albedo (H,W,3) Cycles'
    Diffuse Color pass (the one the add-on's compositor multiplies per_albedo by), so that the EXR
    stands on its own; the std scaled by the luminance the albedo gives each pixel over the one the
    bake assumed (exact where a pixel's caustic lies wholly on textured receivers, as the film keeps no
    batch of the textured part apart). (layer(), std) where there is no albedo or no textured part."""
    if result.per_albedo is None or albedo is None:
        return result.layer(), result.std
    rgb = (result.layer().astype(np.float64) + result.per_albedo * np.asarray(albedo, np.float64)).astype(np.float32)
    std = result.std
    if std is not None:
        was, now = channel_mean(result.image.astype(np.float64)), channel_mean(rgb.astype(np.float64))
        scale = np.divide(now, was, out=np.ones_like(was), where=was > 0)
        std = (std * scale).astype(np.float32)
    return rgb, std
