"""What the first bake after installing costs, and what `prepare` saves.

    python bench/first_bake.py [--jobs 1,2] [--out DIR]

For each jobs count: a copy of the package in a temporary folder (so its numba cache is empty),
`python -m smbs_addon prepare --jobs N` there (wall time, kernels compiled), then bakes of every
sample scene with every method and estimator (2 spp) in one process, counting the kernels they
still compile (each bake's stats["kernels_compiled"]: what prepare missed). With --first, also
the first bake without prepare: an auto bake of sample_blends/glass_sphere.blend on an empty cache.
Writes DIR/first_bake.md.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SAMPLE_BAKES = r'''
import glob
from smbs_addon.cli.inputs import load_input
from smbs_addon import BakeSettings, bake
total = 0
for f in sorted(glob.glob("sample_blends/*.blend")):
    sc = load_input(f, warn=lambda m: None)
    for m, est in [("auto", "unbiased"), ("smbs", "unbiased"), ("smbs", "biased"), ("sms", "unbiased"),
                   ("sms", "biased"), ("mnee", "unbiased"), ("reference", "unbiased")]:
        r = bake(sc, BakeSettings(method=m, spp=2, batches=2, seed=1, estimator=est))
        total += r.stats["kernels_compiled"]
        print(f"bake {f} {m} {est}: {r.stats['kernels_compiled']} kernels compiled", flush=True)
print(f"bakes: {total}")
'''


def _copy(dest: Path) -> None:
    for part in ("smbs_addon", "sample_blends"):
        shutil.copytree(ROOT / part, dest / part, ignore=shutil.ignore_patterns("__pycache__", "*.npz"))


def _run(cmd, cwd) -> tuple[float, str]:
    t = time.perf_counter()
    out = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, check=True)
    return time.perf_counter() - t, out.stdout


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--jobs", default="1,2")
    ap.add_argument("--first", action="store_true", help="also time a first bake without prepare")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results"))
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        if args.first:
            d = Path(tmp) / "first"
            _copy(d)
            sec, _ = _run([sys.executable, "-m", "smbs_addon", "bake", "sample_blends/glass_sphere.blend", "--spp", "2",
                           "--seed", "1", "--out", str(d / "g.exr"), "--quiet"], d)
            rows.append(f"| first auto bake of glass_sphere, no prepare | {sec:.1f} | | |")
            print(rows[-1], flush=True)
        for jobs in (int(j) for j in args.jobs.split(",")):
            d = Path(tmp) / f"jobs{jobs}"
            _copy(d)
            sec, out = _run([sys.executable, "-m", "smbs_addon", "prepare", "--jobs", str(jobs)], d)
            kernels = out.strip().splitlines()[-1].split("prepared: ")[1].split(" kernel")[0]
            _, baked = _run([sys.executable, "-c", SAMPLE_BAKES], d)
            missed = baked.strip().splitlines()[-1].split("bakes: ")[1]
            rows.append(f"| prepare --jobs {jobs} | {sec:.1f} | {kernels} | {missed} |")
            print(rows[-1], flush=True)
    head = ["| run | wall s | kernels compiled | kernels the 35 sample bakes still compiled |", "|---|---|---|---|"]
    text = "\n".join([f"Made by `python bench/first_bake.py --jobs {args.jobs}{' --first' if args.first else ''}` "
                      f"({os.cpu_count()} cores).", ""] + head + rows) + "\n"
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "first_bake.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
