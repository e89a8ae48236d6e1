"""What accuracy costs in time: relative RMSE against the time spent, per scene and method.

    .venv/bin/python bench/accuracy_time.py [--scenes lens_area,pool_sun4] [--methods reference,smbs]
        [--budgets 2,5,12,30,60,120] [--seeds 1] [--cycles] [--out bench/results]

For each conformance scene (testkit/conformance_scenes.py; its converged Cycles reference
is the truth, tests/data/conformance) or sample scene with a reference (sample_mirror,
sample_glass_sphere, sample_glass_spot: sample_blends/*.blend, tests/data/cycles_*; see
tools/conformance.SAMPLES), each method and each budget: one bake with that time
budget (BakeSettings.time_budget: the whole bake, plan and pre-pass included; passes of one
sample per pixel), and its relative RMS error per pixel against the truth over the reference's
caustic region, the reference's own noise taken out (tools/conformance.relative_rmse). Beside
it, what the bake said of itself: relative_error and seconds_to_halve_error, and how well the
time rule kept the budget. With --cycles, Cycles renders the scene through the bpy module with
its own time limit (path tracing, caustics on; its caustic component is that minus the
reference's converged "off" render), measured the same way.

Methods: reference (our light tracer), mnee, sms and smbs (unbiased), sms-b1, sms-b4, smbs-b1,
smbs-b4 (biased, M walks per receiver), auto (per light and effect the cheapest of the
light tracer, SMS and SMBS, by a pilot) and default (what a bake does unless told: auto since
issue 12; smbs before). Writes accuracy_time.md, accuracy_time.csv, accuracy_time_<scene>.png (log-log
RMSE against time) and crops_<scene>.png (every method at one budget, side by side).

With --seeds N each of our cells is baked with N seeds and its RMSE is the root mean square over
them, with the lowest and highest beside it: one seed's RMSE of a caustic with rare bright paths
moves by tens of percent, more than the differences between methods a table is read for.
"""
from __future__ import annotations

import argparse
import csv
import functools
import math
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

from testkit import conformance as conf
from smbs_addon import BakeSettings, bake
from smbs_addon.baking.convergence import caustic_region

METHODS = {
    "reference": dict(method="reference"),
    "mnee": dict(method="mnee"),
    "sms": dict(method="sms"),
    "smbs": dict(method="smbs"),
    "sms-b1": dict(method="sms", estimator="biased", trials=1),
    "sms-b4": dict(method="sms", estimator="biased", trials=4),
    "smbs-b1": dict(method="smbs", estimator="biased", trials=1),
    "smbs-b4": dict(method="smbs", estimator="biased", trials=4),
    "sms-published": dict(method="sms", first_step=1.0, stall_stop=False),  # the walk before
    "smbs-published": dict(method="smbs", first_step=1.0, stall_stop=False),  # first_step, stall_stop
    "auto": dict(method="auto"),
    "default": dict(),
}
BIASED = {"mnee", "sms-b1", "sms-b4", "smbs-b1", "smbs-b4"}
SCENES = ("lens_area", "gold_cylinder", "pool_sun4", "mirror_point_hard", "sphere_point_soft",
          "sphere_refraction_spot", "wavy_mirror_sun2", "water_flat_sun0", "through_glass_disk", "prism_tir",
          "cube_grey", "cube_white_rect") + tuple(conf.SAMPLES)
BATCHES = 4  # per pass of BATCHES samples per pixel: one sample per pixel per batch
CELLS = ROOT / ".cache" / "accuracy_time"  # every measured cell, kept as soon as it is measured


@functools.lru_cache(maxsize=None)
def _commit() -> str:
    import subprocess

    r = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    return r.stdout.strip() or "unknown"


