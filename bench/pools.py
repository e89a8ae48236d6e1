"""Issue 61's pools at equal time: our bakes against Cycles' MNEE, path guiding and path tracing.

    python bench/pools.py timed  --scene pool_sun --variant auto --budgets 10,40      # what --time gets
    python bench/pools.py artist --scene pool_sun                                     # 1920 x 1080 to 10%
    python bench/pools.py ours   --scene pool_sun --variant anchor --spp 256 --batches 32
    python bench/pools.py cycles --scene pool_sun --kind mnee --spp 128,512,1024
    python bench/pools.py reference --scene pool_sun --spp 2048 --batches 64
    python bench/pools.py table [--scenes pool_sun,pool_hdri] [--clock wall|cpu]

Time is wall-clock seconds on the machine's 2 cores when it is quiet (``--clock wall``, the default),
or CPU seconds (``--clock cpu``: both threads; what the first measurements used while the machine was
shared with other jobs; see bench/results/pools.md on why those misled). Each run stores its images
with their seconds in bench/results/pools/: ``timed``, one image per budget, a real ``--time`` bake;
``ours``, the batch images of one bake of fixed spp, the mean of the first k batches an image at k/B
of its time (only for independent batches: a stratified bake's replicates are not shorter bakes);
Cycles, a caustic image per sample count, "on" less an "off" render of the same seed and samples
(only the "on" render's time counted). ``table`` interpolates each method's relative RMSE per pixel
(over the reference's caustic region, the reference's own per-pixel noise taken out) at 10, 40 and
120 s, log-log between measured points, 1/sqrt(t) beyond them, and writes bench/results/pools.md's
table part.

The per-pixel reference is a long unbiased bake of ours (``reference``: its batch spread is its own
noise); its mean is checked against Cycles' path-traced reference (tests/data/conformance/NAME.npz).
"""
from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from testkit import ROOT

OUT = ROOT / "bench" / "results" / "pools"
VARIANTS = {
    "auto": {},  # the default
    "auto-independent": dict(sampling="independent"),  # the default with independent eye and light samples
    "smbs": dict(method="smbs", anchor=False),  # SMBS before issue 61
    "anchor": dict(method="smbs", anchor=True),  # SMBS now
    "anchor-half": dict(method="smbs", anchor=True, anchor_walks=0.5),
    "anchor-quarter": dict(method="smbs", anchor=True, anchor_walks=0.25),
    "mnee": dict(method="mnee"),
}
BUDGETS = (10.0, 40.0, 120.0)  # seconds on 2 cores
# fixed CPU seconds of runs made before run_ours recorded them: pool_sun's auto, from an 8-spp bake (8.1 s,
# bench/pool_profile.py) and its 128-spp run (20.2 s): 0.10 s per spp, 7.3 s of pilot, plan and pre-pass
FIXED = {("pool_sun", "auto"): 7.3}
CORES = 2


def run_ours(scene_name, variant, spp, batches, seed=0, tag=None):
    from smbs_addon import BakeSettings, bake
    from testkit.conformance import scene_arrays

    scene = scene_arrays(scene_name)
    s = BakeSettings(spp=spp, batches=batches, threads=CORES, seed=seed, **VARIANTS[variant])
    c0, t0 = time.process_time(), time.perf_counter()
    bake(scene, BakeSettings(spp=1, batches=1, threads=CORES, **VARIANTS[variant]))  # compiled, warm
    c0, t0 = time.process_time(), time.perf_counter()
    bake(scene, BakeSettings(spp=1, batches=1, threads=CORES, **VARIANTS[variant]))
    # a bake of one sample, compiled: its fixed work (auto's pilot, plan, pre-pass) and one sample
    fixed, fixed_wall = time.process_time() - c0, time.perf_counter() - t0
    c0, t0 = time.process_time(), time.perf_counter()
    res = bake(scene, s)
    cpu, wall = time.process_time() - c0, time.perf_counter() - t0
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / f"{scene_name}_{tag or variant}.npz"
    lights = res.stats.get("lights", {})
    np.savez_compressed(path, batches=np.asarray(res.batch_luminance, np.float32), cpu=cpu, wall=wall, fixed=fixed,
                        fixed_wall=fixed_wall,
                        meta=json.dumps({"variant": variant, "settings": VARIANTS[variant], "spp": spp,
                                         "batches": batches, "seed": seed, "plan": res.stats.get("plan", {}).get("words"),
                                         "relative_error": res.stats.get("relative_error"),
                                         "lights": {k: {kk: v.get(kk) for kk in (
                                             "walks", "successes", "anchor_walks", "anchor_successes",
                                             "anchor_found_again", "bernoulli_lanes", "bernoulli_trials")}
                                             for k, v in lights.items()}}, default=str))
    print(f"{scene_name} {variant}: cpu {cpu:.1f} s, wall {wall:.1f} s, error bar {res.stats.get('relative_error')}",
          flush=True)
    return path


