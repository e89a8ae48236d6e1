"""Where a conformance cell disagrees: the ratio to Cycles over the pixels the camera sees
directly and over those it sees through mirrors and glass, across independent seeds.

    .venv/bin/python bench/conformance_split.py --scenes cube_grey --runs reference:1024,sms:64,smbs:64 --seeds 4

A caustic region is two estimates in one: at receivers the camera sees directly our light
tracer splats photons and the walks start from x0 with the eye path ending there; at receivers
seen through glass or a mirror the light tracer's eye pass and the walks' eye paths through
the caster take over. ``tools/conformance.view_masks`` tells the two kinds of pixel apart (all
4 x 4 primary rays meet a diffuse surface first, or all meet a mirror or glass first; edge
pixels are in neither), and ``judge(..., mask=)`` takes the ratio over each.

Across seeds: each seed is an independent bake, so the spread of its ratios is an honest error
of their mean even where one bake's batches are heavy-tailed (a walk through a fold, a rare
Bernoulli count): the table gives the mean over seeds ± 3 standard errors across seeds, next to
the reference's own 3 sigma over the same pixels. Writes conformance_split.md to --out.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

from testkit import conformance as conf
from smbs_addon import BakeSettings, bake

PARTS = ("all", "direct", "through")
MIN_PIXELS = 20  # of the caustic region, for a part to be judged


def split(name: str, runs: list, seeds: int, first_seed: int = 100) -> dict:
    """{(method, spp): {part: [ratio per seed]}, "ref": {part: reference 1 sigma}, "pixels": {...}}."""
    sc = conf.scene_arrays(name)
    ref = conf.load_reference(name)
    direct, through = conf.view_masks(sc)
    region = conf.region_of(0.5 * (ref["a"] + ref["b"]).mean(axis=2))
    # a kind of pixel the caustic region has (almost) none of is left out
    masks = {p: m for p, m in (("all", None), ("direct", direct), ("through", through))
             if m is None or (region & m).sum() >= MIN_PIXELS}
    out = {"ref": {}, "pixels": {}, "seconds": {}}
    for method, spp in runs:
        ratios = {p: [] for p in masks}
        secs = []
        for seed in range(first_seed, first_seed + seeds):
            t = time.perf_counter()
            r = bake(sc, BakeSettings(method=method, spp=spp, seed=seed))
            secs.append(time.perf_counter() - t)
            for part, m in masks.items():
                j = conf.judge(r.batch_luminance, ref, m)
                ratios[part].append(j["ratio"])
                out["ref"][part] = j["se_ref"]
                out["pixels"][part] = j["pixels"]
            print(f"{name} {method} {spp} spp seed {seed}: "
                  + "  ".join(f"{p} {ratios[p][-1]:.3f}" for p in masks), flush=True)
        out[(method, spp)] = ratios
        out["seconds"][(method, spp)] = float(np.mean(secs))
    return out


def _cell(values: list) -> str:
    v = np.array(values)
    se = v.std(ddof=1) / math.sqrt(len(v)) if len(v) > 1 else float("inf")
    return f"{v.mean():.3f} ± {3 * se:.3f}"


def write(results: dict, runs: list, seeds: int, out: Path, command: str) -> None:
    out.mkdir(parents=True, exist_ok=True)
    lines = [
        "# Conformance split: pixels seen directly / through mirrors and glass",
        "",
        f"Made by `{command}` (2 cores). Each cell: the mean over {seeds} seeds of our ratio to Cycles",
        "over the caustic region's pixels of that kind ± 3 standard errors across the seeds (one",
        "bake per seed, its own samples per pixel as given); the reference column is Cycles' own",
        "3 sigma over the same pixels (from its two halves).",
        "",
    ]
    for name, res in results.items():
        lines += [f"## {name}", "",
                  "| pixels | count | Cycles 3σ | " + " | ".join(f"{m} {s} spp ({res['seconds'][(m, s)]:.1f} s)"
                                                       for m, s in runs) + " |",
                  "|---|---|---|" + "---|" * len(runs)]
        for part in (p for p in PARTS if p in res["pixels"]):
            lines.append(f"| {part} | {res['pixels'][part]} | {3 * res['ref'][part]:.3f} | "
                         + " | ".join(_cell(res[(m, s)][part]) for m, s in runs) + " |")
        lines.append("")
    (out / "conformance_split.md").write_text("\n".join(lines))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="cube_grey")
    ap.add_argument("--runs", default="reference:1024,sms:64,smbs:64", help="method:spp, comma-separated")
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--out", default=str(ROOT / "bench" / "results"))
    args = ap.parse_args(argv)
    runs = [(r.split(":")[0], int(r.split(":")[1])) for r in args.runs.split(",")]
    results = {name: split(name, runs, args.seeds) for name in args.scenes.split(",")}
    command = "python bench/conformance_split.py " + " ".join(sys.argv[1:] if argv is None else argv)
    write(results, runs, args.seeds, Path(args.out), command.strip())


if __name__ == "__main__":
    main()
