"""How many cosine directions the hand-off should take per receiver seen through glass or a mirror
(indirect.HANDOFF_SAMPLES, 64): equal-time bakes with other counts, two seeds each.

    .venv/bin/python bench/handoff_samples.py SCENE METHOD BUDGET_S SAMPLES[,SAMPLES...]

SCENE: a conformance or sample scene with a Cycles reference (tools/conformance.py). Prints one
JSON line per bake: samples per pixel reached, relative RMSE against the reference (its own noise
taken out; `floor` is that noise), the bake's own error bar (`est`), rays in all and the hand-off's.
Results: bench/results/handoff_samples.md.
"""
from __future__ import annotations

import functools
import importlib
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

from testkit import conformance as conf
from smbs_addon import BakeSettings, bake

indirect = importlib.import_module("smbs_addon.paths.gather")


def main(scene: str, method: str, budget: float, counts: list[int]) -> None:
    sc, ref = conf.scene_arrays(scene), conf.load_reference(scene)
    gather = indirect.handoff_gather  # manifold_chunk looks it up on the module at each call
    try:
        for samples in counts:
            indirect.handoff_gather = functools.partial(gather, samples=samples)
            for seed in (1, 2):
                t = time.perf_counter()
                r = bake(sc, BakeSettings(method=method, spp=4, batches=4, seed=seed, time_budget=budget))
                st, eye = r.stats, r.stats["eye_pass"]
                print(json.dumps({
                    "scene": scene, "samples": samples, "seed": seed, "wall": round(time.perf_counter() - t, 1),
                    "spp": st["batches_done"], "rmse": round(conf.relative_rmse(r.image.mean(axis=2), ref), 4),
                    "floor": round(conf.noise_floor(ref), 3), "est": round(st["relative_error"], 4),
                    "rays": st["rays"], "rays_handoff": eye.get("rays_handoff", 0),
                    "handoff_paths": eye.get("handoff_paths", 0)}), flush=True)
    finally:
        indirect.handoff_gather = gather


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], float(sys.argv[3]), [int(x) for x in sys.argv[4].split(",")])