def run_ours_timed(scene_name, variant, budgets, seed=0):
    """Our bake of scene_name by variant at each wall-clock budget (BakeSettings.time_budget, the
    default spp and batches otherwise), stored as Cycles' runs are: an image per budget with its CPU
    and wall seconds. What a user's ``--time`` gets: a stratified bake's batches past the first round
    continue their replicates' sequences (film.Film.use_replicates), so the mean of its first batches
    is not a shorter bake of its own and one run cannot stand for several budgets."""
    from smbs_addon import BakeSettings, bake
    from testkit.conformance import scene_arrays

    scene = scene_arrays(scene_name)
    bake(scene, BakeSettings(spp=1, batches=1, threads=CORES, **VARIANTS[variant]))  # compiled, warm
    rows = []
    for t in budgets:
        s = BakeSettings(time_budget=float(t), threads=CORES, seed=seed, **VARIANTS[variant])
        c0, t0 = time.process_time(), time.perf_counter()
        res = bake(scene, s)
        cpu, wall = time.process_time() - c0, time.perf_counter() - t0
        rows.append((cpu, wall, res.image.mean(axis=2), res.stats.get("relative_error"), res.stats["batches_done"]))
        print(f"{scene_name} {variant} --time {t}: cpu {cpu:.1f} s, wall {wall:.1f} s, error bar "
              f"{res.stats.get('relative_error')}, batches {res.stats['batches_done']}", flush=True)
    OUT.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(OUT / f"{scene_name}_{variant}_timed.npz", cpu=np.array([r[0] for r in rows]),
                        wall=np.array([r[1] for r in rows]), images=np.stack([r[2] for r in rows]).astype(np.float32),
                        error_bar=np.array([r[3] for r in rows], float), batches=np.array([r[4] for r in rows]))


def run_artist(scene_name, cap=600.0):
    """The artist's test: scene_name at 1920 x 1080 to 10% relative error per pixel (the default bake,
    noise_target 0.1, at most cap seconds), wall clock after a warm-up bake."""
    import dataclasses

    from smbs_addon import BakeSettings, bake
    from testkit.conformance import scene_arrays

    scene = scene_arrays(scene_name)
    scene.camera = dataclasses.replace(scene.camera, resolution_x=1920, resolution_y=1080, resolution_percentage=100)
    bake(scene, BakeSettings(spp=1, batches=1, threads=CORES))
    t0 = time.perf_counter()
    res = bake(scene, BakeSettings(noise_target=0.1, time_budget=float(cap), threads=CORES))
    print(f"{scene_name} at 1920 x 1080: {time.perf_counter() - t0:.1f} s wall, error bar {res.stats['relative_error']:.4f}, "
          f"{res.stats['batches_done']} batches, stopped by {res.stats['stopped_by']}; {res.stats['plan']['words'][-1]}",
          flush=True)


