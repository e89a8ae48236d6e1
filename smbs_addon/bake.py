"""The bake: plan the scene, run the caustic pass per light, gather statistics.

Data flows one way: Scene -> plan -> per light (batches x chunks of lanes) ->
film -> image + noise estimate + statistics. Randomness is keyed by
(seed, light, batch, chunk), so one seed gives the same image bit for bit,
whatever the thread count.
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from . import reference
from .camera import CameraModel
from .errors import BakeCancelled, SceneError
from .film import Film
from .lights import emit
from .plan import make_plan
from .tracer import Tracer

METHODS = ("reference",)
CHUNK = 65536  # lanes per chunk (keeps temporaries in cache, see performance-anchors.md)


@dataclass
class BakeSettings:
    method: str = "reference"
    spp: int = 16  # light paths per pixel and light (reference)
    seed: int = 0
    batches: int = 8  # independent batches for the noise estimate
    threads: int = 0  # 0: all cores
    use_cycles_flags: str = "AUTO"  # AUTO, ON, OFF

    def validate(self) -> None:
        if self.method not in METHODS:
            raise SceneError(f"unknown method '{self.method}' (choose from {', '.join(METHODS)})")
        if not (isinstance(self.spp, int) and self.spp >= 1):
            raise SceneError(f"spp must be a positive whole number, not {self.spp!r}")
        if not (isinstance(self.batches, int) and self.batches >= 1):
            raise SceneError(f"batches must be a positive whole number, not {self.batches!r}")
        if self.seed < 0:
            raise SceneError(f"seed must not be negative, not {self.seed}")


@dataclass
class BakeResult:
    image: np.ndarray  # (H,W,3) float32, top row first
    variance: np.ndarray  # (H,W,3) float32, variance of the image estimate
    stats: dict = field(default_factory=dict)


def caustic_region(image: np.ndarray, frac: float = 0.05) -> np.ndarray:
    """Pixels where the caustic is clearly non-zero: luminance above frac of its 99.5th percentile."""
    lum = image.mean(axis=2)
    top = np.percentile(lum, 99.5) if lum.size else 0.0
    return lum > frac * top if top > 0 else np.zeros(lum.shape, bool)


def noise_summary(image: np.ndarray, variance: np.ndarray) -> dict:
    region = caustic_region(image)
    if not region.any():
        return {"region_pixels": 0, "mean": 0.0, "std_error_of_mean": 0.0, "relative_noise": 0.0,
                "pixel_rms_noise": 0.0}
    lum = image.mean(axis=2)[region]
    var = variance.mean(axis=2)[region]  # variance of the channel mean (conservative: /3 ignored)
    mean = float(lum.mean())
    return {
        "region_pixels": int(region.sum()),
        "mean": mean,
        "std_error_of_mean": float(math.sqrt(var.sum()) / region.sum()),
        "pixel_rms_noise": float(math.sqrt(var.mean())),
        "relative_noise": float(math.sqrt(var.mean()) / mean) if mean > 0 else 0.0,
    }


def _rng(seed, *key):
    return np.random.default_rng(np.random.SeedSequence([int(seed), *[int(k) for k in key]]))


class _Scaled:
    """A film view that scales every splat (one chunk's share of a batch)."""

    def __init__(self, film, k):
        self.film, self.k = film, k

    def splat(self, rx, ry, rgb):
        self.film.splat(rx, ry, rgb * self.k)


def _specular_visible(scene, tracer, cam) -> bool:
    """Does any pixel see a mirror or glass surface first? (one ray per pixel)"""
    x0, x1, y0, y1 = cam.region
    jj, ii = np.mgrid[y0:y1, x0:x1]
    if jj.size == 0:
        return False
    o, d, tnear = cam.rays(ii.ravel() + 0.5, jj.ravel() + 0.5)
    h = tracer.intersect(o + tnear[:, None] * d, d)
    kind = scene.mat_kind[scene.tri_material[h.prim[h.hit]]]
    from . import scene as S
    return bool(np.any((kind == S.CONDUCTOR) | (kind == S.DIELECTRIC)))


def bake(scene, settings: BakeSettings | None = None, progress=None, cancel=None) -> BakeResult:
    """Bake the caustic layer of a Scene.

    progress(fraction, message) is called between chunks; cancel() returning
    True stops the bake with BakeCancelled (nothing is returned or written)."""
    settings = settings or BakeSettings()
    settings.validate()
    scene.validate()
    t0 = time.perf_counter()
    plan = make_plan(scene, settings.use_cycles_flags)
    cam = CameraModel(scene.camera)
    film = Film(cam.W, cam.H, scene.camera.filter_width, cam.region)
    tracer = Tracer(scene, threads=settings.threads or None)
    x0, x1, y0, y1 = cam.region
    n_pix = max(0, x1 - x0) * max(0, y1 - y0)
    per_light = settings.spp * n_pix
    per_batch = max(1, per_light // settings.batches)
    keys = ("photons", "rays_photon", "rays_camera", "splats", "truncated", "lost_shading_normal")
    light_stats = {lp.name: dict.fromkeys(keys, 0) | {"time_s": 0.0, "casters":
                   [scene.object_names[o] for o in lp.caster_objects]} for lp in plan.lights}
    eye = _specular_visible(scene, tracer, cam)
    eye_stats = dict.fromkeys(("eye_paths", "rays_eye", "eye_splats"), 0) | {"time_s": 0.0, "enabled": eye}
    eye_per_batch = per_light // settings.batches if eye else 0
    light_ids = [lp.index for lp in plan.lights]
    total_chunks = settings.batches * (len(plan.lights) * math.ceil(per_batch / CHUNK)
                                       + math.ceil(eye_per_batch / CHUNK))
    done = 0
    for b in range(settings.batches):
        for lp in plan.lights:
            st = light_stats[lp.name]
            t_light = time.perf_counter()
            for c, start in enumerate(range(0, per_batch, CHUNK)):
                if cancel is not None and cancel():
                    raise BakeCancelled("bake cancelled")
                n = min(CHUNK, per_batch - start)
                rng = _rng(settings.seed, 0, lp.index, b, c)
                ph = emit(scene, lp.index, lp.targets, n, rng)
                ph.w *= n / per_batch  # emit() weights by 1/n; a batch averages per_batch photons
                reference.trace_photons(scene, tracer, cam, film, plan, ph, rng, st)
                done += 1
                if progress is not None:
                    progress(done / total_chunks, f"light '{lp.name}', batch {b + 1}/{settings.batches}")
            st["time_s"] += time.perf_counter() - t_light
        t_eye = time.perf_counter()
        for c, start in enumerate(range(0, eye_per_batch, CHUNK)):
            if cancel is not None and cancel():
                raise BakeCancelled("bake cancelled")
            n = min(CHUNK, eye_per_batch - start)
            reference.trace_eye(scene, tracer, cam, _Scaled(film, n / eye_per_batch), plan, light_ids, n,
                                _rng(settings.seed, 1, 0, b, c), eye_stats)
            done += 1
            if progress is not None:
                progress(done / total_chunks, f"seen through glass and mirrors, batch {b + 1}/{settings.batches}")
        eye_stats["time_s"] += time.perf_counter() - t_eye
        film.end_batch()
    image = film.image
    variance = film.variance
    if not (np.all(np.isfinite(image)) and np.all(np.isfinite(variance))):
        raise FloatingPointError("non-finite value in the caustic buffer")  # a bug, never user input
    if scene.camera.use_border and scene.camera.use_crop_to_border:
        image = image[y0:y1, x0:x1]
        variance = variance[y0:y1, x0:x1]
    elapsed = time.perf_counter() - t0
    rays = sum(s["rays_photon"] + s["rays_camera"] for s in light_stats.values()) + eye_stats["rays_eye"]
    stats = {
        "method": settings.method,
        "settings": asdict(settings),
        "scene": scene.name,
        "resolution": [int(image.shape[1]), int(image.shape[0])],
        "time_s": elapsed,
        "rays": int(rays),
        "lights": light_stats,
        "eye_pass": eye_stats,
        "skipped": [{"kind": k, "name": n, "reason": r} for k, n, r in plan.skipped],
        "noise": noise_summary(image, variance),
    }
    return BakeResult(image=image.astype(np.float32), variance=variance.astype(np.float32), stats=stats)
