"""Issue 60's property: distractors that cannot contribute change nothing.

Random builder scenes (testkit/distractors.py: a floor, one or two casters, one or two lamps, a dim
world sometimes, a camera anywhere around them), each baked without and with random distractors
(lights aimed away, casters far outside the view or under the floor, casters hidden from diffuse
rays), for every method: the image and its noise (std) must be the same bit for bit, the rays at
most 5% more, and the plan's words those of the scene without them, plus a line per distractor.
Also the issue's own scene (testkit/distractors.issue_lens_scene) at its size, 160 x 120, spp 8.

    python bench/distractors.py --pairs 200 [--start 0] [--methods auto,smbs,sms,mnee,reference]
        [--res 96x72] [--spp 4] [--spp-reference 32] [--out bench/results/distractors.md]

One heavy process: each bake uses every core. Writes the table of counts and the issue scene's
numbers to --out (and a line per pair to stdout as it goes).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from testkit import ROOT
from testkit import distractors as D
from smbs_addon import BakeSettings, bake

METHODS = ("auto", "smbs", "sms", "mnee", "reference")
MAX_RATIO = 1.05


def compare(plain, more, names) -> dict:
    """What the distractors changed: pixels, the std's bytes, the rays' ratio, and whether the plan's
    words are the plain scene's plus a line per distractor (naming it)."""
    d = np.abs(plain.image - more.image).max(axis=2)
    wa, wb = plain.stats["plan"]["words"], more.stats["plan"]["words"]
    extra = [w for w in wb if w not in wa]
    words = [w for w in wb if w in wa] == wa and all(any(n in w for n in names) for w in extra)
    return {"pixels": int((d > 0).sum()), "max": float(d.max()), "same": plain.image.tobytes() == more.image.tobytes()
            and plain.std.tobytes() == more.std.tobytes(), "ratio": more.stats["rays"] / max(plain.stats["rays"], 1),
            "words": words, "rays": (plain.stats["rays"], more.stats["rays"]),
            "plan_rays": (plain.stats["plan"]["rays"], more.stats["plan"]["rays"]),
            "dropped": more.stats["plan"].get("dropped", {})}


def pair(seed: int, method: str, res, spp: int) -> dict:
    r = D.recipe(seed)
    settings = BakeSettings(method=method, spp=spp, batches=2, seed=seed)
    plain = bake(D.build(r, False, res), settings)
    more = bake(D.build(r, True, res), settings)
    out = compare(plain, more, [d["name"] for d in r["distractors"]])
    scene = D.build(r, True, res)
    placed = set(scene.object_names) | set(scene.light_names)  # an unlit ball finds no place beside some lamps
    out.update(seed=seed, method=method, kinds=[d["kind"] for d in r["distractors"] if d["name"] in placed],
               scene=f"{'+'.join(c['kind'] for c in r['casters'])} / {'+'.join(li['kind'] for li in r['lights'])}"
                     + (" + world" if r["world"] > 0 else ""))
    return out


def issue_scene(methods) -> list:
    rows = []
    for m in methods:
        res = [bake(D.issue_lens_scene(extra), BakeSettings(method=m, spp=8, seed=3)) for extra in (False, True)]
        c = compare(*res, ["SkySpot", "FarGlass"])
        c.update(method=m, words=res[1].stats["plan"]["words"],
                 sums=[float(x.image.mean(axis=2).sum()) for x in res],
                 pilots=[x.stats["plan"]["pilot_photons"] for x in res])
        rows.append(c)
        print(f"issue scene {m}: {c['pixels']} px differ, rays {c['rays'][0]:,} -> {c['rays'][1]:,} "
              f"({c['ratio']:.4f}), plan rays {c['plan_rays'][0]:,} -> {c['plan_rays'][1]:,}", flush=True)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pairs", type=int, default=200)
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--res", default="96x72")
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--spp-reference", type=int, default=32)
    ap.add_argument("--no-issue-scene", action="store_true")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "distractors.md"))
    a = ap.parse_args(argv)
    methods = a.methods.split(",")
    res = tuple(int(x) for x in a.res.split("x"))
    t0 = time.perf_counter()
    issue = [] if a.no_issue_scene else issue_scene(methods)
    rows = []
    for seed in range(a.start, a.start + a.pairs):
        for m in methods:
            c = pair(seed, m, res, a.spp_reference if m == "reference" else a.spp)
            rows.append(c)
            ok = c["same"] and c["ratio"] <= MAX_RATIO and c["words"]
            print(f"seed {seed} {m}: {'ok' if ok else 'FAIL'} px {c['pixels']} ratio {c['ratio']:.4f} words "
                  f"{c['words']} | {c['kinds']} | {c['scene']}", flush=True)
        write(a, methods, res, issue, rows, time.perf_counter() - t0)  # after every pair: a cut-short run keeps its table
    write(a, methods, res, issue, rows, time.perf_counter() - t0)
    bad = [c for c in rows if not (c["same"] and c["ratio"] <= MAX_RATIO and c["words"])]
    return 1 if bad or any(not c["same"] or c["ratio"] > MAX_RATIO for c in issue) else 0