def cell(kind: str, key: tuple, run, resume: bool, report_only: bool = False) -> dict | None:
    """run() -> a row, stored under CELLS at once (a long run that stops keeps what it measured);
    with resume, a row stored before is read back instead of measured again; report_only: None
    for a row not stored."""
    import json

    path = CELLS / ("-".join(str(k) for k in (kind,) + key) + ".npz")
    if report_only and not path.exists():
        return None
    if (resume or report_only) and path.exists():
        with np.load(path, allow_pickle=False) as z:
            row = json.loads(str(z["meta"]))
            row["image"] = z["image"] if z["image"].size else None
        return row
    row = run()
    row.setdefault("commit", _commit())
    CELLS.mkdir(parents=True, exist_ok=True)
    img = row.get("image")
    np.savez(path, meta=json.dumps({k: v for k, v in row.items() if k != "image"}),
             image=np.zeros(0) if img is None else np.asarray(img, np.float32))
    return row


def merge_seeds(rows):
    """One row per (scene, method, budget): RMSE as the root mean square over seeds (lowest and
    highest kept), the other numbers averaged, the first seed's image."""
    groups = {}
    for r in rows:
        groups.setdefault((r["scene"], r["method"], r["budget"]), []).append(r)
    out = []
    for g in groups.values():
        m = dict(g[0])
        for k in ("wall", "spp", "rays", "SR", "mps", "est", "halve"):
            vals = [r[k] for r in g if r.get(k) is not None]
            if vals and len(g) > 1:
                m[k] = type(g[0][k])(np.mean(vals)) if isinstance(g[0][k], int) else float(np.mean(vals))
        m["n"] = len(g)
        m["rmse"] = math.sqrt(float(np.mean([r["rmse"] ** 2 for r in g])))
        own = [r["rmse_own"] for r in g if r.get("rmse_own") is not None]
        m["rmse_own"] = math.sqrt(float(np.mean(np.square(own)))) if own else None
        m["floor_own"] = g[0].get("floor_own")
        m["rmse_lo"], m["rmse_hi"] = min(r["rmse"] for r in g), max(r["rmse"] for r in g)
        m["choice"] = " | ".join(dict.fromkeys(r["choice"] for r in g if r.get("choice")))
        out.append(m)
    return out


def ours(scene, method, budget, seed):
    sc = conf.scene_arrays(scene)
    ref = conf.load_reference(scene)
    t = time.perf_counter()
    r = bake(sc, BakeSettings(spp=BATCHES, batches=BATCHES, seed=seed, time_budget=budget, **METHODS[method]))
    wall = time.perf_counter() - t
    st = r.stats
    return {"scene": scene, "method": method, "budget": budget, "seed": seed, "wall": wall, "spp": st["batches_done"],
            "rays": st["rays"], "SR": st.get("success_rate"), "mps": st.get("mutations_per_success"),
            "rmse": conf.relative_rmse(r.image.mean(axis=2), ref), "floor": conf.noise_floor(ref),
            "est": st["relative_error"],
            "halve": st["seconds_to_halve_error"], "image": r.image.mean(axis=2),
            "choice": "; ".join(f"{k}: {v['why']} (bake: {st['auto']['bake']})"
                                for k, v in st.get("auto", {}).get("lights", {}).items())}


def cycles(scene, budget, seed):
    """Cycles' caustic component in `budget` seconds of rendering: on (its time limit) - off."""
    import bpy
    import conformance_scenes as scenes
    from testkit.cycles import read_exr_rgb, set_render

    ref = conf.load_reference(scene)
    with tempfile.TemporaryDirectory() as tmp:
        bpy.ops.wm.open_mainfile(filepath=str(conf.blend_of(scene, Path(tmp))))
        s = bpy.context.scene
        set_render(s, 1 << 20, seed, True, 2, keep_mnee=scene in scenes.MNEE_REFERENCE)
        s.cycles.time_limit = budget
        s.render.filepath = str(Path(tmp) / "on.exr")
        t = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        wall = time.perf_counter() - t
        img = (read_exr_rgb(Path(tmp) / "on.exr") - ref["off"]).mean(axis=2)
    name = "cycles-mnee" if scene in scenes.MNEE_REFERENCE else "cycles"
    return {"scene": scene, "method": name, "budget": budget, "wall": wall, "spp": None, "rays": None, "SR": None,
            "mps": None, "rmse": conf.relative_rmse(img, ref), "floor": conf.noise_floor(ref), "est": None, "halve": None, "image": img}