def run_cycles(scene_name, kind, spp_list, seed=1):
    """Cycles' caustic component of scene_name by kind (pt, guiding, mnee) at each sample count: the
    "on" render's CPU seconds and (on - off) luminance."""
    import bpy

    from testkit import conformance_scenes as scenes
    from testkit.cycles import read_exr_rgb, set_render

    OUT.mkdir(parents=True, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        blend = scenes.build(scene_name, Path(tmp))
        for spp in spp_list:
            imgs = {}
            for on in (True, False):
                bpy.ops.wm.open_mainfile(filepath=str(blend))
                sc = bpy.context.scene
                set_render(sc, spp, seed, on, CORES, keep_mnee=(kind == "mnee" and on))
                if kind == "guiding" and on:
                    sc.cycles.use_guiding = True
                    sc.cycles.use_surface_guiding = True
                    sc.cycles.use_volume_guiding = False
                path = Path(tmp) / f"{spp}_{on}.exr"
                sc.render.filepath = str(path)
                c0, t0 = time.process_time(), time.perf_counter()
                bpy.ops.render.render(write_still=True)
                if on:
                    cpu, wall = time.process_time() - c0, time.perf_counter() - t0
                imgs[on] = read_exr_rgb(path)
            rows.append((spp, cpu, wall, (imgs[True] - imgs[False]).mean(axis=2)))
            print(f"{scene_name} cycles {kind} {spp} spp: cpu {cpu:.1f} s, wall {wall:.1f} s", flush=True)
    np.savez_compressed(OUT / f"{scene_name}_cycles_{kind}.npz", spp=np.array([r[0] for r in rows]),
                        cpu=np.array([r[1] for r in rows]), wall=np.array([r[2] for r in rows]),
                        images=np.stack([r[3] for r in rows]).astype(np.float32))


def reference(scene_name):
    """The per-pixel reference (our long bake's mean and its variance of the mean per pixel)."""
    z = np.load(OUT / f"{scene_name}_reference.npz")
    b = z["batches"].astype(np.float64)
    return b.mean(axis=0), b.var(axis=0, ddof=1) / len(b)


def rel_rmse(img, ref_mean, ref_var, region):
    mse = float(((img - ref_mean)[region] ** 2).mean() - ref_var[region].mean())
    return math.sqrt(max(mse, 0.0)) / float(ref_mean[region].mean())


def curve(scene_name, name, ref_mean, ref_var, region, clock="wall"):
    """(seconds, relative RMSE) points of a run, by clock: "wall" (seconds on the 2 cores) or "cpu"."""
    z = np.load(OUT / f"{scene_name}_{name}.npz")
    if "images" in z.files:  # Cycles
        return [(float(c), rel_rmse(im, ref_mean, ref_var, region)) for c, im in zip(z[clock], z["images"])]
    b = z["batches"].astype(np.float64)
    B, cpu = len(b), float(z[clock])
    # the first k batches cost the bake's fixed work (its one-sample bake's, an upper bound: it holds
    # one sample too) and k / B of the rest
    key = "fixed" if clock == "cpu" else "fixed_wall"
    fixed = min(float(z[key]), cpu) if key in z.files else FIXED.get((scene_name, name), 0.0)
    ks = sorted({max(1, B // 16), B // 8, B // 4, B // 2, B})
    return [(fixed + (cpu - fixed) * k / B, rel_rmse(b[:k].mean(axis=0), ref_mean, ref_var, region))
            for k in ks if k >= 1]


def at(points, t):
    """RMSE at CPU seconds t: log-log between points, 1/sqrt(t) beyond them."""
    pts = sorted(points)
    if t <= pts[0][0]:
        return pts[0][1] * math.sqrt(pts[0][0] / t), True
    if t >= pts[-1][0]:
        return pts[-1][1] * math.sqrt(pts[-1][0] / t), t > pts[-1][0] * 1.05
    for (t0, e0), (t1, e1) in zip(pts, pts[1:]):
        if t0 <= t <= t1:
            if e0 <= 0 or e1 <= 0:
                return e0 + (e1 - e0) * (t - t0) / (t1 - t0), False
            w = math.log(t / t0) / math.log(t1 / t0)
            return math.exp(math.log(e0) + w * (math.log(e1) - math.log(e0))), False


def mean_against_cycles(scene_name, name, region):
    """A run's mean over region over Cycles' path-traced reference's (tests/data/conformance), and the
    standard error of that ratio (our batches' and the reference's halves')."""
    from testkit.conformance import load_reference

    ref = load_reference(scene_name)
    A, B = ref["a"].mean(axis=2)[region].mean(), ref["b"].mean(axis=2)[region].mean()
    truth, se_c = 0.5 * (A + B), 0.5 * abs(A - B)
    z = np.load(OUT / f"{scene_name}_{name}.npz")
    if "images" in z.files:
        return float(z["images"][-1][region].mean() / truth), se_c / truth
    m = z["batches"].astype(np.float64)[:, region].mean(axis=1)
    return float(m.mean() / truth), math.hypot(m.std(ddof=1) / math.sqrt(len(m)) / truth, se_c / truth)


def table(scenes, names, clock="wall"):
    from testkit.conformance import region_of

    lines = []
    for sc in scenes:
        ref_mean, ref_var = reference(sc)
        region = region_of(ref_mean)
        floor = math.sqrt(ref_var[region].mean()) / ref_mean[region].mean()
        r, se = mean_against_cycles(sc, "reference", region)
        lines.append(f"\n**{sc}** (the reference, anchored SMBS: its own noise {floor:.4f} per pixel, its mean "
                     f"{r:.4f} +- {se:.4f} of Cycles' path tracing; region {int(region.sum())} pixels)\n")
        unit = "s on 2 cores" if clock == "wall" else "s x 2 cores (CPU)"
        lines.append("| method | " + " | ".join(f"{b:g} {unit}" for b in BUDGETS) +
                     f" | measured at ({clock} s: RMSE) | mean / Cycles PT |")
        lines.append("|---|" + "---|" * (len(BUDGETS) + 2))
        for n in names:
            if not (OUT / f"{sc}_{n}.npz").exists():
                continue
            pts = curve(sc, n, ref_mean, ref_var, region, clock)
            cells = []
            for b in BUDGETS:
                e, ext = at(pts, b * (CORES if clock == "cpu" else 1))
                cells.append(f"{e:.3f}{'*' if ext else ''}")
            r, se = mean_against_cycles(sc, n, region)
            lines.append(f"| {n} | " + " | ".join(cells) + " | " + ", ".join(f"{t:.0f}: {e:.3f}" for t, e in pts)
                         + f" | {r:.3f} +- {se:.3f} |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=["ours", "timed", "artist", "cycles", "reference", "table"])
    ap.add_argument("--scene", default="pool_sun")
    ap.add_argument("--scenes", default="pool_sun,pool_hdri")
    ap.add_argument("--variant", default="anchor")
    ap.add_argument("--kind", default="pt")
    ap.add_argument("--spp", default="64")
    ap.add_argument("--batches", type=int, default=32)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--budgets", default="10,40", help="timed: wall-clock budgets in seconds")
    ap.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                    help="table: wall seconds on a quiet machine's 2 cores, or CPU seconds (a shared machine)")
    a = ap.parse_args(argv)
    if a.what == "ours":
        run_ours(a.scene, a.variant, int(a.spp), a.batches, a.seed)
    elif a.what == "artist":
        run_artist(a.scene)
    elif a.what == "timed":
        run_ours_timed(a.scene, a.variant, [float(t) for t in a.budgets.split(",")], a.seed)
    elif a.what == "reference":
        run_ours(a.scene, a.variant, int(a.spp), a.batches, seed=1000 + a.seed, tag="reference")
    elif a.what == "cycles":
        run_cycles(a.scene, a.kind, [int(s) for s in a.spp.split(",")])
    else:
        # main: the default before issue 61, baked by main's tree on the same exported scene (the one-off
        # script's output in this folder's format)
        names = (["main"] + list(VARIANTS) + [f"{v}_timed" for v in VARIANTS]
                 + [f"cycles_{k}" for k in ("mnee", "guiding", "pt")])
        print(table(a.scenes.split(","), names, a.clock))


if __name__ == "__main__":
    main()
