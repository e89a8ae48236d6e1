"""Success rate of SMS and SMBS against the strength and scale of a normal map.

    .venv/bin/python bench/normal_map_sweep.py [--spp 1] [--out bench/results]

The caster is testkit/scenes.py's wavy_mirror_scene with normal_mapped=True: a flat
metal sheet whose shading normals follow a sin x sin bump field, sampled on a grid
of n x n cells. Amplitude a and wavelength L give a largest normal tilt of
atan(2 pi a / L). R chains only, biased estimator with one trial (the walks' own
success rate, no Bernoulli re-walks), no photon hand-off. One seed; each row is
one 48 x 36 bake per method (about 10 000 walks).
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

from testkit import scenes
from smbs_addon import BakeSettings, bake

GRID = [  # (amplitude, wavelength, n)
    (0.005, 0.3, 96), (0.01, 0.3, 96), (0.02, 0.3, 96), (0.04, 0.3, 96), (0.08, 0.3, 96),
    (0.005, 0.1, 256), (0.01, 0.1, 256), (0.02, 0.1, 256),
]


def run(spp, out):
    lines = ["| amplitude | wavelength | grid | largest tilt | SMS SR | SMBS SR | ratio | SMS mpp | SMBS mpp |",
             "|---|---|---|---|---|---|---|---|---|"]
    for a, lam, n in GRID:
        sc = scenes.wavy_mirror_scene(resolution=(48, 36), amplitude=a, wavelength=lam, n=n, normal_mapped=True)
        res = {}
        for method in ("sms", "smbs"):
            r = bake(sc, BakeSettings(method=method, spp=spp, seed=1, estimator="biased", trials=1, handoff=0,
                                      chains=("R",), radiance="physical"))
            st = next(iter(r.stats["lights"].values()))
            res[method] = (st["success_rate"], st["mutations_per_path"])
        tilt = math.degrees(math.atan(2 * math.pi * a / lam))
        ratio = res["smbs"][0] / res["sms"][0] if res["sms"][0] else float("inf")
        lines.append(f"| {a} | {lam} | {n + 1}^2 | {tilt:.0f} deg | {res['sms'][0]:.3f} | {res['smbs'][0]:.3f} | "
                     f"{ratio:.2f} | {res['sms'][1]:.2f} | {res['smbs'][1]:.2f} |")
        print(lines[-1], flush=True)
    out.mkdir(parents=True, exist_ok=True)
    (out / "normal_map_sweep.md").write_text(f"spp {spp}, seed 1, R chains, biased estimator with one trial.\n\n"
                                             + "\n".join(lines) + "\n")


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=1)
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results")
    a = ap.parse_args()
    run(a.spp, a.out)
