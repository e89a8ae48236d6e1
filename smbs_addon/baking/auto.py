"""``--method auto``: give each effect the estimator that suits it.

An effect is a light's caustic on the receivers the camera sees directly, or on
those it sees through mirrors and glass. A short pilot per light (that light
alone, a 40 x 30 copy of the frame, PILOT_BATCHES batches of one sample per pixel)
bakes it with each candidate unbiased estimator -- the light tracer, SMS and SMBS --
and measures, per effect, the variance of the mean image times the rays it cast past
the plan and the photon pre-pass (which a longer bake pays once): the cost of a given
error, in rays rather than seconds so that one seed makes one choice. Each effect
then gets the cheapest (``decide``):

- through mirrors and glass the walks, SMS or SMBS, whichever is cheaper over the
  light's caustic (light tracing reaches the camera there only by its eye pass, whose
  rare bright paths a short pilot underestimates);
- directly seen receivers go to the light tracer (the bake's photon hand-off with
  every chain type of the light, as for the guide's weak chains) when it is
  cheaper there than that walk, else to the walk; a light whose caustic is never
  seen through a mirror or glass is then baked by light tracing alone.

Light tracing at directly seen receivers and walks at receivers seen through
mirrors or glass partition path space (as the concentration hand-off does), so
the sum stays unbiased. When the two share a light, the time is shared between them
by their pilot variances V and costs c per sample (``photon_factor``): the light
tracer gets k = sqrt(V_direct c_walk / (V_through c_photon)) times the walks' samples,
which minimises the summed variance for a given time (Neyman's allocation). What the
pilot measured and what it chose is in the statistics and the plan's words.
"""
from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from ..trace.camera import CameraModel
from ..trace.tracer import Tracer
from . import convergence, engine
from ..scene import arrays as S

PILOT_PIXELS = 40 * 30  # the pilot's frame: the camera's, scaled down to about this many pixels
PILOT_BATCHES = 4  # of one sample per pixel, per candidate and light
CANDIDATES = ("reference", "sms", "smbs")
NAMES = {"reference": "light tracing", "sms": "SMS", "smbs": "SMBS"}
# the range of the light tracer's samples per walk sample: the pilot sees a small region (the view
# through a glass ball: 3 of its pixels) too coarsely to be trusted with more
PHOTON_FACTOR = (0.25, 4.0)
# a time budget under this many seconds per planned light runs no pilot (it takes 1-3 s per
# light, and the time rule counts it): SMBS throughout, the paper's method
PILOT_MIN_BUDGET_PER_LIGHT = 10.0
# auto bakes a light's walks by their anchor alone (the straight-line walk, MNEE's way: one solution per
# sample, weight one) where its pilot bounds the light of the other solutions (the random walks' share
# beside the anchor, plus ANCHOR_SIGMAS standard errors, plus ANCHOR_SIGMAS samples of ANCHOR_STANDIN
# times the anchor's mean light for the solutions the pilot may not have met) below this share of the
# light's caustic: 1%, far under the per-pixel error bar of any bake (issue 61: the pool under a 4-degree
# sun). The stand-in is that large because the other solutions lie near the folds and are bright: there
# the pilot met none, and the full bake measured them at 0.34% +- 0.12% (auto's mean against anchored
# SMBS's, bench/results/pools.md), above a bound of 0.05% with a stand-in of one; with 10 the bound reads 0.6%
ANCHOR_ONLY_BIAS = 0.01
ANCHOR_SIGMAS = 3.0
ANCHOR_STANDIN = 10.0


def pilot_fits(time_budget: float, lights: int) -> bool:
    """Is there time for the pilot? Always without a time budget."""
    return time_budget <= 0 or time_budget >= PILOT_MIN_BUDGET_PER_LIGHT * max(1, lights)


@dataclasses.dataclass
class Choice:
    walk: str  # "sms" or "smbs": the walks' method for this light
    photons_direct: bool  # directly seen receivers: light tracing (the photon hand-off)
    through: bool  # the pilot found caustic pixels seen through mirrors or glass
    alone: bool  # light tracing throughout, its eye pass for the view through mirrors and glass
    measured: dict  # method -> {"direct", "through", "all": costs, "rays": work, "time_s": seconds, ...}
    why: str
    photon_factor: float = 1.0  # photons for the direct receivers per walk sample (photons_direct only)
    rays: int = 0  # every ray this light's pilot cast (its bakes' plans and pre-passes too)
    anchor_only: bool = False  # the walks' anchor alone, MNEE's way (biased; anchor_bias)
    anchor_bound: float | None = None  # the pilot's bound on the light the anchor alone leaves out (share)


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
    h = tracer.camera_intersect(o, d, cam.clip_far(d))
    prim = np.where(h.hit, h.prim, 0)
    ok = h.hit & (scene.mat_kind[scene.tri_material[prim]] == S.DIFFUSE) & plan.receivers[scene.tri_object[prim]]
    mask[jj, ii] = ok
    return mask


