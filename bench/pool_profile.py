"""Where a sample's time goes on issue 61's pools (testkit/pools.py): one bake per scene and method under
cProfile, its seconds split by stage (the functions each stage is), with CPU seconds and the walk counts.

    python bench/pool_profile.py [--scenes pool_sun,pool_hdri] [--methods smbs,mnee] [--spp 8] [--threads 2]

Stages are the cumulative seconds of the named functions (a stage holds what its function calls that
no later stage names); 'other' is the rest of the bake. Written to bench/results/pool_profile.md.
"""
from __future__ import annotations

import argparse
import cProfile
import pstats
import resource
import time

from testkit import ROOT

# stage -> (module file suffix, function name): the first match wins, in this order
STAGES = [
    ("plan and pre-pass (photon guide)", [("baking/plan.py", "make_plan"), ("baking/plan.py", "refine_plan"),
                                          ("walks/guide.py", "build_guide")]),
    ("eye paths to receivers", [("trace/eye.py", "eye_receivers")]),
    ("light sampling", [("shading/light_samples.py", "sample_light")]),
    ("seeding + primary walks", [("walks/estimators.py", "_walk")]),
    ("Bernoulli trials", [("walks/trials.py", "bernoulli_trials")]),
    ("anchor walks (straight-line seed)", [("walks/estimators.py", "_anchored")]),
    ("contribution (shadow ray, G, Fresnel)", [("walks/contribution.py", "_contribution")]),
    ("hand-off: drop + photons / gather", [("walks/estimators.py", "_drop_handed_off"),
                                           ("paths/gather.py", "handoff_gather"),
                                           ("baking/passes.py", "handoff_batch")]),
    ("bent-normal gather", [("paths/gather.py", "bent_gather")]),
    ("after a diffuse bounce", [("baking/passes.py", "indirect_batch")]),
]


def _stage_seconds(stats):
    out = {}
    for (file, line, fn), (cc, nc, tt, ct, callers) in stats.stats.items():
        for stage, names in STAGES:
            if any(file.endswith(f) and fn == name for f, name in names):
                out[stage] = out.get(stage, 0.0) + ct
    return out


def profile(scene_name, method, spp, threads):
    from smbs_addon import BakeSettings, bake
    from testkit.conformance import scene_arrays

    scene = scene_arrays(scene_name)
    from pools import VARIANTS

    kw = VARIANTS[method]
    bake(scene, BakeSettings(spp=1, batches=1, threads=threads, **kw))  # warm: compiled kernels
    pr = cProfile.Profile(time.process_time)  # CPU seconds of the process (all threads): the machine is shared
    t0, c0 = time.perf_counter(), time.process_time()
    pr.enable()
    res = bake(scene, BakeSettings(spp=spp, threads=threads, **kw))
    pr.disable()
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    st = pstats.Stats(pr)
    return wall, cpu, _stage_seconds(st), res.stats


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="pool_sun,pool_hdri")
    ap.add_argument("--methods", default="smbs,mnee", help="bench/pools.py's VARIANTS")
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "pool_profile.md"))
    a = ap.parse_args(argv)
    rows = []
    for sc in a.scenes.split(","):
        for m in a.methods.split(","):
            wall, cpu, stages, s = profile(sc, m, a.spp, a.threads)
            lights = s.get("lights", {})
            per = next(iter(lights.values()), {}) if isinstance(lights, dict) else {}
            rows.append((sc, m, wall, cpu, stages, s, per))
            print(sc, m, f"wall {wall:.1f} cpu {cpu:.1f}", {k: round(v, 2) for k, v in stages.items()}, flush=True)
    lines = [f"# Where a pool's sample goes (issue 61)", "",
             f"`python bench/pool_profile.py --scenes {a.scenes} --methods {a.methods} --spp {a.spp} "
             f"--threads {a.threads}`; 160 x 120, one bake each under cProfile after a warm-up (kernels "
             "compiled), on a 2-core machine shared with other jobs. Seconds are CPU seconds (both threads) of the "
             "stage's functions (cumulative, so a stage holds what it calls: the anchor walks hold their own "
             "contributions, which the contribution column counts too; a stage's kernels run on both threads), "
             "per bake.", ""]
    names = [n for n, _ in STAGES]
    lines.append("| scene | method | wall s | cpu s | " + " | ".join(names) + " | other | walks | trials/walk |")
    lines.append("|---|---|---|---|" + "---|" * (len(names) + 3))
    for sc, m, wall, cpu, stages, s, per in rows:
        other = cpu - sum(stages.values())
        walks = per.get("walks", 0)
        trials = per.get("bernoulli_trials", 0)
        lines.append(f"| {sc} | {m} | {wall:.1f} | {cpu:.1f} | " +
                     " | ".join(f"{stages.get(n, 0.0):.2f}" for n in names) +
                     f" | {other:.2f} | {walks:,} | {trials / max(walks, 1):.2f} |")
    with open(a.out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
