"""This tree against another revision, timed in one process: walks or whole bakes, interleaved.

    python bench/ab.py --base REV [--scenes sphere:512,ring:512,hammered:48] [--reps 12]
        [--bakes sms,smbs,reference] [--spp 1]

Timings of separate processes on a shared 2-core machine drift by 20-50% within minutes (the
same walks of the glass sphere took 13 and 20 us each half an hour apart), which hides the few
percent a change to the kernels makes. Here both trees live in one process: REV's
``smbs_addon`` is extracted (``git archive``) into a folder of its own under the temporary
directory and imported from there as ``smbs_base``, this tree's from its own folder as ``smbs_addon``
(each loaded from its folder by name, sys.path untouched; REV's numba cache kept beside it per
revision, so a second run loads it), each tree builds the scenes of its own ``testkit/scenes.py``
(``tests/scenes.py`` in revisions before the test-kit) and records its own
primary walks of a one-sample SMBS bake (as bench/walk_steps.py), and the two trees' walks then
run in turn, one thread, ``--reps`` times, the order swapped every round. Printed per scene and
chain type: microseconds per walk (minimum and median) and the median of the rounds' ratios
this / base, which cancels the drift both share. ``--bakes``: whole bakes of those methods
instead (``spp`` samples, both threads), timed the same way.
"""
from __future__ import annotations

import argparse
import importlib
import importlib.util
import io
import subprocess
import sys
import tarfile
import tempfile
import time
import types
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENES = {"sphere": "glass_sphere_scene", "ring": "ring_scene", "hammered": "hammered_mirror_scene"}
# where a tree keeps the scenes, the walk and the module that calls it by name (newest layout first)
SCENES_PATHS = ("testkit/scenes.py", "tests/scenes.py")
WALK = ("walks.walk", "walk")
WALK_CALLER = ("walks.estimators", "walks.manifold", "manifold")


def extract(rev: str) -> tuple[Path, str]:
    """REV's smbs_addon as smbs_base in <tmp>/smbs_ab/<sha>/, and REV's builder scenes' source."""
    sha = subprocess.check_output(["git", "rev-parse", rev], cwd=ROOT, text=True).strip()
    home = Path(tempfile.gettempdir()) / "smbs_ab" / sha[:12]
    if not (home / "smbs_base" / "__init__.py").exists():
        data = subprocess.check_output(["git", "archive", sha, "smbs_addon"], cwd=ROOT)
        with tarfile.open(fileobj=io.BytesIO(data)) as tar:
            tar.extractall(home / "unpack")
        (home / "unpack" / "smbs_addon").rename(home / "smbs_base")
    for path in SCENES_PATHS:
        shown = subprocess.run(["git", "show", f"{sha}:{path}"], cwd=ROOT, capture_output=True, text=True)
        if shown.returncode == 0:
            return home, shown.stdout
    raise SystemExit(f"{rev} has none of {', '.join(SCENES_PATHS)}")


def load_package(name: str, folder: Path):
    """The package in folder imported under name (its modules import each other relatively), without
    putting its parent on sys.path."""
    spec = importlib.util.spec_from_file_location(name, folder / "__init__.py",
                                                  submodule_search_locations=[str(folder)])
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def submodule(P, candidates, holding=None):
    """The first of P's modules named in candidates that exists (layouts differ between revisions) and, if
    given, holds the name holding."""
    for name in candidates:
        try:
            module = importlib.import_module(f"{P.__name__}.{name}")
        except ModuleNotFoundError:
            continue
        if holding is None or hasattr(module, holding):
            return module
    raise ModuleNotFoundError(f"{P.__name__} has none of {candidates}")


def scenes_module(source: str, package: str):
    m = types.ModuleType(f"scenes_{package}")
    exec(compile(source.replace("from smbs_addon.", f"from {package}."), f"scenes ({package})", "exec"), m.__dict__)
    return m


