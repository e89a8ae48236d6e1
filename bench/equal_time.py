"""Equal-time comparison of SMS and SMBS (and MNEE) on the hard cases.

    .venv/bin/python bench/equal_time.py [--budget 20] [--out bench/results]

Scenes (testkit/scenes.py; --cases picks some): under water with a sun (most SMS
seeds die of total internal reflection); four back-lit reflection scenes: a bumpy
mirror sheet (many seeds land on facets facing away from the light), the same
sheet flat but normal-mapped, the ring (half its wall is lit from behind), and
the hammered mirror (a fine, gentle normal map: the paper's Figure 12 kind).
Each method gets the same wall-clock budget (BakeSettings.time_budget);
RMSE is against the closed form (water) or a long light-tracing reference whose
own noise is subtracted in quadrature. Writes a Markdown table and a CSV; timing
lives here, never in a pass/fail test.
"""
from __future__ import annotations

import argparse
import csv
import math
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

from testkit import scenes
from smbs_addon import BakeSettings, bake


def water_case():
    sc = scenes.water_scene("sun", resolution=48, size=4.0)
    c = math.cos(math.radians(30))
    value = 0.8 / math.pi * 3.0 * c * (1 - scenes.fresnel(c, 1.33))
    region = np.zeros((sc.camera.height, sc.camera.width), bool)
    region[4:-4, 4:-4] = True
    return "water, sun (TIR)", sc, np.full(region.shape, value), np.zeros(region.shape), region


def reference_case(name, sc, ref_seconds):
    ref = bake(sc, BakeSettings(method="reference", spp=64, seed=99, time_budget=ref_seconds, batches=8,
                                radiance="physical"))
    region = ref.image.mean(axis=2) > 0
    return name, sc, ref.image.mean(axis=2), ref.variance.mean(axis=2), region


CASES = {  # key: (name, scene, smallest budget in seconds)
    "water": None,
    "bumpy": ("bumpy mirror (back-lit)", lambda: scenes.wavy_mirror_scene(resolution=(48, 36)), 0),
    "nmap": ("normal-mapped mirror", lambda: scenes.wavy_mirror_scene(resolution=(48, 36), normal_mapped=True), 0),
    "ring": ("ring (back-lit wall)", lambda: scenes.ring_scene(resolution=(48, 36)), 0),
    # one unbiased sample per pixel costs about 70 s (SMS) and 90 s (SMBS) at 24 x 18: the
    # Bernoulli trials average 2800 (SMS) and 1200 (SMBS) per solution found
    "hammered": ("hammered mirror (fine normal map)", lambda: scenes.hammered_mirror_scene(resolution=(24, 18)),
                 300),
}


def cases(ref_seconds, keys):
    for key in keys:
        if key == "water":
            yield water_case() + (0,)
            continue
        name, make, least = CASES[key]
        yield reference_case(name, make(), ref_seconds) + (least,)


def run(budget, out, ref_seconds, keys):
    rows = []
    for name, sc, truth, truth_var, region, least in cases(ref_seconds, keys):
        for method in ("sms", "smbs", "mnee"):
            t = time.perf_counter()
            r = bake(sc, BakeSettings(method=method, spp=1, batches=1, seed=1, time_budget=max(budget, least),
                                      radiance="physical"))  # the truths are physical
            wall = time.perf_counter() - t
            err = (r.image.mean(axis=2) - truth)[region]
            mse = max(float(np.mean(err**2) - np.mean(truth_var[region])), 0.0)
            st = r.stats
            rows.append({
                "scene": name, "method": method, "spp": st["batches_done"], "time_s": round(wall, 2),
                "rays_M": round(st["rays"] / 1e6, 2), "SR": round(st["success_rate"], 3),
                "mpp": round(st["mutations_per_path"], 2),
                "mut/success": round(st["mutations_per_success"], 2),
                "large": sum(sum(l.get("large_mutations", {}).values()) for l in st["lights"].values()),
                "chains": "+".join(st["chain_types"]),
                "to photons": ",".join(t.split(": ")[1] for t in st.get("guide", {}).get("left_to_photons", [])),
                "RMSE": round(math.sqrt(mse), 5), "mean/truth": round(float(r.image.mean(axis=2)[region].mean()
                                                                          / truth[region].mean()), 4),
            })
            print(rows[-1], flush=True)
    out.mkdir(parents=True, exist_ok=True)
    stem = "equal_time" if list(keys) == list(CASES) else "equal_time_" + "_".join(keys)
    with open(out / f"{stem}.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    cols = list(rows[0])
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(str(r[c]) for c in cols) + " |" for r in rows]
    (out / f"{stem}.md").write_text(f"Budget {budget} s per method (hammered mirror: at least 300 s), 2 cores. "
                                    "mut/success is the paper's mpp: mutations needed to find a manifold path.\n\n"
                                    + "\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--budget", type=float, default=20.0)
    ap.add_argument("--ref-seconds", type=float, default=120.0)
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results")
    ap.add_argument("--cases", default=",".join(CASES), help=f"comma-separated subset of {', '.join(CASES)}")
    a = ap.parse_args()
    keys = a.cases.split(",")
    for k in keys:
        if k not in CASES:
            ap.error(f"unknown case {k!r}")
    run(a.budget, a.out, a.ref_seconds, keys)
