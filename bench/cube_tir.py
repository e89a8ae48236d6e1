"""SMBS against SMS where total internal reflection abounds: bevelled glass cubes near the floor.

    .venv/bin/python bench/cube_tir.py [--budget 60] [--scenes cube_grey,cube_white_rect]

The conformance suite's two bevelled cubes (testkit/conformance_scenes.py), baked by SMS
and SMBS (unbiased) for the same wall-clock budget. Per method: success rate and mutations per
solution overall and per chain type (T T, T R T, T R R T), large mutations and what set them
off, Bernoulli trials per lane, and the error against Cycles' reference: the region mean's
ratio (with three standard errors) and the relative RMSE per pixel over the caustic region
(the reference's own per-pixel noise subtracted in quadrature). Writes cube_tir.md.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

from testkit import conformance as conf
from smbs_addon import BakeSettings, bake


def run(name, method, budget, seed):
    sc = conf.scene_arrays(name)
    ref = conf.load_reference(name)
    t = time.perf_counter()
    r = bake(sc, BakeSettings(method=method, spp=8, batches=8, seed=seed, time_budget=budget))  # 1 spp a batch
    wall = time.perf_counter() - t
    j = conf.judge(r.batch_luminance, ref)
    st = r.stats
    (light,) = st["lights"].values()
    chains = {k: v for k, v in light.get("by_chain", {}).items()}
    return {"scene": name, "method": method, "wall": wall, "batches": st["batches_done"],
            "ratio": j["ratio"], "sigma": j["sigma"], "rmse": conf.relative_rmse(r.image.mean(axis=2), ref),
            "SR": st["success_rate"], "mps": st["mutations_per_success"],
            "large": light.get("large_mutations", {}), "trials": light["trials"]["mean"], "chains": chains,
            "left": st.get("guide", {}).get("left_to_photons", []), "rays": st["rays"]}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--budget", type=float, default=60.0)
    ap.add_argument("--scenes", default="cube_grey,cube_white_rect")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results")
    args = ap.parse_args(argv)
    rows = []
    for name in args.scenes.split(","):
        for m in ("sms", "smbs"):
            rows.append(run(name, m, args.budget, args.seed))
            r = rows[-1]
            print(f"{name} {m}: {r['wall']:.0f} s, {r['batches']} spp, ratio {r['ratio']:.3f} ± {3 * r['sigma']:.3f}, "
                  f"rel RMSE {r['rmse']:.3f}, SR {r['SR']:.3f}, mut/sol {r['mps']:.1f}, trials {r['trials']:.1f}, "
                  f"large {r['large']}", flush=True)
            for k, v in r["chains"].items():
                print(f"    {k}: walks {v['walks']} SR {v['success_rate']:.3f} mut/sol "
                      f"{v['mutations_per_success']:.1f} large {v['large_mutations']}", flush=True)
    lines = ["# SMBS and SMS on bevelled glass cubes (total internal reflection)", "",
             f"Made by `python bench/cube_tir.py --budget {args.budget:g}` (2 cores, unbiased estimator, "
             "seed 1). Error against Cycles' reference (tests/data/conformance/).", "",
             "| scene | method | spp in budget | wall s | mean / Cycles ± 3σ | rel. RMSE | SR | mutations / solution "
             "| Bernoulli trials / lane | large mutations (TIR / back-lit / slow) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lm = r["large"]
        lines.append(f"| {r['scene']} | {r['method']} | {r['batches']} | {r['wall']:.0f} | {r['ratio']:.3f} ± "
                     f"{3 * r['sigma']:.3f} | {r['rmse']:.3f} | {r['SR']:.3f} | {r['mps']:.1f} | {r['trials']:.1f} | "
                     f"{lm.get('tir', 0)} / {lm.get('backlit', 0)} / {lm.get('slow', 0)} |")
    lines += ["", "Per chain type (primary walks):", "",
              "| scene | method | chain | walks | SR | mutations / solution | large mutations |",
              "|---|---|---|---|---|---|---|"]
    for r in rows:
        for k, v in r["chains"].items():
            lines.append(f"| {r['scene']} | {r['method']} | {k} | {v['walks']} | {v['success_rate']:.3f} | "
                         f"{v['mutations_per_success']:.1f} | {v['large_mutations']} |")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "cube_tir.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