def captured(P, scene) -> list:
    """The primary walks' arguments of a one-sample SMBS bake, one per chain type."""
    caller = submodule(P, WALK_CALLER, "newton_walk")
    seen, orig = [], caller.newton_walk

    def rec(ctx, cfg, chain_types, x0, ng0, light, chain=None, large_ok=None, seed=None):
        if seed is not None and chain_types not in [c[2] for c in seen]:
            seen.append((ctx, cfg, chain_types, x0, ng0, light, chain, large_ok, seed))
        return orig(ctx, cfg, chain_types, x0, ng0, light, chain, large_ok, seed)

    caller.newton_walk = rec
    try:
        # one thread: the first walk of each chain type is the same in both trees (with two, whichever
        # chunk's thread came first: the trees timed different lanes)
        P.bake(scene, P.BakeSettings(method="smbs", spp=1, batches=1, seed=1, threads=1))
    finally:
        caller.newton_walk = orig
    for c in seen:
        c[0].tracer.threads = 1
    return seen


def report(label: str, base: list, this: list) -> None:
    b, a = np.array(base), np.array(this)
    print(f"{label:24s} base {b.min():8.3f} {np.median(b):8.3f} | this {a.min():8.3f} {np.median(a):8.3f} | "
          f"this / base {np.median(a / b):.3f}", flush=True)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="the revision to compare with (git rev)")
    ap.add_argument("--scenes", default="sphere:512,ring:512,hammered:48")
    ap.add_argument("--reps", type=int, default=12)
    ap.add_argument("--bakes", default="", help="methods: time whole bakes instead of the walks")
    ap.add_argument("--spp", type=int, default=1)
    ap.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                    help="cpu: the process's CPU time (all threads), steadier than wall time on a loaded machine")
    a = ap.parse_args(argv)
    home, base_scenes = extract(a.base)
    pk = {"smbs_base": load_package("smbs_base", home / "smbs_base"),
          "smbs_addon": load_package("smbs_addon", ROOT / "smbs_addon")}
    walks = {n: submodule(P, WALK) for n, P in pk.items()}
    src = {"smbs_base": base_scenes, "smbs_addon": (ROOT / SCENES_PATHS[0]).read_text()}
    unit = "s per bake" if a.bakes else "us per walk"
    clock = time.process_time if a.clock == "cpu" else time.perf_counter
    print(f"this: {ROOT}, base: {a.base} ({home}); min and median {unit}, {a.reps} rounds")
    for item in a.scenes.split(","):
        name, _, size = item.partition(":")
        made = {n: getattr(scenes_module(src[n], n), SCENES[name])(resolution=(int(size or 256),) * 2) for n in pk}
        times = {}
        if a.bakes:
            for r in range(a.reps + 1):  # round 0 warms up (loads the kernels)
                for n in (("smbs_base", "smbs_addon") if r % 2 == 0 else ("smbs_addon", "smbs_base")):
                    P = pk[n]
                    for m in a.bakes.split(","):
                        t = clock()
                        P.bake(made[n], P.BakeSettings(method=m, spp=a.spp, batches=min(a.spp, 2), seed=1))
                        if r:
                            times.setdefault((m, n), []).append(clock() - t)
        else:
            caps = {n: captured(P, made[n]) for n, P in pk.items()}
            for r in range(a.reps):
                for n in (("smbs_base", "smbs_addon") if r % 2 == 0 else ("smbs_addon", "smbs_base")):
                    for ctx, cfg, chain_types, x0, ng0, light, chain, large_ok, seed in caps[n]:
                        t = clock()
                        walks[n].newton_walk(ctx, cfg, chain_types, x0, ng0, light, chain, large_ok, seed)
                        times.setdefault((chain_types, n), []).append((clock() - t) / len(x0) * 1e6)
        for key in dict.fromkeys(k[0] for k in times):
            report(f"{item} {key}", times[(key, "smbs_base")], times[(key, "smbs_addon")])


if __name__ == "__main__":
    main()
