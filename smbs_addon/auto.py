"""``--method auto``: give each effect the estimator that suits it.

An effect is a light's caustic on the receivers the camera sees directly, or on
those it sees through mirrors and glass. A short pilot per light (that light
alone, a small copy of the frame, a few batches) bakes it with each candidate
unbiased estimator -- the light tracer, SMS and SMBS -- and measures, per effect,
the variance of the mean image times the time it took: the cost of a given
error. Each effect then gets the cheapest:

- through mirrors and glass only the walks can connect (the light tracer cannot
  reach the camera through a delta BSDF), so it is SMS or SMBS, whichever is
  cheaper over the light's caustic;
- directly seen receivers go to the light tracer (the bake's photon hand-off with
  every chain type of the light, as for the guide's weak chains) when it is
  cheaper there than that walk, else to the walk.

Light tracing at directly seen receivers and walks at receivers seen through
mirrors or glass partition path space (as the concentration hand-off does), so
the sum stays unbiased. Every effect is baked with the same samples per pixel;
what the pilot measured and what it chose is in the statistics and the plan's words.
"""
from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from . import convergence
from . import scene as S

PILOT_PIXELS = 40 * 30  # the pilot's frame: the camera's, scaled down to about this many pixels
PILOT_SECONDS = 1.0  # per candidate and light, unless the bake's time budget asks for less
PILOT_SHARE = 0.1  # of a bake's time budget, at most, for all the pilots
CANDIDATES = ("reference", "sms", "smbs")
NAMES = {"reference": "light tracing", "sms": "SMS", "smbs": "SMBS"}


@dataclasses.dataclass
class Choice:
    walk: str  # "sms" or "smbs": the walks' method for this light
    photons_direct: bool  # directly seen receivers: light tracing (the photon hand-off)
    through: bool  # the pilot found caustic pixels seen through mirrors or glass
    measured: dict  # method -> {"direct": cost, "through": cost, "all": cost, "time_s": s}
    why: str


def _pilot_scene(scene, li):
    """The scene with only light li powered and a frame of about PILOT_PIXELS pixels."""
    color = np.zeros_like(scene.light_color)
    color[li] = scene.light_color[li]
    cam = scene.camera
    pct = cam.resolution_percentage * min(1.0, math.sqrt(PILOT_PIXELS / max(1, cam.width * cam.height)))
    small = dataclasses.replace(cam, resolution_percentage=max(1, int(pct)))
    return dataclasses.replace(scene, light_color=color, camera=small)


def _direct_pixels(scene, tracer, cam, plan) -> np.ndarray:
    """(H,W) bool: pixels whose camera ray meets a receiver first (a diffuse surface)."""
    mask = np.zeros((cam.H, cam.W), bool)
    jj, ii, o, d = cam.pixel_rays()
    if jj.size == 0:
        return mask
    h = tracer.intersect(o, d)
    prim = np.where(h.hit, h.prim, 0)
    ok = h.hit & (scene.mat_kind[scene.tri_material[prim]] == S.DIFFUSE) & plan.receivers[scene.tri_object[prim]]
    mask[jj, ii] = ok
    return mask


def _cost(batch_lum, region, seconds) -> float:
    """Variance of the mean image over region, times the seconds it took (lower is better);
    inf where there is no spread to measure."""
    if not region.any():
        return 0.0
    if len(batch_lum) < 2:
        return math.inf
    return float(convergence._var_of_mean(batch_lum[:, region]).mean()) * seconds


def choose(scene, settings, plan, cancel=None) -> dict:
    """{light index: Choice} from a pilot per planned light (see the module's notes)."""
    from .bake import BakeSettings, bake
    from .camera import CameraModel
    from .tracer import Tracer

    out = {}
    seconds = PILOT_SECONDS
    if settings.time_budget > 0:
        seconds = min(seconds, PILOT_SHARE * settings.time_budget / max(1, len(plan.lights) * len(CANDIDATES)))
    for lp in plan.lights:
        sub = _pilot_scene(scene, lp.index)
        cam = CameraModel(sub.camera)
        direct = _direct_pixels(sub, Tracer(sub, threads=settings.threads or None), cam, plan)
        runs = {}
        for m in CANDIDATES:
            # one sample per pixel a batch, batches until the seconds are spent (at least two)
            s = dataclasses.replace(settings, method=m, spp=1, batches=1, time_budget=seconds,
                                    noise_target=0.0, indirect=False, estimator="unbiased")
            t = time.perf_counter()
            res = bake(sub, s, cancel=cancel)
            runs[m] = (res.batch_luminance, time.perf_counter() - t, res.image.mean(axis=2))
        lum = sum(r[2] for r in runs.values())
        region = convergence.caustic_region(lum)
        if sub.camera.use_border and sub.camera.use_crop_to_border:
            x0, x1, y0, y1 = cam.region
            direct = direct[y0:y1, x0:x1]
        d_reg, t_reg = region & direct, region & ~direct
        measured = {m: {"direct": _cost(b, d_reg, t), "through": _cost(b, t_reg, t), "all": _cost(b, region, t),
                        "time_s": t} for m, (b, t, _) in runs.items()}
        walk, photons, why = decide(measured, bool(d_reg.any()), bool(t_reg.any()), bool(region.any()))
        out[lp.index] = Choice(walk, photons, bool(t_reg.any()), measured, why)
    return out


def decide(measured: dict, has_direct: bool, has_through: bool, has_caustic: bool = True):
    """(walk method, light tracing for the direct receivers?, why) from the pilot's costs
    (measured[method] = {"direct", "through", "all"}: variance x seconds, lower is better)."""
    if not has_caustic:
        return "smbs", False, "the pilot found no caustic; walks as SMBS"
    walk = min(("sms", "smbs"), key=lambda m: (measured[m]["all"], m != "smbs"))
    lt, wk = measured["reference"]["direct"], measured[walk]["direct"]
    if has_direct and lt < wk:
        return walk, True, (f"light tracing for receivers seen directly ({_ratio(wk, lt)} cheaper than "
                            f"{NAMES[walk]})" + (f"; {NAMES[walk]} through mirrors and glass" if has_through else ""))
    other = "smbs" if walk == "sms" else "sms"
    return walk, False, (f"{NAMES[walk]} ({_ratio(measured[other]['all'], measured[walk]['all'])} cheaper than "
                         f"{NAMES[other]}" + (f", {_ratio(lt, wk)} cheaper than light tracing where seen directly"
                                              if has_direct else "") + ")")


def _ratio(a, b) -> str:
    if not (b > 0) or not math.isfinite(a):
        return "far"
    return f"{a / b:.1f}x"
