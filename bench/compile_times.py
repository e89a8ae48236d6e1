"""Where the first compile goes: numba's compile time per function, for one bake on an empty cache.

    python bench/compile_times.py [--method walks|smbs|sms|mnee|reference] [--top 25]

Copies the package into a temporary folder (its numba cache empty), makes there one 1-spp bake of
prepare's plain scene (``walks``: prepare's first bake, the walks alone) and prints, per function
numba compiled, the seconds inside its own compile (``excl``: less the functions it compiled on the
way, its callees not inlined), with them (``incl``) and how many times it compiled (one per
signature: a constant argument of another value is another signature). A helper marked
``inline="always"`` is compiled inside every caller, once per call site, and never shows here.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = r'''
import collections, sys, time
from numba.core import event

stack, incl, excl, count = [], collections.Counter(), collections.Counter(), collections.Counter()
outer = [0.0]  # the outermost compiles' seconds


class Times(event.Listener):
    def on_start(self, ev):
        d = ev.data.get("dispatcher")
        stack.append([d.py_func.__qualname__ if d is not None else "?", time.perf_counter(), 0.0])

    def on_end(self, ev):
        name, t0, inner = stack.pop()
        dt = time.perf_counter() - t0
        incl[name] += dt
        excl[name] += dt - inner
        count[name] += 1
        if stack:
            stack[-1][2] += dt
        else:
            outer[0] += dt


event.register("numba:compile", Times())
from smbs_addon import BakeSettings, bake
from smbs_addon.baking import prepare

method, top = sys.argv[1], int(sys.argv[2])
kw = prepare.WALKS_ONLY if method == "walks" else dict(method=method)
t = time.perf_counter()
bake(prepare.scene("plain"), BakeSettings(spp=1, seed=1, **kw))
print(f"bake: {time.perf_counter() - t:.1f} s, of which compiling {outer[0]:.1f} s")
print(f"{'function':40s} {'excl s':>7s} {'incl s':>7s} {'n':>3s}")
for name, v in excl.most_common(top):
    print(f"{name:40s} {v:7.1f} {incl[name]:7.1f} {count[name]:3d}")
'''


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", default="walks", choices=("walks", "smbs", "sms", "mnee", "reference"))
    ap.add_argument("--top", type=int, default=25)
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        shutil.copytree(ROOT / "smbs_addon", Path(tmp) / "smbs_addon",
                        ignore=shutil.ignore_patterns("__pycache__"))
        env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
        return subprocess.call([sys.executable, "-c", CHILD, a.method, str(a.top)], cwd=tmp, env=env)


if __name__ == "__main__":
    sys.exit(main())