def _var(batch_lum, region, n_all: int) -> float:
    """The variance of the mean image summed over region, per pixel of the whole caustic region
    (n_all pixels): the region's share of the image's mean squared error, so that the shares
    of the directly seen and the mirrored parts add up to the whole (0 for an empty region)."""
    if not region.any():
        return 0.0
    if len(batch_lum) < 2:
        return math.inf
    return float(convergence._var_of_mean(batch_lum[:, region]).sum()) / max(n_all, 1)


def _cost(batch_lum, region, work, n_all: int) -> float:
    """_var times the work it took (rays: unlike seconds, the same for one seed, so one seed
    makes one choice); lower is better."""
    return _var(batch_lum, region, n_all) * work


def choose(scene, settings, plan, cancel=None, watch=None) -> dict:
    """{light index: Choice} from a pilot per planned light (see the module's notes): each candidate
    baked whole (engine.bake_fixed) on the pilot's scene; watch: the bake's CompileWatch."""
    out = {}
    for lp in plan.lights:
        sub = _pilot_scene(scene, lp.index)
        cam = CameraModel(sub.camera)
        tracer = Tracer(sub, threads=settings.threads or None)
        tracer.set_extent(*plan.bounds, plan.casters)  # the bake's tolerances: of what takes part
        direct = _direct_pixels(sub, tracer, cam, plan)
        runs, cast, bounds = {}, tracer.rays_cast, {}
        for m in CANDIDATES:
            # a fixed pilot (one sample per pixel a batch), so that one seed makes one choice; the same
            # for every shard of a frame (its streams not keyed by the shard), so that shards bake alike.
            # Independent samples: at one sample per pixel a batch stratifying gains nothing, and the pilot
            # keeps the random numbers its choices were measured with (on pool_hdri, other numbers made
            # it choose SMS over SMBS, whose bake then had 1.2x the error at 40 s)
            s = dataclasses.replace(settings, method=m, spp=PILOT_BATCHES, batches=PILOT_BATCHES, time_budget=0.0,
                                    noise_target=0.0, indirect=False, estimator="unbiased", shard=0, shards=1,
                                    sampling="independent")
            t = time.perf_counter()
            # the casters the bake's plan left out stay out of the pilot's: alone with one light, a far
            # ball too faint beside all the lights' caustic may not be, and its walks would move the choice
            res = engine.bake_fixed(sub, s, cancel, watch, left_out=plan.flag_casters & ~plan.casters)
            st = res.stats  # the work per sample: the rays past the plan, the photon pre-pass and the look
            cast += st["rays"]
            work = (st["rays"] - st["plan"].get("rays", 0) - st.get("guide", {}).get("rays", 0)
                    - st.get("eye_pass", {}).get("rays_visible", 0))  # the light tracer's look, once per bake
            ls = st["lights"].get(lp.name, {})
            seen = ls.get("walks_seen", 0) / ls["walks"] if ls.get("walks") else 0.0
            runs[m] = (res.batch_luminance, max(work, 1), res.image.mean(axis=2), time.perf_counter() - t, seen)
            bounds[m] = anchor_bias(ls)
        lum = sum(r[2] for r in runs.values())
        # pixel by pixel: on the pilot's 40 x 30 frame a 5 x 5 average would spread the caustic
        # seen through a glass ball (3 pixels) onto the receivers seen directly around it; the
        # three candidates share the region, so its pick weighs none of them alone
        region = convergence.caustic_region(lum, blur=False)
        if sub.camera.use_border and sub.camera.use_crop_to_border:
            x0, x1, y0, y1 = cam.region
            direct = direct[y0:y1, x0:x1]
        d_reg, t_reg = region & direct, region & ~direct
        n = int(region.sum())
        measured = {m: {"direct": _cost(b, d_reg, w, n), "through": _cost(b, t_reg, w, n),
                        "all": _cost(b, region, w, n), "var_direct": _var(b, d_reg, n),
                        "var_through": _var(b, t_reg, n), "walks_seen_share": seen,
                        "rays": w, "time_s": t} for m, (b, w, _, t, seen) in runs.items()}
        walk, photons, alone, why = decide(measured, bool(d_reg.any()), bool(t_reg.any()), bool(region.any()))
        k = 1.0
        if photons and not alone:
            k = photon_factor(measured, walk)
            if k != 1.0:
                why = why.replace("light tracing for receivers seen directly (",
                                  f"light tracing for receivers seen directly ({k:g}x the samples; ", 1)
        out[lp.index] = _anchor_choice(Choice(walk, photons, bool(t_reg.any()), alone, measured, why, k, cast),
                                       bounds[walk])
    return out