def write(a, methods, res, issue, rows, seconds) -> None:
    lines = ["# Distractors that cannot contribute change nothing (issue 60)", "",
             f"`python bench/distractors.py --pairs {a.pairs} --start {a.start} --methods {','.join(methods)} "
             f"--res {res[0]}x{res[1]} --spp {a.spp} --spp-reference {a.spp_reference}` ({len(rows) // len(methods)} "
             f"pairs done, {seconds / 60:.0f} min, 2 cores shared with other work). Each pair is a random builder scene (testkit/distractors.py, seed = pair) baked without and "
             "with 1-3 random distractors, batches 2, seed = pair; a pair passes when the image and its std are "
             f"bit-identical, the rays at most {MAX_RATIO - 1:.0%} more, and the plan's words those of the plain "
             "scene plus lines naming the distractors.", ""]
    if issue:
        lines += ["## The issue's scene", "",
                  "testkit/distractors.issue_lens_scene: a biconvex glass lens 1.6 m above a 20 m floor, a 0.4 m area light "
                  "at (0.3, -0.2, 6), Blender's default grey world; the distractors a spot at z = 9 aimed up and a "
                  "glass ball (r 0.5) at (40, 40, 0.5). 160 x 120, `--spp 8 --seed 3`.", "",
                  "| method | pixels differing | rays without | rays with | ratio | plan rays | pilot photons |",
                  "|---|---|---|---|---|---|---|"]
        for c in issue:
            lines.append(f"| {c['method']} | {c['pixels']} of 19,200 | {c['rays'][0]:,} | {c['rays'][1]:,} | "
                         f"{c['ratio']:.4f} | {c['plan_rays'][0]:,} -> {c['plan_rays'][1]:,} | "
                         f"{c['pilots'][0]:,} -> {c['pilots'][1]:,} |")
        lines += ["", "Its plan with the distractors:", ""] + [f"    {w}" for w in issue[0]["words"]] + [""]
    lines += ["## Random pairs", "", "| method | pairs | bit-identical | rays <= 5% more | words | all three | "
              "ratio median | ratio max |", "|---|---|---|---|---|---|---|---|"]
    for m in methods + ["all"]:
        cs = [c for c in rows if m == "all" or c["method"] == m]
        if not cs:
            continue
        r = np.array([c["ratio"] for c in cs])
        ok = sum(c["same"] and c["ratio"] <= MAX_RATIO and c["words"] for c in cs)
        lines.append(f"| {m} | {len(cs)} | {sum(c['same'] for c in cs)} | {int((r <= MAX_RATIO).sum())} | "
                     f"{sum(c['words'] for c in cs)} | {ok} | {np.median(r):.4f} | {r.max():.4f} |")
    kinds = sorted({k for c in rows for k in c["kinds"]})
    lines += ["", "Pairs by distractor kind (a pair may hold several):", "",
              "| kind | pairs | bit-identical | rays <= 5% more |", "|---|---|---|---|"]
    for k in kinds:
        cs = [c for c in rows if k in c["kinds"]]
        lines.append(f"| {k} | {len(cs)} | {sum(c['same'] for c in cs)} | "
                     f"{sum(c['ratio'] <= MAX_RATIO for c in cs)} |")
    bad = [c for c in rows if not (c["same"] and c["ratio"] <= MAX_RATIO and c["words"])]
    if bad:
        lines += ["", "Failing pairs:", "", "| seed | method | pixels | ratio | words | distractors | scene |",
                  "|---|---|---|---|---|---|---|"]
        lines += [f"| {c['seed']} | {c['method']} | {c['pixels']} | {c['ratio']:.4f} | {c['words']} | "
                  f"{', '.join(c['kinds'])} | {c['scene']} |" for c in bad]
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    sys.exit(main())
