"""A conformance scene's caustic, judged against Cycles over several seeds, with the walked chain
types (or other settings) restricted: which walked type reads off when a whole bake does.

    .venv/bin/python bench/chain_subsets.py SCENE METHOD:SPP[,METHOD:SPP...] SEEDS ['{"chains": ["TT"]}']

Per bake (seeds 1..SEEDS), conformance.judge's ratio (ours / Cycles over the caustic region) and
its sigma, over the whole region and over the pixels seen directly; then per method the mean of
the seeds' ratios and its standard error from their spread. The JSON holds BakeSettings fields
(chains: the walked types; the paths of the other types go to the photons, so every restricted
bake still estimates the whole caustic). Results: bench/results/chain_subsets.md.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

from testkit import conformance as conf
from smbs_addon import BakeSettings, bake


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    name, configs, seeds = argv[0], [tuple(a.split(":")) for a in argv[1].split(",")], range(1, int(argv[2]) + 1)
    extra = json.loads(argv[3]) if len(argv) > 3 else {}
    sc = conf.scene_arrays(name)
    ref = conf.load_reference(name)
    direct, _ = conf.view_masks(sc)
    for method, spp in configs:
        rows = []
        for s in seeds:
            r = bake(sc, BakeSettings(method=method, spp=int(spp), seed=s, **extra))
            j, jd = conf.judge(r.batch_luminance, ref), conf.judge(r.batch_luminance, ref, direct)
            rows.append((j["ratio"], jd["ratio"]))
            print(method, spp, s, f"all {j['ratio']:.3f} +- {j['sigma']:.3f}  direct {jd['ratio']:.3f} +- "
                  f"{jd['sigma']:.3f}", flush=True)
        a = np.array(rows)
        se = a.std(axis=0, ddof=1) / np.sqrt(len(a))
        print("MEAN", method, extra, f"all {a[:, 0].mean():.3f} ({se[0]:.3f}) direct {a[:, 1].mean():.3f} ({se[1]:.3f})",
              flush=True)


if __name__ == "__main__":
    main()