def _rmse(r):
    if r["rmse"] < 0.5 * r["floor"]:
        return f"< {r['floor']:.3f}"
    if r.get("n", 1) > 1:
        return f"{r['rmse']:.3f} ({r['rmse_lo']:.3f}-{r['rmse_hi']:.3f})"
    return f"{r['rmse']:.3f}"


def _fmt(v, f):
    return "" if v is None else format(v, f)


def plot(rows, scene, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.2))
    for m in dict.fromkeys(r["method"] for r in rows if r["scene"] == scene):
        pts = sorted((r["wall"], r["rmse"]) for r in rows if r["scene"] == scene and r["method"] == m)
        ax.loglog(*zip(*pts), "o-" if m not in BIASED else "s--", label=m, ms=4)
    ax.set_xlabel("wall time (s, 2 cores)")
    ax.set_ylabel("relative RMSE per pixel vs Cycles")
    ax.set_title(scene)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / f"accuracy_time_{scene}.png", dpi=110)
    plt.close(fig)


def crops(rows, scene, budget, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ref = conf.load_reference(scene)
    truth = 0.5 * (ref["a"] + ref["b"]).mean(axis=2)
    sel = [r for r in rows if r["scene"] == scene and r["budget"] == budget]
    panels = [("Cycles reference", truth, None)] + [(r["method"], r["image"], r["rmse"]) for r in sel
                                                    if r.get("image") is not None]
    if len(panels) == 1:  # no image kept (rows rebuilt from a log): no crops
        return False
    vmax = float(np.percentile(truth, 99.5)) or 1.0
    fig, axes = plt.subplots(1, len(panels), figsize=(2.2 * len(panels), 2.1))
    for ax, (title, img, e) in zip(np.atleast_1d(axes), panels):
        ax.imshow(np.clip(img / vmax, 0, 1) ** (1 / 2.2), cmap="gray", vmin=0, vmax=1)
        ax.set_title(title if e is None else f"{title}\nRMSE {e:.2f}", fontsize=7)
        ax.axis("off")
    fig.suptitle(f"{scene}, {budget:g} s each", fontsize=8)
    fig.tight_layout()
    fig.savefig(out / f"crops_{scene}.png", dpi=110)
    plt.close(fig)
    return True


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--budgets", default="2,5,12,30,60,120")
    ap.add_argument("--cycles", action="store_true", help="also Cycles path tracing at the same budgets")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--seeds", type=int, default=1, help="bakes per cell, seeds --seed, --seed + 1, ...")
    ap.add_argument("--noise-targets", default="0.2,0.1",
                    help="per scene, bakes of the default method with these --noise targets (0: none)")
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results")
    ap.add_argument("--note", default="", help="a paragraph under the report's header (how the run went)")
    ap.add_argument("--report-only", action="store_true",
                    help="measure nothing: the report of the cells stored (.cache/accuracy_time)")
    ap.add_argument("--resume", action="store_true",
                    help="reuse the cells a run before measured (.cache/accuracy_time; each row keeps its commit)")
    args = ap.parse_args(argv)
    budgets = [float(b) for b in args.budgets.split(",")]
    rows = []
    for scene in args.scenes.split(","):
        for method in args.methods.split(","):
            if (scene, method) in conf.NOT_APPLICABLE:
                continue
            for b, seed in [(b, s) for b in budgets for s in range(args.seed, args.seed + args.seeds)]:
                r = cell("ours", (scene, method, f"{b:g}", seed), lambda: ours(scene, method, b, seed),
                         args.resume, args.report_only)
                if r is None:
                    continue
                rows.append(r)
                print(f"{scene} {method} {b:g} s, seed {seed}: {r['wall']:.1f} s, {r['spp']} spp, "
                      f"RMSE {r['rmse']:.3f}, estimated {_fmt(r['est'], '.3f')}, halve {_fmt(r['halve'], '.1f')} s"
                      + (f"; auto chose {r['choice']}" if r.get("choice") else ""), flush=True)
        if args.cycles:
            for b in budgets:
                r = cell("cycles", (scene, f"{b:g}", args.seed), lambda: cycles(scene, b, args.seed),
                         args.resume, args.report_only)
                if r is None:
                    continue
                rows.append(r)
                print(f"{scene} {r['method']} {b:g} s: {r['wall']:.1f} s, RMSE {r['rmse']:.3f}", flush=True)
    noise = []
    for scene in args.scenes.split(","):
        for target in [float(x) for x in args.noise_targets.split(",") if float(x) > 0]:
            n = cell("noise", (scene, f"{target:g}", args.seed), lambda: noise_run(scene, target, args.seed),
                     args.resume, args.report_only)
            if n is None:
                continue
            noise.append(n)
            print(f"{scene} --noise {target:g}: {n['wall']:.1f} s, error {n['est']:.3f}, met at {n['met']:.1f} s, "
                  f"{n['batches']} batches, stopped by {n['stopped_by']}", flush=True)
    write(rows, args, budgets, noise)


def noise_run(scene, target, seed, cap=120.0):
    """A bake with a noise target (and a time cap): how long it ran past the batch that met it."""
    sc = conf.scene_arrays(scene)
    t = time.perf_counter()
    r = bake(sc, BakeSettings(spp=BATCHES, batches=BATCHES, seed=seed, noise_target=target, time_budget=cap))
    wall = time.perf_counter() - t
    st = r.stats
    return {"scene": scene, "target": target, "wall": wall, "est": st["relative_error"] or 0.0,
            "met": st["convergence"]["last_batch_end_s"], "batches": st["batches_done"],
            "stopped_by": st["stopped_by"],
            "rmse": conf.relative_rmse(r.image.mean(axis=2), conf.load_reference(scene))}


def _rmse_own(r):
    """The true error over the bake's own caustic region (convergence.caustic_region of its
    image): the pixels its `est.` is about. The reference's region (box-filtered, 5% of its
    99.5th percentile) can be far smaller: on the disk seen through a pane it holds the focus
    (114 pixels), the bake's the whole floor lit through the pane (2,800)."""
    if r.get("est") is None or r.get("image") is None:
        return None, None
    ref, region = conf.load_reference(r["scene"]), caustic_region(r["image"])
    return conf.relative_rmse(r["image"], ref, region), conf.noise_floor(ref, region)


def _own(r):
    """RMSE, own region: as _rmse, against the reference's noise over that region."""
    if r.get("rmse_own") is None:
        return ""
    if r["rmse_own"] < 0.5 * r["floor_own"]:
        return f"< {r['floor_own']:.3f}"
    return f"{r['rmse_own']:.3f}"


def write(raw, args, budgets, noise=()):
    for r in raw:
        r["rmse_own"], r["floor_own"] = _rmse_own(r)
    rows = merge_seeds(raw)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    cmd = "python bench/accuracy_time.py " + (f"--seeds {args.seeds} " if args.seeds > 1 else "") + " ".join(
        f"--{k} {v}" for k, v in (("scenes", args.scenes), ("methods", args.methods), ("budgets", args.budgets),
                                   ("noise-targets", args.noise_targets)))
    if args.cycles:
        cmd += " --cycles"
    lines = ["# Accuracy against time", "", f"Made by `{cmd}` (2 cores). Relative RMSE per pixel against "
             "Cycles' converged caustic component over its caustic region, the reference's noise taken out. "
             "`est.` is the bake's own relative_error (noise only: a biased method's bias is not in it), "
             "over the bake's own caustic region, beside the true error over that region (`RMSE, own region`; "
             "the reference's region can be far smaller); "
             "`halve` its seconds_to_halve_error; `budget kept` the wall time / budget. An RMSE below the "
             "reference's own noise (`floor`, per pixel) is not resolved: it reads `< floor`. Measured at "
             "commit " + ", ".join(sorted({str(r.get("commit", "?")) for r in raw})) + ".", ""]
    if args.note:
        lines += [args.note, ""]
    lines += ["| scene | method | budget s | wall s | budget kept | spp | rays | SR | mut/sol | RMSE | floor | "
              "RMSE, own region | est. | halve s |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        kept = r["wall"] / r["budget"]
        lines.append(f"| {r['scene']} | {r['method']}{' (biased)' if r['method'] in BIASED else ''} | "
                     f"{r['budget']:g} | {r['wall']:.1f} | {kept:.2f} | {_fmt(r['spp'], 'd')} | "
                     f"{_fmt(r['rays'], ',')} | {_fmt(r['SR'], '.3f')} | {_fmt(r['mps'], '.0f')} | {_rmse(r)} | "
                     f"{r['floor']:.3f} | {_own(r)} | "
                     f"{_fmt(r['est'], '.3f')} | {_fmt(r['halve'], '.1f')} |")
    kept = [r["wall"] / r["budget"] for r in raw if r["method"] in METHODS and r["spp"] and r["spp"] > 2]
    if kept:
        lines += ["", f"The time rule (`--time`): wall / budget {min(kept):.2f} to {max(kept):.2f} over the "
                  f"{len(kept)} bakes that ran more than the two batches every bake makes (a shorter budget "
                  "than two batches cannot be kept, and is not counted)."]
    chose = [r for r in rows if r.get("choice")]
    if chose:
        lines += ["", "What auto chose (per light, from its pilot; `bake`: light tracing alone (reference) or the "
                  "walks with light tracing where it won (manifold)):", ""]
        lines += [f"- {r['scene']}, {r['budget']:g} s: {r['choice']}" for r in chose]
    if noise:
        lines += ["", "The noise rule (`--noise`, default method, a 120 s cap): how far it ran past the end of "
                  "the batch whose error met the target (the check, the statistics and the image's "
                  "finishing), and the true error it reached.", "",
                  "| scene | target | wall s | met at s | past it | batches | est. error | true RMSE | stopped by |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for n in noise:
            lines.append(f"| {n['scene']} | {n['target']:g} | {n['wall']:.1f} | {n['met']:.1f} | "
                         f"{n['wall'] / max(n['met'], 1e-9) - 1:+.1%} | {n['batches']} | {n['est']:.3f} | "
                         f"{_fmt(n.get('rmse'), '.3f')} | {n['stopped_by']} |")
    lines += ["", "Equal time, best first (the largest budget):", ""]
    top = max(budgets)
    for scene in dict.fromkeys(r["scene"] for r in rows):
        sel = sorted((r for r in rows if r["scene"] == scene and r["budget"] == top), key=lambda r: r["rmse"])
        lines.append(f"- {scene}: " + ", ".join(f"{r['method']} {_rmse(r)}" for r in sel))
        auto = [r for r in sel if r["method"] == "auto"]
        single = [r for r in sel if r["method"] in ("reference", "sms", "smbs")]
        if auto and single:  # issue 12's rule: auto within 15% of the best single unbiased method
            best = min(single, key=lambda r: r["rmse"])
            ratio = f"{auto[0]['rmse'] / best['rmse']:.2f}" if best["rmse"] > 0 else "not resolved"
            if 0 < best["rmse"] <= 0.5 * best["floor"]:
                ratio += " (under half the reference's noise: resolved only by taking that noise out)"
            lines.append(f"  auto / best single method ({best['method']}): {ratio}")
        plot(rows, scene, out)
        cropped = crops(rows, scene, top, out)
        lines.append(f"  ![{scene}](accuracy_time_{scene}.png)" + (f" ![crops](crops_{scene}.png)" if cropped else ""))
    (out / "accuracy_time.md").write_text("\n".join(lines) + "\n")
    with open(out / "accuracy_time.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        keys = ["scene", "method", "budget", "seed", "wall", "spp", "rays", "SR", "mps", "rmse", "floor", "rmse_own",
                "floor_own", "est", "halve"]
        w.writerow(keys)
        for r in raw:
            w.writerow([r.get(k) for k in keys])


if __name__ == "__main__":
    main()
