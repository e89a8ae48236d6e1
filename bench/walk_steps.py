"""How walks step: Newton steps per solution found, per chain type, for walk settings side by side.

    .venv/bin/python bench/walk_steps.py [--scenes sphere,ring] [--method sms]
        [--variants "first_step=1,stall_stop=0;first_step=0.125;"] [--out bench/results/walk_steps]

Per scene (testkit/scenes.py, 256 x 256 unless ``name:size``): one bake of one sample per pixel
records the primary walks' seed chains (walk.newton_walk's lanes, one call per chain type);
each variant then walks exactly those lanes again with its BakeSettings (first_step,
stall_stop; empty: the defaults), on one thread. Reported: walks, solutions found, Newton
steps (small and large mutations), steps per solution, the outcomes that end the rest, and the
time per walk. Steps per solution is what the unbiased estimator pays per sample twice over: its
primary walk and, on average, as many Bernoulli trials as 1 / (success probability). Writes
walk_steps.md.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

from testkit import scenes
from smbs_addon import BakeSettings, bake
from smbs_addon.kernels import records
from smbs_addon.walks import walk

SCENES = {"sphere": scenes.glass_sphere_scene, "ring": scenes.ring_scene, "hammered": scenes.hammered_mirror_scene}


def _variant(text: str) -> dict:
    out = {}
    for kv in filter(None, text.split(",")):
        k, v = kv.split("=")
        out[k] = bool(int(v)) if k == "stall_stop" else float(v)
    return out


def captured_walks(scene, method: str) -> list:
    """The primary walks' arguments of a one-sample bake, one per chain type (its first call)."""
    from smbs_addon.walks import manifold  # it calls newton_walk by the name it imported

    seen, orig = [], walk.newton_walk

    def rec(ctx, cfg, types, x0, ng0, light, chain=None, large_ok=None, seed=None):
        if seed is not None and types not in [c[2] for c in seen]:
            seen.append((ctx, cfg, types, x0, ng0, light, chain, large_ok, seed))
        return orig(ctx, cfg, types, x0, ng0, light, chain, large_ok, seed)

    manifold.newton_walk = rec
    try:
        bake(scene, BakeSettings(method=method, spp=1, batches=1, seed=1))
    finally:
        manifold.newton_walk = orig
    return seen


def main(argv=None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenes", default="sphere,ring")
    ap.add_argument("--method", default="sms")
    ap.add_argument("--variants", default="first_step=1,stall_stop=0;first_step=1;stall_stop=0;")
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "walk_steps")
    args = ap.parse_args(argv)
    variants = args.variants.split(";")
    rows = []
    for item in args.scenes.split(","):
        name, _, size = item.partition(":")
        scene = SCENES[name](resolution=(int(size or 256),) * 2)
        for ctx, _, types, x0, ng0, light, chain, large_ok, seed in captured_walks(scene, args.method):
            ctx.tracer.threads = 1
            for v in variants:
                c2 = BakeSettings(method=args.method, **_variant(v)).manifold_options().walk
                t = time.perf_counter()
                r = walk.newton_walk(ctx, c2, types, x0, ng0, light, chain, large_ok, seed)
                dt = time.perf_counter() - t
                conv, steps = int(r.converged.sum()), int(r.mutations.sum())
                codes = np.bincount(r.outcome, minlength=len(records.OUTCOMES))
                ends = ", ".join(f"{records.OUTCOMES[c]} {codes[c]}" for c in np.flatnonzero(codes) if c != records.OK)
                rows.append((item, types, v or "defaults", len(x0), conv, steps, steps / max(conv, 1), ends,
                             dt / len(x0) * 1e6))
                print(*rows[-1], flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    lines = ["# Newton steps per solution", "",
             f"Made by `python bench/walk_steps.py --scenes {args.scenes} --method {args.method} "
             f"--variants \"{args.variants}\"` (one thread; the primary walks of a one-sample bake, "
             "walked again per variant).", "",
             "| scene | chain | settings | walks | solutions | steps | steps / solution | other outcomes | us / walk |",
             "|---|---|---|---|---|---|---|---|---|"]
    lines += [f"| {a} | {b} | {c} | {d} | {e} | {f} | {g:.1f} | {h} | {i:.2f} |" for a, b, c, d, e, f, g, h, i in rows]
    (args.out / "walk_steps.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