def anchor_bias(light_stats: dict) -> float | None:
    """The pilot's bound on the share of a light's caustic that the anchor alone would leave out: the
    random walks' light beside the anchor (their other solutions, estimators._unbiased_sum) over the
    whole, plus ANCHOR_SIGMAS standard errors of that sum over the anchored samples (each sample's
    other-solution light an independent draw, most of them 0), plus ANCHOR_SIGMAS samples' worth of
    ANCHOR_STANDIN times the anchor's mean light (where the pilot met few or no other solutions their
    spread says little: the rule of three, with other solutions as bright as the folds they lie at);
    None where nothing was anchored."""
    n, a = light_stats.get("anchor_walks", 0), light_stats.get("anchor_energy", 0.0)
    s, q = light_stats.get("walk_energy", 0.0), light_stats.get("walk_energy_sq", 0.0)
    if n < 2 or a + s <= 0:
        return None
    se = math.sqrt(max(q - s * s / n, 0.0))
    return (max(s, 0.0) + ANCHOR_SIGMAS * (se + ANCHOR_STANDIN * a / n)) / (a + s)


def _anchor_choice(c: Choice, bound: float | None) -> Choice:
    """c with the anchor alone where the pilot's bound on what it leaves out is under ANCHOR_ONLY_BIAS
    and the walks bake the light somewhere; the why says so, with the bound."""
    if bound is None or c.alone:
        return c
    c.anchor_bound = bound
    if bound < ANCHOR_ONLY_BIAS:
        c.anchor_only = True
        c.why += (f"; its straight-line walk alone, MNEE's way (biased: the pilot bounds the other solutions' "
                  f"light below {bound:.2%} of this light's caustic)")
    return c


def photon_factor(measured: dict, walk: str) -> float:
    """The light tracer's samples per walk sample where it serves the directly seen receivers
    and the walks those seen through mirrors and glass: sqrt(V_d c_w / (V_w c_d)) (Neyman's
    allocation: the summed variance V_d / k + V_w for the time c_w + k c_d is least there), V
    the pilot's variances of the mean summed over each region (each region's share of the
    image's error, so a region of many pixels weighs more), c the rays per sample (the walks' own
    share of rays: their walks from receivers seen through mirrors and glass), in
    PHOTON_FACTOR's range and to two digits."""
    ref, wk = measured["reference"], measured[walk]
    v_d, c_d = ref["var_direct"], ref["rays"]
    v_w, c_w = wk["var_through"], wk["rays"] * wk.get("walks_seen_share", 1.0)
    lo, hi = PHOTON_FACTOR
    if not (v_d > 0 and c_d > 0) or not math.isfinite(v_d):
        return 1.0
    if not (v_w > 0 and c_w > 0):
        return hi
    return min(hi, max(lo, float(f"{math.sqrt(v_d * c_w / (v_w * c_d)):.2g}")))


def decide(measured: dict, has_direct: bool, has_through: bool, has_caustic: bool = True):
    """(walk method, light tracing for the direct receivers?, light tracing everywhere?, why)
    from the pilot's costs (measured[method] = {"direct", "through", "all"}: variance x
    rays, lower is better). Three ways to share the work: the walks everywhere; light
    tracing at the receivers seen directly and the walks through mirrors and glass; light
    tracing alone, only where no caustic is seen through mirrors or glass. The cheapest
    sum of the two regions' costs wins."""
    if not has_caustic:
        return "smbs", False, False, "the pilot found no caustic; walks as SMBS"
    walk = min(("sms", "smbs"), key=lambda m: (measured[m]["all"], m != "smbs"))
    ref, wk = measured["reference"], measured[walk]
    costs = {"walks": wk["direct"] + wk["through"],
             "mixed": ref["direct"] + wk["through"] if has_direct else math.inf,
             # the light tracer's eye pass through mirrors and glass: rare bright paths, whose
             # variance a short pilot underestimates (the wavy mirror: 10x the walks' error)
             "photons": ref["direct"] if not has_through else math.inf}
    way = min(costs, key=lambda k: (costs[k], ("walks", "photons", "mixed").index(k)))
    other = "smbs" if walk == "sms" else "sms"
    if way == "photons":
        return walk, has_direct, True, ("light tracing throughout (" + _ratio(costs["walks"], costs["photons"])
                                  + f" cheaper than {NAMES[walk]})")
    if way == "mixed":
        return walk, True, False, (f"light tracing for receivers seen directly ({_ratio(wk['direct'], ref['direct'])} "
                                   f"cheaper than {NAMES[walk]})"
                                   + (f"; {NAMES[walk]} through mirrors and glass" if has_through else ""))
    return walk, False, False, (f"{NAMES[walk]} ({_ratio(measured[other]['all'], wk['all'])} cheaper than "
                                f"{NAMES[other]}" + (f", {_ratio(costs['mixed'], costs['walks'])} cheaper than "
                                                     "light tracing where seen directly" if has_direct else "") + ")")


def _ratio(a, b) -> str:
    if not (b > 0) or not math.isfinite(a):
        return "far"
    return f"{a / b:.1f}x"
