"""Fuzzed walks and fuzzed bakes of random small scenes: no non-finite value, no traceback, no hang.

    python bench/fuzz.py [--walks N] [--bakes M] [--chunk K] [--timeout S] [--out bench/results/fuzz.md]

Walks: tests/test_fuzz.py's random chains (a caster -- sphere, tilted pane, wavy sheet -- of random
mirror or glass at a random scale, a random light, MNEE / SMS / SMBS and either constraint form),
4096 lanes in one newton_walk call per example, each lane checked as that test checks it (a named
outcome, a converged walk within its threshold with a finite positive geometric term and a finite,
non-negative contribution, the clamp's cut adding up). Bakes: tests/test_bake_fuzz.py's random
scenes (receivers, one to three casters of random materials, lamps, mesh lights, worlds, Ray
Visibility, flags, linking, Light Paths limits, any camera) with random settings (every method and
estimator, chains, clamps, guide, a noise rule), each baked whole at 24 x 18: the image, its variance
and batches finite and not negative, the statistics finite.

Examples run in child processes, K at a time, each child on its own hypothesis seed (so the run is
the same every time); a child reports every example on a line of its own. An example that raises is
counted with its error (no traceback reaches the user: what the bake would print is the error
line); a child that prints nothing for S seconds is killed and its example counted as a hang; a child
that dies without reporting (a crash) is counted too. The counts and the failures go to the report.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import select
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LANES = 4096  # walks per walk example (tests/test_fuzz.py)

CHILD = r'''
import json, math, sys, time, traceback
from collections import Counter
sys.path[:0] = [ROOT, ROOT + "/tests"]
import numpy as np
from hypothesis import HealthCheck, Phase, given, seed, settings
kind, seed_value, count = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])

def say(**kw):
    print(json.dumps(kw), flush=True)

def finite_stats(stats):
    bad = []
    def walk(d, path):
        for k, v in d.items():
            if isinstance(v, dict):
                walk(v, path + k + ".")
            elif isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool):
                if not math.isfinite(float(v)):
                    bad.append(path + k)
    walk(stats, "")
    return bad

if kind == "walks":
    import test_fuzz
    strategy = dict(cfg=test_fuzz.configurations())
    def body(cfg):
        t = time.perf_counter()
        totals = Counter()
        try:
            non_finite, g_bad = test_fuzz.walk_example(cfg, totals)
            say(ok=True, walks=totals["walks"], non_finite=non_finite, g_bad=g_bad, converged=totals["outcome:converged"],
                s=time.perf_counter() - t)
        except Exception as e:
            say(ok=False, walks=totals["walks"] or test_fuzz.LANES, error=f"{type(e).__name__}: {e}"[:400],
                trace=traceback.format_exc()[-1500:], cfg=repr(cfg)[:600], s=time.perf_counter() - t)
else:
    import test_bake_fuzz
    from smbs_addon import bake
    strategy = dict(sc=test_bake_fuzz.scenes(), bs=test_bake_fuzz.bake_settings())
    def body(sc, bs):
        t = time.perf_counter()
        try:
            res = bake(sc, bs)
            bad = []
            for name in ("image", "variance", "batch_luminance"):
                a = getattr(res, name, None)
                if a is not None and not (np.isfinite(a).all() and (name == "batch_luminance" or (a >= 0).all())):
                    bad.append(name)
            bad += finite_stats(res.stats)
            say(ok=not bad, non_finite=bad, method=bs.method, nothing=bool(res.stats.get("nothing_to_bake")),
                s=time.perf_counter() - t, **({} if not bad else {"settings": repr(bs)[:600]}))
        except Exception as e:
            say(ok=False, error=f"{type(e).__name__}: {e}"[:400], trace=traceback.format_exc()[-1500:],
                method=bs.method, settings=repr(bs)[:600], s=time.perf_counter() - t)

run = settings(max_examples=count, database=None, deadline=None, phases=[Phase.generate],
               suppress_health_check=list(HealthCheck))(seed(seed_value)(given(**strategy)(body)))
run()
say(done=True)
'''.replace("ROOT", repr(str(ROOT)))


def run_chunks(kind: str, examples: int, chunk: int, timeout: float, first_seed: int, log, on_chunk=None) -> dict:
    """examples examples of kind ('walks' or 'bakes'), chunk per child; the tallies. on_chunk(tallies so
    far) after each child."""
    tally = Counter()
    failures, hangs, crashes, seconds = [], [], [], []
    s = first_seed
    t0 = time.perf_counter()
    while tally["examples"] < examples:
        n = min(chunk, examples - tally["examples"])
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        proc = subprocess.Popen([sys.executable, "-c", CHILD, kind, str(s), str(n)], cwd=ROOT, env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, bufsize=1)
        got, done, hung, last = 0, False, False, time.monotonic()
        while True:
            ready, _, _ = select.select([proc.stdout], [], [], 5.0)
            if ready:
                line = proc.stdout.readline()
                if not line:
                    break
                last = time.monotonic()
                try:
                    rec = json.loads(line)
                except ValueError:
                    continue
                if rec.get("done"):
                    done = True
                    continue
                got += 1
                seconds.append(rec.get("s", 0.0))
                if kind == "walks":
                    tally["walks"] += rec.get("walks", 0)
                    tally["converged"] += rec.get("converged", 0)
                    tally["non_finite"] += rec.get("non_finite", 0)
                    tally["converged_on_fold"] += rec.get("g_bad", 0)
                else:
                    tally["bakes"] += 1
                    tally[f"method:{rec.get('method')}"] += 1
                    tally["nothing_to_bake"] += int(bool(rec.get("nothing")))
                    tally["non_finite"] += int(bool(rec.get("non_finite")))
                if not rec.get("ok", False) or rec.get("non_finite") or rec.get("g_bad"):
                    tally["failed"] += 1
                    failures.append({"seed": s, "example": got, **{k: v for k, v in rec.items() if k != "ok"}})
            elif time.monotonic() - last > timeout:
                proc.kill()
                hung = True
                tally["hangs"] += 1
                hangs.append({"seed": s, "example": got + 1, "after_s": timeout})
                break
            elif proc.poll() is not None:
                break
        proc.wait()
        err = proc.stderr.read()
        tally["examples"] += got
        if not hung and not done:  # died without a word: a crash
            tally["crashes"] += 1
            crashes.append({"seed": s, "example": got + 1, "returncode": proc.returncode, "stderr": err[-1500:]})
        elif done and "Traceback" in err:
            tally["tracebacks_on_stderr"] += 1
            crashes.append({"seed": s, "returncode": proc.returncode, "stderr": err[-1500:]})
        if got < n:  # the rest of the chunk: not drawn (hypothesis ran out), or lost to a hang or a crash
            tally["not_run"] += n - got
            tally["examples"] += n - got
        log(f"{kind}: seed {s}: {got} of {n} examples, {tally['failed']} failed, {tally['hangs']} hangs, "
            f"{tally['crashes']} crashes so far ({time.perf_counter() - t0:.0f} s)")
        if on_chunk is not None:
            on_chunk({"tally": dict(tally), "failures": failures, "hangs": hangs, "crashes": crashes,
                      "wall_s": time.perf_counter() - t0, "example_s": seconds, "of": examples})
        s += 1
    return {"tally": dict(tally), "failures": failures, "hangs": hangs, "crashes": crashes,
            "wall_s": time.perf_counter() - t0, "example_s": seconds}


def _quantiles(xs):
    if not xs:
        return "-"
    xs = sorted(xs)
    q = lambda p: xs[min(len(xs) - 1, int(p * len(xs)))]  # noqa: E731
    return f"median {q(0.5):.2f} s, 95% {q(0.95):.2f} s, max {xs[-1]:.2f} s"


def report(walks: dict | None, bakes: dict | None, args) -> str:
    lines = ["# Fuzzing: random walks and random bakes", "",
             f"Made by `python bench/fuzz.py --walks {args.walks} --bakes {args.bakes} --chunk {args.chunk} "
             f"--timeout {args.timeout:g}` ({os.cpu_count()} cores, shared with other jobs). Generators: "
             "tests/test_fuzz.py (walks), tests/test_bake_fuzz.py (bakes); hypothesis seeds from "
             f"{args.seed} on, one per child process of {args.chunk} examples.", ""]
    for name, r in (("walks", walks), ("bakes", bakes)):
        if r is None:
            continue
        t = r["tally"]
        done = t.get("examples", 0)
        lines += [f"## {name.capitalize()}", ""]
        if r.get("of") and done < r["of"]:
            lines += [f"In progress (this report is rewritten after every child): {done:,} of {r['of']:,} examples.", ""]
        lines += [
                  "| what | count |", "|---|---|"]
        for k in sorted(t):
            lines.append(f"| {k} | {t[k]:,} |")
        lines += ["", f"Wall time {r['wall_s']:.0f} s; per example {_quantiles(r['example_s'])}.", ""]
        if r["failures"] or r["hangs"] or r["crashes"]:
            lines.append("Failures:")
            for f in (r["failures"] + r["hangs"] + r["crashes"])[:30]:
                lines.append(f"- `{json.dumps(f)[:1200]}`")
            lines.append("")
        else:
            lines += ["No non-finite value, no exception, no traceback, no hang.", ""]
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--walks", type=int, default=100_000, help="walks (4096 per example)")
    p.add_argument("--bakes", type=int, default=300)
    p.add_argument("--chunk", type=int, default=25, help="examples per child process")
    p.add_argument("--timeout", type=float, default=600.0, help="seconds without a report before a hang is called")
    p.add_argument("--seed", type=int, default=59)
    p.add_argument("--out", default=str(ROOT / "bench" / "results" / "fuzz.md"))
    args = p.parse_args(argv)
    log = lambda m: print(m, file=sys.stderr, flush=True)  # noqa: E731
    got = {"walks": None, "bakes": None}

    def save(kind):
        def on_chunk(r):
            got[kind] = r
            Path(args.out).write_text(report(got["walks"], got["bakes"], args) + "\n")
            Path(args.out).with_suffix(".json").write_text(json.dumps(got, indent=1))
        return on_chunk

    if args.walks > 0:
        run_chunks("walks", math.ceil(args.walks / LANES), args.chunk, args.timeout, args.seed, log, save("walks"))
    if args.bakes > 0:
        run_chunks("bakes", args.bakes, args.chunk, args.timeout, args.seed, log, save("bakes"))
    walks, bakes = got["walks"], got["bakes"]
    text = report(walks, bakes, args)
    print(text)
    bad = sum(r["tally"].get(k, 0) for r in (walks, bakes) if r for k in ("failed", "hangs", "crashes"))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
