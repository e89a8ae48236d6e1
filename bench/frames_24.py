"""The animated sample baked over its 24 frames (issue 58): frames 1, 12 and 24 of the range against a
single-frame bake of each (bit for bit, every channel) and against the light tracer (within 3 sigma).

    python bench/frames_24.py [--percentage 50] [--spp 8] [--ref-spp 64] [--out DIR] [--md bench/results/frames_24.md]

sample_blends/moving_light.blend (a square light crossing over a glass ball; the caustic slides across
the floor) at --percentage of its 160 x 120, saved to DIR; then, with the command line a farm runs:
``bake --frames 1-24`` (default method, auto), ``bake --frame F`` for F in 1, 12, 24, and ``bake --frame F
--method reference`` (the light tracer) at --ref-spp. A range frame and its single bake agree when every
channel of the two EXRs holds the same bytes; a frame and the light tracer agree when the means over the
light tracer's caustic region differ by less than 3 x the two bakes' standard errors of the mean (their
statistics' noise.std_error_of_mean) combined. CPU time is the children's (RUSAGE_CHILDREN); the
machine is shared, so wall times are rough. Exit 1 if a check fails.
"""
from __future__ import annotations

import argparse
import json
import math
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from smbs_addon.baking.convergence import caustic_region  # noqa: E402
from smbs_addon.io.exr import read_channels  # noqa: E402
from smbs_addon.io.sequence import frame_path  # noqa: E402

CHECKED = (1, 12, 24)


def cli(*args) -> float:
    """Run python -m smbs_addon ARGS; its wall seconds (raises on a non-zero exit)."""
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "smbs_addon", *map(str, args), "--quiet"], cwd=ROOT,
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"smbs_addon {' '.join(map(str, args))}: exit {proc.returncode}\n{proc.stderr[-2000:]}")
    return time.perf_counter() - t0


def scene(folder: Path, percentage: int) -> Path:
    code = ("import sys; sys.path.insert(0, %r); from testkit.motion_scenes import small_moving_light; "
            "small_moving_light(%r, %d)" % (str(ROOT), str(folder / "moving_light.blend"), percentage))
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)
    return folder / "moving_light.blend"


def lum(channels) -> np.ndarray:
    return (channels["R"].astype(np.float64) + channels["G"] + channels["B"]) / 3


def check_frame(f, rng_file, alone_file, ref_file) -> dict:
    a, _ = read_channels(rng_file)
    b, _ = read_channels(alone_file)
    ref, _ = read_channels(ref_file)
    same = sorted(a) == sorted(b) and all(a[k].tobytes() == b[k].tobytes() for k in a)
    sa, sr = (json.loads(Path(p).with_suffix(".json").read_text()) for p in (rng_file, ref_file))
    region = caustic_region(lum(ref))
    ours, theirs = float(lum(a)[region].mean()), float(lum(ref)[region].mean())
    se = math.hypot(sa["noise"]["std_error_of_mean"], sr["noise"]["std_error_of_mean"])
    return {"frame": f, "bit_for_bit": same, "channels": len(a), "ours": ours, "light_tracer": theirs,
            "ratio": ours / theirs if theirs else float("nan"), "se": se,
            "sigmas": abs(ours - theirs) / se if se else float("inf"), "region_pixels": int(region.sum()),
            "error_ours": sa["relative_error"], "error_ref": sr["relative_error"]}


def markdown(args, rows, times, summary) -> str:
    fl = summary["flicker"]
    lines = [
        "# The animated sample over 24 frames (issue 58)",
        "",
        f"`python bench/frames_24.py --percentage {args.percentage} --spp {args.spp} --ref-spp {args.ref_spp}`: "
        f"sample_blends/moving_light.blend at {args.percentage}% of 160 x 120, `bake --frames 1-24 --spp {args.spp} "
        f"--seed {args.seed}` (auto), each of frames {', '.join(map(str, CHECKED))} baked alone (`--frame F`, the same "
        f"settings) and by the light tracer (`--method reference --spp {args.ref_spp}`). Shared 2-core machine: "
        "times are rough.",
        "",
        "| frame | range = alone, bit for bit | channels | range mean | light tracer mean | ratio | difference / sigma |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(f"| {r['frame']} | {'yes' if r['bit_for_bit'] else 'NO'} | {r['channels']} | {r['ours']:.4g} | "
                     f"{r['light_tracer']:.4g} | {r['ratio']:.3f} | {r['sigmas']:.2f} |")
    t = summary["totals"]
    lines += [
        "",
        f"Range: {t['baked']} frames in {t['time_s']:.1f} s of baking ({times['range']:.1f} s wall with the start-up), "
        f"{t['rays']:,} rays, error bar at most +-{t['relative_error_max']:.1%} (RMS {t['relative_error_rms']:.1%}); "
        f"the children's CPU time {times['cpu']:.1f} s in all.",
        f"Flicker (the summary's): {fl['measured']:.1%} RMS change from frame to frame on the caustic, "
        f"{fl['predicted']:.1%} from the error bars ({fl['pairs']} pairs; the motion is in the measured figure).",
        "",
        "All checks pass." if all(r["bit_for_bit"] and r["sigmas"] < 3 for r in rows) else "A CHECK FAILED.",
    ]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--percentage", type=int, default=50)
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--ref-spp", type=int, default=64)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path, default=Path("/tmp/smbs_frames_24"))
    ap.add_argument("--md", type=Path, default=ROOT / "bench" / "results" / "frames_24.md")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    blend = scene(args.out, args.percentage)
    common = ("--spp", args.spp, "--seed", args.seed, "--overwrite")
    pattern = args.out / "range" / "c_####.exr"
    pattern.parent.mkdir(exist_ok=True)
    times = {"range": cli("bake", blend, "--frames", "1-24", *common, "--out", pattern)}
    rows = []
    for f in CHECKED:
        alone, ref = args.out / f"alone_{f}.exr", args.out / f"ref_{f}.exr"
        cli("bake", blend, "--frame", f, *common, "--out", alone)
        cli("bake", blend, "--frame", f, "--method", "reference", "--spp", args.ref_spp, "--seed", args.seed + 100,
            "--overwrite", "--out", ref)
        rows.append(check_frame(f, frame_path(pattern, f), alone, ref))
        print(rows[-1])
    times["cpu"] = resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime
    summary = json.loads((args.out / "range" / "c_summary.json").read_text())
    text = markdown(args, rows, times, summary)
    args.md.write_text(text)
    print(text)
    return 0 if all(r["bit_for_bit"] and r["sigmas"] < 3 for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
